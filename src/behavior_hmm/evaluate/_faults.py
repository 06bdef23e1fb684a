"""Fault sweep: how the learned behaviors ride out sensor and actuator faults.

``experiment faults`` trains the default-preset models of the ablation tasks (turn on
{angle}, approach on {distance, angle}, turn & approach as a CBLM over those two) on the
default grids, exactly as :mod:`behavior_hmm.evaluate._ablation` does, and evaluates them
from the 15 test starts of each task under one fault at a time:

* ``noise``: sensor noise sigma (× each channel's range), the env's ``noise`` option;
* ``wheel_mismatch``: the motors' relative gain mismatch (trained at 0.01);
* ``motor_lag``: the wheels' first-order time constant in s (trained at 0.03);
* ``speed_limit``: the largest wheel speed in rad/s (trained at 10);
* ``push_bearing`` / ``push_distance``: one push of +30° bearing / +0.05 m distance at
  25, 50 or 75 % of the teacher's duration from the same start;
* ``dropout``: NaN on one read channel (:class:`NaNDropout`): once, a 5- or 10-step
  burst (both at half the teacher's duration), or 1 % of the readings at random.

Every cell is scored against the same undisturbed teacher demonstration as the no-fault
evaluation (``evaluate_model(env=...)``), so its success rate measures how far the
commands move away from the nominal ones.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

import gymnasium
import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data import SENSOR_CHANNELS
from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate._ablation import (
    ABLATION_TASKS,
    AblationRow,
    AblationTask,
    _fit_cblm,
    _sblm_task,
)
from behavior_hmm.evaluate._ablation import task as ablation_task
from behavior_hmm.evaluate._executor import Executor, SerialExecutor
from behavior_hmm.evaluate._experiments import _collect_task
from behavior_hmm.evaluate._protocol import evaluate_model
from behavior_hmm.models._presets import departure, option

Progress = Callable[[int, int], None]
Level = float | str

#: Size of the pushes: bearing (deg) and distance (m).
PUSH_ANGLE_DEG: Final[float] = 30.0
PUSH_DISTANCE_M: Final[float] = 0.05
#: Where single and burst dropouts start: this fraction of the teacher's duration.
DROPOUT_AT: Final[float] = 0.5


class NaNDropout(gymnasium.ObservationWrapper[Any, Any, Any]):
    """Replace one sensor channel of the observation by NaN at chosen readings.

    Readings are counted per episode: 0 is the one ``reset`` returns, ``k`` the one the
    ``k``-th ``step`` returns.

    Parameters
    ----------
    env
        A ``behavior_hmm.sim`` env (or a wrapper of one).
    channel
        The channel to drop (one of ``SENSOR_CHANNELS``).
    steps
        Readings that are NaN on ``channel`` (change with :meth:`schedule`).
    fraction
        Probability that any reading after the first (k >= 1) is NaN on ``channel``,
        drawn independently per reading. The generator is re-seeded from
        ``(seed, reset seed)`` at every seeded reset, so a seeded episode always drops
        the same readings.
    seed
        Seed of those draws.

    Attributes
    ----------
    injected
        Readings of the current episode that were made NaN.
    episodes
        ``injected`` of every episode so far (one list per reset, the current one last).
    """

    def __init__(
        self,
        env: Any,
        channel: str,
        *,
        steps: Iterable[int] = (),
        fraction: float = 0.0,
        seed: int = 0,
    ) -> None:
        super().__init__(env)
        if channel not in SENSOR_CHANNELS:
            raise ConfigError(
                f"unknown channel '{channel}'; choose from {', '.join(SENSOR_CHANNELS)}"
            )
        if not 0.0 <= float(fraction) <= 1.0:
            raise ConfigError(f"dropout fraction must lie in [0, 1], got {fraction}")
        self.channel = channel
        self._j = SENSOR_CHANNELS.index(channel)
        self.fraction = float(fraction)
        self.seed = int(seed)
        self._steps: frozenset[int] = frozenset()
        self.schedule(steps)
        self._rng = np.random.default_rng(self.seed)
        self._k = 0
        self.injected: list[int] = []
        self.episodes: list[list[int]] = []

    def schedule(self, steps: Iterable[int]) -> None:
        """Set the readings that are NaN (replaces the previous schedule)."""
        out = set()
        for step in steps:
            if isinstance(step, bool) or not isinstance(step, int | np.integer) or step < 0:
                raise ConfigError(f"dropout steps must be integers >= 0, got {step!r}")
            out.add(int(step))
        self._steps = frozenset(out)

    @property
    def steps(self) -> frozenset[int]:
        """The scheduled readings."""
        return self._steps

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset the env and start counting readings (re-seeding the draws if seeded)."""
        if seed is not None:
            self._rng = np.random.default_rng([self.seed, int(seed)])
        self._k = 0
        self.injected = []
        self.episodes.append(self.injected)
        return super().reset(seed=seed, options=options)

    def observation(self, observation: Any) -> NDArray[np.float64]:
        """The reading, NaN on the channel when scheduled or drawn."""
        k = self._k
        self._k += 1
        drop = k in self._steps
        if self.fraction > 0.0 and k >= 1:
            drop = bool(self._rng.random() < self.fraction) or drop
        out = np.array(observation, dtype=np.float64)
        if drop:
            out[self._j] = np.nan
            self.injected.append(k)
        return out


