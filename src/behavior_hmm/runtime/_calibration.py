"""Wheel calibration on line: a robot whose wheels answer differently from its demonstrations.

A learned behavior commands the wheel speeds its demonstrations used. When a motor is
weaker or stronger than on the robot that was demonstrated (a gain mismatch between
the wheels, worn tyres, a tired battery), the same commands drive a curve instead of a
line, and a behavior that never saw a heading error drifts off (docs/reliability.md,
"wheel mismatch"). :class:`WheelCalibration` estimates each wheel's gain while the robot
runs, from what the robot measures of its own motion, and divides the commands by it:

* **What is measured.** A differential-drive robot's body speed ``v`` (m/s) and yaw rate
  ``ω`` (rad/s) give the speed each wheel actually turned at:
  ``w_left = (v − ω W / 2) / r`` and ``w_right = (v + ω W / 2) / r`` (wheel radius ``r``,
  track width ``W``, from the robot's ``robot_spec``).
* **The model.** ``w_i = g_i · u_i`` for the command ``u_i`` sent ``CALIBRATION_LAG``
  cycles before the reading (the motors' response time), ``g_i`` the wheel's unknown gain.
* **The estimate.** Per wheel, recursive least squares with forgetting
  (``CALIBRATION_FORGET`` = λ per cycle) from a prior ``g_i = 1`` worth
  ``CALIBRATION_PRIOR`` = p (rad/s)² of evidence at the start, forgotten like any
  measurement: ``g_i = (λ^n p + Σ λ^k u_i w_i) / (λ^n p + Σ λ^k u_i²)``, kept within
  ``CALIBRATION_BOUNDS``. At the start every gain is 1 (equal wheels: against a
  reference the first commands restore its difference, 0.5 % on our Khepera; on noisy
  readings, below, they are the behavior's own); a wheel that is not turning tells
  nothing and leaves its gain where it was (both sums fade alike); at a steady command
  the estimate is exact.
* **Against the demonstrated robot.** The demonstrations were made on a robot whose own
  wheels may differ a little (ours by 0.01), and the behavior learned commands that drive
  straight *there*. So the reference is that robot's gains, estimated the same way from
  the demonstrations (:func:`wheel_response`, kept in the model: ``wheel_response_``),
  and the correction restores the demonstrated response rather than an ideal one.
  Calibrating to an ideal robot instead cost 0.4-1.0 points on the approach pushed 30°
  (MuJoCo): it undid the 0.01 the learned commands make up for.
* **The correction.** Only the wheels' *difference* is corrected, the one that turns a
  straight command into a curve: each gain is divided by the mean of the two,
  ``ĝ_i = g_i / mean(g)``, and the command sent is ``rest + (u − rest) / ĝ`` per wheel,
  within the robot's largest wheel speed (with a reference, ``ĝ`` is over the reference's
  ``ĝ``). A gain both wheels share is left to the closed
  loop: a slower motor response reads as a lower gain while the wheels speed up (both
  alike), and correcting it drove harder into every start-up (MuJoCo, motor lag 0.3 s:
  turn 13 of 15 goals, against 15 uncorrected and 15 with the difference only). The
  trace records the commands sent and the final ``ĝ``.
* **Only beyond the readings' noise.** On noisy readings the estimate wanders; only the
  part of the wheels' measured difference (their log-ratio against the reference's) that
  its standard error does not explain is corrected, the fraction
  ``max(0, 1 − (z e / d)²)`` of it (``CALIBRATION_Z`` = z; ``e`` from the readings' noise,
  which their second differences give, over the evidence ``Σ λ^k u²``). On clean
  readings it is all of it.

It needs what it reads: two wheel commands (``left``, ``right``), the robot's wheel
geometry and ``linear_velocity`` and ``angular_velocity`` *measured* by the robot (the
velocities this package derives from ``distance`` and ``angle`` when a robot does not
measure them are the object's motion, not the body's). A robot without them runs
uncalibrated, and a warning says why.
"""

from __future__ import annotations

import math
import warnings
from collections import deque
from collections.abc import Sequence
from typing import TYPE_CHECKING, Final

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.errors import ConfigError

if TYPE_CHECKING:
    from behavior_hmm.runtime._robot import Robot

FloatArray = NDArray[np.float64]

