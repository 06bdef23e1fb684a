"""Our teacher grasps on the Khepera with a gripper: open, lower, close, lift (issue 28)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import behavior_hmm  # noqa: F401 - registers the ids
from behavior_hmm.data._channels import ARM_UP_DEG
from behavior_hmm.errors import ConfigError
from behavior_hmm.sim import GRIPPER_ENV_ID, make_env
from behavior_hmm.teach import Teacher, behavior_spec, collect
from behavior_hmm.teach import test_starts as shipped_starts


@pytest.fixture(scope="module")
def teacher() -> Teacher:
    return Teacher(gym.make(GRIPPER_ENV_ID))


def test_a_grasp_ends_with_the_object_held_up(teacher: Teacher) -> None:
    demo = teacher.demonstrate("grasp", 1.5, 0.006)
    columns = demo.as_arrays()
    assert set(columns) >= {"left", "right", "arm_speed", "finger_speed", "arm", "fingers"}
    final = dict(zip(demo.channels, demo.final_observation, strict=True))  # type: ignore[arg-type]
    assert final["object_present"] == 1.0
    assert final["arm"] == pytest.approx(ARM_UP_DEG, abs=1.0)
    # the wheels rest while the gripper works; every phase is jerk-limited (no step)
    assert np.all(columns["left"] == 0.0) and np.all(columns["right"] == 0.0)
    assert np.max(np.abs(np.diff(columns["arm_speed"]))) < 5.0  # deg/s per 16 ms
    # in order: open (fingers move up), lower (arm down), close, lift (arm up)
    arm, fingers = columns["arm_speed"], columns["finger_speed"]
    first = {
        "open": int(np.argmax(fingers > 0)),
        "lower": int(np.argmax(arm < 0)),
        "close": int(np.argmax(fingers < 0)),
        "lift": int(np.argmax(arm > 0)),
    }
    assert first["open"] < first["lower"] < first["close"] < first["lift"]


def test_turn_approach_grasp_from_behind_tags_each_component(teacher: Teacher) -> None:
    demo = teacher.demonstrate("turn-approach-grasp", 150.0, 0.2)
    tags = list(dict.fromkeys(demo.behavior))
    assert tags == ["turn", "approach", "grasp"]
    final = dict(zip(demo.channels, demo.final_observation, strict=True))  # type: ignore[arg-type]
    assert final["object_present"] == 1.0


def test_a_start_facing_the_object_needs_no_turn(teacher: Teacher) -> None:
    demo = teacher.demonstrate("turn-approach-grasp", 2.0, 0.15)
    assert list(dict.fromkeys(demo.behavior)) == ["approach", "grasp"]


def test_the_khepera_without_a_gripper_is_refused_with_the_env_to_use() -> None:
    with pytest.raises(ConfigError, match="KheperaGripper-v0"):
        Teacher(make_env("kinematic")).demonstrate("grasp", 0.0, 0.004)


def test_collect_defaults_to_the_behaviors_robot_and_declares_its_channels() -> None:
    assert behavior_spec("grasp").env == GRIPPER_ENV_ID
    data = collect("grasp", [{"angle": 0.0, "distance": 0.004}])
    meta = data.metadata
    assert meta["env"] == GRIPPER_ENV_ID
    assert meta["goal"] == {"arm": ARM_UP_DEG, "object_present": 1.0}
    assert [c["name"] for c in meta["commands"]] == ["left", "right", "arm_speed", "finger_speed"]
    assert {c["name"]: c["unit"] for c in meta["channels"]} == {
        "arm": "deg",
        "fingers": "m",
        "object_present": "1",
    }
    assert tuple(data.command_channels) == ("left", "right", "arm_speed", "finger_speed")


def test_shipped_test_starts_lie_where_a_grasp_can_begin() -> None:
    starts = shipped_starts("grasp")
    assert len(starts) == 15
    assert all(0.0 <= s["distance"] <= 0.01 and abs(s["angle"]) <= 3.0 for s in starts)
    around = shipped_starts("turn-approach-grasp")
    assert len(around) == 15
    assert min(s["angle"] for s in around) < -150 and max(s["angle"] for s in around) > 150
