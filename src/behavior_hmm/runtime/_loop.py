"""The 16 ms control loop shared by every learned behavior and baseline.

Safety rules of the loop (docs/usage.md, "Sensor faults and stopping"):

* the robot is always commanded to stop (``env.step(np.zeros(2))``) when a run ends,
  whatever ends it: the goal, the step limit, a sensor fault, or an exception raised
  by the controller or the env (KeyboardInterrupt included), which then propagates;
* a non-finite reading on a channel the controller reads is replaced by that channel's
  last good value for at most ``fault_hold_s`` seconds; past that, or with no good
  value yet, the run ends as a ``"sensor_fault"``. Controllers never see a NaN on a
  channel they read.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data import SENSOR_CHANNELS
from behavior_hmm.errors import ConfigError
from behavior_hmm.models._goals import within_tolerance
from behavior_hmm.runtime._simple import make_controller
from behavior_hmm.runtime._trace import Trace

FloatArray = NDArray[np.float64]

#: Default longest time (s) a non-finite reading is replaced by its last good value
#: (0.1 s: 6 control periods of 16 ms).
DEFAULT_FAULT_HOLD_S: Final[float] = 0.1

#: The channels the stop-at-rest rule of an SBLM reads (``stop_at_rest``).
_REST_CHANNELS: Final[frozenset[str]] = frozenset({"linear_velocity", "angular_velocity"})


def start_options(
    start: Mapping[str, float] | None,
    noise: float | None,
    pushes: Sequence[Mapping[str, float]] | None,
) -> dict[str, Any]:
    """``env.reset`` options for a start (deg, m), sensor noise and scheduled pushes."""
    options: dict[str, Any] = {}
    for key, value in (start or {}).items():
        if key not in ("angle", "distance"):
            raise ConfigError(f"unknown start channel '{key}' (use angle and/or distance)")
        options[key] = float(value)
    if noise is not None:
        if noise < 0:
            raise ConfigError(f"noise must be >= 0, got {noise}")
        options["noise"] = float(noise)
    if pushes:
        options["push"] = [dict(p) for p in pushes]
    return options


def channels_read(model: Any) -> tuple[str, ...]:
    """The sensor channels a model's controller reads, in ``SENSOR_CHANNELS`` order.

    A model reads its ``inputs_``; an SBLM with ``stop_at_rest`` also reads
    ``linear_velocity`` and ``angular_velocity`` (its stop rule waits for rest); a
    CBLM also reads whatever its components read (recursively). Only these channels
    are guarded by the sensor-fault policy of :func:`run_controller`; the others reach
    the controller unchanged, and the controllers ignore them.
    """
    names: set[str] = set(getattr(model, "inputs_", ()))
    if bool(getattr(model, "stop_at_rest", False)):
        names |= _REST_CHANNELS
    for component in getattr(model, "components_", None) or ():
        names.update(channels_read(component))
    return tuple(c for c in SENSOR_CHANNELS if c in names)


class SensorHold:
    """The sensor-fault policy: hold a read channel's last good value for a while.

    Parameters
    ----------
    channels
        Channels guarded (those the controller reads); others pass unchanged.
    hold_steps
        Most consecutive non-finite readings of one channel replaced by its last good
        value; one more is a fault. A non-finite reading before any good value of its
        channel is a fault at once.
    """

    def __init__(self, channels: Iterable[str], hold_steps: int) -> None:
        names = tuple(channels)
        unknown = [c for c in names if c not in SENSOR_CHANNELS]
        if unknown:
            raise ConfigError(
                f"unknown channel(s) {', '.join(unknown)}; choose from {', '.join(SENSOR_CHANNELS)}"
            )
        self.channels = tuple(c for c in SENSOR_CHANNELS if c in names)
        self._idx = np.array([SENSOR_CHANNELS.index(c) for c in self.channels], dtype=np.intp)
        self.hold_steps = int(hold_steps)
        self._last = np.full(len(self._idx), np.nan)
        self._age = np.zeros(len(self._idx), dtype=np.int64)
        self.faulted: list[str] = []

    def __call__(self, reading: FloatArray) -> tuple[FloatArray, int]:
        """The reading to act on and how many of its channels were held.

        Sets :attr:`faulted` (the channels past the hold) and returns the reading
        unchanged when the hold cannot cover a fault.
        """
        values = reading[self._idx]
        bad = ~np.isfinite(values)
        if not bad.any():
            self._last = values
            self._age[:] = 0
            return reading, 0
        good = ~bad
        self._last[good] = values[good]
        self._age[good] = 0
        self._age[bad] += 1
        lost = bad & ((self._age > self.hold_steps) | np.isnan(self._last))
        if lost.any():
            self.faulted = [self.channels[j] for j in np.flatnonzero(lost)]
            return reading, 0
        held = reading.copy()
        held[self._idx[bad]] = self._last[bad]
        return held, int(bad.sum())


def _control_period(env: Any) -> float:
    """The env's control period (s): ``env.unwrapped.control_period`` or its params'."""
    base = env.unwrapped
    period = getattr(base, "control_period", None)
    if period is None:
        period = base.params.control_period
    return float(period)


def hold_steps(fault_hold_s: float, control_period: float) -> int:
    """Control periods a reading may be held: ``floor(fault_hold_s / control_period)``."""
    if isinstance(fault_hold_s, bool) or not isinstance(fault_hold_s, int | float | np.number):
        raise ConfigError(f"fault_hold_s must be a number of seconds, got {fault_hold_s!r}")
    hold = float(fault_hold_s)
    if not (math.isfinite(hold) and hold >= 0.0):
        raise ConfigError(f"fault_hold_s must be a finite number of seconds >= 0, got {hold}")
    return math.floor(hold / control_period + 1e-9)


def _stop(env: Any) -> None:
    """Best effort: command zero wheel speed; an error here is swallowed."""
    try:
        env.step(np.zeros(2))
    except Exception:  # the original exception must propagate, not this one
        pass


def run_controller(
    controller: Any,
    env: Any,
    *,
    start: Mapping[str, float] | None = None,
    seed: int | None = None,
    noise: float | None = None,
    max_steps: int = 2000,
    pushes: Sequence[Mapping[str, float]] | None = None,
    fault_hold_s: float = DEFAULT_FAULT_HOLD_S,
    read_channels: Iterable[str] | None = None,
) -> Trace:
    """Reset ``env`` at ``start`` and run ``controller`` until done or ``max_steps``.

    The robot is always commanded to stop at the end, and the trace's outcome is
    judged on the simulator's noise-free state after that stop. An exception raised
    inside the loop (by the controller or the env, KeyboardInterrupt included) first
    commands zero wheel speed (best effort: if that fails too, the original exception
    still propagates), then propagates. An exception before any command was sent
    (e.g. an unreachable goal) sends none: the robot is still at rest after the reset.

    Parameters
    ----------
    fault_hold_s
        Sensor-fault policy (seconds): a non-finite reading on a channel the controller
        reads is replaced by that channel's last good value for at most
        ``floor(fault_hold_s / control_period)`` consecutive control periods (6 at
        16 ms for the default 0.1 s); counted in ``trace.held_readings``. One more
        non-finite reading, or one before any good value of its channel, stops the
        robot and ends the run with ``reason == "sensor_fault"``. 0 disables holding.
    read_channels
        The channels the controller reads (see :func:`channels_read`); non-finite
        values on others reach it unchanged. ``None``: all sensor channels are guarded.
    """
    dt = _control_period(env)
    guard = SensorHold(
        SENSOR_CHANNELS if read_channels is None else read_channels,
        hold_steps(fault_hold_s, dt),
    )
    options = start_options(start, noise, pushes)
    commanded = False  # whether any command reached env.step in this run
    stopped = False
    try:
        obs, info = env.reset(seed=seed, options=options)
        controller.reset()
        trace = Trace(goal=dict(controller.goal), start=dict(start or {}))
        reason = "step_limit"
        for k in range(max_steps):
            reading = np.array(obs, dtype=np.float64)
            seen, held = guard(reading)
            trace.t.append(k * dt)
            trace.readings.append(reading)
            trace.true_readings.append(np.array(info["true_observation"], dtype=np.float64))
            if guard.faulted:
                # the hold cannot cover it: this step's command is the stop below
                trace.observation.append(-1)
                trace.novel.append(False)
                trace.state.append(-1)
                trace.component.append("")
                trace.commands.append(np.zeros(2))
                trace.plan_changed.append(False)
                trace.held.append(0)
                reason = "sensor_fault"
                trace.fault_channels = list(guard.faulted)
                break
            out = controller.step(seen)
            trace.observation.append(int(out.observation))
            trace.novel.append(bool(out.novel))
            trace.state.append(int(out.state))
            trace.component.append(out.component)
            trace.commands.append(np.array(out.command, dtype=np.float64))
            trace.plan_changed.append(bool(out.plan_changed))
            trace.held.append(held)
            if out.done:
                reason = "goal"
                break
            commanded = True
            obs, _, _, _, info = env.step(out.command)
        # Always command a stop at the end; judge the outcome on the state after it.
        commanded = True
        _, _, _, _, info = env.step(np.zeros(2))
        stopped = True
    finally:
        if commanded and not stopped:
            _stop(env)
    final = np.array(info["true_observation"], dtype=np.float64)
    trace.final_observation = final
    trace.reason = reason
    values = {name: float(final[j]) for j, name in enumerate(SENSOR_CHANNELS)}
    trace.goal_reached = reason != "sensor_fault" and within_tolerance(values, trace.goal)
    return trace


def run_behavior(
    model: Any,
    env: Any,
    *,
    start: Mapping[str, float] | None = None,
    goal: Mapping[str, float] | None = None,
    seed: int | None = None,
    noise: float | None = None,
    max_steps: int | None = None,
    pushes: Sequence[Mapping[str, float]] | None = None,
    fault_hold_s: float = DEFAULT_FAULT_HOLD_S,
) -> Trace:
    """Perform a learned behavior (SBLM or CBLM) in ``env`` from ``start`` to ``goal``.

    Parameters
    ----------
    model
        A fitted SBLM or CBLM.
    env
        A ``behavior_hmm.sim`` env (any backend).
    start
        ``{"angle": deg, "distance": m}`` for ``env.reset``; ``None`` keeps the env default.
    goal
        Goal in physical units (e.g. ``{"angle": 0}``); ``None`` uses the model's default.
    seed, noise
        Passed to ``env.reset`` (sensor noise: sigma times each channel's range).
    max_steps
        Step limit; default the model's ``max_steps_``.
    pushes
        Scheduled pushes ``{"step", "angle", "distance"}`` (see the env's reset options).
    fault_hold_s
        Seconds a non-finite reading on a channel the model reads (:func:`channels_read`)
        is replaced by its last good value (default 0.1 s, 6 control periods); past
        that the robot stops and the trace's ``reason`` is ``"sensor_fault"`` (see
        :func:`run_controller`).

    Raises
    ------
    UnreachableGoalError
        Before any motion, when no observation path leads from the start to the goal,
        or when the goal is one the model was never shown to stop at (a simple
        behavior's ``check_stoppable``).
    """
    stoppable = getattr(model, "check_stoppable", None)
    if stoppable is not None:
        stoppable(goal)
    controller = make_controller(model, goal)
    limit = int(max_steps if max_steps is not None else model.max_steps_)
    if limit < 1:
        raise ConfigError(f"max_steps must be >= 1, got {limit}")
    return run_controller(
        controller,
        env,
        start=start,
        seed=seed,
        noise=noise,
        max_steps=limit,
        pushes=pushes,
        fault_hold_s=fault_hold_s,
        read_channels=channels_read(model),
    )
