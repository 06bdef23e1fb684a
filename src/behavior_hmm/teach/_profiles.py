"""Jerk-limited (third-order s-curve) motion profiles computed with ruckig."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory

from behavior_hmm.errors import ConfigError


@dataclass(frozen=True)
class Limits:
    """Velocity, acceleration and jerk limits of a one-axis profile (units of the axis per s^k)."""

    velocity: float
    acceleration: float
    jerk: float

    def __post_init__(self) -> None:
        for name in ("velocity", "acceleration", "jerk"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ConfigError(f"profile limit '{name}' must be a positive number, got {value}")


#: Turn profiles act on the bearing angle (deg, deg/s, deg/s^2, deg/s^3).
TURN_LIMITS = Limits(velocity=45.0, acceleration=45.0, jerk=90.0)
#: Approach / retreat profiles act on the distance (m, m/s, m/s^2, m/s^3).
DISTANCE_LIMITS = Limits(velocity=0.08, acceleration=0.06, jerk=0.1)
#: A gripper's arm profiles act on the arm angle (deg, deg/s, ...): 80 deg in about 2.2 s.
ARM_LIMITS = Limits(velocity=60.0, acceleration=120.0, jerk=480.0)
#: A gripper's finger profiles act on the opening (m, m/s, ...): 25 mm in about 1.6 s.
FINGER_LIMITS = Limits(velocity=0.02, acceleration=0.04, jerk=0.16)


class SCurve:
    """A rest-to-rest jerk-limited profile from ``start`` to ``target``.

    Parameters
    ----------
    start, target
        Positions in the axis' unit (degrees or metres).
    limits
        Velocity, acceleration and jerk limits.

    Attributes
    ----------
    duration
        Length of the profile in seconds (0 when start == target).
    """

    def __init__(self, start: float, target: float, limits: Limits) -> None:
        self.start = float(start)
        self.target = float(target)
        self.limits = limits
        self._trajectory: Trajectory | None = None
        self.duration = 0.0
        if self.start == self.target:
            return
        inp = InputParameter(1)
        inp.current_position = [self.start]
        inp.current_velocity = [0.0]
        inp.current_acceleration = [0.0]
        inp.target_position = [self.target]
        inp.target_velocity = [0.0]
        inp.target_acceleration = [0.0]
        inp.max_velocity = [limits.velocity]
        inp.max_acceleration = [limits.acceleration]
        inp.max_jerk = [limits.jerk]
        trajectory = Trajectory(1)
        result = Ruckig(1).calculate(inp, trajectory)
        if result not in (Result.Working, Result.Finished):
            raise ConfigError(f"ruckig could not plan {self.start} -> {self.target}: {result}")
        self._trajectory = trajectory
        self.duration = float(trajectory.duration)

    def at(self, t: float) -> tuple[float, float]:
        """Position and velocity of the profile at time ``t`` (s); held at the end."""
        if self._trajectory is None or t >= self.duration:
            return self.target, 0.0
        position, velocity, _ = self._trajectory.at_time(max(t, 0.0))
        return float(position[0]), float(velocity[0])
