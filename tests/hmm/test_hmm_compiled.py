"""The numba Viterbi kernel against the numpy one: the same results, to the bit.

The same states, the same log probability (``==``) and the same ``dead_at`` on dense,
sparse and tied models of 1 to 200 states; and the switch between the kernels
(``set_kernel``) really changes the kernel that runs. The tests of the switch use the
kernels' plain Python source in place of the compiled functions, so they run without numba.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import pytest
from hmm_testing import log_tables, random_model, random_observations

import behavior_hmm.hmm._viterbi as impl
from behavior_hmm.hmm import _compiled
from behavior_hmm.hmm._viterbi import set_kernel, viterbi_kernel, viterbi_log

Result = tuple[np.ndarray, float, int]


@pytest.fixture
def numba_kernels() -> _compiled.Kernels:
    """The compiled kernels (skips the test without numba)."""
    pytest.importorskip("numba", reason="numba is not installed (the 'fast' extra)")
    kernels = _compiled.kernels()
    assert kernels is not None
    return kernels


@contextmanager
def _using(setting: impl.KernelSetting) -> Iterator[None]:
    previous = set_kernel(setting)
    try:
        yield
    finally:
        set_kernel(previous)


def _decode(setting: impl.KernelSetting, *args: np.ndarray) -> Result:
    with _using(setting):
        assert viterbi_kernel() == ("numpy" if setting == "numpy" else "numba")
        return viterbi_log(*args)


def _assert_identical(ours: Result, expected: Result) -> None:
    states, log_prob, dead = ours
    assert states.dtype == np.int64 and states.shape == expected[0].shape
    assert np.array_equal(states, expected[0])
    assert log_prob == expected[1]  # to the bit (-inf == -inf too)
    assert dead == expected[2]


def _both(
    log_pi: np.ndarray, log_a: np.ndarray, log_b: np.ndarray, obs: np.ndarray
) -> tuple[Result, Result]:
    """numba's and numpy's results, asserted identical."""
    compiled = _decode("numba", log_pi, log_a, log_b, obs)
    numpy = _decode("numpy", log_pi, log_a, log_b, obs)
    _assert_identical(compiled, numpy)
    return compiled, numpy


@pytest.mark.usefixtures("numba_kernels")
@pytest.mark.parametrize("t_len", [1, 2, 50])
@pytest.mark.parametrize("n", [1, 2, 3, 16, 17, 50, 200])
@pytest.mark.parametrize("kind", ["dense", "sparse", "tied"])
def test_compiled_kernel_is_bit_identical_to_numpy(
    rng: np.random.Generator, kind: str, n: int, t_len: int
) -> None:
    """Random models, the tied ones with many exactly equal predecessors: the lowest
    index wins on both kernels, so even the tied paths are the same."""
    for _ in range(3):
        pi, a, b = random_model(rng, n, 2 * n, kind)
        obs = random_observations(rng, pi, a, b, t_len)
        (_, log_prob, dead), _ = _both(*log_tables(pi, a, b), obs)
        assert np.isfinite(log_prob) == (dead == -1)


@pytest.mark.usefixtures("numba_kernels")
def test_all_equal_paths_keep_state_zero_on_both_kernels() -> None:
    n = 6
    log_pi, log_a, log_b = log_tables(np.full(n, 1 / n), np.full((n, n), 1 / n), np.ones((n, 1)))
    (states, _, _), _ = _both(log_pi, log_a, log_b, np.zeros(20, dtype=np.int64))
    assert not states.any()


@pytest.mark.usefixtures("numba_kernels")
def test_impossible_start_on_both_kernels() -> None:
    """No start state emits the first observation: dead at 0, before any forward pass."""
    pi = np.array([0.0, 0.0, 1.0])
    a = np.full((3, 3), 1 / 3)
    b = np.array([[1.0, 0.0], [0.5, 0.5], [0.0, 1.0]])
    (states, log_prob, dead), _ = _both(*log_tables(pi, a, b), np.array([0, 1, 1]))
    assert dead == 0 and log_prob == -np.inf and not states.any()


@pytest.mark.usefixtures("numba_kernels")
@pytest.mark.parametrize("n", [4, 30])
def test_sequence_that_dies_midway_on_both_kernels(rng: np.random.Generator, n: int) -> None:
    """An observation no state emits at position 37: every state is impossible from there."""
    pi, a, b = random_model(rng, n, 2 * n, "sparse")
    b[:, -1] = 0.0
    b[:, 0] += 1.0
    b /= b.sum(axis=1, keepdims=True)
    obs = random_observations(rng, pi, a, b, 50)
    obs[obs == 2 * n - 1] = 0
    obs[37] = 2 * n - 1
    (states, log_prob, dead), _ = _both(*log_tables(pi, a, b), obs)
    assert dead == 37 and log_prob == -np.inf and not states.any()


@pytest.mark.usefixtures("numba_kernels")
def test_sequence_that_no_transition_explains_dies_on_both_kernels() -> None:
    """Each category is emitted by one state, but state 0 never goes to state 1."""
    pi = np.array([0.5, 0.5])
    a = np.array([[1.0, 0.0], [0.0, 1.0]])
    b = np.eye(2)
    (_, log_prob, dead), _ = _both(*log_tables(pi, a, b), np.array([0, 0, 0, 1, 1]))
    assert dead == 3 and log_prob == -np.inf


@pytest.mark.usefixtures("numba_kernels")
def test_compiled_kernel_takes_tables_in_any_memory_order(rng: np.random.Generator) -> None:
    pi, a, b = random_model(rng, 20, 40, "dense")
    log_pi, log_a, log_b = log_tables(pi, a, b)
    obs = random_observations(rng, pi, a, b, 60)
    expected = _decode("numpy", log_pi, log_a, log_b, obs)
    fortran = (np.asfortranarray(log_a), np.asfortranarray(log_b))
    _assert_identical(_decode("numba", log_pi, *fortran, obs), expected)
    strided = (np.repeat(log_a, 2, axis=1)[:, ::2], np.repeat(log_b, 2, axis=0)[::2])
    _assert_identical(_decode("numba", log_pi, *strided, obs), expected)


def test_compiled_kernels_are_compiled_once(numba_kernels: _compiled.Kernels) -> None:
    assert _compiled.kernels() is numba_kernels
    signatures: Any = getattr(numba_kernels.forward, "signatures", None)
    assert signatures and len(signatures) == 1  # eagerly compiled for one signature


class _Spy:
    """The kernels' plain Python source standing in for the compiled functions."""

    def __init__(self) -> None:
        self.calls: list[str] = []

    def forward(self, *args: Any) -> None:
        self.calls.append("forward")
        _compiled.forward(*args)

    def forward_sparse(self, *args: Any) -> None:
        self.calls.append("forward_sparse")
        _compiled.forward_sparse(*args)

    def follow(self, *args: Any) -> None:
        self.calls.append("follow")
        _compiled.follow(*args)


