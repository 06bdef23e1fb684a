"""The Khepera with a gripper (behavior_hmm/KheperaGripper-v0): contract, physics, options."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import behavior_hmm  # noqa: F401 - registers the ids
from behavior_hmm.data._channels import ARM_UP_DEG, FINGERS_CLOSED_M, FINGERS_OPEN_M
from behavior_hmm.errors import ConfigError
from behavior_hmm.runtime import Robot
from behavior_hmm.sim import GRIPPER_ENV_ID, KheperaGripperEnv


def _values(obs: dict[str, np.ndarray]) -> dict[str, float]:
    return {c: float(v[0]) for c, v in obs.items()}


def _drive(env: Any, command: list[float], steps: int) -> tuple[dict[str, float], dict[str, Any]]:
    obs: dict[str, np.ndarray] = {}
    info: dict[str, Any] = {}
    for _ in range(steps):
        obs, _, _, _, info = env.step(np.array(command, dtype=np.float64))
    return _values(obs), info


def _grasp(env: Any) -> tuple[dict[str, float], dict[str, Any]]:
    """The Webots controller's sequence: open, arm down, close, arm up (speed commands)."""
    _drive(env, [0, 0, 0, 0.02], 80)
    _drive(env, [0, 0, -60, 0], 100)
    _drive(env, [0, 0, 0, -0.02], 80)
    return _drive(env, [0, 0, 60, 0], 100)


def test_registered_id_meets_gymnasium_and_the_robot_contract() -> None:
    env = gym.make(GRIPPER_ENV_ID)
    check_env(env.unwrapped, skip_render_check=True)
    robot = Robot(env)
    assert robot.channels == (
        "distance",
        "linear_velocity",
        "angle",
        "angular_velocity",
        "arm",
        "fingers",
        "object_present",
    )
    assert robot.command_channels == ("left", "right", "arm_speed", "finger_speed")
    assert robot.rest.tolist() == [0.0, 0.0, 0.0, 0.0]
    assert robot.ranges["arm"] == (0.0, ARM_UP_DEG)


def test_reset_places_the_robot_with_the_gripper_up_and_closed() -> None:
    env = KheperaGripperEnv()
    obs, info = env.reset(options={"angle": 90.0, "distance": 0.3})
    v = _values(obs)
    assert v["distance"] == pytest.approx(0.3, abs=1e-9)
    assert v["angle"] == pytest.approx(90.0, abs=1e-9)
    assert v["arm"] == pytest.approx(ARM_UP_DEG)
    assert v["fingers"] == pytest.approx(FINGERS_CLOSED_M)
    assert v["object_present"] == 0.0
    assert info["lifted"] is False
    obs, _ = env.reset(options={"arm": 20.0, "fingers": FINGERS_OPEN_M})
    assert _values(obs)["arm"] == pytest.approx(20.0)
    assert _values(obs)["fingers"] == pytest.approx(FINGERS_OPEN_M)


def test_open_lower_close_lift_holds_the_object_up_even_while_turning() -> None:
    env = KheperaGripperEnv()
    env.reset(options={"angle": 0.0, "distance": 0.004})
    v, info = _grasp(env)
    assert v["object_present"] == 1.0
    assert v["arm"] == pytest.approx(ARM_UP_DEG, abs=1.0)
    # closed on a 1.5 cm cylinder, the fingers stop at its width
    assert v["fingers"] == pytest.approx(0.015, abs=0.001)
    assert info["lifted"] is True
    assert info["object"][2] > 0.06  # its centre rests at 0.015 m
    v, info = _drive(env, [3.0, -3.0, 0, 0], 60)  # turning in place with it
    assert info["lifted"] is True
    assert abs(v["angular_velocity"]) > 50.0


def test_an_object_out_of_reach_is_not_grasped() -> None:
    env = KheperaGripperEnv()
    env.reset(options={"angle": 0.0, "distance": 0.05})
    v, info = _grasp(env)
    assert v["object_present"] == 0.0
    assert info["lifted"] is False


def test_the_nudge_moves_the_object_once_the_robot_is_ready_to_grasp() -> None:
    env = KheperaGripperEnv()
    env.reset(options={"angle": 0.0, "distance": 0.004, "nudge": {"distance": 0.015}})
    obs, _, _, _, info = env.step(np.zeros(4))
    assert info["nudged"] is True
    assert _values(obs)["distance"] == pytest.approx(0.019, abs=1e-6)
    env.reset(options={"angle": 0.0, "distance": 0.3, "nudge": {"distance": 0.015}})
    _, _, _, _, info = env.step(np.zeros(4))
    assert info["nudged"] is False  # far from the object: not yet


def test_pushes_are_seen_in_the_same_step() -> None:
    env = KheperaGripperEnv()
    env.reset(options={"angle": 0.0, "distance": 0.3, "push": {"step": 1, "angle": 20.0}})
    obs, *_ = env.step(np.zeros(4))
    assert _values(obs)["angle"] == pytest.approx(20.0, abs=0.05)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"arm": 95.0}, "start arm 95 deg not in"),
        ({"fingers": 0.05}, "start fingers 0.05 m not in"),
        ({"distance": 2.0}, "start distance 2 m not in"),
        ({"nudge": {"far": 1}}, "nudge must be a dict"),
        ({"height": 1}, "unknown reset option(s): height"),
    ],
)
def test_bad_reset_options_are_one_clear_error(options: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)")):
        KheperaGripperEnv().reset(options=options)


def test_bad_actions_are_refused() -> None:
    env = KheperaGripperEnv()
    env.reset()
    with pytest.raises(ConfigError, match="action must hold 4 values"):
        env.step(np.zeros(2))
    with pytest.raises(ConfigError, match="finite"):
        env.step(np.array([0.0, math.nan, 0.0, 0.0]))


def test_contacts_stay_stable_driving_into_the_object_with_the_arm_down() -> None:
    """Full speed into the object, arm down and fingers open, from several bearings:
    no MuJoCo warning (a SimulationError would be raised) and finite readings."""
    env = KheperaGripperEnv()
    for angle in (-20.0, 0.0, 35.0):
        env.reset(options={"angle": angle, "distance": 0.05, "arm": 0.0, "fingers": 0.03})
        v, _ = _drive(env, [10.0, 10.0, 0.0, -0.02], 120)
        assert all(math.isfinite(x) for x in v.values())
