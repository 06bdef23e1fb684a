"""Exact best-category search over many prototypes: a k-d partition with lower bounds.

A live reading is matched against every category by one matrix product
(``_engine``): linear in the categories, ~0.8 ms a reading at 100,000 of them. Above
``INDEX_MIN_CATEGORIES`` the :class:`Predictor` searches this index instead, which
finds the same winner while scoring only the prototypes that could win.

The prototypes' feature rows are split, median by median along the feature of widest
weighted spread, into leaves of at most ``LEAF_SIZE`` rows, stored contiguously with the
bounding box of each leaf. Every similarity group's distance ``sqrt(S_g)`` is a scaled
Euclidean norm on its own features, so the distance from the processed input ``p`` to a
leaf's box bounds it from below for every prototype in the leaf, and, because ``min(1,
·)`` is monotone, ``LB = Σ_g w_g min(1, box distance_g)`` bounds the leaf's mismatch
``r_k`` from below. A search screens the leaf of least bound (an upper bound ``U`` on the
best mismatch), then the rows of every leaf with ``LB ≤ U + 2 margin``, gathered into one
product, and takes the exact winner among them (module ``_exact``: ties to the lowest
category index). ``margin`` bounds the rounding of the expansion the screen is computed
with (module ``_engine``), so no prototype left out could have won: the winner is the full
scan's, up to the last bit of a tie.

Not a third-party k-d tree (``scipy.spatial.cKDTree``): the mismatch is a weighted sum of
clipped per-group distances, not one metric such trees search.
"""

from __future__ import annotations

from typing import Final

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.cobart._engine import aligned_zeros, clipped_mismatch
from behavior_hmm.cobart._exact import Groups, margin_constants, margin_of, refine

FloatArray = NDArray[np.float64]

#: From this many categories a predictor searches the index instead of scoring every
#: category (below it one product over all is faster; ``bench memory``'s ``live_match``).
INDEX_MIN_CATEGORIES: Final[int] = 8_192
#: Most prototypes per leaf of the partition.
LEAF_SIZE: Final[int] = 128