@pytest.fixture
def spy(monkeypatch: pytest.MonkeyPatch) -> Iterator[_Spy]:
    """``_compiled.kernels()`` returns the spy's kernels; the setting is "auto"."""
    spy = _Spy()
    monkeypatch.setattr(
        _compiled, "kernels", lambda: _compiled.Kernels(spy.forward, spy.forward_sparse, spy.follow)
    )
    monkeypatch.setattr(impl._switch, "setting", "auto")
    yield spy


def test_the_switch_changes_the_kernel_that_runs(spy: _Spy, rng: np.random.Generator) -> None:
    """With the compiled kernels available, "auto" and "numba" run them and "numpy" does
    not; the kernels' Python source gives numpy's results to the bit (ties included)."""
    seen = set()
    for n, kind in ((5, "tied"), (20, "sparse"), (60, "sparse"), (20, "dense")):
        pi, a, b = random_model(rng, n, 2 * n, kind)
        args = (*log_tables(pi, a, b), random_observations(rng, pi, a, b, 30))
        spy.calls.clear()
        expected = _decode("numpy", *args)
        assert spy.calls == []
        # a table with at most 20 % possible transitions runs the sparse pass
        sparse = np.isfinite(args[1]).mean() <= impl._SPARSE_MAX_DENSITY
        forward = "forward_sparse" if sparse else "forward"
        ran = [forward, "follow"] if np.isfinite(expected[1]) else [forward]
        for setting in ("auto", "numba"):
            _assert_identical(_decode(setting, *args), expected)
            assert spy.calls == ran
            spy.calls.clear()
        seen.add(forward)
    assert seen == {"forward", "forward_sparse"}  # both passes were compared with numpy
    _decode("auto", *args[:3], args[3][:1])  # one step: nothing to run forward
    assert spy.calls == []


def test_set_kernel_returns_the_previous_setting(spy: _Spy) -> None:
    assert set_kernel("numpy") == "auto"
    assert viterbi_kernel() == "numpy"
    assert set_kernel("numba") == "numpy"
    assert viterbi_kernel() == "numba"
    assert set_kernel("auto") == "numba"
    assert viterbi_kernel() == "numba"


def test_set_kernel_refuses_unknown_kernels_and_numba_without_numba(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(impl._switch, "setting", "auto")
    unknown: Any = "cuda"
    with pytest.raises(ValueError, match="unknown Viterbi kernel 'cuda'"):
        set_kernel(unknown)
    monkeypatch.setattr(_compiled, "kernels", lambda: None)  # as without numba
    assert viterbi_kernel() == "numpy"
    with pytest.raises(ImportError, match=r"behavior-hmm\[fast\]"):
        set_kernel("numba")
    assert impl._switch.setting == "auto"


def test_a_plan_never_loads_the_compiled_kernel(monkeypatch: pytest.MonkeyPatch) -> None:
    # a plan is decoded inside a control cycle: importing numba there would stall ~0.7 s
    from behavior_hmm.hmm import BehaviorHMM

    loaded: list[bool] = []
    monkeypatch.setattr(impl._switch, "setting", "auto")
    monkeypatch.setattr(_compiled, "kernels", lambda: loaded.append(True))
    hmm = BehaviorHMM(n_states=2, n_observations=3, on_impossible="emissions").fit(
        np.array([0, 0, 1, 1, 0, 1]), np.array([0, 1, 2, 2, 0, 2])
    )

    class Impossible:  # the goal tree finds no state sequence: the plan decodes in full
        def decode(self, path: list[int]) -> tuple[list[int], float]:
            return [], float("-inf")

    monkeypatch.setattr(hmm, "_decoder", lambda goal: Impossible())
    plan = hmm.plan(0, 2)
    assert len(plan.states) == len(plan.observations)
    assert loaded == []
    hmm.viterbi(np.array([0, 1, 2]))  # the public decoding does use it
    assert loaded == [True]
