"""Import ROS 1 and ROS 2 bags (``rosbags``, pure Python; the optional extra ``bags``).

Each channel is read from one field of one topic (``CHANNEL=TOPIC:FIELD``, dotted
fields for nested messages, ``[i]`` for an element of an array). The topics are
aligned onto the control period by their time stamps in the bag (the time each message
was recorded): the first tick is the first instant at which every mapped topic has had
a message, and at each tick every channel holds its topic's latest message (zero-order
hold), up to the last message of any mapped topic. Each bag is one episode unless a
gap in time (``split_gap``) or a change of a counter topic (``episode_topic``) splits
it.
"""

from __future__ import annotations

import bisect
import contextlib
import itertools
import math
import os
import re
import warnings
from array import array
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from behavior_hmm._safe_read import MAX_SIDE_FILE_BYTES, check_nesting, check_regular, read_text
from behavior_hmm.data._channels import (
    COMMAND_CHANNELS,
    CONTROL_PERIOD,
    SENSOR_CHANNELS,
    ChannelSpec,
)
from behavior_hmm.data._csv import _extra_channels, _extra_unit
from behavior_hmm.data._dataset import Dataset
from behavior_hmm.data._transform import DataImportWarning, finish, parse_derive
from behavior_hmm.data._units import (
    MAX_UNWRAPPED_ANGLE,
    unit_factor,
    wrap_imported_angles,
)
from behavior_hmm.data._validate import (
    MAX_CONTROL_PERIOD,
    MAX_ROWS,
    check_table,
    declared_commands,
    suggest,
)
from behavior_hmm.errors import BehaviorHMMError, ConfigError, DatasetError

#: Channels a bag can fill without declarations (time and episode come from the bag
#: itself); ``channels`` and ``commands`` declare others.
BAG_CHANNELS: Final[tuple[str, ...]] = (*SENSOR_CHANNELS, *COMMAND_CHANNELS)

#: The field read when a ``--map`` or ``--episode-topic`` gives a topic only (std_msgs).
DEFAULT_FIELD: Final[str] = "data"

#: Most rows the alignment grids of one import may hold, over all bags and episodes
#: (checked before a grid is allocated): the dataset bound ``MAX_ROWS``.
MAX_ALIGNED_ROWS: Final[int] = MAX_ROWS

#: Most grid rows per message of the mapped topics in an episode: a grid is bounded by
#: the data it came from (at 16 ms, a value held for 16 s per message on average).
MAX_ROWS_PER_MESSAGE: Final[int] = 1000

#: Most messages of the mapped topics read from one bag.
MAX_BAG_MESSAGES: Final[int] = 5_000_000

#: Most episodes one import may give (gaps and counter changes split a bag).
MAX_EPISODES: Final[int] = 100_000

#: Shortest alignment period (s) (the longest is ``MAX_CONTROL_PERIOD``).
MIN_PERIOD: Final[float] = 1e-6

_INT64_MAX: Final[int] = 2**63 - 1

_PART = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)\Z")
_INDEX = re.compile(r"\[(\d+)\]")


@dataclass(frozen=True)
class TopicField:
    """A field of a topic's messages: ``/odom:twist.twist.linear.x``."""

    topic: str
    field: str

    def __str__(self) -> str:
        return f"{self.topic}:{self.field}" if self.field else self.topic

    @property
    def path(self) -> list[str | int]:
        """Attribute names and array indices, in order."""
        out: list[str | int] = []
        for part in self.field.split("."):
            match = _PART.match(part)
            assert match is not None  # checked by parse_topic_field
            out.append(match.group(1))
            out.extend(int(i) for i in _INDEX.findall(match.group(2)))
        return out


