"""The thesis's simple-behavior experiments (tables 6.3 and 6.4) as one function."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Final

import numpy as np

from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate._baselines import BASELINES, baseline_columns, fit_baselines
from behavior_hmm.evaluate._executor import Executor, SerialExecutor, map_largest_first
from behavior_hmm.evaluate._protocol import evaluate_model
from behavior_hmm.models import AUTO_INPUTS

Progress = Callable[[int, int], None]

#: (behavior, inputs, thesis success rate %) of tables 6.3 and 6.4.
SIMPLE_CONFIGS: Final[tuple[tuple[str, tuple[str, ...], float], ...]] = (
    ("turn", ("angle",), 90.9),
    ("turn", ("angle", "angular_velocity"), 84.2),
    ("approach", ("distance",), 73.9),
    ("approach", ("distance", "angle"), 82.6),
    ("approach", ("distance", "angle", "linear_velocity"), 73.7),
)

#: The rows ``experiment simple --auto-inputs`` adds: each behavior's inputs chosen from
#: its demonstrations alone (``SBLM(inputs="auto")``, as ``train simple --inputs auto``;
#: no thesis figure: the thesis picked them by hand).
AUTO_CONFIGS: Final[tuple[tuple[str, tuple[str, ...], float], ...]] = (
    ("turn", (AUTO_INPUTS,), float("nan")),
    ("approach", (AUTO_INPUTS,), float("nan")),
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
    executor: Executor | None = None,
    seeds: int = 1,
) -> dict[str, Any]:
    """Collect the default datasets, train SBLM and BC per config, evaluate on the test starts.

    ``sblm_params`` are SBLM constructor parameters (e.g. ``preset_params("thesis",
    "SBLM")``) applied to every model; the default is the SBLM's defaults. Each config
    of each seed is one task of ``executor`` (default: this process); with ``seeds`` K
    > 1, seeds ``seed .. seed + K - 1`` each train their own models and every row also
    gets the mean and 95 % interval over them (:func:`over_seeds`).

    Returns
    -------
    dict
        ``rows``: one summary per config (SBLM, BC, thesis figure, zero floor);
        ``evaluations``: the full evaluation dicts; ``figure_starts``: the scores from
        the :data:`FIGURE_STARTS`; ``figures``: generated and demonstrated series per
        config (:func:`_figure_series`), ``"test_starts"`` (every test start, thesis
        appendix B.1) and ``"thesis_starts"`` (figures 6.8 and 6.9); ``timings``
        (training seconds, kept out of results.json); with seeds, ``seeds`` and
        ``over_seeds``. Everything but the timings is the same whatever the executor.
    """

    run = executor or SerialExecutor()
    seed_list = [seed + k for k in range(check_seeds(seeds))]
    behaviors = sorted({c[0] for c in configs})
    # demonstrations are recorded without sensor noise: the same for every seed
    data_tasks = [(b, sim, seed) for b in behaviors]
    total = len(data_tasks) + len(seed_list) * len(configs)

    def collected(done: int, _: int) -> None:
        if progress is not None:
            progress(done, total)

    datasets = dict(zip(data_tasks, run.map(_collect_task, data_tasks, collected), strict=True))
    tasks = [
        (behavior, inputs, thesis, datasets[(behavior, sim, seed)], sim, s, noise, sblm_params)
        for s in seed_list
        for behavior, inputs, thesis in configs
    ]

    def trained(done: int, _: int) -> None:
        if progress is not None:
            progress(len(data_tasks) + done, total)

    # the rows with the most training rows and inputs first: the approach {d, a, v} row
    # alone takes about a third of the work (docs/performance.md, executor)
    sizes = [float(task[3].n_samples * len(task[1])) for task in tasks]
    outcomes = map_largest_first(run, _simple_config_task, tasks, sizes, trained)
    per_seed: list[dict[str, Any]] = []
    for k, s in enumerate(seed_list):
        mine = outcomes[k * len(configs) : (k + 1) * len(configs)]
        figures: dict[str, list[dict[str, Any]]] = {"test_starts": [], "thesis_starts": []}
        for outcome in mine:
            if outcome["test_series"] is not None:
                figures["test_starts"].append(outcome["test_series"])
            if outcome["thesis_series"] is not None:
                figures["thesis_starts"].append(outcome["thesis_series"])
        per_seed.append(
            {
                "sim": sim,
                "seed": s,
                "noise": noise,
                "rows": [o["row"] for o in mine],
                "evaluations": [o["evaluation"] for o in mine],
                "figure_starts": [f for o in mine for f in o["figure_starts"]],
                "figures": figures,
                "timings": {"train_s": [o["train_s"] for o in mine]},
            }
        )
    result = per_seed[0]
    if len(seed_list) > 1:
        result = {
            **result,
            "seeds": seed_list,
            "over_seeds": over_seeds(
                [r["rows"] for r in per_seed],
                ("sblm", "sblm_goal_reached", *BASELINE_KEYS, "zero_floor"),
            ),
            "per_seed_rows": [r["rows"] for r in per_seed],
            "timings": {"train_s": [r["timings"]["train_s"] for r in per_seed]},
        }
    return result


def _collect_task(task: tuple[str, str, int]) -> Any:
    """One behavior's default demonstrations (an executor task)."""
    from behavior_hmm.teach import collect

    behavior, sim, seed = task
    return collect(behavior, sim=sim, seed=seed)


