"""Datasets: schema, Parquet/CSV I/O, validation, normalization, low-pass filter.

A :class:`Dataset` holds all demonstrations of a behavior as column arrays plus
``lengths`` (hmmlearn style) and JSON metadata; it is validated on construction.
:func:`read` / :func:`write` handle the Parquet format, :func:`import_csv` users'
own logs, :func:`import_bags` ROS 1 / ROS 2 bags, :func:`import_lerobot` and
:func:`export_lerobot` LeRobot datasets (v3.0 layout). :class:`SignalPipeline`
filters and normalizes channels identically for training (offline) and at run time
(online, one sample at a time).
"""

from behavior_hmm.data._bags import import_bags
from behavior_hmm.data._channels import (
    ANGLE_TOLERANCE_DEG,
    ARENA_MAX_DISTANCE,
    CHANNELS,
    COMMAND_CHANNELS,
    CONTROL_PERIOD,
    DISTANCE_TOLERANCE_M,
    SENSOR_CHANNELS,
    SENSOR_RANGES,
    UNITS,
    ChannelSpec,
    channel_from_metadata,
    noise_std,
    register_channel,
)
from behavior_hmm.data._csv import import_csv
from behavior_hmm.data._dataset import NUMERIC_CHANNELS, Dataset, Episode
from behavior_hmm.data._filter import (
    ANGLE_CHANNELS,
    DEFAULT_CUTOFF_HZ,
    LowPassFilter,
    OnlineFilter,
    OnlinePipeline,
    SignalPipeline,
)
from behavior_hmm.data._lerobot import export_lerobot, import_lerobot
from behavior_hmm.data._mirror import mirror_map, mirrored
from behavior_hmm.data._normalize import CommandScaler, Normalizer
from behavior_hmm.data._parquet import METADATA_KEY, read, write
from behavior_hmm.data._summary import summarize
from behavior_hmm.data._transform import (
    DERIVABLE,
    DataImportWarning,
    SamplingWarning,
    derive_velocities,
    resample,
)
from behavior_hmm.data._units import UNIT_FACTORS, wrap_degrees
from behavior_hmm.data._validate import (
    BEHAVIOR_NAME_PATTERN,
    OPTIONAL_COLUMNS,
    REQUIRED_COLUMNS,
    SCHEMA_VERSION,
    VALUE_BOUNDS,
    declared_channels,
    declared_commands,
    validate,
)

__all__ = [
    "ANGLE_CHANNELS",
    "ANGLE_TOLERANCE_DEG",
    "ARENA_MAX_DISTANCE",
    "BEHAVIOR_NAME_PATTERN",
    "CHANNELS",
    "COMMAND_CHANNELS",
    "CONTROL_PERIOD",
    "DEFAULT_CUTOFF_HZ",
    "DERIVABLE",
    "DISTANCE_TOLERANCE_M",
    "METADATA_KEY",
    "NUMERIC_CHANNELS",
    "OPTIONAL_COLUMNS",
    "REQUIRED_COLUMNS",
    "SCHEMA_VERSION",
    "SENSOR_CHANNELS",
    "SENSOR_RANGES",
    "UNITS",
    "UNIT_FACTORS",
    "VALUE_BOUNDS",
    "ChannelSpec",
    "CommandScaler",
    "DataImportWarning",
    "Dataset",
    "Episode",
    "LowPassFilter",
    "Normalizer",
    "OnlineFilter",
    "OnlinePipeline",
    "SamplingWarning",
    "SignalPipeline",
    "channel_from_metadata",
    "declared_channels",
    "declared_commands",
    "derive_velocities",
    "export_lerobot",
    "import_bags",
    "import_csv",
    "import_lerobot",
    "mirror_map",
    "mirrored",
    "noise_std",
    "read",
    "register_channel",
    "resample",
    "summarize",
    "validate",
    "wrap_degrees",
    "write",
]
