"""The thesis's simple-behavior experiments (tables 6.3 and 6.4) as one function."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, Final

import numpy as np

from behavior_hmm.evaluate._baselines import BehaviorCloning
from behavior_hmm.evaluate._protocol import evaluate_model

Progress = Callable[[int, int], None]

#: (behavior, inputs, thesis success rate %) of tables 6.3 and 6.4.
SIMPLE_CONFIGS: Final[tuple[tuple[str, tuple[str, ...], float], ...]] = (
    ("turn", ("angle",), 90.9),
    ("turn", ("angle", "angular_velocity"), 84.2),
    ("approach", ("distance",), 73.9),
    ("approach", ("distance", "angle"), 82.6),
    ("approach", ("distance", "angle", "linear_velocity"), 73.7),
)

#: Starts drawn in the generated-vs-demonstrated figures (thesis figs 6.8 and 6.9).
FIGURE_STARTS: Final[dict[str, tuple[int, ...]]] = {"turn": (3, 12), "approach": (4, 10)}


def run_simple_experiment(
    *,
    sim: str = "mujoco",
    seed: int = 0,
    noise: float = 0.0,
    configs: tuple[tuple[str, tuple[str, ...], float], ...] = SIMPLE_CONFIGS,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """Collect the default datasets, train SBLM and BC per config, evaluate on the test starts.

    Returns
    -------
    dict
        ``rows``: one summary per config (SBLM, BC, thesis figure, zero floor, timings);
        ``evaluations``: the full evaluation dicts; ``figures``: generated and
        demonstrated series for a few starts per behavior.
    """
    from behavior_hmm.models import SBLM
    from behavior_hmm.teach import collect, test_starts

    datasets = {b: collect(b, sim=sim, seed=seed) for b in sorted({c[0] for c in configs})}
    rows: list[dict[str, Any]] = []
    evaluations: list[dict[str, Any]] = []
    figures: dict[str, Any] = {}
    for i, (behavior, inputs, thesis) in enumerate(configs):
        dataset = datasets[behavior]
        t0 = time.perf_counter()
        model = SBLM(inputs=inputs, random_state=seed).fit(dataset)
        train_s = time.perf_counter() - t0
        bc = BehaviorCloning(inputs=inputs, random_state=seed).fit(dataset)
        starts = test_starts(behavior)
        want_figure = behavior not in figures
        result = evaluate_model(
            model,
            starts,
            sim=sim,
            seed=seed,
            noise=noise,
            baselines={"bc": bc},
            keep_traces=want_figure,
        )
        if want_figure:
            figures[behavior] = _figure_series(result.pop("_traces"), behavior, starts)
        evaluations.append(result)
        base = result["baselines"]["bc"]
        rows.append(
            {
                "behavior": behavior,
                "inputs": list(inputs),
                "thesis": thesis,
                "sblm": result["success_rate_mean"],
                "sblm_goal_reached": result["goal_reached"],
                "bc": base["success_rate_mean"],
                "bc_goal_reached": base["goal_reached"],
                "zero_floor": result["zero_floor_mean"],
                "sblm_motor_max": result["success_rate_motor_max_mean"],
                "zero_floor_motor_max": result["zero_floor_motor_max_mean"],
                "n": result["n"],
                "primitives": int(model.primitives_.n_categories_),
                "observations": int(model.observations_.n_categories_),
                "train_s": train_s,
            }
        )
        if progress is not None:
            progress(i + 1, len(configs))
    return {
        "sim": sim,
        "seed": seed,
        "noise": noise,
        "rows": rows,
        "evaluations": evaluations,
        "figures": figures,
    }


def _figure_series(
    traces: dict[str, list[Any]], behavior: str, starts: list[dict[str, float]]
) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Generated vs demonstrated channel for a few starts (the teacher replayed in the trace)."""
    from behavior_hmm.data import SENSOR_CHANNELS

    channel = "angle" if behavior == "turn" else "distance"
    j = SENSOR_CHANNELS.index(channel)
    series = []
    for k in FIGURE_STARTS.get(behavior, (0,)):
        if k >= len(traces["model"]):
            continue
        trace, demo = traces["model"][k]
        label = ", ".join(f"{key} {value:g}" for key, value in trace.start.items())
        series.append((label, trace.reading_array[:, j], np.asarray(demo[channel])))
    return series


#: Turn & approach starts drawn in the figure-6.10 analogue (indices into the test starts).
COMPLEX_FIGURE_STARTS: Final[tuple[int, ...]] = (13, 3)


