"""Goals in physical units: parsing, tolerances and the physical stop test."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Final

from behavior_hmm.data import ANGLE_TOLERANCE_DEG, DISTANCE_TOLERANCE_M, SENSOR_CHANNELS
from behavior_hmm.errors import ConfigError

#: Physical tolerance of a goal on each channel (DESIGN §5: 3 deg, 0.01 m).
TOLERANCES: Final[dict[str, float]] = {
    "angle": ANGLE_TOLERANCE_DEG,
    "distance": DISTANCE_TOLERANCE_M,
    "linear_velocity": 0.01,
    "angular_velocity": 5.0,
}


def check_goal(goal: Mapping[str, float], allowed: tuple[str, ...]) -> dict[str, float]:
    """Validate a goal ``{channel: value}`` against the channels a model can see."""
    if not goal:
        raise ConfigError("the goal is empty; give at least one channel, e.g. angle=0")
    out: dict[str, float] = {}
    for name, value in goal.items():
        if name not in SENSOR_CHANNELS:
            raise ConfigError(
                f"unknown goal channel '{name}'; choose from {', '.join(SENSOR_CHANNELS)}"
            )
        if name not in allowed:
            raise ConfigError(
                f"goal channel '{name}' is not an input of this model "
                f"(inputs: {', '.join(allowed)})"
            )
        v = float(value)
        if v != v or v in (float("inf"), float("-inf")):
            raise ConfigError(f"goal {name} must be a finite number, got {value}")
        if name == "angle" and not -180.0 <= v <= 180.0:
            raise ConfigError(f"goal angle {v:g} deg not in [-180, 180]")
        if name == "distance" and not 0.0 <= v <= 1.2:
            raise ConfigError(f"goal distance {v:g} m not in [0, 1.2]")
        out[name] = v
    return out


def within_tolerance(values: Mapping[str, float], goal: Mapping[str, float]) -> bool:
    """True when every goal channel of ``values`` lies within its physical tolerance."""
    for name, target in goal.items():
        error = values[name] - target
        if name == "angle":
            error = (error + 180.0) % 360.0 - 180.0
        if abs(error) > TOLERANCES[name]:
            return False
    return True
