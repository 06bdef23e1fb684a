"""LeRobot datasets (the v3.0 layout), files only: export our datasets, import theirs.

Layout written by :func:`export_lerobot` (LeRobotDataset v3.0)::

    DIR/
      data/chunk-000/file-000.parquet          one row per frame
      meta/info.json                           codebase_version "v3.0", fps, features, ...
      meta/stats.json                          min, max, mean, std, count per feature
      meta/tasks.parquet                       task (the pandas index) -> task_index
      meta/episodes/chunk-000/file-000.parquet one row per episode (lengths, indices, stats)
      meta/behavior_hmm.json                   ours: metadata, episode ids and start times

Frames hold ``observation.state`` (float32: every sensor channel of the dataset, in
``Dataset.sensor_channels`` order: distance m, linear_velocity m/s, angle deg,
angular_velocity deg/s, then the channels its metadata declares, in their units; or the
declared channels only, for a robot without the four), ``action`` (float32: every
command channel, in ``Dataset.command_channels`` order; by default the left, right wheel
speeds, rad/s), ``timestamp`` (float32, s from the episode's start), ``frame_index``,
``episode_index``, ``index`` and ``task_index`` (int64); the element names are listed in
``info.json``, and the declarations (``channels``, ``commands``) travel in
``meta/behavior_hmm.json`` with the rest of the metadata. The task of a frame is the
dataset's behavior (``--task``), or for complex demonstrations (several sub-behaviors)
the active sub-behavior. No videos. LeRobot itself is not needed to write or read these
files; the hub is never contacted.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import math
import os
import re
import secrets
import shutil
from collections.abc import Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from stat import S_ISREG
from typing import Any, Final

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
from numpy.typing import NDArray

from behavior_hmm._safe_read import check_regular, load_json
from behavior_hmm.data._channels import (
    COMMAND_CHANNELS,
    CONTROL_PERIOD,
    SENSOR_CHANNELS,
    UNITS,
    ChannelSpec,
)
from behavior_hmm.data._csv import _extra_channels, _extra_unit
from behavior_hmm.data._dataset import Dataset
from behavior_hmm.data._transform import check_units_of_derived, finish, parse_derive
from behavior_hmm.data._transform import resample as resample_columns
from behavior_hmm.data._units import MAX_UNWRAPPED_ANGLE, unit_factor, wrap_imported_angles
from behavior_hmm.data._validate import (
    check_table,
    declared_channels,
    declared_commands,
    suggest,
)
from behavior_hmm.errors import ConfigError, DatasetError

#: The LeRobotDataset format version written.
CODEBASE_VERSION: Final[str] = "v3.0"

#: LeRobot's default tolerance on time stamps (s): frames are 1/fps apart within it.
TOLERANCE_S: Final[float] = 1e-4

#: Our own file in ``meta/``; LeRobot ignores it.
OURS: Final[str] = "meta/behavior_hmm.json"

DATA_PATH: Final[str] = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
EPISODES_PATH: Final[str] = "meta/episodes/chunk-000/file-000.parquet"
VIDEO_PATH: Final[str] = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"

STATE: Final[str] = "observation.state"
ACTION: Final[str] = "action"

#: LeRobot's bookkeeping columns (``DEFAULT_FEATURES``), in its order.
DEFAULT_FEATURES: Final[dict[str, str]] = {
    "timestamp": "float32",
    "frame_index": "int64",
    "episode_index": "int64",
    "index": "int64",
    "task_index": "int64",
}

_QUANTILES = {"q01": 0.01, "q10": 0.10, "q50": 0.50, "q90": 0.90, "q99": 0.99}
_STATS = ("min", "max", "mean", "std", "count", *_QUANTILES)


# -- export -------------------------------------------------------------------------------


def _stats(values: NDArray[Any]) -> dict[str, list[float] | list[int]]:
    """LeRobot's per-feature statistics of ``(n, k)`` values (lists of length k).

    min, max, mean, std, count and the quantiles q01 ... q99 (LeRobot 0.4 writes them;
    its QUANTILES normalization reads them).
    """
    x = np.asarray(values, dtype=np.float64)
    out: dict[str, list[float] | list[int]] = {
        "min": x.min(axis=0).tolist(),
        "max": x.max(axis=0).tolist(),
        "mean": x.mean(axis=0).tolist(),
        "std": x.std(axis=0).tolist(),
        "count": [len(x)],
    }
    for name, q in _QUANTILES.items():
        out[name] = np.quantile(x, q, axis=0).tolist()
    return out


def _regular_fps(ds: Dataset) -> float:
    """The dataset's frame rate; every time step must match it within ``TOLERANCE_S``."""
    steps = [np.diff(ep.t) for ep in ds.episodes() if len(ep) > 1]
    if not steps:
        return 1.0 / CONTROL_PERIOD
    all_steps = np.concatenate(steps)
    period = float(np.median(all_steps))
    for ep, dt in zip((e for e in ds.episodes() if len(e) > 1), steps, strict=True):
        bad = np.abs(dt - period) > TOLERANCE_S
        if bad.any():
            i = int(np.argmax(bad)) + 1
            raise DatasetError(
                f"time steps are not regular (dt = {dt[i - 1] * 1000:.6g} ms here, "
                f"{period * 1000:.6g} ms typically); a LeRobot dataset has one frame rate: "
                "resample the data first (import-csv --resample)",
                episode=ep.id,
                row=i,
                field="t",
            )
    fps = round(1.0 / period, 6)
    return float(int(fps)) if fps == int(fps) else fps


def _tasks_table(tasks: list[str]) -> pa.Table:
    """``meta/tasks.parquet``: a pandas frame indexed by task text, column ``task_index``."""
    table = pa.table(
        {
            "task_index": pa.array(range(len(tasks)), type=pa.int64()),
            "task": pa.array(tasks, type=pa.string()),
        }
    )
    pandas_md = {
        "index_columns": ["task"],
        "column_indexes": [
            {
                "name": None,
                "field_name": None,
                "pandas_type": "unicode",
                "numpy_type": "object",
                "metadata": {"encoding": "UTF-8"},
            }
        ],
        "columns": [
            {
                "name": "task_index",
                "field_name": "task_index",
                "pandas_type": "int64",
                "numpy_type": "int64",
                "metadata": None,
            },
            {
                "name": "task",
                "field_name": "task",
                "pandas_type": "unicode",
                "numpy_type": "object",
                "metadata": None,
            },
        ],
        "creator": {"library": "pyarrow", "version": pa.__version__},
        "pandas_version": "2.2.3",
    }
    return table.replace_schema_metadata({b"pandas": json.dumps(pandas_md).encode()})


def _vector(values: NDArray[np.float32]) -> pa.FixedSizeListArray:
    k = values.shape[1]
    flat = pa.array(np.ascontiguousarray(values, dtype=np.float32).reshape(-1), type=pa.float32())
    return pa.FixedSizeListArray.from_arrays(flat, k)


