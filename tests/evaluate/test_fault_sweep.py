"""experiment faults: the NaN dropout wrapper, the fault sweep and its command."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from behavior_hmm.cli import app
from behavior_hmm.data import SENSOR_CHANNELS
from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate import evaluate_model
from behavior_hmm.evaluate._faults import FAULTS, NaNDropout, evaluate_fault, run_faults
from behavior_hmm.models import SBLM
from behavior_hmm.sim import make_env
from behavior_hmm.teach import test_starts as starts_of
from behavior_hmm.viz._faults import faults_markdown, write_faults_report

_ANGLE = SENSOR_CHANNELS.index("angle")


def _cli_testing() -> Any:
    """tests/cli/cli_testing.py (a helper module, not a package)."""
    path = Path(__file__).resolve().parents[1] / "cli" / "cli_testing.py"
    spec = importlib.util.spec_from_file_location("_faults_cli_testing", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _nan_readings(env: NaNDropout, n_steps: int, seed: int) -> list[int]:
    """Readings (0 = reset's) that came back NaN on the angle, over one episode."""
    obs, _ = env.reset(seed=seed, options={"angle": 90.0})
    seen = [0] if np.isnan(obs[_ANGLE]) else []
    for k in range(1, n_steps + 1):
        obs, *_ = env.step(np.array([0.5, -0.5]))
        others = np.delete(obs, _ANGLE)
        assert np.isfinite(others).all()  # only the chosen channel is touched
        if np.isnan(obs[_ANGLE]):
            seen.append(k)
    return seen


def test_single_and_burst_dropouts_hit_exactly_the_scheduled_readings() -> None:
    env = NaNDropout(make_env("kinematic"), "angle", steps=[7])
    assert _nan_readings(env, 40, seed=0) == [7]
    assert env.injected == [7]
    env.schedule(range(12, 17))  # a 5-step burst
    assert _nan_readings(env, 40, seed=0) == [12, 13, 14, 15, 16]
    assert env.episodes == [[7], [12, 13, 14, 15, 16]]
    # a scheduled reading past the end of the run is never injected
    env.schedule([100])
    assert _nan_readings(env, 40, seed=0) == []
    assert env.episodes[-1] == []


def test_random_dropouts_are_seeded_and_spare_the_first_reading() -> None:
    env = NaNDropout(make_env("kinematic"), "angle", fraction=0.1, seed=3)
    first = _nan_readings(env, 1000, seed=5)
    assert first == env.injected
    assert 0 not in first
    assert 60 <= len(first) <= 140  # 10 % of 1000 readings
    assert _nan_readings(env, 1000, seed=5) == first  # same seeds, same readings
    assert _nan_readings(env, 1000, seed=6) != first
    other = NaNDropout(make_env("kinematic"), "angle", fraction=0.1, seed=4)
    assert _nan_readings(other, 1000, seed=5) != first


def test_dropout_refuses_bad_arguments() -> None:
    with pytest.raises(ConfigError, match="unknown channel"):
        NaNDropout(make_env("kinematic"), "heading")
    with pytest.raises(ConfigError, match="fraction"):
        NaNDropout(make_env("kinematic"), "angle", fraction=1.5)
    with pytest.raises(ConfigError, match="steps"):
        NaNDropout(make_env("kinematic"), "angle", steps=[-1])


def test_no_fault_cells_equal_a_plain_evaluation(turn_model: SBLM) -> None:
    starts = starts_of("turn")[:3]
    plain = evaluate_model(turn_model, starts, sim="kinematic", seed=2)
    # noise 0 is a plain evaluation; a robot built with the default wheel mismatch
    # (0.01) and run through evaluate_model(env=...) must give the same runs
    for kind, level in (("noise", 0.0), ("wheel_mismatch", 0.01), ("motor_lag", 0.03)):
        cell = evaluate_fault(turn_model, starts, kind, level, sim="kinematic", seed=2)
        assert cell["goal_reached"] == plain["goal_reached"], kind
        assert cell["success_rate_mean"] == plain["success_rate_mean"], kind
        assert [c["steps"] for c in cell["cases"]] == [c["steps"] for c in plain["cases"]]


def test_a_burst_longer_than_the_hold_stops_the_robot(turn_model: SBLM) -> None:
    starts = starts_of("turn")[:2]
    cell = evaluate_fault(
        turn_model, starts, "dropout", "burst10", sim="kinematic", channel="angle"
    )
    assert cell["reasons"] == {"sensor_fault": 2}
    assert cell["goal_reached"] == 0
    assert cell["applied"] == 2
    held = evaluate_fault(turn_model, starts, "dropout", "burst5", sim="kinematic", channel="angle")
    assert "sensor_fault" not in held["reasons"]


def test_sweep_structure_table_and_figures(tmp_path: Path) -> None:
    results = run_faults(
        sim="kinematic",
        tasks=["turn"],
        faults=["noise", "push_bearing"],
        levels={"noise": [0.0, 0.02], "push_bearing": [0.5]},
        n_starts=2,
    )
    assert [f["kind"] for f in results["faults"]] == ["noise", "push_bearing"]
    (entry,) = results["tasks"]
    assert entry["task"] == "turn" and entry["inputs"] == ["angle"]
    assert entry["baseline"]["n"] == 2
    cells = entry["cells"]
    assert [(c["fault"], c["level"]) for c in cells] == [
        ("noise", 0.0),
        ("noise", 0.02),
        ("push_bearing", 0.5),
    ]
    assert cells[0]["goal_reached"] == entry["baseline"]["goal_reached"]
    assert cells[0]["success_rate_mean"] == entry["baseline"]["success_rate_mean"]
    assert cells[2]["applied"] is not None and len(cells[2]["cases"]) == 2
    table = faults_markdown(results)
    assert "push +30° bearing" in table and "| 50 % |" in table
    write_faults_report(results, tmp_path)
    for name in ("results.json", "table.md", "faults_goal.png", "faults_success.png"):
        assert (tmp_path / name).stat().st_size > 0
    assert json.loads((tmp_path / "results.json").read_text())["sim"] == "kinematic"


def test_a_sweep_with_an_option_runs_its_row_and_says_so() -> None:
    results = run_faults(
        sim="kinematic",
        tasks=["turn"],
        faults=["wheel_mismatch"],
        levels={"wheel_mismatch": [0.4]},
        n_starts=3,
        options=("recover",),
    )
    assert results["preset"] == "default + recover"
    assert "default + recover preset" in faults_markdown(results)


def test_a_sweep_without_a_departure_runs_the_thesis_value_and_says_so() -> None:
    # approach under a 0.4 wheel mismatch: the default preset calibrates the wheels and
    # reaches its goals; without that departure the robot curves off on some starts
    common: dict[str, Any] = {
        "sim": "kinematic",
        "tasks": ["approach"],
        "faults": ["wheel_mismatch"],
        "levels": {"wheel_mismatch": [0.4]},
        "n_starts": 5,
    }
    plain = run_faults(**common, without=("wheel_calibration",))
    calibrated = run_faults(**common)
    assert plain["preset"] == "default − wheel_calibration"
    assert "default − wheel_calibration preset" in faults_markdown(plain)
    assert calibrated["preset"] == "default"
    (worse,) = plain["tasks"][0]["cells"]
    (better,) = calibrated["tasks"][0]["cells"]
    assert better["goal_reached"] == 5
    assert better["success_rate_mean"] > worse["success_rate_mean"] + 5.0
    with pytest.raises(ConfigError, match="unknown departure 'wheel'"):
        run_faults(**common, without=("wheel",))


def test_every_fault_kind_has_levels() -> None:
    names = [k.name for k in FAULTS]
    assert names == [
        "noise",
        "wheel_mismatch",
        "motor_lag",
        "speed_limit",
        "push_bearing",
        "push_distance",
        "dropout",
    ]
    assert all(k.levels for k in FAULTS)


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--task", "spin"], "spin"),
        (["--fault", "gremlins"], "gremlins"),
        (["--option", "calibrate"], "calibrate"),
        (["--level", "gremlins=1"], "gremlins"),
        (["--level", "noise"], "KIND=VALUE"),
        (["--level", "noise=loud"], "the noise level must be a number, got 'loud'"),
        (["--level", "noise=-0.01"], "the noise level must be >= 0"),
        (["--level", "motor_lag=0"], "motor_time_constant must be > 0"),
        (["--level", "speed_limit=inf"], "must be finite"),
        (["--level", "push_bearing=1.5"], "in (0, 1), got 1.5"),
        (["--level", "dropout=burst7"], "unknown dropout level 'burst7'"),
    ],
)
def test_command_refuses_unknown_task_or_fault(
    args: list[str], needle: str, tmp_path: Path
) -> None:
    result = CliRunner().invoke(
        app, ["experiment", "faults", "--sim", "kinematic", "-o", str(tmp_path / "f"), *args]
    )
    _cli_testing().assert_user_error(result, needle)
    assert not (tmp_path / "f").exists()


def test_command_runs_the_levels_asked_for(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # levels between the sweep's (issue 27: "fault levels you have not seen")
    from behavior_hmm.evaluate import _faults

    seen: dict[str, Any] = {}

    def first_start(**kwargs: Any) -> dict[str, Any]:
        seen.update(kwargs)
        return run_faults(**kwargs, n_starts=1)

    monkeypatch.setattr(_faults, "run_faults", first_start)
    out = tmp_path / "f"
    args = ["experiment", "faults", "--sim", "kinematic", "--task", "turn", "--workers", "1"]
    args += ["--fault", "noise", "--level", "motor_lag=0.25", "--level", "noise=0.015"]
    result = CliRunner().invoke(app, [*args, "--level", "dropout=burst5", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert seen["faults"] == ["noise", "motor_lag", "dropout"]
    assert seen["levels"] == {"motor_lag": [0.25], "noise": [0.015], "dropout": ["burst5"]}
    cells = json.loads((out / "results.json").read_text())["tasks"][0]["cells"]
    assert [(c["fault"], c["level"]) for c in cells] == [
        ("noise", 0.015),
        ("motor_lag", 0.25),
        ("dropout", "burst5"),
    ]