#: Cycles from a command to the reading that shows it (the motors' first-order response,
#: 0.03 s on our Khepera, plus the cycle the command takes to act). Approach, MuJoCo,
#: wheel mismatch 0.4, the 15 test starts: 15/15 goals with 2 and with 3.
CALIBRATION_LAG: Final[int] = 2
#: A wheel learns only from a command it has held for this many cycles before it (within
#: ``CALIBRATION_STEADY_SHARE`` of its value): while a wheel speeds up or slows down, the
#: motor's lag makes it turn slower or faster than its gain times the command. MuJoCo,
#: the fault sweep's 15 starts: with 0 (learn from every cycle) turn & approach missed one
#: goal at a 0.2 s motor lag (14/15) and reached 10 instead of 12 of 15 at
#: sensor noise 0.02; learning later costs the approach 2.8 points at mismatch 0.4
#: (80.5 against 83.3 %, 15/15 both).
CALIBRATION_STEADY_CYCLES: Final[int] = 8
CALIBRATION_STEADY_SHARE: Final[float] = 0.02
#: Forgetting factor per cycle: the estimate weighs about the last 1 / (1 − λ) = 50
#: cycles (0.8 s at 16 ms), so it follows a gain that changes within a run.
CALIBRATION_FORGET: Final[float] = 0.98
#: Weight of the prior gain 1 at the start of a run, in (rad/s)² of a wheel's command:
#: less than one cycle of a wheel at 3.8 rad/s (the approach's cruise, 14 (rad/s)²), so
#: the measurements take over within a few cycles of motion, while a wheel that has
#: barely turned keeps its gain near 1.
CALIBRATION_PRIOR: Final[float] = 10.0
#: The gains the estimate may take: a wheel that turns at less than half or more than
#: twice its command is a fault no gain should hide.
CALIBRATION_BOUNDS: Final[tuple[float, float]] = (0.5, 2.0)

#: The wheels' measured difference is corrected only beyond this many of its standard
#: errors (the part within them is left alone): on noisy readings of the body's speed and
#: yaw rate the estimate wanders, and correcting the wander turns a straight command into
#: a curve. MuJoCo, turn & approach, sensor noise 0.02 (σ 3.6 deg/s on the yaw rate), the
#: 15 test starts: correcting all of it put a 0.01 mismatch at 0.11 and one run alternated
#: turn and approach until its step limit.
CALIBRATION_Z: Final[float] = 2.0
#: Readings over which the readings' noise is estimated: the median of their second
#: differences' sizes, so that a start or a change of speed (a motion, not noise) does
#: not count as long as it fills less than half of them.
CALIBRATION_NOISE_WINDOW: Final[int] = 64
#: A normal variable's median absolute value over its σ.
_MEDIAN_ABS: Final[float] = 0.6744897501960817

_FLOOR: Final[float] = 1e-300

#: The channels the calibration reads, measured by the robot.
CALIBRATION_CHANNELS: Final[tuple[str, str]] = ("linear_velocity", "angular_velocity")
#: The command channels it corrects, in this order.
CALIBRATION_COMMANDS: Final[tuple[str, str]] = ("left", "right")


