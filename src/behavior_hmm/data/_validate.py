"""Validation of dataset columns and metadata (DESIGN §4).

Every check raises :class:`~behavior_hmm.errors.DatasetError` naming the file,
the episode (its id), the row (0-based, counted within the episode) and the
field, as far as they apply.
"""

from __future__ import annotations

import difflib
import json
import math
import re
from collections.abc import Collection, Iterable, Mapping
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data._channels import (
    CHANNELS,
    COMMAND_CHANNELS,
    SENSOR_CHANNELS,
    UNITS,
    ChannelSpec,
    channel_from_metadata,
    command_from_declaration,
)
from behavior_hmm.errors import ConfigError, DatasetError

#: Version of the dataset schema this package writes and reads.
SCHEMA_VERSION: Final[int] = 1

#: Columns every dataset has, in file order.
REQUIRED_COLUMNS: Final[tuple[str, ...]] = ("episode", "t", *SENSOR_CHANNELS, *COMMAND_CHANNELS)

#: Columns a dataset may have (complex demonstrations name the active sub-behavior).
OPTIONAL_COLUMNS: Final[tuple[str, ...]] = ("behavior",)

#: Columns holding float64 values in physical units.
FLOAT_COLUMNS: Final[tuple[str, ...]] = ("t", *SENSOR_CHANNELS, *COMMAND_CHANNELS)

#: Plausible physical bounds (inclusive, canonical units); values outside are refused
#: as absurd (a glitch or a unit mistake). ``distance`` may dip slightly below 0 because
#: sensor noise near the goal can push a reading of ~0 m under zero.
VALUE_BOUNDS: Final[dict[str, tuple[float, float]]] = {
    name: spec.bounds for name, spec in CHANNELS.items() if spec.bounds is not None
}

#: Behavior names: a lowercase identifier such as ``turn`` or ``turn_approach``; a row
#: where two behaviors run at once (a parallel behavior, ``collect turn-approach-parallel``)
#: names both, joined by ``+`` (``turn+approach``).
BEHAVIOR_NAME_PATTERN: Final[str] = r"^[a-z][a-z0-9_-]{0,63}(\+[a-z][a-z0-9_-]{0,63})?$"
_NAME_RE = re.compile(r"[a-z][a-z0-9_-]{0,63}(\+[a-z][a-z0-9_-]{0,63})?\Z")
_CHANNEL_NAME_RE = re.compile(r"[a-z][a-z0-9_]{0,63}\Z")

_INT64_MAX = np.iinfo(np.int64).max
_INT64_MIN = np.iinfo(np.int64).min

#: Most rows a dataset file may hold (a Parquet file's footer is checked against it
#: before the table is read; a bag's alignment grid before it is allocated): about 8.9
#: hours at the 16 ms control period, some 0.25 GiB of columns.
MAX_ROWS: Final[int] = 2_000_000

#: Largest control period (s) the metadata may state (the robot contract's bound).
MAX_CONTROL_PERIOD: Final[float] = 10.0

#: Largest magnitude of a number in the metadata that a model keeps (a goal, a
#: normalization range): the model file's own bound, so that a model trained on the
#: dataset can be loaded again.
MAX_METADATA_VALUE: Final[float] = 1e6

#: Longest text (characters) of a metadata entry a model keeps (``env``, ``simulator``).
MAX_METADATA_TEXT: Final[int] = 4096

_LINE_BREAKS = re.compile(r"[\x00-\x1f\x7f\x85\u2028\u2029]")


def suggest(name: str, candidates: Iterable[str]) -> str:
    """Return ``"; did you mean 'x'?"`` for the closest candidate, or ``""``."""
    cands = list(candidates)
    lowered = {c.lower(): c for c in cands}
    match = difflib.get_close_matches(name.lower(), list(lowered), n=1, cutoff=0.6)
    return f"; did you mean '{lowered[match[0]]}'?" if match else ""


def check_behavior_name(name: object, *, file: str | None = None, field: str = "behavior") -> str:
    """Check one behavior name against :data:`BEHAVIOR_NAME_PATTERN`; return it."""
    if not isinstance(name, str) or _NAME_RE.match(name) is None:
        raise DatasetError(
            f"invalid behavior name {name!r} (expected a lowercase identifier like 'turn', "
            "or two joined by '+' like 'turn+approach')",
            file=file,
            field=field,
        )
    return name


