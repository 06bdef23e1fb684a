"""to_arrays / from_arrays: round trip and refusal of malformed count tables.

A model file holds only int64 counts: A, B and C as compressed sparse rows
(``{X}_indptr``, ``{X}_indices``, ``{X}_counts``), π and the episode starts as vectors.
Every array is checked as if it came from a stranger, and nothing may be allocated from
a size the file merely claims (a refusal must stay small, traced by ``tracemalloc``).
"""

from __future__ import annotations

import json
import tracemalloc
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hmm_testing import sparse_arrays
from scipy.sparse import csr_array

from behavior_hmm.errors import ModelFileError
from behavior_hmm.hmm import BehaviorHMM
from behavior_hmm.hmm._behavior_hmm import MAX_DENSE_STATES
from behavior_hmm.hmm._tables import LogTable, check_counts

KEYS = {f"{name}_{part}" for name in "ABC" for part in ("indptr", "indices", "counts")} | {
    "pi_counts",
    "start_counts",
}


def fitted(**params: Any) -> BehaviorHMM:
    """N = 3 states, M = 4 categories; rows 0 to 2 of B and C store two counts each.

    C_indptr [0, 2, 4, 6, 7], C_indices [0, 1, 1, 2, 2, 3, 3], C_counts [1, 2, 1, 2, 1, 2, 1];
    pi_counts [3, 4, 3] (the row sums of B).
    """
    states = [0, 0, 1, 1, 2, 0, 1, 1, 2, 2]
    obs = [0, 1, 1, 2, 3, 0, 1, 2, 2, 3]
    return BehaviorHMM(**{"smoothing": 0.0, **params}).fit(states, obs, lengths=[5, 5])


def assert_same_log_table(got: LogTable, want: LogTable) -> None:
    assert got.shape == want.shape
    for part in ("indptr", "indices", "data", "fill"):
        assert getattr(got, part).tobytes() == getattr(want, part).tobytes(), part
    np.testing.assert_array_equal(got.toarray(), want.toarray())


def test_round_trip_reproduces_the_model() -> None:
    hmm = fitted()
    arrays = hmm.to_arrays()
    assert set(arrays) == KEYS
    assert all(a.dtype == np.int64 and a.ndim == 1 for a in arrays.values())
    params = json.loads(json.dumps(hmm.params))  # the params must survive JSON
    back = BehaviorHMM.from_arrays(arrays, params)
    for name in ("log_A_", "log_pi_", "start_prob_first_", "A_counts_"):
        np.testing.assert_array_equal(getattr(back, name), getattr(hmm, name))
    for name in ("B_counts_", "C_counts_"):
        np.testing.assert_array_equal(getattr(back, name).toarray(), getattr(hmm, name).toarray())
    assert_same_log_table(back.log_B_, hmm.log_B_)
    assert_same_log_table(back.log_C_, hmm.log_C_)
    np.testing.assert_array_equal(
        back.C_counts_.toarray(), [[1, 2, 0, 0], [0, 1, 2, 0], [0, 0, 1, 2], [0, 0, 0, 1]]
    )
    assert back.plan(0, 3) == hmm.plan(0, 3)
    assert back.get_params() == hmm.get_params()


def test_round_trip_with_smoothing_and_no_self_transitions() -> None:
    hmm = BehaviorHMM(smoothing=0.3, self_transitions=False, counting="steps")
    hmm.fit([0, 0, 1, 1, 0], [0, 1, 1, 2, 2])
    back = BehaviorHMM.from_arrays(hmm.to_arrays(), hmm.params)
    assert_same_log_table(back.log_B_, hmm.log_B_)
    assert_same_log_table(back.log_C_, hmm.log_C_)
    np.testing.assert_array_equal(back.log_A_, hmm.log_A_)
    assert np.all(np.isneginf(np.diag(back.log_C_.toarray())))


def tamper(key: str, change: Callable[[np.ndarray], Any]) -> dict[str, Any]:
    arrays: dict[str, Any] = fitted().to_arrays()
    arrays[key] = change(arrays[key].copy())
    return arrays


def put(a: np.ndarray, at: int, value: int) -> np.ndarray:
    a[at] = value
    return a


def assert_refused_small(arrays: dict[str, Any], params: dict[str, Any], match: str) -> None:
    """``from_arrays`` raises ModelFileError matching ``match``, allocating under 1 MiB."""
    tracemalloc.start()
    try:
        with pytest.raises(ModelFileError, match=match):
            BehaviorHMM.from_arrays(arrays, params)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20, f"refusing took {peak} bytes"


