"""Physical parameters of the simulated Khepera-like robot."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from behavior_hmm.data._channels import CONTROL_PERIOD
from behavior_hmm.errors import ConfigError

_POSITIVE_FIELDS = (
    "wheel_radius",
    "axle_track",
    "body_radius",
    "max_wheel_speed",
    "motor_time_constant",
    "object_radius",
    "control_period",
    "physics_timestep",
)


@dataclass(frozen=True)
class RobotParams:
    """Geometry, motors and timing of the differential-drive robot (SI units).

    Parameters
    ----------
    wheel_radius
        Wheel radius (m).
    axle_track
        Distance between the two wheels' contact points (m).
    body_radius
        Radius of the round chassis (m); the distance sensor measures from its surface.
    max_wheel_speed
        Largest wheel speed command (rad/s); larger commands are clipped.
    wheel_mismatch
        Relative gain mismatch ``m`` of the motors: the right wheel turns at ``1 + m/2``
        and the left at ``1 - m/2`` times its command, so equal commands drift slightly
        (counter-clockwise for ``m > 0``).  Must lie in (-1, 1).
    motor_time_constant
        Time constant of each wheel's first-order response to a step command (s).
    object_radius
        Radius of the cylindrical object at the origin (m).
    contact_friction
        Coulomb friction coefficient between the chassis and the object (>= 0): a robot
        pushing into the object at a shallow angle sticks to it instead of sliding around.
    control_period
        Time between two observations / commands (s).
    physics_timestep
        Integration step (s); must divide ``control_period`` exactly.
    """

    wheel_radius: float = 0.021
    axle_track: float = 0.053
    body_radius: float = 0.035
    max_wheel_speed: float = 10.0
    wheel_mismatch: float = 0.01
    motor_time_constant: float = 0.03
    object_radius: float = 0.05
    contact_friction: float = 0.5
    control_period: float = CONTROL_PERIOD
    physics_timestep: float = 0.002

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ConfigError(
                    f"RobotParams.{f.name} must be a number, got {type(value).__name__}"
                )
            if not math.isfinite(value):
                raise ConfigError(f"RobotParams.{f.name} must be finite, got {value}")
            object.__setattr__(self, f.name, float(value))
        for name in _POSITIVE_FIELDS:
            value = getattr(self, name)
            if value <= 0.0:
                raise ConfigError(f"RobotParams.{name} must be > 0, got {value}")
        if self.contact_friction < 0.0:
            raise ConfigError(
                f"RobotParams.contact_friction must be >= 0, got {self.contact_friction}"
            )
        if not -1.0 < self.wheel_mismatch < 1.0:
            raise ConfigError(
                f"RobotParams.wheel_mismatch must lie in (-1, 1), got {self.wheel_mismatch}"
            )
        ratio = self.control_period / self.physics_timestep
        if ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-6:
            raise ConfigError(
                f"RobotParams.physics_timestep ({self.physics_timestep} s) must divide "
                f"control_period ({self.control_period} s) a whole number of times"
            )

    @property
    def substeps(self) -> int:
        """Physics steps per control period."""
        return round(self.control_period / self.physics_timestep)

    @property
    def wheel_gains(self) -> tuple[float, float]:
        """(left, right) factors from wheel command to wheel speed (the mismatch)."""
        return (1.0 - 0.5 * self.wheel_mismatch, 1.0 + 0.5 * self.wheel_mismatch)

    @property
    def contact_distance(self) -> float:
        """Centre-to-centre distance (m) at which the chassis touches the object."""
        return self.body_radius + self.object_radius

    @property
    def robot_spec(self) -> dict[str, float]:
        """The robot contract's ``robot_spec``: wheel radius (m), track width (m), top
        wheel speed (rad/s)."""
        return {
            "wheel_radius": self.wheel_radius,
            "track_width": self.axle_track,
            "max_wheel_speed": self.max_wheel_speed,
        }

    def to_dict(self) -> dict[str, float]:
        """JSON-safe ``{field: value}`` (stored in dataset and model metadata)."""
        return {f.name: float(getattr(self, f.name)) for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RobotParams:
        """Rebuild from :meth:`to_dict` output; missing fields take their defaults.

        Raises
        ------
        ConfigError
            If ``data`` is not a mapping, has unknown keys or invalid values.
        """
        if not isinstance(data, Mapping):
            raise ConfigError(f"RobotParams must be a mapping, got {type(data).__name__}")
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(str(k) for k in data if k not in known)
        if unknown:
            raise ConfigError(
                f"unknown RobotParams field(s): {', '.join(unknown)}; "
                f"expected some of {', '.join(sorted(known))}"
            )
        return cls(**dict(data))


class ParamsGeometry:
    """The robot contract's timing and geometry of an env built from ``self.params``.

    Our Khepera-like envs (with or without the gripper) hand these out alike.
    """

    params: RobotParams

    @property
    def control_period(self) -> float:
        """Seconds per step (the robot contract's ``control_period``)."""
        return float(self.params.control_period)

    @property
    def robot_spec(self) -> dict[str, float]:
        """Wheel radius (m), track width (m) and top wheel speed (rad/s): the contract's."""
        return self.params.robot_spec

    @property
    def body_radius(self) -> float:
        """Radius (m) of the round chassis (for plots and videos)."""
        return float(self.params.body_radius)

    @property
    def object_radius(self) -> float:
        """Radius (m) of the object the robot faces (for plots and videos)."""
        return float(self.params.object_radius)
