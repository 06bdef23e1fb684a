"""Validation of dataset columns and metadata (DESIGN §4).

Every check raises :class:`~behavior_hmm.errors.DatasetError` naming the file,
the episode (its id), the row (0-based, counted within the episode) and the
field, as far as they apply.
"""

from __future__ import annotations

import difflib
import json
import re
from collections.abc import Collection, Iterable, Mapping
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data._channels import COMMAND_CHANNELS, SENSOR_CHANNELS, UNITS
from behavior_hmm.errors import DatasetError

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
    "distance": (-0.5, 10.0),
    "linear_velocity": (-5.0, 5.0),
    "angle": (-180.0, 180.0),
    "angular_velocity": (-3600.0, 3600.0),
    "left": (-1000.0, 1000.0),
    "right": (-1000.0, 1000.0),
}

#: Behavior names: a lowercase identifier such as ``turn`` or ``turn_approach``.
BEHAVIOR_NAME_PATTERN: Final[str] = r"^[a-z][a-z0-9_-]{0,63}$"
_NAME_RE = re.compile(r"[a-z][a-z0-9_-]{0,63}\Z")

_INT64_MAX = np.iinfo(np.int64).max


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
            "matching ^[a-z][a-z0-9_-]*$)",
            file=file,
            field=field,
        )
    return name


def check_column_names(
    names: Iterable[str],
    *,
    file: str | None = None,
    required: Collection[str] = REQUIRED_COLUMNS,
) -> None:
    """Refuse duplicate, unexpected (with the closest expected name) and missing columns."""
    names = list(names)
    allowed = (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS)
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise DatasetError("column appears twice", file=file, field=name)
        seen.add(name)
    missing = [c for c in required if c not in seen]
    for name in names:
        if name not in allowed:
            hint = suggest(name, missing or allowed)
            raise DatasetError(
                f"unexpected column{hint or ' (expected columns: ' + ', '.join(allowed) + ')'}",
                file=file,
                field=name,
            )
    if missing:
        raise DatasetError(
            f"missing column (a dataset needs: {', '.join(REQUIRED_COLUMNS)})",
            file=file,
            field=missing[0],
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
    return out


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
        increasing within an episode), the sensor and command columns (physical units)
        and optionally ``behavior`` (one name per row).
    metadata
        JSON-serializable mapping; ``schema_version`` defaults to :data:`SCHEMA_VERSION`.
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
        ``episode`` as int64, the float columns as float64, ``behavior`` as an object
        array of ``str``; all arrays are fresh copies.
    """
    check_column_names(columns.keys(), file=file)
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
    for name in FLOAT_COLUMNS:
        arr = arrays[name]
        if arr.dtype.kind not in "iuf":
            raise DatasetError(
                f"wrong type {arr.dtype} (expected numbers in {UNITS[name]})",
                file=file,
                field=name,
            )
        values = arr.astype(np.float64)
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.argmax(bad))
            kind = "NaN" if np.isnan(values[i]) else "infinite"
            raise where.error(f"{kind} value", i, name)
        if name in VALUE_BOUNDS:
            lo, hi = VALUE_BOUNDS[name]
            bad = (values < lo) | (values > hi)
            if bad.any():
                i = int(np.argmax(bad))
                unit = UNITS[name]
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
                    "'turn', matching ^[a-z][a-z0-9_-]*$)",
                    i,
                    "behavior",
                )
            if known is not None and name not in known:
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
