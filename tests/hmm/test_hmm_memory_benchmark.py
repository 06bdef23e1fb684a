"""``behavior-hmm bench memory``: the synthetic Behavior-HMMs it scales to are shaped like
trained ones, and its probes report what they say (values, not timings, are checked)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import behavior_hmm.benchmarks.memory as bench
from behavior_hmm.cobart import _index


def test_synthetic_walks_end_at_the_goal_one_level_per_step() -> None:
    cats, lengths = bench.synthetic_walks(5_000, 7, np.random.default_rng(0))
    assert lengths.tolist() == [bench.LEVELS] * 7 and cats.size == lengths.sum()
    walks = cats.reshape(7, bench.LEVELS)
    assert (walks[:, -1] == 0).all() and (walks[:, :-1] > 0).all()
    lanes = 5_000 // bench.LEVELS
    level = (walks[:, :-1] - 1) // lanes + 1
    assert (np.diff(level, axis=1) == -1).all()  # one level closer every step
    assert cats.max() < 5_000


def test_synthetic_hmm_is_sparse_and_every_walk_can_plan_to_the_goal() -> None:
    hmm = bench.synthetic_hmm(20_000, 300)
    assert (hmm.n_observations_, hmm.n_states_) == (20_000, 300)
    assert hmm.C_counts_.nnz < 5 * 20_000  # a few successors a category, not M²
    assert hmm.B_counts_.nnz < 2 * 20_000  # a category is emitted by one or two states
    assert np.count_nonzero(hmm.A_counts_) < 10 * 300
    cats, _ = bench.synthetic_walks(20_000, 20, np.random.default_rng(5))
    # held-out walks start in any lane; most of them were demonstrated
    starts = [c for c in cats[:: bench.LEVELS].tolist() if hmm.can_plan(c, 0)]
    assert len(starts) >= 10
    for start in starts:
        plan = hmm.plan(start, 0)
        assert plan.observations[0] == start and plan.goal == 0
        assert len(plan.observations) == bench.LEVELS and np.isfinite(plan.log_prob)


def test_scaling_probe_loads_the_file_and_times_every_cycle(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setattr(bench, "SIZES", ((2_000, 20),))
    monkeypatch.setattr(bench, "WALKS", 2)
    (row,) = bench._scaling(quick=False, folder=tmp_path)
    assert row["observation_categories"] == 2_000 and row["states"] == 20
    assert row["steps_timed"] == 2 * (bench.LEVELS * bench.HOLD_CYCLES - 1)
    assert 0 < row["step_us_median"] <= row["step_us_p99"] <= row["step_us_max"]
    assert row["load_s"] > 0 and row["peak_mb"] >= row["load_peak_above_imports_mb"] >= 0
    assert row["dense_c_would_be_mb"] == 2_000**2 * 8 / 1e6
    assert row["file_mb"] < row["dense_c_would_be_mb"]


def test_scaling_probe_categorizes_a_reading_every_cycle_with_prototypes(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, turn_model: Any
) -> None:
    monkeypatch.setattr(bench, "SIZES", ((2_000, 20),))
    monkeypatch.setattr(bench, "WALKS", 2)
    (row,) = bench._scaling(quick=False, folder=tmp_path, obs=turn_model.observations_)
    assert row["categorizer_build_s"] > 0
    assert 0 < row["control_step_us_median"] <= row["control_step_us_p99"]
    assert row["control_step_us_p99"] <= row["control_step_us_max"]
    # the cycle is the categorization and the HMM calls: never less than the calls alone
    assert row["control_step_us_median"] > row["step_us_median"]


def test_drawn_prototypes_are_near_copies_of_the_models(turn_model: Any) -> None:
    obs = turn_model.observations_
    net = bench.drawn_prototypes(obs, 500)
    assert net.n_categories_ == 500 and net.get_params() == obs.get_params()
    gap = np.abs(net.prototypes_[:, None] - obs.prototypes_[None]).max(axis=(2, 3)).min(axis=1)
    assert gap.max() < 0.06  # every drawn window within a few σ of one of the model's


def test_child_peak_is_measured_in_a_process_of_its_own() -> None:
    peak, wall = bench._child_peak_mb(["--version"])
    assert peak > 10 and wall > 0


def test_live_match_times_the_categorization_at_each_size(
    monkeypatch: pytest.MonkeyPatch, turn_model: Any
) -> None:
    monkeypatch.setattr(_index, "INDEX_MIN_CATEGORIES", 400)
    rows = bench.live_match(turn_model, sizes=(50, 400))
    assert [r["observation_categories"] for r in rows] == [50, 400]
    assert all(0 < r["update_us_median"] <= r["update_us_p99"] for r in rows)
    assert [r["indexed"] for r in rows] == [False, True]
    assert [r["search"] for r in rows] == ["screen", "index"]
    assert rows[0]["scored_median"] == 50 and 0 < rows[1]["scored_median"] < 400


def test_live_match_says_where_the_compiled_tree_was_searched(
    monkeypatch: pytest.MonkeyPatch, turn_model: Any
) -> None:
    pytest.importorskip("numba", reason="numba is not installed (the 'fast' extra)")
    from behavior_hmm.cobart import _compiled, _live

    monkeypatch.setattr(_live, "LIVE_COMPILED_MIN", 40)
    previous = _compiled.set_kernel("numba")
    try:
        rows = bench.live_match(turn_model, sizes=(30, 50))
    finally:
        _compiled.set_kernel(previous)
    assert [r["search"] for r in rows] == ["screen", "tree"]
    assert rows[0]["scored_median"] == 30 and rows[1]["scored_median"] is None


def test_plot_memory_draws_every_size(tmp_path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    from behavior_hmm.benchmarks._plot import plot_memory

    def row(m: int, n: int) -> dict[str, Any]:
        return {
            "observation_categories": m,
            "states": n,
            "load_s": m / 1e6,
            "load_peak_above_imports_mb": m / 1e4,
            "dense_c_would_be_mb": m * m * 8 / 1e6,
            "step_us_median": 10.0,
            "step_us_p99": 50.0 + m / 1e3,
            "step_us_max": 900.0,
        }

    path = plot_memory({"scaling": [row(1_000, 50), row(100_000, 2_000)]}, tmp_path)
    assert path == tmp_path / "memory_scaling.png"
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000
