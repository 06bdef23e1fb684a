"""Confirming a goal on noisy readings: average the raw readings of a robot held at rest.

A stop rule reads the filtered readings. Under sensor noise they still wander: the 2 Hz
filter leaves about a third of the noise (σ 0.02 of the bearing's range is 7.2° a
reading, 2.3° filtered), so a robot 3.4° off its bearing reads inside the 3° tolerance
a third of the time, and a run ends there. At rest the true state does not change, so
the mean of ``n`` raw readings has ``1/√n`` of their noise: the robot holds still, and
the goal is confirmed once the mean lies inside the tolerance by ``CONFIRM_Z`` standard
errors, or refuted once it lies outside by ``REFUTE_Z`` (the robot then moves on toward
its goal); after ``CONFIRM_CYCLES`` readings it is confirmed only if the mean lies inside
by ``FINAL_Z``, so a robot left undecided at the tolerance's edge moves on rather than
ending there on a coin toss. Once begun, a confirmation runs to its verdict: the filtered readings
leaving the tolerance meanwhile do not end it (their flicker used to restart it, and the
robot dithered at the goal's edge until its step limit).

How noisy the readings are is estimated from the run itself (and, once ``SPREAD_MIN``
readings are held at rest, from their own spread): white noise of standard
deviation σ gives second differences of standard deviation √6 σ, while a robot's smooth
motion gives almost none (turning at 45 °/s², a 16 ms cycle: 0.01°). The median of
their absolute values over the last ``NOISE_WINDOW`` cycles is robust to a push's jump. Noise
below ``QUIET`` of a channel's tolerance changes nothing: the stop rule ends the run
as before, so a noise-free run is the same bit for bit.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping

import numpy as np

from behavior_hmm.data._channels import ChannelSpec

#: Standard errors the mean of the raw readings at rest must lie inside the goal's
#: tolerance to confirm it (looked at every reading, so 2 let a goal 3.15 deg off a
#: 3 deg tolerance, noise 7.2 deg, be confirmed in 44 % of 200 draws, 3 in 13 %) ...
CONFIRM_Z = 3.0
#: ... and outside, over at least ``REFUTE_MIN`` readings, to refute it: a refuted goal
#: sets the robot moving again, so it must be beyond doubt (with 2 standard errors from
#: the first reading on, one reading 3 sigma off refuted a goal held 4 mm inside).
REFUTE_Z = 3.0
REFUTE_MIN = 8
#: Cycles a robot is held at rest at most to confirm its goal (2 s at 16 ms) ...
CONFIRM_CYCLES = 128
#: ... after which the mean must lie inside the tolerance by this many standard errors,
#: or the goal counts as refuted (the robot moves on toward it: a complex behavior
#: repairs toward half the tolerance). With 0 the last look was a coin toss for a robot
#: at the tolerance's edge: turn & approach, MuJoCo, noise 0.02, noise seeds 0-4 ended
#: 3 of 75 runs 3.1-3.4 deg off; with 1 (and ``CONFIRM_Z`` 3) none.
FINAL_Z = 1.0
#: Readings held at rest from which their own spread is the noise (before: the estimate).
SPREAD_MIN = 16
#: Second differences the noise estimate is the median of.
NOISE_WINDOW = 128
#: Fewer second differences than this: no estimate (no confirmation).
NOISE_MIN = 8
#: Noise (one reading's standard deviation) below this share of a channel's tolerance
#: counts as none: the goal is not confirmed, the stop rule decides alone.
QUIET = 0.05
#: Cycles a refuted goal's stop rule waits while the generators move the robot on.
REFUTED_HOLD_CYCLES = 32

#: median |x| of a normal variable, in standard deviations
_MEDIAN_ABS = 0.6744897501960817


class GoalConfirmation:
    """Noise estimate of the goal channels' raw readings and the confirmation of a goal.

    Parameters
    ----------
    specs
        The channels' specs (tolerance, wrapping), by name.
    """

    def __init__(self, specs: Mapping[str, ChannelSpec]) -> None:
        self._specs = specs
        self.reset()

    def reset(self) -> None:
        """Forget the run (noise history and any confirmation in progress)."""
        self._last: dict[str, tuple[float, float]] = {}
        self._second: dict[str, deque[float]] = {}
        self._hold = 0
        self._estimate: dict[str, float] = {}
        self.abandon()

    def abandon(self) -> None:
        """Forget a confirmation in progress."""
        self._n = 0
        self._sums: dict[str, float] = {}
        self._squares: dict[str, float] = {}
        self._pending = False

    def begin(self) -> None:
        """Start confirming a goal: every reading from now on counts until it is decided
        (the filtered readings may leave the tolerance meanwhile: the mean decides)."""
        self._pending = True

    @property
    def pending(self) -> bool:
        """Whether a goal is being confirmed (begun, not decided yet)."""
        return self._pending

    @property
    def estimate(self) -> dict[str, float]:
        """The last refuted goal's channels where the mean of the raw readings put them."""
        return dict(self._estimate)

    @property
    def holding(self) -> bool:
        """Whether a refuted goal keeps the stop rule waiting this cycle."""
        return self._hold > 0

    def observe(self, reading: Mapping[str, float], goal: Mapping[str, float]) -> None:
        """Record one cycle's raw readings of the goal channels (call every cycle)."""
        if self._hold > 0:
            self._hold -= 1
        for name in goal:
            spec = self._specs[name]
            value = float(reading[name])
            if not math.isfinite(value):
                continue
            prev = self._last.get(name)
            if prev is not None:
                last, step = prev
                diff = spec.error(value, last)
                if math.isfinite(step):
                    history = self._second.setdefault(name, deque(maxlen=NOISE_WINDOW))
                    history.append(abs(diff - step))
                self._last[name] = (value, diff)
            else:
                self._last[name] = (value, math.nan)

    def noise_known(self, goal: Mapping[str, float]) -> bool:
        """Whether every goal channel has been read long enough for a noise estimate
        (``NOISE_MIN`` second differences: ``NOISE_MIN + 2`` readings)."""
        return all(len(self._second.get(name, ())) >= NOISE_MIN for name in goal)

    def noise(self, name: str) -> float:
        """Estimated standard deviation of one raw reading of ``name`` (0: too few cycles)."""
        history = self._second.get(name, ())
        if len(history) < NOISE_MIN:
            return 0.0
        return float(np.median(history)) / (_MEDIAN_ABS * math.sqrt(6.0))

    def _spread(self, name: str, n: int, mean: float) -> float:
        """One reading's standard deviation while the goal is confirmed: from ``SPREAD_MIN``
        readings on, their own spread (the robot holds still, so it is the noise's; the
        median of the second differences has about twice its sampling error, and a
        confirmation on 128 readings stopped 3.4 deg off with the noise estimated 18 %
        low), before that the run's noise estimate."""
        if n < SPREAD_MIN:
            return self.noise(name)
        return math.sqrt(max(self._squares[name] - n * mean * mean, 0.0) / (n - 1))

    def needed(self, goal: Mapping[str, float], scale: float = 1.0) -> bool:
        """Whether the readings are noisy enough that a goal must be confirmed at rest."""
        return any(
            self.noise(name) > QUIET * scale * float(self._specs[name].tolerance or 0.0)
            for name in goal
        )

    def confirm(
        self, reading: Mapping[str, float], goal: Mapping[str, float], scale: float = 1.0
    ) -> bool | None:
        """One reading at rest: True confirmed, False refuted, None not decided yet (it
        begins the confirmation if :meth:`begin` has not).

        ``scale`` times each channel's tolerance is the goal's. A refuted goal holds the
        stop rule off for ``REFUTED_HOLD_CYCLES`` (:attr:`holding`).
        """
        self._pending = True
        self._n += 1
        n = self._n
        confirmed, refuted = True, False
        means: dict[str, tuple[float, float, float]] = {}
        for name, target in goal.items():
            spec = self._specs[name]
            value = spec.error(float(reading[name]), target)
            self._sums[name] = self._sums.get(name, 0.0) + value
            self._squares[name] = self._squares.get(name, 0.0) + value * value
            mean = self._sums[name] / n
            error = self._spread(name, n, mean) / math.sqrt(n)  # the mean's standard error
            tol = scale * float(spec.tolerance or 0.0)
            means[name] = (abs(mean), error, tol)
            confirmed = confirmed and abs(mean) + CONFIRM_Z * error <= tol
            refuted = refuted or (n >= REFUTE_MIN and abs(mean) - REFUTE_Z * error > tol)
        if n >= CONFIRM_CYCLES and not confirmed and not refuted:  # the last look
            confirmed = all(m + FINAL_Z * e <= tol for m, e, tol in means.values())
            refuted = not confirmed
        if confirmed:
            self.abandon()
            return True
        if refuted:
            self._estimate = {name: goal[name] + self._sums[name] / n for name in goal}
            self.abandon()
            self._hold = REFUTED_HOLD_CYCLES
            return False
        return None
