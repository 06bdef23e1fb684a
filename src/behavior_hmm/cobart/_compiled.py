"""The numba-compiled CobART kernels: learning and categorizing whole episodes.

numba is optional, the ``fast`` extra (``pip install 'behavior-hmm[fast]'``). Without it
CobART runs its numpy paths (module ``_engine``), whose step is a dozen numpy calls
(~35 µs a step against 2,300 categories, most of it call overhead). With it,
:meth:`CobART.partial_fit <behavior_hmm.cobart.CobART.partial_fit>` and
:meth:`~behavior_hmm.cobart.CobART.categorize` of a single-part layout run an episode in
one call of these kernels. Both choose every winner by the exact mismatch of module
``_exact``, formed with the same floating-point operations in the same order, so the
categories, prototypes, counts, labels and scores are identical to the bit either way.

The kernels do not score every category. The categories are split into leaves
(``_index._partition``) with the bounding box of each leaf; a leaf's box gives a lower
bound on the exact mismatch of every category in it, formed with the same operations
on the box distances (each no larger than the category's own difference, and every
operation monotone), so a leaf whose bound exceeds the best mismatch so far cannot hold
the winner and is skipped. A category's mismatch is summed group by group and abandoned
as soon as it exceeds the best so far. The previous step's winner is scored first: the
input moves little from one step to the next. While learning, a prototype that moves
widens its leaf's box, and new categories are scored one by one until the leaves are
rebuilt (every ``REBUILD_ROWS`` steps, or when ``TAIL_MAX`` new categories wait).

numba is imported on the first call of :func:`kernels`, never when ``behavior_hmm`` is
imported. The kernels are compiled with ``cache=True`` (the machine code is kept in
``__pycache__`` next to this file) and without ``fastmath``, which would let the
compiler reorder the sums.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, Final, Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray

from behavior_hmm._numba import KernelSetting, KernelSwitch, compile_kernels
from behavior_hmm.cobart._exact import Groups

if TYPE_CHECKING:
    from behavior_hmm.cobart._engine import Engine

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Most categories per leaf of the kernels' partition (on the turn & approach CBLM's
#: 2,310 observation categories 64-128 learn and categorize fastest, 16 twice and one
#: leaf of all ten times as slow).
LEAF_SIZE: Final[int] = 128
#: New categories scored one by one before the leaves are rebuilt.
TAIL_MAX: Final[int] = 64
#: Learning steps between rebuilds of the leaves (moved prototypes widen their boxes).
REBUILD_ROWS: Final[int] = 4_096


class Kernels(NamedTuple):
    """The compiled kernels (see :func:`learn` and :func:`predict`)."""

    learn: Callable[..., tuple[int, int, int]]
    predict: Callable[..., None]


@functools.cache
def kernels() -> Kernels | None:
    """The compiled kernels, or ``None`` when numba cannot be imported."""
    return compile_kernels(_compiled)


def _compiled(numba: Any, cache: bool) -> Kernels:
    jit = functools.partial(numba.njit, cache=cache, nogil=True)
    g = {"math": math, "np": np}
    mismatch = jit(_bind(_mismatch, g))
    g["_mismatch"] = mismatch
    lower_bound = jit(_bind(_lower_bound, g))
    g["_lower_bound"] = lower_bound
    g["_consider"] = jit(_bind(_consider, g))
    best = jit(_bind(_best, g))
    g["_best"] = best
    return Kernels(learn=jit(_bind(learn, g)), predict=jit(_bind(predict, g)))


def _bind(func: Callable[..., Any], names: dict[str, Any]) -> Callable[..., Any]:
    """``func`` with its globals' kernel names bound to the compiled kernels."""
    import types

    glob = dict(func.__globals__)
    glob.update(names)
    return types.FunctionType(func.__code__, glob, func.__name__, func.__defaults__)


#: Which episode loops CobART runs; see :func:`set_kernel`.
_switch = KernelSwitch("CobART", lambda: kernels())  # looked up at each call


def set_kernel(setting: KernelSetting) -> KernelSetting:
    """Choose CobART's episode loops for this process; return the old setting
    (``"auto"``, ``"numba"`` or ``"numpy"``: see :meth:`KernelSwitch.set
    <behavior_hmm._numba.KernelSwitch.set>`; the results are identical)."""
    return _switch.set(setting)