@pytest.mark.parametrize(
    ("key", "change", "match"),
    [
        # row pointers
        ("A_indptr", lambda a: a[:-1], "array 'A_indptr' must have 4 entries"),
        ("B_indptr", lambda a: np.append(a, a[-1]), "array 'B_indptr' must have 4 entries"),
        ("C_indptr", lambda a: a[[0, 2, 1, 3, 4]], "sparse table 'C' row pointers decrease"),
        ("C_indptr", lambda a: put(a, 1, 2**62), "sparse table 'C' row pointers decrease"),
        ("C_indptr", lambda a: put(a, -1, 6), "sparse table 'C' row pointers must run from 0"),
        ("B_indptr", lambda a: put(a, 0, 1), "sparse table 'B' row pointers must run from 0"),
        ("A_indptr", lambda a: a * 2**40, "sparse table 'A' row pointers must run from 0"),
        # column indices
        (
            "C_indices",
            lambda a: put(a, -1, 4),
            r"sparse table 'C' has column indices outside 0 to 3",
        ),
        ("B_indices", lambda a: put(a, 0, 2**62), r"sparse table 'B' has column indices outside"),
        (
            "A_indices",
            lambda a: put(a, -1, 3),
            r"sparse table 'A' has column indices outside 0 to 2",
        ),
        ("C_indices", lambda a: a[[1, 0, 2, 3, 4, 5, 6]], "'C' has column indices that do not"),
        ("C_indices", lambda a: put(a, 1, 0), "'C' has column indices that do not increase"),
        ("B_indices", lambda a: put(a, 3, 1), "'B' has column indices that do not increase"),
        ("C_indices", lambda a: -a, "array 'C_indices' has negative values"),
        ("C_indices", lambda a: a[:-1], "'C' has 6 column indices but 7 counts"),
        # counts
        ("C_counts", lambda a: put(a, 2, 0), "sparse table 'C' stores counts below 1"),
        ("A_counts", lambda a: put(a, 0, -1), "array 'A_counts' has negative values"),
        ("pi_counts", lambda a: -a, "array 'pi_counts' has negative values"),
        ("C_counts", lambda a: a.astype(np.uint64) + np.uint64(2**63), "does not fit int64"),
        (
            "start_counts",
            lambda a: a.astype(np.uint64) - np.uint64(1),  # [1, 2**64 - 1, 2**64 - 1]
            "array 'start_counts' has negative values or does not fit int64",
        ),
        # dtypes and shapes
        ("B_counts", lambda a: a.astype(np.float64), "'B_counts' must be 1-D integers"),
        ("C_indices", lambda a: a.astype(np.float32), "'C_indices' must be 1-D integers"),
        ("A_indptr", lambda a: a.astype(bool), "'A_indptr' must be 1-D integers"),
        ("pi_counts", lambda a: a[None, :], "'pi_counts' must be 1-D integers"),
        ("C_indptr", lambda a: np.stack([a, a]), "'C_indptr' must be 1-D integers"),
        ("A_counts", lambda a: a.tolist(), "'A_counts' is not an array"),
        # sizes and consistency
        ("start_counts", lambda a: a[:-1], "'pi_counts' and 'start_counts' differ in length"),
        ("pi_counts", lambda a: put(a, 0, a[0] + 1), "'B' do not add up to 'pi_counts'"),
        ("B_counts", lambda a: put(a, 0, a[0] + 1), "'B' do not add up to 'pi_counts'"),
        ("pi_counts", lambda a: a[:0], "no states or no observation categories"),
        ("C_indptr", lambda a: a[:1], "no states or no observation categories"),
    ],
)
def test_from_arrays_refuses_bad_tables(key: str, change: Callable[..., Any], match: str) -> None:
    assert_refused_small(tamper(key, change), fitted().params, match)


@pytest.mark.parametrize("table", ["A", "C"])
def test_self_transitions_are_refused_where_the_parameters_exclude_them(table: str) -> None:
    hmm = fitted(self_transitions=False, counting="steps")
    arrays = hmm.to_arrays()
    BehaviorHMM.from_arrays(arrays, hmm.params)  # the file as saved loads
    counts = hmm.A_counts_.copy() if table == "A" else hmm.C_counts_.toarray()
    assert not np.any(np.diag(counts))
    counts[1, 1] = 3
    arrays.update(sparse_arrays(table, counts))
    assert_refused_small(arrays, hmm.params, f"table '{table}' counts self transitions")
    # the same counts are a valid file of a model that has self transitions
    BehaviorHMM.from_arrays(arrays, {**hmm.params, "self_transitions": True})


def test_a_file_with_self_transitions_is_refused_by_a_model_without() -> None:
    assert_refused_small(
        fitted().to_arrays(), {"self_transitions": False}, "table 'A' counts self transitions"
    )


def test_too_many_states_are_refused_before_anything_is_allocated() -> None:
    """A is held dense: N = MAX_DENSE_STATES + 1 would take 64 MiB; the refusal does not."""
    n = MAX_DENSE_STATES + 1
    empty = np.zeros(0, dtype=np.int64)
    arrays = {
        "A_indptr": np.zeros(n + 1, dtype=np.int64),
        "A_indices": empty,
        "A_counts": empty,
        "B_indptr": np.zeros(n + 1, dtype=np.int64),
        "B_indices": empty,
        "B_counts": empty,
        "C_indptr": np.zeros(2, dtype=np.int64),
        "C_indices": empty,
        "C_counts": empty,
        "pi_counts": np.zeros(n, dtype=np.int64),
        "start_counts": np.zeros(n, dtype=np.int64),
    }
    assert_refused_small(arrays, {}, f"{n} states is more than a Behavior-HMM holds")
    for key in ("A_indptr", "B_indptr", "pi_counts", "start_counts"):
        arrays[key] = arrays[key][1:]
    model = BehaviorHMM.from_arrays(arrays, {})  # one state fewer: the largest model
    assert model.n_states_ == MAX_DENSE_STATES


