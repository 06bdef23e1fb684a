"""The numba-compiled CobART kernels: learning and categorizing whole episodes.

numba is optional, the ``fast`` extra (``pip install 'behavior-hmm[fast]'``). Without it
CobART runs its numpy paths (module ``_engine``), whose step is a dozen or two numpy calls
(~35 µs a step scoring 2,300 categories, ~25 µs screening most steps by the last full scan,
module ``_reference``; most of it call overhead). With it,
:meth:`CobART.partial_fit <behavior_hmm.cobart.CobART.partial_fit>` and
:meth:`~behavior_hmm.cobart.CobART.categorize` of a single-part layout run an episode in
one call of these kernels. Both choose every winner by the exact mismatch of module
``_exact``, formed with the same floating-point operations in the same order, so the
categories, prototypes, counts, labels and scores are identical to the bit either way.

The kernels do not score every category. The categories are held in a k-d tree
(module ``_index``'s split: medians of the widest weighted feature) whose nodes, each
with the bounding box of its categories, are stored in depth-first order with a pointer
past each node's subtree. A box gives a lower bound on the exact mismatch of every
category in it, formed with the same operations on the box distances (each no larger
than the category's own difference, and every operation monotone), so a node whose bound
exceeds the best mismatch so far cannot hold the winner and its subtree is skipped. A
category's mismatch is summed group by group and abandoned as soon as it exceeds the
best so far. The previous step's winner is scored first: the input moves little from one
step to the next. While learning, a prototype that moves widens its leaf's box and its
ancestors', and new categories are scored one by one until the tree is rebuilt (every
``REBUILD_ROWS`` steps, or when ``TAIL_MAX`` new categories wait).

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

#: Most categories per leaf of the kernels' tree (on the turn & approach CBLM's 2,310
#: observation categories leaves of 4-8 categorize fastest, 1.4 us a window; 32 take
#: 2.3 us, and flat leaves of 128 without a tree above them 6.6 us).
LEAF_SIZE: Final[int] = 8
#: New categories scored one by one before the tree is rebuilt.
TAIL_MAX: Final[int] = 32
#: Learning steps between rebuilds of the tree (moved prototypes widen their boxes).
REBUILD_ROWS: Final[int] = 4_096


class Kernels(NamedTuple):
    """The compiled kernels (see :func:`learn` and :func:`predict`)."""

    learn: Callable[..., tuple[int, int, int]]
    predict: Callable[..., None]
    build: Callable[..., int]
    best: Callable[..., tuple[int, float]]


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
    g["_widen"] = jit(_bind(_widen, g))
    g["_consider"] = jit(_bind(_consider, g))
    best = jit(_bind(_best, g))
    g["_best"] = best
    return Kernels(
        learn=jit(_bind(learn, g)),
        predict=jit(_bind(predict, g)),
        build=jit(_bind(build, g)),
        best=best,
    )


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
    kern = active()
    if kern is None:
        return
    from behavior_hmm.cobart._cobart import CobART  # _cobart imports this module

    x = np.linspace(-1.0, 1.0, 24).reshape(12, 2)
    model = CobART(window=3).fit(x)
    model.categorize(x)
    pred = model._predictor()
    pred.compiled_search(kern).best(pred.pt, -1)  # a live stream's search


class Tree(NamedTuple):
    """A k-d tree over categories ``0..n_indexed-1``, its nodes in depth-first order.

    Node ``i`` holds the box ``lo[i]``..``hi[i]`` of its categories; its subtree ends
    before node ``skip[i]``; a leaf lists ``perm[start[i]:end[i]]``, an inner node has
    ``start[i] == -1``. ``parent`` (``-1`` at the root) and ``leaf_of`` (per category,
    sized to the capacity, ``-1`` outside the tree) let a moved prototype widen its
    leaf's box and its ancestors'.
    """

    perm: IntArray
    lo: FloatArray
    hi: FloatArray
    skip: IntArray
    start: IntArray
    end: IntArray
    parent: IntArray
    leaf_of: IntArray
    n_indexed: int


def tree(kern: Kernels, z: FloatArray, n: int, weight: FloatArray, capacity: int) -> Tree:
    """The tree of the first ``n`` feature rows of ``z`` (``leaf_of`` sized ``capacity``);
    ``weight``: ``_index.partition_weight`` of the layout."""
    f = z.shape[1]
    nodes = 4 * (n // LEAF_SIZE + 1)  # a leaf holds at least half of LEAF_SIZE (or all n)
    perm = np.arange(n, dtype=np.int64)
    lo, hi = np.empty((nodes, f)), np.empty((nodes, f))
    skip, start, end, parent = (np.empty(nodes, dtype=np.int64) for _ in range(4))
    leaf_of = np.full(capacity, -1, dtype=np.int64)
    m = kern.build(
        np.ascontiguousarray(z[:n] * weight), z, n, LEAF_SIZE, perm, lo, hi, skip, start, end,
        parent, leaf_of,
    )  # fmt: skip
    return Tree(perm, lo[:m], hi[:m], skip[:m], start[:m], end[:m], parent[:m], leaf_of, n)


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
    node: int,
    gidx: IntArray,
    gptr: IntArray,
    gscale: FloatArray,
    gw: FloatArray,
) -> float:
    """A bound no category under ``node`` can fall below: the exact mismatch's operations
    on the distances from ``p`` to the node's box."""
    r = 0.0
    for g in range(gptr.shape[0] - 1):
        s = 0.0
        for q in range(gptr[g], gptr[g + 1]):
            j = gidx[q]
            x = p[j]
            e = lo[node, j] - x
            u = x - hi[node, j]
            if u > e:
                e = u
            if e > 0.0:
                s += e * e
        c = math.sqrt(s * gscale[g])
        if c > 1.0:
            c = 1.0
        r += gw[g] * c
    return r


