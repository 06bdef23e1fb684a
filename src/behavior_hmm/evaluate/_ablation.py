"""What each departure from the thesis buys: ``experiment ablation``.

For each task (turn {angle}, approach {distance, angle}, turn & approach) the rows are:
the thesis preset; the thesis preset plus each departure alone; the default preset; the
default minus each departure (that one at its thesis value). Only departures that touch
the task's models are listed: an SBLM task has no CBLM departures. Every row is trained
on the same demonstrations and evaluated from the task's test starts (DESIGN §6), beside
the all-zero floor.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate._protocol import evaluate_model
from behavior_hmm.models._presets import DEPARTURES, departure, preset_params

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
    """One row: a preset with some departures switched to the other preset's value."""

    preset: str
    switched: tuple[str, ...] = ()

    @property
    def label(self) -> str:
        """``thesis``, ``thesis + onset_clock``, ``default``, ``default − onset_clock``."""
        if not self.switched:
            return self.preset
        sign = "+" if self.preset == "thesis" else "−"
        return f"{self.preset} {sign} {', '.join(self.switched)}"

    def params(self, kind: str) -> dict[str, Any]:
        """Constructor parameters of ``kind`` in this row."""
        return preset_params(self.preset, kind, switch=self.switched)


def task(name: str) -> AblationTask:
    """The ablation task called ``name``."""
    for item in ABLATION_TASKS:
        if item.name == name:
            return item
    known = ", ".join(t.name for t in ABLATION_TASKS)
    raise ConfigError(f"unknown ablation task '{name}'; choose from {known}")


def ablation_rows(item: AblationTask, departures: Iterable[str] | None = None) -> list[AblationRow]:
    """The rows of ``item``: thesis, thesis + each, default, default − each.

    ``departures`` restricts the single-departure rows to those names (all by default).
    """
    wanted = None if departures is None else {departure(n).name for n in departures}
    names = [
        d.name
        for d in DEPARTURES
        if any(k in d.kinds for k in item.kinds) and (wanted is None or d.name in wanted)
    ]
    rows = [AblationRow("thesis")]
    rows += [AblationRow("thesis", (n,)) for n in names]
    rows.append(AblationRow("default"))
    rows += [AblationRow("default", (n,)) for n in names]
    return rows


class _Models:
    """Fitted models, shared by the rows (and tasks) whose parameters are the same."""

    def __init__(self, sim: str, seed: int) -> None:
        self.sim = sim
        self.seed = seed
        self._data: dict[str, Any] = {}
        self._fitted: dict[tuple[Any, ...], tuple[Any, float]] = {}

    def data(self, behavior: str) -> Any:
        from behavior_hmm.teach import collect

        if behavior not in self._data:
            self._data[behavior] = collect(behavior, sim=self.sim, seed=self.seed)
        return self._data[behavior]

    def simple(self, item: AblationTask, params: Mapping[str, Any]) -> tuple[Any, float]:
        from behavior_hmm.models import SBLM

        key = ("SBLM", item.behavior, item.inputs, _frozen(params))
        if key not in self._fitted:
            dataset = self.data(item.behavior)
            t0 = time.perf_counter()
            model = SBLM(**params, inputs=item.inputs, random_state=self.seed).fit(dataset)
            self._fitted[key] = (model, time.perf_counter() - t0)
        return self._fitted[key]

    def complex(self, item: AblationTask, row: AblationRow) -> tuple[Any, float]:
        from behavior_hmm.models import CBLM

        components = [self.simple(task(name), row.params("SBLM"))[0] for name in item.components]
        params = row.params("CBLM")
        key = ("CBLM", item.behavior, item.inputs, _frozen(params), _frozen(row.params("SBLM")))
        if key not in self._fitted:
            dataset = self.data(item.behavior)
            t0 = time.perf_counter()
            model = CBLM(components, **params, inputs=item.inputs).fit(dataset)
            self._fitted[key] = (model, time.perf_counter() - t0)
        return self._fitted[key]


def _frozen(params: Mapping[str, Any]) -> tuple[tuple[str, str], ...]:
    return tuple(sorted((k, repr(v)) for k, v in params.items()))


def run_ablation(
    *,
    sim: str = "mujoco",
    seed: int = 0,
    noise: float = 0.0,
    tasks: Sequence[str] | None = None,
    departures: Iterable[str] | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """Train and evaluate every ablation row of every task.

    Parameters
    ----------
    sim, seed, noise
        Simulator backend, seed of the demonstrations, models and evaluation, and the
        evaluation's sensor noise (sigma × channel range).
    tasks
        Task names (default: all of :data:`ABLATION_TASKS`).
    departures
        Restrict the single-departure rows to these departures (default: all).
    progress
        Called with (rows done, rows in all).

    Returns
    -------
    dict
        ``tasks``: per task its ``rows`` (label, preset, switched, success %, goals
        reached, zero floor, sizes, training seconds) and the thesis's figure.
    """
    chosen = [task(n) for n in (tasks or [t.name for t in ABLATION_TASKS])]
    wanted = None if departures is None else list(departures)
    plan = [(item, ablation_rows(item, wanted)) for item in chosen]
    total = sum(len(rows) for _, rows in plan)
    models = _Models(sim, seed)
    done = 0
    out: list[dict[str, Any]] = []
    from behavior_hmm.teach import test_starts

    for item, rows in plan:
        starts = test_starts(item.behavior)
        results = []
        for row in rows:
            if item.components:
                model, train_s = models.complex(item, row)
            else:
                model, train_s = models.simple(item, row.params("SBLM"))
            result = evaluate_model(model, starts, sim=sim, seed=seed, noise=noise)
            entry = {
                "label": row.label,
                "preset": row.preset,
                "switched": list(row.switched),
                "success_rate_mean": result["success_rate_mean"],
                "goal_reached": result["goal_reached"],
                "n": result["n"],
                "zero_floor_mean": result["zero_floor_mean"],
                "observations": int(model.observations_.n_categories_),
                "train_s": train_s,
                "refused": sum(1 for c in result["cases"] if c["reason"].startswith("unreach")),
                # component (CBLM) or primitive-plan changes: how much the run switches
                "switches_max": max(len(c["components"]) - 1 for c in result["cases"])
                if item.components
                else max(c["plan_changes"] for c in result["cases"]),
            }
            if not item.components:
                entry["primitives"] = int(model.primitives_.n_categories_)
            results.append(entry)
            done += 1
            if progress is not None:
                progress(done, total)
        out.append(
            {
                "task": item.name,
                "behavior": item.behavior,
                "inputs": list(item.inputs),
                "components": list(item.components),
                "thesis": item.thesis,
                "rows": results,
            }
        )
    return {"sim": sim, "seed": seed, "noise": noise, "tasks": out}
