"""Counting estimation of the Behavior-HMM tables (thesis §4.2, table 4.3).

All functions work on integer label sequences, one label per control cycle, several
episodes concatenated (``lengths`` gives the samples per episode, hmmlearn style).
Transitions are never counted across an episode boundary.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import NDArray

Counting = Literal["changes", "steps"]

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


def same_episode_mask(n_samples: int, lengths: IntArray) -> NDArray[np.bool_]:
    """Mask over the ``n_samples - 1`` consecutive pairs: True where both lie in one episode."""
    mask = np.ones(max(n_samples - 1, 0), dtype=bool)
    ends = np.cumsum(lengths)[:-1]  # index of the first sample of every later episode
    mask[ends - 1] = False
    return mask


def episode_starts(lengths: IntArray) -> IntArray:
    """Index of the first sample of each episode."""
    return np.concatenate(([0], np.cumsum(lengths)[:-1])).astype(np.int64)


def count_transitions(
    labels: IntArray,
    n: int,
    lengths: IntArray,
    *,
    counting: Counting,
    self_transitions: bool,
) -> IntArray:
    """Count label-to-label transitions (A for states, C for observations).

    Parameters
    ----------
    labels
        Label per control cycle, values in ``[0, n)``.
    n
        Number of labels (rows and columns of the result).
    lengths
        Samples per episode; pairs across a boundary are not counted.
    counting
        ``"changes"`` (thesis table 4.3): a transition is counted only when the label
        changes; with ``self_transitions`` one self transition is added to every label
        that occurs in the data. ``"steps"``: every pair of consecutive cycles is
        counted, equal pairs included when ``self_transitions``.
    self_transitions
        Whether the diagonal is counted at all.

    Returns
    -------
    ndarray of int64, shape (n, n)
        ``counts[i, j]`` = number of transitions i → j.
    """
    same = same_episode_mask(labels.size, lengths)
    src = labels[:-1][same]
    dst = labels[1:][same]
    counts = np.bincount(src * n + dst, minlength=n * n).reshape(n, n).astype(np.int64)
    if counting == "changes" or not self_transitions:
        np.fill_diagonal(counts, 0)
    if counting == "changes" and self_transitions:
        seen = np.bincount(labels, minlength=n) > 0
        counts[seen, seen] += 1
    return counts


def count_emissions(
    states: IntArray, observations: IntArray, n_states: int, n_obs: int
) -> IntArray:
    """Count state/observation co-occurrences per control cycle (B), shape (n_states, n_obs)."""
    flat = states * n_obs + observations
    return np.bincount(flat, minlength=n_states * n_obs).reshape(n_states, n_obs).astype(np.int64)


def count_density(states: IntArray, n_states: int) -> IntArray:
    """Control cycles spent in each state (the density that gives π), shape (n_states,)."""
    return np.bincount(states, minlength=n_states).astype(np.int64)


def normalize(counts: NDArray[np.generic], smoothing: float, *, zero_diagonal: bool) -> FloatArray:
    """Turn counts into probabilities along the last axis.

    ``smoothing`` pseudo-counts are added to every cell (except a structurally zero
    diagonal when ``zero_diagonal``). A row whose total is zero stays all zero: never NaN.
    """
    c = np.asarray(counts, dtype=np.float64).copy()
    if smoothing > 0.0:
        c += smoothing
        if zero_diagonal and c.ndim == 2:
            np.fill_diagonal(c, 0.0)
    total = c.sum(axis=-1, keepdims=True)
    out = np.zeros_like(c)
    np.divide(c, total, out=out, where=total > 0.0)
    return out


def safe_log(p: FloatArray) -> FloatArray:
    """Natural log with log(0) = −inf and no warning."""
    with np.errstate(divide="ignore"):
        return np.log(p)
