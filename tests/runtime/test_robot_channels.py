"""Robots with other channels: eight proximity sensors more, or no velocity sensors at all."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from gymnasium import spaces
from test_robot_contract import TwiceKhepera
from typer.testing import CliRunner

from behavior_hmm import data
from behavior_hmm.cli import app
from behavior_hmm.models import SBLM
from behavior_hmm.runtime import Robot
from behavior_hmm.teach import collect

IR = tuple(f"ir{k}" for k in range(8))
#: Beam directions (deg, counter-clockwise from the heading) of the proximity sensors.
BEAMS = np.linspace(-157.5, 157.5, 8)
IR_RANGE = 0.5  # m


class ProximityRobot(TwiceKhepera):
    """The contract robot plus eight infrared proximity readings (m of nearness, 0..0.5)."""

    names = (*TwiceKhepera.names, *IR)
    channel_ranges = {**TwiceKhepera.channel_ranges, **{n: (0.0, IR_RANGE) for n in IR}}  # noqa: RUF012
    channel_units = {n: "m" for n in IR}  # noqa: RUF012

    def _observe(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        obs, info = super()._observe()
        true = info["true_observation"]
        near = max(IR_RANGE - float(true["distance"][0]) / 2.0, 0.0)
        bearing = float(true["angle"][0])
        for name, beam in zip(IR, BEAMS, strict=True):
            value = near * max(math.cos(math.radians(bearing - beam)), 0.0) ** 2
            true[name] = np.array([value])
            obs[name] = np.array([value])
        return obs, info


class PositionsOnlyRobot(TwiceKhepera):
    """A robot that measures only bearing and distance (no velocity sensors)."""

    names = ("angle", "distance")

    def _observe(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        obs, info = super()._observe()
        keep = {k: v for k, v in obs.items() if k in self.names}
        info["true_observation"] = {k: info["true_observation"][k] for k in self.names}
        return keep, info


def test_proximity_channels_are_read_by_name() -> None:
    robot = Robot(ProximityRobot())
    assert robot.channels[:4] == ("distance", "linear_velocity", "angle", "angular_velocity")
    assert robot.channels[4:] == IR
    assert robot.ranges["ir3"] == (0.0, IR_RANGE)
    assert isinstance(ProximityRobot().observation_space, spaces.Dict)


@pytest.mark.slow
def test_eight_proximity_channels_import_train_and_generate(tmp_path: Path) -> None:
    env = ProximityRobot()
    starts = [{"angle": float(a), "distance": 0.6} for a in range(-170, 180, 20)]
    demos = collect("turn", starts, env=env, env_name="proximity")
    assert demos.sensor_channels[4:] == IR
    # a log in a foreign format: CSV, imported with the channels declared on the command line
    log = tmp_path / "log.csv"
    columns = demos.to_columns()
    names = ["episode", "t", *demos.sensor_channels, "left", "right"]
    with log.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(names)
        for row in zip(*(columns[n] for n in names), strict=True):
            writer.writerow([f"{v:.9g}" for v in row])
    imported = tmp_path / "turn.parquet"
    args = ["import-csv", str(log), "--behavior", "turn", "-o", str(imported)]
    for name in IR:
        args += ["--channel", f"{name}:m:0:{IR_RANGE}"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    dataset = data.read(imported)
    assert dataset.sensor_channels[4:] == IR
    assert np.allclose(dataset.columns(["ir2"]), demos.columns(["ir2"]), atol=1e-8)
    # the proximity readings alone say where the object is: train on them, no angle
    model = SBLM(inputs=("angle", *IR), random_state=0).fit(dataset)
    assert model.pipeline_.normalizer.ranges["ir5"] == (0.0, IR_RANGE)
    assert model.policy().channels[-8:] == IR
    for angle in (-125.0, 35.0, 105.0):
        trace = model.generate(env, start={"angle": angle, "distance": 0.6}, seed=0)
        assert trace.goal_reached, (angle, trace.final_errors())
        assert "ir7" in trace.channels


@pytest.mark.slow
def test_a_robot_without_velocity_sensors(tmp_path: Path) -> None:
    env = PositionsOnlyRobot()
    robot = Robot(env)
    assert robot.derived == ("linear_velocity", "angular_velocity")
    starts = [{"angle": float(a), "distance": 0.6} for a in range(-170, 180, 20)]
    demos = collect("turn", starts, env=env, env_name="positions-only")
    assert demos.metadata["derived"] == ["linear_velocity", "angular_velocity"]
    # the derived yaw rate follows the turn: the robot turns toward the object
    for episode in demos:
        start, rate = episode.channel("angle")[0], episode.channel("angular_velocity")[30]
        assert np.sign(rate) == np.sign(start)  # object on the left: turn left (CCW)
    model = SBLM(inputs=("angle",), random_state=0).fit(demos)
    for angle in (-125.0, 35.0, 105.0):
        trace = model.generate(env, start={"angle": angle, "distance": 0.6}, seed=0)
        assert trace.goal_reached, (angle, trace.final_errors())
