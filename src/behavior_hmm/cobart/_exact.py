"""The exact mismatch that decides every CobART winner, and the screen that finds it.

A category's mismatch to a processed input ``p`` is, in exact arithmetic,
``r_k = Σ_g w_g min(1, sqrt(s_g Σ_{j in g} (z_kj - p_j)^2))`` (module ``_engine``). The
winner is the category of least ``r_k``, ties to the lowest index, and its score is
``max(0, 1 - r_k)``. Both are taken from one fixed sequence of floating-point operations,
:func:`exact_mismatch`: features of a group in increasing order, each squared difference
added to the group's sum, the sum times the group's scale, its square root clipped at
1, times the group's weight, added to the mismatch, groups in order. Every path that
categorizes (the numpy paths, the index of many prototypes, the compiled kernels of
module ``_compiled``) forms the winner's mismatch with exactly these operations, so they
choose the same winners and report the same scores, to the bit.

The numpy paths screen with the expansion of module ``_engine`` (one matrix product for
all categories), whose rounding moves a mismatch by at most :func:`expansion_margin`;
every category within twice that of the screen's least mismatch is then scored exactly
(:func:`refine`), which is one category at almost every step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Relative rounding of one product term of the expansion, times a safety factor.
ROUNDING: Final[float] = 16.0 * float(np.finfo(np.float64).eps)
#: Added to every screening margin: the rounding of the exact mismatch itself (a sum of a
#: few terms of at most 1) is below 1e-15.
MARGIN_FLOOR: Final[float] = 1e-12


@dataclass(frozen=True, eq=False)
class Groups:
    """The similarity groups of a layout, as the exact mismatch reads them.

    Attributes
    ----------
    scales
        Per group, the scale ``s_g`` of every one of its features (``gs[j, g]``).
    weights
        Per group, its weight ``w_g``.
    index, pointer
        The groups' feature indices in increasing order, flattened: group ``g`` at
        ``index[pointer[g]:pointer[g+1]]`` (for the compiled kernels).
    parts
        Per group: the slice of a feature row holding its features (they are evenly
        spaced: one channel of a window), its scale and its weight (what
        :func:`exact_mismatch` walks).
    """

    scales: tuple[float, ...]
    weights: tuple[float, ...]
    index: IntArray
    pointer: IntArray
    parts: tuple[tuple[slice, float, float], ...]

    @classmethod
    def of(cls, gs: FloatArray, wts: FloatArray) -> Groups:
        """Groups of a ``(F, G)`` membership matrix (each feature in one group, one scale
        per group) and the ``(G,)`` weights."""
        feats: list[tuple[int, ...]] = []
        scales: list[float] = []
        for g in range(gs.shape[1]):
            idx = np.flatnonzero(gs[:, g])
            col = gs[idx, g]
            if idx.size == 0 or np.any(col != col[0]):
                raise ValueError(f"similarity group {g} must hold features of one scale")
            feats.append(tuple(int(j) for j in idx))
            scales.append(float(col[0]))
        flat = [j for f in feats for j in f]
        pointer = np.cumsum([0] + [len(f) for f in feats]).astype(np.int64)
        slices = []
        for f in feats:
            step = f[1] - f[0] if len(f) > 1 else 1
            sl = slice(f[0], f[-1] + 1, step)
            if tuple(range(f[0], f[-1] + 1, step)) != f:
                raise ValueError("a similarity group's features must be evenly spaced")
            slices.append(sl)
        weights = tuple(float(w) for w in wts)
        return cls(
            scales=tuple(scales),
            weights=weights,
            index=np.asarray(flat, dtype=np.int64),
            pointer=pointer,
            parts=tuple(zip(slices, scales, weights, strict=True)),
        )


def exact_mismatch(z: FloatArray, p: FloatArray, groups: Groups) -> float:
    """The mismatch of prototype features ``z`` to processed input ``p``, in the fixed
    order of operations every path follows.

    The differences and their squares are elementwise (numpy forms them as a scalar loop
    would); only the sums need the order, and they are formed here one by one.
    """
    d = z[: p.shape[0]] - p
    np.multiply(d, d, out=d)
    sq = d.tolist()
    r = 0.0
    for sl, scale, w in groups.parts:
        s = 0.0
        for x in sq[sl]:  # the group's features in increasing order
            s += x
        c = math.sqrt(s * scale)
        r += w * (c if c < 1.0 else 1.0)
    return r


def expansion_margin(pn2: list[float], zmax: list[float], groups: Groups, terms: int) -> float:
    """Bound on how far an expanded mismatch can lie from the exact one.

    ``S_g`` sums ``terms`` products whose magnitudes add up to at most
    ``2 (|z|^2_g + |p|^2_g)``; its rounding error ``e_g`` moves ``sqrt(S_g)`` by at most
    ``sqrt(e_g)``. ``pn2``: the query's ``-2 |p|^2_g`` (the last row of the expansion's
    query matrix); ``zmax``: an upper bound on every prototype's ``|z|^2_g``.
    """
    return margin_of(pn2, *margin_constants(zmax, groups, terms))


def margin_constants(
    zmax: list[float], groups: Groups, terms: int
) -> tuple[list[float], tuple[float, ...], float]:
    """The parts of :func:`expansion_margin` that depend on the categories only, for
    :func:`margin_of` (a categorizer whose categories do not change computes them once):
    ``c zmax_g``, the weights and ``c / 2``, with ``c = 2 terms ROUNDING``."""
    c = terms * ROUNDING * 2.0
    return [c * zm for zm in zmax], groups.weights, 0.5 * c


def margin_of(
    pn2: list[float], czmax: list[float], weights: tuple[float, ...], half_c: float
) -> float:
    """:func:`expansion_margin` from the query's ``pn2`` and :func:`margin_constants`."""
    m = MARGIN_FLOOR
    for w, cz, q in zip(weights, czmax, pn2, strict=True):
        m += w * math.sqrt(cz + half_c * abs(q))
    return m


