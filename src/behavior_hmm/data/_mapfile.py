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

Options given on the command line win over the file's, key by key.
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

from behavior_hmm.data._validate import suggest
from behavior_hmm.errors import ConfigError

#: Keys each importer's mapping file may hold (besides the tables ``map`` and ``unit``).
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


def _table(doc: dict[str, Any], key: str, file: str) -> dict[str, str]:
    value = doc.get(key, {})
    if not isinstance(value, dict):
        raise ConfigError(f"{file}: '{key}' must be a table ([{key}]) of NAME = \"VALUE\" lines")
    out: dict[str, str] = {}
    for name, item in value.items():
        if not isinstance(item, str) or not item.strip():
            raise ConfigError(f"{file}: [{key}] {name} must be a non-empty string, got {item!r}")
        out[str(name)] = item.strip()
    return out


def read_map_file(path: str | os.PathLike[str], kind: str) -> MapFile:
    """Read a TOML mapping file for the ``kind`` importer (``csv``, ``bag``, ``lerobot``).

    Raises
    ------
    ConfigError
        If the file cannot be read, is not TOML, or holds an unknown key or a value of
        the wrong type (one line naming the file and key).
    """
    file = str(path)
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"{file}: no such mapping file")
    try:
        doc = tomllib.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{file}: cannot read mapping file ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{file}: not a valid TOML file ({exc})") from None
    allowed = OPTION_KEYS[kind]
    known = ("map", "unit", *allowed)
    for key in doc:
        if key not in known:
            raise ConfigError(
                f"{file}: unknown key '{key}' (known: {', '.join(known)}){suggest(key, known)}"
            )
    options: dict[str, Any] = {}
    for key, typ in allowed.items():
        if key not in doc:
            continue
        value = doc[key]
        if isinstance(value, bool) and typ is not bool:
            raise ConfigError(f"{file}: '{key}' has the wrong type (got {value!r})")
        if not isinstance(value, typ):
            raise ConfigError(f"{file}: '{key}' has the wrong type (got {value!r})")
        if isinstance(value, list) and not all(isinstance(v, str) for v in value):
            raise ConfigError(f"{file}: '{key}' must be a list of strings")
        options[key] = value
    return MapFile(_table(doc, "map", file), _table(doc, "unit", file), options)
