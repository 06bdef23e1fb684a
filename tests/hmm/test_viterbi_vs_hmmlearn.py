"""``viterbi_log`` against hmmlearn's compiled Viterbi on random models of many shapes.

Dense, sparse (most transitions impossible, some states never entered) and tied models,
from 1 to 200 states, so that every forward pass of ``viterbi_log`` is used: the one that
stores the best predecessors (up to 16 states), the dense one (one block or blocks of
rows) and the sparse one. The paths must be identical except among equally likely
predecessors (we keep the lowest state index, hmmlearn's backtracking the highest), where
both paths must be equally likely, and the log probabilities must agree. Every test runs
once per kernel (the ``kernel`` fixture: numpy, and numba where it is installed); the
numpy forward passes are also compared with the default kernel, to the bit. No timing
here: ``behavior-hmm bench hmm`` compares the speed.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator

import numpy as np
import pytest
from hmm_testing import log_tables, random_model, random_observations

import behavior_hmm.hmm._viterbi as impl
from behavior_hmm.hmm._viterbi import viterbi_log

hmmlearn_hmm = pytest.importorskip(
    "hmmlearn.hmm",
    reason="hmmlearn is not installed (pip install 'behavior-hmm[bench]' or '[test]')",
)

pytestmark = pytest.mark.usefixtures("kernel")

REL = 1e-9


def _theirs(
    pi: np.ndarray, a: np.ndarray, b: np.ndarray, obs: np.ndarray
) -> tuple[float, np.ndarray]:
    model = hmmlearn_hmm.CategoricalHMM(n_components=pi.size, n_features=b.shape[1])
    model.startprob_, model.transmat_, model.emissionprob_ = pi, a, b
    with warnings.catch_warnings(), np.errstate(divide="ignore"):
        warnings.simplefilter("ignore")  # log(0) and hmmlearn's deprecation notices
        log_prob, states = model.decode(obs.reshape(-1, 1), algorithm="viterbi")
    return float(log_prob), np.asarray(states)


def _joint(
    log_pi: np.ndarray, log_a: np.ndarray, log_b: np.ndarray, states: np.ndarray, obs: np.ndarray
) -> float:
    """log P(states, obs), summed in the Viterbi's order."""
    total = log_pi[states[0]] + log_b[states[0], obs[0]]
    for t in range(1, obs.size):
        total = total + log_a[states[t - 1], states[t]] + log_b[states[t], obs[t]]
    return float(total)


def _check(
    pi: np.ndarray, a: np.ndarray, b: np.ndarray, obs: np.ndarray
) -> tuple[np.ndarray, float]:
    """Assert that ours and hmmlearn's agree; return our path and log probability."""
    log_pi, log_a, log_b = log_tables(pi, a, b)
    states, log_prob, dead = viterbi_log(log_pi, log_a, log_b, obs)
    their_log_prob, their_states = _theirs(pi, a, b, obs)
    assert states.dtype == np.int64 and states.shape == obs.shape
    if not np.isfinite(their_log_prob):
        assert log_prob == -np.inf and 0 <= dead < obs.size
        assert not states.any()
        return states, log_prob
    assert dead == -1
    assert log_prob == pytest.approx(their_log_prob, rel=REL)
    ours_joint = _joint(log_pi, log_a, log_b, states, obs)
    assert ours_joint == pytest.approx(log_prob, rel=REL)  # the path scores what we say
    if not np.array_equal(states, their_states):  # ties: both paths equally likely
        their_joint = _joint(log_pi, log_a, log_b, their_states, obs)
        assert ours_joint == pytest.approx(their_joint, rel=REL)
    return states, log_prob


SIZES = [(1, 3), (2, 4), (5, 12), (16, 40), (17, 40), (50, 200), (200, 400)]


@pytest.mark.parametrize("kind", ["dense", "sparse", "tied"])
@pytest.mark.parametrize(("n", "m"), SIZES)
def test_random_models_match_hmmlearn(rng: np.random.Generator, n: int, m: int, kind: str) -> None:
    t_len = 120 if n >= 200 else 300
    for _ in range(3):
        pi, a, b = random_model(rng, n, m, kind)
        _check(pi, a, b, random_observations(rng, pi, a, b, t_len))


