"""Counting estimation of the Behavior-HMM tables (thesis §4.2, table 4.3).

The transition and emission counts are sparse (:mod:`behavior_hmm.hmm._tables`). All
functions work on integer label sequences, one label per control cycle, several
episodes concatenated (``lengths`` gives the samples per episode, hmmlearn style).
Transitions are never counted across an episode boundary.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_array

from behavior_hmm.hmm._tables import canonical, count_pairs, entry_rows, grown_sparse

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
) -> csr_array:
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
    scipy.sparse.csr_array of int64, shape (n, n)
        ``counts[i, j]`` = number of transitions i → j (canonical: sorted, no zeros).
    """
    same = same_episode_mask(labels.size, lengths)
    src = labels[:-1][same]
    dst = labels[1:][same]
    if counting == "changes" or not self_transitions:
        moved = src != dst
        src, dst = src[moved], dst[moved]
    if counting == "changes" and self_transitions:
        seen = np.flatnonzero(np.bincount(labels, minlength=n) > 0)
        src = np.concatenate([src, seen])  # one self transition per label seen
        dst = np.concatenate([dst, seen])
    return count_pairs(src, dst, (n, n))


def count_emissions(
    states: IntArray, observations: IntArray, n_states: int, n_obs: int
) -> csr_array:
    """State/observation co-occurrences per control cycle (B), sparse (n_states, n_obs)."""
    return count_pairs(states, observations, (n_states, n_obs))


def count_density(states: IntArray, n_states: int) -> IntArray:
    """Control cycles spent in each state (the density that gives π), shape (n_states,)."""
    return np.bincount(states, minlength=n_states).astype(np.int64)


def grown(counts: NDArray[np.generic], shape: tuple[int, ...]) -> IntArray:
    """``counts`` as int64, enlarged to ``shape`` with zeros (new trailing entries).

    Every axis of ``shape`` must be at least as long as that of ``counts``: tables only
    grow (new states or observation categories get the highest indices).
    """
    c = np.asarray(counts, dtype=np.int64)
    if c.ndim != len(shape) or any(a > b for a, b in zip(c.shape, shape, strict=True)):
        raise ValueError(f"cannot grow a table of shape {c.shape} to {shape}")
    out = np.zeros(shape, dtype=np.int64)
    out[tuple(slice(0, k) for k in c.shape)] = c
    return out


def add_counts(old: NDArray[np.generic], new: IntArray) -> IntArray:
    """Counts of two disjoint sets of episodes added (``old`` grown to ``new``'s shape).

    Exact for π and the episode starts: every count is a sum over episodes.
    """
    return grown(old, new.shape) + new


def add_tables(
    old: csr_array,
    new: csr_array,
    *,
    counting: Counting | None = None,
    self_transitions: bool = False,
) -> csr_array:
    """Sparse counts of two disjoint sets of episodes, combined exactly.

    Emissions (B; ``counting=None``) and transitions counted with ``"steps"`` or without
    self transitions add up. With ``counting="changes"`` and ``self_transitions``,
    :func:`count_transitions` puts one self transition on every label seen in the data,
    so the combined diagonal is 1 where the label was seen in either part. The result
    equals the counts of both parts' episodes together.

    Parameters
    ----------
    old
        Counts of the earlier episodes; no larger than ``new`` on either axis.
    new
        Counts of the new episodes, made with the same rule.
    counting, self_transitions
        The rule transitions were counted with (see :func:`count_transitions`).
    """
    total = canonical(grown_sparse(old, new.shape) + new)
    if counting == "changes" and self_transitions:
        on_diagonal = entry_rows(total.indptr) == total.indices
        total.data[on_diagonal] = 1
    return total


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
