"""Vectorized CobART scoring and learning on preallocated buffers.

A window (or, for the relation network, a stack of windows, one per *part*) is mapped
to a feature vector ``[raw readings, first differences]``. The squared RMS of every
similarity group (EDM or DCM of one channel of one part) is a scaled sum of squared
feature differences, computed for all categories at once with one matrix product
through the expansion ``|p - z|^2 = |z|^2 - 2 p·z + |p|^2``::

    S = [Z, |Z|^2_g, -1/2] @ [[-2 G ⊙ p], [I], [p @ (-2 G ⊙ p)]]     (K, n_groups)
    r_k = 1 - Σ_g w_g · min(1, sqrt(max(S_kg, 0)))

with ``G`` the (feature, group) matrix holding ``1 / (I e^2)`` (EDM) and
``1 / ((I - 1) s_c^2)`` (DCM) and ``w`` the group weights (``(1 - b)/C`` and ``b/C``
times the part weight), which sum to 1. The expansion loses up to ~1e-8 of a score
next to an exact match, so it only screens: the categories within its rounding margin
of the least expanded mismatch are scored exactly (module ``_exact``), and the winner
and its score are the exact ones.

Every buffer is 64-byte aligned so that the same products take the same BLAS code
path in the offline and in the live categorizer (bit-identical results).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.cobart import _compiled as compiled
from behavior_hmm.cobart._exact import (
    Groups,
    expansion_margin,
    margin_constants,
    margin_of,
    refine,
    score_of,
)

if TYPE_CHECKING:
    from behavior_hmm.cobart._index import PrototypeIndex
    from behavior_hmm.cobart._reference import ReferenceScreen

FloatArray = NDArray[np.float64]


def clipped_mismatch(s: FloatArray, wts: FloatArray, out: FloatArray | None = None) -> FloatArray:
    """``r = Σ_g w_g min(1, sqrt(max(S_g, 0)))`` of each row of expanded ``S`` (``s`` is
    overwritten; ``out``: where ``r`` goes)."""
    np.maximum(s, 0.0, out=s)
    np.sqrt(s, out=s)
    np.minimum(s, 1.0, out=s)
    return np.dot(s, wts, out=out)


def aligned_zeros(shape: int | tuple[int, ...], align: int = 64) -> FloatArray:
    """Zero float64 array whose data start on an ``align``-byte boundary."""
    shp = (shape,) if isinstance(shape, int) else tuple(shape)
    n = int(np.prod(shp)) if shp else 1
    buf = np.zeros(n + align // 8, dtype=np.float64)
    off = (-buf.ctypes.data % align) // 8
    return buf[off : off + n].reshape(shp)


@dataclass(frozen=True, eq=False)
class Layout:
    """Feature layout of one or more window parts and its similarity groups.

    Attributes
    ----------
    windows, channels
        ``I_m`` and ``C_m`` of every part.
    raw_offsets, diff_offsets
        Where each part's raw readings / differences start in the feature vector.
    n_raw, n_features, n_groups
        Sizes; raw readings come first (``n_raw`` = Σ I_m C_m).
    gs
        ``(n_features, n_groups)`` scaled membership matrix.
    wts
        ``(n_groups,)`` group weights, summing to 1.
    """

    windows: tuple[int, ...]
    channels: tuple[int, ...]
    raw_offsets: tuple[int, ...]
    diff_offsets: tuple[int, ...]
    n_raw: int
    n_features: int
    n_groups: int
    gs: FloatArray
    wts: FloatArray


def make_layout(
    windows: Sequence[int],
    channels: Sequence[int],
    part_weights: Sequence[float],
    b: float,
    edm_scale: float,
    dcm_scales: Sequence[FloatArray],
) -> Layout:
    """Build the layout for parts ``(I_m, C_m)`` weighted ``w_m`` (normalized to sum 1)."""
    wsum = float(sum(part_weights))
    raw_off, diff_off = [], []
    n_raw = n_diff = 0
    for i_m, c_m in zip(windows, channels, strict=True):
        raw_off.append(n_raw)
        diff_off.append(n_diff)
        n_raw += i_m * c_m
        n_diff += (i_m - 1) * c_m
    n_feat = n_raw + n_diff
    cols: list[FloatArray] = []
    wts: list[float] = []
    for m, (i_m, c_m) in enumerate(zip(windows, channels, strict=True)):
        w_m = float(part_weights[m]) / wsum
        for c in range(c_m):
            col = np.zeros(n_feat)
            col[raw_off[m] + c : raw_off[m] + i_m * c_m : c_m] = 1.0 / (i_m * edm_scale**2)
            cols.append(col)
            wts.append(w_m * ((1.0 - b) if i_m > 1 else 1.0) / c_m)
            if i_m > 1:
                col = np.zeros(n_feat)
                start = n_raw + diff_off[m] + c
                col[start : n_raw + diff_off[m] + (i_m - 1) * c_m : c_m] = 1.0 / (
                    (i_m - 1) * float(dcm_scales[m][c]) ** 2
                )
                cols.append(col)
                wts.append(w_m * b / c_m)
    gs = np.stack(cols, axis=1)
    return Layout(
        windows=tuple(int(i) for i in windows),
        channels=tuple(int(c) for c in channels),
        raw_offsets=tuple(raw_off),
        diff_offsets=tuple(diff_off),
        n_raw=n_raw,
        n_features=n_feat,
        n_groups=gs.shape[1],
        gs=gs,
        wts=np.asarray(wts),
    )


def features(layout: Layout, raw: FloatArray) -> FloatArray:
    """Feature rows ``[raw, differences]`` for raw rows ``(N, n_raw)``."""
    out = np.empty((raw.shape[0], layout.n_features))
    out[:, : layout.n_raw] = raw
    for i_m, c_m, ro, do in zip(
        layout.windows, layout.channels, layout.raw_offsets, layout.diff_offsets, strict=True
    ):
        if i_m > 1:
            part = raw[:, ro : ro + i_m * c_m]
            d0 = layout.n_raw + do
            np.subtract(part[:, c_m:], part[:, :-c_m], out=out[:, d0 : d0 + (i_m - 1) * c_m])
    return out


def episode_windows(x: FloatArray, window: int) -> FloatArray:
    """Causal windows of one episode ``(T, C)`` → ``(T, I*C)`` rows ``t-I+1..t`` flattened.

    The first ``I - 1`` steps are padded by repeating the episode's first reading.
    """
    t_len, c = x.shape
    pad = np.concatenate([np.repeat(x[:1], window - 1, axis=0), x], axis=0)
    win = np.lib.stride_tricks.sliding_window_view(pad, window, axis=0)  # (T, C, I)
    return np.ascontiguousarray(win.transpose(0, 2, 1)).reshape(t_len, window * c)


class Engine:
    """Categories in feature space: prototypes, their group norms and win counts."""

    def __init__(self, layout: Layout, capacity: int = 32) -> None:
        self.layout = layout
        f, g = layout.n_features, layout.n_groups
        self.F = f
        self.NG = g
        self.width = f + g + 1
        self.K = 0
        self.counts: list[int] = []
        self.gs = aligned_zeros((f, g))
        self.gs[:] = layout.gs
        self.gm2 = aligned_zeros((f, g))
        self.gm2[:] = -2.0 * layout.gs
        self.wts = aligned_zeros(g)
        self.wts[:] = layout.wts
        self.paug = aligned_zeros((self.width, g))
        self.paug[f : f + g] = np.eye(g)
        self.top = self.paug[:f]
        self.pn2 = self.paug[f + g]
        self.pt = aligned_zeros(f)
        self.pt_col = self.pt[:, None]
        self.tmp = aligned_zeros(f)
        self.zl = aligned_zeros(f)
        self.groups = Groups.of(layout.gs, layout.wts)
        self.zmax = np.zeros(g)
        """An upper bound on every category's group norms ``|z|^2_g`` (for the screen)."""
        self._alloc(max(int(capacity), 1))

    def _alloc(self, capacity: int) -> None:
        self.capacity = capacity
        self.zaug = aligned_zeros((capacity, self.width))
        self.s = aligned_zeros((capacity, self.NG))
        self.v = aligned_zeros(capacity)
        self._rows: list[tuple[FloatArray, ...]] | None = None

    @property
    def rows(self) -> list[tuple[FloatArray, ...]]:
        """Per-row views for the single-part fast path of learning: raw, raw[C:],
        raw[:-C], diffs, features, group norms (made on first use: six views a row)."""
        if self._rows is None:
            nr, f, g = self.layout.n_raw, self.F, self.NG
            c = self.layout.channels[0]
            self._rows = [
                (r[:nr], r[c:nr], r[: nr - c], r[nr:f], r[:f], r[f : f + g]) for r in self.zaug
            ]
        return self._rows

    def grow(self) -> None:
        """Double the capacity, keeping the categories."""
        old_z = self.zaug
        self._alloc(self.capacity * 2)
        self.zaug[: self.K] = old_z[: self.K]

    # -- single operations (used by the hierarchical network and the slow paths) --
    def load(self, protos: FloatArray, counts: Sequence[int]) -> None:
        """Replace all categories by feature rows ``protos`` ``(K, F)`` with win ``counts``."""
        k = protos.shape[0]
        self.zmax[:] = 0.0
        capacity = self.capacity
        while capacity < k:
            capacity *= 2
        if capacity != self.capacity:
            self._alloc(capacity)
        # what ``add`` does row by row, in bulk where that is bit for bit the same: the
        # differences are elementwise; the norms keep add's per-row product
        z = self.zaug[:k]
        z[:, : self.F] = features(self.layout, protos[:, : self.layout.n_raw])
        z[:, -1] = -0.5
        for row in z:
            self._set_norms(row)
        self.counts = [int(c) for c in counts]
        self.K = k

    def _fix_diffs(self, row: FloatArray) -> None:
        """Recompute a feature row's differences from its raw readings (as ``features``)."""
        lay = self.layout
        nr = lay.n_raw
        for i_m, c_m, ro, do in zip(
            lay.windows, lay.channels, lay.raw_offsets, lay.diff_offsets, strict=True
        ):
            if i_m > 1:
                n = (i_m - 1) * c_m
                np.subtract(
                    row[ro + c_m : ro + i_m * c_m], row[ro : ro + n], out=row[nr + do : nr + do + n]
                )

    def _set_norms(self, row: FloatArray) -> None:
        f = self.F
        np.multiply(row[:f], row[:f], out=self.tmp)
        norms = row[f : f + self.NG]
        np.dot(self.tmp, self.gs, out=norms)
        np.maximum(self.zmax, norms, out=self.zmax)

    def margin(self) -> float:
        """:func:`~behavior_hmm.cobart._exact.expansion_margin` of the current query ``pt``
        (``paug`` set for it) against these categories."""
        return expansion_margin(self.pn2.tolist(), self.zmax.tolist(), self.groups, self.width)

    def add(self, pt: FloatArray, count: int = 1) -> int:
        """Append a category with prototype ``pt`` (features); returns its index.

        The prototype is its raw readings; its differences are recomputed from them, so
        a prototype is fully defined by ``prototypes_`` (a restored model is identical).
        """
        if self.K == self.capacity:
            self.grow()
        k = self.K
        row = self.zaug[k]
        row[: self.F] = pt
        self._fix_diffs(row)
        self._set_norms(row)
        row[-1] = -0.5
        self.counts.append(count)
        self.K = k + 1
        return k

    def learn(self, k: int, pt: FloatArray, d: float, alpha: float) -> None:
        """Move prototype ``k`` toward ``pt`` by ``d · n_k^alpha`` (``n_k`` counts this win)."""
        n = self.counts[k] + 1
        self.counts[k] = n
        lr = d * n**alpha
        nr = self.layout.n_raw
        row = self.zaug[k]
        zr = row[:nr]
        tr = self.tmp[:nr]
        np.subtract(pt[:nr], zr, out=tr)
        np.multiply(tr, lr, out=tr)
        np.add(zr, tr, out=zr)
        self._fix_diffs(row)
        self._set_norms(row)

    def prototypes(self) -> FloatArray:
        """Copy of the prototypes' feature rows ``(K, F)``."""
        return self.zaug[: self.K, : self.F].copy()