def cobart_kernel() -> Literal["numba", "numpy"]:
    """The episode loops CobART runs now."""
    return _switch.name()


def active() -> Kernels | None:
    """The compiled kernels when the setting and the installation allow them."""
    return _switch.active()


def warm() -> None:
    """Load the kernels now, or compile them the first time on a machine (~4 s; later
    processes load numba's cache, ~0.5 s), so that the first fit a caller times does not
    pay for it. Nothing to do without numba or with the numpy paths chosen."""
    if active() is None:
        return
    from behavior_hmm.cobart._cobart import CobART  # _cobart imports this module

    x = np.linspace(-1.0, 1.0, 24).reshape(12, 2)
    CobART(window=3).fit(x).categorize(x)


class Leaves(NamedTuple):
    """A partition of categories ``0..n_indexed-1`` into leaves with bounding boxes."""

    perm: IntArray
    start: IntArray
    end: IntArray
    lo: FloatArray
    hi: FloatArray
    leaf_of: IntArray
    n_indexed: int


def leaves(z: FloatArray, n: int, weight: FloatArray, capacity: int) -> Leaves:
    """Leaves of the first ``n`` feature rows of ``z`` (``leaf_of`` sized ``capacity``);
    ``weight``: ``_index.partition_weight`` of the layout."""
    from behavior_hmm.cobart._index import _partition  # _index imports _engine, which imports us

    f = z.shape[1]
    parts = _partition(z[:n] * weight, LEAF_SIZE) if n else []
    sizes = np.array([p.size for p in parts], dtype=np.int64)
    bounds = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    perm = np.concatenate(parts).astype(np.int64) if parts else np.zeros(0, dtype=np.int64)
    lo = np.empty((len(parts), f))
    hi = np.empty((len(parts), f))
    if parts:
        zp = z[perm]
        np.minimum.reduceat(zp, bounds[:-1], axis=0, out=lo)
        np.maximum.reduceat(zp, bounds[:-1], axis=0, out=hi)
    leaf_of = np.full(capacity, -1, dtype=np.int64)
    leaf_of[perm] = np.repeat(np.arange(len(parts), dtype=np.int64), sizes)
    return Leaves(perm, bounds[:-1].copy(), bounds[1:].copy(), lo, hi, leaf_of, n)


# -- plain Python, compiled by ``kernels``: far too slow to call as it is --------------


def _mismatch(
    z: FloatArray,
    k: int,
    p: FloatArray,
    gidx: IntArray,
    gptr: IntArray,
    gscale: FloatArray,
    gw: FloatArray,
    bound: float,
) -> float:
    """Exact mismatch of category ``k`` (``_exact.exact_mismatch``'s operations), or a
    partial sum above ``bound`` as soon as one exceeds it."""
    r = 0.0
    for g in range(gptr.shape[0] - 1):
        s = 0.0
        for q in range(gptr[g], gptr[g + 1]):
            j = gidx[q]
            d = z[k, j] - p[j]
            s += d * d
        c = math.sqrt(s * gscale[g])
        if c > 1.0:
            c = 1.0
        r += gw[g] * c
        if r > bound:
            return r
    return r


def _lower_bound(
    p: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    leaf: int,
    gidx: IntArray,
    gptr: IntArray,
    gscale: FloatArray,
    gw: FloatArray,
) -> float:
    """A bound no category of ``leaf`` can fall below: the exact mismatch's operations on
    the distances from ``p`` to the leaf's box."""
    r = 0.0
    for g in range(gptr.shape[0] - 1):
        s = 0.0
        for q in range(gptr[g], gptr[g + 1]):
            j = gidx[q]
            x = p[j]
            e = lo[leaf, j] - x
            u = x - hi[leaf, j]
            if u > e:
                e = u
            if e > 0.0:
                s += e * e
        c = math.sqrt(s * gscale[g])
        if c > 1.0:
            c = 1.0
        r += gw[g] * c
    return r