class WheelCalibration:
    """Estimate each wheel's gain on line and correct the commands by it.

    Parameters
    ----------
    wheel_radius, track_width
        The robot's geometry (m).
    max_wheel_speed
        Largest wheel command (rad/s); corrected commands stay within it.
    rest
        The command that holds the robot still (rad/s per wheel), default zeros.
    reference
        The demonstrated robot's gains ``(left, right)`` (:meth:`reference_gains`), whose
        difference the correction restores; default equal gains.
    lag, steady, forget, prior, bounds
        See :data:`CALIBRATION_LAG`, :data:`CALIBRATION_STEADY_CYCLES`,
        :data:`CALIBRATION_FORGET`, :data:`CALIBRATION_PRIOR` and
        :data:`CALIBRATION_BOUNDS`.

    Attributes
    ----------
    measured_gains
        The current estimate ``(left, right)``: measured wheel speed per unit of command.
    gains
        The gains the commands are divided by: ``measured_gains`` over their mean (the
        wheels' difference only).
    """

    def __init__(
        self,
        wheel_radius: float,
        track_width: float,
        max_wheel_speed: float,
        *,
        rest: FloatArray | None = None,
        reference: FloatArray | None = None,
        lag: int = CALIBRATION_LAG,
        steady: int = CALIBRATION_STEADY_CYCLES,
        forget: float = CALIBRATION_FORGET,
        prior: float = CALIBRATION_PRIOR,
        bounds: tuple[float, float] = CALIBRATION_BOUNDS,
    ) -> None:
        for name, value in (
            ("wheel_radius", wheel_radius),
            ("track_width", track_width),
            ("max_wheel_speed", max_wheel_speed),
            ("prior", prior),
        ):
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"wheel calibration: {name} must be > 0, got {value}")
        if not isinstance(lag, int) or lag < 1:
            raise ConfigError(f"wheel calibration: lag must be an integer >= 1, got {lag!r}")
        if not isinstance(steady, int) or steady < 0:
            raise ConfigError(f"wheel calibration: steady must be an integer >= 0, got {steady!r}")
        if not 0.0 < forget <= 1.0:
            raise ConfigError(f"wheel calibration: forget must lie in (0, 1], got {forget}")
        if not 0.0 < bounds[0] <= 1.0 <= bounds[1]:
            raise ConfigError(f"wheel calibration: bounds must hold 1, got {bounds}")
        self.wheel_radius = float(wheel_radius)
        self.track_width = float(track_width)
        self.max_wheel_speed = float(max_wheel_speed)
        self.rest = np.zeros(2) if rest is None else np.asarray(rest, dtype=np.float64)
        if self.rest.shape != (2,):
            raise ConfigError(f"wheel calibration: rest must be 2 wheel commands, got {rest!r}")
        ref = np.ones(2) if reference is None else np.asarray(reference, dtype=np.float64)
        if ref.shape != (2,) or not np.all(np.isfinite(ref)) or not np.all(ref > 0.0):
            raise ConfigError(
                f"wheel calibration: reference must be 2 gains > 0, got {reference!r}"
            )
        self.reference = ref / float(np.mean(ref))
        self._reference_log_ratio = math.log(ref[0] / ref[1])
        self.lag = lag
        self.steady = steady
        self.forget = float(forget)
        self.prior = float(prior)
        self.bounds = (float(bounds[0]), float(bounds[1]))
        self.reset()

    @classmethod
    def for_robot(cls, robot: Robot, response: FloatArray | None = None) -> WheelCalibration | None:
        """The calibration of ``robot``, or ``None`` (with a warning) when it cannot have one.

        ``response``: the demonstrations' :func:`wheel_response` (the reference); None
        calibrates toward equal wheels.
        """
        why = _missing(robot)
        if why:
            warnings.warn(
                f"wheel_calibration is off: {why}; the commands go to the wheels uncorrected",
                RuntimeWarning,
                stacklevel=3,
            )
            return None
        spec = robot.spec
        reference = None
        if response is not None:
            reference = reference_gains(response, spec.wheel_radius, spec.track_width)
        return cls(
            spec.wheel_radius,
            spec.track_width,
            spec.max_wheel_speed,
            rest=robot.rest.copy(),
            reference=reference,
        )

    def reset(self) -> None:
        """Start a new run: gains 1, no commands sent yet."""
        self._suu = np.full(2, self.prior)
        self._suw = np.full(2, self.prior)
        self._readings: list[FloatArray] = []  # the last two (m/s, rad/s)
        self._jitter: deque[FloatArray] = deque(maxlen=CALIBRATION_NOISE_WINDOW)
        self._sent: list[FloatArray] = []
        self._asked: list[FloatArray] = []
        self.gains = np.ones(2)
        self.measured_gains = np.ones(2)

    def wheel_speeds(self, linear_velocity: float, angular_velocity: float) -> FloatArray:
        """Wheel speeds (rad/s; left, right) giving a body speed (m/s) and yaw rate (deg/s)."""
        half = math.radians(angular_velocity) * self.track_width / 2.0
        return np.array([linear_velocity - half, linear_velocity + half]) / self.wheel_radius

    def observe(self, linear_velocity: float, angular_velocity: float) -> None:
        """Update the gains from one reading of the robot's body speed and yaw rate.

        The reading is paired with the command sent ``lag`` cycles before it; a wheel
        learns from it only if the behavior had asked for the same speed of it (within
        ``CALIBRATION_STEADY_SHARE``) for ``steady`` cycles before. Before there is such
        a command, and from a non-finite reading, nothing is learned.
        """
        history = len(self._sent)
        if not (math.isfinite(linear_velocity) and math.isfinite(angular_velocity)):
            return
        self._note_jitter(np.array([linear_velocity, math.radians(angular_velocity)]))
        if history < self.lag:
            return
        # the behavior's commands up to the one paired with this reading: held steady, by
        # the rule the demonstrations' pairs are chosen by (the correction's own slow
        # changes do not count as a change of command)
        asked = np.asarray(self._asked[: history - self.lag + 1]) - self.rest
        steady = _held(asked, self.steady)[-1]
        u = self._sent[-self.lag] - self.rest
        w = self.wheel_speeds(linear_velocity, angular_velocity) - self.rest
        learn = np.where(steady, 1.0, 0.0)
        self._suu = self.forget * self._suu + learn * u * u
        self._suw = self.forget * self._suw + learn * u * w
        # a tiny floor keeps 0 / 0 at gain 1 once a long pause has faded both sums away
        measured = np.clip((self._suw + _FLOOR) / (self._suu + _FLOOR), *self.bounds)
        self.measured_gains = measured
        # only the wheels' difference is corrected: a gain both share (a slow motor
        # response, a speed limit) is the closed loop's to ride out (see the module)
        share = measured / float(np.mean(measured))
        self.gains = (self.reference + self._trust(measured) * (share - self.reference)) / (
            self.reference
        )

    def _note_jitter(self, reading: FloatArray) -> None:
        """Record a reading's second difference: its noise, apart from the motion."""
        self._readings.append(reading)
        if len(self._readings) < 3:
            return
        first, middle, last = self._readings[-3:]
        del self._readings[0]
        self._jitter.append(np.abs(last - 2.0 * middle + first))

    def _trust(self, measured: FloatArray) -> float:
        """How much of the measured difference between the wheels to correct (0 to 1):
        what lies beyond ``CALIBRATION_Z`` standard errors of it.

        A wheel's speed reading ``(v ∓ ω W / 2) / r`` carries the readings' noise: white
        noise of σ gives second differences of σ √6, whose size the median of the last
        ``CALIBRATION_NOISE_WINDOW`` gives robustly (a smooth motion adds little). A
        gain's standard error is that noise over the evidence ``Σ λ^k u²`` (the prior's
        included; with forgetting the estimate's variance is smaller, by up to the factor
        1 + λ, so ``CALIBRATION_Z`` errs on the side of leaving the commands alone).
        """
        departure = abs(math.log(measured[0] / measured[1]) - self._reference_log_ratio)
        if departure <= 0.0 or not self._jitter:
            return 1.0
        sigma = np.median(np.asarray(self._jitter), axis=0) / _MEDIAN_ABS
        noise = sigma**2 / 6.0  # variance of a reading of v (m/s)² and ω (rad/s)²
        wheel = (noise[0] + noise[1] * (self.track_width / 2.0) ** 2) / self.wheel_radius**2
        relative = np.sqrt(wheel / self._suu) / measured
        error = float(np.hypot(relative[0], relative[1]))
        return max(0.0, 1.0 - (CALIBRATION_Z * error / departure) ** 2)

    def correct(self, command: FloatArray) -> FloatArray:
        """The command to send for the wheel speeds ``command`` asks for (rad/s)."""
        u = np.asarray(command, dtype=np.float64)
        sent = np.clip(
            self.rest + (u - self.rest) / self.gains, -self.max_wheel_speed, self.max_wheel_speed
        )
        self._sent.append(sent)
        self._asked.append(u)
        if len(self._sent) > self.lag + self.steady:
            del self._sent[0]
            del self._asked[0]
        return sent