def parse_topic_field(spec: str, what: str = "--map") -> TopicField:
    """``/topic:field.sub[2]`` (or ``/topic``, field ``data``) -> :class:`TopicField`."""
    text = spec.strip()
    topic, sep, field = text.partition(":")
    topic = topic.strip()
    field = field.strip() if sep else DEFAULT_FIELD
    if not topic:
        raise ConfigError(f"{what}: no topic in '{spec}' (expected TOPIC:FIELD, e.g. /angle:data)")
    if not field or not all(_PART.match(p) for p in field.split(".")):
        raise ConfigError(
            f"{what}: bad field '{field}' in '{spec}' (expected dotted names such as "
            "twist.linear.x, with [i] for an array element)"
        )
    return TopicField(topic, field)


def _rosbags() -> Any:
    try:
        import rosbags.highlevel
        import rosbags.typesys
    except ImportError:
        raise ConfigError(
            "reading ROS bags needs the optional package 'rosbags': "
            "pip install 'behavior-hmm[bags]'"
        ) from None
    return rosbags


def _fields_of(msg: Any) -> list[str]:
    names: Any = getattr(msg, "__dataclass_fields__", None) or getattr(msg, "__slots__", ())
    return [str(n) for n in names if not str(n).startswith("__")]


def _extract(msg: Any, source: TopicField, bag: str) -> float:
    """The numeric value at ``source.field`` in ``msg``; one-line errors otherwise."""
    value = msg
    where = source.topic
    for step in source.path:
        if isinstance(step, int):
            try:
                value = value[step]
            except (IndexError, TypeError, KeyError):
                size = len(value) if hasattr(value, "__len__") else "no"
                raise DatasetError(
                    f"no element [{step}] in topic {source.topic} (its array has {size} elements)",
                    file=bag,
                    field=str(source),
                ) from None
        else:
            if not hasattr(value, step):
                fields = _fields_of(value)
                raise DatasetError(
                    f"no field '{step}' in {where}'s {getattr(value, '__msgtype__', 'message')} "
                    f"(fields: {', '.join(fields) or 'none'}){suggest(step, fields)}",
                    file=bag,
                    field=str(source),
                )
            value = getattr(value, step)
            where = f"{where}.{step}"
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | float | np.number):
        kind = getattr(value, "__msgtype__", None) or type(value).__name__
        raise DatasetError(
            f"topic {source.topic}: the field is a {kind}, not a number "
            f"(name a numeric field inside it, e.g. {source.field}.x or {source.field}[0])",
            file=bag,
            field=str(source),
        )
    return float(value)


@dataclass
class _Series:
    times: Any  # int64 ns: an array('q') while reading, then sorted NDArray[np.int64]
    values: dict[str, Any]  # field -> array('d') while reading, then NDArray[np.float64]

    def finish(self) -> None:
        """Turn the read arrays into NumPy arrays, sorted by time (stable)."""
        times = (
            np.frombuffer(self.times, dtype=np.int64) if len(self.times) else np.zeros(0, np.int64)
        )
        values = {
            k: np.frombuffer(v, dtype=np.float64) if len(v) else np.zeros(0)
            for k, v in self.values.items()
        }
        if len(times) > 1 and (np.diff(times) < 0).any():
            order = np.argsort(times, kind="stable")
            times = times[order]
            values = {k: v[order] for k, v in values.items()}
        self.times = times
        self.values = values


def _short(text: object, limit: int = 120) -> str:
    out = " ".join(str(text).split()) or type(text).__name__
    return out if len(out) <= limit else out[: limit - 3] + "..."


