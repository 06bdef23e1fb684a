"""The 16 ms control loop shared by every learned behavior and baseline.

Safety rules of the loop (docs/usage.md, "Sensor faults and stopping"):

* the robot is always commanded to stop (``env.step(rest)``: each command channel's
  ``rest``, zero wheel speed on our robots) when a run ends,
  whatever ends it: the goal, the step limit, a sensor fault, or an exception raised
  by the controller or the env (KeyboardInterrupt included), which then propagates;
* a non-finite reading on a channel the controller reads is replaced by that channel's
  last good value for at most ``fault_hold_s`` seconds; past that, or with no good
  value yet, the run ends as a ``"sensor_fault"``. Controllers never see a NaN on a
  channel they read;
* the step limit ends a run, unless ``progress_limit`` lets a run that still closes in
  on its goal go on (:class:`Progress`): a robot slower than its demonstrations (a lower
  speed limit, a weaker motor) is not stopped short while it is getting there.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data._channels import channel, within_tolerance
from behavior_hmm.errors import ConfigError
from behavior_hmm.runtime._calibration import CALIBRATION_CHANNELS, WheelCalibration
from behavior_hmm.runtime._policy import Policy
from behavior_hmm.runtime._robot import Robot
from behavior_hmm.runtime._trace import Trace

FloatArray = NDArray[np.float64]

#: Default longest time (s) a non-finite reading is replaced by its last good value
#: (0.1 s: 6 control periods of 16 ms).
DEFAULT_FAULT_HOLD_S: Final[float] = 0.1
#: Past the step limit, the goal error is checked every ``max_steps / PROGRESS_CHECKS``
#: cycles; the run goes on only if the error fell by at least ``PROGRESS_MIN_DROP`` (a
#: share of the last check's) since the last check.
PROGRESS_CHECKS: Final[int] = 4
PROGRESS_MIN_DROP: Final[float] = 0.1
#: Readings averaged into one goal error (sensor noise would make single readings jump).
PROGRESS_READINGS: Final[int] = 8


class Progress:
    """Whether a run at its step limit still closes in on its goal, so may go on.

    The goal error of a reading is the sum over the goal's channels of ``|error| /
    tolerance`` (an angle's error wrapped, as its channel declares), averaged over the
    last ``PROGRESS_READINGS`` readings. At ``max_steps`` and every ``max_steps /
    PROGRESS_CHECKS`` cycles after, the run goes on if that error fell by at least
    ``PROGRESS_MIN_DROP`` of its value at the previous check (the first check compares
    with one period before the limit), up to ``progress_limit × max_steps`` cycles in
    all. ``progress_limit == 1`` is a fixed step limit.
    """

    def __init__(
        self,
        goal: Mapping[str, float],
        specs: Mapping[str, Any],
        max_steps: int,
        progress_limit: float,
    ) -> None:
        self._goal = [
            (name, float(value), specs[name] if name in specs else channel(name))
            for name, value in goal.items()
        ]
        self.max_steps = int(max_steps)
        self.period = max(1, self.max_steps // PROGRESS_CHECKS)
        self.limit = max(self.max_steps, math.floor(progress_limit * self.max_steps))
        self._recent: list[float] = []
        self._checks: dict[int, float] = {}

    def error(self, values: Mapping[str, float]) -> float:
        """The goal error of one reading (0 at the goal; 1 at one tolerance on one channel)."""
        total = 0.0
        for name, target, spec in self._goal:
            tol = float(spec.tolerance or 1.0)
            total += abs(spec.error(values[name], target)) / tol
        return total

    def observe(self, step: int, values: Mapping[str, float]) -> None:
        """Record the reading of cycle ``step``."""
        if self.limit == self.max_steps:
            return
        self._recent.append(self.error(values))
        del self._recent[:-PROGRESS_READINGS]
        after = step + 1 - (self.max_steps - self.period)  # checks are due before cycles
        if after >= 0 and after % self.period == 0:  # max_steps - period, max_steps, ...
            self._checks[step + 1] = sum(self._recent) / len(self._recent)

    def goes_on(self, step: int) -> bool:
        """Whether cycle ``step`` (``>= max_steps``) may still run."""
        if step >= self.limit:
            return False
        if (step - self.max_steps) % self.period:
            return True  # between checks: decided at the last one
        now = self._checks.get(step)
        before = self._checks.get(step - self.period)
        if now is None or before is None:
            return False
        return now <= (1.0 - PROGRESS_MIN_DROP) * before


def start_options(
    start: Mapping[str, float] | None,
    noise: float | None,
    pushes: Sequence[Mapping[str, float]] | None,
    robot: Robot | None = None,
) -> dict[str, Any]:
    """``env.reset`` options for a start (channel -> value), sensor noise and pushes.

    A start may name any channel the robot can be placed at: its ``start_channels``
    when it declares them, else any of its channels (contract version 2); without a
    robot, the data contract's ``angle`` and ``distance``.
    """
    if robot is None:
        allowed: Sequence[str] = ("angle", "distance")
    elif robot.start_channels is not None:
        allowed = robot.start_channels
    else:
        allowed = robot.channels
    options: dict[str, Any] = {}
    for key, value in (start or {}).items():
        if key not in allowed:
            raise ConfigError(
                f"unknown start channel '{key}' (the robot starts at {', '.join(allowed)})"
            )
        options[key] = float(value)
    if noise is not None:
        if noise < 0:
            raise ConfigError(f"noise must be >= 0, got {noise}")
        options["noise"] = float(noise)
    if pushes:
        options["push"] = [dict(p) for p in pushes]
    return options


class SensorHold:
    """The sensor-fault policy: hold a read channel's last good value for a while.

    Parameters
    ----------
    channels
        Every channel of a reading, in its order.
    guarded
        Channels guarded (those the policy reads); others pass unchanged.
    hold_steps
        Most consecutive non-finite readings of one channel replaced by its last good
        value; one more is a fault. A non-finite reading before any good value of its
        channel is a fault at once.
    """

    def __init__(self, channels: Sequence[str], guarded: Iterable[str], hold_steps: int) -> None:
        names = tuple(guarded)
        unknown = [c for c in names if c not in channels]
        if unknown:
            raise ConfigError(
                f"the robot has no channel(s) {', '.join(unknown)} that the behavior reads "
                f"(the robot's: {', '.join(channels)})"
            )
        self.channels = tuple(c for c in channels if c in names)
        self._idx = np.array([list(channels).index(c) for c in self.channels], dtype=np.intp)
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


def hold_steps(fault_hold_s: float, control_period: float) -> int:
    """Control periods a reading may be held: ``floor(fault_hold_s / control_period)``."""
    if isinstance(fault_hold_s, bool) or not isinstance(fault_hold_s, int | float | np.number):
        raise ConfigError(f"fault_hold_s must be a number of seconds, got {fault_hold_s!r}")
    hold = float(fault_hold_s)
    if not (math.isfinite(hold) and hold >= 0.0):
        raise ConfigError(f"fault_hold_s must be a finite number of seconds >= 0, got {hold}")
    return math.floor(hold / control_period + 1e-9)


def _stop(env: Any, rest: FloatArray) -> None:
    """Best effort: command the robot to rest; an error here is swallowed."""
    try:
        env.step(rest)
    except Exception:  # the original exception must propagate, not this one
        pass


def run_policy(
    policy: Policy,
    env: Any,
    *,
    start: Mapping[str, float] | None = None,
    seed: int | None = None,
    noise: float | None = None,
    max_steps: int = 2000,
    pushes: Sequence[Mapping[str, float]] | None = None,
    fault_hold_s: float = DEFAULT_FAULT_HOLD_S,
    progress_limit: float = 1.0,
    wheel_calibration: bool = False,
    wheel_response: NDArray[np.float64] | None = None,
) -> Trace:
    """Reset ``env`` at ``start`` and run ``policy`` until done or ``max_steps``.

    ``env`` is any Gymnasium env that meets the robot contract (docs/robots.md); each
    cycle the policy gets ``{channel: value}`` and its command goes to ``env.step``.
    The robot is always commanded to stop at the end, and the trace's outcome is
    judged on the env's noise-free observation after that stop
    (``info["true_observation"]``, else the observation). An exception raised inside
    the loop (by the policy or the env, KeyboardInterrupt included) first commands zero
    wheel speed (best effort: if that fails too, the original exception still
    propagates), then propagates. An exception before any command was sent (e.g. an
    unreachable goal) sends none: the robot is still at rest after the reset.

    Parameters
    ----------
    policy
        What :class:`~behavior_hmm.runtime.Policy` says: ``goal``, ``channels``,
        ``reset()``, ``step(reading)``.
    start
        ``{"angle": deg, "distance": m}`` for ``env.reset``; ``None`` keeps the env's default.
    seed, noise, pushes
        Passed to ``env.reset`` (``noise`` and ``push`` are options of our envs; a robot
        that does not offer them refuses them).
    max_steps
        Step limit (control periods).
    fault_hold_s
        Sensor-fault policy (seconds): a non-finite reading on a channel the policy
        reads is replaced by that channel's last good value for at most
        ``floor(fault_hold_s / control_period)`` consecutive control periods (6 at
        16 ms for the default 0.1 s); counted in ``trace.held_readings``. One more
        non-finite reading, or one before any good value of its channel, stops the
        robot and ends the run with ``reason == "sensor_fault"``. 0 disables holding.
    progress_limit
        At most this many times ``max_steps`` cycles in all, for a run that at its
        step limit still closes in on its goal (:class:`Progress`); 1 (default): the
        step limit is fixed. A run that ends past ``max_steps`` without its goal ends
        with ``reason == "step_limit"`` too.
    wheel_calibration
        Estimate each wheel's gain from the robot's measured body speed and yaw rate and
        divide the commands by it (:class:`~behavior_hmm.runtime.WheelCalibration`); the
        trace records the commands sent and the final gains (``wheel_gains``). A robot
        that cannot be calibrated (no wheel geometry, no measured velocities) runs
        uncorrected, with a warning.
    wheel_response
        How the demonstrated robot's wheels answered (a model's ``wheel_response_``,
        :func:`~behavior_hmm.runtime.wheel_response`): the calibration restores their
        difference; None calibrates toward equal wheels.
    """
    robot = env if isinstance(env, Robot) else Robot(env)
    dt = robot.control_period
    wanted = tuple(getattr(policy, "command_channels", robot.command_channels))
    if wanted != robot.command_channels:
        raise ConfigError(
            f"the behavior commands {', '.join(wanted)}; the robot takes "
            f"{', '.join(robot.command_channels)}"
        )
    bind = getattr(policy, "bind", None)
    if callable(bind):  # e.g. rules that read channels only some robots have
        bind(robot.channels)
    guard = SensorHold(robot.channels, policy.channels, hold_steps(fault_hold_s, dt))
    calibration = WheelCalibration.for_robot(robot, wheel_response) if wheel_calibration else None
    options = start_options(start, noise, pushes, robot)
    names = robot.channels
    commanded = False  # whether any command reached env.step in this run
    stopped = False
    try:
        reading, true, pose = robot.reset(seed=seed, options=options)
        policy.reset()
        if calibration is not None:
            calibration.reset()
        trace = Trace(
            goal=dict(policy.goal),
            start=dict(start or {}),
            channels=list(names),
            command_channels=list(robot.command_channels),
        )
        # a policy may declare channels the registry does not know (a model's own)
        trace.channel_specs = {
            **{spec.name: spec for spec in robot.command_specs},
            **robot.channel_specs,
            **(getattr(policy, "channel_specs", {})),
        }
        reason = "step_limit"
        progress = Progress(trace.goal, trace.channel_specs, max_steps, progress_limit)
        k = -1
        while True:
            k += 1
            if k >= max_steps and not progress.goes_on(k):
                break
            seen, held = guard(reading)
            trace.t.append(k * dt)
            trace.readings.append(reading)
            trace.true_readings.append(true)
            if pose is not None:
                trace.pose.append(np.asarray(pose, dtype=np.float64))
            if guard.faulted:
                # the hold cannot cover it: this step's command is the stop below
                trace.observation.append(-1)
                trace.novel.append(False)
                trace.state.append(-1)
                trace.component.append("")
                trace.commands.append(robot.rest.copy())
                trace.plan_changed.append(False)
                trace.held.append(0)
                reason = "sensor_fault"
                trace.fault_channels = list(guard.faulted)
                break
            values = dict(zip(names, seen.tolist(), strict=True))
            progress.observe(k, values)
            out = policy.step(values)
            if calibration is not None and not out.done:
                calibration.observe(*(values[c] for c in CALIBRATION_CHANNELS))
                out = out._replace(command=calibration.correct(out.command))
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
            reading, true, pose = robot.step(out.command)
        # Always command a stop at the end; judge the outcome on the state after it.
        commanded = True
        _, true, pose = robot.step(robot.rest)
        stopped = True
    finally:
        if commanded and not stopped:
            _stop(robot.env, robot.rest)
    trace.final_observation = true
    trace.final_pose = None if pose is None else np.asarray(pose, dtype=np.float64)
    trace.reason = reason
    if calibration is not None:
        trace.wheel_gains = [float(g) for g in calibration.gains]
    values = robot.as_dict(true)
    trace.goal_reached = reason != "sensor_fault" and within_tolerance(
        values, trace.goal, 1.0, trace.channel_specs
    )
    return trace
