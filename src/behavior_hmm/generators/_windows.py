"""Causal sliding windows of sensor readings: the motion generators' inputs."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from behavior_hmm.errors import ConfigError


def make_windows(
    signals: ArrayLike,
    lengths: Sequence[int] | NDArray[np.integer] | None = None,
    window: int = 10,
) -> NDArray[np.float64]:
    """Build one causal window of the last ``window`` readings per row.

    Parameters
    ----------
    signals
        Readings, shape (n, C) (or (n,) for one channel), normalized to [-1, 1];
        several episodes concatenated one after the other.
    lengths
        Length of each episode, summing to ``n``; ``None`` means one episode.
    window
        Readings per channel in a window (thesis: 10).

    Returns
    -------
    ndarray, shape (n, window * C)
        Row ``t`` holds readings ``t - window + 1 .. t`` of its episode, never
        a later one (causal). Features are channel-major, oldest first:
        ``[c0[t-w+1], ..., c0[t], c1[t-w+1], ..., c1[t], ...]``. Readings before
        the episode's first row are replaced by that first row (the robot was
        at rest there), so an episode's first window is flat.

    Raises
    ------
    ConfigError
        Non-finite readings, a bad window, or lengths that do not sum to ``n``.
    """
    if isinstance(window, bool) or not isinstance(window, int | np.integer) or window < 1:
        raise ConfigError(f"window must be a positive integer, got {window!r}")
    try:
        values = np.asarray(signals, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"signals must be numeric: {exc}") from None
    if values.ndim == 1:
        values = values[:, None]
    if values.ndim != 2:
        raise ConfigError(f"signals must have shape (n, channels), got {values.shape}")
    if not np.isfinite(values).all():
        raise ConfigError("signals contain NaN or infinite values")
    n = values.shape[0]
    episode_lengths = _check_lengths(lengths, n)

    # Index of each row's episode start, then the window's row indices clipped to it.
    starts = np.repeat(np.cumsum(episode_lengths) - episode_lengths, episode_lengths)
    rows = np.arange(n)[:, None] - (window - 1) + np.arange(window)[None, :]
    rows = np.maximum(rows, starts[:, None])
    windows = values[rows]  # (n, window, C)
    return np.ascontiguousarray(windows.transpose(0, 2, 1)).reshape(n, window * values.shape[1])


def _check_lengths(
    lengths: Sequence[int] | NDArray[np.integer] | None, n: int
) -> NDArray[np.int64]:
    if lengths is None:
        return np.array([n] if n > 0 else [], dtype=np.int64)
    try:
        arr = np.asarray(lengths)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"lengths must be integers: {exc}") from None
    if arr.ndim != 1 or (arr.size and arr.dtype.kind not in "iu"):
        raise ConfigError("lengths must be a 1-D sequence of integers")
    arr = arr.astype(np.int64)
    if (arr <= 0).any():
        raise ConfigError("every episode length must be positive")
    if int(arr.sum()) != n:
        raise ConfigError(f"lengths sum to {int(arr.sum())} but signals have {n} rows")
    return arr
