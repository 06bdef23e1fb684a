"""The robot contract, version 2 (issue 26): a robot that is not wheels facing an object.

A 2-D point mass driven by velocity commands declares its own sensor channels (its
offset ``x``, ``y`` from the goal, each with a goal tolerance) in
``env.unwrapped.sensor_channels``, and where ``reset`` can place it in
``start_channels``. It has no ``angle``, ``distance`` or wheel geometry. An SBLM learns
to reach the goal from demonstrations of a scripted teacher and reaches it from held-out
starts; the goal on its declared channels works from Python, and the model file carries
the declarations, so the goal still works after a load in a process that never saw them.

The demonstrations come from a scripted teacher of the test's own (``collect_with_teacher``,
the ``--teacher`` of the command line), and the dataset holds the robot's own channels
only. Evaluation scores the model against that teacher, or against recorded
demonstrations, with path metrics on the goal channels beside the thesis's score.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from contract_testing import Cli
from gymnasium import spaces

from behavior_hmm.data import CONTROL_PERIOD, Dataset
from behavior_hmm.data._channels import (
    CHANNELS,
    TOLERANCES,
    UNITS,
    ChannelSpec,
    register_channel,
    within_tolerance,
)
from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate import evaluate_model
from behavior_hmm.models import SBLM, load
from behavior_hmm.runtime import Robot
from behavior_hmm.teach._collect import collect_with_teacher

VMAX = 0.3  # m/s


class PointMass(gym.Env):  # type: ignore[type-arg]
    """A point in the plane; commands are its x and y velocity (m/s), lagged 50 ms."""

    control_period = CONTROL_PERIOD
    sensor_channels = (
        {"name": "x", "unit": "m", "range": [-1.0, 1.0], "tolerance": 0.01},
        {"name": "y", "unit": "m", "range": [-1.0, 1.0], "tolerance": 0.01},
    )
    start_channels = ("x", "y")

    def __init__(self, lag: float = 0.05) -> None:
        box = spaces.Box(-2.0, 2.0, shape=(1,), dtype=np.float64)
        self.observation_space = spaces.Dict({"x": box, "y": box})
        self.action_space = spaces.Box(-VMAX, VMAX, shape=(2,), dtype=np.float64)
        self._keep = 1.0 - math.exp(-CONTROL_PERIOD / lag)
        self._p = np.zeros(2)
        self._v = np.zeros(2)

    def _obs(self) -> dict[str, Any]:
        return {"x": self._p[:1].copy(), "y": self._p[1:].copy()}

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        super().reset(seed=seed)
        left = dict(options or {})
        self._p = np.array([float(left.pop("x", 0.5)), float(left.pop("y", 0.0))])
        self._v = np.zeros(2)
        if left:
            raise ValueError(f"unknown reset options {sorted(left)}")
        return self._obs(), {}

    def step(self, action: Any) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        command = np.clip(np.asarray(action, dtype=np.float64), -VMAX, VMAX)
        self._v += self._keep * (command - self._v)
        self._p = self._p + self._v * CONTROL_PERIOD
        return self._obs(), 0.0, False, False, {}


def make(**kwargs: Any) -> PointMass:
    """The factory ``--env tests/runtime/test_contract_v2.py:make`` names."""
    return PointMass(**kwargs)


class MinimumJerkTeacher:
    """A scripted teacher: a minimum-jerk straight line to the goal, then 0.2 s at rest.

    ``--teacher tests/runtime/test_contract_v2.py:teacher`` names it.
    """

    def __init__(self, env: Any, seconds_per_m: float = 6.0) -> None:
        self.seconds_per_m = float(seconds_per_m)
        self._from = np.zeros(2)
        self._to = np.zeros(2)
        self._duration = 1.0
        self._t = 0.0

    def reset(self, start: dict[str, float], goal: dict[str, float]) -> None:
        self._from = np.array([start.get("x", 0.0), start.get("y", 0.0)])
        self._to = np.array([goal.get("x", 0.0), goal.get("y", 0.0)])
        self._duration = max(1.0, self.seconds_per_m * float(np.linalg.norm(self._to - self._from)))
        self._t = 0.0

    def step(self, observation: dict[str, float], info: dict[str, Any]) -> tuple[Any, bool]:
        s = min(self._t / self._duration, 1.0)
        speed = (30 * s**2 - 60 * s**3 + 30 * s**4) / self._duration
        self._t += CONTROL_PERIOD
        return (self._to - self._from) * speed, self._t > self._duration + 0.2


def teacher(env: Any, **kwargs: Any) -> MinimumJerkTeacher:
    """The factory ``--teacher tests/runtime/test_contract_v2.py:teacher`` names."""
    return MinimumJerkTeacher(env, **kwargs)


TRAIN_STARTS = [
    {"x": r * math.cos(a), "y": r * math.sin(a)}
    for r in (0.2, 0.4, 0.6)
    for a in np.linspace(0.0, 2.0 * math.pi, 12, endpoint=False)
]
GOAL = {"x": 0.0, "y": 0.0}


@pytest.fixture(scope="module")
def demonstrations() -> Dataset:
    env = make()
    return collect_with_teacher("reach", env, teacher(env), GOAL, TRAIN_STARTS, env_name="pm")


@pytest.fixture(scope="module")
def reach(demonstrations: Dataset) -> SBLM:
    return SBLM(inputs=("x", "y"), random_state=0).fit(demonstrations)


HELD_OUT = [(0.5, 0.1), (-0.3, 0.35), (0.1, -0.5), (-0.45, -0.2), (0.25, 0.25)]


def test_the_robot_declares_its_channels_and_needs_no_wheels() -> None:
    robot = Robot(make())
    assert robot.channels == ("x", "y")
    assert robot.channel_specs["x"].tolerance == 0.01
    assert robot.start_channels == ("x", "y")
    assert "x" not in CHANNELS  # declared by the robot, not registered
    with pytest.raises(ConfigError, match="has no robot_spec"):
        _ = robot.spec  # only our teacher needs it


def test_a_declaration_the_observation_lacks_is_refused() -> None:
    env = make()
    env.sensor_channels = (*PointMass.sensor_channels, {"name": "z", "unit": "m", "range": [0, 1]})
    with pytest.raises(ConfigError, match=r"declares sensor channel.*z.*lacks"):
        Robot(env)


def test_the_model_carries_the_declarations(reach: SBLM, tmp_path: Path) -> None:
    assert reach.channels_["x"] == ChannelSpec("x", "m", (-1.0, 1.0), tolerance=0.01)
    assert reach.default_goal_ == {"x": 0.0, "y": 0.0}  # the dataset's goal, declared channels
    path = tmp_path / "reach.bhmm"
    reach.save(path)
    again = load(path)
    assert again.channels_ == reach.channels_
    assert again.resolve_goal({"x": 0.0, "y": 0.0}) == {"x": 0.0, "y": 0.0}
    with pytest.raises(ConfigError, match="unknown goal channel 'z'; choose from x, y"):
        again.resolve_goal({"z": 0.0})
    with pytest.raises(ConfigError, match="goal channel 'angle' is not an input"):
        again.resolve_goal({"angle": 0.0})


@pytest.mark.slow
def test_the_point_mass_reaches_its_goal_from_held_out_starts(reach: SBLM) -> None:
    for x0, y0 in HELD_OUT:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            trace = reach.generate(make(), start={"x": x0, "y": y0}, goal={"x": 0.0, "y": 0.0})
        assert trace.reason == "goal" and trace.goal_reached, (x0, y0, trace.final_errors())
        errors = trace.final_errors()
        assert errors["x"] <= 0.01 and errors["y"] <= 0.01
        # it moved there: the path covers the start's distance, not a stop where it began
        path = np.abs(np.diff(trace.reading_array, axis=0)).sum()
        assert path >= 0.9 * math.hypot(x0, y0)
        # stop_at_rest reads velocities this robot does not have, and says it is off
        assert any("stop_at_rest is off" in str(w.message) for w in caught)


def test_a_start_on_a_channel_the_robot_cannot_be_placed_at_is_refused(reach: SBLM) -> None:
    env = make()
    env.start_channels = ("x",)
    with pytest.raises(ConfigError, match="unknown start channel 'y'"):
        reach.generate(env, start={"x": 0.3, "y": 0.1}, goal={"x": 0.0, "y": 0.0})


def test_registered_channels_update_every_derived_table() -> None:
    name = "contract_v2_heave"
    assert name not in TOLERANCES
    spec = register_channel(ChannelSpec(name, "mm", (0.0, 50.0), tolerance=0.5))
    try:
        assert TOLERANCES[name] == 0.5
        assert UNITS[name] == "mm"
        assert within_tolerance({name: 10.4}, {name: 10.0})
        assert not within_tolerance({name: 10.6}, {name: 10.0})
    finally:
        del CHANNELS[spec.name]
    assert name not in TOLERANCES


def test_the_teachers_dataset_holds_the_robots_own_channels(demonstrations: Dataset) -> None:
    assert demonstrations.sensor_channels == ("x", "y")
    assert len(demonstrations) == len(TRAIN_STARTS)
    assert demonstrations.metadata["goal"] == GOAL
    first = demonstrations.episode(0)
    assert first.channel("x")[0] == pytest.approx(TRAIN_STARTS[0]["x"])
    assert abs(first.channel("x")[-1]) < 0.01 and abs(first.channel("y")[-1]) < 0.01


@pytest.mark.slow
def test_evaluation_against_the_teacher_and_against_recordings(
    reach: SBLM, demonstrations: Dataset
) -> None:
    env = make()
    starts = [{"x": x, "y": y} for x, y in HELD_OUT]
    result = evaluate_model(reach, starts, sim=None, env=env, teacher=teacher(env))
    assert result["goal_reached"] == len(HELD_OUT)
    assert result["reference"] == "teacher"
    assert result["success_rate_mean"] > result["zero_floor_mean"] + 20.0
    assert result["success_rate_motor_max_mean"] is None  # no wheels, no motor limit
    case = result["cases"][0]
    assert set(case["final_errors"]) == {"x", "y"}
    assert case["path"]["frechet"] is not None and case["path"]["frechet"] < 0.1
    assert case["path"]["swept_area"] is not None  # a 2-D path
    recorded = evaluate_model(reach, [], sim=None, env=make(), reference=demonstrations)
    assert recorded["n"] == len(TRAIN_STARTS) and recorded["reference"] == "recorded"
    assert recorded["cases"][5]["start"] == pytest.approx(TRAIN_STARTS[5])
    # in-sample: 33 of 36 at seed 0; the closest starts (0.2 m) stop 1.3 cm short or
    # find no observation path (measured when this test was written)
    assert recorded["goal_reached"] >= 0.9 * len(TRAIN_STARTS)


def test_a_behavior_name_is_checked_before_any_demonstration_runs() -> None:
    class Counting(MinimumJerkTeacher):
        resets = 0

        def reset(self, start: dict[str, float], goal: dict[str, float]) -> None:
            Counting.resets += 1
            super().reset(start, goal)

    env = make()
    with pytest.raises(ConfigError, match="behavior name: invalid behavior name 'Reach Me'"):
        collect_with_teacher("Reach Me", env, Counting(env), GOAL, TRAIN_STARTS)
    assert Counting.resets == 0


def test_a_model_without_a_teacher_of_ours_needs_one(reach: SBLM) -> None:
    with pytest.raises(ConfigError, match=r"has no teacher of ours.*--teacher.*--reference"):
        evaluate_model(reach, [{"x": 0.3, "y": 0.0}], sim=None, env=make())


@pytest.mark.slow
def test_collect_train_generate_evaluate_through_the_cli(tmp_path: Path, cli: Cli) -> None:
    """The whole loop on a robot that is not wheels, through the command line only."""
    here = Path(__file__)
    env, tutor = f"{here}:make", f"{here}:teacher"
    starts = tmp_path / "starts.csv"
    starts.write_text("x,y\n" + "".join(f"{s['x']},{s['y']}\n" for s in TRAIN_STARTS))
    data, model = tmp_path / "reach.parquet", tmp_path / "reach.bhmm"
    cli(
        "collect",
        "reach",
        "--env",
        env,
        "--teacher",
        tutor,
        "--teacher-kwargs",
        '{"seconds_per_m": 6.0}',
        "--starts",
        starts,
        "--goal",
        "x=0,y=0",
        "-o",
        data,
    )
    cli("train", "simple", data, "--inputs", "x,y", "-o", model)
    out = cli("generate", model, "--env", env, "--start", "x=0.45,y=-0.25", "--goal", "x=0,y=0")
    summary = json.loads(out.stdout.splitlines()[0])
    assert summary["goal_reached"] and max(summary["final_errors"].values()) <= 0.01
    held_out = tmp_path / "held_out.csv"
    held_out.write_text("x,y\n" + "".join(f"{x},{y}\n" for x, y in HELD_OUT))
    report = tmp_path / "eval.json"
    cli("evaluate", model, "--env", env, "--teacher", tutor, "--starts", held_out, "--json", report)
    result = json.loads(report.read_text())
    assert result["goal_reached"] == len(HELD_OUT) and result["reference"] == "teacher"
    assert result["path_frechet_median"] is not None
    recorded = tmp_path / "recorded.json"
    cli("evaluate", model, "--env", env, "--reference", data, "--json", recorded)
    assert json.loads(recorded.read_text())["n"] == len(TRAIN_STARTS)