def fit_episode(
    eng: Engine,
    wt: FloatArray,
    a: float,
    rho: float,
    d: float,
    alpha: float,
    labels: list[int],
) -> None:
    """Categorize and learn one episode of window features ``wt`` ``(T, F)`` in order.

    Appends one category per step to ``labels``. ``z_last`` starts empty: the first
    step's processed input is the window itself.
    """
    f = eng.F
    oma = 1.0 - a
    awt = wt * a
    pt, pt_col, tmp, zl = eng.pt, eng.pt_col, eng.tmp, eng.zl
    if len(eng.layout.windows) != 1:
        raise ValueError("fit_episode handles single-part layouts only")
    nr = eng.layout.n_raw
    has_diff = nr < f
    pt_raw, tmp_raw = pt[:nr], tmp[:nr]
    top, pn2, paug, gm2, gs, wts = eng.top, eng.pn2, eng.paug, eng.gm2, eng.gs, eng.wts
    counts = eng.counts
    k_cnt = eng.K
    zaug = eng.zaug
    rows = eng.rows
    z, s, v = zaug[:k_cnt], eng.s[:k_cnt], eng.v[:k_cnt]
    groups, zmax, margin = eng.groups, eng.zmax, eng.margin
    append = labels.append
    from behavior_hmm.cobart._reference import REFERENCE_MIN_CATEGORIES, ReferenceScreen, best_of

    # from REFERENCE_MIN_CATEGORIES on, a step scores only the categories that could win
    # (module _reference): the same winners
    reference = ReferenceScreen(gs, wts, groups)
    k = -1
    for t in range(wt.shape[0]):
        if t == 0:
            np.copyto(pt, wt[0])
        else:
            np.add(awt[t], zl, out=pt)
        if k_cnt:
            np.multiply(gm2, pt_col, out=top)
            np.dot(pt, top, out=pn2)
            screened = k_cnt >= REFERENCE_MIN_CATEGORIES
            found = reference.candidates(k, z, pt) if screened else None
            if found is not None:
                ids, upper = found
                k, miss = best_of(ids, zaug, paug, wts, margin(), pt, groups, (k, upper))
            else:
                np.dot(z, paug, out=s)
                clipped_mismatch(s, wts, out=v)
                mg = margin()
                k, miss = refine(v, int(v.argmin()), mg, z, pt, groups)
                if screened:
                    reference.set_reference(pt, v, mg)
            score = score_of(miss)
        else:
            k = 0
            score = -1.0
        if score >= rho:
            # resonance: z_k += d · n_k^alpha · (p - z_k), on the raw readings
            n = counts[k] + 1
            counts[k] = n
            lr = d * n**alpha
            zr, z_hi, z_lo, zd, zk, zn = rows[k]
            np.subtract(pt_raw, zr, out=tmp_raw)
            np.multiply(tmp_raw, lr, out=tmp_raw)
            np.add(zr, tmp_raw, out=zr)
            if has_diff:
                np.subtract(z_hi, z_lo, out=zd)
            np.multiply(zk, zk, out=tmp)
            np.dot(tmp, gs, out=zn)
            np.maximum(zmax, zn, out=zmax)
            np.multiply(zk, oma, out=zl)
        else:
            k = eng.add(pt)
            k_cnt = eng.K
            zaug = eng.zaug
            rows = eng.rows
            z, s, v = zaug[:k_cnt], eng.s[:k_cnt], eng.v[:k_cnt]
            np.multiply(rows[k][4], oma, out=zl)
        reference.moved(k)
        append(k)