def _write_tree(ds: Dataset, root: Path, task: str, robot_type: str | None) -> None:
    fps = _regular_fps(ds)
    n_eps = len(ds)
    lengths = ds.lengths
    offsets = ds.offsets
    episode_index = np.repeat(np.arange(n_eps, dtype=np.int64), lengths)
    frame_index = np.concatenate([np.arange(n, dtype=np.int64) for n in lengths])
    t0 = ds.t[offsets[:-1]]
    timestamp = (ds.t - np.repeat(t0, lengths)).astype(np.float32)
    names = ds.behaviors
    per_frame = len(names) > 1  # complex demonstrations: each frame's sub-behavior
    if per_frame:
        assert ds.behavior is not None
        tasks = list(dict.fromkeys(ds.behavior.tolist()))
        lookup = {name: i for i, name in enumerate(tasks)}
        task_index = np.array([lookup[b] for b in ds.behavior.tolist()], dtype=np.int64)
    else:
        tasks = [task]
        task_index = np.zeros(ds.n_samples, dtype=np.int64)
    state = ds.sensors.astype(np.float32)
    action = ds.commands.astype(np.float32)
    index = np.arange(ds.n_samples, dtype=np.int64)
    frames = {
        STATE: state,
        ACTION: action,
        "timestamp": timestamp[:, None],
        "frame_index": frame_index[:, None],
        "episode_index": episode_index[:, None],
        "index": index[:, None],
        "task_index": task_index[:, None],
    }
    data = pa.table(
        {
            STATE: _vector(state),
            ACTION: _vector(action),
            "timestamp": pa.array(timestamp, type=pa.float32()),
            "frame_index": pa.array(frame_index, type=pa.int64()),
            "episode_index": pa.array(episode_index, type=pa.int64()),
            "index": pa.array(index, type=pa.int64()),
            "task_index": pa.array(task_index, type=pa.int64()),
        }
    )
    features: dict[str, Any] = {
        STATE: {
            "dtype": "float32",
            "shape": [len(ds.sensor_channels)],
            "names": list(ds.sensor_channels),
        },
        ACTION: {
            "dtype": "float32",
            "shape": [len(ds.command_channels)],
            "names": list(ds.command_channels),
        },
        **{
            name: {"dtype": dtype, "shape": [1], "names": None}
            for name, dtype in DEFAULT_FEATURES.items()
        },
    }
    info = {
        "codebase_version": CODEBASE_VERSION,
        "robot_type": robot_type,
        "total_episodes": n_eps,
        "total_frames": ds.n_samples,
        "total_tasks": len(tasks),
        "chunks_size": 1000,
        "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 200,
        "fps": fps,
        "splits": {"train": f"0:{n_eps}"},
        "data_path": DATA_PATH,
        "video_path": None,
        "features": features,
    }
    stats = {name: _stats(values) for name, values in frames.items()}
    episodes: dict[str, Any] = {
        "episode_index": pa.array(range(n_eps), type=pa.int64()),
        "tasks": pa.array(
            [
                list(dict.fromkeys(tasks[i] for i in task_index[a:b].tolist()))
                for a, b in itertools.pairwise(offsets.tolist())
            ],
            type=pa.list_(pa.string()),
        ),
        "length": pa.array(lengths, type=pa.int64()),
        "data/chunk_index": pa.array(np.zeros(n_eps, dtype=np.int64)),
        "data/file_index": pa.array(np.zeros(n_eps, dtype=np.int64)),
        "dataset_from_index": pa.array(offsets[:-1], type=pa.int64()),
        "dataset_to_index": pa.array(offsets[1:], type=pa.int64()),
        "meta/episodes/chunk_index": pa.array(np.zeros(n_eps, dtype=np.int64)),
        "meta/episodes/file_index": pa.array(np.zeros(n_eps, dtype=np.int64)),
    }
    for name, values in frames.items():
        per_episode = [_stats(values[a:b]) for a, b in itertools.pairwise(offsets.tolist())]
        for stat in _STATS:
            typ = pa.int64() if stat == "count" else pa.float64()
            episodes[f"stats/{name}/{stat}"] = pa.array(
                [s[stat] for s in per_episode], type=pa.list_(typ)
            )
    ours = {
        "format": 1,
        "metadata": ds.metadata,
        "episode_ids": ds.episode_ids.tolist(),
        "t0": t0.tolist(),
        "behavior_from_task": per_frame,
        "behavior_name": names[0] if len(names) == 1 else None,
        "units": {spec.name: spec.unit for spec in (*ds.channel_specs, *ds.command_specs)},
    }
    data_file = root / DATA_PATH.format(chunk_index=0, file_index=0)
    data_file.parent.mkdir(parents=True)
    pq.write_table(data, data_file)
    (root / EPISODES_PATH).parent.mkdir(parents=True)
    pq.write_table(pa.table(episodes), root / EPISODES_PATH)
    pq.write_table(_tasks_table(tasks), root / "meta" / "tasks.parquet")
    for name, doc in (("info.json", info), ("stats.json", stats)):
        (root / "meta" / name).write_text(json.dumps(doc, indent=4) + "\n", encoding="utf-8")
    (root / OURS).write_text(json.dumps(ours, indent=2, sort_keys=True) + "\n", encoding="utf-8")


def export_lerobot(
    ds: Dataset,
    folder: str | os.PathLike[str],
    *,
    task: str | None = None,
    robot_type: str | None = "differential_drive",
) -> Path:
    """Write ``ds`` as a LeRobotDataset v3.0 folder (module docstring); all or nothing.

    Parameters
    ----------
    ds
        Demonstrations or generated traces; their time steps must be regular (one frame
        rate, within LeRobot's 0.1 ms tolerance).
    folder
        A new folder (or an empty one); it is written in a temporary folder beside it
        and renamed into place, so a failure leaves nothing behind.
    task
        The task text of every frame (default: the dataset's behavior). Complex
        demonstrations use each frame's sub-behavior instead.
    robot_type
        ``info.json``'s ``robot_type``.

    Raises
    ------
    DatasetError
        Irregular time steps, or a folder that exists and is not empty.
    """
    target = Path(folder)
    if target.exists() and (not target.is_dir() or any(target.iterdir())):
        raise DatasetError(
            "exists and is not an empty folder; give a new folder for the LeRobot dataset",
            file=str(folder),
        )
    text = task if task is not None else str(ds.metadata.get("behavior") or "behavior")
    if not text.strip():
        raise ConfigError("--task must not be empty")
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.parent / f".{target.name}.{secrets.token_hex(4)}.tmp"
    try:
        tmp.mkdir()
        _write_tree(ds, tmp, text, robot_type)
        if target.exists():
            target.rmdir()
        os.rename(tmp, target)
    except OSError as exc:
        raise DatasetError(
            f"cannot write the LeRobot dataset ({exc.strerror or exc})", file=str(folder)
        ) from None
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return target


