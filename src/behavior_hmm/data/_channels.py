"""The data contract's channels, units and default normalization ranges (DESIGN §4)."""

from __future__ import annotations

from typing import Final

#: Control period of every recording and of closed-loop generation (seconds).
CONTROL_PERIOD: Final[float] = 0.016

#: Sensor channels in their canonical order (the simulator's observation order).
SENSOR_CHANNELS: Final[tuple[str, ...]] = (
    "distance",
    "linear_velocity",
    "angle",
    "angular_velocity",
)

#: Motor command channels (wheel speeds, rad/s), in order.
COMMAND_CHANNELS: Final[tuple[str, ...]] = ("left", "right")

#: Physical unit of every channel.
UNITS: Final[dict[str, str]] = {
    "t": "s",
    "distance": "m",
    "linear_velocity": "m/s",
    "angle": "deg",
    "angular_velocity": "deg/s",
    "left": "rad/s",
    "right": "rad/s",
}

#: Default normalization range (physical units) of each sensor channel; mapped onto [-1, 1].
#: Sensor noise ``--noise SIGMA`` has standard deviation ``SIGMA * (hi - lo)`` per channel.
SENSOR_RANGES: Final[dict[str, tuple[float, float]]] = {
    "distance": (0.0, 1.2),
    "linear_velocity": (-0.15, 0.15),
    "angle": (-180.0, 180.0),
    "angular_velocity": (-90.0, 90.0),
}

#: Largest start distance (m) the arena allows; the object sits at the arena's centre.
ARENA_MAX_DISTANCE: Final[float] = 1.2

#: Physical goal tolerances used by demonstrator and generation stop rule (DESIGN §5).
ANGLE_TOLERANCE_DEG: Final[float] = 3.0
DISTANCE_TOLERANCE_M: Final[float] = 0.01


def noise_std(sigma: float) -> dict[str, float]:
    """Per-channel standard deviation (physical units) of ``--noise sigma``."""
    if not sigma >= 0.0:
        raise ValueError(f"noise sigma must be >= 0, got {sigma}")
    return {name: sigma * (hi - lo) for name, (lo, hi) in SENSOR_RANGES.items()}