def _best(
    p: FloatArray,
    z: FloatArray,
    n_cat: int,
    perm: IntArray,
    start: IntArray,
    end: IntArray,
    lo: FloatArray,
    hi: FloatArray,
    n_indexed: int,
    hint: int,
    gidx: IntArray,
    gptr: IntArray,
    gscale: FloatArray,
    gw: FloatArray,
) -> tuple[int, float]:
    """The category of least exact mismatch (ties to the lowest index) and the mismatch."""
    best_k = -1
    best_r = np.inf
    if hint >= 0:
        best_r = _mismatch(z, hint, p, gidx, gptr, gscale, gw, np.inf)
        best_k = hint
    for leaf in range(start.shape[0]):
        if _lower_bound(p, lo, hi, leaf, gidx, gptr, gscale, gw) > best_r:
            continue
        for q in range(start[leaf], end[leaf]):
            best_k, best_r = _consider(z, perm[q], p, hint, best_k, best_r, gidx, gptr, gscale, gw)
    for k in range(n_indexed, n_cat):  # the categories made since the leaves were built
        best_k, best_r = _consider(z, k, p, hint, best_k, best_r, gidx, gptr, gscale, gw)
    return best_k, best_r


def _consider(
    z: FloatArray,
    k: int,
    p: FloatArray,
    hint: int,
    best_k: int,
    best_r: float,
    gidx: IntArray,
    gptr: IntArray,
    gscale: FloatArray,
    gw: FloatArray,
) -> tuple[int, float]:
    """The better of category ``k`` and the best so far (the hint is scored already)."""
    if k == hint:
        return best_k, best_r
    r = _mismatch(z, k, p, gidx, gptr, gscale, gw, best_r)
    if r < best_r or (r == best_r and k < best_k):
        return k, r
    return best_k, best_r


def learn(
    wt: FloatArray,
    awt: FloatArray,
    t: int,
    t_stop: int,
    prev: int,
    n_cat: int,
    tail_max: int,
    z: FloatArray,
    counts: IntArray,
    perm: IntArray,
    start: IntArray,
    end: IntArray,
    lo: FloatArray,
    hi: FloatArray,
    leaf_of: IntArray,
    n_indexed: int,
    zl: FloatArray,
    p: FloatArray,
    oma: float,
    rho: float,
    d: float,
    alpha: float,
    nr: int,
    c: int,
    gidx: IntArray,
    gptr: IntArray,
    gscale: FloatArray,
    gw: FloatArray,
    labels: IntArray,
) -> tuple[int, int, int]:
    """Learn steps ``t..t_stop-1`` of one episode (``_engine.fit_episode``'s operations).

    Stops early, before a step, when the prototype rows ``z`` are full or ``tail_max``
    categories wait outside the leaves. Returns the next step, the number of categories
    and the last winner (``-1`` before the first step).
    """
    cap = z.shape[0]
    f = z.shape[1]
    while t < t_stop:
        if n_cat == cap or n_cat - n_indexed >= tail_max:
            break
        if t == 0:
            for j in range(f):
                p[j] = wt[0, j]
        else:
            for j in range(f):
                p[j] = awt[t, j] + zl[j]
        score = -1.0
        k = 0
        if n_cat > 0:
            k, r = _best(
                p, z, n_cat, perm, start, end, lo, hi, n_indexed, prev, gidx, gptr, gscale, gw
            )
            score = 1.0 - r
            if score < 0.0:
                score = 0.0
        if score >= rho:
            n = counts[k] + 1
            counts[k] = n
            lr = d * float(n) ** alpha
            for j in range(nr):
                zj = z[k, j]
                z[k, j] = zj + (p[j] - zj) * lr
            for j in range(nr - c):
                z[k, nr + j] = z[k, c + j] - z[k, j]
            if k < n_indexed:
                leaf = leaf_of[k]
                for j in range(f):
                    x = z[k, j]
                    if x < lo[leaf, j]:
                        lo[leaf, j] = x
                    if x > hi[leaf, j]:
                        hi[leaf, j] = x
        else:
            k = n_cat
            for j in range(nr):
                z[k, j] = p[j]
            for j in range(nr - c):
                z[k, nr + j] = z[k, c + j] - z[k, j]
            counts[k] = 1
            n_cat += 1
        for j in range(f):
            zl[j] = z[k, j] * oma
        labels[t] = k
        prev = k
        t += 1
    return t, n_cat, prev