# -- import -------------------------------------------------------------------------------
#
# Every value read from the folder is typed and range-checked before numpy sees it, and
# every refusal is one DatasetError line naming the file (and the field, episode and row
# where there is one). The files are opened through behavior_hmm._safe_read (regular
# files only, sizes and nesting bounded); a Parquet file's footer is checked against the
# bounds below before its columns are read, and only the columns used are read.

#: ``fps`` in ``meta/info.json``: ``0 < fps <= MAX_FPS`` frames per second.
MAX_FPS: Final[float] = 10_000.0

#: Frames in all data files together (from the Parquet footers, before reading): about
#: 8.9 hours at the controller's 62.5 Hz.
MAX_FRAMES: Final[int] = 2_000_000

#: Uncompressed bytes of the columns read from one Parquet row group (from the footer);
#: row groups are read in batches of at most this (a read takes about 3.5 times as much).
MAX_READ_BYTES: Final[int] = 96 * 1024 * 1024

#: Values (vector elements included) in the columns read from one Parquet row group.
MAX_READ_VALUES: Final[int] = MAX_READ_BYTES // 4

#: Uncompressed bytes of the columns read from all data files together (bounds the time
#: spent decompressing).
MAX_TOTAL_READ_BYTES: Final[int] = 512 * 1024 * 1024

#: Parquet files under ``data/``.
MAX_DATA_FILES: Final[int] = 10_000

#: Start time of an episode in ``meta/behavior_hmm.json`` (``t0``), in s either side of 0
#: (about 317 years: a Unix time fits; float64 still resolves 2 µs there).
MAX_START_TIME_S: Final[float] = 1e10

#: Dimensions of a feature's ``shape`` in ``meta/info.json``.
_MAX_DIMS: Final[int] = 8

_INT64_MAX: Final[int] = 2**63 - 1

_INFO: Final[str] = "meta/info.json"
_TASKS: Final[str] = "meta/tasks.parquet"
_INDEX_COLUMNS: Final[tuple[str, ...]] = ("episode_index", "frame_index", "task_index")


@dataclass(frozen=True)
class FeatureRef:
    """A feature (``observation.state``) and, for a vector, one element (name or index)."""

    feature: str
    element: str | None = None

    def __str__(self) -> str:
        return self.feature if self.element is None else f"{self.feature}:{self.element}"


def parse_feature_ref(spec: str) -> FeatureRef:
    """``observation.state:angle`` / ``observation.state:2`` / ``timestamp``."""
    feature, sep, element = spec.strip().partition(":")
    if not feature.strip() or (sep and not element.strip()):
        raise ConfigError(
            f"--map: bad feature '{spec}' (expected FEATURE or FEATURE:NAME, e.g. "
            "observation.state:angle or observation.state:2)"
        )
    return FeatureRef(feature.strip(), element.strip() if sep else None)


def _names(feature: Mapping[str, Any]) -> list[str]:
    """Element names of a vector feature (``names`` may be a list or ``{axis: list}``).

    Lenient (``[]`` for anything else): used to look our channels up among features that
    are not read. A feature that is read has its names checked by :func:`_feature_spec`.
    """
    names = feature.get("names")
    if isinstance(names, dict) and len(names) == 1:
        names = next(iter(names.values()))
    if isinstance(names, list) and all(isinstance(n, str) for n in names):
        return list(names)
    return []


def _default_refs(
    features: Mapping[str, Any],
    sensors: Collection[str] = SENSOR_CHANNELS,
    commands: Collection[str] = COMMAND_CHANNELS,
) -> dict[str, FeatureRef]:
    """Our channels found by name among the features' element names (or as features).

    ``sensors`` are looked up first in ``observation.state``, ``commands`` in ``action``.
    """
    refs: dict[str, FeatureRef] = {"t": FeatureRef("timestamp")}
    for channel in (*sensors, *commands):
        prefer = (STATE, ACTION) if channel in sensors else (ACTION, STATE)
        order = [*prefer, *(f for f in features if f not in prefer)]
        for name in order:
            feature = features.get(name)
            if isinstance(feature, Mapping) and channel in _names(feature):
                refs[channel] = FeatureRef(name, channel)
                break
        else:
            for name in (channel, f"observation.{channel}", f"action.{channel}"):
                if name in features:
                    refs[channel] = FeatureRef(name)
                    break
    return refs


def _kind(value: Any) -> str:
    """What a JSON value is, for messages."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true/false"
    if isinstance(value, int | float):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, dict):
        return "an object"
    return type(value).__name__


def _show(value: Any, limit: int = 40) -> str:
    """A JSON value, shortened for a message."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**limit:
        return f"a {len(str(abs(value)))}-digit number"
    try:
        text = json.dumps(value, ensure_ascii=True)
    except (TypeError, ValueError):
        text = _kind(value)
    return text if len(text) <= limit else f"{_kind(value)} {text[: limit - 3]}..."


def _found(doc: Mapping[str, Any], key: str) -> str:
    return f"found {_show(doc[key])}" if key in doc else "missing"


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _one_line(exc: BaseException, limit: int = 160) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


# -- meta/info.json


@dataclass(frozen=True)
class _Info:
    file: str
    features: dict[str, dict[str, Any]]
    fps: int | float
    codebase_version: str | None


def _read_info(path: Path) -> _Info:
    file = str(path)
    info = load_json(path, file=file)
    if not isinstance(info, dict):
        raise DatasetError(f"must hold a JSON object (found {_kind(info)})", file=file)
    features = info.get("features")
    if not isinstance(features, dict) or not features:
        raise DatasetError(
            f"has no 'features' table (a JSON object of features; {_found(info, 'features')})",
            file=file,
            field="features",
        )
    for name, feature in features.items():
        if not isinstance(feature, dict):
            raise DatasetError(
                f"must be a JSON object (dtype, shape, names) (found {_kind(feature)})",
                file=file,
                field=f"features.{name}",
            )
    fps = info.get("fps")
    if not isinstance(fps, int | float) or isinstance(fps, bool) or not 0 < fps <= MAX_FPS:
        raise DatasetError(
            f"must be the frame rate, a number of frames per second with 0 < fps <= "
            f"{MAX_FPS:g} ({_found(info, 'fps')})",
            file=file,
            field="fps",
        )
    version = info.get("codebase_version")
    if version is not None and not isinstance(version, str):
        raise DatasetError(
            f"must be a string like {CODEBASE_VERSION!r} (found {_show(version)})",
            file=file,
            field="codebase_version",
        )
    return _Info(file, features, fps, version)


@dataclass(frozen=True)
class _Feature:
    """A feature that is read: its element names and width as ``info.json`` states them."""

    name: str
    names: list[str] | None
    width: int | None