def _widen(lo: FloatArray, hi: FloatArray, node: int, z: FloatArray, k: int) -> bool:
    """Widen ``node``'s box to hold feature row ``k`` of ``z``; whether it grew."""
    grown = False
    for j in range(z.shape[1]):
        x = z[k, j]
        if x < lo[node, j]:
            lo[node, j] = x
            grown = True
        if x > hi[node, j]:
            hi[node, j] = x
            grown = True
    return grown


def _best(
    p: FloatArray,
    z: FloatArray,
    n_cat: int,
    perm: IntArray,
    lo: FloatArray,
    hi: FloatArray,
    skip: IntArray,
    start: IntArray,
    end: IntArray,
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
    node = 0
    while node < skip.shape[0]:
        if _lower_bound(p, lo, hi, node, gidx, gptr, gscale, gw) > best_r:
            node = skip[node]  # past the subtree
            continue
        for q in range(start[node], end[node]):  # a leaf's categories (none inside)
            best_k, best_r = _consider(z, perm[q], p, hint, best_k, best_r, gidx, gptr, gscale, gw)
        node += 1
    for k in range(n_indexed, n_cat):  # the categories made since the tree was built
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
    lo: FloatArray,
    hi: FloatArray,
    skip: IntArray,
    start: IntArray,
    end: IntArray,
    parent: IntArray,
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
                p, z, n_cat, perm, lo, hi, skip, start, end, n_indexed, prev, gidx, gptr,
                gscale, gw,
            )  # fmt: skip
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
            node = leaf_of[k]  # -1 for a category made since the tree was built
            # widen the boxes up the tree while one grows (the ancestors' hold the rest)
            while node >= 0 and _widen(lo, hi, node, z, k):
                node = parent[node]
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
    lo: FloatArray,
    hi: FloatArray,
    skip: IntArray,
    start: IntArray,
    end: IntArray,
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
        k, r = _best(p, z, n_cat, perm, lo, hi, skip, start, end, n_cat, k, gidx, gptr, gscale, gw)
        labels[offset + t] = k
        s = 1.0 - r
        scores[offset + t] = s if s > 0.0 else 0.0