@dataclass(frozen=True)
class FaultKind:
    """One kind of fault of the sweep and the levels it is measured at."""

    name: str
    title: str
    unit: str
    levels: tuple[Level, ...]
    nominal: Level | None = None


#: The fault kinds, in the order of the tables and figures.
FAULTS: Final[tuple[FaultKind, ...]] = (
    FaultKind("noise", "sensor noise", "σ × channel range", (0.0, 0.005, 0.01, 0.02), 0.0),
    FaultKind(
        "wheel_mismatch", "wheel mismatch", "relative gain", (-0.2, 0.0, 0.1, 0.2, 0.4), 0.01
    ),
    FaultKind("motor_lag", "motor lag", "time constant, s", (0.01, 0.05, 0.1, 0.2, 0.3), 0.03),
    FaultKind("speed_limit", "wheel-speed limit", "rad/s", (5.0, 3.0, 2.0, 1.0, 0.5), 10.0),
    FaultKind(
        "push_bearing", f"push +{PUSH_ANGLE_DEG:g}° bearing", "at % of the demo", (0.25, 0.5, 0.75)
    ),
    FaultKind(
        "push_distance",
        f"push +{PUSH_DISTANCE_M:g} m distance",
        "at % of the demo",
        (0.25, 0.5, 0.75),
    ),
    FaultKind(
        "dropout", "NaN dropout", "on the steered channel", ("single", "burst5", "burst10", "1%")
    ),
)

#: The channel each task's dropouts hit: the one it steers (read by its model).
DROPOUT_CHANNEL: Final[dict[str, str]] = {
    "turn": "angle",
    "approach": "distance",
    "turn-approach": "distance",
}

#: RobotParams field set by each physical fault.
_PARAM_OF: Final[dict[str, str]] = {
    "wheel_mismatch": "wheel_mismatch",
    "motor_lag": "motor_time_constant",
    "speed_limit": "max_wheel_speed",
}


def fault_kind(name: str) -> FaultKind:
    """The fault kind called ``name``."""
    for kind in FAULTS:
        if kind.name == name:
            return kind
    known = ", ".join(k.name for k in FAULTS)
    raise ConfigError(f"unknown fault '{name}'; choose from {known}")


