"""Sparse B and C (``_tables``) against the dense computations they replace.

The emission table B and the observation transition table C are counted, normalized and
used as sparse tables. Every test here computes the same thing from dense arrays with the
dense functions that remain (``normalize``, ``safe_log``, ``edge_costs``,
``reversed_graph``, ``viterbi_log``) and requires the sparse result to equal it: to the
bit where no smoothing is involved.
"""

from __future__ import annotations

import itertools
import tracemalloc
from typing import Any

import numpy as np
import pytest
from scipy.sparse import csr_array
from scipy.sparse.csgraph import dijkstra

from behavior_hmm.errors import UnreachableGoalError
from behavior_hmm.hmm import BehaviorHMM
from behavior_hmm.hmm._counting import count_transitions, normalize, safe_log
from behavior_hmm.hmm._paths import edge_costs, path_graph, reversed_graph
from behavior_hmm.hmm._tables import LogTable, canonical, check_counts, normalize_sparse
from behavior_hmm.hmm._viterbi import viterbi_log

SMOOTHINGS = [0.0, 1e-3, 0.5, 2.0]
SQUARE = [(1, 1), (2, 2), (6, 6), (40, 40)]
OBLONG = [(3, 17), (25, 4), (1, 9), (9, 1)]
#: (shape, zero_diagonal): a structural zero diagonal exists only in the square A and C
TABLES = [(shape, False) for shape in SQUARE + OBLONG] + [(shape, True) for shape in SQUARE]


