"""Model parameters from a preset, a TOML config file and ``--set name=value``.

The effective parameters of a model are, in order of precedence (last wins):

1. the preset (``thesis`` or ``default``, :mod:`behavior_hmm.models._presets`);
2. a config file (``--config FILE.toml``): top-level ``name = value`` keys, or tables
   ``[sblm]`` / ``[cblm]`` for one kind; a top-level ``preset = "thesis"`` selects the
   preset when the command line names none;
3. ``--set name=value`` (repeatable; ``sblm.name=value`` / ``cblm.name=value`` for one
   kind). Values are TOML (``1``, ``0.5``, ``true``, ``"plan"``, ``[10, 5]``); a bare
   word is a string and ``none`` means ``None``.

A name without a kind applies to every model kind being configured that has it. An
unknown name, a value of the wrong type, or a table that is not a parameter is refused
with one line (and a did-you-mean), before any work.
"""

from __future__ import annotations

import difflib
import math
import os
import tomllib
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Final

from behavior_hmm._safe_read import MAX_SIDE_FILE_BYTES, check_nesting, config_error, load_toml
from behavior_hmm.errors import ConfigError
from behavior_hmm.models._presets import (
    KINDS,
    NOT_PRESET,
    check_preset,
    constructor_defaults,
    preset_params,
)

#: Parameters that also take ``None`` (their default, or a documented meaning).
_NULLABLE = frozenset({"hidden", "cutoff_hz", "primitive_params", "observation_params"})
#: Parameters that take a table of CobART overrides.
_TABLES = frozenset({"primitive_params", "observation_params"})
#: Config files larger than this are refused before parsing (bytes).
_MAX_CONFIG_BYTES: Final[int] = 1 << 20
#: Integers a parameter may take: 64-bit signed (numpy's and the model file's).
_INT_RANGE: Final[tuple[int, int]] = (-(2**63), 2**63 - 1)
#: Characters of a value of the user's quoted in an error message (then ``...``).
SHOWN_CHARS: Final[int] = 80


def shown(value: object) -> str:
    """``value`` for an error message: its ``repr``, cut to :data:`SHOWN_CHARS`."""
    if isinstance(value, dict):
        return f"a table of {len(value):,} entries"
    if isinstance(value, list) and len(value) > SHOWN_CHARS:
        return f"a list of {len(value):,} items"
    text = repr(value)
    return text if len(text) <= SHOWN_CHARS else text[:SHOWN_CHARS] + "..."


def _name(name: str) -> str:
    return name if len(name) <= SHOWN_CHARS else name[:SHOWN_CHARS] + "..."