def parse_level(text: str) -> tuple[str, Level]:
    """A fault level written ``KIND=VALUE`` (``--level motor_lag=0.25``), checked.

    Numbers for the physical faults (checked as :class:`~behavior_hmm.sim.RobotParams`
    checks them), noise (>= 0) and pushes (a fraction of the teacher's duration in
    (0, 1)); a dropout level is one of its kind's names.
    """
    from behavior_hmm.sim import RobotParams
    from behavior_hmm.sim._options import check_noise, number

    name, sep, value = text.partition("=")
    if not sep or not value.strip():
        raise ConfigError(f"a fault level is KIND=VALUE, e.g. motor_lag=0.25, got {text!r}")
    kind = fault_kind(name.strip())
    value = value.strip()
    if kind.name == "dropout":
        if value not in kind.levels:
            known = ", ".join(str(v) for v in kind.levels)
            raise ConfigError(f"unknown dropout level {value!r}; choose {known}")
        return kind.name, value
    what = f"the {kind.name} level"
    try:
        parsed = float(value)
    except ValueError:
        raise ConfigError(f"{what} must be a number, got {value!r}") from None
    if kind.name == "noise":
        return kind.name, check_noise(parsed, what)  # as every simulated robot checks it
    level = number(parsed, what)  # finite
    if kind.name in _PARAM_OF:
        RobotParams(**{_PARAM_OF[kind.name]: level})  # its own checks (ConfigError)
    elif kind.name.startswith("push_") and not 0.0 < level < 1.0:
        raise ConfigError(f"a push level is a fraction of the teacher's run in (0, 1), got {value}")
    return kind.name, level


def level_label(kind: str, level: Level) -> str:
    """How a level is written in tables and figures."""
    if kind.startswith("push_"):
        return f"{100 * float(level):.0f} %"
    if kind == "dropout":
        return {
            "burst5": "5-step burst",
            "burst10": "10-step burst (> hold)",
            "1%": "1 % of steps",
        }.get(str(level), str(level))
    return f"{float(level):g}"


def _dropout_env(env: Any, level: Level, channel: str, seed: int) -> tuple[NaNDropout, Any]:
    """The wrapped env of a dropout level and the case hook that schedules it."""
    if level == "1%":
        return NaNDropout(env, channel, fraction=0.01, seed=seed), None
    lengths = {"single": 1, "burst5": 5, "burst10": 10}
    if level not in lengths:
        raise ConfigError(f"unknown dropout level '{level}'; choose single, burst5, burst10, 1%")
    length = lengths[str(level)]
    wrapped = NaNDropout(env, channel, seed=seed)

    def hook(i: int, start: dict[str, float], reference: dict[str, np.ndarray]) -> dict[str, Any]:
        at = max(1, round(DROPOUT_AT * len(reference["t"])))
        wrapped.schedule(range(at, at + length))
        return {}

    return wrapped, hook


def evaluate_fault(
    model: Any,
    starts: Sequence[Mapping[str, float]],
    kind: str,
    level: Level,
    *,
    sim: str = "mujoco",
    seed: int = 0,
    channel: str = "angle",
) -> dict[str, Any]:
    """Evaluate ``model`` from ``starts`` under one fault (see :data:`FAULTS`).

    ``channel`` is the channel a ``dropout`` hits. Returns the cell: ``fault``,
    ``level``, ``label``, ``goal_reached``, ``n``, ``success_rate_mean``,
    ``zero_floor_mean``, ``reasons`` (how the runs ended), ``applied`` (runs still going
    when the push or dropout came; None for the other kinds) and ``cases`` (per start:
    goal reached, success rate, reason, final errors).
    """
    from behavior_hmm.sim import RobotParams, make_env

    fault_kind(kind)
    applied: list[bool] | None = None
    if kind == "noise":
        result = evaluate_model(model, starts, sim=sim, seed=seed, noise=float(level))
    elif kind in _PARAM_OF:
        params = RobotParams(**{_PARAM_OF[kind]: float(level)})
        env = make_env(sim, params=params)
        result = evaluate_model(model, starts, sim=sim, seed=seed, env=env)
    elif kind.startswith("push_"):
        fraction = float(level)
        push_steps: list[int] = []

        def push(i: int, start: dict[str, float], reference: dict[str, np.ndarray]) -> Any:
            step = max(1, round(fraction * len(reference["t"])))
            push_steps.append(step)
            size = (
                {"angle": PUSH_ANGLE_DEG}
                if kind == "push_bearing"
                else {"distance": PUSH_DISTANCE_M}
            )
            return {"pushes": [{"step": step, **size}]}

        result = evaluate_model(model, starts, sim=sim, seed=seed, case_options=push)
        # the push happens after env step `step`; a run ends with one stop step
        applied = [c["steps"] >= s for c, s in zip(result["cases"], push_steps, strict=True)]
    else:
        wrapped, hook = _dropout_env(make_env(sim), level, channel, seed)
        result = evaluate_model(model, starts, sim=sim, seed=seed, env=wrapped, case_options=hook)
        applied = [bool(e) for e in wrapped.episodes]
    cases = result["cases"]
    return {
        "fault": kind,
        "level": level,
        "label": level_label(kind, level),
        "goal_reached": result["goal_reached"],
        "n": result["n"],
        "success_rate_mean": result["success_rate_mean"],
        "zero_floor_mean": result["zero_floor_mean"],
        "reasons": dict(Counter(_reason(c["reason"]) for c in cases)),
        "applied": None if applied is None else int(sum(applied)),
        "channel": channel if kind == "dropout" else None,
        "cases": [
            {
                "start": c["start"],
                "goal_reached": c["goal_reached"],
                "success_rate": c["success_rate"],
                "reason": c["reason"],
                "final_angle_error_deg": c["final_angle_error_deg"],
                "final_distance_error_m": c["final_distance_error_m"],
                "steps": c["steps"],
                "components": c["components"],
                **({} if applied is None else {"fault_applied": applied[i]}),
            }
            for i, c in enumerate(cases)
        ],
    }