def run_complex_experiment(
    *,
    sim: str = "mujoco",
    seed: int = 0,
    noise: float = 0.0,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """Thesis table 6.5 and beyond: turn & approach, position, and a nested composition.

    Components are trained once (turn on {angle}, approach and retreat on {distance,
    angle}, the thesis's best inputs) and composed without retraining: turn & approach
    (thesis table 6.5, with a behavior-cloning baseline trained on the same complex
    demonstrations), *position* over {turn, approach, retreat} on the 30 position test
    starts, and *position* again as a CBLM whose components are the turn & approach CBLM
    and retreat (a CBLM inside a CBLM).
    """
    from behavior_hmm.data import Dataset
    from behavior_hmm.models import CBLM, SBLM
    from behavior_hmm.teach import collect, test_starts

    steps = 6
    done = 0

    def tick() -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, steps)

    behaviors = ("turn", "approach", "retreat", "turn-approach", "position")
    data = {b: collect(b, sim=sim, seed=seed) for b in behaviors}
    tick()
    turn = SBLM(inputs=("angle",), random_state=seed).fit(data["turn"])
    approach = SBLM(inputs=("distance", "angle"), random_state=seed).fit(data["approach"])
    retreat = SBLM(inputs=("distance", "angle"), random_state=seed).fit(data["retreat"])
    tick()
    t0 = time.perf_counter()
    ta = CBLM([turn, approach], inputs=("distance", "angle")).fit(data["turn-approach"])
    train_ta_s = time.perf_counter() - t0
    bc = BehaviorCloning(inputs=("distance", "angle"), random_state=seed).fit(data["turn-approach"])
    ta_starts = test_starts("turn-approach")
    ta_result = evaluate_model(
        ta, ta_starts, sim=sim, seed=seed, noise=noise, baselines={"bc": bc}, keep_traces=True
    )
    traces = ta_result.pop("_traces")
    figure = []
    for k in COMPLEX_FIGURE_STARTS:
        trace, demo = traces["model"][k]
        figure.append(
            {
                "start": trace.start,
                "t": np.arange(len(trace)) * 0.016,
                "angle": trace.reading_array[:, 2],
                "distance": trace.reading_array[:, 0],
                "component": list(trace.component),
                "demo_angle": np.asarray(demo["angle"]),
                "demo_distance": np.asarray(demo["distance"]),
                "demo_behavior": list(demo["behavior"]),
            }
        )
    tick()
    position = CBLM([turn, approach, retreat], inputs=("distance", "angle")).fit(data["position"])
    pos_starts = test_starts("position")
    pos_result = evaluate_model(position, pos_starts, sim=sim, seed=seed, noise=noise)
    tick()
    # A CBLM as a component: relabel the position demonstrations' turn/approach rows as
    # the turn & approach CBLM, and compose it with retreat.
    relabelled = []
    for episode in data["position"].episodes():
        cols = episode.to_dict()
        tags = np.asarray(cols["behavior"], dtype=object)
        cols["behavior"] = np.where(tags == "retreat", "retreat", "turn-approach")
        relabelled.append(cols)
    nested_data = Dataset.from_episodes(relabelled, metadata=data["position"].metadata)
    nested = CBLM([ta, retreat], inputs=("distance", "angle")).fit(nested_data)
    nested_result = evaluate_model(nested, pos_starts, sim=sim, seed=seed, noise=noise)
    tick()
    retreat_result = evaluate_model(retreat, test_starts("retreat"), sim=sim, seed=seed)
    tick()

    def split(result: dict[str, Any]) -> dict[str, Any]:
        cases = result["cases"]
        need_approach = [c for c in cases if c["start"]["distance"] > c["goal"]["distance"]]
        need_retreat = [c for c in cases if c["start"]["distance"] < c["goal"]["distance"]]
        return {
            "success_rate_mean": result["success_rate_mean"],
            "zero_floor_mean": result["zero_floor_mean"],
            "goal_reached": result["goal_reached"],
            "n": result["n"],
            "approach_goal_reached": sum(c["goal_reached"] for c in need_approach),
            "approach_n": len(need_approach),
            "retreat_goal_reached": sum(c["goal_reached"] for c in need_retreat),
            "retreat_n": len(need_retreat),
            "components_used": sorted({n for c in cases for n in c.get("components", [])}),
        }

    return {
        "sim": sim,
        "seed": seed,
        "noise": noise,
        "turn_approach": ta_result,
        "turn_approach_train_s": train_ta_s,
        "turn_approach_observations": int(ta.observations_.n_categories_),
        "figure": figure,
        "position": {**split(pos_result), "evaluation": pos_result},
        "nested_position": {**split(nested_result), "evaluation": nested_result},
        "retreat": retreat_result,
    }
