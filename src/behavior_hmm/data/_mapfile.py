"""Mapping files (TOML) for the importers: column / topic / feature mapping, units, options.

One file holds what the command-line options would say, so a lab can keep the mapping
of its logs beside them::

    # mapping.toml
    derive = ["linear_velocity", "angular_velocity"]
    resample = true

    [map]          # ours = theirs
    angle = "bearing"
    t = "time_ms"

    [unit]         # ours = the unit the file uses
    angle = "rad"
    t = "ms"

A robot's own channels and its goal are declared as the options declare them::

    channel = ["ir0:m:0:0.1", "x:m:-1:1:0.01"]   # --channel NAME:UNIT:LO:HI[:TOL]
    command = ["vx:m/s:-0.5:0.5", "vy:m/s:-0.5:0.5"]   # --command, in action order

    [goal]         # --goal x=0,y=0
    x = 0.0
    y = 0.0

Options given on the command line win over the file's, key by key (``--channel``,
``--command`` and ``--goal`` replace the file's list or table as a whole).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Final, TypeVar

from behavior_hmm._safe_read import config_error, load_toml
from behavior_hmm.data._validate import suggest
from behavior_hmm.errors import ConfigError

T = TypeVar("T")

#: Characters of a name or value in a mapping file (a column, topic, unit, behavior).
MAX_VALUE_CHARS: Final[int] = 256
#: Entries of a table (``[map]``, ``[unit]``) or items of a list (``drop``, ``derive``).
MAX_ITEMS: Final[int] = 1024
#: Characters of a value of the file's quoted in an error message (then ``...``).
SHOWN_CHARS: Final[int] = 80

#: Keys each importer's mapping file may hold (besides the tables ``map`` and ``unit``).
#: Keys every importer's mapping file may hold: the robot's own channels and the goal.
DECLARATION_KEYS: Final[dict[str, type]] = {"channel": list, "command": list}

OPTION_KEYS: Final[dict[str, dict[str, type | tuple[type, ...]]]] = {
    "csv": {
        "drop": list,
        "derive": list,
        "resample": bool,
        "delimiter": str,
        "split_on_time_reset": bool,
        "behavior": str,
    },
    "bag": {
        "derive": list,
        "resample": bool,
        "twist": str,
        "split_gap": (int, float),
        "episode_topic": str,
        "behavior": str,
        "wheel_radius": (int, float),
        "track_width": (int, float),
    },
    "lerobot": {"derive": list, "resample": bool, "behavior": str},
}


@dataclass
class MapFile:
    """A mapping file's contents: ``map`` (ours -> theirs), ``unit`` and other options."""

    map: dict[str, str] = field(default_factory=dict)
    unit: dict[str, str] = field(default_factory=dict)
    options: dict[str, Any] = field(default_factory=dict)


def _shown(value: object) -> str:
    """``value`` for an error message: its ``repr``, cut to :data:`SHOWN_CHARS`."""
    text = repr(value) if isinstance(value, str | int | float | bool) else _kind(value)
    return text if len(text) <= SHOWN_CHARS else text[:SHOWN_CHARS] + "..."


def _kind(value: object) -> str:
    if isinstance(value, dict):
        return f"a table of {len(value):,} entries"
    if isinstance(value, list):
        return f"a list of {len(value):,} items"
    return f"a {type(value).__name__}"


def _key(name: str) -> str:
    """A key of the file for an error message, cut to :data:`SHOWN_CHARS`."""
    return name if len(name) <= SHOWN_CHARS else name[:SHOWN_CHARS] + "..."


def _string(value: object, where: str, file: str) -> str:
    """A non-empty string of at most :data:`MAX_VALUE_CHARS` characters, stripped."""
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(f"{file}: {where} must be a non-empty string, got {_shown(value)}")
    _bounded(value, where, file)
    return value.strip()


def _bounded(value: str, where: str, file: str) -> None:
    if len(value) > MAX_VALUE_CHARS:
        raise ConfigError(
            f"{file}: {where} is longer than {MAX_VALUE_CHARS} characters ({_shown(value)})"
        )


