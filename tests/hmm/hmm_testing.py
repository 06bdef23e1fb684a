"""Helpers shared by the Behavior-HMM tests: build models straight from count tables."""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.sparse import csr_array

from behavior_hmm.hmm import BehaviorHMM


def sparse_arrays(name: str, counts: Any) -> dict[str, np.ndarray]:
    """The model-file arrays ``{name}_indptr``, ``_indices``, ``_counts`` of dense counts."""
    table = csr_array(np.asarray(counts, dtype=np.int64))  # sorted, zeros not stored
    return {
        f"{name}_indptr": np.asarray(table.indptr, dtype=np.int64),
        f"{name}_indices": np.asarray(table.indices, dtype=np.int64),
        f"{name}_counts": np.asarray(table.data, dtype=np.int64),
    }


def model_from_counts(
    A: Any,
    B: Any,
    C: Any,
    pi: Any | None = None,
    start: Any | None = None,
    **params: Any,
) -> BehaviorHMM:
    """A fitted model whose tables are the given counts, normalized by the model.

    Built through ``from_arrays`` when π is the row sums of B (as counting makes it,
    and as a model file must have it). A π of its own (to test Viterbi on any tables)
    is not a valid model file, so that model is given its counts directly.
    """
    A = np.asarray(A, dtype=np.int64)
    B = np.asarray(B, dtype=np.int64)
    C = np.asarray(C, dtype=np.int64)
    pi = B.sum(axis=1) if pi is None else np.asarray(pi, dtype=np.int64)
    start = pi if start is None else np.asarray(start, dtype=np.int64)
    if np.array_equal(pi, B.sum(axis=1)):
        arrays = {
            **sparse_arrays("A", A),
            **sparse_arrays("B", B),
            **sparse_arrays("C", C),
            "pi_counts": pi,
            "start_counts": start,
        }
        return BehaviorHMM.from_arrays(arrays, params)
    hmm = BehaviorHMM(**params)
    hmm._validate_params()
    tables = {"A": A, "B": csr_array(B), "C": csr_array(C), "pi": pi, "start_prob_first": start}
    hmm._set_tables(tables)
    return hmm


def probs(counts: Any) -> np.ndarray:
    """Row-normalize counts in plain float arithmetic (independent of the package)."""
    c = np.asarray(counts, dtype=float)
    tot = c.sum(axis=-1, keepdims=True)
    return np.where(tot > 0, c / np.where(tot > 0, tot, 1.0), 0.0)


def random_rows(rng: np.random.Generator, shape: tuple[int, int], kind: str) -> np.ndarray:
    """Row-stochastic probabilities: ``dense`` (all > 0), ``sparse`` (mostly 0: at most
    3 entries per row) or ``tied`` (small integer counts, so many entries are equal)."""
    rows, cols = shape
    if kind == "dense":
        p = rng.dirichlet(np.ones(cols), rows)
    elif kind == "sparse":
        p = np.zeros(shape)
        for r in range(rows):
            support = rng.choice(cols, size=min(cols, int(rng.integers(1, 4))), replace=False)
            p[r, support] = rng.dirichlet(np.ones(support.size))
    else:
        p = rng.integers(0, 3, shape).astype(float)
        p[p.sum(axis=1) == 0, 0] = 1.0
    return p / p.sum(axis=1, keepdims=True)


def random_model(
    rng: np.random.Generator, n: int, m: int, kind: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """π, A, B of a random model of ``n`` states and ``m`` categories (kinds as in
    :func:`random_rows`); a sparse one has a state no state enters (only a start state)."""
    a = random_rows(rng, (n, n), kind)
    b = random_rows(rng, (n, m), "dense" if kind == "sparse" else kind)
    if kind == "tied":
        b[1::2] = b[::2][: n // 2]  # pairs of states that emit alike: more exact ties
        pi = np.full(n, 1.0 / n)
    else:
        pi = rng.dirichlet(np.ones(n))
    if kind == "sparse" and n > 2:
        a[:, n - 1] = 0.0  # a state no state enters (only a start state)
        a[a.sum(axis=1) == 0, 0] = 1.0  # every state keeps a successor
        a /= a.sum(axis=1, keepdims=True)
    return pi, a, b


def log_tables(
    pi: np.ndarray, a: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tables in log space (``-inf`` for the zeros)."""
    with np.errstate(divide="ignore"):
        return np.log(pi), np.log(a), np.log(b)


def random_observations(
    rng: np.random.Generator, pi: np.ndarray, a: np.ndarray, b: np.ndarray, t_len: int
) -> np.ndarray:
    """Observations sampled from the model (so that most are possible), a few at random."""
    n, m = b.shape
    obs = np.empty(t_len, dtype=np.int64)
    state = rng.choice(n, p=pi)
    for t in range(t_len):
        obs[t] = rng.choice(m, p=b[state])
        state = rng.choice(n, p=a[state])
    noisy = rng.random(t_len) < 0.05
    obs[noisy] = rng.integers(0, m, int(noisy.sum()))
    return obs
