"""Most likely observation path: Dijkstra on −log c_ij against brute force."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hmm_testing import model_from_counts
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from behavior_hmm.errors import ConfigError, UnreachableGoalError
from behavior_hmm.hmm import BehaviorHMM


def edge_prob(C: np.ndarray, i: int, j: int, rule: str) -> float:
    """Transition probability used for planning, computed from counts by hand."""
    row = C[i].astype(float)
    if rule == "drop":
        rest = row.sum() - row[i]
        return row[j] / rest if rest > 0 else 0.0
    return row[j] / row.sum() if row.sum() > 0 else 0.0


def brute_force_best(C: np.ndarray, start: int, goal: int, rule: str) -> float:
    """Largest log probability over all simple paths start → goal (−inf if none)."""
    m = C.shape[0]
    best = -math.inf

    def extend(node: int, visited: set[int], logp: float) -> None:
        nonlocal best
        if node == goal:
            best = max(best, logp)
            return
        for nxt in range(m):
            if nxt in visited or nxt == node:
                continue
            p = edge_prob(C, node, nxt, rule)
            if p > 0:
                extend(nxt, visited | {nxt}, logp + math.log(p))

    extend(start, {start}, 0.0)
    return best


def path_log_prob(C: np.ndarray, path: tuple[int, ...], rule: str) -> float:
    return sum(math.log(edge_prob(C, a, b, rule)) for a, b in itertools.pairwise(path))


def chain_model(C: np.ndarray, **params: object) -> BehaviorHMM:
    """One state that sees every observation: the planning only depends on C."""
    m = C.shape[0]
    return model_from_counts([[1]], np.ones((1, m), dtype=int), C, **params)


@settings(max_examples=80, deadline=None)
@given(
    C=st.integers(2, 6).flatmap(
        lambda m: arrays(np.int64, (m, m), elements=st.sampled_from([0, 0, 0, 1, 2, 3, 7, 20]))
    ),
    rule=st.sampled_from(["drop", "keep"]),
    data=st.data(),
)
def test_dijkstra_path_is_the_brute_force_most_likely_path(
    C: np.ndarray, rule: str, data: st.DataObject
) -> None:
    m = C.shape[0]
    start = data.draw(st.integers(0, m - 1))
    goal = data.draw(st.integers(0, m - 1))
    hmm = chain_model(C, path_self_loops=rule)
    best = brute_force_best(C, start, goal, rule)
    if best == -math.inf:
        with pytest.raises(UnreachableGoalError):
            hmm.most_likely_path(start, goal)
        return
    path = hmm.most_likely_path(start, goal)
    assert path[0] == start and path[-1] == goal
    assert len(set(path)) == len(path)  # a simple path
    assert path_log_prob(C, path, rule) == pytest.approx(best, abs=1e-9)
    assert hmm.plan(start, goal).path_log_prob == pytest.approx(best, abs=1e-9)


def test_path_goes_through_a_bottleneck_and_avoids_a_tempting_dead_end() -> None:
    C = np.zeros((7, 7), dtype=int)
    for a in (0, 1, 2):  # cluster {0, 1, 2}, densely connected
        for b in (0, 1, 2):
            C[a, b] = 10
    for a in (3, 4, 5):  # cluster {3, 4, 5}
        for b in (3, 4, 5):
            C[a, b] = 10
    C[2, 3] = 1  # the only bridge, rare
    C[0, 6] = 50  # likely, but 6 leads nowhere
    hmm = chain_model(C)
    assert hmm.most_likely_path(0, 5) == (0, 2, 3, 5)
    with pytest.raises(UnreachableGoalError, match="category 0 cannot be reached from category 5"):
        hmm.most_likely_path(5, 0)


def test_self_loop_rule_changes_the_chosen_path() -> None:
    # 0 -> 1 -> 3 and 0 -> 2 -> 3; node 1 dwells a lot (self count 9), node 2 also leaks to 4
    C = np.zeros((5, 5), dtype=int)
    C[0, 1] = C[0, 2] = 1
    C[1, 1], C[1, 3] = 9, 1
    C[2, 3] = C[2, 4] = 1
    assert chain_model(C, path_self_loops="drop").most_likely_path(0, 3) == (0, 1, 3)
    assert chain_model(C, path_self_loops="keep").most_likely_path(0, 3) == (0, 2, 3)


def test_changing_the_rule_after_fit_is_picked_up() -> None:
    C = np.zeros((5, 5), dtype=int)
    C[0, 1] = C[0, 2] = 1
    C[1, 1], C[1, 3] = 9, 1
    C[2, 3] = C[2, 4] = 1
    hmm = chain_model(C)
    assert hmm.plan(0, 3).observations == (0, 1, 3)
    hmm.path_self_loops = "keep"
    assert hmm.plan(0, 3).observations == (0, 2, 3)
    hmm.set_params(path_self_loops="drop")
    assert hmm.most_likely_path(0, 3) == (0, 1, 3)


def test_current_equal_to_goal_is_a_one_element_path() -> None:
    hmm = chain_model(np.array([[1, 1], [0, 1]]))
    assert hmm.most_likely_path(1, 1) == (1,)
    plan = hmm.plan(1, 1)
    assert plan.observations == (1,) and plan.path_log_prob == 0.0


def test_deterministic_edges_cost_nothing() -> None:
    hmm = chain_model(np.array([[0, 5, 0], [0, 0, 3], [0, 0, 1]]))
    assert hmm.most_likely_path(0, 2) == (0, 1, 2)
    assert hmm.plan(0, 2).path_log_prob == 0.0


def test_unseen_current_category_cannot_reach_anything() -> None:
    hmm = BehaviorHMM(n_observations=4).fit([0, 0, 0], [0, 1, 2])
    with pytest.raises(UnreachableGoalError, match="3"):
        hmm.most_likely_path(3, 0)


@pytest.mark.parametrize("bad", [-1, 7, 1.0, True, "0"])
def test_out_of_range_categories_are_config_errors(bad: object) -> None:
    hmm = BehaviorHMM().fit([0, 0, 0], [0, 1, 2])
    with pytest.raises(ConfigError):
        hmm.most_likely_path(bad, 0)  # type: ignore[arg-type]
    with pytest.raises(ConfigError):
        hmm.plan(0, bad)  # type: ignore[arg-type]


@settings(max_examples=40, deadline=None)
@given(
    obs=st.lists(st.integers(0, 4), min_size=2, max_size=40),
    smoothing=st.sampled_from([0.0, 0.5]),
    data=st.data(),
)
def test_dropped_self_loops_make_paths_independent_of_the_counting_mode(
    obs: list[int], smoothing: float, data: st.DataObject
) -> None:
    states = [0] * len(obs)
    kw = {"n_observations": 5, "smoothing": smoothing}
    changes = BehaviorHMM(counting="changes", **kw).fit(states, obs)  # type: ignore[arg-type]
    steps = BehaviorHMM(counting="steps", **kw).fit(states, obs)  # type: ignore[arg-type]
    c, g = data.draw(st.integers(0, 4)), data.draw(st.integers(0, 4))
    try:
        expected = changes.plan(c, g).path_log_prob
    except UnreachableGoalError:
        with pytest.raises(UnreachableGoalError):
            steps.plan(c, g)
        return
    assert steps.plan(c, g).path_log_prob == pytest.approx(expected, abs=1e-9)
