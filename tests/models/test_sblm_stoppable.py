"""A goal the demonstrations only passed through is refused before any motion."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from behavior_hmm.cli import app
from behavior_hmm.errors import UnreachableGoalError
from behavior_hmm.models import SBLM


def test_stops_are_the_demonstrations_final_readings(turn_model: SBLM) -> None:
    assert turn_model.stops_.shape[1] == 1
    assert np.all(np.abs(turn_model.stops_[:, 0]) <= 3.0)


@pytest.mark.parametrize("goal", [90.0, 45.0, -120.0])
def test_a_pass_through_goal_is_refused_before_motion(
    turn_model: SBLM, kinematic_env: Any, goal: float
) -> None:
    t0 = time.perf_counter()
    with pytest.raises(UnreachableGoalError, match=r"stops only where its demonstrations stopped"):
        turn_model.generate(kinematic_env, start={"angle": 120.0}, goal={"angle": goal})
    assert time.perf_counter() - t0 < 1.0
    assert kinematic_env.unwrapped.elapsed_steps == 0


@pytest.mark.parametrize("goal", [0.0, 2.0, -4.0])
def test_goals_where_demonstrations_stopped_are_accepted(turn_model: SBLM, goal: float) -> None:
    turn_model.check_stoppable({"angle": goal})


def test_stops_survive_save_and_load(turn_model: SBLM, tmp_path: Path) -> None:
    turn_model.save(tmp_path / "t.bhmm")
    loaded = SBLM.load(tmp_path / "t.bhmm")
    assert np.array_equal(loaded.stops_, turn_model.stops_)
    with pytest.raises(UnreachableGoalError):
        loaded.check_stoppable({"angle": 60.0})


def test_generate_refuses_a_pass_through_goal_naming_the_reachable_ones(
    turn_model: SBLM, tmp_path: Path
) -> None:
    turn_model.save(tmp_path / "t.bhmm")
    t0 = time.perf_counter()
    result = CliRunner().invoke(
        app,
        ["generate", str(tmp_path / "t.bhmm"), "--start", "angle=120", "--goal", "angle=45",
         "--sim", "kinematic"],
    )  # fmt: skip
    assert time.perf_counter() - t0 < 2.0
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert "goal angle 45 deg" in lines[0] and "stops only where" in lines[0]