def _held(commands: FloatArray, steady: int) -> NDArray[np.bool_]:
    """Per row and wheel: the command was held (within the share) for ``steady`` rows
    before it (False for the first ``steady`` rows)."""
    n = len(commands)
    out = np.zeros(commands.shape, dtype=bool)
    if n <= steady:
        return out
    spread = np.zeros((n - steady, commands.shape[1]))
    for k in range(1, steady + 1):
        spread = np.maximum(spread, np.abs(commands[steady - k : n - k] - commands[steady:]))
    out[steady:] = spread <= CALIBRATION_STEADY_SHARE * np.abs(commands[steady:])
    return out


def wheel_response(
    commands: FloatArray,
    linear_velocity: FloatArray,
    angular_velocity: FloatArray,
    lengths: Sequence[int] | NDArray[np.int64],
    *,
    rest: FloatArray | None = None,
    lag: int = CALIBRATION_LAG,
    steady: int = CALIBRATION_STEADY_CYCLES,
) -> FloatArray:
    """How demonstrated wheels answered their commands, as sums a geometry turns into gains.

    Over every pair (a command a wheel held for ``steady`` cycles, the reading ``lag``
    cycles later) within each episode, exactly the pairs :class:`WheelCalibration` learns
    from, row ``i`` (left, right) holds ``Σ u_i²``, ``Σ u_i v`` and ``Σ u_i ω`` (``u``
    relative to ``rest``; ``v`` m/s, ``ω`` deg/s). Sums of two datasets add up to the sums
    of both (a model's ``partial_fit``). :func:`reference_gains` makes the gains.

    Parameters
    ----------
    commands
        ``(n, 2)`` wheel commands (rad/s), left and right.
    linear_velocity, angular_velocity
        ``(n,)`` measured body speed (m/s) and yaw rate (deg/s), row by row.
    lengths
        Rows per episode.
    """
    u_all = np.asarray(commands, dtype=np.float64)
    if u_all.ndim != 2 or u_all.shape[1] != 2:
        raise ConfigError(f"wheel_response needs (n, 2) wheel commands, got {u_all.shape}")
    u_all = u_all - (np.zeros(2) if rest is None else np.asarray(rest, dtype=np.float64))
    v_all = np.asarray(linear_velocity, dtype=np.float64)
    w_all = np.asarray(angular_velocity, dtype=np.float64)
    sums = np.zeros((2, 3))
    start = 0
    for n in np.asarray(lengths, dtype=np.int64).tolist():
        u, v, w = u_all[start : start + n], v_all[start : start + n], w_all[start : start + n]
        start += n
        if n <= lag:
            continue
        held = _held(u, steady)[: n - lag]
        paired, later_v, later_w = u[: n - lag], v[lag:], w[lag:]
        ok = held & np.isfinite(later_v)[:, None] & np.isfinite(later_w)[:, None]
        weight = np.where(ok, paired, 0.0)
        sums[:, 0] += np.sum(weight * paired, axis=0)
        sums[:, 1] += weight.T @ np.where(np.isfinite(later_v), later_v, 0.0)
        sums[:, 2] += weight.T @ np.where(np.isfinite(later_w), later_w, 0.0)
    return sums


