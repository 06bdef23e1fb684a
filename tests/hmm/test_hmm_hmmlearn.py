"""Our Viterbi against hmmlearn's compiled one on the same models (identical up to ties).

Among equally likely predecessors we keep the lowest state index; hmmlearn's backtracking
keeps the highest. Where that makes the paths differ, both must be optimal. Every test
runs once per kernel (the ``kernel`` fixture: numpy, and numba where it is installed).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from behavior_hmm.hmm import BehaviorHMM
from behavior_hmm.hmm._viterbi import _ONE_BLOCK_MAX, viterbi_log

hmmlearn_hmm = pytest.importorskip(
    "hmmlearn.hmm",
    reason="hmmlearn is not installed (pip install 'behavior-hmm[bench]' or '[test]')",
)

pytestmark = pytest.mark.usefixtures("kernel")


def _theirs(hmm: BehaviorHMM) -> object:
    probs = hmm.dense_probabilities()
    model = hmmlearn_hmm.CategoricalHMM(n_components=hmm.n_states_, n_features=hmm.n_observations_)
    model.startprob_ = probs["pi"]
    model.transmat_ = probs["A"]
    model.emissionprob_ = probs["B"]
    return model


def _decode_theirs(model: object, obs: np.ndarray) -> tuple[float, np.ndarray]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        log_prob, states = model.decode(obs.reshape(-1, 1), algorithm="viterbi")  # type: ignore[attr-defined]
    return float(log_prob), np.asarray(states)


def _joint(hmm: BehaviorHMM, states: np.ndarray, obs: np.ndarray) -> float:
    return float(
        hmm.log_pi_[states[0]]
        + hmm.log_A_[states[:-1], states[1:]].sum()
        + hmm.log_B_.toarray()[states, obs].sum()
    )


def _counted(
    rng: np.random.Generator, n: int, m: int, samples: int, **params: object
) -> BehaviorHMM:
    """A model counted from a random labelled sequence (every state seen, rows valid)."""
    states = rng.integers(0, n, samples)
    states[:n] = np.arange(n)  # every state appears, so every row of A and B is a distribution
    states[-1] = 0  # ... and every state has a successor
    obs = rng.integers(0, m, samples)
    return BehaviorHMM(n_states=n, n_observations=m, **params).fit(states, obs)


@pytest.mark.parametrize(
    ("n", "m", "t_len", "samples", "smoothing"),
    [
        (1, 3, 5, 20, 0.0),
        (3, 4, 50, 60, 0.0),  # sparse counts: zeros in A and B, many exact ties
        (12, 30, 200, 400, 0.0),
        (50, 200, 200, 20_000, 1.0),  # the benchmark's small size
        (40, 120, 300, 200, 0.0),  # few samples: most transitions impossible
    ],
)
def test_viterbi_matches_hmmlearn(
    n: int, m: int, t_len: int, samples: int, smoothing: float, rng: np.random.Generator
) -> None:
    for _ in range(5):
        hmm = _counted(rng, n, m, samples, smoothing=smoothing)
        # observation sequences the model can explain: emitted along a path of A
        obs = rng.integers(0, m, t_len)
        theirs = _theirs(hmm)
        their_log_prob, their_states = _decode_theirs(theirs, obs)
        if not np.isfinite(their_log_prob):
            continue  # nothing explains it; the refusal is tested elsewhere
        states, log_prob = hmm.viterbi(obs)
        assert log_prob == pytest.approx(their_log_prob, rel=1e-12, abs=1e-9)
        if not np.array_equal(states, their_states):  # a tie: both paths are optimal
            assert _joint(hmm, states, obs) == pytest.approx(
                _joint(hmm, their_states, obs), rel=1e-12, abs=1e-9
            )
        # the sums are formed in hmmlearn's order: the same log probability to the bit
        assert log_prob == their_log_prob


def test_blocked_viterbi_matches_hmmlearn(
    rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Large models score the states in blocks of rows; small blocks here, same result."""
    import behavior_hmm.hmm._viterbi as impl

    assert _ONE_BLOCK_MAX > 0
    monkeypatch.setattr(impl._switch, "setting", "numpy")  # the blocks are numpy's
    monkeypatch.setattr(impl, "_ONE_BLOCK_MAX", 0)
    monkeypatch.setattr(impl, "_BLOCK_ELEMENTS", 7 * 23)
    hmm = _counted(rng, 23, 50, 3000, smoothing=0.5)
    obs = rng.integers(0, 50, 120)
    their_log_prob, their_states = _decode_theirs(_theirs(hmm), obs)
    states, log_prob, dead = viterbi_log(hmm.log_pi_, hmm.log_A_, hmm.log_B_, obs)
    assert dead == -1 and log_prob == their_log_prob
    assert np.array_equal(states, their_states) or _joint(hmm, states, obs) == pytest.approx(
        _joint(hmm, their_states, obs), rel=1e-12
    )


def test_dense_random_model_gives_hmmlearn_path(rng: np.random.Generator) -> None:
    """Without ties (real-valued random tables) the paths are identical."""
    n, m = 30, 60
    a = rng.dirichlet(np.ones(n), n)
    b = rng.dirichlet(np.ones(m), n)
    pi = rng.dirichlet(np.ones(n))
    theirs = hmmlearn_hmm.CategoricalHMM(n_components=n, n_features=m)
    theirs.startprob_, theirs.transmat_, theirs.emissionprob_ = pi, a, b
    obs = rng.integers(0, m, 500)
    states, log_prob, _ = viterbi_log(np.log(pi), np.log(a), np.log(b), obs)
    their_log_prob, their_states = _decode_theirs(theirs, obs)
    assert np.array_equal(states, their_states) and log_prob == their_log_prob