#: How to declare a column that is not one of ours (end of "unexpected column" errors).
DECLARE_HINT: Final[str] = 'declare it in the metadata\'s "channels" with unit and range'


def declared_channels(metadata: object, *, file: str | None = None) -> tuple[ChannelSpec, ...]:
    """The extra sensor channels declared in a dataset's metadata, in declared order.

    ``metadata["channels"]`` is a list of declarations ``{"name", "unit", "range", ...}``
    (:func:`~behavior_hmm.data._channels.channel_from_metadata`; :class:`ChannelSpec`
    objects are accepted too). Each becomes a float64 sensor column after the four of the
    data contract. Metadata that is not a mapping, or without ``"channels"``, declares
    none.

    Raises
    ------
    DatasetError
        For a malformed declaration, a declaration of a built-in or reserved column,
        a command channel, or a channel declared twice (naming the file).
    """
    if not isinstance(metadata, Mapping) or metadata.get("channels") is None:
        return ()
    entries = metadata["channels"]
    if not isinstance(entries, list | tuple):
        raise DatasetError(
            f"'channels' must be a list of channel declarations "
            f'({{"name", "unit", "range"}}), got {type(entries).__name__}',
            file=file,
            field="channels",
        )
    specs: list[ChannelSpec] = []
    for entry in entries:
        if isinstance(entry, ChannelSpec):
            spec = entry
        else:
            try:
                spec = channel_from_metadata(entry)
            except (TypeError, ValueError) as exc:  # ConfigError is a ValueError
                text = " ".join(str(exc).split())
                raise DatasetError(
                    f"bad channel declaration: {text}", file=file, field="channels"
                ) from None
        if spec.name in REQUIRED_COLUMNS or spec.name in OPTIONAL_COLUMNS:
            raise DatasetError(
                f"channel '{spec.name}' is a built-in column of the data contract; declare "
                "only a robot's own channels, under other names",
                file=file,
                field="channels",
            )
        if spec.kind != "sensor":
            raise DatasetError(
                f"channel '{spec.name}': only sensor channels can be declared (kind {spec.kind!r})",
                file=file,
                field="channels",
            )
        if any(s.name == spec.name for s in specs):
            raise DatasetError(
                f"channel '{spec.name}' is declared twice", file=file, field="channels"
            )
        specs.append(spec)
    return tuple(specs)


def own_channels_only(names: Collection[str], declared: Collection[str]) -> bool:
    """Whether a table of columns ``names`` holds a robot's own channels only.

    A robot that is not our Khepera (a point mass, an arm) declares its channels and
    has none of the data contract's four sensors: then those four are not required.
    A table with some of them still needs all four.
    """
    return bool(declared) and not any(c in names for c in SENSOR_CHANNELS)


#: Most command channels a dataset may declare.
MAX_COMMANDS: Final[int] = 64


def declared_commands(metadata: object, *, file: str | None = None) -> tuple[ChannelSpec, ...]:
    """The command channels of a dataset, in action order.

    ``metadata["commands"]`` lists them: declarations ``{"name", "unit", "range", ...,
    "rest"}`` (their ``kind`` is ``"command"``), or the names of registered command
    channels (``"left"``). Without it, a dataset commands our robots' two wheels,
    :data:`~behavior_hmm.data._channels.COMMAND_CHANNELS`.

    Raises
    ------
    DatasetError
        For a malformed declaration, a sensor or reserved name, a channel listed twice,
        or none or more than :data:`MAX_COMMANDS` of them (naming the file).
    """
    if not isinstance(metadata, Mapping) or metadata.get("commands") is None:
        return tuple(CHANNELS[name] for name in COMMAND_CHANNELS)
    entries = metadata["commands"]
    if not isinstance(entries, list | tuple) or not 1 <= len(entries) <= MAX_COMMANDS:
        raise DatasetError(
            f"'commands' must list 1 to {MAX_COMMANDS} command channels "
            '({"name", "unit", "range", "rest"} or a known name such as "left")',
            file=file,
            field="commands",
        )
    specs: list[ChannelSpec] = []
    for entry in entries:
        try:
            spec = command_from_declaration(entry)
        except (TypeError, ValueError) as exc:  # ConfigError is a ValueError
            text = " ".join(str(exc).split())[:200]
            raise DatasetError(
                f"bad command declaration: {text}", file=file, field="commands"
            ) from None
        if any(s.name == spec.name for s in specs):
            raise DatasetError(
                f"command '{spec.name}' is listed twice", file=file, field="commands"
            )
        specs.append(spec)
    return tuple(specs)