def reference_gains(response: FloatArray, wheel_radius: float, track_width: float) -> FloatArray:
    """Each wheel's gain (measured speed per unit of command) from :func:`wheel_response`'s
    sums and the robot's geometry; 1 for a wheel the sums never saw turning."""
    sums = np.asarray(response, dtype=np.float64)
    if sums.shape != (2, 3) or not np.all(np.isfinite(sums)):
        raise ConfigError(f"a wheel response must be 2 x 3 finite sums, got shape {sums.shape}")
    half = np.radians(sums[:, 2]) * track_width / 2.0
    speed = np.array([sums[0, 1] - half[0], sums[1, 1] + half[1]]) / wheel_radius
    seen = sums[:, 0] > 1e-9
    gains = np.where(seen, speed / np.where(seen, sums[:, 0], 1.0), 1.0)
    return np.clip(gains, *CALIBRATION_BOUNDS)


def _missing(robot: Robot) -> str:
    """Why ``robot`` cannot be calibrated ('' when it can)."""
    if tuple(robot.command_channels) != CALIBRATION_COMMANDS:
        return (
            f"the robot's commands are {', '.join(robot.command_channels)}, not the two "
            "wheels left, right"
        )
    lacking = [c for c in CALIBRATION_CHANNELS if c not in robot.channels or c in robot.derived]
    if lacking:
        return f"the robot does not measure {', '.join(lacking)}"
    try:
        _ = robot.spec
    except ConfigError:
        return "the robot declares no wheel geometry (robot_spec)"
    return ""
