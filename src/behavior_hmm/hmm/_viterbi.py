"""Viterbi decoding in log space (thesis §3.3.1), vectorized over states."""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Container, Iterable, Mapping, Sequence
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from behavior_hmm._numba import KernelSetting, KernelSwitch
from behavior_hmm.hmm import _compiled
from behavior_hmm.hmm._tables import LogTable

#: Log emissions: a dense (N, M) array, or a model's sparse :class:`LogTable`.
Emissions = NDArray[np.float64] | LogTable


#: Elements of the (rows, N) score buffer in one block of a large model: the block of
#: scores stays in the cache between the add and the max (≈ 256 KB).
_BLOCK_ELEMENTS = 32_768
#: Models with at most this many transitions (N²) score all states in one block.
_ONE_BLOCK_MAX = 32_768
#: Transition tables with at most this share of possible (finite) entries are scored
#: entry by entry (work proportional to the possible transitions) instead of densely.
_SPARSE_MAX_DENSITY = 0.2
#: Up to this many states the forward pass also stores every best predecessor (an argmax
#: per state and step), which costs less than recomputing them while backtracking.
_PREDECESSORS_MAX_STATES = 16
#: Largest message (support of a node × support of its successor) that
#: :class:`TreeViterbi` computes entry by entry in Python instead of with numpy calls.
_SCALAR_MESSAGE_MAX = 64
#: Dense messages (N-vectors) :class:`TreeViterbi` keeps, most recently asked for first.
_DENSE_MESSAGES = 256
#: Which forward pass :func:`viterbi_log` runs; see :func:`set_kernel`.
_switch = KernelSwitch("Viterbi", lambda: _compiled.kernels())  # looked up at each call


def set_kernel(setting: KernelSetting) -> KernelSetting:
    """Choose the forward pass of :func:`viterbi_log`, for this process; return the old setting.

    Parameters
    ----------
    setting
        ``"auto"`` (the default): the numba-compiled kernel when numba is installed, the
        numpy one otherwise; ``"numba"``: the compiled kernel (ImportError without
        numba); ``"numpy"``: the numpy forward passes even when numba is installed (for
        tests and benchmarks: the results are identical, only the speed differs).
    """
    return _switch.set(setting)


def viterbi_kernel() -> Literal["numba", "numpy"]:
    """The forward pass :func:`viterbi_log` runs now (on sequences of two or more steps)."""
    return _switch.name()


def _kernels() -> _compiled.Kernels | None:
    """The compiled kernels when the setting and the installation allow them."""
    return _switch.active()


