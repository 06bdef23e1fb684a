"""Figure data of the simple experiment: every test start, and the thesis's figure starts."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from behavior_hmm import teach
from behavior_hmm.data import SENSOR_CHANNELS
from behavior_hmm.evaluate._experiments import FIGURE_STARTS, _figure_series


def test_figure_starts_are_the_thesis_starts_and_not_test_starts() -> None:
    assert FIGURE_STARTS["turn"] == ({"angle": 100.0}, {"angle": -100.0})  # fig 6.8
    assert FIGURE_STARTS["approach"] == ({"distance": 0.7}, {"distance": 0.35})  # fig 6.9
    for behavior, starts in FIGURE_STARTS.items():
        channel = "angle" if behavior == "turn" else "distance"
        tests = {round(s[channel], 6) for s in teach.test_starts(behavior)}
        assert not {round(s[channel], 6) for s in starts} & tests


def test_figure_series_keeps_the_steered_channel_of_every_run() -> None:
    j = SENSOR_CHANNELS.index("distance")
    traces, cases = [], []
    for k, d in enumerate((0.3, 0.6, 0.9)):
        readings = np.zeros((20 + k, len(SENSOR_CHANNELS)))
        readings[:, j] = np.linspace(d, 0.0, 20 + k)
        trace = SimpleNamespace(start={"angle": 0.0, "distance": d}, reading_array=readings)
        demo = {"distance": np.linspace(d, 0.0, 25), "angle": np.zeros(25)}
        traces.append((trace, demo))
        cases.append({"success_rate": 90.0 + k, "goal_reached": k != 1})
    series = _figure_series({"model": traces}, "approach", ("distance", "angle"), cases)
    assert series["channel"] == "distance" and series["inputs"] == ["distance", "angle"]
    assert [r["start"]["distance"] for r in series["runs"]] == [0.3, 0.6, 0.9]
    run = series["runs"][2]
    assert run["generated"].shape == (22,) and run["generated"][0] == 0.9
    assert run["demonstrated"].shape == (25,) and run["success_rate"] == 92.0
    assert [r["goal_reached"] for r in series["runs"]] == [True, False, True]
    with pytest.raises(ValueError):  # one case per trace
        _figure_series({"model": traces}, "approach", ("distance",), cases[:2])


@pytest.mark.slow
def test_simple_experiment_draws_every_test_start_and_the_thesis_starts(tmp_path: Path) -> None:
    from behavior_hmm.evaluate._experiments import run_simple_experiment
    from behavior_hmm.viz import write_simple_report

    results = run_simple_experiment(
        sim="kinematic", configs=(("turn", ("angle",), 90.9),), sblm_params={"epochs": 40}
    )
    grid = results["figures"]["test_starts"]
    assert len(grid) == 1 and len(grid[0]["runs"]) == 15
    assert [r["start"]["angle"] for r in grid[0]["runs"]] == [
        s["angle"] for s in teach.test_starts("turn")
    ]
    thesis = results["figures"]["thesis_starts"][0]
    assert [r["start"]["angle"] for r in thesis["runs"]] == [100.0, -100.0]
    for run in thesis["runs"]:
        # the teacher's demonstration from that start, and the model's run, both reach 0 deg
        assert run["demonstrated"][0] == pytest.approx(run["start"]["angle"], abs=0.5)
        assert abs(run["demonstrated"][-1]) < 3.0
        assert abs(run["generated"][-1]) < 3.0 and run["goal_reached"]
    assert [(f["start"]["angle"], f["inputs"]) for f in results["figure_starts"]] == [
        (100.0, ["angle"]),
        (-100.0, ["angle"]),
    ]
    write_simple_report(results, tmp_path)
    for name in ("turn_test_starts.png", "turn_generated_vs_demonstrated.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "figure_starts" in (tmp_path / "results.json").read_text()


@pytest.mark.slow
def test_an_auto_inputs_row_scores_the_channels_the_demonstrations_choose() -> None:
    from behavior_hmm.evaluate._experiments import AUTO_CONFIGS, run_simple_experiment
    from behavior_hmm.viz._reports import simple_table

    configs = (("turn", ("angle", "angular_velocity"), 84.2), AUTO_CONFIGS[0])
    results = run_simple_experiment(sim="kinematic", configs=configs, sblm_params={"epochs": 40})
    hand, auto = results["rows"]
    assert "chosen" not in hand
    assert auto["chosen"] and auto["inputs"] == ["angle"]  # the wheels' echo is left out
    assert "angular_velocity" in auto["reason"]
    assert auto["thesis"] != auto["thesis"]  # NaN: the thesis picked its inputs by hand
    assert auto["zero_floor"] < auto["sblm"] and auto["n"] == 15
    table = simple_table(results)
    assert (
        "| turn | auto → angle | — |" in table
        and "| turn | angle, angular_velocity | 84.2 |" in table
    )
    # the figures draw each input set once: the auto row repeats a hand-picked one
    assert len(results["figures"]["test_starts"]) == 1
