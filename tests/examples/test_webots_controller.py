"""The Webots example's readings -> commands logic, driven by the kinematic simulator.

Webots itself is not installed here: the Supervisor's view (position, orientation,
velocity) is built from the simulator's state, as Webots would report it.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from behavior_hmm.models import SBLM
from behavior_hmm.sim import make_env

CONTROLLER = Path(__file__).resolve().parents[2] / "examples" / "webots" / "controllers"
sys.path.insert(0, str(CONTROLLER / "behavior_hmm_controller"))

from webots_logic import WebotsBehavior, sensor_reading  # noqa: E402


def supervisor_view(env: Any) -> dict[str, Any]:
    """What Webots' Supervisor would report of the simulated robot and object."""
    x, y, yaw, vx, vy, wz, _, _ = env.unwrapped.sim.state()
    c, s = math.cos(yaw), math.sin(yaw)
    return {
        "robot_position": [x, y, 0.02],
        "robot_orientation": [c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0],
        "robot_velocity": [vx, vy, 0.0, 0.0, 0.0, wz],
        "object_position": [0.0, 0.0, 0.05],
    }


def reading(env: Any) -> np.ndarray:
    params = env.unwrapped.params
    return sensor_reading(
        **supervisor_view(env),
        body_radius=params.body_radius,
        object_radius=params.object_radius,
    )


@pytest.mark.parametrize("start", [(120.0, 0.5), (-170.0, 0.3), (30.0, 0.8), (180.0, 0.1)])
def test_supervisor_readings_match_the_sensors(start: tuple[float, float]) -> None:
    env = make_env("kinematic")
    _, info = env.reset(options={"angle": start[0], "distance": start[1]})
    np.testing.assert_allclose(reading(env), info["true_observation"], atol=1e-9)
    for command in ([2.0, 4.0], [-3.0, 3.0], [5.0, 5.0]):
        for _ in range(10):
            _, _, _, _, info = env.step(np.array(command))
        ours, theirs = reading(env), info["true_observation"]
        np.testing.assert_allclose(ours[[0, 1, 3]], theirs[[0, 1, 3]], atol=1e-9)
        diff = (ours[2] - theirs[2] + 180.0) % 360.0 - 180.0
        assert abs(diff) < 1e-9


@pytest.mark.parametrize("basic_time_step_ms", [16, 8])
def test_the_controller_turns_to_the_goal_and_stops(
    turn_model: SBLM, basic_time_step_ms: int
) -> None:
    env = make_env("kinematic")
    env.reset(options={"angle": 100.0, "distance": 0.5})
    behavior = WebotsBehavior(
        turn_model, {"angle": 0.0}, basic_time_step_ms=basic_time_step_ms, max_wheel_speed=10.0
    )
    every = 16 // basic_time_step_ms
    commands = []
    done = None
    for k in range(4000 * every):
        command = behavior.step(reading(env))
        commands.append((command.left, command.right))
        if command.done:
            done = command
            break
        if k % every == every - 1:  # the simulator advances one 16 ms control period
            env.step(np.array([command.left, command.right]))
    assert done is not None and done.reason == "goal"
    assert (done.left, done.right) == (0.0, 0.0)
    assert abs(reading(env)[2]) <= 3.0
    # held between decisions: each control period's command repeats `every` times
    if every > 1:
        pairs = commands[: (len(commands) // every) * every]
        assert all(pairs[i] == pairs[i - i % every] for i in range(len(pairs)))
    # stopped for good
    assert behavior.step(reading(env)) == done


def test_commands_are_clipped_and_faults_stop(turn_model: SBLM) -> None:
    env = make_env("kinematic")
    env.reset(options={"angle": 150.0, "distance": 0.5})
    behavior = WebotsBehavior(turn_model, None, max_wheel_speed=0.5)
    for _ in range(30):
        command = behavior.step(reading(env))
        assert abs(command.left) <= 0.5 and abs(command.right) <= 0.5
        env.step(np.array([command.left, command.right]))
    bad = reading(env)
    bad[2] = np.nan
    stop = behavior.step(bad)
    assert stop.done and stop.reason == "sensor_fault" and (stop.left, stop.right) == (0, 0)


def test_a_basic_time_step_that_does_not_divide_16_ms_is_refused(turn_model: SBLM) -> None:
    with pytest.raises(ValueError, match="basicTimeStep"):
        WebotsBehavior(turn_model, None, basic_time_step_ms=10)
