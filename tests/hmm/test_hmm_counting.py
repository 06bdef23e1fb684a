"""Counting estimation of A, B, C, π (thesis §4.2, table 4.3) and the estimator contract."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from behavior_hmm.errors import ConfigError, DatasetError, NotFittedError
from behavior_hmm.hmm import BehaviorHMM

S1, S2, S3 = 0, 1, 2
O1, O2, O_OTHER = 0, 1, 2


def table_4_3_sequences() -> tuple[list[int], list[int]]:
    """S1 visited 7 times, then S2 four times and S3 three times; S1 sees o1 twice, o2 5 times."""
    followers = [S2, S2, S2, S2, S3, S3, S3]
    seen_in_s1 = [O1, O2, O2, O1, O2, O2, O2]
    states: list[int] = []
    observations: list[int] = []
    for nxt, obs in zip(followers, seen_in_s1, strict=True):
        states += [S1, nxt]
        observations += [obs, O_OTHER]
    return states, observations


def test_table_4_3_exactly() -> None:
    states, observations = table_4_3_sequences()
    hmm = BehaviorHMM().fit(states, observations)
    np.testing.assert_array_equal(hmm.A_counts_[S1], [1, 4, 3])
    np.testing.assert_array_equal(hmm.B_counts_.toarray()[S1], [2, 5, 0])
    np.testing.assert_allclose(np.exp(hmm.log_A_[S1]), [1 / 8, 4 / 8, 3 / 8], rtol=0, atol=1e-15)
    np.testing.assert_allclose(
        np.exp(hmm.log_B_.toarray()[S1]), [2 / 7, 5 / 7, 0.0], rtol=0, atol=1e-15
    )


def test_table_4_3_split_over_episodes_gives_the_same_row() -> None:
    states, observations = table_4_3_sequences()
    hmm = BehaviorHMM().fit(states, observations, lengths=[2] * 7)
    # every S1 -> next pair lies inside one episode, nothing crosses a boundary
    np.testing.assert_array_equal(hmm.A_counts_[S1], [1, 4, 3])
    np.testing.assert_array_equal(hmm.B_counts_.toarray()[S1], [2, 5, 0])


def test_changes_counting_adds_one_self_transition_per_seen_state() -> None:
    hmm = BehaviorHMM(n_states=3).fit([0, 0, 0, 1, 1, 0], [0, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(hmm.A_counts_, [[1, 1, 0], [1, 1, 0], [0, 0, 0]])
    assert np.all(np.isneginf(hmm.log_A_[2]))  # unseen state: no counts, no NaN


def test_steps_counting_counts_every_consecutive_pair() -> None:
    hmm = BehaviorHMM(counting="steps").fit([0, 0, 0, 1, 1], [0, 0, 1, 1, 1])
    np.testing.assert_array_equal(hmm.A_counts_, [[2, 1], [0, 1]])
    np.testing.assert_array_equal(hmm.C_counts_.toarray(), [[1, 1], [0, 2]])


@pytest.mark.parametrize("counting", ["changes", "steps"])
def test_without_self_transitions_the_diagonal_is_zero_even_when_smoothed(counting: str) -> None:
    hmm = BehaviorHMM(counting=counting, self_transitions=False, smoothing=0.5)  # type: ignore[arg-type]
    hmm.fit([0, 0, 1, 1, 2], [0, 1, 1, 2, 2])
    assert np.all(np.isneginf(np.diag(hmm.log_A_)))
    assert np.all(np.isneginf(np.diag(hmm.log_C_.toarray())))
    np.testing.assert_allclose(np.exp(hmm.log_A_).sum(axis=1), 1.0)
    np.testing.assert_allclose(np.exp(hmm.log_C_.toarray()).sum(axis=1), 1.0)


def test_transitions_are_not_counted_across_episodes() -> None:
    hmm = BehaviorHMM().fit([0, 1, 2, 0], [0, 1, 2, 0], lengths=[2, 2])
    assert hmm.A_counts_[1, 2] == 0
    assert hmm.C_counts_[1, 2] == 0
    assert hmm.A_counts_[0, 1] == 1 and hmm.A_counts_[2, 0] == 1


def test_pi_is_the_density_and_start_distribution_is_kept() -> None:
    hmm = BehaviorHMM().fit([0, 0, 0, 1, 1, 0, 0, 0], [0] * 8, lengths=[5, 3])
    np.testing.assert_allclose(np.exp(hmm.log_pi_), [6 / 8, 2 / 8])
    np.testing.assert_allclose(hmm.start_prob_first_, [1.0, 0.0])
    np.testing.assert_array_equal(hmm.pi_counts_, [6, 2])
    np.testing.assert_array_equal(hmm.start_counts_, [2, 0])


def test_smoothing_adds_pseudo_counts_and_fills_unseen_rows_uniformly() -> None:
    k = 0.5
    hmm = BehaviorHMM(n_states=3, n_observations=2, smoothing=k).fit([0, 0, 1], [0, 1, 1])
    # raw counts are unchanged by smoothing
    np.testing.assert_array_equal(hmm.A_counts_, [[1, 1, 0], [0, 1, 0], [0, 0, 0]])
    np.testing.assert_allclose(np.exp(hmm.log_A_[0]), [1.5 / 3.5, 1.5 / 3.5, 0.5 / 3.5])
    np.testing.assert_allclose(np.exp(hmm.log_A_[2]), [1 / 3] * 3)  # unseen state
    np.testing.assert_allclose(np.exp(hmm.log_B_.toarray()[2]), [0.5, 0.5])
    np.testing.assert_allclose(np.exp(hmm.log_pi_), [2.5 / 4.5, 1.5 / 4.5, 0.5 / 4.5])
    assert np.all(np.isfinite(hmm.log_A_)) and np.all(np.isfinite(hmm.log_C_.toarray()))


@st.composite
def labelled_episodes(draw: st.DrawFn) -> tuple[list[int], list[int], list[int], int, int]:
    n = draw(st.integers(1, 5))
    m = draw(st.integers(1, 5))
    lengths = draw(st.lists(st.integers(1, 12), min_size=1, max_size=4))
    total = sum(lengths)
    states = draw(st.lists(st.integers(0, n - 1), min_size=total, max_size=total))
    obs = draw(st.lists(st.integers(0, m - 1), min_size=total, max_size=total))
    return states, obs, lengths, n, m


@settings(max_examples=60, deadline=None)
@given(
    data=labelled_episodes(),
    counting=st.sampled_from(["changes", "steps"]),
    self_transitions=st.booleans(),
)
def test_rows_sum_to_one_where_counted_and_never_nan(
    data: tuple[list[int], list[int], list[int], int, int], counting: str, self_transitions: bool
) -> None:
    states, obs, lengths, n, m = data
    hmm = BehaviorHMM(
        n_states=n,
        n_observations=m,
        counting=counting,  # type: ignore[arg-type]
        self_transitions=self_transitions,
    ).fit(states, obs, lengths)
    tables = [
        (hmm.log_A_, hmm.A_counts_),
        (hmm.log_B_.toarray(), hmm.B_counts_.toarray()),
        (hmm.log_C_.toarray(), hmm.C_counts_.toarray()),
        (hmm.log_pi_, hmm.pi_counts_),
    ]
    for log_p, counts in tables:
        assert not np.any(np.isnan(log_p))
        assert not np.any(np.isposinf(log_p))
        sums = np.exp(log_p).sum(axis=-1)
        counted = counts.sum(axis=-1) > 0
        np.testing.assert_allclose(sums[counted], 1.0)
        assert np.all(sums[~counted] == 0.0)
        # a probability is zero exactly where its count is zero
        np.testing.assert_array_equal(np.isneginf(log_p), counts == 0)
    # total count checks: B sees every cycle, π counts every cycle
    assert hmm.B_counts_.sum() == len(states) == hmm.pi_counts_.sum()


def test_fit_returns_self_and_refit_is_identical() -> None:
    states, obs = table_4_3_sequences()
    hmm = BehaviorHMM(smoothing=0.1)
    assert hmm.fit(states, obs) is hmm
    first = hmm.to_arrays()
    hmm.fit([0, 1], [1, 0]).fit(states, obs)
    for key, value in hmm.to_arrays().items():
        np.testing.assert_array_equal(value, first[key])


def test_one_sample_and_one_category() -> None:
    hmm = BehaviorHMM().fit([0], [0])
    assert hmm.plan(0, 0).states == (0,)
    np.testing.assert_allclose(np.exp(hmm.log_A_), [[1.0]])
    steps = BehaviorHMM(counting="steps").fit([0], [0])
    assert np.isneginf(steps.log_A_[0, 0])  # nothing to count; no NaN


def test_methods_before_fit_raise_not_fitted() -> None:
    hmm = BehaviorHMM()
    for call in (
        lambda: hmm.plan(0, 1),
        lambda: hmm.viterbi([0]),
        lambda: hmm.most_likely_path(0, 1),
        hmm.to_arrays,
    ):
        with pytest.raises(NotFittedError):
            call()


@pytest.mark.parametrize(
    ("states", "obs", "lengths", "match"),
    [
        ([0, 1], [0], None, "samples"),
        ([], [], None, "no samples"),
        ([0.5, 1.0], [0, 1], None, "integer"),
        ([0, -1], [0, 1], None, "negative"),
        ([[0, 1]], [[0, 1]], None, "1-D"),
        ([0, 1, 0], [0, 1, 0], [2, 2], "sum to 4"),
        ([0, 1, 0], [0, 1, 0], [3, 0], "empty episode"),
    ],
)
def test_bad_training_data_is_refused(
    states: list[int], obs: list[int], lengths: list[int] | None, match: str
) -> None:
    with pytest.raises(DatasetError, match=match):
        BehaviorHMM().fit(states, obs, lengths)


def test_declared_sizes_must_hold_every_label() -> None:
    with pytest.raises(DatasetError, match="n_states=2"):
        BehaviorHMM(n_states=2).fit([0, 1, 2], [0, 0, 0])
    hmm = BehaviorHMM(n_states=4, n_observations=6).fit([0, 1], [0, 1])
    assert hmm.log_A_.shape == (4, 4) and hmm.log_B_.shape == (4, 6)
    assert hmm.log_B_.toarray().shape == (4, 6) and hmm.log_C_.toarray().shape == (6, 6)


@pytest.mark.parametrize(
    "params",
    [
        {"smoothing": -1.0},
        {"smoothing": float("nan")},
        {"smoothing": True},
        {"counting": "pairs"},
        {"self_transitions": "yes"},
        {"path_self_loops": "sometimes"},
        {"on_impossible": "ignore"},
        {"n_states": 0},
        {"n_observations": 2.5},
    ],
)
def test_bad_parameters_raise_config_error_at_fit(params: dict[str, object]) -> None:
    hmm = BehaviorHMM(**params)  # type: ignore[arg-type]  # __init__ only stores
    with pytest.raises(ConfigError):
        hmm.fit([0, 1], [0, 1])


def test_get_and_set_params() -> None:
    hmm = BehaviorHMM(smoothing=0.25)
    params = hmm.get_params()
    assert params["smoothing"] == 0.25 and params["counting"] == "changes"
    assert set(params) == {
        "n_states",
        "n_observations",
        "counting",
        "self_transitions",
        "smoothing",
        "path_self_loops",
        "on_impossible",
    }
    assert hmm.set_params(path_self_loops="keep") is hmm and hmm.path_self_loops == "keep"
    with pytest.raises(ConfigError, match="unknown"):
        hmm.set_params(alpha=1)
    assert repr(hmm) == "BehaviorHMM(smoothing=0.25, path_self_loops='keep')"