@pytest.mark.parametrize("t_len", [1, 2, 3])
@pytest.mark.parametrize("kind", ["dense", "sparse", "tied"])
def test_very_short_sequences_match_hmmlearn(
    rng: np.random.Generator, t_len: int, kind: str
) -> None:
    for n in (1, 3, 20):
        pi, a, b = random_model(rng, n, 2 * n, kind)
        _check(pi, a, b, random_observations(rng, pi, a, b, t_len))


@pytest.mark.parametrize("n", [4, 30])
def test_impossible_sequences_agree_with_hmmlearn(rng: np.random.Generator, n: int) -> None:
    pi, a, b = random_model(rng, n, 2 * n, "sparse")
    b[:, -1] = 0.0  # nobody emits the last category ...
    b[:, 0] += 1.0  # ... (rows stay distributions)
    b /= b.sum(axis=1, keepdims=True)
    obs = random_observations(rng, pi, a, b, 50)
    obs[obs == 2 * n - 1] = 0
    obs[37] = 2 * n - 1
    _, log_prob = _check(pi, a, b, obs)
    assert log_prob == -np.inf
    log_pi, log_a, log_b = log_tables(pi, a, b)
    assert viterbi_log(log_pi, log_a, log_b, obs)[2] == 37


def test_exact_ties_keep_the_lowest_predecessor() -> None:
    """Every path equally likely: we keep state 0 throughout, hmmlearn differs but ties."""
    n, t_len = 3, 6
    pi, a, b = np.full(n, 1 / n), np.full((n, n), 1 / n), np.full((n, 2), 0.5)
    obs = np.zeros(t_len, dtype=np.int64)
    states, _ = _check(pi, a, b, obs)
    assert not states.any()


#: The module's tuning constants as shipped (read before any test patches them).
_SHIPPED = {
    name: getattr(impl, name)
    for name in (
        "_PREDECESSORS_MAX_STATES",
        "_SPARSE_MAX_DENSITY",
        "_ONE_BLOCK_MAX",
        "_BLOCK_ELEMENTS",
    )
}


@pytest.fixture(params=["predecessors", "one block", "blocks", "sparse"])
def forward(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """Force one numpy forward pass of ``viterbi_log`` whatever the model's size and density."""
    name = str(request.param)
    monkeypatch.setattr(impl._switch, "setting", "numpy")
    monkeypatch.setattr(impl, "_PREDECESSORS_MAX_STATES", 10**9 if name == "predecessors" else 0)
    monkeypatch.setattr(impl, "_SPARSE_MAX_DENSITY", 1.0 if name == "sparse" else -1.0)
    monkeypatch.setattr(impl, "_ONE_BLOCK_MAX", 10**9 if name == "one block" else 0)
    monkeypatch.setattr(impl, "_BLOCK_ELEMENTS", 7 * 23)  # blocks of 8 rows
    yield name


@pytest.mark.parametrize("kind", ["dense", "sparse", "tied"])
def test_every_forward_pass_gives_the_same_result(
    rng: np.random.Generator, forward: str, kind: str, kernel: str
) -> None:
    """Each numpy forward pass on models of any size: the same path and log probability
    as the default choice of the kernel under test (numpy's or numba's), to the bit, and
    hmmlearn's up to ties."""
    for n in (1, 2, 9, 23, 40):
        pi, a, b = random_model(rng, n, 3 * n, kind)
        obs = random_observations(rng, pi, a, b, 150)
        states, log_prob = _check(pi, a, b, obs)
        with pytest.MonkeyPatch.context() as shipped:
            for name, value in _SHIPPED.items():
                shipped.setattr(impl, name, value)
            shipped.setattr(impl._switch, "setting", kernel)
            expected = viterbi_log(*log_tables(pi, a, b), obs)
        assert np.array_equal(states, expected[0]) and log_prob == expected[1]