def build(
    zw: FloatArray,
    z: FloatArray,
    n: int,
    leaf_size: int,
    perm: IntArray,
    lo: FloatArray,
    hi: FloatArray,
    skip: IntArray,
    start: IntArray,
    end: IntArray,
    parent: IntArray,
    leaf_of: IntArray,
) -> int:
    """Build :class:`Tree`'s arrays over rows ``0..n-1`` (``perm`` holding ``0..n-1``):
    each node of more than ``leaf_size`` categories split at the median of the feature of
    widest spread in ``zw`` (the weighted rows), boxes from ``z``; returns the node count.
    Which categories share a leaf changes only how fast a winner is found, never which.

    The split is ``_index._partition``'s, compiled: learning rebuilds the tree often (78
    times in the turn & approach CBLM's fit), and ``_partition`` takes ~9 ms for the
    leaves alone of 2,310 categories where this takes ~1.5 ms for the whole tree."""
    f = z.shape[1]
    if n == 0:
        return 0
    stack = np.empty((128, 3), dtype=np.int64)  # depth ~log2(n): 128 is never reached
    stack[0, 0], stack[0, 1], stack[0, 2] = 0, n, -1
    top = 1
    m = 0
    while top > 0:
        top -= 1
        a, b, up = stack[top, 0], stack[top, 1], stack[top, 2]
        node = m
        m += 1
        parent[node] = up
        for j in range(f):
            lo[node, j] = np.inf
            hi[node, j] = -np.inf
        for q in range(a, b):
            _widen(lo, hi, node, z, perm[q])
        if b - a <= leaf_size:
            start[node], end[node] = a, b
            for q in range(a, b):
                leaf_of[perm[q]] = node
            continue
        start[node], end[node] = -1, -1
        dim, widest = 0, -1.0
        for j in range(f):
            low, high = np.inf, -np.inf
            for q in range(a, b):
                x = zw[perm[q], j]
                if x < low:
                    low = x
                if x > high:
                    high = x
            if high - low > widest:
                dim, widest = j, high - low
        values = np.empty(b - a)
        for q in range(a, b):
            values[q - a] = zw[perm[q], dim]
        order = np.argsort(values)
        members = perm[a:b].copy()
        for q in range(b - a):
            perm[a + q] = members[order[q]]
        half = a + (b - a) // 2
        stack[top, 0], stack[top, 1], stack[top, 2] = half, b, node  # right after left
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = a, half, node
        top += 2
    size = np.ones(m, dtype=np.int64)
    for node in range(m - 1, 0, -1):  # children come after their parent
        size[parent[node]] += size[node]
    for node in range(m):
        skip[node] = node + size[node]
    return m


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
    tr = tree(kern, z, n_cat, weight, cap)
    since = 0  # learning steps since the tree was built
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
                tr.leaf_of.shape[0] != cap
                or n_cat - tr.n_indexed >= TAIL_MAX
                or since >= REBUILD_ROWS
            ):
                tr = tree(kern, z, n_cat, weight, cap)
                since = 0
            t_stop = min(steps, t + REBUILD_ROWS - since)
            t_next, n_cat, prev = kern.learn(
                wt, awt, t, t_stop, prev, n_cat, TAIL_MAX, z, counts, *tr, zl, p, 1.0 - a,
                rho, d, alpha, nr, c, *group_arrays, out,
            )  # fmt: skip
            since += t_next - t
            t = t_next
        offset += steps
    eng.load(z[:n_cat], counts[:n_cat].tolist())
    return labels


class CompiledPredictor:
    """What :func:`predict` needs of a fixed set of categories, built once."""

    def __init__(
        self, kern: Kernels, z: FloatArray, omaz: FloatArray, groups: Groups, weight: FloatArray
    ) -> None:
        self.z = np.ascontiguousarray(z)
        self.omaz = np.ascontiguousarray(omaz)
        self.n = self.z.shape[0]
        self.tree = tree(kern, self.z, self.n, weight, self.n)
        self.groups = _group_arrays(groups)
        self.p = np.zeros(self.z.shape[1])
        self._best = kern.best

    def best(self, p: FloatArray, hint: int) -> tuple[int, float]:
        """The category of least exact mismatch to the processed input ``p`` and that
        mismatch (``hint``: a category to score first, e.g. the last winner; -1: none).
        One compiled call of ~1 µs of dispatch: a live stream's search."""
        tr = self.tree
        return self._best(
            p, self.z, self.n, tr.perm, tr.lo, tr.hi, tr.skip, tr.start, tr.end, self.n,
            hint, *self.groups,
        )  # fmt: skip

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
        tr = self.tree
        kern.predict(
            wt, wt * a, self.z, self.omaz, tr.perm, tr.lo, tr.hi, tr.skip, tr.start, tr.end,
            self.p, *self.groups, labels, scores, offset,
        )  # fmt: skip