def viterbi_log(
    log_pi: NDArray[np.float64],
    log_A: NDArray[np.float64],
    log_B: Emissions,
    observations: NDArray[np.int64],
    *,
    compiled: bool = True,
) -> tuple[NDArray[np.int64], float, int]:
    """Most likely state sequence for an observation sequence.

    Parameters
    ----------
    log_pi, log_A, log_B
        Log initial distribution (N,), log transitions (N, N), log emissions (N, M,
        dense or a sparse :class:`~behavior_hmm.hmm._tables.LogTable`); ``-inf`` marks
        an impossible entry. Nothing here ever subtracts two log values,
        so ``-inf`` never turns into NaN.
    observations
        Observation indices, shape (T,), T ≥ 1.
    compiled
        Allow the compiled kernel (when installed and not switched off, see
        :func:`set_kernel`). ``False`` runs the numpy pass: a short sequence decoded
        inside a control cycle must not be the call that first imports numba (~0.7 s).

    Returns
    -------
    states : ndarray of int64, shape (T,)
        Most likely states (all zeros when no sequence is possible).
    log_prob : float
        ``log P(states, observations)``; ``-inf`` when every sequence is impossible.
    dead_at : int
        First position where every state became impossible, or -1.

    Notes
    -----
    There are two forward passes, with identical results (path, log probability and
    ``dead_at``, to the bit). When numba is installed (the ``fast`` extra), a compiled
    loop (:mod:`behavior_hmm.hmm._compiled`) scores every transition in the order below
    and stores the best predecessors, then follows them back. Otherwise, or after
    ``set_kernel("numpy")`` (:func:`set_kernel`; :func:`viterbi_kernel` says which pass
    runs), the numpy forward passes described next run.

    Each step of the numpy forward pass is a fixed handful of numpy calls on buffers
    allocated once, so that small models pay little per step and large ones stream
    through the cache. From 17 states on, the forward pass keeps only the best scores, as
    hmmlearn's compiled Viterbi does: the previous scores are copied into every row of a
    tile, one flat add with the transposed transitions gives ``scores[j, i] = log a_ij +
    delta_i``, one segmented max (``maximum.reduceat``) the best score of each state, and
    one add the emissions; a large table is scored in blocks of rows that stay in the
    cache, a sparse one (mostly ``-inf``) only at its possible transitions. Backtracking
    then recomputes the best predecessor of each position from the stored scores (one add
    and one argmax). Smaller models store the best predecessors during the forward pass
    instead (an argmax per row of the scores).

    Both passes form the sums in hmmlearn's order (``delta_i + log a_ij``, then
    ``+ log b_j``), so all give the same log probability, to the bit, and the same path
    except among equally likely predecessors: both our passes keep the lowest state index
    (the argmax's rule), hmmlearn's backtracking the highest; either path is optimal.
    """
    n = log_pi.shape[0]
    t_len = observations.shape[0]
    emit = _emissions(log_B, observations)  # row t = log b_j(o_t) for all j
    lattice = np.empty((t_len, n))
    np.add(log_pi, emit[0], out=lattice[0])
    if not np.isfinite(lattice[0].max()):
        return np.zeros(t_len, dtype=np.int64), float("-inf"), 0
    kernels = _kernels() if compiled and t_len > 1 else None
    if kernels is not None:
        return _compiled_viterbi(kernels, log_A, emit, lattice)
    log_at = _aligned_empty((n, n))
    log_at[...] = log_A.T  # row j = log a_·j: the transitions into state j
    psi = None
    if t_len > 1 and n <= _PREDECESSORS_MAX_STATES:
        psi = _forward_predecessors(log_at, emit, lattice)
    elif t_len > 1:
        _forward(log_at, emit, lattice)
    state = int(lattice[-1].argmax())
    log_prob = float(lattice[-1, state])
    if not np.isfinite(log_prob):
        return _impossible(lattice)
    if psi is not None:
        return _follow(psi, state), log_prob, -1
    return _backtrack(log_at, lattice, state), log_prob, -1


def _compiled_viterbi(
    kernels: _compiled.Kernels,
    log_A: NDArray[np.float64],
    emit: NDArray[np.float64],
    lattice: NDArray[np.float64],
) -> tuple[NDArray[np.int64], float, int]:
    """The rest of :func:`viterbi_log` (``lattice[0]`` filled and possible), compiled."""
    t_len, n = lattice.shape
    psi = np.empty((t_len, n), dtype=np.intp)
    emit = np.ascontiguousarray(emit)
    sparse = _sparse_transitions(log_A.T)
    if sparse is not None:
        source, weights, starts = sparse
        kernels.forward_sparse(starts, source, weights, emit, lattice, psi)
    else:
        log_a = np.ascontiguousarray(log_A, dtype=np.float64)
        kernels.forward(log_a, emit, lattice, psi)
    state = int(lattice[-1].argmax())
    log_prob = float(lattice[-1, state])
    if not np.isfinite(log_prob):
        return _impossible(lattice)
    states = np.empty(t_len, dtype=np.int64)
    kernels.follow(psi, state, states)
    return states, log_prob, -1


def _impossible(lattice: NDArray[np.float64]) -> tuple[NDArray[np.int64], float, int]:
    """:func:`viterbi_log`'s answer when no state is possible at the last position."""
    # Once every state is impossible, every later one is too (-inf only propagates).
    alive = np.isfinite(lattice.max(axis=1))
    return np.zeros(lattice.shape[0], dtype=np.int64), float("-inf"), int(np.argmin(alive))


def _emissions(log_B: Emissions, observations: NDArray[np.int64]) -> NDArray[np.float64]:
    """``log_B[:, observations].T`` as a C-contiguous (T, N) array."""
    if isinstance(log_B, LogTable):
        return log_B.columns(observations)
    if log_B.nbytes <= 1 << 20:  # in the cache: gather the columns directly
        return log_B.T.take(observations, axis=0)
    # a large table: gather inside its rows, then transpose only the T columns needed
    return np.ascontiguousarray(log_B.take(observations, axis=1).T)