def _check_bag_files(path: Path, bag: str) -> None:
    """Refuse a bag any of whose files is not a regular file, before rosbags opens it.

    A ROS 1 bag is one file; a ROS 2 bag folder holds ``metadata.yaml`` (read here within
    ``MAX_SIDE_FILE_BYTES``) and the storage files it lists (``.db3``, ``.mcap``). A named
    pipe or a device among them would block the reader forever.
    """
    if path.suffix == ".bag":
        check_regular(path, file=bag)
        return
    yaml_path = path / "metadata.yaml"
    where = str(Path(bag) / "metadata.yaml")
    if not (yaml_path.exists() or yaml_path.is_symlink()):
        raise DatasetError("not a ROS 2 bag folder: it has no metadata.yaml", file=bag)
    text = read_text(yaml_path, limit=MAX_SIDE_FILE_BYTES, file=where)
    check_nesting(text, file=where)
    try:
        from ruamel.yaml import YAML

        info = YAML(typ="safe").load(text)
    except Exception as exc:  # any failure to parse means "not a bag"
        raise DatasetError(f"not readable YAML ({_short(exc)})", file=where) from None
    if not isinstance(info, dict):
        raise DatasetError("not a rosbag2 metadata file (not a mapping)", file=where)
    body = info.get("rosbag2_bagfile_information")
    files = body.get("relative_file_paths") if isinstance(body, dict) else None
    if not isinstance(files, list) or not files:
        raise DatasetError(
            "not a rosbag2 metadata file (no rosbag2_bagfile_information.relative_file_paths)",
            file=where,
        )
    for name in files:
        if not isinstance(name, str) or not name:
            raise DatasetError(
                f"relative_file_paths holds {_short(repr(name), 60)}, not a file name", file=where
            )
        storage = path / PurePath(name).name
        if storage.exists() or storage.is_symlink():
            check_regular(storage, file=str(Path(bag) / PurePath(name).name))


