"""EDM and DCM similarities and the CobART matching score (thesis §3.2, DESIGN §5).

These are the readable reference definitions; the estimators use an equivalent
vectorized form (``_layout``) and the tests check that both agree.

Windows are arrays with time on axis ``-2`` and channels on axis ``-1`` (shape
``(..., I, C)``); a 1-D array is one channel (shape ``(I,)``). Leading axes
broadcast, so ``(K, I, C)`` prototypes against one ``(I, C)`` window give ``(K, C)``.
Values are normalized readings (about [-1, 1]).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from behavior_hmm.cobart._validation import check_data, check_positive
from behavior_hmm.errors import ConfigError

FloatArray = NDArray[np.float64]

#: Default EDM scale: similarity 0 at an RMS difference of 1 normalized unit (half the range).
DEFAULT_EDM_SCALE: Final[float] = 1.0

#: Fallback DCM scale (normalized units per control step, ~0.9 deg per 16 ms step for an
#: angle normalized by 180 deg): used where ``"auto"`` finds a channel that never moves.
DEFAULT_DCM_SCALE: Final[float] = 0.005

#: Percentile of the per-step changes of moving samples that ``"auto"`` takes as DCM scale.
AUTO_DCM_PERCENTILE: Final[float] = 95.0

#: Per-step changes at or below this (normalized units) count as "not moving" for ``"auto"``.
_STILL: Final[float] = 1e-9


def _pair(p: ArrayLike, z: ArrayLike) -> tuple[FloatArray, FloatArray, bool]:
    pa = np.asarray(p, dtype=np.float64)
    za = np.asarray(z, dtype=np.float64)
    scalar = pa.ndim == 1 and za.ndim == 1
    if pa.ndim == 1:
        pa = pa[:, None]
    if za.ndim == 1:
        za = za[:, None]
    if pa.ndim < 2 or za.ndim < 2 or pa.shape[-2:] != za.shape[-2:]:
        raise ConfigError(
            f"windows must have the same (I, C) shape, got {np.shape(p)} and {np.shape(z)}"
        )
    if pa.shape[-2] == 0:
        raise ConfigError("windows must hold at least one reading")
    return pa, za, scalar


def _scale(scale: float | ArrayLike, n_channels: int, name: str) -> FloatArray:
    arr = np.asarray(scale, dtype=np.float64)
    if arr.ndim == 0:
        return np.full(n_channels, check_positive(name, float(arr)))
    if arr.shape != (n_channels,) or not (np.all(np.isfinite(arr)) and np.all(arr > 0)):
        raise ConfigError(f"{name} must be > 0, one value or one per channel ({n_channels})")
    return arr


def _out(sim: FloatArray, scalar: bool) -> FloatArray | float:
    return float(sim[..., 0]) if scalar and sim.ndim == 1 else sim


def edm_similarity(
    p: ArrayLike, z: ArrayLike, scale: float | ArrayLike = DEFAULT_EDM_SCALE
) -> FloatArray | float:
    """Euclidean-distance similarity per channel, in [0, 1] (1 = identical).

    ``EDM = max(0, 1 - RMS_t(p - z) / scale)``: the thesis's EDM (the root mean square
    difference over the window, eq. in §6.1) mapped onto a similarity.

    Parameters
    ----------
    p, z
        Windows ``(..., I, C)`` or one channel ``(I,)``, normalized units.
    scale
        RMS difference (normalized units) at which the similarity reaches 0; one value
        or one per channel.

    Returns
    -------
    float or ndarray
        A float for two 1-D windows, else shape ``(..., C)``.
    """
    pa, za, scalar = _pair(p, z)
    s = _scale(scale, pa.shape[-1], "edm_scale")
    rms = np.sqrt(np.mean((pa - za) ** 2, axis=-2))
    return _out(np.clip(1.0 - rms / s, 0.0, 1.0), scalar)


def dcm_similarity(
    p: ArrayLike, z: ArrayLike, scale: float | ArrayLike = DEFAULT_DCM_SCALE
) -> FloatArray | float:
    """Derivation-correspondence (shape) similarity per channel, in [0, 1].

    ``DCM = max(0, 1 - RMS_t(Δp - Δz) / scale)`` with ``Δ`` the first difference along
    time (one control step). It ignores an offset between the windows but not the
    rate: a ramp rising ``m`` per step against a flat line scores ``max(0, 1 - m/scale)``.

    Parameters
    ----------
    p, z
        Windows ``(..., I, C)`` with ``I >= 2``, or one channel ``(I,)``.
    scale
        Per-step difference (normalized units per step) at which the similarity reaches
        0; one value or one per channel.

    Raises
    ------
    ConfigError
        Windows of different shapes or shorter than 2 readings (no difference exists).
    """
    pa, za, scalar = _pair(p, z)
    if pa.shape[-2] < 2:
        raise ConfigError("DCM needs windows of at least 2 readings")
    s = _scale(scale, pa.shape[-1], "dcm_scale")
    dd = np.diff(pa, axis=-2) - np.diff(za, axis=-2)
    rms = np.sqrt(np.mean(dd**2, axis=-2))
    return _out(np.clip(1.0 - rms / s, 0.0, 1.0), scalar)


def cobart_score(
    p: ArrayLike,
    z: ArrayLike,
    b: float,
    edm_scale: float | ArrayLike = DEFAULT_EDM_SCALE,
    dcm_scale: float | ArrayLike = DEFAULT_DCM_SCALE,
) -> FloatArray | float:
    """Matching score ``r = mean over channels of (b·DCM + (1 - b)·EDM)``, in [0, 1].

    For windows of one reading (``I = 1``) there is no shape to compare and the score
    is the EDM similarity alone.

    Returns
    -------
    float or ndarray
        A float for ``(I, C)`` / ``(I,)`` windows, else shape of the leading axes.
    """
    pa, za, _ = _pair(p, z)
    edm = np.asarray(edm_similarity(pa, za, edm_scale))
    if pa.shape[-2] < 2:
        sim = edm
    else:
        dcm = np.asarray(dcm_similarity(pa, za, dcm_scale))
        sim = b * dcm + (1.0 - b) * edm
    r = np.clip(np.mean(sim, axis=-1), 0.0, 1.0)
    return float(r) if r.ndim == 0 else r


def suggest_dcm_scale(
    X: ArrayLike,
    lengths: Sequence[int] | ArrayLike | None = None,
    *,
    percentile: float = AUTO_DCM_PERCENTILE,
) -> FloatArray:
    """The ``"auto"`` DCM scale: per channel, a high percentile of how fast it moves.

    Per channel: the ``percentile``-th percentile of ``|x[t] - x[t-1]|`` over the steps
    (within episodes) where the channel moves at all; ``DEFAULT_DCM_SCALE`` for a channel
    that never moves. It approximates the peak per-step change, so a still window and
    one moving at peak rate get DCM 0, and two rates half the peak apart get DCM 0.5.

    Returns
    -------
    ndarray, shape (C,)
        Normalized units per control step.
    """
    if not 0.0 < percentile <= 100.0:
        raise ConfigError(f"percentile must lie in (0, 100], got {percentile!r}")
    arr, lens = check_data(X, lengths)
    diffs = np.abs(np.diff(arr, axis=0))
    keep = np.ones(diffs.shape[0], dtype=bool)
    keep[np.cumsum(lens)[:-1] - 1] = False  # no difference across an episode boundary
    diffs = diffs[keep]
    out = np.full(arr.shape[1], DEFAULT_DCM_SCALE)
    for c in range(arr.shape[1]):
        moving = diffs[:, c][diffs[:, c] > _STILL]
        if moving.size:
            out[c] = float(np.percentile(moving, percentile))
    return out
