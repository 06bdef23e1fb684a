"""The CobART benchmark runs and reports its figures (values are not checked: no timings)."""

from __future__ import annotations

import numpy as np

from behavior_hmm.benchmarks.cobart import run, synthetic_turn_episodes


def test_synthetic_turns_are_normalized_filtered_episodes() -> None:
    x, lengths = synthetic_turn_episodes(channels=("angle", "angular_velocity"))
    assert len(lengths) == 36 and x.shape == (lengths.sum(), 2)
    assert np.all(np.abs(x) <= 1.0 + 1e-9)
    starts = np.cumsum(lengths) - lengths
    np.testing.assert_allclose(x[starts[0], 0], -1.0)  # -180 deg
    np.testing.assert_allclose(x[np.cumsum(lengths) - 1, 0], 0.0, atol=0.02)  # ends at 0 deg
    assert np.abs(np.diff(x[: lengths[0], 0])).max() < 0.01  # ~0.005 per 16 ms step


def test_run_reports_the_issue_figures() -> None:
    x, lengths = synthetic_turn_episodes(
        starts_deg=[-90, -40, 30, 120], channels=("angle", "angular_velocity")
    )
    out = run(quick=True, data=(x, lengths))
    for key in ("windows_per_s", "predict_us_median", "predict_us_p99", "predict_us_median_2ch"):
        assert out[key] > 0
    assert out["n_windows"] == len(x)
