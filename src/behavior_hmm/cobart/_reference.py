"""Categorizing an episode with fixed prototypes: one query's full scan screens the next ones.

The numpy path of :meth:`Predictor.episode <behavior_hmm.cobart._engine.Predictor.episode>`
scored every category at every step (one product over all of them, ~55 µs a step against
the turn & approach CBLM's 2,310 categories). Consecutive processed inputs lie close
together, so most of that work can be skipped with the same winners.

Each similarity group's distance ``d_g(p, z) = sqrt(s_g Σ_{j in g} (p_j - z_j)^2)`` is a
scaled Euclidean norm, so it obeys the triangle inequality, and ``min(1, ·)`` moves by no
more than its argument. With ``D = Σ_g w_g d_g(ref, p)`` for a *reference* input ``ref``
whose every mismatch ``r_k(ref)`` was screened, every category's exact mismatch at ``p``
is at least ``r_k(ref) - D``. The previous step's winner, scored exactly at ``p``, bounds
the best mismatch from above by ``U``; a category whose screened ``r_k(ref)`` exceeds
``U + D`` plus the screen's rounding margin at ``ref`` is strictly worse than the winner
and is not scored. The reference's mismatches are kept sorted, so the rest are a prefix:
they are screened with one product over their rows and the exact winner taken among them
(module ``_exact``, ties to the lowest category index), the full scan's winner and score
to the bit. When more than ``SCREEN_LIMIT`` categories remain, or at an episode's first
step, the step scans every category and becomes the new reference.

On the turn & approach CBLM (kinematic default grid) 1.3 % of the steps scan every
category and the rest score 13 categories on average (a script over 60 of its episodes).
"""

from __future__ import annotations

from typing import Final

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.cobart._engine import aligned_zeros, clipped_mismatch
from behavior_hmm.cobart._exact import Groups, exact_mismatch, refine

FloatArray = NDArray[np.float64]

#: Most categories a step scores before it scans every category and becomes the reference.
SCREEN_LIMIT: Final[int] = 32
#: From this many categories an episode is categorized this way (below it a scan is cheap).
REFERENCE_MIN_CATEGORIES: Final[int] = 256
#: Relative and absolute allowance on the bound's own rounding (it is formed in floating
#: point from a few terms of at most 1, so its rounding is below 1e-15).
_SLACK_REL: Final[float] = 1e-9
_SLACK_ABS: Final[float] = 1e-12


class ReferenceScreen:
    """Which categories could win a step, from the last fully scanned step (the reference).

    Parameters
    ----------
    gs, wts
        The layout's ``(F, G)`` scaled group membership and ``(G,)`` weights.
    groups
        The layout's :class:`~behavior_hmm.cobart._exact.Groups`.

    While learning, a category that moves or is added after the reference (:meth:`moved`)
    is always a candidate; the others keep their reference mismatch.
    """

    def __init__(self, gs: FloatArray, wts: FloatArray, groups: Groups) -> None:
        self.gs, self.wts, self.groups = gs, wts, groups
        self.ref = aligned_zeros(gs.shape[0])
        self.diff = aligned_zeros(gs.shape[0])
        self.dist = np.empty(gs.shape[1])
        self.order: NDArray[np.intp] | None = None
        self.sorted: FloatArray = np.empty(0)
        self.ref_margin = 0.0
        self.dirty: list[int] = []

    def candidates(
        self, prev: int, z: FloatArray, pt: FloatArray
    ) -> tuple[NDArray[np.intp], float] | None:
        """The categories that could win at ``pt`` and the previous winner's exact
        mismatch there (``None``: scan every one and make this step the reference,
        :meth:`set_reference`). ``prev``: the previous step's winner (``-1`` at an
        episode's start); ``z``: the categories' feature rows now."""
        if prev < 0 or self.order is None:
            return None
        upper = exact_mismatch(z[prev], pt, self.groups)
        reach = upper + self._bound(pt) + self.ref_margin
        n = int(np.searchsorted(self.sorted, reach * (1.0 + _SLACK_REL) + _SLACK_ABS, "right"))
        if n + len(self.dirty) > SCREEN_LIMIT:
            return None
        if self.dirty:
            return np.concatenate((self.order[:n], np.asarray(self.dirty, dtype=np.intp))), upper
        return self.order[:n], upper

    def set_reference(self, pt: FloatArray, v: FloatArray, margin: float) -> None:
        """Make ``pt``, whose every category was screened into ``v`` with rounding
        ``margin``, the reference."""
        np.copyto(self.ref, pt)
        self.ref_margin = margin
        self.order = np.argsort(v, kind="stable")
        self.sorted = v[self.order]
        self.dirty.clear()

    def moved(self, k: int) -> None:
        """Category ``k`` moved or was added since the reference."""
        if self.order is not None and k not in self.dirty:
            self.dirty.append(k)

    def _bound(self, pt: FloatArray) -> float:
        """``Σ_g w_g d_g(ref, pt)``: how far any mismatch can have moved since the reference."""
        np.subtract(self.ref, pt, out=self.diff)
        np.multiply(self.diff, self.diff, out=self.diff)
        np.dot(self.diff, self.gs, out=self.dist)
        np.sqrt(self.dist, out=self.dist)
        return float(np.dot(self.dist, self.wts))


def best_of(
    ids: NDArray[np.intp],
    zaug: FloatArray,
    paug: FloatArray,
    wts: FloatArray,
    margin: float,
    pt: FloatArray,
    groups: Groups,
    known: tuple[int, float],
) -> tuple[int, float]:
    """The exact winner among categories ``ids`` (rows of ``zaug``) for the query ``paug``
    of ``pt``, and its exact mismatch: one screen of their rows, then :func:`refine`
    (``known``: the previous winner and its exact mismatch at ``pt``)."""
    rows = zaug.take(ids, axis=0)
    v = clipped_mismatch(rows @ paug, wts)
    return refine(v, int(v.argmin()), margin, rows, pt, groups, ids, known)
