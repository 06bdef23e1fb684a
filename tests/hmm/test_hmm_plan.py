"""plan(): path + Viterbi + segments with exit observations, and its caches."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from hmm_testing import model_from_counts
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import behavior_hmm.hmm._behavior_hmm as impl
from behavior_hmm.errors import UnreachableGoalError
from behavior_hmm.hmm import BehaviorHMM, Plan, Segment
from behavior_hmm.hmm._plan import make_segments

TURN, APPROACH, GRASP = 0, 1, 2
O_C, O_1, O_2, O_G, O_FAR = 0, 1, 2, 3, 4  # thesis ch. 5: o_c, o1, o2, o_g; O_FAR: 70°, 0 m


def complex_behavior_model(**params: float) -> BehaviorHMM:
    """CBLM-style data: states are learned behaviors, tagged per control cycle."""
    ep1_s = [TURN] * 5 + [APPROACH] * 5 + [GRASP] * 4
    ep1_o = [O_C] * 5 + [O_1] * 5 + [O_2] * 3 + [O_G]
    ep2_s = [TURN] * 4 + [GRASP] * 3
    ep2_o = [O_FAR] * 4 + [O_2] * 2 + [O_G]
    hmm = BehaviorHMM(**params)  # type: ignore[arg-type]
    return hmm.fit(ep1_s + ep2_s, ep1_o + ep2_o, lengths=[len(ep1_s), len(ep2_s)])


def test_thesis_chapter_5_example() -> None:
    hmm = complex_behavior_model()
    plan = hmm.plan(O_C, O_G)
    assert plan.observations == (O_C, O_1, O_2, O_G)
    assert plan.state_sequence == (TURN, APPROACH, GRASP)
    # each behavior is handed the intermediate goal that ends it
    assert plan.exit_observations == (O_1, O_2, O_G)
    assert plan.decoding == "viterbi" and np.isfinite(plan.log_prob)
    # starting already at angle 0: [approach, grasp]; at 70°, 0 m: [turn, grasp]
    assert hmm.plan(O_1, O_G).state_sequence == (APPROACH, GRASP)
    assert hmm.plan(O_FAR, O_G).state_sequence == (TURN, GRASP)
    assert hmm.plan(O_FAR, O_G).exit_observations == (O_2, O_G)


def test_segments_cover_the_path_in_order() -> None:
    plan = complex_behavior_model().plan(O_C, O_G)
    assert plan.states == (TURN, APPROACH, GRASP, GRASP)
    assert plan.segments == (
        Segment(state=TURN, exit_observation=O_1, last_observation=O_C, start=0, stop=1),
        Segment(state=APPROACH, exit_observation=O_2, last_observation=O_1, start=1, stop=2),
        Segment(state=GRASP, exit_observation=O_G, last_observation=O_G, start=2, stop=4),
    )
    assert plan.goal == O_G


@settings(max_examples=40, deadline=None)
@given(states=st.lists(st.integers(0, 3), min_size=1, max_size=8))
def test_segments_partition_the_states(states: list[int]) -> None:
    observations = tuple(range(10, 10 + len(states)))
    segments = make_segments(observations, tuple(states))
    rebuilt = [seg.state for seg in segments for _ in range(seg.start, seg.stop)]
    assert rebuilt == states
    assert segments[0].start == 0 and segments[-1].stop == len(states)
    for a, b in itertools.pairwise(segments):
        assert a.stop == b.start and a.state != b.state
        assert a.exit_observation == observations[b.start]
    assert segments[-1].exit_observation == observations[-1]
    assert all(s.last_observation == observations[s.stop - 1] for s in segments)


def test_current_equal_to_goal_gives_the_state_to_hold_the_goal() -> None:
    plan = complex_behavior_model().plan(O_G, O_G)
    assert plan.observations == (O_G,)
    assert plan.segments == (Segment(GRASP, O_G, O_G, 0, 1),)


def test_unreachable_goal_raises_before_any_decoding(monkeypatch: pytest.MonkeyPatch) -> None:
    hmm = complex_behavior_model()

    def no_decoding(*args: object) -> None:
        raise AssertionError("Viterbi must not run for an unreachable goal")

    monkeypatch.setattr(impl, "viterbi_log", no_decoding)
    with pytest.raises(UnreachableGoalError, match="category 0 cannot be reached from category 3"):
        hmm.plan(O_G, O_C)


def test_plan_cache_returns_the_same_plan_as_a_fresh_model() -> None:
    hmm = complex_behavior_model()
    first = hmm.plan(O_C, O_G)
    assert hmm.plan(O_C, O_G) is first  # warm: a dict lookup
    assert hmm.plan(np.int64(O_C), np.int64(O_G)) is first
    assert complex_behavior_model().plan(O_C, O_G) == first
    with pytest.raises(dataclasses.FrozenInstanceError):
        first.states = ()  # type: ignore[misc]


def test_lru_eviction_keeps_results_correct(monkeypatch: pytest.MonkeyPatch) -> None:
    hmm = complex_behavior_model()
    monkeypatch.setattr(hmm, "_PLAN_CACHE_SIZE", 2)
    pairs = [(O_C, O_G), (O_1, O_G), (O_FAR, O_G), (O_2, O_G), (O_C, O_G)]
    fresh = complex_behavior_model()
    plans = [hmm.plan(c, g) for c, g in pairs]
    assert len(hmm._plans) == 2
    assert plans == [fresh.plan(c, g) for c, g in pairs]


def test_prepare_goals_computes_every_message_the_plans_then_use() -> None:
    import behavior_hmm.benchmarks.memory as bench

    hmm = bench.synthetic_hmm(3_000, 40)
    hmm.prepare_goals([0])
    decoder = hmm._decoders[0]
    reaching = np.flatnonzero(np.isfinite(hmm._tree(0).cost))
    assert reaching.size > 2_000 and set(decoder._value) == set(reaching.tolist())
    cats, _ = bench.synthetic_walks(3_000, 5, np.random.default_rng(2))
    fresh = bench.synthetic_hmm(3_000, 40)  # computes each path's messages on first use
    for c in dict.fromkeys(cats.tolist()):
        if hmm.can_plan(c, 0):
            assert hmm.plan(c, 0) == fresh.plan(c, 0)
            np.testing.assert_array_equal(hmm.state_scores(c, 0), fresh.state_scores(c, 0))
    assert set(decoder._value) == set(reaching.tolist())  # nothing left to compute


def test_prepare_goals_leaves_the_messages_of_a_smoothed_b_to_first_use() -> None:
    hmm = complex_behavior_model(smoothing=0.1)
    hmm.prepare_goals([O_G])
    decoder = hmm._decoders[O_G]
    assert decoder._dense and not decoder._full_value  # N-vectors: only on first use
    assert hmm.plan(O_C, O_G).observations[-1] == O_G


def test_refit_clears_the_caches() -> None:
    hmm = complex_behavior_model()
    assert hmm.plan(O_C, O_G).state_sequence == (TURN, APPROACH, GRASP)
    hmm.fit([0, 0, 0, 0], [O_C, O_1, O_2, O_G])
    plan = hmm.plan(O_C, O_G)
    assert isinstance(plan, Plan) and plan.state_sequence == (0,)


small_counts = st.sampled_from([0, 0, 1, 3])


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 3), m=st.integers(2, 5), data=st.data())
def test_plan_states_are_the_viterbi_optimum_of_the_path(
    n: int, m: int, data: st.DataObject
) -> None:
    A = data.draw(arrays(np.int64, (n, n), elements=small_counts))
    B = data.draw(arrays(np.int64, (n, m), elements=small_counts))
    C = data.draw(arrays(np.int64, (m, m), elements=small_counts))
    hmm = model_from_counts(A, B, C)
    for c, g in data.draw(
        st.lists(st.tuples(st.integers(0, m - 1), st.integers(0, m - 1)), min_size=1, max_size=6)
    ):
        try:
            path = hmm.most_likely_path(c, g)
        except UnreachableGoalError:
            with pytest.raises(UnreachableGoalError):
                hmm.plan(c, g)
            continue
        try:
            _, best = hmm.viterbi(path)
        except UnreachableGoalError:
            with pytest.raises(UnreachableGoalError):
                hmm.plan(c, g)
            continue
        plan = hmm.plan(c, g)
        assert plan.observations == path
        assert plan.log_prob == pytest.approx(best, abs=1e-9)
        states = np.array(plan.states)
        obs = np.array(path)
        achieved = (
            hmm.log_pi_[states[0]]
            + hmm.log_A_[states[:-1], states[1:]].sum()
            + hmm.log_B_.toarray()[states, obs].sum()
        )
        assert achieved == pytest.approx(best, abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(
    episodes=st.lists(
        st.lists(st.tuples(st.integers(0, 3), st.integers(0, 7)), min_size=1, max_size=9),
        min_size=1,
        max_size=5,
    ),
    goals=st.lists(st.integers(0, 7), min_size=1, max_size=3),
    smoothing=st.sampled_from([0.0, 0.1]),
    on_impossible=st.sampled_from(["raise", "emissions"]),
)
def test_plannable_from_is_can_plan_toward_any_goal(
    episodes: list[list[tuple[int, int]]], goals: list[int], smoothing: float, on_impossible: str
) -> None:
    states = [s for ep in episodes for s, _ in ep]
    observations = [o for ep in episodes for _, o in ep]
    hmm = BehaviorHMM(smoothing=smoothing, on_impossible=on_impossible)  # type: ignore[arg-type]
    hmm.fit(states, observations, lengths=[len(ep) for ep in episodes])
    goals = [g for g in goals if g < hmm.n_observations_] or [observations[-1]]
    mask = hmm.plannable_from(goals)
    expected = [any(hmm.can_plan(c, g) for g in goals) for c in range(hmm.n_observations_)]
    assert mask.tolist() == expected


def test_plannable_from_names_the_categories_a_plan_to_a_goal_starts_from() -> None:
    # the approach (O_1) was only ever entered from the turn at O_C; every category
    # leads to the grasp's end O_G, the one at 70 deg (O_FAR) by its own demonstration
    hmm = complex_behavior_model()
    assert hmm.plannable_from([O_G]).tolist() == [True, True, True, True, True]
    assert hmm.plannable_from([O_1]).tolist() == [True, True, False, False, False]