class PrototypeIndex:
    """Leaves of prototypes with bounding boxes, searched for the least mismatch.

    Parameters
    ----------
    zaug
        ``(K, F + G + 1)`` augmented prototype rows ``[z, |z|^2_g, -1/2]``.
    gs
        ``(F, G)`` scaled group membership (each feature in one group).
    wts
        ``(G,)`` group weights.
    """

    def __init__(self, zaug: FloatArray, gs: FloatArray, wts: FloatArray) -> None:
        k = zaug.shape[0]
        f, g = gs.shape
        self.K, self.F, self.NG = k, f, g
        z = zaug[:, :f]
        leaves = _partition(z * partition_weight(gs, wts), LEAF_SIZE)
        self.order = np.concatenate(leaves).astype(np.int64)
        sizes = np.array([leaf.size for leaf in leaves], dtype=np.int64)
        self.bounds = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self._bounds = self.bounds.tolist()
        self._starts = self.bounds[:-1].copy()
        self._sizes = sizes
        self.zaug = aligned_zeros(zaug.shape)
        self.zaug[:] = zaug[self.order]
        zp = self.zaug[:, :f]
        n_leaves = len(leaves)
        self.lo = np.empty((n_leaves, f))
        self.hi = np.empty((n_leaves, f))
        np.minimum.reduceat(zp, self.bounds[:-1], axis=0, out=self.lo)
        np.maximum.reduceat(zp, self.bounds[:-1], axis=0, out=self.hi)
        self.gs, self.wts = gs, wts
        self.groups = Groups.of(gs, wts)
        # from the largest |z|^2_g of any prototype: the rounding margin's fixed parts
        zmax = self.zaug[:, f : f + g].max(axis=0).tolist()
        self._margin_args = margin_constants(zmax, self.groups, zaug.shape[1])
        self._d = np.empty((n_leaves, f))
        self._d2 = np.empty((n_leaves, f))
        self._lbg = np.empty((n_leaves, g))
        self._lb = np.empty(n_leaves)
        self._s = aligned_zeros((int(sizes.max()), g))
        self.scored = 0
        """Prototypes scored by the last search (for benchmarks and tests)."""

    def _margin(self, paug: FloatArray) -> float:
        """Bound on how far an expanded mismatch can lie from the exact one."""
        return margin_of(paug[self.F + self.NG].tolist(), *self._margin_args)

    def _first(self, leaf: int, paug: FloatArray) -> float:
        """Least mismatch among the prototypes of one leaf (an upper bound on the best)."""
        a, b = self._bounds[leaf], self._bounds[leaf + 1]
        s = self._s[: b - a]
        np.dot(self.zaug[a:b], paug, out=s)
        return float(clipped_mismatch(s, self.wts).min())

    def search(self, pt: FloatArray, paug: FloatArray) -> tuple[int, float]:
        """Category of least mismatch for processed input ``pt`` and its exact mismatch.

        ``paug`` is the predictor's ``(F + G + 1, G)`` query matrix for ``pt``.
        """
        d, d2, lbg, lb = self._d, self._d2, self._lbg, self._lb
        np.subtract(self.lo, pt, out=d)
        np.subtract(pt, self.hi, out=d2)
        np.maximum(d, d2, out=d)
        np.maximum(d, 0.0, out=d)
        np.multiply(d, d, out=d)
        np.dot(d, self.gs, out=lbg)
        np.sqrt(lbg, out=lbg)
        np.minimum(lbg, 1.0, out=lbg)
        np.dot(lbg, self.wts, out=lb)
        margin = self._margin(paug)
        upper = self._first(int(lb.argmin()), paug)
        # a leaf is left out only if no prototype in it could be within the screen's
        # reach of the exact winner (module ``_exact``)
        cand = np.flatnonzero(lb <= upper + 2.0 * margin)
        # the candidate leaves' rows, gathered in one index array (no loop over leaves)
        sizes = self._sizes[cand]
        ends = np.cumsum(sizes)
        rows = np.arange(int(ends[-1]), dtype=np.int64)
        rows += np.repeat(self._starts[cand] - (ends - sizes), sizes)
        self.scored = rows.size
        z = self.zaug.take(rows, axis=0)
        v = clipped_mismatch(z @ paug, self.wts)
        return refine(v, int(v.argmin()), margin, z, pt, self.groups, self.order[rows])

    def mismatches(self, paug: FloatArray, out: FloatArray, s: FloatArray) -> None:
        """Every category's mismatch, in category order, into ``out`` (``s``: (K, G) work)."""
        np.dot(self.zaug, paug, out=s)
        out[self.order] = clipped_mismatch(s, self.wts)


def partition_weight(gs: FloatArray, wts: FloatArray) -> FloatArray:
    """Per feature, the scale at which a partition of the prototypes splits along what
    the mismatch weighs most (``gs``: the ``(F, G)`` group membership, ``wts``: weights)."""
    return np.asarray(np.sqrt(gs.sum(axis=1)) * wts[gs.argmax(axis=1)])


def _partition(points: FloatArray, leaf_size: int) -> list[NDArray[np.int64]]:
    """Row indices of ``points`` split at medians of the widest coordinate into leaves."""
    leaves: list[NDArray[np.int64]] = []
    stack = [np.arange(points.shape[0], dtype=np.int64)]
    while stack:
        idx = stack.pop()
        if idx.size <= leaf_size:
            leaves.append(idx)
            continue
        sub = points[idx]
        dim = int(np.argmax(sub.max(axis=0) - sub.min(axis=0)))
        half = idx.size // 2
        part = np.argpartition(sub[:, dim], half, kind="introselect")
        # right half pushed first so that leaves come out left to right
        stack.append(idx[part[half:]])
        stack.append(idx[part[:half]])
    return leaves
