"""The robot contract (docs/robots.md) on a robot defined here, not in behavior_hmm.sim.

``make`` builds a differential-drive robot twice the Khepera's size with its own
control period (20 ms), its own channel ranges and Dict observations; the command line
runs collect -> train -> generate -> evaluate on it through ``--env FILE.py:make``,
and a plain Python loop drives ``SBLM.policy`` with no Gymnasium at all.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
from gymnasium import spaces
from typer.testing import CliRunner

from behavior_hmm.cli import app
from behavior_hmm.errors import ConfigError
from behavior_hmm.runtime import Robot, make_robot_env, run_policy
from behavior_hmm.teach import Teacher

HERE = Path(__file__).resolve()
PERIOD = 0.02  # s: not our 16 ms
CONTACT = 0.1  # m between the robot's centre and the object's centre at contact


class TwiceKhepera(gymnasium.Env[dict[str, np.ndarray], np.ndarray]):
    """A unicycle with first-order motors and one round object at the origin."""

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012
    robot_spec = {"wheel_radius": 0.04, "track_width": 0.1, "max_wheel_speed": 10.0}  # noqa: RUF012
    control_period = PERIOD
    channel_ranges = {  # noqa: RUF012
        "distance": (0.0, 2.4),
        "linear_velocity": (-0.3, 0.3),
        "angle": (-180.0, 180.0),
        "angular_velocity": (-90.0, 90.0),
    }
    start_scale = {"distance": 2.0}  # noqa: RUF012
    names = ("angle", "distance", "linear_velocity", "angular_velocity")  # not our order

    def __init__(self, lag: float = 0.05) -> None:
        self.lag = float(lag)
        box = {n: spaces.Box(-1e4, 1e4, shape=(1,), dtype=np.float64) for n in self.names}
        self.observation_space = spaces.Dict(box)
        self.action_space = spaces.Box(-10.0, 10.0, shape=(2,), dtype=np.float64)
        self._state = np.zeros(5)  # x, y, yaw, left wheel, right wheel (rad/s)
        self._noise = 0.0

    def _observe(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        x, y, yaw, wl, wr = self._state
        r, track = self.robot_spec["wheel_radius"], self.robot_spec["track_width"]
        v, w = r * (wl + wr) / 2.0, r * (wr - wl) / track
        bearing = math.degrees(math.atan2(-y, -x) - yaw)
        bearing = (bearing + 180.0) % 360.0 - 180.0
        true = {
            "angle": bearing,
            "distance": max(math.hypot(x, y) - CONTACT, 0.0),
            "linear_velocity": v,
            "angular_velocity": math.degrees(w),
        }
        obs = {}
        for name in true:
            lo, hi = self.channel_ranges[name]
            noisy = true[name] + self._noise * (hi - lo) * float(self.np_random.standard_normal())
            obs[name] = np.array([noisy])
        info = {
            "true_observation": {k: np.array([v]) for k, v in true.items()},
            "pose": (x, y, yaw),
        }
        return obs, info

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        super().reset(seed=seed)
        options = dict(options or {})
        angle = float(options.pop("angle", 0.0))
        distance = float(options.pop("distance", 1.0))
        self._noise = float(options.pop("noise", 0.0))
        if options:
            raise ValueError(f"unknown reset options {sorted(options)}")
        # robot on the -x axis, object ahead at `angle` degrees of bearing
        self._state = np.array([-(distance + CONTACT), 0.0, -math.radians(angle), 0.0, 0.0])
        return self._observe()

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        left, right = np.clip(np.asarray(action, dtype=np.float64), -10.0, 10.0)
        x, y, yaw, wl, wr = self._state
        k = 1.0 - math.exp(-PERIOD / self.lag)
        wl += k * (left - wl)
        wr += k * (right - wr)
        r, track = self.robot_spec["wheel_radius"], self.robot_spec["track_width"]
        v, w = r * (wl + wr) / 2.0, r * (wr - wl) / track
        yaw += w * PERIOD
        x += v * math.cos(yaw) * PERIOD
        y += v * math.sin(yaw) * PERIOD
        reach = math.hypot(x, y)
        if reach < CONTACT:  # the object stops the robot: no driving through it
            x, y = x * CONTACT / reach, y * CONTACT / reach
        self._state = np.array([x, y, yaw, wl, wr])
        obs, info = self._observe()
        return obs, 0.0, False, False, info


def make(**kwargs: Any) -> TwiceKhepera:
    """The factory ``--env tests/runtime/test_robot_contract.py:make`` names."""
    return TwiceKhepera(**kwargs)


def test_the_robot_meets_the_contract() -> None:
    robot = Robot(make())
    assert robot.channels == ("distance", "linear_velocity", "angle", "angular_velocity")
    assert robot.control_period == PERIOD
    assert robot.spec.max_linear_speed == pytest.approx(0.4)
    reading, true, pose = robot.reset(options={"angle": 30.0, "distance": 1.5})
    assert robot.as_dict(true)["angle"] == pytest.approx(30.0)
    assert robot.as_dict(reading)["distance"] == pytest.approx(1.5)
    assert pose is not None


def test_env_spec_forms(tmp_path: Path) -> None:
    env = make_robot_env(f"{HERE}:make", {"lag": 0.1})
    assert type(env).__name__ == "TwiceKhepera" and env.lag == 0.1
    assert make_robot_env("behavior_hmm/KheperaKinematic-v0").unwrapped.control_period == 0.016
    assert isinstance(make_robot_env(f"{__name__}:make"), TwiceKhepera)
    for bad in (f"{tmp_path}/none.py:make", "no_such_module_xyz:make", "Nope-v9", f"{HERE}:absent"):
        with pytest.raises(ConfigError):
            make_robot_env(bad)


def test_an_env_that_breaks_the_contract_is_refused() -> None:
    env = make()
    env.observation_space = spaces.Box(-1.0, 1.0, shape=(4,))
    with pytest.raises(ConfigError, match=r"spaces\.Dict"):
        Robot(env)
    # contract version 2 requires no channel; our own teacher reads angle and distance
    env = make()
    env.observation_space = spaces.Dict({"angle": spaces.Box(-180, 180, shape=(1,))})
    assert Robot(env).channels == ("angle", "angular_velocity")
    with pytest.raises(ConfigError, match="has no distance channel; our teacher reads"):
        Teacher(env)


@pytest.mark.slow
def test_collect_train_generate_evaluate_through_the_cli(tmp_path: Path) -> None:
    runner = CliRunner()

    def cli(*args: str) -> Any:
        return runner.invoke(app, list(args))

    env = f"{HERE}:make"
    starts = tmp_path / "starts.csv"
    starts.write_text("angle\n" + "\n".join(str(a) for a in range(-170, 180, 20)) + "\n")
    data, model = tmp_path / "turn.parquet", tmp_path / "turn.bhmm"
    out = cli("collect", "turn", "--env", env, "--starts", str(starts), "-o", str(data))
    assert out.exit_code == 0, out.output
    out = cli("train", "simple", str(data), "--inputs", "angle", "-o", str(model))
    assert out.exit_code == 0, out.output
    out = cli("generate", str(model), "--env", env, "--start", "angle=75,distance=1.0")
    assert out.exit_code == 0, out.output
    summary = json.loads(out.stdout.splitlines()[0])
    assert summary["goal_reached"] and summary["final_errors"]["angle"] <= 3.0
    # the robot's own period: 20 ms steps in the trace
    assert summary["duration_s"] == pytest.approx(PERIOD * (summary["steps"] - 1))
    tests = tmp_path / "tests.csv"
    tests.write_text("angle\n-125\n-55\n35\n105\n165\n")
    report = tmp_path / "eval.json"
    out = cli("evaluate", str(model), "--env", env, "--starts", str(tests), "--json", str(report))
    assert out.exit_code == 0, out.output
    result = json.loads(report.read_text())
    assert result["goal_reached"] == 5 and result["success_rate_mean"] > result["zero_floor_mean"]
    # the model remembers the robot it learned on
    out = cli("inspect", str(model), "--json", str(tmp_path / "m.json"))
    assert out.exit_code == 0, out.output
    meta = json.loads((tmp_path / "m.json").read_text())
    assert meta["provenance"]["env"] == env
    assert meta["provenance"]["control_period"] == PERIOD
    # run on our robot instead: a warning, not a refusal
    out = cli("generate", str(model), "--sim", "kinematic", "--start", "angle=75")
    assert "trained on" in out.stderr and "20 ms" in out.stderr


def test_policy_in_a_plain_loop_without_gymnasium(turn_model: Any) -> None:
    """A robot's own control loop: readings in, wheel commands out, no env at all."""
    policy = turn_model.policy({"angle": 0.0})
    policy.reset()
    # our own tiny unicycle, integrated here: the robot the loop would talk to
    yaw, speeds = math.radians(-100.0), np.zeros(2)  # object at +100 deg of bearing
    r, track, dt = 0.021, 0.053, 0.016
    for _ in range(1500):
        w = r * (speeds[1] - speeds[0]) / track
        bearing = (math.degrees(-yaw) + 180.0) % 360.0 - 180.0
        reading = {"angle": bearing, "angular_velocity": math.degrees(w), "linear_velocity": 0.0}
        out = policy.step(reading)
        if out.done:
            break
        speeds += (np.asarray(out.command) - speeds) * (1.0 - math.exp(-dt / 0.02))
        yaw += w * dt
    assert out.done
    assert abs((math.degrees(-yaw) + 180.0) % 360.0 - 180.0) <= 3.0


def test_run_policy_reads_by_name_in_any_channel_order(turn_model: Any) -> None:
    trace = run_policy(turn_model.policy(), make(), start={"angle": 60.0}, max_steps=800)
    assert trace.channels == ["distance", "linear_velocity", "angle", "angular_velocity"]
    assert trace.pose_array.shape == (len(trace), 3)
    assert trace.channel("angle")[0] == pytest.approx(60.0)