def refine(
    v: FloatArray,
    k: int,
    margin: float,
    z: FloatArray,
    pt: FloatArray,
    groups: Groups,
    ids: IntArray | None = None,
    known: tuple[int, float] | None = None,
) -> tuple[int, float]:
    """The exact winner among screened mismatches ``v`` and its exact mismatch.

    Parameters
    ----------
    v
        Screened (expanded) mismatches of the scored categories.
    k
        Position of the least of them in ``v``.
    margin
        :func:`expansion_margin` for this input: every category whose exact mismatch
        could be the least lies within ``2 margin`` of ``v[k]``.
    z
        Feature rows of the scored categories, row ``i`` for ``v[i]``.
    pt
        The processed input.
    groups
        The layout's groups.
    ids
        Category index of each scored row (``None``: the row number), for the tie rule:
        among equal exact mismatches the lowest category index wins.
    known
        A category and its exact mismatch for ``pt``, already formed by the caller: not
        formed again when that category alone is within reach.

    Returns
    -------
    category, mismatch
    """
    reach = float(v[k]) + 2.0 * margin
    if np.count_nonzero(v <= reach) == 1:  # almost always: the screen's winner alone
        cat = k if ids is None else int(ids[k])
        if known is not None and known[0] == cat:
            return known
        return cat, exact_mismatch(z[k], pt, groups)
    best_id, best = -1, math.inf
    for i in np.flatnonzero(v <= reach).tolist():
        r = exact_mismatch(z[i], pt, groups)
        cat = i if ids is None else int(ids[i])
        if r < best or (r == best and cat < best_id):
            best_id, best = cat, r
    return best_id, best


def score_of(mismatch: float) -> float:
    """The score of a mismatch: ``1 - r`` clipped at 0 (the weights sum to 1 only up to
    rounding)."""
    score = 1.0 - mismatch
    return score if score > 0.0 else 0.0