def _table(
    doc: dict[str, Any],
    key: str,
    file: str,
    parse: Callable[[object, str, str], T],
    lines: str,
) -> dict[str, T]:
    """The table ``[key]`` (empty if absent), each value read by ``parse``."""
    value = doc.get(key, {})
    if not isinstance(value, dict):
        raise ConfigError(f"{file}: '{key}' must be a table ([{key}]) of {lines} lines")
    if len(value) > MAX_ITEMS:
        raise ConfigError(f"{file}: [{key}] has {len(value):,} entries (limit {MAX_ITEMS:,})")
    out: dict[str, T] = {}
    for name, item in value.items():
        label = f"[{key}] {_key(name)}"
        if len(name) > MAX_VALUE_CHARS:
            raise ConfigError(f"{file}: {label} is longer than {MAX_VALUE_CHARS} characters")
        out[str(name)] = parse(item, label, file)
    return out


def read_map_file(path: str | os.PathLike[str], kind: str) -> MapFile:
    """Read a TOML mapping file for the ``kind`` importer (``csv``, ``bag``, ``lerobot``).

    The file is read as every side file is (:func:`behavior_hmm._safe_read.load_toml`):
    a regular file (a FIFO or a device is refused unopened) of at most 4 MiB, lines of
    at most 1 MiB, nested at most 32 levels. Names and values are strings of at most
    :data:`MAX_VALUE_CHARS` characters, tables and lists of at most :data:`MAX_ITEMS`
    entries, numbers finite.

    Raises
    ------
    ConfigError
        If the file cannot be read, is not TOML, or holds an unknown key or a value of
        the wrong type (one line naming the file and key).
    """
    file = str(path)
    if not os.path.exists(path):  # a stat: never opens (a FIFO is refused by load_toml)
        raise ConfigError(f"{file}: no such mapping file")
    try:
        doc = load_toml(path, file=file, error=config_error)
    except ConfigError:
        raise
    except ValueError as exc:  # e.g. an integer of more than 4,300 digits
        reason = " ".join(str(exc).split())[: 2 * SHOWN_CHARS]
        raise ConfigError(f"{file}: not valid TOML ({reason})") from None
    allowed = {**OPTION_KEYS[kind], **DECLARATION_KEYS}
    known = ("map", "unit", "goal", *allowed)
    for key in doc:
        if key not in known:
            raise ConfigError(
                f"{file}: unknown key '{_key(key)}' (known: {', '.join(known)})"
                f"{suggest(key[:SHOWN_CHARS], known)}"
            )
    options: dict[str, Any] = {}
    for key, typ in allowed.items():
        if key not in doc:
            continue
        value = doc[key]
        if isinstance(value, bool) and typ is not bool:
            raise ConfigError(f"{file}: '{key}' has the wrong type (got {_shown(value)})")
        if not isinstance(value, typ):
            raise ConfigError(f"{file}: '{key}' has the wrong type (got {_shown(value)})")
        if isinstance(value, list):
            if not all(isinstance(v, str) for v in value):
                raise ConfigError(f"{file}: '{key}' must be a list of strings")
            if len(value) > MAX_ITEMS:
                raise ConfigError(f"{file}: '{key}' has {len(value):,} items (limit {MAX_ITEMS:,})")
            for item in value:
                _bounded(item, f"'{key}' item", file)
        elif isinstance(value, str):
            _bounded(value, f"'{key}'", file)
            if key == "delimiter":
                _check_delimiter(value, file)
        elif isinstance(value, float) and not math.isfinite(value):
            raise ConfigError(f"{file}: '{key}' must be a finite number, got {_shown(value)}")
        options[key] = value
    if "goal" in doc:
        options["goal"] = _table(doc, "goal", file, _number, "CHANNEL = NUMBER")
        if not options["goal"]:
            raise ConfigError(f"{file}: [goal] is empty; e.g. [goal] x = 0.0")
    text = 'NAME = "VALUE"'
    return MapFile(
        _table(doc, "map", file, _string, text), _table(doc, "unit", file, _string, text), options
    )


def _number(value: object, where: str, file: str) -> float:
    """A finite number of magnitude at most 1e6 (a goal in a channel's unit)."""
    if (
        isinstance(value, bool)
        or not isinstance(value, int | float)
        or abs(value) > 1e6
        or not math.isfinite(value)
    ):
        raise ConfigError(f"{file}: {where} must be a finite number, got {_shown(value)}")
    return float(value)


def _check_delimiter(value: str, file: str) -> None:
    """One character, or ``tab`` (``\\t``), as ``--delimiter`` takes it."""
    if len(value) != 1 and value not in ("tab", "\\t"):
        raise ConfigError(
            f"{file}: 'delimiter' must be one character or 'tab', got {_shown(value)}"
        )
