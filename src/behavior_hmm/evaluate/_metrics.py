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


def _commands(values: ArrayLike, width: int = 2) -> NDArray[np.float64]:
    """Commands as an (n, k) array: a 2-D array keeps its columns; a flat one is read as
    rows of ``width`` (our wheels' left, right)."""
    u = np.asarray(values, dtype=np.float64)
    return u.reshape(len(u), -1) if u.ndim >= 2 else u.reshape(-1, width)


def pad_to_same_length(
    a: NDArray[np.float64], b: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Align two (n, k) command sequences at t = 0 and pad the shorter with zeros (stopped)."""
    n = max(len(a), len(b))
    out = []
    for x in (a, b):
        padded = np.zeros((n, x.shape[1]), dtype=np.float64)
        padded[: len(x)] = x
        out.append(padded)
    return out[0], out[1]


def success_rate(generated: ArrayLike, demonstrated: ArrayLike, scale: float | ArrayLike) -> float:
    """``100 * (1 - EDM)`` of two command sequences, clamped at 0.

    Parameters
    ----------
    generated, demonstrated
        (n, k) commands (our wheels: left, right in rad/s) from the same start, aligned
        at t = 0.
    scale
        Normalization: the largest absolute command in the behavior's training
        demonstrations (headline) or the motor limit (the ``motor_max`` variant); one
        number, or one per command channel (channels of one unit share one).
    """
    scales = np.asarray(scale, dtype=np.float64)
    if not np.all(np.isfinite(scales)) or np.any(scales <= 0) or scales.size == 0:
        raise ConfigError(f"success-rate scale must be positive numbers, got {scale!r}")
    width = scales.size if scales.ndim == 1 else 2
    gen = _commands(generated, width) / (scales if scales.ndim == 0 else scales[None, :])
    ref = _commands(demonstrated, width) / (scales if scales.ndim == 0 else scales[None, :])
    gen, ref = pad_to_same_length(gen, ref)
    return max(0.0, 100.0 * (1.0 - edm(gen, ref)))


def zero_floor(demonstrated: ArrayLike, scale: float | ArrayLike) -> float:
    """The success rate a robot that never moves gets against ``demonstrated``."""
    scales = np.asarray(scale, dtype=np.float64)
    ref = _commands(demonstrated, scales.size if scales.ndim == 1 else 2)
    return success_rate(np.zeros((1, ref.shape[1])), ref, scale)


def command_jump(commands: ArrayLike) -> float:
    """Largest change of any command channel within one control period (wheels: rad/s).

    Measured along the recorded sequence (a run that stops at its goal records its final
    zero command, so an abrupt stop counts); 0 for fewer than two commands.
    """
    u = _commands(commands)
    if len(u) < 2:
        return 0.0
    return float(np.max(np.abs(np.diff(u, axis=0))))


def command_jump_ratio(generated: ArrayLike, demonstrated: ArrayLike) -> float:
    """:func:`command_jump` of the generated commands ÷ the teacher's from the same start.

    1 means no larger jolt than the jerk-limited teacher; the teacher's own jump is
    floored at 1e-6 rad/s so a teacher that never moves gives a finite ratio.
    """
    return command_jump(generated) / max(command_jump(demonstrated), 1e-6)


def switches(states: ArrayLike) -> int:
    """Changes of the active primitive or component along a run (``-1``: none active)."""
    s = np.asarray(states, dtype=np.int64).ravel()
    s = s[s >= 0]
    return int(np.count_nonzero(np.diff(s))) if s.size > 1 else 0


#: Path metrics compare curves thinned to at most this many points (evenly in time): the
#: discrete Fréchet distance is quadratic in the points (~30 ms at 200 x 200).
PATH_POINTS = 200


def _thinned(curve: NDArray[np.float64]) -> NDArray[np.float64]:
    if len(curve) <= PATH_POINTS:
        return curve
    keep = np.unique(np.round(np.linspace(0, len(curve) - 1, PATH_POINTS)).astype(np.intp))
    return curve[keep]


def path_metrics(
    generated: ArrayLike, reference: ArrayLike, wraps: ArrayLike | None = None
) -> dict[str, float | None]:
    """How far a generated path on the goal channels lies from the reference's.

    Computed with the ``similaritymeasures`` package (``pip install
    'behavior-hmm[metrics]'``), as published learning-from-demonstration benchmark code
    computes them, on both curves thinned to at most :data:`PATH_POINTS` points evenly
    in time:

    - ``dtw``: dynamic time warping distance (sum of the matched points' Euclidean
      distances, in the channels' units);
    - ``frechet``: discrete Fréchet distance (channels' units);
    - ``swept_area``: the area between the two curves, for a 2-D path only (units
      squared; ``None`` otherwise).

    Parameters
    ----------
    generated, reference
        (n, k) and (m, k) readings of the k goal channels (physical units).
    wraps
        (k,) booleans: channels that are angles in degrees, unwrapped along each path
        before comparing.

    Returns
    -------
    dict
        The three metrics; all ``None`` when ``similaritymeasures`` is not installed or a
        path has fewer than two points.
    """
    gen = np.asarray(generated, dtype=np.float64)
    ref = np.asarray(reference, dtype=np.float64)
    if gen.ndim == 1:
        gen, ref = gen[:, None], ref.reshape(-1, 1)
    out: dict[str, float | None] = {"dtw": None, "frechet": None, "swept_area": None}
    try:
        import similaritymeasures
    except ImportError:
        return out
    if len(gen) < 2 or len(ref) < 2:
        return out
    if wraps is not None:
        for j in np.flatnonzero(np.asarray(wraps, dtype=bool)):
            gen[:, j] = np.degrees(np.unwrap(np.radians(gen[:, j])))
            ref[:, j] = np.degrees(np.unwrap(np.radians(ref[:, j])))
    a, b = _thinned(gen), _thinned(ref)
    if a.shape[1] == 1:  # a 1-D path: its value against time would mix units; pad a zero axis
        a = np.column_stack([a, np.zeros(len(a))])
        b = np.column_stack([b, np.zeros(len(b))])
        out["swept_area"] = None
    elif a.shape[1] == 2:
        out["swept_area"] = float(similaritymeasures.area_between_two_curves(a, b))
    out["dtw"] = float(similaritymeasures.dtw(a, b)[0])
    out["frechet"] = float(similaritymeasures.frechet_dist(a, b))
    return out
