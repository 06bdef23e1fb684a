"""LeRobot datasets (the v3.0 layout), files only: export our datasets, import theirs.

Layout written by :func:`export_lerobot` (LeRobotDataset v3.0)::

    DIR/
      data/chunk-000/file-000.parquet          one row per frame
      meta/info.json                           codebase_version "v3.0", fps, features, ...
      meta/stats.json                          min, max, mean, std, count per feature
      meta/tasks.parquet                       task (the pandas index) -> task_index
      meta/episodes/chunk-000/file-000.parquet one row per episode (lengths, indices, stats)
      meta/behavior_hmm.json                   ours: metadata, episode ids and start times

Frames hold ``observation.state`` (float32: distance m, linear_velocity m/s, angle deg,
angular_velocity deg/s, in ``SENSOR_CHANNELS`` order, names listed in ``info.json``),
``action`` (float32: left, right wheel speeds, rad/s), ``timestamp`` (float32, s from
the episode's start), ``frame_index``, ``episode_index``, ``index`` and ``task_index``
(int64). The task of a frame is the dataset's behavior (``--task``), or for complex
demonstrations (several sub-behaviors) the active sub-behavior. No videos. LeRobot
itself is not needed to write or read these files; the hub is never contacted.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import re
import secrets
import shutil
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
from numpy.typing import NDArray

from behavior_hmm.data._channels import COMMAND_CHANNELS, CONTROL_PERIOD, SENSOR_CHANNELS, UNITS
from behavior_hmm.data._dataset import Dataset
from behavior_hmm.data._transform import check_units_of_derived, finish, parse_derive
from behavior_hmm.data._units import unit_factor, wrap_degrees
from behavior_hmm.data._validate import suggest
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

_MAPPABLE = ("t", *SENSOR_CHANNELS, *COMMAND_CHANNELS)


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
            "shape": [len(SENSOR_CHANNELS)],
            "names": list(SENSOR_CHANNELS),
        },
        ACTION: {
            "dtype": "float32",
            "shape": [len(COMMAND_CHANNELS)],
            "names": list(COMMAND_CHANNELS),
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
        "units": {name: UNITS[name] for name in (*SENSOR_CHANNELS, *COMMAND_CHANNELS)},
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
    """Element names of a vector feature (``names`` may be a list or ``{axis: list}``)."""
    names = feature.get("names")
    if isinstance(names, dict) and len(names) == 1:
        names = next(iter(names.values()))
    if isinstance(names, list) and all(isinstance(n, str) for n in names):
        return list(names)
    return []


def _read_json(path: Path, file: str) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        text = " ".join(str(exc).split())[:160]
        raise DatasetError(f"cannot read {path.name} ({text})", file=file) from None


def _column(
    table: pa.Table, ref: FeatureRef, feature: Mapping[str, Any], file: str
) -> NDArray[np.float64]:
    """One numeric column of the frames (a vector feature's element by name or index)."""
    if ref.feature not in table.column_names:
        raise DatasetError(
            f"feature '{ref.feature}' is in info.json but not in the data files",
            file=file,
            field=str(ref),
        )
    col = table.column(ref.feature).combine_chunks()
    if col.null_count:
        raise DatasetError("missing values (null)", file=file, field=str(ref))
    typ = col.type
    if pa.types.is_fixed_size_list(typ) or pa.types.is_list(typ) or pa.types.is_large_list(typ):
        lengths = pc.list_value_length(col).to_numpy(zero_copy_only=False)
        k = int(lengths[0]) if len(lengths) else 0
        if len(lengths) and not (lengths == k).all():
            raise DatasetError("vectors of different lengths", file=file, field=ref.feature)
        flat = col.flatten()
        if not (pa.types.is_floating(flat.type) or pa.types.is_integer(flat.type)):
            raise DatasetError(f"wrong type {typ} (expected numbers)", file=file, field=ref.feature)
        values = flat.to_numpy(zero_copy_only=False).astype(np.float64).reshape(len(col), k)
        if ref.element is None:
            if k != 1:
                names = _names(feature)
                listing = ", ".join(names) if names else f"0..{k - 1}"
                raise ConfigError(
                    f"--map: feature '{ref.feature}' is a vector of {k}; name an element: "
                    f"{ref.feature}:NAME or {ref.feature}:INDEX (elements: {listing})"
                )
            return values[:, 0]
        names = _names(feature)
        if ref.element in names:
            j = names.index(ref.element)
        elif re.fullmatch(r"\d+", ref.element) and int(ref.element) < k:
            j = int(ref.element)
        else:
            listing = ", ".join(names) if names else f"indices 0..{k - 1}"
            raise ConfigError(
                f"--map: feature '{ref.feature}' has no element '{ref.element}' "
                f"(elements: {listing}){suggest(ref.element, names)}"
            )
        return values[:, j]
    if ref.element is not None:
        raise ConfigError(f"--map: feature '{ref.feature}' is a scalar; drop ':{ref.element}'")
    if not (pa.types.is_floating(typ) or pa.types.is_integer(typ)):
        raise DatasetError(f"wrong type {typ} (expected numbers)", file=file, field=ref.feature)
    out: NDArray[np.float64] = col.to_numpy(zero_copy_only=False).astype(np.float64)
    return out


def _default_refs(features: Mapping[str, Any]) -> dict[str, FeatureRef]:
    """Our channels found by name among the features' element names (or as features)."""
    refs: dict[str, FeatureRef] = {"t": FeatureRef("timestamp")}
    for channel in (*SENSOR_CHANNELS, *COMMAND_CHANNELS):
        prefer = (STATE, ACTION) if channel in SENSOR_CHANNELS else (ACTION, STATE)
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


def _task_names(root: Path, file: str) -> dict[int, str]:
    path = root / "meta" / "tasks.parquet"
    if not path.is_file():
        return {}
    try:
        table = pq.read_table(path)
    except Exception as exc:
        raise DatasetError(f"cannot read meta/tasks.parquet ({exc})", file=file) from None
    text_cols = [
        n
        for n in table.column_names
        if pa.types.is_string(table.schema.field(n).type)
        or pa.types.is_large_string(table.schema.field(n).type)
    ]
    if "task_index" not in table.column_names or not text_cols:
        return {}
    name = "task" if "task" in text_cols else text_cols[0]
    idx = table.column("task_index").to_pylist()
    texts = table.column(name).to_pylist()
    return {int(i): str(t) for i, t in zip(idx, texts, strict=True)}


def import_lerobot(
    folder: str | os.PathLike[str],
    *,
    mapping: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    derive: Collection[str] | str = (),
    resample: bool = False,
    metadata: Mapping[str, Any] | None = None,
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

    Time stamps lying on the frame grid (``timestamp ≈ frame_index / fps`` within 0.1
    ms) are snapped onto it, undoing float32 rounding.
    """
    file = str(folder)
    root = Path(folder)
    if not (root / "meta" / "info.json").is_file():
        raise DatasetError(
            "not a LeRobot dataset (no meta/info.json)" if root.is_dir() else "no such folder",
            file=file,
        )
    info = _read_json(root / "meta" / "info.json", file)
    features = info.get("features") if isinstance(info, dict) else None
    if not isinstance(features, dict):
        raise DatasetError("meta/info.json has no 'features' table", file=file)
    ours = _read_json(root / OURS, file) if (root / OURS).is_file() else None
    derived = parse_derive(derive)
    refs = _default_refs(features)
    mapping = dict(mapping or {})
    for channel, spec in mapping.items():
        if channel not in _MAPPABLE:
            raise ConfigError(
                f"--map {channel}: unknown channel (channels: {', '.join(_MAPPABLE)}; episodes "
                f"are episode_index){suggest(channel, _MAPPABLE)}"
            )
        refs[channel] = parse_feature_ref(spec)
    for ref in refs.values():
        if ref.feature not in features:
            raise ConfigError(
                f"--map: no feature '{ref.feature}' in meta/info.json (features: "
                f"{', '.join(features)}){suggest(ref.feature, list(features))}"
            )
    for name in derived:
        if name in mapping:
            raise ConfigError(f"--derive {name}: it is mapped too (--map {name}=...); choose one")
        refs.pop(name, None)
    missing = [c for c in _MAPPABLE if c not in refs and c not in derived]
    if missing:
        raise ConfigError(
            f"no feature for channel(s) {', '.join(missing)}: map each with --map "
            f"CHANNEL=FEATURE:ELEMENT, e.g. --map {missing[0]}=observation.state:0"
        )
    factors = {name: unit_factor(name, unit) for name, unit in (units or {}).items()}
    check_units_of_derived(factors, derived)

    paths = sorted((root / "data").glob("**/*.parquet"))
    if not paths:
        raise DatasetError("no data files (data/**/*.parquet)", file=file)
    try:
        table = pa.concat_tables([pq.read_table(p) for p in paths], promote_options="default")
    except Exception as exc:
        text = " ".join(str(exc).split())[:160]
        raise DatasetError(f"cannot read the data files ({text})", file=file) from None
    for needed in ("episode_index",):
        if needed not in table.column_names:
            raise DatasetError(f"the data files have no '{needed}' column", file=file)
    episode_index = table.column("episode_index").to_numpy().astype(np.int64)
    frame = (
        table.column("frame_index").to_numpy().astype(np.int64)
        if "frame_index" in table.column_names
        else np.arange(table.num_rows)
    )
    order = np.lexsort((frame, episode_index))
    table = table.take(pa.array(order))
    episode_index = episode_index[order]
    frame = frame[order]
    columns: dict[str, NDArray[Any]] = {}
    for channel, ref in refs.items():
        values = _column(table, ref, features[ref.feature], file)
        columns[channel] = values * factors[channel] if channel in factors else values
    columns["t"] = _snap(columns["t"], frame, episode_index, info.get("fps"))

    md: dict[str, Any] = {}
    if isinstance(ours, dict):
        md = dict(ours.get("metadata") or {})
        ids = ours.get("episode_ids")
        t0 = ours.get("t0")
        n_eps = int(episode_index.max()) + 1 if len(episode_index) else 0
        if isinstance(t0, list) and len(t0) == n_eps and "t" not in mapping:
            columns["t"] = columns["t"] + np.asarray(t0, dtype=np.float64)[episode_index]
        if isinstance(ids, list) and len(ids) == n_eps and all(isinstance(i, int) for i in ids):
            episode = np.asarray(ids, dtype=np.int64)[episode_index]
        else:
            episode = episode_index
        constant = ours.get("behavior_name")
        if isinstance(constant, str):
            columns["behavior"] = np.full(len(episode), constant, dtype=object)
        elif ours.get("behavior_from_task") and "task_index" in table.column_names:
            tasks = _task_names(root, file)
            task_index = table.column("task_index").to_numpy().astype(np.int64)
            columns["behavior"] = np.array(
                [tasks.get(int(i), str(i)) for i in task_index], dtype=object
            )
    else:
        episode = episode_index
    md.update(metadata or {})
    md["source"] = {
        "format": "lerobot",
        "folder": root.name,
        "codebase_version": info.get("codebase_version"),
        "fps": info.get("fps"),
        "mapping": {ch: str(ref) for ch, ref in refs.items()},
        "units": dict(units or {}),
    }
    columns["episode"] = episode
    angle = columns["angle"]
    columns["angle"] = np.where(np.isfinite(angle), wrap_degrees(angle), angle)
    cols, md = finish(
        columns,
        md,
        file=file,
        derive=derived,
        resample_to=CONTROL_PERIOD if resample else None,
        what="dataset",
    )
    return Dataset._trusted(cols, md)


def _snap(
    t: NDArray[np.float64], frame: NDArray[np.int64], episode: NDArray[np.int64], fps: Any
) -> NDArray[np.float64]:
    """``frame_index / fps`` (+ the episode's first time) where the time stamps lie on it."""
    if isinstance(fps, bool) or not isinstance(fps, int | float) or not fps > 0:
        return t
    if not math.isfinite(float(fps)) or not len(t):
        return t
    first = np.r_[True, episode[1:] != episode[:-1]]
    start_idx = np.maximum.accumulate(np.where(first, np.arange(len(t)), 0))
    t0 = t[start_idx] - frame[start_idx] / float(fps)
    grid = t0 + frame / float(fps)
    if np.all(np.abs(grid - t) <= TOLERANCE_S):
        t0 = np.where(np.abs(t0) <= TOLERANCE_S, 0.0, t0)
        return np.asarray(t0 + frame / float(fps), dtype=np.float64)
    return t