def _aligned_empty(shape: tuple[int, ...]) -> NDArray[np.float64]:
    """An uninitialized float64 array whose data starts on a 64-byte (cache line) boundary.

    numpy's vectorized add writes whole cache lines when its output is aligned, about
    twice as fast as unaligned on small buffers.
    """
    size = int(np.prod(shape))
    raw = np.empty(size + 8)
    skip = (-raw.ctypes.data % 64) // raw.itemsize
    return raw[skip : skip + size].reshape(shape)


def _forward(
    log_at: NDArray[np.float64],
    emit: NDArray[np.float64],
    lattice: NDArray[np.float64],
) -> None:
    """Fill ``lattice[1:]`` with the best log scores, in place.

    ``log_at`` is the transposed log transition table (row j = log a_·j), ``emit[t]`` the
    log emissions of observation t, ``lattice[0]`` the start scores.
    """
    n = log_at.shape[0]
    sparse = _sparse_transitions(log_at)
    if sparse is not None:
        _forward_sparse(*sparse, emit, lattice)
        return
    rows = n if n * n <= _ONE_BLOCK_MAX else min(n, max(8, _BLOCK_ELEMENTS // n))
    tile = _aligned_empty((rows, n))  # every row = the previous scores
    fill = tile.__setitem__
    buf = _aligned_empty((rows * n,))
    add, reduceat = np.add, np.maximum.reduceat
    steps = zip(lattice[1:], emit[1:], strict=True)
    prev = lattice[0]
    if rows == n:
        flat_at, flat_tile = log_at.reshape(-1), tile.reshape(-1)
        starts = np.arange(0, n * n, n)
        for cur, e in steps:
            fill(Ellipsis, prev)
            add(flat_at, flat_tile, buf)  # buf[j * n + i] = log a_ij + delta_i
            reduceat(buf, starts, 0, None, cur)  # best score into each state j
            add(cur, e, cur)
            prev = cur
        return
    blocks = []
    for start in range(0, n, rows):
        stop = min(start + rows, n)
        size = (stop - start) * n
        flat_tile = tile.reshape(-1)[:size]
        blocks.append(
            (log_at[start:stop].reshape(-1), flat_tile, buf[:size], np.arange(0, size, n), start)
        )
    for cur, e in steps:
        fill(Ellipsis, prev)
        for flat_at, flat_tile, block, starts, start in blocks:
            add(flat_at, flat_tile, block)
            reduceat(block, starts, 0, None, cur[start : start + starts.shape[0]])
        add(cur, e, cur)
        prev = cur


def _sparse_transitions(
    log_at: NDArray[np.float64],
) -> tuple[NDArray[np.intp], NDArray[np.float64], NDArray[np.intp]] | None:
    """The possible transitions of a sparse table, or ``None`` for a dense one.

    ``log_at`` is the transposed log transition table (row j = log a_·j). A table is
    sparse when at most ``_SPARSE_MAX_DENSITY`` of it is finite. Returns ``source``,
    ``weights`` and ``starts`` (N + 1,): the transitions into state j are entries
    ``starts[j] .. starts[j + 1] - 1``, their predecessors ``source`` in increasing
    order with ``log a_ij`` in ``weights``. A target no state can reach gets one entry
    (state 0, ``-inf``): every segment is non-empty, its score stays ``-inf`` and its
    best predecessor 0, in the numpy and the compiled pass alike.
    """
    n = log_at.shape[0]
    listed = np.isfinite(log_at)
    if np.count_nonzero(listed) > _SPARSE_MAX_DENSITY * n * n:
        return None
    listed[~listed.any(axis=1), 0] = True  # log_at is -inf there
    target, source = np.nonzero(listed)  # row-major: grouped by target, sources ascending
    weights = np.ascontiguousarray(log_at[target, source], dtype=np.float64)
    starts = np.searchsorted(target, np.arange(n + 1)).astype(np.intp)
    return source.astype(np.intp), weights, starts


def _forward_sparse(
    source: NDArray[np.intp],
    weights: NDArray[np.float64],
    starts: NDArray[np.intp],
    emit: NDArray[np.float64],
    lattice: NDArray[np.float64],
) -> None:
    """:func:`_forward` over the possible transitions only (:func:`_sparse_transitions`)."""
    starts = starts[:-1]  # the segments' first entries, for the segmented max
    scores = np.empty(source.shape[0])
    add, reduceat = np.add, np.maximum.reduceat
    prev = lattice[0]
    for cur, e in zip(lattice[1:], emit[1:], strict=True):
        prev.take(source, None, scores, "clip")  # indices are in range: no checked copy
        add(scores, weights, scores)  # delta_i + log a_ij, for every possible (i, j)
        reduceat(scores, starts, 0, None, cur)
        add(cur, e, cur)
        prev = cur


def _forward_predecessors(
    log_at: NDArray[np.float64],
    emit: NDArray[np.float64],
    lattice: NDArray[np.float64],
) -> NDArray[np.intp]:
    """:func:`_forward` for small models, also returning the best predecessors ``psi``.

    Each step: one (N, N) add of the previous scores to the transposed transitions, one
    argmax per row (the lowest predecessor among ties), and a gather of the winning
    scores plus the emissions.
    """
    n = log_at.shape[0]
    psi = np.empty(lattice.shape, dtype=np.intp)
    buf = _aligned_empty((n, n))
    offsets = np.arange(0, n * n, n, dtype=np.intp)  # flat index of each row's start
    flat_index = np.empty(n, dtype=np.intp)
    add, argmax, take = np.add, buf.argmax, buf.reshape(-1).take
    prev = lattice[0]
    for best, cur, e in zip(psi[1:], lattice[1:], emit[1:], strict=True):
        add(log_at, prev, buf)  # buf[j, i] = log a_ij + delta_i
        argmax(1, best)
        add(best, offsets, flat_index)
        take(flat_index, None, cur, "clip")  # indices are in range: no checked copy
        add(cur, e, cur)
        prev = cur
    return psi


def _backtrack(
    log_at: NDArray[np.float64], lattice: NDArray[np.float64], last: int
) -> NDArray[np.int64]:
    """Best path ending in state ``last``, one predecessor argmax per position."""
    into = list(log_at)  # into[j] = log a_·j
    scores = np.empty(log_at.shape[0])
    add, argmax = np.add, scores.argmax
    state = last
    path = [state]
    append = path.append
    for row in lattice[-2::-1]:
        add(row, into[state], scores)  # the sums of the forward pass, bit for bit
        state = int(argmax())
        append(state)
    path.reverse()
    return np.array(path, dtype=np.int64)


def _follow(psi: NDArray[np.intp], last: int) -> NDArray[np.int64]:
    """The path through the stored best predecessors ending in state ``last``."""
    states = np.empty(psi.shape[0], dtype=np.int64)
    state = last
    item = psi.item
    for t in range(psi.shape[0] - 1, 0, -1):
        states[t] = state
        state = item(t, state)
    states[0] = state
    return states


def emission_decode(
    log_pi: NDArray[np.float64],
    log_B: Emissions,
    observations: NDArray[np.int64],
) -> tuple[NDArray[np.int64], int]:
    """Per-element posterior mode ``argmax_j π_j b_j(o)``, ignoring transitions.

    With π the state density and B counted per cycle, ``π_j b_j(o)`` is proportional
    to how often state j was seen together with observation o.

    Returns
    -------
    states : ndarray of int64, shape (T,)
    dead_at : int
        First position whose observation no state ever emits, or -1.
    """
    scores = log_pi[None, :] + _emissions(log_B, observations)  # (T, N)
    best = scores.max(axis=1)
    bad = np.flatnonzero(~np.isfinite(best))
    states = scores.argmax(axis=1).astype(np.int64)
    return states, int(bad[0]) if bad.size else -1


def sequence_log_prob(
    log_pi: NDArray[np.float64],
    log_A: NDArray[np.float64],
    log_B: Emissions,
    states: NDArray[np.int64],
    observations: NDArray[np.int64],
) -> float:
    """Joint ``log P(states, observations)`` of one given state sequence."""
    total = log_pi[states[0]] + log_A[states[:-1], states[1:]].sum()
    if isinstance(log_B, LogTable):
        return float(total + log_B.values(states, observations).sum())
    return float(total + log_B[states, observations].sum())


class TreeViterbi:
    """Viterbi for every path of one goal's shortest-path tree, shared between paths.

    All paths to one goal form an in-tree (each node has one successor), so the
    backward max-product message of a node depends only on the node and its
    successor: ``V_u(i) = log b_i(u) + max_j [log a_ij + V_next(u)(j)]`` with
    ``V_goal(i) = log b_i(goal)``. Each node's message is computed once per goal; a
    plan from any current node is then ``argmax_i log π_i + V_c(i)`` followed by a
    walk through the stored argmaxes. The result is the Viterbi optimum of the path
    (ties may be broken differently from :func:`viterbi_log`).

    A message is finite only at the states that emit the node's category (``log b_i(u)``
    is ``-inf`` elsewhere), and a trained model's category is emitted by a few states.
    So each node keeps its message on that support only, and a message costs
    ``support(u) × support(next)`` entries of A instead of N × N: memory and time stay
    small at thousands of states and 100,000 categories. Every kept value and argmax is
    the one the dense recursion gives (the same sums; ties to the lowest state index).
    A smoothed B has every state emit every category: the messages are then whole
    N-vectors, computed with numpy as the dense recursion computes them.

    Parameters
    ----------
    next_node
        Successor of each node on its path to ``goal`` (from the goal tree).
    goal
        The goal observation category.
    log_pi, log_A, log_B
        Model tables in log space, as in :func:`viterbi_log` (``log_B`` sparse).
    """

    def __init__(
        self,
        next_node: list[int],
        goal: int,
        log_pi: NDArray[np.float64],
        log_A: NDArray[np.float64],
        log_B: LogTable,
    ) -> None:
        self._next_node = next_node
        self._goal = goal
        self._log_pi = log_pi
        self._log_A = log_A
        self._log_B = log_B
        self._dense = log_B.dense_fill
        self._col_ptr, self._col_rows, self._col_data = log_B._by_column()
        self._log_a = log_A.item  # one entry of A as a Python float
        # per node: the states that emit it (ascending), their message values, and for
        # each of them the best state at the next node. Tuples of numbers and dicts of
        # ints: the garbage collector stops tracking them, so that tens of thousands of
        # cached nodes do not slow every full collection down.
        self._support: dict[int, tuple[int, ...]] = {}
        self._value: dict[int, tuple[float, ...]] = {}
        self._best_next: dict[int, dict[int, int]] = {}
        self._dense_cache: OrderedDict[int, NDArray[np.float64]] = OrderedDict()
        # a smoothed B (every state emits every category): whole N-vectors and argmaxes,
        # numpy throughout (the supports would be all N states)
        self._full_value: dict[int, NDArray[np.float64]] = {}
        self._full_next: dict[int, list[int]] = {}
        self._rows = np.arange(log_A.shape[0])

    def _emitters(self, u: int) -> tuple[tuple[int, ...], tuple[float, ...]]:
        """The states that may emit category ``u`` and their ``log b_i(u)``."""
        lo, hi = self._col_ptr.item(u), self._col_ptr.item(u + 1)
        return tuple(self._col_rows[lo:hi].tolist()), tuple(self._col_data[lo:hi].tolist())

    def _uncomputed(self, node: int, done: Container[int]) -> list[int]:
        """``node`` and the nodes after it toward the goal not in ``done``, goal side first."""
        chain: list[int] = []
        u = node
        while u not in done:  # climb to the first node already computed
            chain.append(u)
            if u == self._goal:
                break
            u = self._next_node[u]
        chain.reverse()
        return chain

    def _compute_full(self, node: int) -> None:
        """:meth:`_compute` for a smoothed B: dense messages, ``N × N`` per node."""
        for u in self._uncomputed(node, self._full_value):
            if u == self._goal:
                self._full_value[u] = self._log_B.column(u)
                continue
            scores = self._log_A + self._full_value[self._next_node[u]][None, :]
            best = scores.argmax(axis=1)
            self._full_value[u] = scores[self._rows, best] + self._log_B.column(u)
            self._full_next[u] = best.tolist()

    def compute(self, nodes: Iterable[int]) -> None:
        """Compute the messages of ``nodes`` (and of their paths) now; a smoothed B's later.

        The values are those a first use computes (each depends on its node and the
        next one only), so when they are computed changes no plan.
        """
        if self._dense:
            return
        done = self._value
        for u in nodes:
            if u not in done:
                self._compute(u)

    def _compute(self, node: int) -> None:
        """Compute the messages of ``node`` and of the nodes after it not yet computed."""
        for u in self._uncomputed(node, self._value):
            support, log_b = self._emitters(u)
            self._support[u] = support
            if u == self._goal:
                self._value[u] = log_b
                continue
            nxt = self._next_node[u]
            if len(support) * len(self._support[nxt]) <= _SCALAR_MESSAGE_MAX:
                value, best = self._scalar_message(support, log_b, nxt)
            else:
                value, best = self._array_message(support, log_b, nxt)
            self._value[u] = value
            self._best_next[u] = dict(zip(support, best, strict=True))

    def _scalar_message(
        self, support: tuple[int, ...], log_b: tuple[float, ...], nxt: int
    ) -> tuple[tuple[float, ...], list[int]]:
        """A small message entry by entry: the same sums and ties as the array path."""
        next_support = self._support[nxt]
        next_value = self._value[nxt]
        log_a = self._log_a
        first = next_support[0] if next_support else 0
        value: list[float] = []
        best: list[int] = []
        for i, b in zip(support, log_b, strict=True):
            top, arg = -math.inf, first
            for j, v in zip(next_support, next_value, strict=True):
                score = log_a(i, j) + v
                if score > top:  # strictly: the lowest state wins a tie, as argmax
                    top, arg = score, j
            value.append(top + b)
            best.append(arg)
        return tuple(value), best

    def _array_message(
        self, support: tuple[int, ...], log_b: tuple[float, ...], nxt: int
    ) -> tuple[tuple[float, ...], list[int]]:
        """A large message (categories emitted by many states) with numpy."""
        next_support = np.asarray(self._support[nxt], dtype=np.intp)
        rows = np.asarray(support, dtype=np.intp)
        scores = self._log_A[np.ix_(rows, next_support)] + np.asarray(self._value[nxt])[None, :]
        arg = scores.argmax(axis=1)
        value = scores[np.arange(rows.shape[0]), arg] + np.asarray(log_b)
        return tuple(value.tolist()), next_support[arg].tolist()

    def startable(self, nodes: Sequence[int]) -> list[bool]:
        """Whether a decoding starts at each of ``nodes``: ``max(log π + V_node)`` is
        finite (what :meth:`decode` needs; the nodes must reach the goal)."""
        log_pi = self._log_pi
        if self._dense:
            return [bool(np.isfinite(np.max(log_pi + self._message(u)))) for u in nodes]
        self.compute(nodes)
        pi = log_pi.tolist()
        support, value = self._support, self._value
        return [
            any(math.isfinite(pi[s] + v) for s, v in zip(support[u], value[u], strict=True))
            for u in nodes
        ]

    def _message(self, node: int) -> NDArray[np.float64]:
        """The dense message ``V_node`` (N,): ``-inf`` off its support.

        The last ``_DENSE_MESSAGES`` asked for are kept (a controller asks for the same
        category's message every cycle while it stays there); do not modify the array.
        """
        if self._dense:
            self._compute_full(node)
            return self._full_value[node]
        dense = self._dense_cache
        out = dense.get(node)
        if out is not None:
            dense.move_to_end(node)
            return out
        self._compute(node)
        out = np.full(self._log_A.shape[0], -np.inf)
        out[list(self._support[node])] = self._value[node]
        dense[node] = out
        if len(dense) > _DENSE_MESSAGES:
            dense.popitem(last=False)
        return out

    def decode(self, path: list[int]) -> tuple[list[int], float]:
        """Most likely states along ``path`` (which must be a path of this tree).

        Returns ``([], -inf)`` when every state sequence is impossible.
        """
        first = path[0]
        follow: Mapping[int, Mapping[int, int]] | Mapping[int, list[int]]
        if self._dense:  # whole N-vectors: position = state
            self._compute_full(first)
            support: Sequence[int] = range(self._log_A.shape[0])
            start = self._log_pi + self._full_value[first]
            follow = self._full_next
        else:
            self._compute(first)
            support = self._support[first]
            if not support:
                return [], float("-inf")
            start = self._log_pi[list(support)] + np.asarray(self._value[first])
            follow = self._best_next
        at = int(start.argmax())
        log_prob = float(start[at])
        if not np.isfinite(log_prob):
            return [], float("-inf")
        state = support[at]
        states = [state]
        for u in path[:-1]:
            state = follow[u][state]
            states.append(state)
        return states, log_prob
