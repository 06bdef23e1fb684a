"""The headline tasks on any robot that meets the contract (``experiment robot --env``).

Turn, approach and turn & approach are demonstrated by our teacher on the robot itself,
from the default training grids scaled to it (``env.unwrapped.start_scale``); turn
{angle} and approach {distance, angle} are learned, turn & approach is composed from the
robot's own two components without retraining them, and each is scored on the shipped
test starts scaled the same way, beside the all-zero floor and behavior cloning.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any, Final

from behavior_hmm.evaluate._baselines import baseline_columns, fit_baselines
from behavior_hmm.evaluate._protocol import evaluate_model

Progress = Callable[[int, int], None]

#: (task, behavior, inputs) of the robot experiment; turn & approach is a CBLM.
ROBOT_TASKS: Final[tuple[tuple[str, str, tuple[str, ...]], ...]] = (
    ("turn {angle}", "turn", ("angle",)),
    ("approach {distance, angle}", "approach", ("distance", "angle")),
    ("turn & approach (composed)", "turn-approach", ("distance", "angle")),
)


def run_robot_experiment(
    env: Any,
    env_name: str,
    *,
    seed: int = 0,
    sblm_params: Mapping[str, Any] | None = None,
    cblm_params: Mapping[str, Any] | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """Collect, train, compose and evaluate the three headline tasks on ``env``.

    Returns
    -------
    dict
        ``env``, ``seed``, ``robot`` (its spec), ``rows`` (per task: success %, goals
        reached, BC, zero floor, timings) and ``evaluations`` (the full evaluation
        dicts, with traces under ``"_traces"`` for the figures).
    """
    from behavior_hmm.models import CBLM, SBLM
    from behavior_hmm.runtime import Robot
    from behavior_hmm.teach import (
        behavior_spec,
        collect,
        default_starts,
        scaled_starts,
        test_starts,
    )

    robot = Robot(env)
    steps = 2 + len(ROBOT_TASKS)
    done = 0

    def tick() -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, steps)

    data = {
        b: collect(
            b,
            scaled_starts(default_starts(b), env),
            seed=seed,
            corrections=behavior_spec(b).corrections,  # the default grid's recipe
            env=env,
            env_name=env_name,
        )
        for b in ("turn", "approach", "turn-approach")
    }
    tick()
    own = dict(sblm_params or {})
    models: dict[str, Any] = {}
    train_s: dict[str, float] = {}
    for _, behavior, inputs in ROBOT_TASKS[:2]:
        t0 = time.perf_counter()
        models[behavior] = SBLM(**{**own, "inputs": inputs, "random_state": seed}).fit(
            data[behavior]
        )
        train_s[behavior] = time.perf_counter() - t0
    t0 = time.perf_counter()
    params = {**dict(cblm_params or {}), "inputs": ROBOT_TASKS[2][2]}
    models["turn-approach"] = CBLM([models["turn"], models["approach"]], **params).fit(
        data["turn-approach"]
    )
    train_s["turn-approach"] = time.perf_counter() - t0
    tick()
    rows: list[dict[str, Any]] = []
    evaluations: list[dict[str, Any]] = []
    for task, behavior, inputs in ROBOT_TASKS:
        baselines = fit_baselines(inputs, data[behavior], seed)
        starts = scaled_starts(test_starts(behavior), env)
        result = evaluate_model(
            models[behavior],
            starts,
            sim=None,
            env=env,
            seed=seed,
            baselines=baselines,
            keep_traces=True,
        )
        evaluations.append(result)
        rows.append(
            {
                "task": task,
                "behavior": behavior,
                "inputs": list(inputs),
                "model": result["kind"],
                "success_rate": result["success_rate_mean"],
                "goal_reached": result["goal_reached"],
                **baseline_columns(result),
                "zero_floor": result["zero_floor_mean"],
                "n": result["n"],
                "switches_max": result["switches_max"],
                "train_s": train_s[behavior],
                "demonstrations": len(data[behavior]),
            }
        )
        tick()
    return {
        "env": env_name,
        "seed": seed,
        "robot": robot.spec.to_dict(),
        "control_period": robot.control_period,
        "start_scale": dict(getattr(env.unwrapped, "start_scale", None) or {}),
        "rows": rows,
        "evaluations": evaluations,
    }


def robot_table(result: Mapping[str, Any]) -> str:
    """The Markdown table of :func:`run_robot_experiment`."""
    lines = [
        f"Robot: `{result['env']}` (control period {result['control_period'] * 1000:g} ms; "
        f"test starts scaled by {result['start_scale'] or 'nothing'})",
        "",
        "| task | model | success % | goal reached | BC % (goals) | BC-strong % (goals) "
        "| all-zero floor % |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for row in result["rows"]:
        lines.append(
            f"| {row['task']} | {row['model']} | {row['success_rate']:.1f} | "
            f"{row['goal_reached']}/{row['n']} | {row['bc']:.1f} ({row['bc_goal_reached']}) | "
            f"{row['bc_strong']:.1f} ({row['bc_strong_goal_reached']}) | {row['zero_floor']:.1f} |"
        )
    return "\n".join(lines) + "\n"