def _simple_config_task(task: tuple[Any, ...]) -> dict[str, Any]:
    """Train an SBLM and BC on one config's data and evaluate them (an executor task)."""
    from behavior_hmm.models import SBLM
    from behavior_hmm.teach import test_starts

    behavior, inputs, thesis, dataset, sim, seed, noise, sblm_params = task
    auto = tuple(inputs) == (AUTO_INPUTS,)  # chosen by the fit from the demonstrations
    t0 = time.perf_counter()
    names = AUTO_INPUTS if auto else inputs
    model = SBLM(**{**dict(sblm_params or {}), "inputs": names, "random_state": seed})
    model.fit(dataset)
    train_s = time.perf_counter() - t0
    inputs = model.inputs_
    choice = model.provenance_["inputs_selection"] if auto else None
    baselines = fit_baselines(inputs, dataset, seed)
    result = evaluate_model(
        model,
        test_starts(behavior),
        sim=sim,
        seed=seed,
        noise=noise,
        baselines=baselines,
        keep_traces=True,
    )
    traces = result.pop("_traces")
    # an auto row's runs repeat a hand-picked row's inputs: the figures draw those once
    test_series = None if choice else _figure_series(traces, behavior, inputs, result["cases"])
    thesis_series = None
    figure_starts: list[dict[str, Any]] = []
    if FIGURE_STARTS.get(behavior) and choice is None:
        extra = evaluate_model(
            model, FIGURE_STARTS[behavior], sim=sim, seed=seed, noise=noise, keep_traces=True
        )
        thesis_series = _figure_series(extra.pop("_traces"), behavior, inputs, extra["cases"])
        figure_starts = [
            {
                "behavior": behavior,
                "inputs": list(inputs),
                "start": case["start"],
                "success_rate": case["success_rate"],
                "goal_reached": case["goal_reached"],
            }
            for case in extra["cases"]
        ]
    row = {
        "behavior": behavior,
        "inputs": list(inputs),
        "thesis": thesis,
        "sblm": result["success_rate_mean"],
        "sblm_goal_reached": result["goal_reached"],
        **baseline_columns(result),
        "zero_floor": result["zero_floor_mean"],
        "sblm_motor_max": result["success_rate_motor_max_mean"],
        "zero_floor_motor_max": result["zero_floor_motor_max_mean"],
        "n": result["n"],
        "primitives": int(model.primitives_.n_categories_),
        "observations": int(model.observations_.n_categories_),
    }
    if choice is not None:
        row["chosen"] = True
        row["reason"] = choice
    return {
        "row": row,
        "evaluation": result,
        "test_series": test_series,
        "thesis_series": thesis_series,
        "figure_starts": figure_starts,
        "train_s": train_s,
    }


#: Row keys of the baselines (``bc``, ``bc_goal_reached``, ``bc_strong``, ...).
BASELINE_KEYS: Final[tuple[str, ...]] = tuple(
    f"{name.replace('-', '_')}{suffix}" for name in BASELINES for suffix in ("", "_goal_reached")
)


def check_seeds(seeds: int) -> int:
    """Refuse a seed count below 1 (``--seeds``)."""
    if isinstance(seeds, bool) or not isinstance(seeds, int) or not 1 <= seeds <= 1000:
        raise ConfigError(f"--seeds must be an integer in [1, 1000], got {seeds!r}")
    return seeds