def _reason(text: str) -> str:
    return "unreachable" if text.startswith("unreach") else text


def run_faults(
    *,
    sim: str = "mujoco",
    seed: int = 0,
    tasks: Sequence[str] | None = None,
    faults: Sequence[str] | None = None,
    levels: Mapping[str, Sequence[Level]] | None = None,
    n_starts: int | None = None,
    options: Sequence[str] = (),
    without: Sequence[str] = (),
    progress: Progress | None = None,
    executor: Executor | None = None,
) -> dict[str, Any]:
    """Train the default-preset model of each task and evaluate it under every fault level.

    The work runs through ``executor`` in four stages of independent tasks: collect each
    behavior's demonstrations; fit every SBLM (a task's own, and a complex task's
    components, each once); fit every CBLM; then every cell (each task's no-fault
    baseline and each fault level), one task per cell. Every seed is the run's, so the
    results are the same whatever executor runs them.

    Parameters
    ----------
    sim, seed
        Simulator backend, and the seed of the demonstrations, models and evaluation.
    tasks
        Task names (default: turn, approach, turn-approach).
    faults
        Fault kinds (default: all of :data:`FAULTS`).
    levels
        Other levels for some fault kinds (default: each kind's levels).
    n_starts
        Evaluate from only the first ``n_starts`` test starts (default: all 15).
    options
        Options (:data:`~behavior_hmm.models._presets.OPTIONS`) switched on over the
        default preset, e.g. ``("recover",)``; the results' ``preset`` is the row's
        label (``default + recover``).
    without
        Departures (:data:`~behavior_hmm.models._presets.DEPARTURES`) switched back to
        their thesis value, e.g. ``("wheel_calibration",)`` (``default −
        wheel_calibration``).
    progress
        Called with (tasks done, tasks in all): collections, fits and cells.
    executor
        Runs the tasks (default: this process, one after another).

    Returns
    -------
    dict
        ``sim``, ``seed``, ``preset``, ``faults`` (kind, title, unit, levels, nominal),
        and per task ``baseline`` (the no-fault evaluation, a plain ``evaluate_model``)
        and ``cells`` (:func:`evaluate_fault` per fault and level).
    """
    from behavior_hmm.teach import test_starts

    run = executor or SerialExecutor()
    chosen = [ablation_task(n) for n in (tasks or [t.name for t in ABLATION_TASKS])]
    kinds = [fault_kind(n) for n in (faults or [k.name for k in FAULTS])]
    own = {fault_kind(k).name: tuple(v) for k, v in (levels or {}).items()}
    plan = [(k, own.get(k.name, k.levels)) for k in kinds]
    if n_starts is not None and n_starts < 1:
        raise ConfigError(f"n_starts must be >= 1, got {n_starts}")
    row = AblationRow(
        "default",
        switched=tuple(departure(name).name for name in without),
        options=tuple(option(name).name for name in options),
    )
    # the simple tasks whose SBLMs are fitted: each task's own, or a complex task's
    # components (shared with a simple task of the same name), each once
    parts: dict[str, AblationTask] = {}
    for item in chosen:
        for part in [ablation_task(n) for n in item.components] or [item]:
            parts.setdefault(part.name, part)
    behaviors = sorted({p.behavior for p in parts.values()} | {i.behavior for i in chosen})
    complex_items = [item for item in chosen if item.components]
    n_cells = 1 + sum(len(lv) for _, lv in plan)
    total = len(behaviors) + len(parts) + len(complex_items) + len(chosen) * n_cells
    offset = 0

    def advance(done: int, _: int) -> None:
        if progress is not None:
            progress(offset + done, total)

    data_tasks = [(b, sim, seed) for b in behaviors]
    datasets = dict(zip(behaviors, run.map(_collect_task, data_tasks, advance), strict=True))
    offset += len(data_tasks)
    sblm = row.params("SBLM")
    fit_tasks = [(p.inputs, sblm, datasets[p.behavior], seed) for p in parts.values()]
    fitted = [model for model, _ in run.map(_sblm_task, fit_tasks, advance)]
    simple = dict(zip(parts, fitted, strict=True))
    offset += len(fit_tasks)
    cblm_tasks = [
        (
            [simple[name] for name in item.components],
            item.inputs,
            row.params("CBLM"),
            datasets[item.behavior],
            seed,
        )
        for item in complex_items
    ]
    composed = dict(
        zip(
            [item.name for item in complex_items],
            run.map(_cblm_task, cblm_tasks, advance),
            strict=True,
        )
    )
    offset += len(cblm_tasks)
    models = {**simple, **composed}

    # every cell of every task: its no-fault baseline (kind None) first, then the levels
    cell_tasks: list[tuple[Any, ...]] = []
    for item in chosen:
        starts = test_starts(item.behavior)[:n_starts]
        channel = DROPOUT_CHANNEL[item.name]
        cell_tasks.append((models[item.name], starts, None, None, sim, seed, channel))
        for kind, kind_levels in plan:
            for level in kind_levels:
                cell_tasks.append((models[item.name], starts, kind.name, level, sim, seed, channel))
    cells = iter(run.map(_cell_task, cell_tasks, advance))

    out = []
    for item in chosen:
        base = next(cells)
        out.append(
            {
                "task": item.name,
                "behavior": item.behavior,
                "inputs": list(item.inputs),
                "components": list(item.components),
                "dropout_channel": DROPOUT_CHANNEL[item.name],
                "baseline": base,
                "cells": [next(cells) for _ in range(n_cells - 1)],
            }
        )
    return {
        "sim": sim,
        "seed": seed,
        "preset": row.label,
        "fault_hold_s": _hold_s(),
        "push": {"angle_deg": PUSH_ANGLE_DEG, "distance_m": PUSH_DISTANCE_M},
        "dropout_at": DROPOUT_AT,
        "faults": [
            {
                "kind": k.name,
                "title": k.title,
                "unit": k.unit,
                "levels": list(lv),
                "nominal": k.nominal,
            }
            for k, lv in plan
        ],
        "tasks": out,
    }


def _cblm_task(task: tuple[Any, ...]) -> Any:
    """Fit one CBLM: ``(components, inputs, params, dataset, seed)`` (an executor task)."""
    components, inputs, params, dataset, seed = task
    return _fit_cblm(components, inputs, params, dataset, seed)[0]


def _cell_task(task: tuple[Any, ...]) -> dict[str, Any]:
    """Evaluate one cell (an executor task): ``(model, starts, kind, level, sim, seed,
    channel)``; ``kind`` None: the no-fault baseline's summary (a plain evaluation)."""
    model, starts, kind, level, sim, seed, channel = task
    if kind is not None:
        return evaluate_fault(model, starts, kind, level, sim=sim, seed=seed, channel=channel)
    base = evaluate_model(model, starts, sim=sim, seed=seed)
    return {
        "goal_reached": base["goal_reached"],
        "n": base["n"],
        "success_rate_mean": base["success_rate_mean"],
        "zero_floor_mean": base["zero_floor_mean"],
    }


def _hold_s() -> float:
    from behavior_hmm.runtime import DEFAULT_FAULT_HOLD_S

    return float(DEFAULT_FAULT_HOLD_S)