def _read_bag(
    path: Path,
    sources: Sequence[TopicField],
    counter: TopicField | None,
) -> tuple[dict[str, _Series], _Series | None]:
    """Times (ns) and field values of every needed topic in one bag."""
    rb = _rosbags()
    bag = str(path)
    fields_by_topic: dict[str, list[TopicField]] = {}
    for src in sources:
        fields_by_topic.setdefault(src.topic, [])
        if src not in fields_by_topic[src.topic]:
            fields_by_topic[src.topic].append(src)
    if not path.exists():
        raise DatasetError("no such bag (a ROS 1 .bag file or a ROS 2 bag folder)", file=bag)
    is_ros1 = path.suffix == ".bag"
    if is_ros1 and path.is_dir():
        raise DatasetError("not a bag: a ROS 1 bag (.bag) is a file, this is a folder", file=bag)
    if not is_ros1 and not path.is_dir():
        hint = (
            "; give the ROS 2 bag's folder (with metadata.yaml), not a file inside it"
            if path.suffix in (".db3", ".mcap", ".yaml")
            else ""
        )
        raise DatasetError(
            f"not a bag: expected a ROS 1 .bag file or a ROS 2 bag folder{hint}", file=bag
        )
    _check_bag_files(path, bag)
    store = rb.typesys.Stores.ROS1_NOETIC if is_ros1 else rb.typesys.Stores.ROS2_HUMBLE
    typestore = rb.typesys.get_typestore(store)
    series = {
        topic: _Series(array("q"), {str(f): array("d") for f in fs})
        for topic, fs in fields_by_topic.items()
    }
    counter_series = (
        _Series(array("q"), {str(counter): array("d")}) if counter is not None else None
    )
    try:
        reader = rb.highlevel.AnyReader([path], default_typestore=typestore)
        reader.open()
    except Exception as exc:  # any failure to open means "not a readable bag"
        raise DatasetError(f"not a readable ROS bag ({_short(exc, 160)})", file=bag) from None
    count = 0
    last = ""
    wanted: list[str] = []
    connections: list[Any] = []
    per_topic: dict[str, int] = {}
    try:
        topics = sorted(reader.topics)
        wanted = [*fields_by_topic, *([counter.topic] if counter else [])]
        for topic in wanted:
            if topic not in topics:
                candidates = [*sources, *([counter] if counter else [])]
                named = next((s for s in candidates if s.topic == topic), None)
                raise DatasetError(
                    f"no topic {topic} in the bag (topics: {', '.join(topics) or 'none'})"
                    f"{suggest(topic, topics)}",
                    file=bag,
                    field=str(named) if named else topic,
                )
        connections = [c for c in reader.connections if c.topic in wanted]
        per_topic = dict.fromkeys(wanted, 0)
        for conn, stamp, raw in reader.messages(connections=connections):
            topic = conn.topic
            index = per_topic.get(topic, 0)
            per_topic[topic] = index + 1
            count += 1
            last = f"message {index} on {topic}"
            if count > MAX_BAG_MESSAGES:
                raise DatasetError(
                    f"more than MAX_BAG_MESSAGES ({MAX_BAG_MESSAGES:,}) messages on the mapped "
                    "topics; split the bag",
                    file=bag,
                )
            if type(stamp) is not int or not 0 <= stamp <= _INT64_MAX:
                raise DatasetError(
                    f"damaged bag: {last} has the time stamp {_short(repr(stamp), 60)}, "
                    "not a number of nanoseconds",
                    file=bag,
                    field=topic,
                )
            try:
                msg = reader.deserialize(raw, conn.msgtype)
            except Exception as exc:
                raise DatasetError(
                    f"cannot decode {last}, a {conn.msgtype} ({_short(exc)})",
                    file=bag,
                    field=topic,
                ) from None
            if topic in series:
                s = series[topic]
                values = [_extract(msg, src, bag) for src in fields_by_topic[topic]]
                s.times.append(stamp)
                for src, value in zip(fields_by_topic[topic], values, strict=True):
                    s.values[str(src)].append(value)
            if counter is not None and counter_series is not None and topic == counter.topic:
                value = _extract(msg, counter, bag)
                counter_series.times.append(stamp)
                counter_series.values[str(counter)].append(value)
    except BehaviorHMMError:
        raise
    except Exception as exc:  # damage that shows only while iterating
        after = f" after {last}" if last else " before its first message"
        raise DatasetError(
            f"damaged bag: cannot read it{after} ({type(exc).__name__}: {_short(exc)})",
            file=bag,
        ) from None
    finally:
        with contextlib.suppress(Exception):
            reader.close()
    short = []
    for topic in wanted:
        listed = sum(int(getattr(c, "msgcount", 0) or 0) for c in connections if c.topic == topic)
        if listed and per_topic[topic] != listed:
            short.append(f"{per_topic[topic]:,} of the {listed:,} messages on {topic}")
    if short:
        more = f" (and {len(short) - 1} more topics)" if len(short) > 1 else ""
        # damage rosbags does not raise on (a corrupt chunk read as a shorter bag): the
        # bag is refused, not imported short
        raise DatasetError(
            f"damaged bag: read {short[0]}{more} that its index lists",
            file=bag,
        )
    for s in series.values():
        s.finish()
    if counter_series is not None:
        counter_series.finish()
    for topic, s in series.items():
        if not len(s.times):
            raise DatasetError(
                f"topic {topic} has no messages", file=bag, field=str(fields_by_topic[topic][0])
            )
    return series, counter_series


def _segments(
    series: Mapping[str, _Series],
    split_gap: float | None,
    counter: _Series | None,
) -> list[tuple[float, float]]:
    """Time ranges [start, end) (ns) of the episodes in one bag."""
    bounds: list[tuple[float, float]] = [(-math.inf, math.inf)]
    if counter is not None:
        values = next(iter(counter.values.values()))
        times = counter.times
        if not len(times):
            return []
        change = np.flatnonzero(np.r_[True, values[1:] != values[:-1]])
        cuts = times[change].tolist()
        bounds = [
            (float(c), float(cuts[k + 1]) if k + 1 < len(cuts) else math.inf)
            for k, c in enumerate(cuts)
        ]
    if split_gap is not None:
        stamps = np.unique(np.concatenate([s.times for s in series.values()]))
        gaps = np.flatnonzero(np.diff(stamps) > split_gap * 1e9)
        cut_at = [float(c) for c in stamps[gaps + 1].tolist()]  # sorted
        out: list[tuple[float, float]] = []
        for a, b in bounds:
            inside = cut_at[bisect.bisect_right(cut_at, a) : bisect.bisect_left(cut_at, b)]
            out.extend(itertools.pairwise([a, *inside, b]))
        bounds = out
    return bounds


