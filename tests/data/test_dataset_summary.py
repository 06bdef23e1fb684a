"""summarize(): the numbers behind ``behavior-hmm inspect``."""

from __future__ import annotations

import json

import pytest

from behavior_hmm.data import Dataset, summarize


def test_summary_numbers(small_ds: Dataset) -> None:
    s = summarize(small_ds)
    assert s["episodes"] == 4 and s["samples"] == 300
    assert s["samples_per_episode"] == {"min": 60.0, "median": 75.0, "max": 90.0}
    durations = [ep.t[-1] - ep.t[0] for ep in small_ds.episodes()]
    assert s["duration_s"]["min"] == pytest.approx(min(durations))
    assert s["duration_s"]["max"] == pytest.approx(max(durations))
    assert s["sample_period_s"] == pytest.approx(3.0 / 75, rel=0.2)
    assert s["channels"]["angle"] == {"unit": "deg", "min": -170.0, "max": 150.0}
    assert set(s["channels"]) == {
        "distance",
        "linear_velocity",
        "angle",
        "angular_velocity",
        "left",
        "right",
    }
    assert s["behaviors"] == []
    assert s["metadata"]["behavior"] == "turn_approach"
    json.dumps(s, allow_nan=False)  # JSON-ready


def test_summary_of_complex_and_single_sample_data(complex_ds: Dataset, episode_factory) -> None:
    assert summarize(complex_ds)["behaviors"] == ["approach", "turn"]
    one = Dataset.from_episodes([{k: v[:1] for k, v in episode_factory(n=5).items()}])
    s = summarize(one)
    assert s["sample_period_s"] is None and s["duration_s"]["max"] == 0.0
