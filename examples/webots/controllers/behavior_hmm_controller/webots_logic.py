"""The Webots controller's logic, free of Webots: readings in, wheel commands out.

``behavior_hmm_controller.py`` (beside this file) binds it to Webots' ``controller``
module; everything here runs, and is tested, without Webots (tests/examples/).

Conventions (those of behavior-hmm's data contract, DESIGN §4):

* ``distance``: m from the robot's body surface to the object's surface;
* ``linear_velocity``: m/s along the robot's heading;
* ``angle``: deg in (−180, 180], bearing of the object from the heading,
  counter-clockwise positive;
* ``angular_velocity``: deg/s, the yaw rate, counter-clockwise positive;
* commands: left and right wheel speeds, rad/s.

Webots' world is ENU (z up) and a robot's forward axis is its +x (FLU), as in Webots
R2022a and later.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from behavior_hmm.data import CONTROL_PERIOD, SENSOR_CHANNELS


def sensor_reading(
    robot_position: Sequence[float],
    robot_orientation: Sequence[float],
    robot_velocity: Sequence[float],
    object_position: Sequence[float],
    *,
    body_radius: float,
    object_radius: float,
) -> np.ndarray:
    """The four sensor channels (``SENSOR_CHANNELS`` order) from a Supervisor's view.

    Parameters
    ----------
    robot_position
        ``Node.getPosition()`` of the robot: x, y, z (m, world frame).
    robot_orientation
        ``Node.getOrientation()`` of the robot: its 3x3 rotation matrix, row-major
        (9 numbers).
    robot_velocity
        ``Node.getVelocity()`` of the robot: vx, vy, vz (m/s), wx, wy, wz (rad/s),
        world frame.
    object_position
        ``Node.getPosition()`` of the object (its centre).
    body_radius, object_radius
        Radii (m) of the robot's body and of the (round) object: the distance is
        measured between their surfaces.
    """
    x, y = float(robot_position[0]), float(robot_position[1])
    ox, oy = float(object_position[0]), float(object_position[1])
    r = robot_orientation
    yaw = math.atan2(float(r[3]), float(r[0]))  # heading of the robot's +x axis
    dx, dy = ox - x, oy - y
    distance = math.hypot(dx, dy) - body_radius - object_radius
    bearing = math.degrees(math.atan2(dy, dx) - yaw)
    bearing = bearing - 360.0 * math.ceil((bearing - 180.0) / 360.0)  # into (-180, 180]
    vx, vy = float(robot_velocity[0]), float(robot_velocity[1])
    linear = vx * math.cos(yaw) + vy * math.sin(yaw)
    angular = math.degrees(float(robot_velocity[5]))
    out = np.array([0.0, 0.0, 0.0, 0.0])
    values = {
        "distance": distance,
        "linear_velocity": linear,
        "angle": bearing,
        "angular_velocity": angular,
    }
    for j, name in enumerate(SENSOR_CHANNELS):
        out[j] = values[name] + 0.0
    return out


@dataclass(frozen=True)
class WheelCommand:
    """What to send to the two wheel motors this basic time step."""

    left: float
    right: float
    done: bool
    reason: str = ""


class WebotsBehavior:
    """Runs a learned SBLM or CBLM at the 16 ms control period inside Webots' loop.

    Webots calls the controller every basic time step (``WorldInfo.basicTimeStep``);
    the model decides every ``16 / basicTimeStep`` steps and its command is held in
    between. When the behavior is done (goal reached) or a reading is not finite, the
    wheels stop and stay stopped.

    Parameters
    ----------
    model
        A fitted SBLM or CBLM.
    goal
        Goal in physical units (e.g. ``{"angle": 0}``); ``None``: the model's default.
    basic_time_step_ms
        Webots' basic time step (ms); must divide the control period (16 ms: 1, 2, 4,
        8 or 16).
    max_wheel_speed
        The motors' largest speed (rad/s, ``Motor.getMaxVelocity()``); commands are
        clipped to it.
    wheel_scale
        Factor from the model's wheel speeds to this robot's (the simulated robot's
        wheel radius over this robot's), so that the robot moves at the same speed.
    """

    def __init__(
        self,
        model: Any,
        goal: Mapping[str, float] | None = None,
        *,
        basic_time_step_ms: float = 16.0,
        max_wheel_speed: float = math.inf,
        wheel_scale: float = 1.0,
    ) -> None:
        period_ms = CONTROL_PERIOD * 1000.0
        every = period_ms / float(basic_time_step_ms)
        if basic_time_step_ms <= 0 or abs(every - round(every)) > 1e-9:
            raise ValueError(
                f"basicTimeStep {basic_time_step_ms} ms does not divide the control period "
                f"{period_ms:g} ms; set WorldInfo.basicTimeStep to 16 (or 8, 4, 2, 1)"
            )
        self.every = round(every)
        self.max_wheel_speed = float(max_wheel_speed)
        self.wheel_scale = float(wheel_scale)
        self.controller = model.policy(goal)
        self.reset()

    def reset(self) -> None:
        """Start a new run (the controller forgets its filters, plan and history)."""
        self.controller.reset()
        self._k = 0
        self._held = WheelCommand(0.0, 0.0, False)

    def step(self, reading: Sequence[float]) -> WheelCommand:
        """The wheel command for this basic time step, from the current reading."""
        if self._held.done:
            return self._held
        if self._k % self.every == 0:
            values = np.asarray(reading, dtype=np.float64)
            if not np.isfinite(values).all():
                self._held = WheelCommand(0.0, 0.0, True, "sensor_fault")
            else:
                out = self.controller.step(dict(zip(SENSOR_CHANNELS, values.tolist(), strict=True)))
                if out.done:
                    self._held = WheelCommand(0.0, 0.0, True, "goal")
                else:
                    limit = self.max_wheel_speed
                    left, right = (float(c) * self.wheel_scale for c in out.command)
                    self._held = WheelCommand(
                        max(-limit, min(limit, left)), max(-limit, min(limit, right)), False
                    )
        self._k += 1
        return self._held