class Predictor:
    """Fixed-prototype categorizer shared by ``predict`` and the live stream.

    Holds an aligned snapshot of an engine's categories; ``step`` categorizes one
    processed-input feature vector. Both offline and live paths run the same
    operations on buffers of the same shapes, so they agree bit for bit. From
    ``INDEX_MIN_CATEGORIES`` categories on, both search a :class:`PrototypeIndex`
    (module ``_index``) instead of scoring every category: the same winners.
    """

    def __init__(self, eng: Engine, a: float, rho: float) -> None:
        k, f, g = eng.K, eng.F, eng.NG
        self.K, self.F, self.NG = k, f, g
        self.a = a
        self.oma = 1.0 - a
        self.rho = rho
        self.zaug = aligned_zeros((k, eng.width))
        self.zaug[:] = eng.zaug[:k]
        self.z = self.zaug[:, :f]
        self.omaz = aligned_zeros((k, f))
        np.multiply(self.z, self.oma, out=self.omaz)
        self.omaz_rows = list(self.omaz)
        self.gs = aligned_zeros((f, g))
        self.gs[:] = eng.gs
        self.gm2 = aligned_zeros((f, g))
        self.gm2[:] = eng.gm2
        self.wts = aligned_zeros(g)
        self.wts[:] = eng.wts
        self.paug = aligned_zeros((eng.width, g))
        self.paug[:] = eng.paug
        self.top = self.paug[:f]
        self.pn2 = self.paug[f + g]
        self.s = aligned_zeros((k, g))
        self.v = aligned_zeros(k)
        self.pt = aligned_zeros(f)
        self.pt_col = self.pt[:, None]
        self.tmp = aligned_zeros(f)
        self.groups = eng.groups
        zmax = self.zaug[:, f : f + g].max(axis=0) if k else np.zeros(g)
        self._margin_args = margin_constants(zmax.tolist(), self.groups, eng.width)
        from behavior_hmm.cobart._index import INDEX_MIN_CATEGORIES, PrototypeIndex

        self.index: PrototypeIndex | None = None
        """Searched instead of scoring every category from ``INDEX_MIN_CATEGORIES`` on."""
        if k >= INDEX_MIN_CATEGORIES:
            self.index = PrototypeIndex(self.zaug, self.gs, self.wts)
        self._compiled: compiled.CompiledPredictor | None = None

    def query(self) -> None:
        """Set the screen's query ``paug`` for the current ``pt`` (a hot loop inlines
        these two calls)."""
        np.multiply(self.gm2, self.pt_col, out=self.top)
        np.dot(self.pt, self.top, out=self.pn2)

    def screen(self) -> FloatArray:
        """Every category's screened (expanded) mismatch for the query ``paug``, into ``v``."""
        np.dot(self.zaug, self.paug, out=self.s)
        return clipped_mismatch(self.s, self.wts, out=self.v)

    def best(self) -> tuple[int, float]:
        """Category of least mismatch for the current ``pt`` (``paug`` set for it) and
        that mismatch, exact (module ``_exact``): every category screened into ``v``, or
        the index searched."""
        pt = self.pt
        if self.index is not None:
            return self.index.search(pt, self.paug)
        v = self.screen()
        margin = margin_of(self.pn2.tolist(), *self._margin_args)
        return refine(v, int(v.argmin()), margin, self.z, pt, self.groups)

    def _scanned(self, prev: int) -> tuple[int, float]:
        """:meth:`best` (``prev``, the previous step's winner, is not needed)."""
        return self.best()

    def _screened(self, reference: ReferenceScreen, prev: int) -> tuple[int, float]:
        """:meth:`best` scoring only the categories ``reference`` says could win
        (``prev``: the previous step's winner), or every one, then the new reference."""
        from behavior_hmm.cobart._reference import best_of

        pt = self.pt
        margin = margin_of(self.pn2.tolist(), *self._margin_args)
        found = reference.candidates(prev, self.z, pt)
        if found is not None:
            ids, upper = found
            return best_of(
                ids, self.zaug, self.paug, self.wts, margin, pt, self.groups, (prev, upper)
            )
        v = self.screen()
        won = refine(v, int(v.argmin()), margin, self.z, pt, self.groups)
        reference.set_reference(pt, v, margin)
        return won

    def compiled_search(self, kern: compiled.Kernels) -> compiled.CompiledPredictor:
        """The compiled kernels' view of these categories (their tree), built once."""
        if self._compiled is None:
            from behavior_hmm.cobart._index import partition_weight

            weight = partition_weight(self.gs, self.wts)
            self._compiled = compiled.CompiledPredictor(
                kern, self.z, self.omaz, self.groups, weight
            )
        return self._compiled

    def episode(
        self, wt: FloatArray, labels: NDArray[np.int64], scores: FloatArray, offset: int
    ) -> None:
        """Categorize one episode (features ``(T, F)``) into ``labels``/``scores`` at ``offset``."""
        kern = compiled.active()
        if kern is not None and self.index is None:
            self.compiled_search(kern).episode(kern, wt, self.a, labels, scores, offset)
            return
        awt = wt * self.a
        pt, pt_col, omaz = self.pt, self.pt_col, self.omaz_rows
        top, pn2, gm2 = self.top, self.pn2, self.gm2
        from behavior_hmm.cobart._reference import REFERENCE_MIN_CATEGORIES, ReferenceScreen

        best: Callable[[int], tuple[int, float]] = self._scanned
        if self.index is None and self.K >= REFERENCE_MIN_CATEGORIES:
            # the same winners, scoring a few categories a step (module _reference)
            best = functools.partial(
                self._screened, ReferenceScreen(self.gs, self.wts, self.groups)
            )
        k = -1
        for t in range(wt.shape[0]):
            if k < 0:
                np.copyto(pt, wt[t])
            else:
                np.add(awt[t], omaz[k], out=pt)
            np.multiply(gm2, pt_col, out=top)
            np.dot(pt, top, out=pn2)
            k, miss = best(k)
            labels[offset + t] = k
            scores[offset + t] = score_of(miss)
