"""``behavior-hmm bench plan`` times plans that reach their goal, on tiny sizes (values are
not checked: no timings)."""

from __future__ import annotations

import numpy as np

from behavior_hmm.benchmarks.plan import _demonstrations, run


def test_the_synthetic_episodes_drift_down_to_the_goal_category() -> None:
    states, observations, lengths = _demonstrations(40, 8, np.random.default_rng(0))
    assert sum(lengths) == len(states) == len(observations)
    ends = np.cumsum(lengths) - 1
    assert np.all(observations[ends] == 0)  # every episode ends at the goal category
    starts = np.r_[0, ends[:-1] + 1]
    for a, b in zip(starts, ends + 1, strict=True):
        steps = np.diff(observations[a:b])
        assert np.all((steps <= 0) & (steps >= -2))  # stays, moves one down or skips one
    assert np.array_equal(states, observations * 8 // 40)  # the chain's bands


def test_bench_plan_plans_from_every_visited_category_to_the_goal() -> None:
    results = run(quick=True, sizes=((30, 5), (60, 30)))
    assert results["repeats"] == 2
    for row, (m, n) in zip(results["sizes"], ((30, 5), (60, 30)), strict=True):
        assert (row["n_observations"], row["n_states"]) == (m, n)
        assert row["reached"] is True
        assert 0 < row["plans"] < m
        assert 2 <= row["path_length_median"] <= row["path_length_max"] <= m
        for key in ("new_goal_ms_median", "new_pair_us_median", "repeated_pair_us_median"):
            assert row[key] > 0
        assert row["path_us_median"] > 0
