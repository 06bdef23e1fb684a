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

import itertools
import math
import os
import re
import warnings
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data._channels import COMMAND_CHANNELS, CONTROL_PERIOD, SENSOR_CHANNELS
from behavior_hmm.data._dataset import Dataset
from behavior_hmm.data._transform import DataImportWarning, finish, parse_derive
from behavior_hmm.data._units import (
    MAX_UNWRAPPED_ANGLE,
    unit_factor,
    wrap_imported_angles,
)
from behavior_hmm.data._validate import check_table, suggest
from behavior_hmm.errors import ConfigError, DatasetError

#: Channels a bag can fill (time and episode come from the bag itself).
BAG_CHANNELS: Final[tuple[str, ...]] = (*SENSOR_CHANNELS, *COMMAND_CHANNELS)

#: The field read when a ``--map`` or ``--episode-topic`` gives a topic only (std_msgs).
DEFAULT_FIELD: Final[str] = "data"

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
    times: list[int]
    values: dict[str, list[float]]  # field -> values


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
    if is_ros1 and not path.is_file():
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
    store = rb.typesys.Stores.ROS1_NOETIC if is_ros1 else rb.typesys.Stores.ROS2_HUMBLE
    typestore = rb.typesys.get_typestore(store)
    series = {topic: _Series([], {str(f): [] for f in fs}) for topic, fs in fields_by_topic.items()}
    counter_series = _Series([], {str(counter): []}) if counter is not None else None
    try:
        reader = rb.highlevel.AnyReader([path], default_typestore=typestore)
        reader.open()
    except Exception as exc:  # any failure to open means "not a readable bag"
        text = " ".join(str(exc).split())[:160] or type(exc).__name__
        raise DatasetError(f"not a readable ROS bag ({text})", file=bag) from None
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
        for conn, stamp, raw in reader.messages(connections=connections):
            try:
                msg = reader.deserialize(raw, conn.msgtype)
            except Exception as exc:
                text = " ".join(str(exc).split())[:120] or type(exc).__name__
                raise DatasetError(
                    f"cannot decode a {conn.msgtype} message on {conn.topic} ({text})",
                    file=bag,
                    field=conn.topic,
                ) from None
            if conn.topic in series:
                s = series[conn.topic]
                s.times.append(int(stamp))
                for src in fields_by_topic[conn.topic]:
                    s.values[str(src)].append(_extract(msg, src, bag))
            if counter is not None and counter_series is not None and conn.topic == counter.topic:
                counter_series.times.append(int(stamp))
                counter_series.values[str(counter)].append(_extract(msg, counter, bag))
    finally:
        reader.close()
    for topic, s in series.items():
        if not s.times:
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
        cuts = [times[i] for i in range(len(times)) if i == 0 or values[i] != values[i - 1]]
        if not cuts:
            return []
        bounds = [
            (float(c), float(cuts[k + 1]) if k + 1 < len(cuts) else math.inf)
            for k, c in enumerate(cuts)
        ]
    if split_gap is not None:
        stamps = np.unique(np.concatenate([np.asarray(s.times) for s in series.values()]))
        gaps = np.flatnonzero(np.diff(stamps) > split_gap * 1e9)
        cut_at = [float(stamps[i + 1]) for i in gaps]
        out: list[tuple[float, float]] = []
        for a, b in bounds:
            edges = [a, *[c for c in cut_at if a < c < b], b]
            out.extend(itertools.pairwise(edges))
        bounds = out
    return bounds


def _align(
    series: Mapping[str, _Series], start: float, end: float, period_ns: int
) -> tuple[NDArray[np.int64], dict[str, NDArray[np.float64]]] | None:
    """Ticks (ns) and each field's zero-order-held value, or None if a topic is silent."""
    parts = []
    for s in series.values():
        times = np.asarray(s.times, dtype=np.int64)
        keep = (times >= start) & (times < end)
        if not keep.any():
            return None
        parts.append((times[keep], {k: np.asarray(v)[keep] for k, v in s.values.items()}))
    t0 = max(int(times[0]) for times, _ in parts)
    t_end = max(int(times[-1]) for times, _ in parts)
    ticks = t0 + period_ns * np.arange((t_end - t0) // period_ns + 1, dtype=np.int64)
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
) -> Dataset:
    """Read ROS 1 / ROS 2 bags into a validated :class:`Dataset` (module docstring).

    Parameters
    ----------
    paths
        ROS 1 ``.bag`` files and/or ROS 2 bag folders (``metadata.yaml`` + storage).
    mapping
        Channel -> ``TOPIC:FIELD`` (``/object_bearing:data``, ``/odom:twist.twist.linear.x``;
        a topic alone reads its ``data`` field). Every sensor channel and ``left`` and
        ``right`` need one, unless derived (``derive``) or given by ``twist``.
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
    sources: dict[str, TopicField] = {}
    for channel, spec in mapping.items():
        if channel not in BAG_CHANNELS:
            raise ConfigError(
                f"--map {channel}: unknown channel (channels: {', '.join(BAG_CHANNELS)}; time "
                f"and episodes come from the bag){suggest(channel, BAG_CHANNELS)}"
            )
        sources[channel] = spec if isinstance(spec, TopicField) else parse_topic_field(spec)
    twist_src = None
    if twist is not None:
        twist_src = twist if isinstance(twist, TopicField) else _twist_source(twist)
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
    missing = [c for c in BAG_CHANNELS if c not in covered]
    if missing:
        hints = []
        if any(c in ("linear_velocity", "angular_velocity") for c in missing):
            hints.append("derive velocities with --derive")
        if any(c in COMMAND_CHANNELS for c in missing):
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
    factors = {name: unit_factor(name, unit) for name, unit in units.items()}
    counter = None
    if episode_topic is not None:
        counter = (
            episode_topic
            if isinstance(episode_topic, TopicField)
            else parse_topic_field(episode_topic, "--episode-topic")
        )
    if split_gap is not None and not (math.isfinite(split_gap) and split_gap > 0):
        raise ConfigError(f"--split-gap must be a number of seconds > 0, got {split_gap}")
    period_ns = round(period * 1e9)

    reads: list[TopicField] = list(sources.values())
    if twist_src is not None:
        reads += [_child(twist_src, "linear.x"), _child(twist_src, "angular.z")]
    columns: dict[str, list[NDArray[Any]]] = {c: [] for c in ("episode", "t", *covered)}
    episodes_md: list[dict[str, Any]] = []
    bag_names: list[str] = []
    next_id = 0
    for raw_path in paths:
        path = Path(raw_path)
        bag = str(raw_path)
        bag_names.append(path.name)
        series, counter_series = _read_bag(path, reads, counter)
        bag_cols: dict[str, list[NDArray[Any]]] = {c: [] for c in columns if c not in derived}
        first_id = next_id
        for start, end in _segments(series, split_gap, counter_series):
            aligned = _align(series, start, end, period_ns)
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
            cols, _ = finish(cols, {}, file=bag, derive=derived, what="bag")
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
    md = dict(metadata or {})
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
