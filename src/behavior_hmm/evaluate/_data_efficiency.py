"""Data efficiency: the learning curve over nested subsets of each default grid.

``experiment data-efficiency`` trains turn {angle}, approach {distance, angle} and turn &
approach (a CBLM over those two, reading distance and angle: the tasks and inputs of
:data:`behavior_hmm.evaluate._ablation.ABLATION_TASKS`) on a fraction of each behavior's
default training grid (default 1/8, 1/4, 1/2 and all of it), beside BC and BC-strong
trained on the same subset with the same seed (:func:`fit_baselines`, as ``experiment
simple`` and ``experiment complex`` train them), and scores every model on the
behavior's 15 shipped test starts with :func:`evaluate_model` (seed: the model's seed).

Subsets
-------
Each behavior's default grid is demonstrated once (``collect(behavior, sim=sim,
seed=seed)``, the first seed). For seed ``s`` one permutation of the grid's starts is
drawn per behavior from ``np.random.default_rng(s)`` (:func:`nested_subsets`); fraction
``f`` takes the first ``max(2, ceil(f · n))`` starts of it, so at one seed the 1/8
subset lies inside the 1/4 one, and so on; fraction 1 is the whole grid (the same data
for every seed; the models still get ``random_state=s``). A subset keeps every episode
of its starts: approach's corrective copies (``collect``'s ``corrections``) come with
their nominal start. "Demonstrations" in the tables count starts (nominal episodes).

Turn & approach's components are the turn and approach SBLMs trained on the *same*
fraction and seed (each on its own grid's subset); the CBLM is fitted on turn &
approach's subset. Its training seconds are the CBLM's fit alone, as in ``experiment
complex``.

The success rate's normalization (DESIGN §6) is the largest command of the model's own
training demonstrations; a subset that misses the grid's fastest starts would score on
a smaller scale. Every cell records its ``command_scale`` so such a cell can be found
(on the default grids the fastest starts are most of the grid: turn's peak command is
reached from 24 of its 36 starts, approach's from 16 of 19).

The work runs through the project's executor in three stages of independent tasks:
collect each grid; per (fraction, seed) fit and score each simple task and fit turn &
approach's baselines; then fit and score each turn & approach CBLM. Every seed comes
from the run's seed and the task's identity, so the results are the same whatever
executor runs them; only the timings differ.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Final

import numpy as np

from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate._ablation import ABLATION_TASKS, AblationTask
from behavior_hmm.evaluate._baselines import BASELINES, fit_baselines
from behavior_hmm.evaluate._executor import Executor, SerialExecutor, map_largest_first
from behavior_hmm.evaluate._experiments import _collect_task, check_seeds
from behavior_hmm.evaluate._protocol import evaluate_model

Progress = Callable[[int, int], None]
Start = dict[str, float]

#: Fractions of each default grid trained on, smallest first.
DEFAULT_FRACTIONS: Final[tuple[float, ...]] = (0.125, 0.25, 0.5, 1.0)

#: Fewest demonstrations a subset holds, whatever the fraction.
MIN_DEMONSTRATIONS: Final[int] = 2

#: The tasks, in table order: turn {angle}, approach {distance, angle}, turn & approach.
TASKS: Final[tuple[AblationTask, ...]] = ABLATION_TASKS

#: Keys of the learners in every cell and summary row: ours, then the baselines.
LEARNERS: Final[tuple[str, ...]] = ("ours", *(n.replace("-", "_") for n in BASELINES))


def check_fractions(fractions: Sequence[float]) -> tuple[float, ...]:
    """Fractions as a sorted tuple; ConfigError unless each lies in (0, 1], once."""
    values = tuple(fractions)
    if not values:
        raise ConfigError("--fractions needs at least one fraction in (0, 1]")
    out = []
    for value in values:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"--fractions must be numbers in (0, 1], got {value!r}")
        number = float(value)
        if not (math.isfinite(number) and 0.0 < number <= 1.0):
            raise ConfigError(f"--fractions must each lie in (0, 1], got {value:g}")
        if number in out:
            raise ConfigError(f"--fractions repeats {number:g}")
        out.append(number)
    return tuple(sorted(out))


def parse_fractions(text: str) -> tuple[float, ...]:
    """``--fractions``: comma-separated numbers in (0, 1] (e.g. ``0.125,0.25,0.5,1``)."""
    values = []
    for part in text.split(","):
        try:
            values.append(float(part.strip()))
        except ValueError:
            raise ConfigError(
                f"--fractions must be comma-separated numbers in (0, 1], got {text!r}"
            ) from None
    return check_fractions(values)


def subset_size(fraction: float, n: int) -> int:
    """Starts in the ``fraction`` subset of a grid of ``n``: ``max(2, ceil(f · n))``, at most n."""
    # a hair below the product so that e.g. 0.5 · 38 stays 19 despite rounding
    return min(n, max(MIN_DEMONSTRATIONS, math.ceil(fraction * n - 1e-9)))


def nested_subsets(n: int, seed: int, fractions: Sequence[float]) -> dict[float, list[int]]:
    """Grid positions (sorted) of each fraction's subset at ``seed``; nested by construction.

    One permutation of ``range(n)`` from ``np.random.default_rng(seed)``; fraction ``f``
    takes its first :func:`subset_size` entries.
    """
    order = np.random.default_rng(seed).permutation(n)
    return {
        float(f): sorted(int(i) for i in order[: subset_size(float(f), n)])
        for f in check_fractions(fractions)
    }


def grid_subset(dataset: Any, positions: Sequence[int], n_starts: int) -> Any:
    """The episodes of the grid starts at ``positions`` (their corrective copies too).

    ``dataset`` holds ``n_starts`` nominal episodes followed by whole copies of them
    (``collect``'s ``corrections``); the metadata's ``starts`` and
    ``corrective_episodes`` are narrowed to the subset. The whole grid is ``dataset``.
    """
    if len(dataset) % n_starts:
        raise ConfigError(
            f"{len(dataset)} episodes are not whole copies of a grid of {n_starts} starts"
        )
    chosen = sorted(int(p) for p in positions)
    if chosen == list(range(n_starts)):
        return dataset
    copies = len(dataset) // n_starts
    episodes = [p + c * n_starts for c in range(copies) for p in chosen]
    part = dataset.subset(episodes)
    meta = dataset.metadata
    updates: dict[str, Any] = {}
    if isinstance(meta.get("starts"), list) and len(meta["starts"]) == n_starts:
        updates["starts"] = [meta["starts"][p] for p in chosen]
    if meta.get("corrective_episodes"):
        ids = {int(i) for i in part.episode_ids}
        updates["corrective_episodes"] = [i for i in meta["corrective_episodes"] if i in ids]
    return part.with_metadata(updates) if updates else part


def grid_command_scale(dataset: Any) -> float:
    """The largest absolute command of the nominal demonstrations: the success rate's
    normalization of a model trained on the whole grid (DESIGN §6)."""
    from behavior_hmm.models._sblm import nominal_rows

    return float(np.max(np.abs(np.asarray(dataset.commands)[nominal_rows(dataset)])))


def _stats(values: Sequence[float]) -> dict[str, Any]:
    """Mean, sample standard deviation (0 for one value), 95 % interval, min, max, values."""
    from scipy import stats

    v = np.asarray(values, dtype=np.float64)
    k = len(v)
    sd = float(v.std(ddof=1)) if k > 1 else 0.0
    t = float(stats.t.ppf(0.975, k - 1)) if k > 1 else 0.0
    return {
        "mean": float(v.mean()),
        "sd": sd,
        "ci95": t * sd / math.sqrt(k),
        "min": float(v.min()),
        "max": float(v.max()),
        "values": v.tolist(),
    }


def summarize(cells: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Per (behavior, fraction), in the cells' order: the learners' statistics over seeds.

    Returns one row per (behavior, fraction): ``behavior``, ``fraction``, ``seeds``,
    ``n_demonstrations`` (starts per subset; the same at every seed), ``n_episodes``,
    ``zero_floor`` (mean, %) and per learner present in the cells (``ours``, ``bc``,
    ``bc_strong``): ``success`` (:func:`_stats` of ``success_rate_mean``, %), ``goals``
    (of ``goal_reached``) and ``n`` (test starts).
    """
    groups: dict[tuple[str, float], list[Mapping[str, Any]]] = {}
    for cell in cells:
        groups.setdefault((cell["behavior"], float(cell["fraction"])), []).append(cell)
    rows = []
    for (behavior, fraction), mine in groups.items():
        sizes = {int(c["n_demonstrations"]) for c in mine}
        if len(sizes) != 1:
            raise ConfigError(f"{behavior} at {fraction:g}: subsets of different sizes {sizes}")
        row: dict[str, Any] = {
            "behavior": behavior,
            "fraction": fraction,
            "seeds": [int(c["seed"]) for c in mine],
            "n_demonstrations": sizes.pop(),
            "n_episodes": int(mine[0]["n_episodes"]),
            "zero_floor": float(np.mean([c["ours"]["zero_floor"] for c in mine])),
        }
        for learner in LEARNERS:
            if all(learner in c for c in mine):
                row[learner] = {
                    "success": _stats([c[learner]["success_rate_mean"] for c in mine]),
                    "goals": _stats([c[learner]["goal_reached"] for c in mine]),
                    "n": int(mine[0][learner]["n"]),
                }
        rows.append(row)
    return rows


def check_tasks(names: Sequence[str]) -> tuple[AblationTask, ...]:
    """The tasks called ``names`` in table order; a composed one needs its components."""
    known = {t.name: t for t in TASKS}
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ConfigError(f"unknown task '{unknown[0]}'; choose from {', '.join(known)}")
    chosen = tuple(t for t in TASKS if t.name in names)
    if not chosen:
        raise ConfigError("no task to run")
    for item in chosen:
        missing = [c for c in item.components if c not in names]
        if missing:
            raise ConfigError(f"task '{item.name}' needs its components: {', '.join(missing)}")
    return chosen


def run_data_efficiency_experiment(
    *,
    sim: str = "mujoco",
    seed: int = 0,
    seeds: int = 5,
    fractions: Sequence[float] = DEFAULT_FRACTIONS,
    sblm_params: Mapping[str, Any] | None = None,
    cblm_params: Mapping[str, Any] | None = None,
    bc: bool = True,
    tasks: Sequence[str] | None = None,
    starts: Mapping[str, Sequence[Mapping[str, float]]] | None = None,
    test_starts: Mapping[str, Sequence[Mapping[str, float]]] | None = None,
    progress: Progress | None = None,
    executor: Executor | None = None,
) -> dict[str, Any]:
    """Train on nested fractions of each grid, ``seeds`` times, beside BC and BC-strong.

    Parameters
    ----------
    sim
        Simulator of the demonstrations and the evaluations (``mujoco``, ``kinematic``).
    seed, seeds
        Seeds ``seed .. seed + seeds - 1``: each draws its own subsets and trains its own
        models (``random_state``) and is the seed of their evaluations. The grids are
        demonstrated once, with ``seed``.
    fractions
        Fractions of each grid in (0, 1] (:func:`check_fractions`).
    sblm_params, cblm_params
        SBLM and CBLM constructor parameters (a preset's), for every model.
    bc
        Also train and score BC and BC-strong on every subset.
    tasks
        Task names (default all of :data:`TASKS`; turn-approach needs turn and approach).
    starts
        Training grid per task (default: the behavior's default grid).
    test_starts
        Test starts per task (default: the shipped 15).
    progress
        Called as ``progress(done, total)`` as collections and cells finish.
    executor
        Runs the independent tasks (default: this process).

    Returns
    -------
    dict
        ``sim``, ``seeds``, ``fractions``, ``bc``; ``tasks``: per task ``behavior``,
        ``inputs``, ``components``, ``thesis`` (%), ``grid_size`` (starts),
        ``episodes_per_start`` and ``command_scale`` (:func:`grid_command_scale`);
        ``cells``: one per (task, fraction, seed) with
        ``n_demonstrations``, ``n_episodes``, ``n_rows``, ``grid_indices`` and ``starts``
        (the subset), and per learner (``ours``, with bc ``bc`` and ``bc_strong``)
        ``success_rate_mean`` (%), ``goal_reached`` and ``n``; ours also ``zero_floor``
        (%; the baselines share it: same references, same scale), ``command_scale``,
        ``primitives`` (a CBLM: its components' total) and ``observations``;
        ``summary``: :func:`summarize`; ``timings``: ``collect_s``
        and per cell (cells' order) each learner's training seconds. Everything but the
        timings is the same for the same arguments, whatever the executor.
    """
    from behavior_hmm.teach import default_starts
    from behavior_hmm.teach import test_starts as shipped_tests

    run = executor or SerialExecutor()
    seed_list = [seed + k for k in range(check_seeds(seeds))]
    chosen_fractions = check_fractions(fractions)
    items = check_tasks(list(tasks) if tasks is not None else [t.name for t in TASKS])
    simple = [t for t in items if not t.components]
    composed = [t for t in items if t.components]
    grids = {
        t.name: [dict(s) for s in (starts or {}).get(t.name) or default_starts(t.behavior)]
        for t in items
    }
    tests = {
        t.name: [dict(s) for s in (test_starts or {}).get(t.name) or shipped_tests(t.behavior)]
        for t in items
    }
    cases = [(f, s) for s in seed_list for f in chosen_fractions]
    stage2 = len(cases) * (len(simple) + (len(composed) if bc else 0))
    total = len(items) + stage2 + len(cases) * len(composed)
    offset = 0

    def advance(done: int, _: int) -> None:
        if progress is not None:
            progress(offset + done, total)

    # stage 1: each grid demonstrated once
    t0 = time.perf_counter()
    collected = run.map(
        _collect_grid, [(t.behavior, grids[t.name], sim, seed) for t in items], advance
    )
    collect_s = time.perf_counter() - t0
    offset += len(items)
    data = dict(zip((t.name for t in items), collected, strict=True))
    n_starts = {t.name: len(grids[t.name]) for t in items}
    subsets = {
        (t.name, s): nested_subsets(n_starts[t.name], s, chosen_fractions)
        for t in items
        for s in seed_list
    }

    def subset(name: str, f: float, s: int) -> Any:
        return grid_subset(data[name], subsets[(name, s)][f], n_starts[name])

    # stage 2: every simple task's cell; turn & approach's baselines (they need no SBLM)
    jobs: list[tuple[Any, ...]] = []
    owners: list[tuple[str, str, float, int]] = []
    for f, s in cases:
        for t in simple:
            jobs.append(
                ("simple", t.inputs, subset(t.name, f, s), tests[t.name], sim, s, sblm_params, bc)
            )
            owners.append(("simple", t.name, f, s))
        if bc:
            for t in composed:
                jobs.append(("baselines", t.inputs, subset(t.name, f, s), s))
                owners.append(("baselines", t.name, f, s))
    sizes = [float(job[2].n_samples * len(job[1])) for job in jobs]
    outcomes = map_largest_first(run, _stage_task, jobs, sizes, advance)
    offset += len(jobs)
    done = dict(zip(owners, outcomes, strict=True))

    # stage 3: turn & approach over the SBLMs of the same fraction and seed
    jobs = []
    owners = []
    for f, s in cases:
        for t in composed:
            parts = [done[("simple", c, f, s)]["model"] for c in t.components]
            baselines = done[("baselines", t.name, f, s)] if bc else None
            part = subset(t.name, f, s)
            jobs.append((t.inputs, parts, part, tests[t.name], sim, s, cblm_params, baselines))
            owners.append(("composed", t.name, f, s))
    sizes = [float(job[2].n_samples) for job in jobs]
    outcomes = map_largest_first(run, _composed_task, jobs, sizes, advance)
    done.update(zip(owners, outcomes, strict=True))

    cells: list[dict[str, Any]] = []
    cell_timings: list[dict[str, Any]] = []
    for t in items:
        kind = "composed" if t.components else "simple"
        for f in chosen_fractions:
            for s in seed_list:
                outcome = done[(kind, t.name, f, s)]
                positions = subsets[(t.name, s)][f]
                part = subset(t.name, f, s)
                cells.append(
                    {
                        "behavior": t.name,
                        "fraction": f,
                        "seed": s,
                        "n_demonstrations": len(positions),
                        "n_episodes": len(part),
                        "n_rows": int(part.n_samples),
                        "grid_indices": positions,
                        "starts": [grids[t.name][p] for p in positions],
                        **outcome["scores"],
                    }
                )
                cell_timings.append(
                    {"behavior": t.name, "fraction": f, "seed": s, **outcome["train_s"]}
                )
    if progress is not None:
        progress(total, total)
    return {
        "sim": sim,
        "seeds": seed_list,
        "fractions": list(chosen_fractions),
        "bc": bc,
        "tasks": {
            t.name: {
                "behavior": t.behavior,
                "inputs": list(t.inputs),
                "components": list(t.components),
                "thesis": t.thesis,
                "grid_size": n_starts[t.name],
                "episodes_per_start": len(data[t.name]) // n_starts[t.name],
                "command_scale": grid_command_scale(data[t.name]),
            }
            for t in items
        },
        "cells": cells,
        "summary": summarize(cells),
        "timings": {"collect_s": collect_s, "cells": cell_timings},
    }


def _collect_grid(task: tuple[str, list[Start], str, int]) -> Any:
    """One behavior's grid demonstrated (an executor task): the default grid, or starts
    given (then without corrective copies, as ``collect`` does for starts given)."""
    from behavior_hmm.teach import collect, default_starts

    behavior, grid, sim, seed = task
    if grid == [dict(s) for s in default_starts(behavior)]:
        return _collect_task((behavior, sim, seed))
    return collect(behavior, grid, sim=sim, seed=seed)


def _scores(result: Mapping[str, Any]) -> dict[str, Any]:
    """A learner's entry of a cell from its evaluation summary."""
    return {
        "success_rate_mean": float(result["success_rate_mean"]),
        "goal_reached": int(result["goal_reached"]),
        "n": int(result["n"]),
    }


def _timed_baselines(
    inputs: Sequence[str], dataset: Any, seed: int
) -> tuple[dict[str, Any], dict[str, float]]:
    """BC and BC-strong fitted as every experiment fits them, each timed."""
    fitted: dict[str, Any] = {}
    seconds: dict[str, float] = {}
    for name in BASELINES:
        t0 = time.perf_counter()
        fitted.update(fit_baselines(inputs, dataset, seed, names=(name,)))
        seconds[name.replace("-", "_")] = time.perf_counter() - t0
    return fitted, seconds


def _cell(
    model: Any,
    baselines: Mapping[str, Any] | None,
    tests: Sequence[Start],
    sim: str,
    seed: int,
    primitives: int,
) -> dict[str, Any]:
    """Score ``model`` and its baselines on the test starts: the cell's learner entries."""
    result = evaluate_model(model, tests, sim=sim, seed=seed, baselines=baselines or None)
    scale = float(result["command_scale"])
    scores: dict[str, Any] = {
        "ours": {
            **_scores(result),
            "zero_floor": float(result["zero_floor_mean"]),
            "command_scale": scale,
            "primitives": primitives,
            "observations": int(model.observations_.n_categories_),
        }
    }
    for name, base in result["baselines"].items():
        # scored against the same references on the model's scale: the same floor
        scores[name.replace("-", "_")] = _scores(base)
    return scores


def _stage_task(job: tuple[Any, ...]) -> dict[str, Any]:
    """A simple task's cell, or a composed task's baselines (an executor task)."""
    from behavior_hmm.models import SBLM

    if job[0] == "baselines":
        _, inputs, dataset, seed = job
        fitted, seconds = _timed_baselines(inputs, dataset, seed)
        return {"baselines": fitted, "train_s": seconds}
    _, inputs, dataset, tests, sim, seed, sblm_params, bc = job
    t0 = time.perf_counter()
    model = SBLM(**{**dict(sblm_params or {}), "inputs": inputs, "random_state": seed})
    model.fit(dataset)
    train_s = {"ours": time.perf_counter() - t0}
    baselines = None
    if bc:
        baselines, seconds = _timed_baselines(inputs, dataset, seed)
        train_s.update(seconds)
    primitives = int(model.primitives_.n_categories_)
    scores = _cell(model, baselines, tests, sim, seed, primitives)
    return {"model": model, "scores": scores, "train_s": train_s}


def _composed_task(job: tuple[Any, ...]) -> dict[str, Any]:
    """A composed task's cell: its CBLM over the components, fitted and scored."""
    from behavior_hmm.models import CBLM

    inputs, parts, dataset, tests, sim, seed, cblm_params, baselines = job
    t0 = time.perf_counter()
    params = {**dict(cblm_params or {}), "inputs": inputs, "random_state": seed}
    model = CBLM(list(parts), **params).fit(dataset)
    train_s = {"ours": time.perf_counter() - t0}
    fitted = None
    if baselines is not None:
        fitted = baselines["baselines"]
        train_s.update(baselines["train_s"])
    primitives = sum(int(p.primitives_.n_categories_) for p in parts)
    scores = _cell(model, fitted, tests, sim, seed, primitives)
    return {"scores": scores, "train_s": train_s}