# ------------------------------------------------------------------ helpers
def random_counts(
    rng: np.random.Generator, shape: tuple[int, int], *, zero_diagonal: bool = False
) -> np.ndarray:
    """Sparse int64 counts with rows and columns that hold no count at all.

    Without a diagonal where ``zero_diagonal`` (a model without self transitions
    never has one: counting does not make it and a model file may not hold it).
    """
    rows, cols = shape
    counts = rng.integers(1, 9, shape) * (rng.random(shape) < 0.3)
    counts[rng.random(rows) < 0.25] = 0  # rows without any count (unseen labels)
    counts[:, rng.random(cols) < 0.25] = 0  # columns no row enters
    counts[rows // 2, counts.any(axis=0)] = 7  # one row counted in every used column
    if zero_diagonal:
        np.fill_diagonal(counts, 0)
    return counts.astype(np.int64)


def log_table(counts: np.ndarray, smoothing: float, *, zero_diagonal: bool) -> LogTable:
    sparse = canonical(csr_array(counts))
    return LogTable(*normalize_sparse(sparse, smoothing, zero_diagonal=zero_diagonal))


def dense_log(counts: np.ndarray, smoothing: float, *, zero_diagonal: bool) -> np.ndarray:
    return safe_log(normalize(counts, smoothing, zero_diagonal=zero_diagonal))


def random_labels(rng: np.random.Generator, m: int, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """A random walk over ``m`` labels in a few episodes: runs of one label, local moves,
    label ``m - 2`` never seen, label ``m - 1`` seen once at the very end (so its row of
    C counts nothing but, under ``"changes"``, its one self transition)."""
    steps = rng.choice([-2, -1, 0, 0, 0, 1, 1, 3], samples)
    labels = np.cumsum(steps) % (m - 2)
    labels[-1] = m - 1
    cuts = np.sort(rng.choice(np.arange(1, samples), 3, replace=False))
    lengths = np.diff(np.concatenate([[0], cuts, [samples]]))
    return labels.astype(np.int64), lengths.astype(np.int64)


def assert_same_bits(got: np.ndarray, want: np.ndarray) -> None:
    assert got.shape == want.shape and got.dtype == want.dtype
    np.testing.assert_array_equal(got, want)
    assert got.tobytes() == want.tobytes()


def assert_close_log(got: np.ndarray, want: np.ndarray) -> None:
    """Equal up to rounding, with ``-inf`` (impossible) in exactly the same cells."""
    assert got.shape == want.shape
    np.testing.assert_array_equal(np.isneginf(got), np.isneginf(want))
    finite = np.isfinite(want)
    assert np.all(np.isfinite(got[finite]))
    np.testing.assert_allclose(got[finite], want[finite], rtol=1e-12, atol=0)


# ---------------------------------------------------- 1. normalize_sparse
@pytest.mark.parametrize("smoothing", SMOOTHINGS)
@pytest.mark.parametrize(("shape", "zero_diagonal"), TABLES)
def test_normalize_sparse_equals_the_dense_normalization(
    shape: tuple[int, int], zero_diagonal: bool, smoothing: float, rng: np.random.Generator
) -> None:
    for _ in range(5):
        counts = random_counts(rng, shape, zero_diagonal=zero_diagonal)
        got = log_table(counts, smoothing, zero_diagonal=zero_diagonal).toarray()
        want = dense_log(counts, smoothing, zero_diagonal=zero_diagonal)
        if smoothing == 0.0:  # integer row totals: the same divisions, to the bit
            assert_same_bits(got, want)
        else:  # the row total is sum + k · cells instead of a sum over the cells
            assert_close_log(got, want)


@pytest.mark.parametrize("smoothing", SMOOTHINGS)
@pytest.mark.parametrize("zero_diagonal", [False, True])
def test_normalize_sparse_of_a_table_without_any_count(
    smoothing: float, zero_diagonal: bool
) -> None:
    counts = np.zeros((5, 5), dtype=np.int64)
    table = log_table(counts, smoothing, zero_diagonal=zero_diagonal)
    want = dense_log(counts, smoothing, zero_diagonal=zero_diagonal)
    if smoothing == 0.0:
        assert table.nnz == 0 and not table.dense_fill
        assert np.all(np.isneginf(table.toarray()))
        assert_same_bits(table.toarray(), want)
    else:  # uniform rows, over the cells off the diagonal when it is a structural zero
        assert_close_log(table.toarray(), want)
        np.testing.assert_allclose(np.exp(table.toarray()).sum(axis=1), 1.0, rtol=1e-12)
        assert np.all(np.isneginf(table.diagonal())) == zero_diagonal


def test_normalize_sparse_keeps_the_counted_structure_and_fill() -> None:
    counts = np.array([[0, 3, 1], [0, 0, 0], [2, 0, 2]], dtype=np.int64)
    probs, fill = normalize_sparse(canonical(csr_array(counts)), 0.0, zero_diagonal=False)
    np.testing.assert_array_equal(probs.indptr, [0, 2, 2, 4])
    np.testing.assert_array_equal(probs.indices, [1, 2, 0, 2])
    np.testing.assert_array_equal(probs.data, [3 / 4, 1 / 4, 1 / 2, 1 / 2])
    np.testing.assert_array_equal(fill, [0.0, 0.0, 0.0])
    counts[2, 2] = 0  # no self transitions: nothing counted on the diagonal
    probs, fill = normalize_sparse(canonical(csr_array(counts)), 1.0, zero_diagonal=True)
    # smoothed: every cell off the diagonal gets 1, the diagonal is stored as an explicit 0
    np.testing.assert_array_equal(probs.indptr, [0, 3, 4, 6])
    np.testing.assert_array_equal(probs.indices, [0, 1, 2, 1, 0, 2])
    np.testing.assert_allclose(probs.data, [0, 4 / 6, 2 / 6, 0, 3 / 4, 0], rtol=1e-15)
    assert np.all(probs.diagonal() == 0.0)
    np.testing.assert_allclose(fill, [1 / 6, 1 / 2, 1 / 4], rtol=1e-15)


# ---------------------------------------------------------- 2. LogTable
@pytest.mark.parametrize("smoothing", [0.0, 0.5])
@pytest.mark.parametrize("shape", SQUARE + OBLONG + [(30, 200)])
def test_log_table_reads_what_its_dense_table_holds(
    shape: tuple[int, int], smoothing: float, rng: np.random.Generator
) -> None:
    rows, cols = shape
    zero_diagonal = rows == cols and bool(rng.integers(2))
    counts = random_counts(rng, shape, zero_diagonal=zero_diagonal)
    table = log_table(counts, smoothing, zero_diagonal=zero_diagonal)
    dense = table.toarray()
    assert dense.shape == table.shape == shape
    assert table.dense_fill == (smoothing > 0.0 and cols - zero_diagonal > 0)
    if smoothing == 0.0:
        assert table.nnz == np.count_nonzero(counts)
    for i in range(rows):
        assert_same_bits(table.row(i), dense[i])
    for j in range(cols):  # also the columns no row enters
        assert_same_bits(table.column(j), dense[:, j])
    assert_same_bits(table.diagonal(), np.diag(dense).copy())
    wanted = rng.integers(0, cols, 3 * cols)  # repeats, in any order
    for some in (wanted, np.flatnonzero(~counts.any(axis=0)), np.arange(cols)[::-1], wanted[:0]):
        got = table.columns(some)
        assert got.flags.c_contiguous
        assert_same_bits(got, np.ascontiguousarray(dense[:, some].T))
    some_rows, some_cols = rng.integers(0, rows, 200), rng.integers(0, cols, 200)
    assert_same_bits(table.values(some_rows, some_cols), dense[some_rows, some_cols])
    every = np.array(list(itertools.product(range(rows), range(cols)))).T
    assert_same_bits(table.values(every[0], every[1]), dense.ravel())


def test_log_table_of_a_probability_table_with_explicit_zeros() -> None:
    """An explicit 0 is stored (a structural zero under smoothing): log gives −inf there."""
    probs = csr_array(
        (np.array([0.5, 0.0, 0.25]), np.array([0, 1, 2]), np.array([0, 2, 2, 3])), shape=(3, 3)
    )
    table = LogTable(probs, np.array([0.25, 0.0, 0.375]))
    want = np.log([[0.5, 1.0, 0.25], [1.0, 1.0, 1.0], [0.375, 0.375, 0.25]])
    want[0, 1] = want[1] = -np.inf
    want[0, 2] = np.log(0.25)
    assert_same_bits(table.toarray(), want)
    assert_same_bits(table.column(1), want[:, 1].copy())
    assert_same_bits(table.diagonal(), np.diag(want).copy())
    assert table.nnz == 3 and table.dense_fill


# ------------------------------------------------------------ 3. path_graph
@pytest.mark.parametrize("rule", ["drop", "keep"])
@pytest.mark.parametrize("counting", ["changes", "steps"])
@pytest.mark.parametrize("self_transitions", [True, False])
@pytest.mark.parametrize("smoothing", [0.0, 0.5])
def test_path_graph_equals_the_dense_reversed_graph(
    rule: Any, counting: Any, self_transitions: bool, smoothing: float, rng: np.random.Generator
) -> None:
    m = 40
    for _ in range(4):
        labels, lengths = random_labels(rng, m, 600)
        counts = count_transitions(
            labels, m, lengths, counting=counting, self_transitions=self_transitions
        )
        dense_counts = counts.toarray()
        assert check_counts(counts.indptr, counts.indices, counts.data, m) is None
        table = LogTable(*normalize_sparse(counts, smoothing, zero_diagonal=not self_transitions))
        if smoothing == 0.0:  # independent of LogTable: normalized from the dense counts
            dense = dense_log(dense_counts, 0.0, zero_diagonal=not self_transitions)
        else:  # smoothed, the dense table is the model's (its totals differ in the last bit)
            dense = table.toarray()
        got = path_graph(table, rule)
        want = reversed_graph(edge_costs(dense, rule))
        assert got.shape == want.shape == (m, m)
        np.testing.assert_array_equal(got.indptr, want.indptr)
        np.testing.assert_array_equal(got.indices, want.indices)
        assert got.data.tobytes() == want.data.tobytes()
        if smoothing == 0.0:  # only counted transitions are edges, none on the diagonal
            edges = (dense_counts > 0) & ~np.eye(m, dtype=bool)
            if rule == "drop":  # ... and none out of a row that only stays put
                edges &= (dense_counts.sum(axis=1) > np.diag(dense_counts))[:, None]
            assert got.nnz == np.count_nonzero(edges)
        for goal in rng.choice(m, 5, replace=False):
            d_got, p_got = dijkstra(got, indices=goal, return_predecessors=True)
            d_want, p_want = dijkstra(want, indices=goal, return_predecessors=True)
            assert d_got.tobytes() == d_want.tobytes()
            np.testing.assert_array_equal(p_got, p_want)


# ------------------------------------------------------------- 4. plan()
def dense_reference(hmm: BehaviorHMM) -> dict[str, np.ndarray]:
    """log π, A, B, C as dense arrays, computed in the test from the model's counts."""
    k = float(hmm.smoothing)
    no_self = not hmm.self_transitions
    tables = {
        "pi": dense_log(hmm.pi_counts_, k, zero_diagonal=False),
        "A": dense_log(hmm.A_counts_, k, zero_diagonal=no_self),
        "B": dense_log(hmm.B_counts_.toarray(), k, zero_diagonal=False),
        "C": dense_log(hmm.C_counts_.toarray(), k, zero_diagonal=no_self),
    }
    if k == 0.0:  # the same to the bit; checked, so the reference ties break alike
        assert_same_bits(hmm.log_B_.toarray(), tables["B"])
        assert_same_bits(hmm.log_C_.toarray(), tables["C"])
    else:  # smoothed sums round differently: take the model's own dense tables
        assert_close_log(hmm.log_B_.toarray(), tables["B"])
        assert_close_log(hmm.log_C_.toarray(), tables["C"])
        tables["B"], tables["C"] = hmm.log_B_.toarray(), hmm.log_C_.toarray()
    return tables


@pytest.mark.parametrize(
    "params",
    [
        {},
        {"counting": "steps"},
        {"self_transitions": False, "path_self_loops": "keep"},
        {"counting": "steps", "path_self_loops": "keep"},
        {"smoothing": 0.5},
        {"smoothing": 0.5, "self_transitions": False, "counting": "steps"},
    ],
)
def test_plan_equals_dense_dijkstra_and_viterbi(
    params: dict[str, Any], rng: np.random.Generator
) -> None:
    n, m, samples = 4, 14, 400
    observations, lengths = random_labels(rng, m, samples)
    states = observations % n  # states that go with the observations, and some noise
    noisy = rng.random(samples) < 0.3
    states[noisy] = rng.integers(0, n, int(noisy.sum()))
    hmm = BehaviorHMM(n_states=n, **params).fit(states, observations, lengths)
    ref = dense_reference(hmm)
    graph = reversed_graph(edge_costs(ref["C"], hmm.path_self_loops))
    planned = 0
    for goal in range(m):
        dist, pred = dijkstra(graph, directed=True, indices=goal, return_predecessors=True)
        for current in range(m):
            if not np.isfinite(dist[current]):
                with pytest.raises(UnreachableGoalError, match="cannot be reached"):
                    hmm.plan(current, goal)
                continue
            path = [current]
            while path[-1] != goal:
                path.append(int(pred[path[-1]]))
            states_ref, log_prob, dead = viterbi_log(
                ref["pi"], ref["A"], ref["B"], np.array(path), compiled=False
            )
            if dead >= 0:
                with pytest.raises(UnreachableGoalError, match="no state sequence"):
                    hmm.plan(current, goal)
                continue
            plan = hmm.plan(current, goal)
            assert plan.observations == tuple(path), (current, goal)
            assert plan.path_log_prob == 0.0 - dist[current]
            # forward (viterbi_log) and backward (the plan's messages) sums: same optimum
            assert plan.log_prob == pytest.approx(log_prob, rel=1e-12, abs=1e-12)
            s = np.array(plan.states)  # may differ from states_ref only among ties
            achieved = ref["pi"][s[0]] + ref["A"][s[:-1], s[1:]].sum() + ref["B"][s, path].sum()
            assert achieved == pytest.approx(log_prob, rel=1e-12, abs=1e-12)
            assert len(states_ref) == len(s)
            planned += 1
    assert planned >= m  # the comparison is not vacuous


# ---------------------------------------------------------- 5. check_counts
def test_check_counts_accepts_canonical_rows() -> None:
    ok = np.array
    # an empty row, a row that restarts below the previous row's last index, equal
    # indices across a row boundary, and the last column used
    assert check_counts(ok([0, 2, 2, 4, 5]), ok([1, 5, 0, 5, 5]), ok([1, 2, 3, 1, 9]), 6) is None
    assert check_counts(ok([0, 0, 0]), ok([], dtype=np.int64), ok([], dtype=np.int64), 4) is None
    assert check_counts(ok([0, 1]), ok([0]), ok([2**62]), 2**62) is None  # sizes as given


@pytest.mark.parametrize(
    ("indptr", "indices", "counts", "match"),
    [
        ([[0, 1]], [0], [1], "must be 1-D"),
        ([0, 1], [[0]], [1], "must be 1-D"),
        ([0, 1], [0], [[1]], "must be 1-D"),
        ([0, 2], [0, 1], [1], "has 2 column indices but 1 counts"),
        ([0], [], [], "must run from 0 to the number of stored counts"),
        ([1, 2], [0, 1], [1, 1], "must run from 0 to the number of stored counts"),
        ([0, 1], [0, 1], [1, 1], "must run from 0 to the number of stored counts"),
        ([0, 3], [0, 1], [1, 1], "must run from 0 to the number of stored counts"),
        ([0, 2, 1, 2], [0, 1], [1, 1], "row pointers decrease"),
        ([0, 2**62, 2], [0, 1], [1, 1], "row pointers decrease"),
        ([0, -1, 2], [0, 1], [1, 1], "row pointers decrease"),
        ([0, 2], [0, 4], [1, 1], "column indices outside 0 to 3"),
        ([0, 2], [-1, 2], [1, 1], "column indices outside 0 to 3"),
        ([0, 1], [2**62], [1], "column indices outside 0 to 3"),
        ([0, 2], [0, 1], [1, 0], "stores counts below 1"),
        ([0, 2], [0, 1], [-3, 1], "stores counts below 1"),
        ([0, 2], [1, 0], [1, 1], "do not increase within a row"),
        ([0, 1, 3], [3, 2, 2], [1, 1, 1], "do not increase within a row"),
        ([0, 0, 3], [0, 3, 1], [1, 1, 1], "do not increase within a row"),
    ],
)
def test_check_counts_names_what_is_wrong(
    indptr: list[Any], indices: list[Any], counts: list[Any], match: str
) -> None:
    arrays = [np.array(a, dtype=np.int64) for a in (indptr, indices, counts)]
    tracemalloc.start()
    try:
        problem = check_counts(arrays[0], arrays[1], arrays[2], 4)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert problem is not None and match in problem
    assert peak < 1 << 16  # one pass over the arrays: nothing from a claimed size


# ---------------------------------------------------------------- 6. memory
def test_two_hundred_thousand_categories_fit_and_plan_sparsely() -> None:
    """A dense C would be 200,000² float64 = 320 GB; the counted entries are ~2 per cell."""
    rng = np.random.default_rng(2024)
    n, m, samples = 50, 200_000, 400_000
    steps = rng.integers(-1, 4, samples)  # mostly forward: the walk goes round twice
    observations = np.cumsum(steps) % m
    states = rng.integers(0, n, samples)
    tracemalloc.start()
    try:
        hmm = BehaviorHMM(n_states=n, n_observations=m).fit(
            states, observations, [samples // 2, samples - samples // 2]
        )
        current = int(observations[1000])
        goal = (current + 25) % m
        plan = hmm.plan(current, goal)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1 << 30  # measured ~60 MB
    assert hmm.C_counts_.shape == (m, m) and hmm.log_C_.shape == (m, m)
    assert hmm.C_counts_.nnz < 6 * m  # at most 5 moves and a self transition per category
    assert hmm.C_counts_.nnz * 10_000 < m * m
    assert hmm.B_counts_.nnz <= samples and hmm.log_B_.nnz == hmm.B_counts_.nnz
    assert not hmm.log_C_.dense_fill
    assert plan.observations[0] == current and plan.observations[-1] == goal
    assert plan.decoding == "viterbi" and np.isfinite(plan.log_prob)
    # the path follows counted transitions, with probabilities from the counts (drop rule)
    log_prob = 0.0
    for a, b in itertools.pairwise(plan.observations):
        row = hmm.C_counts_[[a]].toarray()[0]  # one row: dense only over its M entries
        assert row[b] > 0
        log_prob += np.log(row[b] / (row.sum() - row[a]))
    assert plan.path_log_prob == pytest.approx(log_prob, rel=1e-12)