def _largest_gap(parts: Sequence[NDArray[np.int64]]) -> tuple[float, float, float]:
    """The longest stretch without a message on any mapped topic: (gap, from, to) in s,
    from and to counted from the first message."""
    stamps = np.unique(np.concatenate(parts))
    if len(stamps) < 2:
        return 0.0, float(stamps[0]) / 1e9, float(stamps[0]) / 1e9
    i = int(np.argmax(np.diff(stamps)))
    first, a, b = int(stamps[0]), int(stamps[i]), int(stamps[i + 1])
    return (b - a) / 1e9, (a - first) / 1e9, (b - first) / 1e9


def _align(
    series: Mapping[str, _Series],
    start: float,
    end: float,
    period_ns: int,
    *,
    bag: str,
    rows_before: int = 0,
) -> tuple[NDArray[np.int64], dict[str, NDArray[np.float64]]] | None:
    """Ticks (ns) and each field's zero-order-held value, or None if a topic is silent.

    The grid is refused before it is allocated if it would take the import past
    ``MAX_ALIGNED_ROWS`` rows, or hold more than ``MAX_ROWS_PER_MESSAGE`` rows per message
    it came from.
    """
    parts = []
    for s in series.values():
        lo = 0 if start == -math.inf else int(np.searchsorted(s.times, start, side="left"))
        hi = len(s.times) if end == math.inf else int(np.searchsorted(s.times, end, side="left"))
        if hi <= lo:
            return None
        parts.append((s.times[lo:hi], {k: v[lo:hi] for k, v in s.values.items()}))
    t0 = max(int(times[0]) for times, _ in parts)
    t_end = max(int(times[-1]) for times, _ in parts)
    n = (t_end - t0) // period_ns + 1
    messages = sum(len(times) for times, _ in parts)
    too_many = rows_before + n > MAX_ALIGNED_ROWS
    if too_many or n > MAX_ROWS_PER_MESSAGE * messages:
        gap, since, until = _largest_gap([times for times, _ in parts])
        limit = (
            f"past MAX_ALIGNED_ROWS ({MAX_ALIGNED_ROWS:,} rows in all)"
            if too_many
            else f"from only {messages:,} messages, more than MAX_ROWS_PER_MESSAGE "
            f"({MAX_ROWS_PER_MESSAGE:,}) rows per message"
        )
        raise DatasetError(
            f"aligning it at {period_ns / 1e6:g} ms gives {n:,} rows {limit}: no mapped topic "
            f"has a message for {gap:,.6g} s (from {since:,.3f} s to {until:,.3f} s after the "
            "episode's first message); "
            "split the bag at such gaps with --split-gap SECONDS",
            file=bag,
        )
    ticks = t0 + period_ns * np.arange(n, dtype=np.int64)
    values: dict[str, NDArray[np.float64]] = {}
    for times, fields in parts:
        idx = np.searchsorted(times, ticks, side="right") - 1
        for key, v in fields.items():
            values[key] = v[idx].astype(np.float64)
    return ticks, values