def check_column_names(
    names: Iterable[str],
    *,
    file: str | None = None,
    required: Collection[str] = REQUIRED_COLUMNS,
    extra: Collection[str] = (),
    commands: Collection[str] = COMMAND_CHANNELS,
) -> None:
    """Refuse duplicate, unexpected (with the closest expected name) and missing columns.

    ``extra`` are the dataset's declared channels (:func:`declared_channels`): allowed,
    and required; ``commands`` its command channels (:func:`declared_commands`), which
    replace the two wheels.
    """
    names = list(names)
    if tuple(commands) != COMMAND_CHANNELS:
        required = [c for c in required if c not in COMMAND_CHANNELS]
        required = [*required, *commands]
    base = [c for c in REQUIRED_COLUMNS if c not in COMMAND_CHANNELS]
    allowed = (*base, *commands, *OPTIONAL_COLUMNS, *extra)
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise DatasetError("column appears twice", file=file, field=name)
        seen.add(name)
    if own_channels_only(seen, extra):
        required = [c for c in required if c not in SENSOR_CHANNELS]
    missing = [c for c in required if c not in seen]
    missing_extra = [c for c in extra if c not in seen]
    for name in names:
        if name not in allowed:
            hint = suggest(name, missing + missing_extra or allowed)
            if hint:
                message = f"unexpected column{hint} (or {DECLARE_HINT})"
            else:
                example = name if _CHANNEL_NAME_RE.match(name) else "ir0"
                message = (
                    f"unexpected column (expected columns: {', '.join(allowed)}; a robot's own "
                    f'sensor channel? {DECLARE_HINT}, e.g. {{"name": "{example}", "unit": "m", '
                    '"range": [0, 1]})'
                )
            raise DatasetError(message, file=file, field=name)
    if missing:
        raise DatasetError(
            f"missing column (a dataset needs: {', '.join(required)})",
            file=file,
            field=missing[0],
        )
    if missing_extra:
        raise DatasetError(
            'missing column of a declared channel (the metadata\'s "channels" declares it: '
            "add the column or remove the declaration)",
            file=file,
            field=missing_extra[0],
        )


class _Locator:
    """Turns a row index over the whole table into (episode id, row within episode)."""

    def __init__(
        self,
        file: str | None,
        episode: NDArray[np.int64],
        starts: NDArray[np.int64],
        lines: NDArray[np.int64] | None,
    ) -> None:
        self.file = file
        self.episode = episode
        self.starts = starts
        self.lines = lines

    def error(self, message: str, index: int, field: str | None) -> DatasetError:
        block = int(np.searchsorted(self.starts, index, side="right")) - 1
        row = index - int(self.starts[block])
        if self.lines is not None:
            message = f"{message} (CSV line {int(self.lines[index])})"
        return DatasetError(
            message, file=self.file, episode=int(self.episode[index]), row=row, field=field
        )


def _as_array(values: object, name: str, file: str | None) -> NDArray[Any]:
    try:
        arr = np.asarray(values)
    except (ValueError, TypeError) as exc:
        raise DatasetError(f"not a column of values ({exc})", file=file, field=name) from None
    if arr.ndim != 1:
        raise DatasetError(f"expected a 1-D column, got shape {arr.shape}", file=file, field=name)
    return arr


def _json_default(obj: object) -> object:
    if isinstance(obj, ChannelSpec):
        return obj.to_metadata()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"{type(obj).__name__} is not JSON-serializable")