def did_you_mean(name: str, choices: Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest choice, or a list of the choices."""
    options = sorted(set(choices))
    close = difflib.get_close_matches(name[: 4 * SHOWN_CHARS], options, n=1, cutoff=0.6)
    if close:
        return f"; did you mean '{close[0]}'?"
    return f"; known: {', '.join(options)}"


def parse_value(text: str) -> Any:
    """A ``--set`` value: TOML (numbers, booleans, strings, arrays), bare words as strings."""
    stripped = text.strip()
    if stripped.lower() in ("none", "null"):
        return None
    try:
        check_nesting(stripped, file="--set", toml=True, error=config_error)
        return tomllib.loads(f"v = {stripped}")["v"]
    except ConfigError as err:  # nested too deep
        raise ConfigError(f"{err} (a --set value)") from None
    except (tomllib.TOMLDecodeError, ValueError, RecursionError):
        # not TOML (or an integer of more than 4,300 digits): a bare word
        return stripped


def parse_sets(items: Sequence[str]) -> dict[str, Any]:
    """``["batch_size=1", "cblm.repair=false"]`` → ``{"batch_size": 1, "cblm.repair": False}``."""
    out: dict[str, Any] = {}
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ConfigError(f"--set expects NAME=VALUE, got {shown(item)}")
        if name in out:
            raise ConfigError(f"--set names '{_name(name)}' twice")
        out[name] = parse_value(value)
    return out


def read_config(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a TOML config file (flattened to ``name`` / ``kind.name`` keys).

    Read as every side file is (:func:`behavior_hmm._safe_read.load_toml`): a regular
    file (a FIFO or a device is refused unopened) of at most 1 MiB, nested at most 32
    levels; a ``[kind]`` table holds parameters, whose values :func:`check_value` types.
    """
    where = os.fspath(path)
    if not os.path.exists(where):  # a stat: never opens (a FIFO is refused by load_toml)
        raise ConfigError(f"{where}: no such config file")
    try:
        doc = load_toml(where, limit=min(_MAX_CONFIG_BYTES, MAX_SIDE_FILE_BYTES), file=where)
    except ConfigError:
        raise
    except ValueError as err:  # e.g. an integer of more than 4,300 digits
        reason = " ".join(str(err).split())[: 2 * SHOWN_CHARS]
        raise ConfigError(f"{where}: not valid TOML ({reason})") from None
    out: dict[str, Any] = {}
    for key, value in doc.items():
        kind = _kind_of(key)
        if kind is not None and isinstance(value, dict):
            for name, sub in value.items():
                out[f"{kind.lower()}.{name}"] = sub
        else:
            out[key] = value
    return out


def _kind_of(prefix: str) -> str | None:
    for kind in KINDS:
        if prefix.lower() == kind.lower():
            return kind
    return None


def check_value(kind: str, name: str, value: Any) -> Any:
    """``value`` converted to the type of ``kind``'s parameter ``name`` (ConfigError if wrong)."""
    defaults = constructor_defaults(kind)
    if name not in defaults:
        raise ConfigError(f"unknown {kind} parameter '{_name(name)}'{did_you_mean(name, defaults)}")
    default = defaults[name]
    label = f"{kind} parameter '{name}'"
    if value is None:
        if name in _NULLABLE:
            return None
        raise ConfigError(f"{label} cannot be none")
    if name in _TABLES:
        if not isinstance(value, dict):
            raise ConfigError(f"{label} must be a table of CobART parameters, got {shown(value)}")
        return dict(value)
    if name == "hidden":
        if isinstance(value, list) and value and all(_small_int(v) for v in value):
            return tuple(int(v) for v in value)
        if _small_int(value):
            return int(value)
        raise ConfigError(f"{label} must be a positive integer, a list of them, or none")
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ConfigError(f"{label} must be true or false, got {shown(value)}")
        return value
    if isinstance(default, int):
        if not _is_int(value):
            raise ConfigError(f"{label} must be an integer, got {shown(value)}")
        if not _INT_RANGE[0] <= value <= _INT_RANGE[1]:
            raise ConfigError(f"{label} must be a 64-bit integer, got {shown(value)}")
        return int(value)
    if isinstance(default, float):
        number = isinstance(value, int | float) and not isinstance(value, bool)
        if not number or not math.isfinite(value):
            raise ConfigError(f"{label} must be a finite number, got {shown(value)}")
        return float(value)
    if isinstance(default, str):
        if not isinstance(value, str):
            raise ConfigError(f"{label} must be a string, got {shown(value)}")
        return value
    return value


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _small_int(value: Any) -> bool:
    """A positive integer of at most 64 bits (a layer size)."""
    return _is_int(value) and 0 < value <= _INT_RANGE[1]


def resolve_params(
    kinds: Sequence[str],
    preset: str | None = None,
    config: Mapping[str, Any] | None = None,
    sets: Mapping[str, Any] | None = None,
    *,
    config_name: str = "config",
) -> tuple[str, dict[str, dict[str, Any]]]:
    """The effective constructor parameters of each of ``kinds``.

    Parameters
    ----------
    kinds
        The model kinds being configured (``("SBLM",)``, ``("CBLM",)`` or both).
    preset
        ``"thesis"`` or ``"default"``; ``None`` takes the config's ``preset`` key, else
        ``"default"``.
    config
        Flattened config file (:func:`read_config`).
    sets
        ``--set`` assignments (:func:`parse_sets`).
    config_name
        How errors name the config (its path).

    Returns
    -------
    tuple
        The preset used and ``{kind: parameters}`` (without inputs, components, seed).
    """
    config = dict(config or {})
    chosen = config.pop("preset", None)
    if chosen is not None and not isinstance(chosen, str):
        raise ConfigError(f"{config_name}: 'preset' must be a string, got {shown(chosen)}")
    if isinstance(chosen, str) and len(chosen) > SHOWN_CHARS:
        raise ConfigError(f"{config_name}: unknown preset {shown(chosen)}")
    name = check_preset(preset if preset is not None else (chosen or "default"))
    params = {kind: preset_params(name, kind) for kind in kinds}
    for source, assignments in ((config_name, config), ("--set", dict(sets or {}))):
        for key, value in assignments.items():
            try:
                _apply(params, key, value, source)
            except ConfigError as err:
                text = str(err)
                where = text if text.startswith(source) else f"{source}: {text}"
                raise ConfigError(where) from None
    return name, params


def _apply(params: dict[str, dict[str, Any]], key: str, value: Any, source: str) -> None:
    head, dot, rest = key.partition(".")
    kind = _kind_of(head) if dot else None
    name = rest if kind is not None else key
    if name in NOT_PRESET:
        option = {"random_state": "--seed", "inputs": "--inputs", "components": "--component"}
        raise ConfigError(f"'{name}' is set by its own option ({option[name]}), not here")
    if kind is not None:
        targets = [kind]
        check_value(kind, name, value)  # a config file's other tables are checked too
    else:
        targets = [k for k in KINDS if name in constructor_defaults(k)]
        if not targets:
            known = {n for k in KINDS for n in constructor_defaults(k)}
            raise ConfigError(f"unknown parameter '{_name(name)}'{did_you_mean(name, known)}")
    used = [k for k in targets if k in params]
    if not used and source == "--set":
        # a config file may serve several commands; an explicit --set must take effect
        raise ConfigError(
            f"{key} is a {'/'.join(targets)} parameter, but this command "
            f"configures {'/'.join(params)}"
        )
    for target in used:
        params[target][name] = check_value(target, name, value)