def _feature_spec(info: _Info, name: str) -> _Feature:
    feature = info.features[name]
    field = f"features.{name}.names"
    raw = feature.get("names")
    names: list[str] | None = None
    if raw is not None:
        listed = raw
        if isinstance(raw, dict):
            if len(raw) != 1:
                raise DatasetError(
                    "must be a list of element names or {axis: list of names} with one axis "
                    f"(found an object of {len(raw)} keys)",
                    file=info.file,
                    field=field,
                )
            listed = next(iter(raw.values()))
        if not isinstance(listed, list):
            raise DatasetError(
                f"must be a list of element names (found {_show(raw)})", file=info.file, field=field
            )
        for i, n in enumerate(listed):
            if not isinstance(n, str):
                raise DatasetError(
                    f"element {i} must be a name (a string), found {_show(n)}",
                    file=info.file,
                    field=field,
                )
        seen: set[str] = set()
        for n in listed:
            if n in seen:
                raise DatasetError(f"names '{n[:40]}' twice", file=info.file, field=field)
            seen.add(n)
        names = list(listed)
    shape = feature.get("shape")
    width: int | None = None
    if shape is not None:
        if (
            not isinstance(shape, list)
            or not 1 <= len(shape) <= _MAX_DIMS
            or not all(_is_int(d) and 1 <= d <= MAX_READ_VALUES for d in shape)
        ):
            raise DatasetError(
                f"must be a list of 1 to {_MAX_DIMS} positive sizes, e.g. [4] "
                f"(found {_show(shape)})",
                file=info.file,
                field=f"features.{name}.shape",
            )
        width = math.prod(shape)
        if names is not None and len(shape) == 1 and len(names) != width:
            raise DatasetError(
                f"lists {len(names)} names but 'shape' says {width} values per frame",
                file=info.file,
                field=field,
            )
    return _Feature(name, names, width)


# -- meta/behavior_hmm.json


@dataclass(frozen=True)
class _Ours:
    file: str
    metadata: dict[str, Any]
    episode_ids: list[int] | None
    t0: list[float] | None
    behavior_from_task: bool
    behavior_name: str | None


def _read_ours(path: Path) -> _Ours:
    """Our own file, every key typed (unknown keys are ignored, for later versions)."""
    file = str(path)
    doc = load_json(path, file=file)
    if not isinstance(doc, dict):
        raise DatasetError(f"must hold a JSON object (found {_kind(doc)})", file=file)

    def bad(key: str, what: str) -> DatasetError:
        return DatasetError(f"must be {what} ({_found(doc, key)})", file=file, field=key)

    if doc.get("format") != 1 or not _is_int(doc.get("format")):
        raise bad("format", "1 (the only version of this file)")
    metadata = doc.get("metadata")
    if metadata is None:
        metadata = {}
    elif not isinstance(metadata, dict):
        raise bad("metadata", "a JSON object (the dataset's metadata)")
    ids = doc.get("episode_ids")
    if ids is not None:
        if not isinstance(ids, list):
            raise bad("episode_ids", "a list of integer episode ids")
        for i, v in enumerate(ids):
            if not _is_int(v) or not -_INT64_MAX <= v <= _INT64_MAX:
                raise DatasetError(
                    f"episode id {i} must be an integer within int64 (found {_show(v)})",
                    file=file,
                    field="episode_ids",
                )
        if len(set(ids)) != len(ids):
            twice = next(v for k, v in enumerate(ids) if v in ids[:k])
            raise DatasetError(f"episode id {twice} appears twice", file=file, field="episode_ids")
    t0 = doc.get("t0")
    if t0 is not None:
        if not isinstance(t0, list):
            raise bad("t0", "a list of episode start times (s)")
        for i, v in enumerate(t0):
            if not _is_number(v) or not -MAX_START_TIME_S <= v <= MAX_START_TIME_S:
                raise DatasetError(
                    f"start time {i} must be a number of seconds within "
                    f"±{MAX_START_TIME_S:g} (found {_show(v)})",
                    file=file,
                    field="t0",
                )
        t0 = [float(v) for v in t0]
    from_task = doc.get("behavior_from_task", False)
    if not isinstance(from_task, bool):
        raise bad("behavior_from_task", "true or false")
    name = doc.get("behavior_name")
    if name is not None and (not isinstance(name, str) or not name):
        raise bad("behavior_name", "a behavior name (a string) or null")
    # the channels and commands the metadata declares (checked here, naming this file)
    declared = {
        spec.name: spec.unit
        for spec in (
            *declared_channels(metadata, file=file),
            *declared_commands(metadata, file=file),
        )
    }
    units = doc.get("units")
    if units is not None:
        if not isinstance(units, dict):
            raise bad("units", "a JSON object of channel -> unit")
        known = {name: UNITS[name] for name in UNITS}
        known.update(declared)
        for channel, unit in units.items():
            if channel not in known or unit != known[channel]:
                want = f"'{known[channel]}'" if channel in known else "none (not our channel)"
                raise DatasetError(
                    f"unit of '{channel[:40]}' is {_show(unit)}; this reader takes {want}",
                    file=file,
                    field="units",
                )
    return _Ours(file, metadata, ids, t0, from_task, name)


# -- Parquet files