def canonical_metadata(
    metadata: Mapping[str, Any] | None, *, file: str | None = None
) -> dict[str, Any]:
    """Return the metadata as JSON would give it back, with ``schema_version`` set.

    The result survives a Parquet round trip unchanged (tuples become lists, NumPy
    scalars become Python numbers).
    """
    md = {} if metadata is None else metadata
    if not isinstance(md, Mapping):
        raise DatasetError(
            f"metadata must be a JSON object, got {type(md).__name__}", file=file, field="metadata"
        )
    try:
        out = json.loads(json.dumps(dict(md), allow_nan=False, default=_json_default))
    except (TypeError, ValueError, RecursionError) as exc:
        raise DatasetError(
            f"metadata is not JSON-serializable ({exc})", file=file, field="metadata"
        ) from None
    version = out.setdefault("schema_version", SCHEMA_VERSION)
    if type(version) is not int or version != SCHEMA_VERSION:
        raise DatasetError(
            f"unsupported schema version {version!r} (this version of behavior-hmm reads "
            f"version {SCHEMA_VERSION})",
            file=file,
            field="schema_version",
        )
    if out.get("behavior") is not None:
        check_behavior_name(out["behavior"], file=file, field="behavior")
    if out.get("behaviors") is not None:
        if not isinstance(out["behaviors"], list):
            raise DatasetError("'behaviors' must be a list of names", file=file, field="behaviors")
        for name in out["behaviors"]:
            check_behavior_name(name, file=file, field="behaviors")
    if out.get("channels") is not None:
        out["channels"] = [spec.to_metadata() for spec in declared_channels(out, file=file)]
    if out.get("commands") is not None:
        out["commands"] = [spec.to_metadata() for spec in declared_commands(out, file=file)]
    check_metadata_values(out, file=file)
    return out


