"""What a motion generator reads: one feature layout for training and for the policy.

A row is, in this order: the sensor windows (``window`` filtered, normalized readings
of each input channel, channel-major, as :func:`make_windows`), the goal (behavior
cloning's goal-conditioned network), the efference copy (the last ``history``
normalized commands), the command's last change (a generator that outputs changes)
and the onset clock (``min(t, clock) / clock``, t = control cycles since the start).
:meth:`FeatureLayout.offline` builds the rows of whole demonstrations for training;
:meth:`FeatureLayout.online` gives the per-cycle stepper a policy uses, which builds
the same numbers one reading at a time.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.generators._windows import make_windows

FloatArray = NDArray[np.float64]
Lengths = Sequence[int] | NDArray[np.integer[Any]]

#: A generator that outputs changes keeps its command within this (normalized) bound.
DELTA_COMMAND_BOUND = 1.5

#: Default onset clock length in control cycles (~1.5 s at 16 ms): as long as the
#: demonstrations' start-up ramps, which reach 90 % of their peak command after up to 73
#: cycles (turn) and 95 cycles (approach, retreat). A 64-cycle clock saturated mid-ramp.
DEFAULT_ONSET_CLOCK = 96


def command_features(commands: FloatArray, lengths: Lengths, history: int) -> FloatArray:
    """Previous ``history`` normalized commands per row (zeros before an episode starts).

    Row ``t`` holds ``[u[t-history], ..., u[t-1]]`` flattened (every command channel per
    step: left, right for our wheels), the efference copy a motion generator reads beside
    its sensor window.
    """
    n, k = commands.shape[0], commands.shape[1]
    out = np.zeros((n, k * history), dtype=np.float64)
    start = 0
    for length in lengths:
        stop = start + int(length)
        for lag in range(1, history + 1):
            col = k * (history - lag)
            if length > lag:
                out[start + lag : stop, col : col + k] = commands[start : stop - lag]
        start = stop
    return out


def onset_features(lengths: Lengths, clock: int) -> FloatArray:
    """The onset clock per row: ``min(t, clock) / clock``, t = control cycles since the start."""
    steps = np.concatenate([np.arange(int(n)) for n in lengths])
    return (np.minimum(steps, clock) / clock)[:, None]


def onset_floors(
    clock: FloatArray, states: Sequence[int] | NDArray[np.integer[Any]], n: int
) -> FloatArray:
    """The earliest onset clock each of ``n`` primitives' networks was trained on.

    ``clock``: the onset clock column of the training rows; ``states``: each row's
    primitive. A primitive without rows gets 0 (nothing to hold it to). A network of a
    primitive met only mid-motion never read a clock near 0; fed one at a start from
    rest, it extrapolates (``SBLM(onset_floor=True)`` feeds it its floor instead).
    """
    floors = np.zeros(int(n))
    ids = np.asarray(states, dtype=np.int64)
    values = np.asarray(clock, dtype=np.float64)
    present = np.unique(ids)
    if present.size:
        floors[present] = np.full(present.size, np.inf)
        np.minimum.at(floors, ids, values)
    return floors


def input_ranges(
    windows: FloatArray, states: Sequence[int] | NDArray[np.integer[Any]], n: int
) -> FloatArray:
    """The range of sensor-window inputs each of ``n`` primitives' networks was trained on.

    ``windows``: the training rows' sensor-window columns (normalized readings);
    ``states``: each row's primitive. Returns ``(n, 2, columns)``: per primitive the
    lowest (``[:, 0]``) and highest (``[:, 1]``) value of each column among its rows. A
    primitive without rows gets the range of all rows. A network fed readings beyond
    its own rows' (a start farther than any demonstrated, or a category the primitive
    was decoded in but never trained on) extrapolates; ``SBLM(input_range=True)`` clips
    its windows to this range instead.
    """
    values = np.asarray(windows, dtype=np.float64)
    ids = np.asarray(states, dtype=np.int64)
    ranges = np.zeros((int(n), 2, values.shape[1]))
    if values.shape[0] == 0:
        return ranges
    ranges[:, 0] = values.min(axis=0)
    ranges[:, 1] = values.max(axis=0)
    present = np.unique(ids)
    if present.size:
        lo = np.full((int(n), values.shape[1]), np.inf)
        hi = np.full((int(n), values.shape[1]), -np.inf)
        np.minimum.at(lo, ids, values)
        np.maximum.at(hi, ids, values)
        ranges[present, 0] = lo[present]
        ranges[present, 1] = hi[present]
    return ranges


def grown_ranges(old: FloatArray, fresh: FloatArray, states: Any, side: int = 1) -> FloatArray:
    """``input_ranges`` (or ``start_ranges``, ``side=-1``) after an update: ``fresh`` (the
    new rows' ranges, every primitive of the grown model) for a new primitive, the union of
    ``old`` and ``fresh`` for one with new rows (its network is fine-tuned on them), ``old``
    for the rest. ``side``: the axis holding the lowest (0) and highest (1) value; where one
    of ``old`` and ``fresh`` is NaN (no row), the union is the other."""
    grown = np.array(fresh, dtype=np.float64)
    kept = old.shape[0]
    seen = np.zeros(grown.shape[0], dtype=bool)
    seen[np.unique(np.asarray(states, dtype=np.int64))] = True
    mine = seen[:kept].reshape((kept,) + (1,) * (old.ndim - 2))
    lo, hi = np.take(old, 0, axis=side), np.take(old, 1, axis=side)
    new = np.moveaxis(grown[:kept], side, 0)  # a view: written into ``grown``
    new[0] = np.where(mine, np.fmin(lo, new[0]), lo)
    new[1] = np.where(mine, np.fmax(hi, new[1]), hi)
    return grown


def start_ranges(
    windows: FloatArray,
    clock: FloatArray,
    states: Sequence[int] | NDArray[np.integer[Any]],
    n: int,
    n_channels: int,
    cycles: int,
) -> FloatArray:
    """The readings each of ``n`` primitives' networks was shown at each onset clock.

    ``windows``: the training rows' sensor-window columns (normalized readings,
    ``n_channels`` channels of equal windows, channel-major); ``clock``: their onset clock
    column (``min(k, cycles) / cycles`` after ``k`` cycles); ``states``: each row's
    primitive. Returns ``(n, n_channels, cycles + 1, 2)``: entry ``[p, c, k]`` is the
    lowest (``0``) and highest (``1``) reading in channel ``c``'s windows among primitive
    ``p``'s rows whose clock had counted at most ``k`` cycles (NaN where it has none), so
    it widens with ``k`` and its last row is the primitive's whole range.

    A start from rest closer to the goal than any demonstrated start is a reading the
    networks met only late in a run: the approach's nearest start began 0.1 m off, and
    at 4 cm its network, read at clock 0, backed the robot away first.
    ``SBLM(input_range=True)`` clips such a start-up's windows to this range; an update
    grows it with :func:`grown_ranges` (``side=-1``).
    """
    values = np.asarray(windows, dtype=np.float64)
    ids = np.asarray(states, dtype=np.int64)
    ticks = np.clip(np.rint(np.asarray(clock, dtype=np.float64) * cycles), 0, cycles)
    at = (ids, ticks.astype(np.int64))
    window = values.shape[1] // max(int(n_channels), 1)
    out = np.full((int(n), int(n_channels), int(cycles) + 1, 2), np.nan)
    for c in range(int(n_channels)):
        part = values[:, c * window : (c + 1) * window]
        lo = np.full((int(n), int(cycles) + 1), np.inf)
        hi = np.full((int(n), int(cycles) + 1), -np.inf)
        if part.shape[0]:
            np.minimum.at(lo, at, part.min(axis=1))
            np.maximum.at(hi, at, part.max(axis=1))
        lo = np.minimum.accumulate(lo, axis=1)
        hi = np.maximum.accumulate(hi, axis=1)
        seen = np.isfinite(lo)
        out[:, c, :, 0] = np.where(seen, lo, np.nan)
        out[:, c, :, 1] = np.where(seen, hi, np.nan)
    return out


def shifted_windows(
    features: FloatArray, n_channels: int, window: int, sigma: float, rng: np.random.Generator
) -> FloatArray:
    """A copy of ``features`` whose sensor windows are offset by one Gaussian draw per channel.

    The windows are the first ``n_channels * window`` columns, channel-major (as
    :func:`~behavior_hmm.generators.make_windows` lays them out).
    """
    noisy = features.copy()
    offsets = rng.normal(0.0, sigma, size=(features.shape[0], n_channels))
    noisy[:, : n_channels * window] += np.repeat(offsets, window, axis=1)
    return noisy


@dataclass(frozen=True)
class FeatureLayout:
    """The columns of a generator's input row.

    Parameters
    ----------
    n_channels, window
        Input channels and readings per channel in the sensor windows.
    goal
        Goal values in the row (0 for an SBLM's generators; behavior cloning's goal).
    history
        Previous commands in the efference copy (0: none).
    delta
        Whether the generator outputs command changes (then the row also holds the
        command's last change, in units of ``delta_scale``; needs ``history >= 1``).
    clock
        Onset clock length in control cycles (0: no clock).
    delta_scale
        Normalized command change a generator output of 1 stands for.
    n_commands
        Command channels (our wheels: 2): the width of one efference-copy step.
    """

    n_channels: int
    window: int
    goal: int = 0
    history: int = 0
    delta: bool = False
    clock: int = 0
    delta_scale: float = 1.0
    n_commands: int = 2

    @property
    def width(self) -> int:
        """Columns of a row."""
        k = self.n_commands
        delta = k if self.delta and self.history > 0 else 0
        clock = 1 if self.clock > 0 else 0
        return self.n_channels * self.window + self.goal + k * self.history + delta + clock

    def offline(
        self, x: FloatArray, y: FloatArray, lengths: Lengths, goals: FloatArray | None = None
    ) -> FloatArray:
        """Rows of whole demonstrations: ``x`` (n, channels) normalized readings, ``y``
        (n, n_commands) normalized commands, ``goals`` (n, goal) per row (when ``goal > 0``)."""
        parts = [make_windows(x, lengths, self.window)]
        if self.goal:
            if goals is None or goals.shape != (x.shape[0], self.goal):
                raise ValueError(f"goals must have shape ({x.shape[0]}, {self.goal})")
            parts.append(goals)
        if self.history > 0:
            parts.append(command_features(y, lengths, self.history))
            if self.delta:
                # previous command and its last change (in units of delta_scale)
                k = self.n_commands
                prev2 = command_features(y, lengths, 2)
                parts.append(np.clip((prev2[:, k:] - prev2[:, :k]) / self.delta_scale, -1, 1))
        if self.clock > 0:
            parts.append(onset_features(lengths, self.clock))
        return np.hstack(parts) if len(parts) > 1 else parts[0]

    def online(self) -> OnlineFeatures:
        """A fresh stepper building the same rows one reading at a time."""
        return OnlineFeatures(self)


class OnlineFeatures:
    """Per-cycle rows of a :class:`FeatureLayout`, as the policy runs.

    Each cycle: :meth:`push` the filtered, normalized reading; when a command is needed,
    :meth:`row` gives the generator's input (advancing the onset clock), and
    :meth:`commit` turns the generator's output into the command and records it in the
    efference copy.
    """

    def __init__(self, layout: FeatureLayout) -> None:
        self.layout = layout
        self._n = layout.n_channels * layout.window
        self._buf = np.zeros((layout.n_channels, layout.window))
        self._row = np.zeros(layout.width)
        self._u = layout.n_commands  # columns of one command
        self._h = self._n + layout.goal + self._u * layout.history  # end of the efference copy
        self._delta = bool(layout.delta and layout.history > 0)
        self._scale = float(layout.delta_scale)
        self.reset()

    def reset(self) -> None:
        """Forget the run (windows, efference copy, clock); the goal stays."""
        goal = self._row[self._n : self._n + self.layout.goal].copy()
        self._row[:] = 0.0
        self._row[self._n : self._n + self.layout.goal] = goal
        self._started = False
        self._k = 0

    @property
    def cycles(self) -> int:
        """Control cycles the onset clock has counted since the run's start."""
        return self._k

    def resume(self, cycles: int) -> None:
        """Go on counting the onset clock from ``cycles`` (after :meth:`reset`): the run
        resumes where it stopped instead of starting anew."""
        self._k = int(cycles)

    def set_goal(self, goal: FloatArray) -> None:
        """The goal values (normalized) written into every row."""
        self._row[self._n : self._n + self.layout.goal] = goal

    def push(self, x: FloatArray) -> None:
        """Add one filtered, normalized reading (the first one fills the whole window)."""
        if not self._started:
            self._buf[:] = x[:, None]
            self._started = True
        else:
            self._buf[:, :-1] = self._buf[:, 1:]
            self._buf[:, -1] = x

    def row(self) -> FloatArray:
        """The generator's input for this cycle (a view: read it before :meth:`commit`)."""
        row = self._row
        row[: self._n] = self._buf.ravel()
        clock = self.layout.clock
        if clock:
            row[-1] = min(self._k, clock) / clock
        self._k += 1
        return row

    def commit(self, out: FloatArray) -> FloatArray:
        """The normalized command for generator output ``out``; recorded as sent."""
        row, h, k = self._row, self._h, self._u
        if self._delta:
            y = np.clip(
                row[h - k : h] + self._scale * out, -DELTA_COMMAND_BOUND, DELTA_COMMAND_BOUND
            )
            row[h : h + k] = np.clip((y - row[h - k : h]) / self._scale, -1.0, 1.0)
        else:
            y = out
        if self.layout.history:
            hist = row[self._n + self.layout.goal : h]
            hist[:-k] = hist[k:]
            hist[-k:] = y
        return y
