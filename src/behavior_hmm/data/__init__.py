"""Datasets: schema, Parquet/CSV I/O, validation, normalization, low-pass filter."""

from behavior_hmm.data._channels import (
    ANGLE_TOLERANCE_DEG,
    ARENA_MAX_DISTANCE,
    COMMAND_CHANNELS,
    CONTROL_PERIOD,
    DISTANCE_TOLERANCE_M,
    SENSOR_CHANNELS,
    SENSOR_RANGES,
    UNITS,
    noise_std,
)

__all__ = [
    "ANGLE_TOLERANCE_DEG",
    "ARENA_MAX_DISTANCE",
    "COMMAND_CHANNELS",
    "CONTROL_PERIOD",
    "DISTANCE_TOLERANCE_M",
    "SENSOR_CHANNELS",
    "SENSOR_RANGES",
    "UNITS",
    "noise_std",
]
