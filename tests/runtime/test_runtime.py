from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest

from behavior_hmm.data import ANGLE_TOLERANCE_DEG, SENSOR_CHANNELS
from behavior_hmm.errors import UnreachableGoalError
from behavior_hmm.models import SBLM
from behavior_hmm.models import perform as run_behavior

ANGLE = SENSOR_CHANNELS.index("angle")


def test_generation_reaches_goal_and_ends_stopped(turn_model: SBLM, kinematic_env: Any) -> None:
    trace = turn_model.generate(kinematic_env, start={"angle": 90.0, "distance": 0.5}, seed=0)
    assert trace.reason in ("goal", "step_limit")
    # the robot turned toward the object: the bearing shrank a lot
    assert abs(trace.final_observation[ANGLE]) < 45.0
    if trace.goal_reached:
        assert abs(trace.final_observation[ANGLE]) <= ANGLE_TOLERANCE_DEG
        assert np.all(trace.command_array[-1] == 0.0)
    # the trace records every step's observation, primitive and command
    n = len(trace)
    assert len(trace.observation) == len(trace.state) == len(trace.commands) == n
    assert all(s >= 0 for s in trace.state[:-1])


def test_step_limit_stops_the_robot(turn_model: SBLM, kinematic_env: Any) -> None:
    trace = run_behavior(
        turn_model, kinematic_env, start={"angle": 150.0, "distance": 0.5}, max_steps=5
    )
    assert trace.reason == "step_limit"
    assert not trace.goal_reached
    # after the final stop command the wheels come to rest
    speeds = (
        kinematic_env.unwrapped.sim.wheel_speeds
        if hasattr(kinematic_env.unwrapped.sim, "wheel_speeds")
        else None
    )
    assert len(trace) == 5
    assert speeds is None or np.all(np.isfinite(speeds))


def test_unreachable_goal_raises_before_any_motion(turn_model: SBLM, kinematic_env: Any) -> None:
    # Turning from -90 deg never passes +120 deg in the demonstrations: no path leads there.
    with pytest.raises(UnreachableGoalError):
        turn_model.generate(
            kinematic_env, start={"angle": -90.0, "distance": 0.5}, goal={"angle": 120.0}
        )
    assert kinematic_env.unwrapped.elapsed_steps == 0


def test_trace_written_as_parquet(turn_model: SBLM, kinematic_env: Any, tmp_path: Path) -> None:
    trace = turn_model.generate(kinematic_env, start={"angle": -40.0, "distance": 0.5}, seed=0)
    path = tmp_path / "trace.parquet"
    trace.write(path)
    table = pq.read_table(path)
    assert table.num_rows == len(trace)
    assert {"t", "angle", "left", "right", "observation", "state", "plan_changed"} <= set(
        table.column_names
    )


def test_push_mid_run_is_recovered(turn_model: SBLM, kinematic_env: Any) -> None:
    start = {"angle": 60.0, "distance": 0.5}
    pushed = turn_model.generate(
        kinematic_env, start=start, seed=0, pushes=[{"step": 60, "angle": 40.0}]
    )
    plain = turn_model.generate(kinematic_env, start=start, seed=0)
    # the push sends the bearing up by 40 deg; the controller keeps turning toward the object
    assert (
        len(pushed) != len(plain) or pushed.command_array.tolist() != plain.command_array.tolist()
    )
    assert abs(pushed.final_observation[ANGLE]) < 45.0
