"""Viterbi in log space against brute-force enumeration, long sequences, impossible paths.

Every test runs once per kernel (the ``kernel`` fixture: numpy, and numba where it is
installed).
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
import pytest
from hmm_testing import model_from_counts, probs
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from behavior_hmm.errors import DatasetError, UnreachableGoalError
from behavior_hmm.hmm import BehaviorHMM

pytestmark = pytest.mark.usefixtures("kernel")


def joint_log_prob(
    pi: np.ndarray, A: np.ndarray, B: np.ndarray, states: tuple[int, ...], obs: list[int]
) -> float:
    """log P(states, obs) in plain Python (−inf when any factor is zero)."""
    factors = [pi[states[0]] * B[states[0], obs[0]]]
    for t in range(1, len(obs)):
        factors.append(A[states[t - 1], states[t]] * B[states[t], obs[t]])
    if min(factors) == 0.0:
        return -math.inf
    return sum(math.log(f) for f in factors)


counts = st.sampled_from([0, 0, 1, 2, 5])


@settings(max_examples=80, deadline=None)
@given(
    n=st.integers(1, 3),
    m=st.integers(1, 3),
    data=st.data(),
)
def test_viterbi_equals_brute_force_enumeration(n: int, m: int, data: st.DataObject) -> None:
    A_c = data.draw(arrays(np.int64, (n, n), elements=counts))
    B_c = data.draw(arrays(np.int64, (n, m), elements=counts))
    pi_c = data.draw(arrays(np.int64, (n,), elements=counts))
    obs = data.draw(st.lists(st.integers(0, m - 1), min_size=1, max_size=5))
    hmm = model_from_counts(A_c, B_c, np.ones((m, m), dtype=int), pi=pi_c)
    pi, A, B = probs(pi_c), probs(A_c), probs(B_c)
    best = max(
        joint_log_prob(pi, A, B, seq, obs) for seq in itertools.product(range(n), repeat=len(obs))
    )
    if best == -math.inf:
        with pytest.raises(UnreachableGoalError, match="position"):
            hmm.viterbi(obs)
        return
    states, log_prob = hmm.viterbi(obs)
    assert log_prob == pytest.approx(best, abs=1e-9)
    assert joint_log_prob(pi, A, B, tuple(int(s) for s in states), obs) == pytest.approx(
        best, abs=1e-9
    )


def test_viterbi_on_a_1e5_step_sequence_stays_finite(rng: np.random.Generator) -> None:
    n, m, t_len = 4, 5, 100_000
    A_c = rng.integers(1, 20, size=(n, n))
    B_c = rng.integers(1, 20, size=(n, m))
    hmm = model_from_counts(A_c, B_c, np.ones((m, m), dtype=int))
    obs = rng.integers(0, m, size=t_len)
    states, log_prob = hmm.viterbi(obs)
    assert states.shape == (t_len,)
    assert np.isfinite(log_prob)
    assert log_prob < -1e4  # far below float64 underflow in probability space
    # the reported log probability is the one of the returned sequence
    expected = (
        hmm.log_pi_[states[0]]
        + hmm.log_A_[states[:-1], states[1:]].sum()
        + hmm.log_B_.toarray()[states, obs].sum()
    )
    assert log_prob == pytest.approx(expected, rel=1e-9)


def test_viterbi_with_unseen_states_and_zero_rows_never_gives_nan() -> None:
    # state 2 was never seen: its rows are all −inf
    hmm = BehaviorHMM(n_states=3).fit([0, 0, 1, 1, 0], [0, 1, 1, 0, 0])
    assert np.all(np.isneginf(hmm.log_A_[2])) and np.all(np.isneginf(hmm.log_B_.toarray()[2]))
    states, log_prob = hmm.viterbi([0, 1, 1, 0])
    assert np.isfinite(log_prob)
    assert 2 not in states


def impossible_model(**params: object) -> BehaviorHMM:
    """o0 only in state 0, o1 only in state 1, and state 0 never goes to state 1."""
    return model_from_counts(
        A=[[1, 0], [0, 1]], B=[[1, 0], [0, 1]], C=[[1, 1], [0, 1]], pi=[1, 1], **params
    )


def test_impossible_sequence_raises_with_position() -> None:
    hmm = impossible_model()
    with pytest.raises(UnreachableGoalError, match=r"position 1 \(observation category 1\)"):
        hmm.viterbi([0, 1])
    with pytest.raises(UnreachableGoalError, match="position 1"):
        hmm.plan(0, 1)


def test_emission_fallback_decodes_each_element_alone() -> None:
    hmm = impossible_model(on_impossible="emissions")
    states, log_prob = hmm.viterbi([0, 1])
    assert states.tolist() == [0, 1] and log_prob == -math.inf
    plan = hmm.plan(0, 1)
    assert plan.decoding == "emissions" and plan.states == (0, 1)
    # the per-call override wins over the estimator setting
    with pytest.raises(UnreachableGoalError):
        hmm.viterbi([0, 1], on_impossible="raise")
    assert impossible_model().viterbi([0, 1], on_impossible="emissions")[0].tolist() == [0, 1]


def test_emission_fallback_cannot_decode_an_observation_no_state_emits() -> None:
    hmm = model_from_counts(A=[[1]], B=[[1, 0]], C=[[1, 1], [0, 1]], on_impossible="emissions")
    with pytest.raises(UnreachableGoalError, match="never seen"):
        hmm.viterbi([0, 1])


def test_smoothing_makes_the_impossible_sequence_decodable() -> None:
    hmm = impossible_model(smoothing=0.1)
    states, log_prob = hmm.viterbi([0, 1])
    # (0, 0) and (0, 1) now tie at 0.5 * (1.1/1.2)^2 * (0.1/1.2)
    assert log_prob == pytest.approx(math.log(0.5 * (1.1 / 1.2) ** 2 * (0.1 / 1.2)))
    assert states[0] == 0


@pytest.mark.parametrize("obs", [[], [0, 5], [0.0, 1.0], [[0]]])
def test_bad_observation_sequences_are_refused(obs: Any) -> None:
    hmm = BehaviorHMM().fit([0, 1], [0, 1])
    with pytest.raises(DatasetError):
        hmm.viterbi(obs)
