"""The thesis's success rate (DESIGN §6) and the figures reported beside it."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from behavior_hmm.errors import ConfigError


def edm(a: ArrayLike, b: ArrayLike) -> float:
    """Euclidean distance method of the thesis: RMS difference of two equal-shape arrays."""
    x = np.asarray(a, dtype=np.float64)
    y = np.asarray(b, dtype=np.float64)
    if x.shape != y.shape:
        raise ConfigError(f"edm needs equal shapes, got {x.shape} and {y.shape}")
    if x.size == 0:
        return 0.0
    return float(np.sqrt(np.mean((x - y) ** 2)))


def pad_to_same_length(
    a: NDArray[np.float64], b: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Align two (n, 2) command sequences at t = 0 and pad the shorter with zeros (stopped)."""
    n = max(len(a), len(b))
    out = []
    for x in (a, b):
        padded = np.zeros((n, x.shape[1]), dtype=np.float64)
        padded[: len(x)] = x
        out.append(padded)
    return out[0], out[1]


def success_rate(generated: ArrayLike, demonstrated: ArrayLike, scale: float) -> float:
    """``100 * (1 - EDM)`` of two left/right command sequences, clamped at 0.

    Parameters
    ----------
    generated, demonstrated
        (n, 2) wheel commands (rad/s) from the same start, aligned at t = 0.
    scale
        Normalization (rad/s): the largest absolute command in the behavior's training
        demonstrations (headline) or the motor limit (the ``motor_max`` variant).
    """
    if not np.isfinite(scale) or scale <= 0:
        raise ConfigError(f"success-rate scale must be a positive number, got {scale}")
    gen = np.asarray(generated, dtype=np.float64).reshape(-1, 2) / scale
    ref = np.asarray(demonstrated, dtype=np.float64).reshape(-1, 2) / scale
    gen, ref = pad_to_same_length(gen, ref)
    return max(0.0, 100.0 * (1.0 - edm(gen, ref)))


def zero_floor(demonstrated: ArrayLike, scale: float) -> float:
    """The success rate a robot that never moves gets against ``demonstrated``."""
    ref = np.asarray(demonstrated, dtype=np.float64).reshape(-1, 2)
    return success_rate(np.zeros((1, 2)), ref, scale)
