"""Input and parameter checks shared by the CobART estimators (thesis table 4.1 ranges)."""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from behavior_hmm.errors import ConfigError, DatasetError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def check_unit_interval(name: str, value: Any) -> float:
    """A real number in [0, 1] (parameters a, b, d, rho, w_f)."""
    v = _real(name, value)
    if not 0.0 <= v <= 1.0:
        raise ConfigError(f"{name} must lie in [0, 1], got {value!r}")
    return v


def check_alpha(value: Any) -> float:
    """The learning-rate decrease alpha: a finite real number <= 0."""
    v = _real("alpha", value)
    if not v <= 0.0:
        raise ConfigError(f"alpha must be <= 0 (thesis table 4.1), got {value!r}")
    return v


def check_window(value: Any) -> int:
    """The window length I: an integer >= 1."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ConfigError(f"window (I) must be an integer >= 1, got {value!r}")
    if int(value) < 1:
        raise ConfigError(f"window (I) must be an integer >= 1, got {value!r}")
    return int(value)


def check_positive(name: str, value: Any) -> float:
    """A finite real number > 0 (similarity scales)."""
    v = _real(name, value)
    if not v > 0.0:
        raise ConfigError(f"{name} must be > 0, got {value!r}")
    return v


def check_dcm_scale(value: Any, n_channels: int | None) -> FloatArray | None:
    """``"auto"`` (None returned) or one positive scale per channel (normalized units per step)."""
    if isinstance(value, str):
        if value != "auto":
            raise ConfigError(
                f"dcm_scale must be 'auto', a number or one number per channel, got {value!r}"
            )
        return None
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        v = check_positive("dcm_scale", value)
        return np.full(n_channels if n_channels is not None else 1, v)
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(
            f"dcm_scale must be 'auto', a number or one number per channel, got {value!r}"
        ) from None
    if arr.ndim != 1 or arr.size == 0:
        raise ConfigError(
            f"dcm_scale must be 'auto', a number or one number per channel, got {value!r}"
        )
    if not (np.all(np.isfinite(arr)) and np.all(arr > 0.0)):
        raise ConfigError(f"every dcm_scale must be finite and > 0, got {value!r}")
    if n_channels is not None and arr.size != n_channels:
        raise ConfigError(
            f"dcm_scale has {arr.size} entries but the data has {n_channels} channels"
        )
    return arr.copy()


def _real(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ConfigError(f"{name} must be a real number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise ConfigError(f"{name} must be finite, got {value!r}")
    return v


def check_data(
    X: ArrayLike, lengths: Sequence[int] | ArrayLike | None
) -> tuple[FloatArray, IntArray]:
    """Validate normalized data and episode lengths.

    Parameters
    ----------
    X
        Filtered, normalized readings, shape ``(n_samples, n_channels)``; a 1-D array is
        one channel. Values are expected in about [-1, 1].
    lengths
        Samples per episode (hmmlearn style); ``None`` means one episode.

    Returns
    -------
    X, lengths
        ``X`` as a C-contiguous float64 ``(n, C)`` array and ``lengths`` as int64.

    Raises
    ------
    DatasetError
        Empty, non-numeric, wrongly shaped data, or NaN/inf (the message names episode and row).
    ConfigError
        ``lengths`` not positive integers summing to ``n_samples``.
    """
    try:
        arr = np.asarray(X, dtype=np.float64)
    except (TypeError, ValueError):
        raise DatasetError("X must be numeric readings of shape (n_samples, n_channels)") from None
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise DatasetError(f"X must have shape (n_samples, n_channels), got {arr.ndim} dimensions")
    n, c = arr.shape
    if n == 0:
        raise DatasetError("X has no samples")
    if c == 0:
        raise DatasetError("X has no channels")
    lens = check_lengths(lengths, n)
    finite = np.isfinite(arr)
    if not finite.all():
        row, col = (int(i) for i in np.argwhere(~finite)[0])
        starts = np.cumsum(lens) - lens
        ep = int(np.searchsorted(starts, row, side="right") - 1)
        raise DatasetError(
            "NaN or infinite value in X",
            episode=ep,
            row=row - int(starts[ep]),
            field=f"channel {col}",
        )
    return np.ascontiguousarray(arr), lens


def check_lengths(lengths: Sequence[int] | ArrayLike | None, n_samples: int) -> IntArray:
    """Episode lengths: positive integers summing to ``n_samples`` (None = one episode)."""
    if lengths is None:
        return np.array([n_samples], dtype=np.int64)
    try:
        raw = np.asarray(lengths)
    except (TypeError, ValueError):
        raise ConfigError("lengths must be a sequence of positive integers") from None
    if raw.ndim != 1 or raw.size == 0:
        raise ConfigError("lengths must be a non-empty 1-D sequence of positive integers")
    if raw.dtype.kind not in "iu":
        if (
            raw.dtype.kind != "f"
            or not np.all(np.isfinite(raw))
            or not np.all(raw == np.round(raw))
        ):
            raise ConfigError("lengths must be integers")
    lens = raw.astype(np.int64)
    if np.any(lens < 1):
        raise ConfigError("every episode length must be >= 1")
    total = int(lens.sum())
    if total != n_samples:
        raise ConfigError(f"lengths sum to {total} but X has {n_samples} samples")
    return lens


def check_ranges(ranges: ArrayLike, n_channels: int) -> FloatArray:
    """Physical ``(lo, hi)`` per channel with ``lo < hi``, shape ``(C, 2)``."""
    try:
        arr = np.asarray(ranges, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError("ranges must be one (lo, hi) pair per channel") from None
    if arr.shape == (2,) and n_channels == 1:
        arr = arr[None, :]
    if arr.shape != (n_channels, 2):
        raise ConfigError(f"ranges must be {n_channels} (lo, hi) pairs, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)) or not np.all(arr[:, 1] > arr[:, 0]):
        raise ConfigError("every range must be finite with lo < hi")
    return arr
