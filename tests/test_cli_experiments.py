"""The thesis experiments run from the command line (kinematic robot; slow)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from behavior_hmm.cli import app

runner = CliRunner()
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_experiment_categorization(tmp_path: Path) -> None:
    res = runner.invoke(app, ["experiment", "categorization", "--sim", "kinematic", "-o", tmp_path])
    assert res.exit_code == 0, res.output
    summary = json.loads((tmp_path / "categorization.json").read_text())
    runs = {run["rho"]: run for run in summary["runs"]}
    # a higher vigilance gives finer primitives, and the table 6.1 starts get sequences
    assert runs[0.85]["n_primitives"] > runs[0.75]["n_primitives"]
    assert len(runs[0.85]["sequences"]) == 4
    assert runs[0.85]["same_direction_share_tail"]
    for name in ("categories_rho085", "transitions_rho075"):
        assert (tmp_path / f"{name}.png").read_bytes()[:8] == PNG


@pytest.mark.slow
def test_experiment_generators(tmp_path: Path) -> None:
    res = runner.invoke(
        app, ["experiment", "generators", "--sim", "kinematic", "--epochs", "3", "-o", tmp_path]
    )
    assert res.exit_code == 0, res.output
    assert "momentum sweep" in res.output
    for sweep in ("learning_rate", "momentum", "hidden"):
        assert (tmp_path / f"generator_sweep_{sweep}.png").read_bytes()[:8] == PNG


@pytest.mark.slow
def test_experiment_simple_beats_the_thesis_on_the_kinematic_robot(tmp_path: Path) -> None:
    # both cores: the test session's default is one process (tests/conftest.py)
    args = ["experiment", "simple", "--sim", "kinematic", "--workers", "2", "-o", tmp_path]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    results = json.loads((tmp_path / "results.json").read_text())
    rows = results["rows"]
    assert len(rows) == 5
    missed = []
    for row, evaluation in zip(rows, results["evaluations"], strict=True):
        assert row["sblm"] > row["thesis"], row
        assert row["sblm"] > row["zero_floor"] + 30, row
        missed += [c for c in evaluation["cases"] if not c["goal_reached"]]
    # Every goal but one: with the rate limit, turn on {angle, angular velocity} from -38 deg
    # stops 3.03 deg off (filter lag at the 3 deg edge; docs/results.md). No other miss,
    # and that one within 0.1 deg of the tolerance.
    assert len(missed) <= 1, missed
    for case in missed:
        assert abs(case["final_angle_error_deg"]) <= 3.1, case