def import_bags(
    paths: Sequence[str | os.PathLike[str]],
    *,
    mapping: Mapping[str, str | TopicField],
    units: Mapping[str, str] | None = None,
    twist: str | TopicField | None = None,
    wheel_radius: float | None = None,
    track_width: float | None = None,
    split_gap: float | None = None,
    episode_topic: str | TopicField | None = None,
    derive: Collection[str] | str = (),
    metadata: Mapping[str, Any] | None = None,
    period: float = CONTROL_PERIOD,
    channels: Sequence[ChannelSpec | Mapping[str, Any]] | None = None,
    commands: Sequence[ChannelSpec | Mapping[str, Any] | str] | None = None,
) -> Dataset:
    """Read ROS 1 / ROS 2 bags into a validated :class:`Dataset` (module docstring).

    Parameters
    ----------
    paths
        ROS 1 ``.bag`` files and/or ROS 2 bag folders (``metadata.yaml`` + storage).
    mapping
        Channel -> ``TOPIC:FIELD`` (``/object_bearing:data``, ``/odom:twist.twist.linear.x``;
        a topic alone reads its ``data`` field). Every sensor channel (declared ones
        included) and every command channel need one, unless derived (``derive``) or
        given by ``twist``.
    units
        Channel -> the unit its field is in (as for CSV: ``angle="rad"``,
        ``angular_velocity="rad/s"``, ``left="rpm"``, ...).
    twist
        A ``geometry_msgs/Twist`` topic (``TOPIC`` or ``TOPIC:FIELD`` of a message that
        holds one, e.g. ``/cmd_vel_stamped:twist``) whose ``linear.x`` (m/s) and
        ``angular.z`` (rad/s) become the wheel speeds
        ``left = (v − ω·track_width/2) / wheel_radius``, ``right = (v + ω·track_width/2) /
        wheel_radius``.
    wheel_radius, track_width
        The robot's wheel radius and distance between the wheels (m), for ``twist``.
    split_gap
        Start a new episode wherever no mapped topic has a message for this long (s).
    episode_topic
        A counter topic (``TOPIC`` or ``TOPIC:FIELD``, numeric): a new episode starts
        wherever its value changes; messages before its first one are dropped.
    derive
        Velocities computed from positions (see :func:`import_csv`).
    metadata
        Dataset metadata; ``source`` records bags, mapping, units and each episode's
        bag and start time.
    period
        The alignment period (s); default the control period.
    channels
        A robot's own sensor channels, as for :func:`import_csv` (:class:`ChannelSpec`
        objects or declarations ``{"name", "unit", "range"}``), after any ``metadata``
        declares; each mapped from a topic, read in its declared unit. With declared
        channels and none of the data contract's four mapped or derived, the dataset
        holds the robot's own channels only.
    commands
        The command channels in action order, replacing our two wheels: declarations
        ``{"name", "unit", "range", "rest"}`` or known names (``"left"``); e.g. the
        wheels and a gripper. Each is mapped from a topic (``twist`` gives ``left`` and
        ``right``).

    Raises
    ------
    DatasetError
        One line naming the bag, the topic and field, and what is wrong.
    ConfigError
        For a bad mapping, unit or option, or when ``rosbags`` is not installed.
    """
    if not paths:
        raise ConfigError("no bag given")
    derived = parse_derive(derive)
    units = dict(units or {})
    declared: dict[str, Any] = dict(metadata or {})
    extras = _extra_channels(declared, channels, "metadata")
    if commands is not None:
        declared["commands"] = [
            spec.to_metadata() for spec in declared_commands({"commands": list(commands)})
        ]
    command_specs = declared_commands(declared)
    command_names = tuple(spec.name for spec in command_specs)
    mappable = (*SENSOR_CHANNELS, *(spec.name for spec in extras), *command_names)
    sources: dict[str, TopicField] = {}
    for channel, spec in mapping.items():
        if channel not in mappable:
            raise ConfigError(
                f"--map {channel}: unknown channel (channels: {', '.join(mappable)}; time "
                "and episodes come from the bag; declare a robot's own with --channel or "
                f"--command){suggest(channel, mappable)}"
            )
        sources[channel] = spec if isinstance(spec, TopicField) else parse_topic_field(spec)
    twist_src = None
    if twist is not None:
        twist_src = twist if isinstance(twist, TopicField) else _twist_source(twist)
        if not set(COMMAND_CHANNELS) <= set(command_names):
            raise ConfigError(
                f"--twist gives the wheels {', '.join(COMMAND_CHANNELS)}, which are not among "
                f"the commands ({', '.join(command_names)}); add --command left --command right"
            )
        for wheel in COMMAND_CHANNELS:
            if wheel in sources:
                raise ConfigError(f"--twist gives '{wheel}'; do not --map it too")
        if wheel_radius is None or track_width is None:
            raise ConfigError("--twist needs the robot's wheel_radius and track_width")
        if not (wheel_radius > 0 and track_width > 0):
            raise ConfigError(
                f"wheel_radius and track_width must be > 0 m, got {wheel_radius} and {track_width}"
            )
    for name in derived:
        if name in sources:
            raise ConfigError(f"--derive {name}: it is mapped too (--map {name}=...); choose one")
    covered = set(sources) | set(derived) | (set(COMMAND_CHANNELS) if twist_src else set())
    # a robot's own channels only: none of the data contract's four mapped or derived
    own_only = bool(extras) and not any(c in covered for c in SENSOR_CHANNELS)
    needed = [c for c in mappable if not (own_only and c in SENSOR_CHANNELS)]
    missing = [c for c in needed if c not in covered]
    if missing:
        hints = []
        if any(c in ("linear_velocity", "angular_velocity") for c in missing):
            hints.append("derive velocities with --derive")
        if any(c in COMMAND_CHANNELS for c in missing) and twist_src is None:
            hints.append("take the wheels from a twist with --twist TOPIC")
        raise ConfigError(
            f"no topic for channel(s) {', '.join(missing)}: map each with --map "
            f"CHANNEL=TOPIC:FIELD" + (f" ({'; '.join(hints)})" if hints else "")
        )
    for name in units:
        if name not in sources:
            raise ConfigError(
                f"--unit {name}: only mapped channels take a unit (mapped: {', '.join(sources)})"
            )
    own_specs = [*extras, *(s for s in command_specs if s.name not in COMMAND_CHANNELS)]
    factors = {
        name: _extra_unit(own, unit)
        if (own := next((s for s in own_specs if s.name == name), None))
        else unit_factor(name, unit)
        for name, unit in units.items()
    }
    # what the columns are, for validating each bag's (and the whole import's) table
    if extras:
        declared["channels"] = [spec.to_metadata() for spec in extras]
    shape: dict[str, Any] = {k: declared[k] for k in ("channels", "commands") if k in declared}
    counter = None
    if episode_topic is not None:
        counter = (
            episode_topic
            if isinstance(episode_topic, TopicField)
            else parse_topic_field(episode_topic, "--episode-topic")
        )
    if split_gap is not None and not (math.isfinite(split_gap) and split_gap > 0):
        raise ConfigError(f"--split-gap must be a number of seconds > 0, got {split_gap}")
    if isinstance(period, bool) or not isinstance(period, int | float):
        raise ConfigError(f"the alignment period must be a number of seconds, got {period!r}")
    if not (math.isfinite(period) and MIN_PERIOD <= period <= MAX_CONTROL_PERIOD):
        raise ConfigError(
            f"the alignment period must be in [{MIN_PERIOD:g}, {MAX_CONTROL_PERIOD:g}] s, "
            f"got {period}"
        )
    period_ns = round(period * 1e9)

    reads: list[TopicField] = list(sources.values())
    if twist_src is not None:
        reads += [_child(twist_src, "linear.x"), _child(twist_src, "angular.z")]
    columns: dict[str, list[NDArray[Any]]] = {c: [] for c in ("episode", "t", *covered)}
    episodes_md: list[dict[str, Any]] = []
    bag_names: list[str] = []
    next_id = 0
    rows = 0
    for raw_path in paths:
        path = Path(raw_path)
        bag = str(raw_path)
        bag_names.append(path.name)
        series, counter_series = _read_bag(path, reads, counter)
        bag_cols: dict[str, list[NDArray[Any]]] = {c: [] for c in columns if c not in derived}
        first_id = next_id
        for start, end in _segments(series, split_gap, counter_series):
            aligned = _align(series, start, end, period_ns, bag=bag, rows_before=rows)
            if aligned is None:
                warnings.warn(
                    DataImportWarning(
                        f"{bag}: skipped a stretch in which a mapped topic has no message"
                    ),
                    stacklevel=2,
                )
                continue
            ticks, values = aligned
            n = len(ticks)
            rows += n
            if next_id >= MAX_EPISODES:
                raise DatasetError(
                    f"more than MAX_EPISODES ({MAX_EPISODES:,}) episodes (a counter topic that "
                    "changes at every message, or a --split-gap shorter than the period?)",
                    file=bag,
                )
            bag_cols["episode"].append(np.full(n, next_id, dtype=np.int64))
            bag_cols["t"].append((ticks - ticks[0]) / 1e9)
            for channel, src in sources.items():
                bag_cols[channel].append(values[str(src)] * factors.get(channel, 1.0))
            if twist_src is not None:
                v = values[str(_child(twist_src, "linear.x"))]
                w = values[str(_child(twist_src, "angular.z"))]
                assert wheel_radius is not None and track_width is not None
                bag_cols["left"].append((v - 0.5 * w * track_width) / wheel_radius)
                bag_cols["right"].append((v + 0.5 * w * track_width) / wheel_radius)
            episodes_md.append({"bag": path.name, "start_ns": int(ticks[0])})
            next_id += 1
        if next_id == first_id:
            raise DatasetError(
                "no episode: no stretch of the bag in which every mapped topic has a message"
                + (f" (is {counter} ever published?)" if counter else ""),
                file=bag,
            )
        cols = {name: np.concatenate(parts) for name, parts in bag_cols.items()}
        _check_angle(cols, sources.get("angle"), bag)
        try:
            cols, _ = finish(cols, dict(shape), file=bag, derive=derived, what="bag")
        except DatasetError as err:
            raise DatasetError(
                err.reason,
                file=err.file,
                episode=err.episode,
                row=err.row,
                field=f"{err.field} ({sources[err.field]})"
                if err.field in sources
                else _twist_label(err.field, twist_src),
            ) from None
        for name in columns:
            columns[name].append(cols[name])
    md = declared
    md.setdefault(
        "source",
        {
            "format": "rosbag",
            "bags": bag_names,
            "mapping": {ch: str(src) for ch, src in sources.items()},
            "units": units,
            "twist": str(twist_src) if twist_src else None,
            "derived": list(derived),
            "episodes": episodes_md,
        },
    )
    if twist_src is not None:
        md.setdefault("robot", {"wheel_radius": wheel_radius, "track_width": track_width})
    table = {name: np.concatenate(parts) for name, parts in columns.items()}
    final, md = check_table(table, md)
    return Dataset._trusted(final, md)