def test_many_observation_categories_load_without_a_dense_table() -> None:
    """M has no bound: B and C are sparse, so loading takes memory of order M, not M²."""
    m = 1_000_000  # dense C: 8 TB
    arrays = fitted().to_arrays()
    arrays["C_indptr"] = np.concatenate([arrays["C_indptr"], np.full(m - 4, 7, dtype=np.int64)])
    tracemalloc.start()
    try:
        model = BehaviorHMM.from_arrays(arrays, {})
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert model.n_observations_ == m and model.log_C_.shape == (m, m)
    assert peak < 64 * m  # a few vectors of length M (24 bytes per category today)
    assert model.plan(0, 3).observations == fitted().plan(0, 3).observations


def test_from_arrays_refuses_missing_and_unexpected_arrays() -> None:
    arrays: dict[str, Any] = fitted().to_arrays()
    del arrays["C_counts"]
    with pytest.raises(ModelFileError, match=r"missing from model file: \['C_counts'\]"):
        BehaviorHMM.from_arrays(arrays, {})
    arrays = {**fitted().to_arrays(), "payload": np.zeros(1)}
    with pytest.raises(ModelFileError, match="unexpected"):
        BehaviorHMM.from_arrays(arrays, {})
    arrays = {**fitted().to_arrays(), "A": np.eye(3)}  # the old dense probabilities
    with pytest.raises(ModelFileError, match=r"unexpected Behavior-HMM arrays .*\['A'\]"):
        BehaviorHMM.from_arrays(arrays, {})


@pytest.mark.parametrize(
    ("params", "match"),
    [
        ({"alpha": 1}, "unknown"),
        ({"counting": "pairs"}, "invalid"),
        ({"smoothing": -1}, "invalid"),
        ({"n_states": 7}, "n_states=7"),
        ({"n_observations": 3}, "n_observations=3"),
    ],
)
def test_from_arrays_refuses_bad_params(params: dict[str, Any], match: str) -> None:
    with pytest.raises(ModelFileError, match=match):
        BehaviorHMM.from_arrays(fitted().to_arrays(), params)


def test_probabilities_are_normalized_under_the_loading_parameters() -> None:
    """Only counts are saved: the same file loads as a model of whatever smoothing."""
    states, obs = [0, 0, 1], [0, 1, 1]
    arrays = BehaviorHMM(smoothing=1.0).fit(states, obs).to_arrays()
    plain = BehaviorHMM(smoothing=0.0).fit(states, obs)
    loaded = BehaviorHMM.from_arrays(arrays, {"smoothing": 0.0})
    np.testing.assert_array_equal(loaded.log_A_, plain.log_A_)
    assert_same_log_table(loaded.log_B_, plain.log_B_)
    assert_same_log_table(loaded.log_C_, plain.log_C_)
    assert np.isneginf(loaded.log_C_.toarray()[1, 0])  # never counted, not smoothed
    smoothed = BehaviorHMM.from_arrays(arrays, {"smoothing": 1.0})
    assert np.isfinite(smoothed.log_C_.toarray()[1, 0])


def test_to_arrays_round_trips_bit_for_bit() -> None:
    rng = np.random.default_rng(7)
    states = rng.integers(0, 5, 400)
    observations = rng.integers(0, 17, 400)
    model = BehaviorHMM(smoothing=0.3).fit(states, observations, [150, 250])
    arrays = model.to_arrays()
    again = BehaviorHMM.from_arrays(arrays, model.params).to_arrays()
    for key, value in arrays.items():
        assert value.dtype == again[key].dtype == np.int64, key
        assert value.tobytes() == again[key].tobytes(), key


def test_to_arrays_holds_the_counts_as_canonical_compressed_rows() -> None:
    rng = np.random.default_rng(11)
    model = BehaviorHMM(n_observations=40).fit(rng.integers(0, 6, 300), rng.integers(0, 30, 300))
    arrays = model.to_arrays()
    n, m = model.n_states_, model.n_observations_
    tables = {"A": model.A_counts_, "B": model.B_counts_.toarray(), "C": model.C_counts_.toarray()}
    for name, dense in tables.items():
        indptr, indices, counts = (arrays[f"{name}_{p}"] for p in ("indptr", "indices", "counts"))
        assert check_counts(indptr, indices, counts, dense.shape[1]) is None, name
        np.testing.assert_array_equal(
            indptr, np.concatenate([[0], np.cumsum((dense > 0).sum(axis=1))])
        )
        table = csr_array((counts, indices, indptr), shape=dense.shape)
        np.testing.assert_array_equal(table.toarray(), dense)
    assert tables["A"].shape == (n, n) and tables["C"].shape == (m, m)
    np.testing.assert_array_equal(arrays["pi_counts"], model.pi_counts_)
    np.testing.assert_array_equal(arrays["start_counts"], model.start_counts_)
