"""The demonstrations' start-up envelope: how far from rest any of them had got by each cycle.

The teacher starts every run from rest with a jerk-limited s-curve. A generator decoded
at rest between demonstrated starts is often one of mid-motion, never shown a start, and
(bounded only by the rate limit) reaches cruising speed in a third of the teacher's
time: on a quarter of the approach grid the robot from 0.41 m commanded 2.18 rad/s after
25 cycles where the teacher commanded 0.41. The envelope bounds such a start by what the
demonstrations did: ``E[t, c]`` is the largest ``|command_c - rest_c|`` any demonstration
reached within its first ``t + 1`` cycles. It is a running maximum, so it never falls,
and it stops where every channel has reached its overall largest value (from there on
it bounds nothing). An episode that began at speed makes its first row that largest
value, and the envelope bounds nothing at all.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def startup_envelope(
    commands: FloatArray, lengths: NDArray[np.int64], rest: FloatArray
) -> FloatArray:
    """The start-up envelope of demonstrations (see the module docstring).

    Parameters
    ----------
    commands
        ``(n_rows, n_commands)`` commands of the episodes in order (physical units, e.g.
        rad/s).
    lengths
        Rows of each episode (each >= 1).
    rest
        ``(n_commands,)`` the command that holds the robot still.

    Returns
    -------
    ndarray of shape (T, n_commands)
        ``E[t]`` for ``t = 0 .. T - 1``; its last row is the largest ``|command - rest|``
        of every channel, reached first at ``T - 1`` by the slowest channel.
    """
    away = np.abs(np.asarray(commands, dtype=np.float64) - np.asarray(rest, dtype=np.float64))
    lengths = np.asarray(lengths, dtype=np.int64)
    longest = int(lengths.max())
    envelope = np.zeros((longest, away.shape[1]))
    start = 0
    for n in lengths.tolist():
        run = np.maximum.accumulate(away[start : start + n], axis=0)
        envelope[:n] = np.maximum(envelope[:n], run)
        envelope[n:] = np.maximum(envelope[n:], run[-1])  # a stopped episode keeps its top
        start += n
    return _cut(envelope)


def merged_envelope(a: FloatArray, b: FloatArray) -> FloatArray:
    """The envelope of two sets of demonstrations from the envelopes of each: exactly what
    :func:`startup_envelope` gives on them together."""
    longest = max(a.shape[0], b.shape[0])
    both = np.maximum(_padded(a, longest), _padded(b, longest))
    return _cut(both)


def _padded(envelope: FloatArray, rows: int) -> FloatArray:
    """``envelope`` held at its last row (its top) up to ``rows`` rows."""
    extra = np.repeat(envelope[-1:], rows - envelope.shape[0], axis=0)
    return np.concatenate([envelope, extra])


def _cut(envelope: FloatArray) -> FloatArray:
    """``envelope`` up to the first row where every channel is at its top."""
    top = envelope[-1]
    reached = int(np.argmax(np.all(envelope >= top, axis=1)))
    return envelope[: reached + 1].copy()
