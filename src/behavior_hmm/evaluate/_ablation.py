"""What each departure from the thesis buys: ``experiment ablation``.

For each task (turn {angle}, approach {distance, angle}, turn & approach) the rows are:
the thesis preset; the thesis preset plus each departure alone; the default preset; the
default minus each departure (that one at its thesis value); the default plus each
option the default leaves off (thesis §7.2's future work, ``OPTIONS``: recurrent
generators), alone and without its paired departures. Only departures that touch
the task's models are listed: an SBLM task has no CBLM departures. Every row is trained
on the same demonstrations and evaluated from the task's test starts (DESIGN §6), beside
the all-zero floor.

The work runs through the project's executor (:mod:`behavior_hmm.evaluate._executor`) in
three stages of independent tasks: collect each behavior's demonstrations; fit every
distinct SBLM (an SBLM with the same parameters, data and seed is fitted once, whichever
rows and tasks use it, the turn-approach components included); then per row and seed,
fit the row's CBLM (complex task) and evaluate. Every seed comes from the run's seed and
the task's identity, so the results are the same whatever executor runs them.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate._executor import Executor, SerialExecutor
from behavior_hmm.evaluate._experiments import _collect_task, check_seeds, over_seeds
from behavior_hmm.evaluate._protocol import evaluate_model
from behavior_hmm.models._presets import (
    DEPARTURES,
    KINDS,
    OPTIONS,
    check_row_name,
    option,
    preset_params,
)

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class AblationTask:
    """A task of the ablation: a behavior, its model's inputs and the thesis's score.

    ``components`` names the simple tasks composed (empty for a simple task).
    """

    name: str
    behavior: str
    inputs: tuple[str, ...]
    thesis: float
    components: tuple[str, ...] = ()

    @property
    def kinds(self) -> tuple[str, ...]:
        """Model kinds trained for this task."""
        return ("SBLM", "CBLM") if self.components else ("SBLM",)


#: The thesis tasks of the ablation (thesis tables 6.3, 6.4 and 6.5).
ABLATION_TASKS: Final[tuple[AblationTask, ...]] = (
    AblationTask("turn", "turn", ("angle",), 90.9),
    AblationTask("approach", "approach", ("distance", "angle"), 82.6),
    AblationTask(
        "turn-approach", "turn-approach", ("distance", "angle"), 79.8, ("turn", "approach")
    ),
)


@dataclass(frozen=True)
class AblationRow:
    """One row: a preset with some departures switched to the other preset's value,
    and some options (:data:`~behavior_hmm.models._presets.OPTIONS`) on."""

    preset: str
    switched: tuple[str, ...] = ()
    options: tuple[str, ...] = ()

    @property
    def label(self) -> str:
        """``thesis``, ``thesis + onset_clock``, ``default``, ``default − onset_clock``,
        ``default + elman``, ``default − onset_clock + elman``."""
        label = self.preset
        if self.switched:
            sign = "+" if self.preset == "thesis" else "−"
            label += f" {sign} {', '.join(self.switched)}"
        if self.options:
            label += f" + {', '.join(self.options)}"
        return label

    def params(self, kind: str) -> dict[str, Any]:
        """Constructor parameters of ``kind`` in this row."""
        params = preset_params(self.preset, kind, switch=self.switched)
        for name in self.options:
            params.update(option(name).params.get(kind, {}))
        return params


def task(name: str) -> AblationTask:
    """The ablation task called ``name``."""
    for item in ABLATION_TASKS:
        if item.name == name:
            return item
    known = ", ".join(t.name for t in ABLATION_TASKS)
    raise ConfigError(f"unknown ablation task '{name}'; choose from {known}")


def ablation_rows(item: AblationTask, departures: Iterable[str] | None = None) -> list[AblationRow]:
    """The rows of ``item``: thesis, thesis + each, default, default − each, then
    default + each option (and default − d + the option, for its paired departures).

    ``departures`` restricts the single-departure and option rows to those names (all
    by default).
    """
    wanted = None if departures is None else {check_row_name(n) for n in departures}
    names = [
        d.name
        for d in DEPARTURES
        if any(k in d.kinds for k in item.kinds) and (wanted is None or d.name in wanted)
    ]
    rows = [AblationRow("thesis")]
    rows += [AblationRow("thesis", (n,)) for n in names]
    rows.append(AblationRow("default"))
    rows += [AblationRow("default", (n,)) for n in names]
    for extra in OPTIONS:
        if any(k in extra.kinds for k in item.kinds) and (wanted is None or extra.name in wanted):
            rows.append(AblationRow("default", options=(extra.name,)))
            rows += [AblationRow("default", (d,), (extra.name,)) for d in extra.paired]
    return rows


#: Row keys summarized over seeds (``seeds`` K > 1): mean and 95 % interval of each.
OVER_SEEDS_KEYS: Final[tuple[str, ...]] = ("success_rate_mean", "goal_reached")


def _frozen(params: Mapping[str, Any]) -> tuple[tuple[str, str], ...]:
    return tuple(sorted((k, repr(v)) for k, v in params.items()))


def _fit_sblm(
    inputs: tuple[str, ...], params: Mapping[str, Any], dataset: Any, seed: int
) -> tuple[Any, float]:
    """An SBLM fitted on ``dataset`` and its fitting time (wall-clock seconds)."""
    from behavior_hmm.models import SBLM

    t0 = time.perf_counter()
    # the task's inputs, unless the row's parameters choose them (inputs="auto")
    model = SBLM(**{"inputs": inputs, **params}, random_state=seed).fit(dataset)
    return model, time.perf_counter() - t0


def _fit_cblm(
    components: Sequence[Any],
    inputs: tuple[str, ...],
    params: Mapping[str, Any],
    dataset: Any,
    seed: int,
) -> tuple[Any, float]:
    """A CBLM composed of fitted ``components``, fitted on ``dataset``, and its time (s)."""
    from behavior_hmm.models import CBLM

    t0 = time.perf_counter()
    model = CBLM(list(components), **params, inputs=inputs, random_state=seed).fit(dataset)
    return model, time.perf_counter() - t0


def run_ablation(
    *,
    sim: str = "mujoco",
    seed: int = 0,
    noise: float = 0.0,
    tasks: Sequence[str] | None = None,
    departures: Iterable[str] | None = None,
    progress: Progress | None = None,
    executor: Executor | None = None,
    seeds: int = 1,
    overrides: Mapping[str, Mapping[str, Any]] | None = None,
) -> dict[str, Any]:
    """Train and evaluate every ablation row of every task.

    Parameters
    ----------
    sim, seed, noise
        Simulator backend; the run's seed (of the demonstrations, and of the first
        seed's models and evaluation); the evaluation's sensor noise (sigma × channel
        range).
    tasks
        Task names (default: all of :data:`ABLATION_TASKS`).
    departures
        Restrict the single-departure and option rows to these names (default: all; an empty
        list leaves the thesis and default rows only).
    progress
        Called with (tasks done, tasks in all): collections, SBLM fits and rows.
    executor
        Runs the tasks (default: this process, one after another).
    seeds
        K models per row: one demonstration set per behavior (collected with ``seed``),
        then each row trained and evaluated with seeds ``seed .. seed + K - 1``.
    overrides
        Constructor parameters by kind (``{"SBLM": {"epochs": 20}}``) set in every row
        over its preset and departures (e.g. shorter training for a quick check); one
        that a departure switches makes that departure's rows equal to their preset's.

    Returns
    -------
    dict
        ``sim``, ``seed``, ``noise`` and ``tasks``: per task its ``rows`` (label, preset,
        switched, success %, goals reached, zero floor, the evaluation's command-jump
        ratio median and max and its ``switches_max`` (primitive changes of an SBLM,
        component changes of a CBLM), sizes, refused goals) and the thesis's figure;
        ``timings``: ``{"train_s": {task: [[seconds per seed] per row]}}`` (wall-clock,
        kept out of results.json). With K > 1, also ``seeds``, each row's
        ``over_seeds`` (:func:`over_seeds` of :data:`OVER_SEEDS_KEYS`; the row's other
        values are the first seed's) and each task's ``per_seed_rows``. Everything but
        the timings is the same whatever the executor.
    """
    run = executor or SerialExecutor()
    seed_list = [seed + k for k in range(check_seeds(seeds))]
    extra = _check_overrides(overrides)
    chosen = [task(n) for n in (tasks or [t.name for t in ABLATION_TASKS])]
    wanted = None if departures is None else list(departures)
    plan = [(item, ablation_rows(item, wanted)) for item in chosen]

    def params(row: AblationRow, kind: str) -> dict[str, Any]:
        return {**row.params(kind), **extra.get(kind, {})}

    # Every distinct SBLM (stage 2) and row (stage 3), once each, in a fixed order: rows
    # (and tasks) whose models have the same parameters and seed share them.
    fits: dict[tuple[Any, ...], tuple[AblationTask, dict[str, Any], int]] = {}
    jobs: dict[tuple[Any, ...], tuple[AblationTask, list[tuple[Any, ...]], Any, int]] = {}
    owner: dict[tuple[str, int, int], tuple[Any, ...]] = {}
    for s in seed_list:
        for item, rows in plan:
            for j, row in enumerate(rows):
                sblm = params(row, "SBLM")
                sblm_keys = []
                for part in [task(n) for n in item.components] or [item]:
                    key = ("SBLM", part.behavior, part.inputs, _frozen(sblm), s)
                    fits.setdefault(key, (part, sblm, s))
                    sblm_keys.append(key)
                cblm = params(row, "CBLM") if item.components else None
                job = (item.name, _frozen(sblm), _frozen(cblm or {}), s)
                jobs.setdefault(job, (item, sblm_keys, cblm, s))
                owner[(item.name, j, s)] = job
    behaviors = sorted(
        {part.behavior for part, _, _ in fits.values()} | {i.behavior for i in chosen}
    )
    data_tasks = [(b, sim, seed) for b in behaviors]
    total = len(data_tasks) + len(fits) + len(jobs)
    offset = 0

    def advance(done: int, _: int) -> None:
        if progress is not None:
            progress(offset + done, total)

    # demonstrations are recorded once, with the run's seed: the same for every seed
    collected = run.map(_collect_task, data_tasks, advance)
    datasets = dict(zip(behaviors, collected, strict=True))
    offset += len(data_tasks)
    fit_tasks = [(part.inputs, p, datasets[part.behavior], s) for part, p, s in fits.values()]
    fitted = dict(zip(fits, run.map(_sblm_task, fit_tasks, advance), strict=True))
    offset += len(fit_tasks)
    row_tasks = [
        (
            item,
            [fitted[k][0] for k in sblm_keys],
            cblm,
            datasets[item.behavior] if item.components else None,
            sim,
            s,
            noise,
        )
        for item, sblm_keys, cblm, s in jobs.values()
    ]
    outcomes = dict(zip(jobs, run.map(_row_task, row_tasks, advance), strict=True))

    out: list[dict[str, Any]] = []
    train_s: dict[str, list[list[float]]] = {}
    for item, rows in plan:
        per_seed: list[list[dict[str, Any]]] = []
        seconds: list[list[float]] = [[] for _ in rows]
        for s in seed_list:
            mine = []
            for j, row in enumerate(rows):
                key = owner[(item.name, j, s)]
                outcome = outcomes[key]
                # a CBLM row's time is its CBLM's fit, an SBLM row's its SBLM's
                took = outcome["train_s"]
                seconds[j].append(took if took is not None else fitted[jobs[key][1][0]][1])
                mine.append(
                    {
                        "label": row.label,
                        "preset": row.preset,
                        "switched": list(row.switched),
                        "options": list(row.options),
                        **outcome["summary"],
                    }
                )
            per_seed.append(mine)
        entry: dict[str, Any] = {
            "task": item.name,
            "behavior": item.behavior,
            "inputs": list(item.inputs),
            "components": list(item.components),
            "thesis": item.thesis,
            "rows": per_seed[0],
        }
        if len(seed_list) > 1:
            summaries = over_seeds(per_seed, OVER_SEEDS_KEYS)
            entry["rows"] = [
                {**r, "over_seeds": o} for r, o in zip(per_seed[0], summaries, strict=True)
            ]
            entry["per_seed_rows"] = per_seed
        out.append(entry)
        train_s[item.name] = seconds
    result: dict[str, Any] = {"sim": sim, "seed": seed, "noise": noise, "tasks": out}
    if len(seed_list) > 1:
        result["seeds"] = seed_list
    result["timings"] = {"train_s": train_s}
    return result


def _check_overrides(
    overrides: Mapping[str, Mapping[str, Any]] | None,
) -> dict[str, dict[str, Any]]:
    """``overrides`` by kind, or a ConfigError naming an unknown kind or parameter."""
    from behavior_hmm.models._presets import constructor_defaults

    out: dict[str, dict[str, Any]] = {}
    for kind, values in (overrides or {}).items():
        if kind not in KINDS:
            raise ConfigError(f"unknown model kind {kind!r}; choose from {', '.join(KINDS)}")
        unknown = sorted(set(values) - set(constructor_defaults(kind)))
        if unknown:
            raise ConfigError(f"unknown {kind} parameter(s) {', '.join(unknown)}")
        out[kind] = dict(values)
    return out


def _sblm_task(task: tuple[Any, ...]) -> tuple[Any, float]:
    """Fit one SBLM: ``(inputs, params, dataset, seed)`` (an executor task)."""
    inputs, params, dataset, seed = task
    return _fit_sblm(inputs, params, dataset, seed)


def _row_task(task: tuple[Any, ...]) -> dict[str, Any]:
    """Evaluate one row of one seed (an executor task).

    ``task``: ``(item, models, cblm_params, dataset, sim, seed, noise)``. A simple task's
    ``models`` is its fitted SBLM, evaluated as it is; a complex task's are the fitted
    components of a CBLM with ``cblm_params``, fitted here on ``dataset`` first. Returns
    the row's ``summary`` and ``train_s`` (the CBLM's fitting seconds; None for an SBLM).
    """
    from behavior_hmm.teach import test_starts

    item, models, cblm_params, dataset, sim, seed, noise = task
    train_s = None
    if item.components:
        model, train_s = _fit_cblm(models, item.inputs, cblm_params, dataset, seed)
    else:
        (model,) = models
    result = evaluate_model(model, test_starts(item.behavior), sim=sim, seed=seed, noise=noise)
    summary = {
        "success_rate_mean": result["success_rate_mean"],
        "goal_reached": result["goal_reached"],
        "n": result["n"],
        "zero_floor_mean": result["zero_floor_mean"],
        "command_jump_ratio_median": result["command_jump_ratio_median"],
        "command_jump_ratio_max": result["command_jump_ratio_max"],
        # primitive changes of an SBLM, component changes of a CBLM (the evaluation's)
        "switches_max": result["switches_max"],
        "observations": int(model.observations_.n_categories_),
        "refused": sum(1 for c in result["cases"] if c["reason"].startswith("unreach")),
    }
    if not item.components:
        summary["primitives"] = int(model.primitives_.n_categories_)
    auto = [m for m in models if m.auto_inputs]
    if auto:  # the inputs each simple behavior's fit chose (inputs="auto")
        summary["chosen_inputs"] = "; ".join(
            f"{m.behavior_}: {', '.join(m.inputs_)}" if item.components else ", ".join(m.inputs_)
            for m in auto
        )
    return {"summary": summary, "train_s": train_s}