def over_seeds(
    rows_per_seed: Sequence[Sequence[Mapping[str, Any]]], keys: Sequence[str]
) -> list[dict[str, Any]]:
    """Mean and 95 % interval (Student's t) of each row's ``keys`` over the seeds.

    Returns one dict per row: ``{key: {"mean", "ci95", "min", "max", "values"}}``; the
    interval is ``mean ± t(0.975, K-1) · sd / sqrt(K)``.
    """
    from scipy import stats

    k = len(rows_per_seed)
    t = float(stats.t.ppf(0.975, k - 1)) if k > 1 else 0.0
    out = []
    for j in range(len(rows_per_seed[0])):
        summary: dict[str, Any] = {}
        for key in keys:
            values = np.array([float(rows[j][key]) for rows in rows_per_seed])
            sd = float(values.std(ddof=1)) if k > 1 else 0.0
            summary[key] = {
                "mean": float(values.mean()),
                "ci95": t * sd / np.sqrt(k),
                "min": float(values.min()),
                "max": float(values.max()),
                "values": values.tolist(),
            }
        out.append(summary)
    return out


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
    executor: Executor | None = None,
    seeds: int = 1,
) -> dict[str, Any]:
    """Thesis table 6.5 and beyond: turn & approach, position, and a nested composition.

    Components are trained once (turn on {angle}, approach and retreat on {distance,
    angle}, the thesis's best inputs) and composed without retraining: turn & approach
    (thesis table 6.5, with a behavior-cloning baseline trained on the same complex
    demonstrations), *position* over {turn, approach, retreat} on the 30 position test
    starts, and *position* again as a CBLM whose components are the turn & approach CBLM
    and retreat (a CBLM inside a CBLM). Collecting, training the components and the four
    evaluations are tasks of ``executor``; with ``seeds`` K > 1 each seed trains its own
    components and turn & approach, whose row gets its mean and 95 % interval
    (``over_seeds``); position, nesting and retreat are run for the first seed.
    """
    run = executor or SerialExecutor()
    seed_list = [seed + k for k in range(check_seeds(seeds))]
    behaviors = ("turn", "approach", "retreat", "turn-approach", "position")
    # demonstrations are recorded without sensor noise: the same for every seed
    data_tasks = [(b, sim, seed) for b in behaviors]
    parts = ("turn_approach", "position", "nested_position", "retreat")
    total = len(data_tasks) + 3 * len(seed_list) + len(parts) + len(seed_list) - 1
    offset = 0

    def advance(done: int, _: int) -> None:
        if progress is not None:
            progress(offset + done, total)

    datasets = dict(zip(data_tasks, run.map(_collect_task, data_tasks, advance), strict=True))
    offset += len(data_tasks)
    component_tasks = [
        (inputs, datasets[(behavior, sim, seed)], s, sblm_params)
        for s in seed_list
        for behavior, inputs in _COMPONENTS
    ]
    trained = run.map(_component_task, component_tasks, advance)
    offset += len(component_tasks)
    # every part for the first seed; the other seeds repeat the headline row (turn &
    # approach), which the interval over seeds is reported for
    tasks, owners = [], []
    for k, s in enumerate(seed_list):
        turn, approach, retreat = trained[3 * k : 3 * k + 3]
        data = {b: datasets[(b, sim, seed)] for b in behaviors}
        for part in parts if k == 0 else parts[:1]:
            tasks.append((part, turn, approach, retreat, data, sim, s, noise, cblm_params))
            owners.append((k, part))
    outcomes = run.map(_complex_part_task, tasks, advance)
    mine_by_seed: list[dict[str, Any]] = [{} for _ in seed_list]
    for (k, part), outcome in zip(owners, outcomes, strict=True):
        mine_by_seed[k][part] = outcome
    per_seed = []
    for k, s in enumerate(seed_list):
        mine = mine_by_seed[k]
        ta = mine["turn_approach"]
        entry = {
            "sim": sim,
            "seed": s,
            "noise": noise,
            "turn_approach": ta["evaluation"],
            "turn_approach_observations": ta["observations"],
            "figure": ta["figure"],
            "figure_highlight": list(COMPLEX_FIGURE_STARTS),
            "timings": {"turn_approach_train_s": ta["train_s"]},
        }
        for part in parts[1:]:
            if part in mine:
                entry[part] = mine[part]["evaluation"]
        per_seed.append(entry)
    result = per_seed[0]
    if len(seed_list) > 1:
        rows = [[_complex_row(r)] for r in per_seed]
        result = {
            **result,
            "seeds": seed_list,
            "over_seeds": over_seeds(
                rows, ("cblm", "cblm_goal_reached", *BASELINE_KEYS, "zero_floor")
            ),
            "per_seed_rows": rows,
            "timings": {
                "turn_approach_train_s": [r["timings"]["turn_approach_train_s"] for r in per_seed]
            },
        }
    return result


