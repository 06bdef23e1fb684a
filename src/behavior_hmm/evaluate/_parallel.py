"""Parallel behaviors (thesis §7.2): ``experiment parallel``.

"While a robot is turning to an object, it can also approach to object in parallel."
The experiment compares, on turn & approach's 15 shipped test starts:

- ``sequential``: the turn & approach CBLM of the sequential teacher's demonstrations
  (turn, then approach), scored against that teacher;
- ``parallel``: a CBLM over the same turn and approach components, fitted on the
  parallel teacher's demonstrations (``collect turn-approach-parallel``: it turns while
  it drives) with ``parallel=True``, scored against the parallel teacher;
- ``parallel, one at a time``: the same model with ``parallel=False`` (the thesis's
  execution), against the same teacher: what running the two at once buys;

and the two teachers themselves. For every run: the thesis's success rate beside its
all-zero floor, goals reached, the time to goal (control cycles × period, s) and the
path length (m, from the simulator's pose). The headline is the median over the starts
of the parallel run's time over the sequential run's.

Each seed trains its own components (turn {angle}, approach {distance, angle}) and
CBLMs on one set of demonstrations (collected with the run's seed); the seeds' runs are
independent executor tasks, so the results are the same whatever executor runs them.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any, Final

import numpy as np

from behavior_hmm.evaluate._executor import Executor, SerialExecutor
from behavior_hmm.evaluate._experiments import _collect_task, check_seeds, over_seeds
from behavior_hmm.evaluate._protocol import evaluate_model

Progress = Callable[[int, int], None]

#: The behaviors demonstrated: the components, then the two composites.
BEHAVIORS: Final[tuple[str, ...]] = ("turn", "approach", "turn-approach", "turn-approach-parallel")

#: The rows, in table order: (key, label).
ROWS: Final[tuple[tuple[str, str], ...]] = (
    ("sequential", "sequential turn & approach (CBLM)"),
    ("parallel", "parallel turn & approach (CBLM, parallel=True)"),
    ("one_at_a_time", "parallel demonstrations, one at a time (parallel=False)"),
)

#: Keys summarized over seeds.
SUMMARY_KEYS: Final[tuple[str, ...]] = (
    "success_rate_mean",
    "goal_reached",
    "time_median_s",
    "time_ratio_median",
)


def path_length(pose: np.ndarray) -> float:
    """Length (m) of the path through the poses' ``x``, ``y`` columns."""
    xy = np.asarray(pose, dtype=np.float64)[:, :2]
    return float(np.sum(np.hypot(*np.diff(xy, axis=0).T))) if len(xy) > 1 else 0.0


def _row(result: Mapping[str, Any], period: float) -> dict[str, Any]:
    """One row's figures from an :func:`evaluate_model` result (with its traces)."""
    cases = []
    for case, (trace, reference) in zip(result["cases"], result["_traces"]["model"], strict=True):
        tags = np.asarray(reference["behavior"]).astype(str)
        cases.append(
            {
                "start": case["start"],
                "success_rate": case["success_rate"],
                "goal_reached": case["goal_reached"],
                "time_s": case["steps"] * period,
                "teacher_time_s": case["reference_steps"] * period,
                # the teacher's time turning alone (rows tagged ``turn``)
                "teacher_turn_s": int(np.count_nonzero(tags == "turn")) * period,
                "path_m": path_length(trace.pose_array),
                # the path drawn in the figure: every 8th pose (x, y in m)
                "xy": np.round(trace.pose_array[::8, :2], 4).tolist(),
            }
        )
    times = [c["time_s"] for c in cases]
    return {
        "success_rate_mean": result["success_rate_mean"],
        "goal_reached": result["goal_reached"],
        "zero_floor_mean": result["zero_floor_mean"],
        "n": result["n"],
        "time_median_s": float(np.median(times)),
        "time_total_s": float(np.sum(times)),
        "teacher_time_median_s": float(np.median([c["teacher_time_s"] for c in cases])),
        "teacher_time_total_s": float(np.sum([c["teacher_time_s"] for c in cases])),
        "path_median_m": float(np.median([c["path_m"] for c in cases])),
        "cases": cases,
    }


def _without_paths(row: Mapping[str, Any]) -> dict[str, Any]:
    """``row`` with its cases' drawn paths (``xy``) left out."""
    cases = [{k: v for k, v in case.items() if k != "xy"} for case in row["cases"]]
    return {**row, "cases": cases}