def _twist_source(spec: str) -> TopicField:
    topic, sep, _ = spec.strip().partition(":")
    if not sep:
        return TopicField(topic.strip(), "")
    return parse_topic_field(spec, "--twist")


def _child(src: TopicField, sub: str) -> TopicField:
    return TopicField(src.topic, f"{src.field}.{sub}" if src.field else sub)


def _twist_label(field: str | None, twist: TopicField | None) -> str | None:
    if twist is not None and field in COMMAND_CHANNELS:
        return f"{field} (from the twist on {twist.topic})"
    return field


def _check_angle(cols: dict[str, NDArray[Any]], src: TopicField | None, bag: str) -> None:
    """Refuse absurd angles (wrong units?), then wrap the rest into (−180, 180]."""
    if "angle" not in cols:
        return
    angle = cols["angle"]
    cols["angle"], absurd = wrap_imported_angles(angle)
    if absurd is not None:
        i = absurd
        episode = cols["episode"]
        eid = int(episode[i])
        raise DatasetError(
            f"absurd angle {angle[i]:g} deg (beyond ±{MAX_UNWRAPPED_ANGLE:g} deg; wrong units? "
            "--unit angle=rad)",
            file=bag,
            episode=eid,
            row=i - int(np.argmax(episode == eid)),
            field=f"angle ({src})" if src else "angle",
        )