#: The components every complex behavior is composed of: (behavior, inputs).
_COMPONENTS: Final[tuple[tuple[str, tuple[str, ...]], ...]] = (
    ("turn", ("angle",)),
    ("approach", ("distance", "angle")),
    ("retreat", ("distance", "angle")),
)


def _component_task(task: tuple[Any, ...]) -> Any:
    """One component SBLM (an executor task)."""
    from behavior_hmm.models import SBLM

    inputs, dataset, seed, sblm_params = task
    return SBLM(**{**dict(sblm_params or {}), "inputs": inputs, "random_state": seed}).fit(dataset)


def _complex_row(result: Mapping[str, Any]) -> dict[str, Any]:
    """The turn & approach row of one seed (for :func:`over_seeds`)."""
    ta = result["turn_approach"]
    return {
        "cblm": ta["success_rate_mean"],
        "cblm_goal_reached": ta["goal_reached"],
        **baseline_columns(ta),
        "zero_floor": ta["zero_floor_mean"],
    }


def _turn_approach(turn: Any, approach: Any, data: Any, cblm_params: Any) -> Any:
    from behavior_hmm.models import CBLM

    params = {**dict(cblm_params or {}), "inputs": ("distance", "angle")}
    return CBLM([turn, approach], **params).fit(data["turn-approach"])


def _complex_part_task(task: tuple[Any, ...]) -> dict[str, Any]:
    """One evaluation of the complex experiment (an executor task)."""
    from behavior_hmm.data import Dataset
    from behavior_hmm.models import CBLM
    from behavior_hmm.teach import test_starts

    part, turn, approach, retreat, data, sim, seed, noise, cblm_params = task
    params = {**dict(cblm_params or {}), "inputs": ("distance", "angle")}
    if part == "retreat":
        result = evaluate_model(retreat, test_starts("retreat"), sim=sim, seed=seed)
        return {"evaluation": result}
    if part == "turn_approach":
        t0 = time.perf_counter()
        ta = _turn_approach(turn, approach, data, cblm_params)
        train_s = time.perf_counter() - t0
        baselines = fit_baselines(("distance", "angle"), data["turn-approach"], seed)
        result = evaluate_model(
            ta,
            test_starts("turn-approach"),
            sim=sim,
            seed=seed,
            noise=noise,
            baselines=baselines,
            keep_traces=True,
        )
        traces = result.pop("_traces")
        figure = []
        for (trace, demo), case in zip(traces["model"], result["cases"], strict=True):
            figure.append(
                {
                    "start": trace.start,
                    "success_rate": float(case["success_rate"]),
                    "goal_reached": bool(case["goal_reached"]),
                    "t": np.asarray(trace.t, dtype=float),
                    "angle": trace.channel("angle"),
                    "distance": trace.channel("distance"),
                    "component": list(trace.component),
                    "demo_angle": np.asarray(demo["angle"]),
                    "demo_distance": np.asarray(demo["distance"]),
                    "demo_behavior": list(demo["behavior"]),
                }
            )
        return {
            "evaluation": result,
            "figure": figure,
            "train_s": train_s,
            "observations": int(ta.observations_.n_categories_),
        }
    pos_starts = test_starts("position")
    if part == "position":
        position = CBLM([turn, approach, retreat], **params).fit(data["position"])
        result = evaluate_model(position, pos_starts, sim=sim, seed=seed, noise=noise)
        return {"evaluation": _split(result)}
    # A CBLM as a component: relabel the position demonstrations' turn/approach rows as
    # the turn & approach CBLM, and compose it with retreat.
    ta = _turn_approach(turn, approach, data, cblm_params)
    relabelled = []
    for episode in data["position"].episodes():
        cols = episode.to_dict()
        tags = np.asarray(cols["behavior"], dtype=object)
        cols["behavior"] = np.where(tags == "retreat", "retreat", "turn-approach")
        relabelled.append(cols)
    nested_data = Dataset.from_episodes(relabelled, metadata=data["position"].metadata)
    nested = CBLM([ta, retreat], **params).fit(nested_data)
    result = evaluate_model(nested, pos_starts, sim=sim, seed=seed, noise=noise)
    return {"evaluation": _split(result)}


def _split(result: dict[str, Any]) -> dict[str, Any]:
    """A position evaluation's summary, split into the starts needing approach or retreat."""
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
        "evaluation": result,
    }
