"""Viterbi decoding in log space (thesis §3.3.1), vectorized over states."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: Rows of the (rows, N) score buffer in one block: the block of scores stays in the cache
#: between the add and the argmax (≈ 256 KB); small models use one block of N rows.
_BLOCK_ELEMENTS = 32_768
#: Models with at most this many transitions (N²) score all states in one block.
_ONE_BLOCK_MAX = 131_072


def viterbi_log(
    log_pi: NDArray[np.float64],
    log_A: NDArray[np.float64],
    log_B: NDArray[np.float64],
    observations: NDArray[np.int64],
) -> tuple[NDArray[np.int64], float, int]:
    """Most likely state sequence for an observation sequence.

    Parameters
    ----------
    log_pi, log_A, log_B
        Log initial distribution (N,), log transitions (N, N), log emissions (N, M);
        ``-inf`` marks an impossible entry. Nothing here ever subtracts two log values,
        so ``-inf`` never turns into NaN.
    observations
        Observation indices, shape (T,), T ≥ 1.

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
    Each step is one (N, N) add of the previous scores to the transposed transitions
    (``scores[j, i] = log a_ij + delta_i``), one argmax per row (ties go to the lowest
    predecessor, as in hmmlearn), and a gather of the winning scores plus the emissions,
    all written into buffers allocated once. The sums are formed in the same order as
    hmmlearn's compiled Viterbi (``delta_i + log a_ij``, then ``+ log b_j``), so both give
    the same path and the same log probability. A large model scores the states in
    blocks of rows so that each block stays in the cache.
    """
    n = log_pi.shape[0]
    t_len = observations.shape[0]
    emit = np.ascontiguousarray(log_B.T)[observations]  # row t = log b_j(o_t) for all j
    lattice = np.empty((t_len, n))
    np.add(log_pi, emit[0], out=lattice[0])
    if not np.isfinite(lattice[0].max()):
        return np.zeros(t_len, dtype=np.int64), float("-inf"), 0
    psi = np.empty((t_len, n), dtype=np.intp)
    if t_len > 1:
        _forward(np.ascontiguousarray(log_A.T), emit, lattice, psi)
    # Once every state is impossible, every later one is too (-inf only propagates).
    alive = np.isfinite(lattice.max(axis=1))
    if not alive[-1]:
        return np.zeros(t_len, dtype=np.int64), float("-inf"), int(np.argmin(alive))
    states = np.empty(t_len, dtype=np.int64)
    state = int(lattice[-1].argmax())
    log_prob = float(lattice[-1, state])
    item = psi.item
    for t in range(t_len - 1, 0, -1):
        states[t] = state
        state = item(t, state)
    states[0] = state
    return states, log_prob, -1


def _forward(
    log_at: NDArray[np.float64],
    emit: NDArray[np.float64],
    lattice: NDArray[np.float64],
    psi: NDArray[np.intp],
) -> None:
    """Fill ``lattice[1:]`` (best log scores) and ``psi[1:]`` (best predecessors) in place.

    ``log_at`` is the transposed log transition table (row j = log a_·j), ``emit[t]`` the
    log emissions of observation t, ``lattice[0]`` the start scores.
    """
    n = log_at.shape[0]
    rows = n if n * n <= _ONE_BLOCK_MAX else max(16, _BLOCK_ELEMENTS // n)
    buf = np.empty((rows, n))
    offsets = np.arange(0, rows * n, n, dtype=np.intp)  # flat index of each row's start
    flat_index = np.empty(rows, dtype=np.intp)
    add = np.add
    steps = zip(psi[1:], lattice[1:], emit[1:], strict=True)
    prev = lattice[0]
    if rows == n:
        take, argmax = buf.reshape(-1).take, buf.argmax
        for best, cur, e in steps:
            add(log_at, prev, buf)  # buf[j, i] = delta_i + log a_ij
            argmax(1, best)
            add(best, offsets, flat_index)
            take(flat_index, None, cur, "wrap")  # indices are in range: no checked copy
            add(cur, e, cur)
            prev = cur
        return
    blocks = []
    for start in range(0, n, rows):
        stop = min(start + rows, n)
        block = buf[: stop - start]
        blocks.append(
            (
                log_at[start:stop],
                block,
                block.reshape(-1).take,
                slice(start, stop),
                offsets[: stop - start],
                flat_index[: stop - start],
            )
        )
    for best, cur, e in steps:
        for at, block, take, rows_of, offs, index in blocks:
            block_best = best[rows_of]
            add(at, prev, block)
            block.argmax(1, block_best)
            add(block_best, offs, index)
            take(index, None, cur[rows_of], "wrap")
        add(cur, e, cur)
        prev = cur


def emission_decode(
    log_pi: NDArray[np.float64],
    log_B: NDArray[np.float64],
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
    scores = log_pi[None, :] + log_B[:, observations].T  # (T, N)
    best = scores.max(axis=1)
    bad = np.flatnonzero(~np.isfinite(best))
    states = scores.argmax(axis=1).astype(np.int64)
    return states, int(bad[0]) if bad.size else -1


def sequence_log_prob(
    log_pi: NDArray[np.float64],
    log_A: NDArray[np.float64],
    log_B: NDArray[np.float64],
    states: NDArray[np.int64],
    observations: NDArray[np.int64],
) -> float:
    """Joint ``log P(states, observations)`` of one given state sequence."""
    total = log_pi[states[0]] + log_A[states[:-1], states[1:]].sum()
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

    Parameters
    ----------
    next_node
        Successor of each node on its path to ``goal`` (from the goal tree).
    goal
        The goal observation category.
    log_pi, log_A, log_B
        Model tables in log space, as in :func:`viterbi_log`.
    """

    def __init__(
        self,
        next_node: list[int],
        goal: int,
        log_pi: NDArray[np.float64],
        log_A: NDArray[np.float64],
        log_B: NDArray[np.float64],
    ) -> None:
        self._next_node = next_node
        self._goal = goal
        self._log_pi = log_pi
        self._log_A = log_A
        self._log_B = log_B
        self._rows = np.arange(log_A.shape[0])
        self._value: dict[int, NDArray[np.float64]] = {}
        self._best_next: dict[int, list[int]] = {}

    def _message(self, node: int) -> NDArray[np.float64]:
        chain: list[int] = []
        u = node
        while u not in self._value:  # climb to the first node already computed
            chain.append(u)
            if u == self._goal:
                break
            u = self._next_node[u]
        for u in reversed(chain):
            if u == self._goal:
                self._value[u] = self._log_B[:, u].copy()
                continue
            scores = self._log_A + self._value[self._next_node[u]][None, :]
            best = scores.argmax(axis=1)
            self._value[u] = scores[self._rows, best] + self._log_B[:, u]
            self._best_next[u] = best.tolist()
        return self._value[node]

    def decode(self, path: list[int]) -> tuple[list[int], float]:
        """Most likely states along ``path`` (which must be a path of this tree).

        Returns ``([], -inf)`` when every state sequence is impossible.
        """
        start = self._log_pi + self._message(path[0])
        state = int(start.argmax())
        log_prob = float(start[state])
        if not np.isfinite(log_prob):
            return [], float("-inf")
        states = [state]
        for u in path[:-1]:
            state = self._best_next[u][state]
            states.append(state)
        return states, log_prob
