"""A gripper command beside the two wheels (robot contract, version 2; issue 26).

Our kinematic Khepera with a gripper whose fingers close at a commanded speed: the
action is ``(left, right, grip)`` (rad/s, rad/s, m/s), declared in ``command_channels``,
and the finger opening (m) is a sensor channel declared with a tolerance. A scripted
teacher turns to face the object while it closes the gripper. The log is written as a
CSV file, imported with ``import-csv --command``, trained, and generated through the
command line; the model outputs all three commands.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from contract_testing import Cli
from gymnasium import spaces
from typer.testing import CliRunner

from behavior_hmm.cli import app
from behavior_hmm.data import read
from behavior_hmm.models import load
from behavior_hmm.teach._collect import collect_with_teacher

OPEN, CLOSED = 0.03, 0.005  # m
GRIP_SPEED = 0.02  # m/s, the fingers' top speed


class GripperKhepera(gym.Env):  # type: ignore[type-arg]
    """The kinematic Khepera plus a gripper: action (left, right, grip)."""

    command_channels = (
        "left",
        "right",
        {"name": "grip", "unit": "m/s", "range": [-GRIP_SPEED, GRIP_SPEED], "label": "fingers"},
    )
    sensor_channels = ({"name": "opening", "unit": "m", "range": [0.0, 0.035], "tolerance": 0.001},)

    def __init__(self) -> None:
        self.base = gym.make("behavior_hmm/KheperaKinematic-v0")
        self.control_period = self.base.unwrapped.control_period
        self.robot_spec = self.base.unwrapped.robot_spec
        box = spaces.Box(0.0, 0.04, shape=(1,), dtype=np.float64)
        self.observation_space = spaces.Dict({**self.base.observation_space.spaces, "opening": box})
        low = np.r_[self.base.action_space.low, -GRIP_SPEED]
        high = np.r_[self.base.action_space.high, GRIP_SPEED]
        self.action_space = spaces.Box(low, high, dtype=np.float64)
        self.opening = OPEN

    def _with_opening(self, obs: dict[str, Any], info: dict[str, Any]) -> Any:
        obs = {**obs, "opening": np.array([self.opening])}
        true = info.get("true_observation")
        if true is not None:
            info = {**info, "true_observation": {**true, "opening": np.array([self.opening])}}
        return obs, info

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        given = dict(options or {})
        self.opening = float(given.pop("opening", OPEN))
        obs, info = self.base.reset(seed=seed, options=given)
        return self._with_opening(obs, info)

    def step(self, action: Any) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        u = np.asarray(action, dtype=np.float64)
        grip = float(np.clip(u[2], -GRIP_SPEED, GRIP_SPEED))
        self.opening = float(np.clip(self.opening + grip * self.control_period, 0.0, 0.035))
        obs, reward, done, cut, info = self.base.step(u[:2])
        obs, info = self._with_opening(obs, info)
        return obs, reward, done, cut, info


def make() -> GripperKhepera:
    """``--env tests/runtime/test_contract_v2_gripper.py:make``."""
    return GripperKhepera()


class TurnAndClose:
    """Turn in place to face the object while the fingers close, both smoothly."""

    def __init__(self, env: Any) -> None:
        self.spec = env.unwrapped.robot_spec
        self._t = 0.0
        self._done_for = 0

    def reset(self, start: dict[str, float], goal: dict[str, float]) -> None:
        self._t = 0.0
        self._done_for = 0
        self._goal = goal

    def step(self, observation: dict[str, float], info: dict[str, Any]) -> tuple[Any, bool]:
        ramp = min(1.0, self._t / 0.5)  # a gentle start
        self._t += 0.016
        turn = ramp * float(np.clip(0.03 * observation["angle"], -1.0, 1.0))
        close = self._goal["opening"] - observation["opening"]
        grip = ramp * float(np.clip(4.0 * close, -GRIP_SPEED, GRIP_SPEED))
        settled = abs(observation["angle"]) < 1.0 and abs(close) < 0.0005
        self._done_for = self._done_for + 1 if settled else 0
        return [-turn, turn, grip], self._done_for > 12


def teacher(env: Any) -> TurnAndClose:
    """``--teacher tests/runtime/test_contract_v2_gripper.py:teacher``."""
    return TurnAndClose(env)


TRAIN = [{"angle": float(a), "distance": 0.4} for a in range(-170, 180, 20)]


@pytest.mark.slow
def test_a_gripper_command_beside_the_wheels_imports_trains_and_generates(
    tmp_path: Path, cli: Cli
) -> None:
    env = make()
    demos = collect_with_teacher(
        "turn-close", env, teacher(env), {"angle": 0.0, "opening": CLOSED}, TRAIN
    )
    assert demos.command_channels == ("left", "right", "grip")
    # a log of the robot's own: our column names, the gripper's columns beside them
    log = tmp_path / "log.csv"
    columns = ["episode", "t", *demos.sensor_channels, *demos.command_channels]
    table = np.column_stack(
        [np.repeat(demos.episode_ids, demos.lengths), demos.columns(columns[1:])]
    )
    np.savetxt(log, table, delimiter=",", header=",".join(columns), comments="", fmt="%.9g")
    data, model = tmp_path / "turn-close.parquet", tmp_path / "turn-close.bhmm"
    cli(
        "import-csv",
        log,
        "--behavior",
        "turn-close",
        "--channel",
        "opening:m:0:0.035:0.001",
        "--command",
        "left",
        "--command",
        "right",
        "--command",
        "grip:m/s:-0.02:0.02",
        "-o",
        data,
    )
    imported = read(data)
    assert imported.command_channels == ("left", "right", "grip")
    assert np.allclose(imported.commands, demos.commands, atol=1e-8)
    cli("train", "simple", data, "--inputs", "angle,opening", "-o", model)
    learned = load(model)
    assert learned.command_channels == ("left", "right", "grip")
    assert learned.generators_.n_outputs_ == 3
    here = Path(__file__)
    out = cli(
        "generate",
        model,
        "--env",
        f"{here}:make",
        "--start",
        "angle=75,distance=0.4",
        "--goal",
        f"angle=0,opening={CLOSED}",
    )
    summary = json.loads(out.stdout.splitlines()[0])
    assert summary["goal_reached"], summary
    assert summary["final_errors"]["opening"] <= 0.001 and summary["final_errors"]["angle"] <= 3.0
    # the wheels alone are a robot of the other kind: refused in one line
    wrong = CliRunner().invoke(
        app, ["generate", str(model), "--sim", "kinematic", "--start", "angle=30"]
    )
    assert wrong.exit_code == 2 and "commands left, right, grip" in wrong.stderr