def _seed_task(task: tuple[Any, ...]) -> dict[str, Any]:
    """Fit one seed's components and CBLMs and score every row (an executor task)."""
    from behavior_hmm.models import CBLM, SBLM
    from behavior_hmm.teach import test_starts

    datasets, sim, seed, sblm_params, cblm_params = task
    t0 = time.perf_counter()
    turn = SBLM(**sblm_params, inputs=("angle",), random_state=seed).fit(datasets["turn"])
    approach = SBLM(**sblm_params, inputs=("distance", "angle"), random_state=seed).fit(
        datasets["approach"]
    )
    params = {**cblm_params, "inputs": ("distance", "angle"), "random_state": seed}
    sequential = CBLM([turn, approach], **params).fit(datasets["turn-approach"])
    parallel = CBLM([turn, approach], **{**params, "parallel": True}).fit(
        datasets["turn-approach-parallel"]
    )
    alone = CBLM([turn, approach], **{**params, "parallel": False}).fit(
        datasets["turn-approach-parallel"]
    )
    train_s = time.perf_counter() - t0
    starts = test_starts("turn-approach")
    period = float(datasets["turn-approach"].metadata.get("control_period", 0.016))
    rows: dict[str, Any] = {}
    models = {"sequential": sequential, "parallel": parallel, "one_at_a_time": alone}
    for key, model in models.items():
        result = evaluate_model(model, starts, sim=sim, seed=seed, keep_traces=True)
        rows[key] = _row(result, period)
    base = [c["time_s"] for c in rows["sequential"]["cases"]]
    for key in ("sequential", "parallel", "one_at_a_time"):
        ratios = [c["time_s"] / b for c, b in zip(rows[key]["cases"], base, strict=True)]
        rows[key]["time_ratio_median"] = float(np.median(ratios))
        rows[key]["time_ratio_total"] = rows[key]["time_total_s"] / float(np.sum(base))
    rows["parallel_categories"] = int(np.count_nonzero(parallel.parallel_ >= 0))
    rows["observation_categories"] = int(parallel.parallel_.shape[0])
    rows["directions"] = parallel.directions_.round(4).tolist()
    rows["train_s"] = train_s
    return rows


def run_parallel_experiment(
    *,
    sim: str = "mujoco",
    seed: int = 0,
    seeds: int = 1,
    sblm_params: Mapping[str, Any] | None = None,
    cblm_params: Mapping[str, Any] | None = None,
    executor: Executor | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """Sequential against parallel turn & approach, and the two teachers.

    Parameters
    ----------
    sim, seed
        Simulator backend; the demonstrations' seed and the first model seed.
    seeds
        K model seeds ``seed .. seed + K - 1`` (one demonstration set).
    sblm_params, cblm_params
        Constructor parameters of the components and the CBLMs (a preset's); the
        ``parallel`` of the rows overrides the CBLM's.
    executor, progress
        Runs the tasks (collections, then one task per seed); called with (done, total).

    Returns
    -------
    dict
        ``sim``, ``seed``, ``seeds``, ``rows`` (the first seed's, per row key: success,
        goals, floor, time and path medians and totals, the time ratio to the sequential
        run, per-case figures), ``over_seeds`` (per row, :data:`SUMMARY_KEYS` over the
        seeds), ``per_seed`` and ``timings`` (training seconds per seed; kept out of
        results.json).
    """
    run = executor or SerialExecutor()
    seed_list = [seed + k for k in range(check_seeds(seeds))]
    total = len(BEHAVIORS) + len(seed_list)

    def advance(offset: int) -> Callable[[int, int], None]:
        return lambda done, _: progress(offset + done, total) if progress else None

    collected = run.map(_collect_task, [(b, sim, seed) for b in BEHAVIORS], advance(0))
    datasets = dict(zip(BEHAVIORS, collected, strict=True))
    tasks = [
        (datasets, sim, s, dict(sblm_params or {}), dict(cblm_params or {})) for s in seed_list
    ]
    per_seed = run.map(_seed_task, tasks, advance(len(BEHAVIORS)))
    keys = [key for key, _ in ROWS]
    summaries = over_seeds([[seed_rows[k] for k in keys] for seed_rows in per_seed], SUMMARY_KEYS)
    first = per_seed[0]
    return {
        "sim": sim,
        "seed": seed,
        "seeds": seed_list,
        "rows": {k: first[k] for k in keys},
        "labels": dict(ROWS),
        "over_seeds": dict(zip(keys, summaries, strict=True)),
        "parallel_categories": first["parallel_categories"],
        "observation_categories": first["observation_categories"],
        "directions": first["directions"],
        # the paths are drawn from the first seed only: the other seeds' cases without them
        "per_seed": [{k: _without_paths(s[k]) for k in keys} for s in per_seed],
        "timings": {"train_s": [s["train_s"] for s in per_seed]},
    }