def predict(
    wt: FloatArray,
    awt: FloatArray,
    z: FloatArray,
    omaz: FloatArray,
    perm: IntArray,
    start: IntArray,
    end: IntArray,
    lo: FloatArray,
    hi: FloatArray,
    p: FloatArray,
    gidx: IntArray,
    gptr: IntArray,
    gscale: FloatArray,
    gw: FloatArray,
    labels: IntArray,
    scores: FloatArray,
    offset: int,
) -> None:
    """Categorize one episode without learning (``_engine.Predictor.episode``'s operations)."""
    n_cat = z.shape[0]
    f = z.shape[1]
    k = -1
    for t in range(wt.shape[0]):
        if k < 0:
            for j in range(f):
                p[j] = wt[t, j]
        else:
            for j in range(f):
                p[j] = awt[t, j] + omaz[k, j]
        k, r = _best(p, z, n_cat, perm, start, end, lo, hi, n_cat, k, gidx, gptr, gscale, gw)
        labels[offset + t] = k
        s = 1.0 - r
        scores[offset + t] = s if s > 0.0 else 0.0


# -- drivers --------------------------------------------------------------------------


def _group_arrays(groups: Groups) -> tuple[IntArray, IntArray, FloatArray, FloatArray]:
    return (
        groups.index,
        groups.pointer,
        np.asarray(groups.scales, dtype=np.float64),
        np.asarray(groups.weights, dtype=np.float64),
    )


def learn_episodes(
    kern: Kernels,
    eng: Engine,
    episodes: Sequence[FloatArray],
    a: float,
    rho: float,
    d: float,
    alpha: float,
) -> IntArray:
    """Learn ``episodes`` (window features, in order) into ``eng`` with the kernels, as
    ``_engine.fit_episode`` would one by one; returns every step's category."""
    lay = eng.layout
    f, nr, c = eng.F, lay.n_raw, lay.channels[0]
    from behavior_hmm.cobart._index import partition_weight

    group_arrays = _group_arrays(eng.groups)
    weight = partition_weight(eng.gs, eng.wts)
    n_cat = eng.K
    cap = max(eng.capacity, 32)
    z = np.zeros((cap, f))
    z[:n_cat] = eng.zaug[:n_cat, :f]
    counts = np.zeros(cap, dtype=np.int64)
    counts[:n_cat] = eng.counts
    labels = np.empty(sum(w.shape[0] for w in episodes), dtype=np.int64)
    zl, p = np.zeros(f), np.zeros(f)
    lv = leaves(z, n_cat, weight, cap)
    since = 0  # learning steps since the leaves were built
    offset = 0
    for wt in episodes:
        awt = wt * a
        steps = wt.shape[0]
        out = labels[offset : offset + steps]
        t, prev = 0, -1
        while t < steps:
            if n_cat == cap:
                cap *= 2
                z = np.concatenate([z, np.zeros_like(z)])
                counts = np.concatenate([counts, np.zeros_like(counts)])
            if (
                lv.leaf_of.shape[0] != cap
                or n_cat - lv.n_indexed >= TAIL_MAX
                or since >= REBUILD_ROWS
            ):
                lv = leaves(z, n_cat, weight, cap)
                since = 0
            t_stop = min(steps, t + REBUILD_ROWS - since)
            t_next, n_cat, prev = kern.learn(
                wt, awt, t, t_stop, prev, n_cat, TAIL_MAX, z, counts, lv.perm, lv.start,
                lv.end, lv.lo, lv.hi, lv.leaf_of, lv.n_indexed, zl, p, 1.0 - a, rho, d,
                alpha, nr, c, *group_arrays, out,
            )  # fmt: skip
            since += t_next - t
            t = t_next
        offset += steps
    eng.load(z[:n_cat], counts[:n_cat].tolist())
    return labels


class CompiledPredictor:
    """What :func:`predict` needs of a fixed set of categories, built once."""

    def __init__(self, z: FloatArray, omaz: FloatArray, groups: Groups, weight: FloatArray) -> None:
        self.z = np.ascontiguousarray(z)
        self.omaz = np.ascontiguousarray(omaz)
        self.leaves = leaves(self.z, self.z.shape[0], weight, self.z.shape[0])
        self.groups = _group_arrays(groups)
        self.p = np.zeros(self.z.shape[1])

    def episode(
        self,
        kern: Kernels,
        wt: FloatArray,
        a: float,
        labels: IntArray,
        scores: FloatArray,
        offset: int,
    ) -> None:
        """Categorize one episode into ``labels``/``scores`` at ``offset``."""
        lv = self.leaves
        kern.predict(
            wt, wt * a, self.z, self.omaz, lv.perm, lv.start, lv.end, lv.lo, lv.hi, self.p,
            *self.groups, labels, scores, offset,
        )  # fmt: skip
