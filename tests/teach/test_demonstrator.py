from __future__ import annotations

import numpy as np
import pytest

from behavior_hmm.data import ANGLE_TOLERANCE_DEG, DISTANCE_TOLERANCE_M, SENSOR_CHANNELS
from behavior_hmm.errors import ConfigError
from behavior_hmm.sim import make_env
from behavior_hmm.teach import Teacher, default_starts, plan_phases, wrap_deg

ANGLE = SENSOR_CHANNELS.index("angle")
DIST = SENSOR_CHANNELS.index("distance")


def _check_goal(behavior: str, final: np.ndarray, start: dict[str, float]) -> None:
    if behavior in ("turn", "turn-approach", "position"):
        assert abs(final[ANGLE]) <= ANGLE_TOLERANCE_DEG, (start, final)
    if behavior in ("approach", "turn-approach"):
        assert 0.0 <= final[DIST] <= DISTANCE_TOLERANCE_M, (start, final)
    if behavior in ("retreat", "position"):
        assert abs(final[DIST] - start["goal_distance"]) <= DISTANCE_TOLERANCE_M, (start, final)


def _random_starts(behavior: str, rng: np.random.Generator, n: int) -> list[dict[str, float]]:
    starts = []
    for _ in range(n):
        angle = float(rng.uniform(-180, 180))
        distance = float(rng.uniform(0.0, 1.0))
        if behavior == "turn":
            starts.append({"angle": angle, "distance": 0.5})
        elif behavior == "approach":
            starts.append({"angle": 0.0, "distance": max(distance, 0.02)})
        else:
            starts.append({"angle": angle, "distance": distance})
    return starts


@pytest.mark.parametrize("behavior", ["turn", "approach", "turn-approach"])
def test_teacher_reaches_goal_from_grid_and_random_starts_kinematic(
    behavior: str, rng: np.random.Generator
) -> None:
    env = make_env("kinematic")
    teacher = Teacher(env)
    grid = default_starts(behavior)
    if behavior == "turn-approach":
        grid = grid[::7]  # the full 208-start grid runs in the MuJoCo slow test below
    for start in grid + _random_starts(behavior, rng, 20):
        demo = teacher.demonstrate(behavior, start["angle"], start["distance"], seed=0)
        assert demo.final_observation is not None
        _check_goal(behavior, demo.final_observation, start)
        cols = demo.as_arrays()
        assert np.all(np.diff(cols["t"]) > 0)
        # every demonstration ends commanding a stop
        assert cols["left"][-1] == 0.0 and cols["right"][-1] == 0.0


@pytest.mark.slow
@pytest.mark.parametrize("behavior", ["turn", "approach", "turn-approach"])
def test_teacher_reaches_goal_from_grid_and_random_starts_mujoco(
    behavior: str, rng: np.random.Generator
) -> None:
    env = make_env("mujoco")
    teacher = Teacher(env)
    for start in default_starts(behavior) + _random_starts(behavior, rng, 20):
        demo = teacher.demonstrate(behavior, start["angle"], start["distance"], seed=0)
        assert demo.final_observation is not None
        _check_goal(behavior, demo.final_observation, start)


def test_turn_commands_are_smooth_and_start_at_rest() -> None:
    env = make_env("kinematic")
    demo = Teacher(env).demonstrate("turn", 100.0, 0.5, seed=0).as_arrays()
    left, right = demo["left"], demo["right"]
    assert abs(left[0]) < 1e-6 and abs(right[0]) < 1e-6
    # turning toward an object on the left (positive bearing) means right wheel forward
    assert np.max(right) > 0.5 and np.min(left) < -0.5
    # jerk-limited: no jumps between consecutive commands beyond a small fraction of the peak
    assert np.max(np.abs(np.diff(right))) < 0.1 * np.max(np.abs(right))


def test_turn_approach_tags_sub_behaviors_in_order() -> None:
    env = make_env("kinematic")
    demo = Teacher(env).demonstrate("turn-approach", -90.0, 0.5, seed=0).as_arrays()
    tags = list(demo["behavior"])
    first_approach = tags.index("approach")
    assert set(tags[:first_approach]) == {"turn"}
    assert set(tags[first_approach:]) == {"approach"}


@pytest.mark.parametrize(
    ("angle", "distance", "expected"),
    [
        (0.0, 0.5, ["approach"]),
        (90.0, 0.0, ["turn"]),
        (2.0, 0.005, []),
        (45.0, 0.3, ["turn", "approach"]),
    ],
)
def test_turn_approach_skips_what_is_not_needed(
    angle: float, distance: float, expected: list[str]
) -> None:
    assert [p.name for p in plan_phases("turn-approach", angle, distance)] == expected


def test_position_chooses_approach_or_retreat() -> None:
    assert [p.name for p in plan_phases("position", 0.0, 0.8, goal_distance=0.3)] == ["approach"]
    assert [p.name for p in plan_phases("position", 30.0, 0.1, goal_distance=0.6)] == [
        "turn",
        "retreat",
    ]


def test_unknown_behavior_is_refused() -> None:
    with pytest.raises(ConfigError, match="unknown behavior 'dance'"):
        plan_phases("dance", 0.0, 0.5)


def test_wrap_deg() -> None:
    assert wrap_deg(180.0) == 180.0
    assert wrap_deg(-180.0) == 180.0
    assert wrap_deg(190.0) == pytest.approx(-170.0)
    assert wrap_deg(-370.0) == pytest.approx(-10.0)


def test_retreat_reaches_its_goal_kinematic() -> None:
    env = make_env("kinematic")
    start = {"angle": 0.0, "distance": 0.2, "goal_distance": 0.9}
    demo = Teacher(env).demonstrate("retreat", 0.0, 0.2, goal_distance=0.9, seed=0)
    assert demo.final_observation is not None
    _check_goal("retreat", demo.final_observation, start)
