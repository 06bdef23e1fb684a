"""The thesis's simple-behavior experiments (tables 6.3 and 6.4) as one function."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
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

#: Starts of thesis figures 6.8 (turn from +100 and -100 deg) and 6.9 (approach from 0.7
#: and 0.35 m). They lie on the training grids, not among the test starts; every input
#: set is run from them, beside the teacher's demonstration from the same start.
FIGURE_STARTS: Final[dict[str, tuple[dict[str, float], ...]]] = {
    "turn": ({"angle": 100.0}, {"angle": -100.0}),
    "approach": ({"distance": 0.7}, {"distance": 0.35}),
}

#: The channel each behavior steers, drawn in its figures.
FIGURE_CHANNEL: Final[dict[str, str]] = {"turn": "angle", "approach": "distance"}


def run_simple_experiment(
    *,
    sim: str = "mujoco",
    seed: int = 0,
    noise: float = 0.0,
    configs: tuple[tuple[str, tuple[str, ...], float], ...] = SIMPLE_CONFIGS,
    sblm_params: Mapping[str, Any] | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """Collect the default datasets, train SBLM and BC per config, evaluate on the test starts.

    ``sblm_params`` are SBLM constructor parameters (e.g. ``preset_params("thesis",
    "SBLM")``) applied to every model; the default is the SBLM's defaults.

    Returns
    -------
    dict
        ``rows``: one summary per config (SBLM, BC, thesis figure, zero floor, timings);
        ``evaluations``: the full evaluation dicts; ``figure_starts``: the scores from
        the :data:`FIGURE_STARTS`; ``figures``: generated and demonstrated series per
        config (:func:`_figure_series`), ``"test_starts"`` (every test start, thesis
        appendix B.1) and ``"thesis_starts"`` (figures 6.8 and 6.9).
    """
    from behavior_hmm.models import SBLM
    from behavior_hmm.teach import collect, test_starts

    datasets = {b: collect(b, sim=sim, seed=seed) for b in sorted({c[0] for c in configs})}
    rows: list[dict[str, Any]] = []
    evaluations: list[dict[str, Any]] = []
    figures: dict[str, list[dict[str, Any]]] = {"test_starts": [], "thesis_starts": []}
    figure_starts: list[dict[str, Any]] = []
    for i, (behavior, inputs, thesis) in enumerate(configs):
        dataset = datasets[behavior]
        t0 = time.perf_counter()
        model = SBLM(**{**dict(sblm_params or {}), "inputs": inputs, "random_state": seed})
        model.fit(dataset)
        train_s = time.perf_counter() - t0
        bc = BehaviorCloning(inputs=inputs, random_state=seed).fit(dataset)
        starts = test_starts(behavior)
        result = evaluate_model(
            model,
            starts,
            sim=sim,
            seed=seed,
            noise=noise,
            baselines={"bc": bc},
            keep_traces=True,
        )
        traces = result.pop("_traces")
        figures["test_starts"].append(_figure_series(traces, behavior, inputs, result["cases"]))
        if FIGURE_STARTS.get(behavior):
            extra = evaluate_model(
                model, FIGURE_STARTS[behavior], sim=sim, seed=seed, noise=noise, keep_traces=True
            )
            series = _figure_series(extra.pop("_traces"), behavior, inputs, extra["cases"])
            figures["thesis_starts"].append(series)
            figure_starts.extend(
                {
                    "behavior": behavior,
                    "inputs": list(inputs),
                    "start": case["start"],
                    "success_rate": case["success_rate"],
                    "goal_reached": case["goal_reached"],
                }
                for case in extra["cases"]
            )
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
        "figure_starts": figure_starts,
        "figures": figures,
    }


def _figure_series(
    traces: dict[str, list[Any]],
    behavior: str,
    inputs: tuple[str, ...],
    cases: list[dict[str, Any]],
) -> dict[str, Any]:
    """The steered channel, generated and demonstrated, of every run of one config.

    Returns ``behavior``, ``inputs``, ``channel`` and ``runs``: per start (in order)
    ``start``, ``generated`` and ``demonstrated`` (arrays sampled every control period;
    the demonstration is the teacher's run from the same start), ``success_rate`` and
    ``goal_reached``.
    """
    from behavior_hmm.data import SENSOR_CHANNELS

    channel = FIGURE_CHANNEL.get(behavior, "angle")
    j = SENSOR_CHANNELS.index(channel)
    runs = []
    for (trace, demo), case in zip(traces["model"], cases, strict=True):
        runs.append(
            {
                "start": dict(trace.start),
                "generated": np.asarray(trace.reading_array[:, j], dtype=float),
                "demonstrated": np.asarray(demo[channel], dtype=float),
                "success_rate": float(case["success_rate"]),
                "goal_reached": bool(case["goal_reached"]),
            }
        )
    return {"behavior": behavior, "inputs": list(inputs), "channel": channel, "runs": runs}


#: Turn & approach starts drawn alone as the figure-6.10 analogue (indices into the test
#: starts); every test start is drawn in the appendix B.3 grid.
COMPLEX_FIGURE_STARTS: Final[tuple[int, ...]] = (13, 3)


def run_complex_experiment(
    *,
    sim: str = "mujoco",
    seed: int = 0,
    noise: float = 0.0,
    sblm_params: Mapping[str, Any] | None = None,
    cblm_params: Mapping[str, Any] | None = None,
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
    own = dict(sblm_params or {})

    def simple(inputs: tuple[str, ...], behavior: str) -> Any:
        return SBLM(**{**own, "inputs": inputs, "random_state": seed}).fit(data[behavior])

    def complex_(components: list[Any], dataset: Any) -> Any:
        params = {**dict(cblm_params or {}), "inputs": ("distance", "angle")}
        return CBLM(components, **params).fit(dataset)

    turn = simple(("angle",), "turn")
    approach = simple(("distance", "angle"), "approach")
    retreat = simple(("distance", "angle"), "retreat")
    tick()
    t0 = time.perf_counter()
    ta = complex_([turn, approach], data["turn-approach"])
    train_ta_s = time.perf_counter() - t0
    bc = BehaviorCloning(inputs=("distance", "angle"), random_state=seed).fit(data["turn-approach"])
    ta_starts = test_starts("turn-approach")
    ta_result = evaluate_model(
        ta, ta_starts, sim=sim, seed=seed, noise=noise, baselines={"bc": bc}, keep_traces=True
    )
    traces = ta_result.pop("_traces")
    figure = []
    for (trace, demo), case in zip(traces["model"], ta_result["cases"], strict=True):
        figure.append(
            {
                "start": trace.start,
                "success_rate": float(case["success_rate"]),
                "goal_reached": bool(case["goal_reached"]),
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
    position = complex_([turn, approach, retreat], data["position"])
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
    nested = complex_([ta, retreat], nested_data)
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
        "figure_highlight": list(COMPLEX_FIGURE_STARTS),
        "position": {**split(pos_result), "evaluation": pos_result},
        "nested_position": {**split(nested_result), "evaluation": nested_result},
        "retreat": retreat_result,
    }