def _short(value: object, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters (a hostile value can be huge)."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _finite(value: object) -> bool:
    """A finite int or float (not a bool); an int too large for a float is not."""
    if not isinstance(value, int | float) or isinstance(value, bool):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def _metadata_error(message: str, file: str | None, key: str) -> DatasetError:
    return DatasetError(message, file=file, field=f"metadata {key}")


def check_metadata_values(metadata: Mapping[str, Any], *, file: str | None = None) -> None:
    """Refuse a metadata entry the package reads back, if its type or range is wrong.

    Metadata read back from a file is validated like user input, before any work
    starts: every key a learner, filter or command reads (``goal``, ``control_period``,
    ``ranges``, ``corrective_episodes``, ``corrections``, ``env``, ``simulator``;
    ``schema_version``, ``behavior``, ``behaviors`` and ``channels`` are checked by
    :func:`canonical_metadata`). Other keys are kept as given.

    Raises
    ------
    DatasetError
        One line naming the file and the key (``field 'metadata goal'``).
    """
    _check_goal(metadata.get("goal"), file, _declared(metadata.get("channels")))
    period = metadata.get("control_period")
    if period is not None and not (_finite(period) and 0 < period <= MAX_CONTROL_PERIOD):
        raise _metadata_error(
            f"control_period must be a number of seconds in (0, {MAX_CONTROL_PERIOD:g}], "
            f"got {_short(period)}",
            file,
            "control_period",
        )
    _check_ranges(metadata.get("ranges"), file)
    corrective = metadata.get("corrective_episodes")
    if corrective is not None:
        if not isinstance(corrective, list):
            raise _metadata_error(
                f"corrective_episodes must be a list of episode ids, got {_short(corrective)}",
                file,
                "corrective_episodes",
            )
        for eid in corrective:
            if not (
                isinstance(eid, int)
                and not isinstance(eid, bool)
                and _INT64_MIN <= eid <= _INT64_MAX
            ):
                raise _metadata_error(
                    f"corrective_episodes must hold episode ids (int64 integers), got "
                    f"{_short(eid)}",
                    file,
                    "corrective_episodes",
                )
    _check_corrections(metadata.get("corrections"), file)
    for key in ("env", "simulator"):
        value = metadata.get(key)
        if value is not None and not (
            isinstance(value, str)
            and len(value) <= MAX_METADATA_TEXT
            and _LINE_BREAKS.search(value) is None
        ):
            raise _metadata_error(
                f"{key} must be one line of text of at most {MAX_METADATA_TEXT} characters, "
                f"got {_short(value)}",
                file,
                key,
            )


def _declared(entries: object) -> dict[str, ChannelSpec]:
    """The channels a dataset's metadata declares (malformed ones are refused elsewhere)."""
    out: dict[str, ChannelSpec] = {}
    for entry in entries if isinstance(entries, list) else []:
        if isinstance(entry, ChannelSpec):
            out[entry.name] = entry
            continue
        try:
            spec = channel_from_metadata(entry)
        except (ConfigError, TypeError, ValueError):
            continue
        out[spec.name] = spec
    return out


def _check_goal(
    goal: object, file: str | None, declared: Mapping[str, ChannelSpec] | None = None
) -> None:
    """``goal``: ``{channel: value}`` on goal channels (with a tolerance), values in range.

    A goal channel is a registered channel or one the dataset declares (``channels``).
    """
    if goal is None:
        return
    if not isinstance(goal, dict):
        raise _metadata_error(
            f"goal must be an object {{channel: value}}, got {_short(goal)}", file, "goal"
        )
    known = {**CHANNELS, **(declared or {})}
    goals = [c for c, s in known.items() if s.kind == "sensor" and s.tolerance is not None]
    for name, value in goal.items():
        spec = known.get(name) if isinstance(name, str) else None
        if spec is None or spec.kind != "sensor" or spec.tolerance is None:
            raise _metadata_error(
                f"unknown goal channel {_short(name)} (goal channels: {', '.join(goals)})",
                file,
                "goal",
            )
        if not _finite(value):
            raise _metadata_error(
                f"goal {name} must be a finite number, got {_short(value)}", file, "goal"
            )
        lo, hi = (-180.0, 180.0) if spec.wraps else spec.bounds or spec.range
        lo = max(lo, 0.0) if spec.range[0] >= 0.0 else lo
        lo, hi = max(lo, -MAX_METADATA_VALUE), min(hi, MAX_METADATA_VALUE)
        if not lo <= value <= hi:
            raise _metadata_error(
                f"goal {name} {value:g} {spec.unit} not in [{lo:g}, {hi:g}]", file, "goal"
            )


def _check_ranges(ranges: object, file: str | None) -> None:
    """``ranges``: ``{channel: [lo, hi]}``, finite, ``lo < hi``, within the model's bounds."""
    if ranges is None:
        return
    if not isinstance(ranges, dict):
        raise _metadata_error(
            f"ranges must be an object {{channel: [lo, hi]}}, got {_short(ranges)}",
            file,
            "ranges",
        )
    for name, pair in ranges.items():
        if not _CHANNEL_NAME_RE.match(name):
            raise _metadata_error(
                f"range given for {_short(name)}, which is not a channel name", file, "ranges"
            )
        if not (isinstance(pair, list) and len(pair) == 2 and all(_finite(v) for v in pair)):
            raise _metadata_error(
                f"range of {name} must be [lo, hi] (two finite numbers), got {_short(pair)}",
                file,
                "ranges",
            )
        lo, hi = float(pair[0]), float(pair[1])
        if not lo < hi:
            raise _metadata_error(
                f"range of {name} must satisfy lo < hi, got [{lo:g}, {hi:g}]", file, "ranges"
            )
        if max(abs(lo), abs(hi)) > MAX_METADATA_VALUE or hi - lo < 1.0 / MAX_METADATA_VALUE:
            raise _metadata_error(
                f"range of {name} must lie within ±{MAX_METADATA_VALUE:g} and span at least "
                f"{1.0 / MAX_METADATA_VALUE:g}, got [{lo:g}, {hi:g}]",
                file,
                "ranges",
            )


def _check_corrections(corrections: object, file: str | None) -> None:
    """``corrections``: ``{"copies": int >= 0, "noise": number >= 0, "disturbs": [names]}``."""
    if corrections is None:
        return
    if not isinstance(corrections, dict):
        raise _metadata_error(
            f"corrections must be an object, got {_short(corrections)}", file, "corrections"
        )
    copies = corrections.get("copies")
    if copies is not None and not (
        isinstance(copies, int) and not isinstance(copies, bool) and 0 <= copies <= _INT64_MAX
    ):
        raise _metadata_error(
            f"corrections.copies must be an integer >= 0, got {_short(copies)}",
            file,
            "corrections",
        )
    noise = corrections.get("noise")
    if noise is not None and not (_finite(noise) and noise >= 0):
        raise _metadata_error(
            f"corrections.noise must be a number >= 0, got {_short(noise)}", file, "corrections"
        )
    disturbs = corrections.get("disturbs")
    if disturbs is not None and not (
        isinstance(disturbs, list)
        and all(isinstance(c, str) and _CHANNEL_NAME_RE.match(c) for c in disturbs)
    ):
        raise _metadata_error(
            f"corrections.disturbs must be a list of channel names, got {_short(disturbs)}",
            file,
            "corrections",
        )


def check_table(
    columns: Mapping[str, object],
    metadata: Mapping[str, Any] | None = None,
    *,
    file: str | None = None,
    lines: NDArray[np.int64] | None = None,
    behaviors: Collection[str] | None = None,
) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
    """Validate a table of columns; return canonical arrays and metadata.

    Parameters
    ----------
    columns
        ``episode`` (integer ids, each episode's rows contiguous), ``t`` (s, strictly
        increasing within an episode), the sensor and command columns (physical units),
        one column per channel the metadata declares, and optionally ``behavior`` (one
        name per row).
    metadata
        JSON-serializable mapping; ``schema_version`` defaults to :data:`SCHEMA_VERSION`.
        ``channels`` declares extra sensor channels (:func:`declared_channels`); their
        values are checked like the standard ones (finite, within the spec's ``bounds``).
    file
        File name to put in error messages.
    lines
        CSV line number of each row, added to error messages.
    behaviors
        If given, the only behavior names allowed in the ``behavior`` column (the
        metadata key ``behaviors`` restricts them too).

    Returns
    -------
    columns, metadata
        ``episode`` as int64, the float columns (declared channels included) as
        float64, ``behavior`` as an object array of ``str``; all arrays are fresh copies.
    """
    extras = declared_channels(metadata, file=file)
    commands = declared_commands(metadata, file=file)
    clash = {spec.name for spec in extras} & {spec.name for spec in commands}
    if clash:
        raise DatasetError(
            f"'{sorted(clash)[0]}' is declared both as a sensor channel and as a command",
            file=file,
            field="commands",
        )
    check_column_names(
        columns.keys(),
        file=file,
        extra=[spec.name for spec in extras],
        commands=[spec.name for spec in commands],
    )
    arrays = {name: _as_array(values, name, file) for name, values in columns.items()}
    n = len(arrays["episode"])
    for name, arr in arrays.items():
        if len(arr) != n:
            raise DatasetError(
                f"column has {len(arr)} rows but 'episode' has {n}", file=file, field=name
            )
    if n == 0:
        raise DatasetError("dataset is empty (no rows, no episodes)", file=file)

    # Episode ids: integers, each episode one contiguous block of rows.
    ep = arrays["episode"]
    if ep.dtype.kind not in "iu":
        raise DatasetError(
            f"wrong type {ep.dtype} (episode ids must be integers)", file=file, field="episode"
        )
    if ep.dtype.kind == "u" and int(ep.max()) > _INT64_MAX:
        raise DatasetError("episode id too large for int64", file=file, field="episode")
    episode = ep.astype(np.int64)
    starts = np.flatnonzero(np.r_[True, episode[1:] != episode[:-1]]).astype(np.int64)
    block_ids = episode[starts]
    if len(np.unique(block_ids)) != len(block_ids):
        first_block: dict[int, int] = {}
        for b, eid in enumerate(block_ids.tolist()):
            if eid in first_block:
                prev = first_block[eid]
                message = (
                    "rows of one episode are not contiguous: it appears again after episode "
                    f"{int(block_ids[b - 1])} (keep each episode's rows together)"
                )
                if lines is not None:
                    message += f" (CSV line {int(lines[starts[b]])})"
                raise DatasetError(
                    message,
                    file=file,
                    episode=eid,
                    row=int(starts[prev + 1] - starts[prev]),
                    field="episode",
                )
            first_block[eid] = b
    where = _Locator(file, episode, starts, lines)
    out: dict[str, NDArray[Any]] = {"episode": episode}

    # Float columns: numeric type, finite, within plausible bounds.
    own_only = own_channels_only(arrays, [spec.name for spec in extras])
    floats = [
        (name, UNITS[name], VALUE_BOUNDS.get(name))
        for name in FLOAT_COLUMNS
        if not (own_only and name in SENSOR_CHANNELS) and name not in COMMAND_CHANNELS
    ]
    floats += [(spec.name, spec.unit, spec.bounds) for spec in commands]
    floats += [(spec.name, spec.unit, spec.bounds) for spec in extras]
    for name, unit, bounds in floats:
        arr = arrays[name]
        if arr.dtype.kind not in "iuf":
            raise DatasetError(
                f"wrong type {arr.dtype} (expected numbers in {unit})",
                file=file,
                field=name,
            )
        values = arr.astype(np.float64)
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.argmax(bad))
            kind = "NaN" if np.isnan(values[i]) else "infinite"
            raise where.error(f"{kind} value", i, name)
        if bounds is not None:
            lo, hi = bounds
            bad = (values < lo) | (values > hi)
            if bad.any():
                i = int(np.argmax(bad))
                raise where.error(
                    f"absurd value {values[i]:g} {unit}, outside the plausible range "
                    f"[{lo:g}, {hi:g}] {unit} (wrong units?)",
                    i,
                    name,
                )
        out[name] = values

    # Time strictly increasing within each episode.
    t = out["t"]
    same_episode = episode[1:] == episode[:-1]
    bad = same_episode & (t[1:] <= t[:-1])
    if bad.any():
        i = int(np.argmax(bad)) + 1
        raise where.error(
            f"time does not increase (t = {t[i]:.10g} s after t = {t[i - 1]:.10g} s)", i, "t"
        )

    md = canonical_metadata(metadata, file=file)

    # Behavior names: valid identifiers, and known ones where a list is given.
    if "behavior" in arrays:
        arr = arrays["behavior"]
        if arr.dtype.kind == "U":
            names = arr.astype(object)
        elif arr.dtype.kind == "O":
            names = arr.copy()
            not_str = np.fromiter((type(v) is not str for v in names), bool, count=n)
            if not_str.any():
                i = int(np.argmax(not_str))
                raise where.error(
                    f"wrong type {type(names[i]).__name__} (behavior names are strings)",
                    i,
                    "behavior",
                )
        else:
            raise DatasetError(
                f"wrong type {arr.dtype} (behavior names are strings)", file=file, field="behavior"
            )
        known: set[str] | None = None
        if behaviors is not None:
            known = set(behaviors)
        if md.get("behaviors") is not None:
            listed = set(md["behaviors"])
            known = listed if known is None else known & listed
        for name in np.unique(names).tolist():
            if _NAME_RE.match(name) is None:
                i = int(np.argmax(names == name))
                raise where.error(
                    f"invalid behavior name {name!r} (expected a lowercase identifier like "
                    "'turn', or two joined by '+' like 'turn+approach')",
                    i,
                    "behavior",
                )
            if known is not None and not (name in known or set(name.split("+")) <= known):
                i = int(np.argmax(names == name))
                listing = ", ".join(sorted(known)) or "none"
                raise where.error(
                    f"unknown behavior {name!r} (known: {listing}){suggest(name, known)}",
                    i,
                    "behavior",
                )
        out["behavior"] = names
    elif behaviors is not None:
        raise DatasetError(
            "no 'behavior' column (complex demonstrations name the active sub-behavior per row)",
            file=file,
            field="behavior",
        )
    return out, md


def validate(
    columns: Mapping[str, object],
    metadata: Mapping[str, Any] | None = None,
    *,
    file: str | None = None,
    behaviors: Collection[str] | None = None,
) -> None:
    """Check a table of dataset columns; raise :class:`DatasetError` if anything is wrong.

    See :func:`read` and :class:`Dataset` for the checks; both run them.
    """
    check_table(columns, metadata, file=file, behaviors=behaviors)
