"""Viterbi decoding in log space (thesis §3.3.1), vectorized over states."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


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
    """
    n = log_pi.shape[0]
    t_len = observations.shape[0]
    log_bt = np.ascontiguousarray(log_B.T)  # row o = log b_j(o) for all j
    psi = np.zeros((t_len, n), dtype=np.int32)
    delta = log_pi + log_bt[observations[0]]
    if not np.isfinite(delta.max()):
        return np.zeros(t_len, dtype=np.int64), float("-inf"), 0
    cols = np.arange(n)
    for t in range(1, t_len):
        # scores[i, j] = delta_{t-1}(i) + log a_ij ; best predecessor of each j
        scores = delta[:, None] + log_A
        best = scores.argmax(axis=0)
        psi[t] = best
        delta = scores[best, cols] + log_bt[observations[t]]
        if not np.isfinite(delta.max()):
            return np.zeros(t_len, dtype=np.int64), float("-inf"), t
    states = np.empty(t_len, dtype=np.int64)
    states[-1] = int(delta.argmax())
    log_prob = float(delta[states[-1]])
    for t in range(t_len - 1, 0, -1):
        states[t - 1] = psi[t, states[t]]
    return states, log_prob, -1


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