@contextlib.contextmanager
def _parquet(path: Path, file: str) -> Iterator[pq.ParquetFile]:
    """The Parquet file ``path`` (a regular file, opened without waiting), footer read."""
    resolved = check_regular(path, file=file)
    flags = os.O_RDONLY | getattr(os, "O_BINARY", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(resolved, flags)
    except OSError as exc:
        raise DatasetError(f"cannot read file ({exc.strerror or exc})", file=file) from None
    with os.fdopen(fd, "rb") as handle:
        if not S_ISREG(os.fstat(handle.fileno()).st_mode):  # swapped after the check
            raise DatasetError("not a regular file; give a file", file=file)
        try:
            reader = pq.ParquetFile(handle)
            _ = reader.schema_arrow  # read and convert the schema now
        except Exception as exc:  # pyarrow raises many kinds on a damaged file
            raise DatasetError(f"not a Parquet file ({_one_line(exc)})", file=file) from None
        yield reader


def _leaves(typ: pa.DataType) -> int:
    """Parquet leaf columns of an Arrow type."""
    if isinstance(typ, pa.ExtensionType):
        return _leaves(typ.storage_type)
    if pa.types.is_struct(typ):
        return sum(_leaves(typ.field(i).type) for i in range(typ.num_fields))
    if pa.types.is_map(typ):
        return _leaves(typ.key_type) + _leaves(typ.item_type)
    if isinstance(typ, pa.ListType | pa.LargeListType | pa.FixedSizeListType):
        return _leaves(typ.value_type)
    return 1


def _leaf_indices(reader: pq.ParquetFile, columns: Collection[str]) -> list[int]:
    """Indices of the Parquet leaf columns of the top-level ``columns`` (all, if unsure)."""
    schema = reader.schema_arrow
    n_leaves = reader.metadata.num_columns
    try:
        counts = [_leaves(f.type) for f in schema]
    except RecursionError:
        return list(range(n_leaves))
    if sum(counts) != n_leaves:
        return list(range(n_leaves))
    starts = list(itertools.accumulate(counts, initial=0))
    out: list[int] = []
    for i, field in enumerate(schema):
        if field.name in columns:
            out.extend(range(starts[i], starts[i + 1]))
    return out


@dataclass(frozen=True)
class _Footer:
    """A Parquet file's rows, and its row groups in batches read one at a time."""

    rows: int
    batches: list[tuple[list[int], int]]  # row groups read together, the first one's row
    n_bytes: int  # uncompressed, in the columns read


def _check_footer(reader: pq.ParquetFile, columns: Collection[str], file: str) -> _Footer:
    """The file's footer, its sizes in ``columns`` checked against the bounds.

    Row groups are batched so that each read holds at most ``MAX_READ_BYTES`` and
    ``MAX_READ_VALUES`` (uncompressed, in the columns read); one row group past them is
    refused.
    """
    groups: list[tuple[int, int, int]] = []  # rows, bytes, values
    try:
        md = reader.metadata
        leaves = _leaf_indices(reader, columns)
        declared = md.num_rows
        for g in range(md.num_row_groups):
            group = md.row_group(g)
            n_bytes = n_values = 0
            for j in leaves:
                chunk = group.column(j)
                n_bytes += max(chunk.total_uncompressed_size, 0)
                n_values += max(chunk.num_values, 0)
            groups.append((group.num_rows, n_bytes, n_values))
    except Exception as exc:  # pyarrow raises many kinds on a damaged footer
        raise DatasetError(f"damaged Parquet footer ({_one_line(exc)})", file=file) from None
    rows = sum(r for r, _, _ in groups)
    if rows != declared or any(r < 0 for r, _, _ in groups):
        raise DatasetError(
            f"damaged Parquet footer (it says {declared:,} rows, its row groups {rows:,})",
            file=file,
        )
    batches: list[tuple[list[int], int]] = []
    current: list[int] = []
    first = row = batch_bytes = batch_values = 0
    for g, (n, n_bytes, n_values) in enumerate(groups):
        if n_bytes > MAX_READ_BYTES or n_values > MAX_READ_VALUES:
            raise DatasetError(
                f"row group {g} holds {n_values:,} values, {n_bytes / 2**20:,.0f} MiB "
                "uncompressed in the columns read (Parquet footer); this reader takes at most "
                f"{MAX_READ_VALUES:,} values, {MAX_READ_BYTES // 2**20} MiB per row group",
                file=file,
            )
        if n:
            full = batch_bytes + n_bytes > MAX_READ_BYTES
            if current and (full or batch_values + n_values > MAX_READ_VALUES):
                batches.append((current, first))
                current, batch_bytes, batch_values = [], 0, 0
            if not current:
                first = row
            current.append(g)
            batch_bytes += n_bytes
            batch_values += n_values
        row += n
    if current:
        batches.append((current, first))
    return _Footer(rows, batches, sum(b for _, b, _ in groups))


def _first(mask: NDArray[np.bool_]) -> int:
    return int(np.argmax(mask))


def _int_column(table: pa.Table, name: str, file: str, offset: int = 0) -> NDArray[np.int64]:
    """An index column (``episode_index``, ...): integers, none null, none negative.

    ``offset``: the file's row of the table's first row (named in errors).
    """
    col = table.column(name).combine_chunks()
    if not pa.types.is_integer(col.type):
        raise DatasetError(f"wrong type {col.type} (expected integers)", file=file, field=name)
    if col.null_count:
        row = _first(pc.is_null(col).to_numpy(zero_copy_only=False))
        raise DatasetError("missing value (null)", file=file, row=offset + row, field=name)
    values = col.to_numpy(zero_copy_only=False)
    if values.dtype.kind == "u" and len(values) and int(values.max()) > _INT64_MAX:
        row = _first(values > _INT64_MAX)
        raise DatasetError(
            f"{int(values[row])} is too large for int64", file=file, row=offset + row, field=name
        )
    out = values.astype(np.int64)
    if len(out) and (out < 0).any():
        row = _first(out < 0)
        raise DatasetError(
            f"negative index {int(out[row])}", file=file, row=offset + row, field=name
        )
    return out


def _element(ref: FeatureRef, spec: _Feature, k: int) -> int:
    """The index of ``ref``'s element in a vector of ``k``."""
    names = spec.names or []
    if ref.element is None:
        if k != 1:
            listing = ", ".join(names) if names else f"0..{k - 1}"
            raise ConfigError(
                f"--map: feature '{ref.feature}' is a vector of {k}; name an element: "
                f"{ref.feature}:NAME or {ref.feature}:INDEX (elements: {listing})"
            )
        return 0
    if ref.element in names:
        return names.index(ref.element)
    if re.fullmatch(r"\d+", ref.element) and int(ref.element) < k:
        return int(ref.element)
    listing = ", ".join(names) if names else f"indices 0..{k - 1}"
    raise ConfigError(
        f"--map: feature '{ref.feature}' has no element '{ref.element}' "
        f"(elements: {listing}){suggest(ref.element, names)}"
    )


def _check_width(spec: _Feature, k: int, info: _Info, file: str) -> None:
    """The width ``info.json`` states for a feature (names, shape) is the data's."""
    if spec.names and len(spec.names) != k:
        raise DatasetError(
            f"lists {len(spec.names)} names but {file} holds {k} values per frame",
            file=info.file,
            field=f"features.{spec.name}.names",
        )
    if spec.width is not None and spec.width != k:
        raise DatasetError(
            f"says {spec.width} values per frame but {file} holds {k}",
            file=info.file,
            field=f"features.{spec.name}.shape",
        )


def _column(
    table: pa.Table,
    ref: FeatureRef,
    spec: _Feature,
    info: _Info,
    file: str,
    offset: int = 0,
    widths: dict[str, int] | None = None,
) -> NDArray[np.float64]:
    """One numeric column of the frames (a vector feature's element by name or index).

    ``offset``: the file's row of the table's first row (named in errors); ``widths``:
    each vector feature's width so far (the same in every file and row group).
    """
    col = table.column(ref.feature).combine_chunks()
    if col.null_count:
        row = offset + _first(pc.is_null(col).to_numpy(zero_copy_only=False))
        raise DatasetError("missing value (null)", file=file, row=row, field=str(ref))
    typ = col.type
    n = len(col)
    if isinstance(typ, pa.ListType | pa.LargeListType | pa.FixedSizeListType):
        lengths = pc.list_value_length(col).to_numpy(zero_copy_only=False)
        k = typ.list_size if isinstance(typ, pa.FixedSizeListType) else int(lengths[0])
        if widths is not None:
            k = widths.setdefault(ref.feature, k)
        if not (lengths == k).all():
            row = _first(lengths != k)
            raise DatasetError(
                f"vectors of different lengths ({int(lengths[row])} here, {k} before)",
                file=file,
                row=offset + row,
                field=ref.feature,
            )
        flat = col.flatten()
        if not (pa.types.is_floating(flat.type) or pa.types.is_integer(flat.type)):
            raise DatasetError(f"wrong type {typ} (expected numbers)", file=file, field=ref.feature)
        if flat.null_count:
            row = offset + _first(pc.is_null(flat).to_numpy(zero_copy_only=False)) // max(k, 1)
            raise DatasetError("missing value (null)", file=file, row=row, field=str(ref))
        _check_width(spec, k, info, file)
        j = _element(ref, spec, k)
        values = flat.to_numpy(zero_copy_only=False).reshape(n, k)[:, j]
        return np.asarray(values, dtype=np.float64)
    if not (pa.types.is_floating(typ) or pa.types.is_integer(typ)):
        raise DatasetError(f"wrong type {typ} (expected numbers)", file=file, field=ref.feature)
    _check_width(spec, 1, info, file)
    if ref.element is not None:
        raise ConfigError(f"--map: feature '{ref.feature}' is a scalar; drop ':{ref.element}'")
    return np.asarray(col.to_numpy(zero_copy_only=False), dtype=np.float64)


def _data_files(data: Path, file: str) -> list[Path]:
    """``data/**/*.parquet``, symlinked folders not followed, at most MAX_DATA_FILES."""
    found: list[Path] = []
    for top, dirs, names in os.walk(data):
        dirs.sort()
        for name in names:
            if name.endswith(".parquet"):
                found.append(Path(top) / name)
                if len(found) > MAX_DATA_FILES:
                    raise DatasetError(
                        f"more than {MAX_DATA_FILES:,} data files (data/**/*.parquet); "
                        "this reader takes at most that many",
                        file=file,
                    )
    return sorted(found)


@dataclass
class _Frames:
    """The columns read from the data files, concatenated (file order)."""

    episode: NDArray[np.int64]
    frame: NDArray[np.int64] | None
    task: NDArray[np.int64] | None
    values: dict[str, NDArray[np.float64]]
    source: NDArray[np.int32]  # the data file of each row (index into ``paths``)
    paths: list[str]


def _read_frames(
    paths: list[Path],
    refs: Mapping[str, FeatureRef],
    info: _Info,
    need_task: bool,
) -> _Frames:
    specs = {ref.feature: _feature_spec(info, ref.feature) for ref in refs.values()}
    index_columns = [c for c in _INDEX_COLUMNS if need_task or c != "task_index"]
    wanted = [*dict.fromkeys([*specs, *index_columns])]
    files: list[tuple[str, list[str], int]] = []
    total = total_bytes = 0
    # first pass: footers only (the bounds hold before anything is read)
    present_in_all = set(index_columns)
    for path in paths:
        file = str(path)
        with _parquet(path, file) as reader:
            names = reader.schema_arrow.names
            for name in wanted:
                if names.count(name) > 1:
                    raise DatasetError(f"column '{name}' appears twice", file=file, field=name)
            for name in ("episode_index", *specs):
                if name not in names:
                    what = "column" if name == "episode_index" else "feature (from info.json)"
                    raise DatasetError(f"no '{name}' {what} in this data file", file=file)
            if need_task and "task_index" not in names:
                raise DatasetError(
                    "no 'task_index' column (meta/behavior_hmm.json says the tasks are the "
                    "behaviors)",
                    file=file,
                )
            present_in_all &= set(names)
            columns = [n for n in wanted if n in names]
            footer = _check_footer(reader, columns, file)
            rows = footer.rows
        total += rows
        total_bytes += footer.n_bytes
        if total_bytes > MAX_TOTAL_READ_BYTES:
            raise DatasetError(
                f"the data files hold more than {MAX_TOTAL_READ_BYTES // 2**20} MiB "
                f"uncompressed in the columns read ({footer.n_bytes / 2**20:,.0f} MiB in this "
                "one, from its Parquet footer); this reader takes at most "
                f"{MAX_TOTAL_READ_BYTES // 2**20} MiB",
                file=file,
            )
        if total > MAX_FRAMES:
            raise DatasetError(
                f"the data files hold more than {MAX_FRAMES:,} frames ({rows:,} in this one, "
                f"from its Parquet footer); this reader takes at most {MAX_FRAMES:,}",
                file=file,
            )
        files.append((file, columns, rows))
    use_frame = "frame_index" in present_in_all
    episode: list[NDArray[np.int64]] = []
    frame: list[NDArray[np.int64]] = []
    task: list[NDArray[np.int64]] = []
    values: dict[str, list[NDArray[np.float64]]] = {channel: [] for channel in refs}
    widths: dict[str, int] = {}
    counts: list[int] = []
    for path, (file, columns, rows) in zip(paths, files, strict=True):
        counts.append(rows)
        if rows == 0:
            continue
        with _parquet(path, file) as reader:
            footer = _check_footer(reader, columns, file)
            if footer.rows != rows:
                raise DatasetError("changed while it was read", file=file)
            for groups, offset in footer.batches:
                try:
                    table = reader.read_row_groups(groups, columns=columns, use_threads=False)
                except Exception as exc:  # pyarrow raises many kinds on a damaged file
                    raise DatasetError(
                        f"cannot read the data file ({_one_line(exc)})", file=file
                    ) from None
                episode.append(_int_column(table, "episode_index", file, offset))
                if use_frame:
                    frame.append(_int_column(table, "frame_index", file, offset))
                if need_task:
                    task.append(_int_column(table, "task_index", file, offset))
                for channel, ref in refs.items():
                    spec = specs[ref.feature]
                    column = _column(table, ref, spec, info, file, offset, widths)
                    values[channel].append(column)
                del table
                pa.default_memory_pool().release_unused()
    source = np.repeat(np.arange(len(paths), dtype=np.int32), counts)
    empty = np.zeros(0, dtype=np.int64)
    return _Frames(
        episode=np.concatenate(episode) if episode else empty,
        frame=(np.concatenate(frame) if frame else empty) if use_frame else None,
        task=(np.concatenate(task) if task else empty) if need_task else None,
        values={c: np.concatenate(v) if v else np.zeros(0) for c, v in values.items()},
        source=source,
        paths=[str(p) for p in paths],
    )


def _task_names(path: Path) -> dict[int, str]:
    """``meta/tasks.parquet``: task_index -> task text, both checked."""
    file = str(path)
    with _parquet(path, file) as reader:
        schema = reader.schema_arrow
        text_cols = [
            f.name for f in schema if pa.types.is_string(f.type) or pa.types.is_large_string(f.type)
        ]
        if "task_index" not in schema.names or not text_cols:
            raise DatasetError(
                "needs a 'task_index' column and a text column 'task'", file=file, field="task"
            )
        name = "task" if "task" in text_cols else text_cols[0]
        for column in ("task_index", name):
            if schema.names.count(column) > 1:
                raise DatasetError(f"column '{column}' appears twice", file=file, field=column)
        footer = _check_footer(reader, ["task_index", name], file)
        if footer.rows > MAX_FRAMES or len(footer.batches) > 1:
            raise DatasetError(
                f"too large ({footer.rows:,} tasks, from its Parquet footer); this reader "
                f"takes at most {MAX_FRAMES:,} tasks in {MAX_READ_BYTES // 2**20} MiB",
                file=file,
            )
        try:
            table = reader.read(columns=["task_index", name], use_threads=False)
        except Exception as exc:  # pyarrow raises many kinds on a damaged file
            raise DatasetError(f"cannot read the file ({_one_line(exc)})", file=file) from None
    index = _int_column(table, "task_index", file)
    text = table.column(name).combine_chunks()
    if text.null_count:
        row = _first(pc.is_null(text).to_numpy(zero_copy_only=False))
        raise DatasetError("missing task text (null)", file=file, row=row, field=name)
    uniq, first = np.unique(index, return_index=True)
    if len(uniq) != len(index):
        dup = np.ones(len(index), dtype=bool)
        dup[first] = False
        row = _first(dup)
        raise DatasetError(
            f"task_index {int(index[row])} appears twice", file=file, row=row, field="task_index"
        )
    return dict(zip(index.tolist(), text.to_pylist(), strict=True))


def import_lerobot(
    folder: str | os.PathLike[str],
    *,
    mapping: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    derive: Collection[str] | str = (),
    resample: bool = False,
    metadata: Mapping[str, Any] | None = None,
    channels: Sequence[ChannelSpec | Mapping[str, Any]] | None = None,
    commands: Sequence[ChannelSpec | Mapping[str, Any] | str] | None = None,
) -> Dataset:
    """Read a LeRobot dataset folder (v3.0; v2.x data files too) into a :class:`Dataset`.

    Parameters
    ----------
    folder
        The dataset's root (``meta/info.json``, ``data/**/*.parquet``).
    mapping
        Our channel -> ``FEATURE`` or ``FEATURE:ELEMENT`` (an element by its name in
        ``info.json`` or by index), e.g. ``{"angle": "observation.state:bearing",
        "left": "action:0"}``. Unmapped channels are looked up by name among the
        features' element names (a dataset written by :func:`export_lerobot` needs no
        mapping); ``t`` defaults to ``timestamp`` and episodes are ``episode_index``.
    units, derive, resample
        As for :func:`import_csv`.
    metadata
        Dataset metadata over the exported one (if the folder holds ours).
    channels
        A robot's own sensor channels to read besides ours, as for :func:`import_csv`
        (:class:`ChannelSpec` objects or declarations ``{"name", "unit", "range"}``),
        after any the metadata declares; each is found by name among the features'
        element names (``observation.state`` first) unless mapped. Read in its declared
        unit. A dataset of declared channels only (none of the four of the data
        contract found, mapped or derived) is a robot's own.
    commands
        The command channels in action order, replacing the metadata's (default: our two
        wheels): declarations ``{"name", "unit", "range", "rest"}`` or known names
        (``"left"``); each found by name (``action`` first) unless mapped.

    A folder written by :func:`export_lerobot` restores its declared channels and
    commands from ``meta/behavior_hmm.json`` without any of these.

    Time stamps lying on the frame grid (``timestamp ≈ frame_index / fps`` within 0.1
    ms) are snapped onto it, undoing float32 rounding. Angles beyond
    ±``MAX_UNWRAPPED_ANGLE`` degrees are refused (wrong units), the others wrapped.

    Raises
    ------
    DatasetError
        For anything wrong in the folder's files, in one line naming the file (and the
        field, episode and row where there is one): missing or special files (a FIFO, a
        device), JSON that is not what LeRobot writes (``fps`` outside ``0 < fps <=
        MAX_FPS``, ``names`` not matching the data), columns of the wrong type or with
        nulls, more than ``MAX_FRAMES`` frames or ``MAX_READ_BYTES`` per file (checked on
        the Parquet footers before reading), absurd angles.
    ConfigError
        For a mapping, unit or derivation that does not fit the folder.
    """
    file = str(folder)
    root = Path(folder)
    info_path = root / _INFO
    if not root.is_dir():
        raise DatasetError("no such folder" if not root.exists() else "not a folder", file=file)
    if not os.path.lexists(info_path):
        raise DatasetError("not a LeRobot dataset (no meta/info.json)", file=file)
    info = _read_info(info_path)
    features = info.features
    for name in (STATE, ACTION):  # ours, or LeRobot's usual: checked even if not read
        if name in features:
            _feature_spec(info, name)
    ours = _read_ours(root / OURS) if os.path.lexists(root / OURS) else None
    derived = parse_derive(derive)
    md: dict[str, Any] = dict(ours.metadata) if ours is not None else {}
    md.update(metadata or {})
    extras = _extra_channels(md, channels, file)
    if extras:
        md["channels"] = [spec.to_metadata() for spec in extras]
    if commands is not None:
        md["commands"] = [
            spec.to_metadata() for spec in declared_commands({"commands": list(commands)})
        ]
    command_specs = declared_commands(md, file=file)
    extra_names = tuple(spec.name for spec in extras)
    command_names = tuple(spec.name for spec in command_specs)
    mappable = ("t", *SENSOR_CHANNELS, *extra_names, *command_names)
    refs = _default_refs(features, (*SENSOR_CHANNELS, *extra_names), command_names)
    mapping = dict(mapping or {})
    for channel, spec in mapping.items():
        if channel not in mappable:
            raise ConfigError(
                f"--map {channel}: unknown channel (channels: {', '.join(mappable)}; episodes "
                f"are episode_index; declare a robot's own with --channel or --command)"
                f"{suggest(channel, mappable)}"
            )
        refs[channel] = parse_feature_ref(spec)
    for ref in refs.values():
        if ref.feature not in features:
            names = list(features)
            listing = ", ".join(names[:30]) + (", ..." if len(names) > 30 else "")
            raise ConfigError(
                f"--map: no feature '{ref.feature}' in meta/info.json (features: "
                f"{listing}){suggest(ref.feature, names[:1000])}"
            )
    for name in derived:
        if name in mapping:
            raise ConfigError(f"--derive {name}: it is mapped too (--map {name}=...); choose one")
        refs.pop(name, None)
    # a robot's own channels only: none of the data contract's four found, mapped or derived
    own_only = bool(extras) and not any(c in refs or c in derived for c in SENSOR_CHANNELS)
    needed = [c for c in mappable if not (own_only and c in SENSOR_CHANNELS)]
    missing = [c for c in needed if c not in refs and c not in derived]
    if missing:
        feature = ACTION if missing[0] in command_names else STATE
        raise ConfigError(
            f"no feature for channel(s) {', '.join(missing)}: map each with --map "
            f"CHANNEL=FEATURE:ELEMENT, e.g. --map {missing[0]}={feature}:0"
        )
    own_specs = [*extras, *(s for s in command_specs if s.name not in COMMAND_CHANNELS)]
    factors = {
        name: _extra_unit(own, unit)
        if (own := next((s for s in own_specs if s.name == name), None))
        else unit_factor(name, unit)
        for name, unit in (units or {}).items()
    }
    check_units_of_derived(factors, derived)

    data_dir = root / "data"
    paths = _data_files(data_dir, file) if data_dir.is_dir() else []
    if not paths:
        raise DatasetError("no data files (data/**/*.parquet)", file=file)
    tasks_from_frames = ours is not None and ours.behavior_name is None and ours.behavior_from_task
    frames = _read_frames(paths, refs, info, need_task=tasks_from_frames)
    episode_index = frames.episode
    if not len(episode_index):
        raise DatasetError("the data files hold no frames", file=str(data_dir))
    frame = frames.frame if frames.frame is not None else np.arange(len(episode_index))
    later = episode_index[1:] > episode_index[:-1]
    same = episode_index[1:] == episode_index[:-1]
    if not (later | (same & (frame[1:] >= frame[:-1]))).all():  # not in order yet
        order = np.lexsort((frame, episode_index))
        episode_index = episode_index[order]
        frame = frame[order]
        frames.source = frames.source[order]
        for channel in refs:
            frames.values[channel] = frames.values[channel][order]
        if frames.task is not None:
            frames.task = frames.task[order]
        del order
    del later, same
    source = frames.source
    columns: dict[str, NDArray[Any]] = {}
    with np.errstate(over="ignore", invalid="ignore"):
        for channel in refs:
            values = frames.values.pop(channel)
            columns[channel] = values * factors[channel] if channel in factors else values
    columns["t"] = _snap(columns["t"], frame, episode_index, info.fps)

    episode = episode_index
    if ours is not None:
        n_eps = int(episode_index.max()) + 1
        stale = f"; delete {OURS} to import without it"
        if ours.t0 is not None and "t" not in mapping:
            if len(ours.t0) != n_eps:
                raise DatasetError(
                    f"lists {len(ours.t0)} start times but the data files hold episodes "
                    f"0..{n_eps - 1}{stale}",
                    file=ours.file,
                    field="t0",
                )
            with np.errstate(over="ignore", invalid="ignore"):
                columns["t"] = columns["t"] + np.asarray(ours.t0, dtype=np.float64)[episode_index]
        if ours.episode_ids is not None:
            if len(ours.episode_ids) != n_eps:
                raise DatasetError(
                    f"lists {len(ours.episode_ids)} episode ids but the data files hold "
                    f"episodes 0..{n_eps - 1}{stale}",
                    file=ours.file,
                    field="episode_ids",
                )
            episode = np.asarray(ours.episode_ids, dtype=np.int64)[episode_index]
        if ours.behavior_name is not None:
            columns["behavior"] = np.full(len(episode), ours.behavior_name, dtype=object)
        elif ours.behavior_from_task:
            assert frames.task is not None
            task_index = frames.task
            tasks_path = root / _TASKS
            if not os.path.lexists(tasks_path):
                raise DatasetError(
                    f"no {_TASKS}, and {OURS} says the tasks are the behaviors", file=file
                )
            tasks = _task_names(tasks_path)
            used, inverse = np.unique(task_index, return_inverse=True)
            for i in used.tolist():
                if i not in tasks:
                    row = _first(task_index == i)
                    raise _frame_error(
                        f"task_index {i} is not in {_TASKS}",
                        row,
                        "task_index",
                        episode,
                        source,
                        frames.paths,
                    )
            texts = np.array([tasks[i] for i in used.tolist()], dtype=object)
            columns["behavior"] = texts[inverse.reshape(-1)]
    md["source"] = {
        "format": "lerobot",
        "folder": root.name,
        "codebase_version": info.codebase_version,
        "fps": info.fps,
        "mapping": {ch: str(ref) for ch, ref in refs.items()},
        "units": dict(units or {}),
    }
    columns["episode"] = episode
    if "angle" in columns:
        angle = columns["angle"]
        columns["angle"], absurd = wrap_imported_angles(angle)
        if absurd is not None:
            raise _frame_error(
                f"absurd angle {angle[absurd]:g} deg (beyond ±{MAX_UNWRAPPED_ANGLE:g} deg; "
                "wrong units? --unit angle=rad)",
                absurd,
                f"angle ({refs['angle']})",
                episode,
                source,
                frames.paths,
            )
    cols, md = finish(
        columns,
        md,
        file=file,
        derive=derived,
        resample_to=CONTROL_PERIOD if resample else None,
        what="dataset",
    )
    wrapping = [s.name for s in (*extras, *command_specs) if s.wraps and s.name != "angle"]
    if resample and wrapping:
        # resampled like the angle (unwrapped, interpolated, wrapped), not straight across
        for name in wrapping:
            grid = {"episode": columns["episode"], "t": columns["t"], "angle": columns[name]}
            cols[name] = resample_columns(grid, CONTROL_PERIOD)["angle"]
        cols, md = check_table(cols, md, file=file)
    return Dataset._trusted(cols, md)


def _frame_error(
    reason: str,
    i: int,
    field: str,
    episode: NDArray[np.int64],
    source: NDArray[np.int32],
    paths: list[str],
) -> DatasetError:
    """An error at sorted row ``i``: its data file, episode and row within the episode."""
    eid = int(episode[i])
    start = _first(episode == eid)
    return DatasetError(reason, file=paths[int(source[i])], episode=eid, row=i - start, field=field)


def _snap(
    t: NDArray[np.float64], frame: NDArray[np.int64], episode: NDArray[np.int64], fps: float
) -> NDArray[np.float64]:
    """``frame_index / fps`` (+ the episode's first time) where the time stamps lie on it."""
    if not len(t) or not np.isfinite(t).all():
        return t
    rate = float(fps)
    first = np.r_[True, episode[1:] != episode[:-1]]
    start_idx = np.maximum.accumulate(np.where(first, np.arange(len(t)), 0))
    with np.errstate(all="ignore"):  # a tiny fps overflows: then nothing lies on the grid
        t0 = t[start_idx] - frame[start_idx] / rate
        grid = t0 + frame / rate
        if np.all(np.abs(grid - t) <= TOLERANCE_S):
            t0 = np.where(np.abs(t0) <= TOLERANCE_S, 0.0, t0)
            return np.asarray(t0 + frame / rate, dtype=np.float64)
    return t
