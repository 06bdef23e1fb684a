"""Most likely observation path: Dijkstra on −log transition probabilities.

The thesis (§4.3) runs a "most likely path" variant of Dijkstra from the current
observation category. Because closed-loop generation re-plans every control cycle
towards the *same* goal, we run Dijkstra once per goal on the reversed graph (every
node → goal) and keep the shortest-path tree; a re-plan is then a walk up that tree.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_array
from scipy.sparse.csgraph import dijkstra

from behavior_hmm.hmm._tables import LogTable

PathSelfLoops = Literal["drop", "keep"]


def edge_costs(log_C: NDArray[np.float64], path_self_loops: PathSelfLoops) -> NDArray[np.float64]:
    """Edge cost matrix ``w_ij = −log c_ij`` (``inf`` = no edge, diagonal never an edge).

    With ``"drop"`` the self transition is taken out first and each row renormalized,
    ``c_ij / (1 − c_ii)``: the probability that the *next different* category is j.
    """
    m = log_C.shape[0]
    w = -log_C.copy()
    if path_self_loops == "drop":
        c_ii = np.exp(np.diag(log_C))
        with np.errstate(divide="ignore"):
            log_rest = np.log1p(-np.minimum(c_ii, 1.0))  # log(1 − c_ii); −inf when c_ii = 1
        # rows with c_ii = 1 have no off-diagonal mass: w stays +inf there
        finite_rest = np.isfinite(log_rest)
        w[finite_rest] += log_rest[finite_rest, None]
    w[np.arange(m), np.arange(m)] = np.inf
    # rounding may leave −1e-16 on a deterministic edge; Dijkstra refuses negatives
    np.maximum(w, 0.0, out=w)
    return w


def reversed_graph(w: NDArray[np.float64]) -> csr_array:
    """Sparse graph with edge j → i of cost ``w_ij`` (explicit zeros are edges)."""
    src, dst = np.nonzero(np.isfinite(w))
    return csr_array((w[src, dst], (dst, src)), shape=w.shape)


def path_graph(log_C: LogTable, path_self_loops: PathSelfLoops) -> csr_array:
    """The reversed graph of :func:`reversed_graph` built from the stored entries of C.

    Without smoothing only counted transitions are edges, so the graph is built from the
    stored entries alone; every cost is the one :func:`edge_costs` computes on the dense
    table, to the bit, and the edges come in the same order (so Dijkstra gives the same
    tree). A smoothed C makes every pair of categories an edge: that graph is built from
    the dense table (memory M², as smoothing implies).
    """
    if log_C.dense_fill:
        return reversed_graph(edge_costs(log_C.toarray(), path_self_loops))
    src = log_C.rows()
    dst = log_C.indices
    w = -log_C.data
    if path_self_loops == "drop":
        c_ii = np.exp(log_C.diagonal())
        with np.errstate(divide="ignore"):
            log_rest = np.log1p(-np.minimum(c_ii, 1.0))
        finite_rest = np.isfinite(log_rest)[src]
        w[finite_rest] += log_rest[src[finite_rest]]
    edge = (src != dst) & np.isfinite(w)
    w = np.maximum(w[edge], 0.0)
    return csr_array((w, (dst[edge], src[edge])), shape=log_C.shape)


@dataclass(frozen=True)
class GoalTree:
    """Shortest-path tree towards one goal: ``next_node[i]`` is i's successor on its path."""

    goal: int
    cost: NDArray[np.float64]  # −log probability of the best path i → goal; inf if none
    next_node: list[int]


def goal_tree(graph_rev: csr_array, goal: int) -> GoalTree:
    """Run Dijkstra once from ``goal`` on the reversed graph."""
    dist, pred = dijkstra(graph_rev, directed=True, indices=goal, return_predecessors=True)
    return GoalTree(goal=goal, cost=np.asarray(dist, dtype=np.float64), next_node=pred.tolist())


def walk(tree: GoalTree, current: int) -> list[int]:
    """Observation path from ``current`` to the tree's goal (caller checks reachability)."""
    path = [current]
    node = current
    nxt = tree.next_node
    while node != tree.goal:
        node = nxt[node]
        path.append(node)
    return path
