"""Label-sequence summaries for the thesis §6.1 categorization experiments."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from behavior_hmm.cobart._validation import check_lengths
from behavior_hmm.errors import ConfigError

IntArray = NDArray[np.int64]


def _labels(labels: ArrayLike) -> IntArray:
    arr = np.asarray(labels)
    if arr.ndim != 1:
        raise ConfigError(f"labels must be 1-D, got shape {arr.shape}")
    if arr.size and (arr.dtype.kind not in "iu" or int(arr.min()) < 0):
        raise ConfigError("labels must be non-negative integers")
    return arr.astype(np.int64)


def primitive_sequence(labels: ArrayLike) -> list[int]:
    """Collapse runs of equal labels: ``[3, 3, 4, 4, 4, 1] -> [3, 4, 1]`` (thesis table 6.1).

    Parameters
    ----------
    labels
        One category per time step of one episode.
    """
    arr = _labels(labels)
    if arr.size == 0:
        return []
    keep = np.ones(arr.size, dtype=bool)
    keep[1:] = arr[1:] != arr[:-1]
    return [int(v) for v in arr[keep]]


def transition_counts(
    labels: ArrayLike,
    lengths: Sequence[int] | ArrayLike | None = None,
    n_categories: int | None = None,
    *,
    collapse: bool = False,
) -> IntArray:
    """Count category-to-category transitions within episodes (thesis figs. 6.2/6.4).

    Parameters
    ----------
    labels
        One category per time step, episodes concatenated.
    lengths
        Samples per episode (``None``: one episode); no transition crosses episodes.
    n_categories
        Size ``K`` of the result (default ``max(labels) + 1``).
    collapse
        ``False``: every pair of consecutive steps counts, self-transitions included.
        ``True``: only changes of category count (runs collapsed, empty diagonal).

    Returns
    -------
    ndarray, shape (K, K)
        ``counts[i, j]`` = number of steps from category ``i`` to category ``j``.
    """
    arr = _labels(labels)
    lens = check_lengths(lengths, arr.size) if arr.size else np.zeros(0, dtype=np.int64)
    k = int(arr.max()) + 1 if arr.size else 0
    if n_categories is not None:
        if n_categories < k:
            raise ConfigError(f"n_categories={n_categories} but labels go up to {k - 1}")
        k = int(n_categories)
    out = np.zeros((k, k), dtype=np.int64)
    if arr.size < 2:
        return out
    same = np.ones(arr.size - 1, dtype=bool)
    same[np.cumsum(lens)[:-1] - 1] = False
    src, dst = arr[:-1][same], arr[1:][same]
    if collapse:
        moved = src != dst
        src, dst = src[moved], dst[moved]
    np.add.at(out, (src, dst), 1)
    return out
