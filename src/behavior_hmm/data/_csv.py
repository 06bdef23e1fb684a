"""Import users' own CSV logs: column mapping, units, the same validation as Parquet."""

from __future__ import annotations

import csv
import os
from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data._dataset import Dataset
from behavior_hmm.data._units import unit_factor, wrap_degrees
from behavior_hmm.data._validate import (
    FLOAT_COLUMNS,
    OPTIONAL_COLUMNS,
    REQUIRED_COLUMNS,
    check_column_names,
    check_table,
    suggest,
)
from behavior_hmm.errors import ConfigError, DatasetError

_OURS = (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS)

#: Largest |angle| (deg, after unit conversion) accepted before wrapping into (−180, 180].
MAX_UNWRAPPED_ANGLE = 36000.0


def _read_rows(
    path: Path, file: str, delimiter: str
) -> tuple[list[str], list[list[str]], list[int]]:
    """Header, data rows and the CSV line number (1-based) where each row ends."""
    rows: list[list[str]] = []
    lines: list[int] = []
    header: list[str] | None = None
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh, delimiter=delimiter, strict=True)
            for cells in reader:
                if not cells or (len(cells) == 1 and not cells[0].strip()):
                    continue  # blank line
                if header is None:
                    header = [c.strip() for c in cells]
                    continue
                rows.append(cells)
                lines.append(reader.line_num)
    except UnicodeDecodeError as exc:
        raise DatasetError(f"not UTF-8 text (byte {exc.start})", file=file) from None
    except csv.Error as exc:
        raise DatasetError(f"not a valid CSV file ({exc})", file=file) from None
    except OSError as exc:
        raise DatasetError(f"cannot read file ({exc.strerror or exc})", file=file) from None
    if header is None:
        raise DatasetError("empty file (no header line)", file=file)
    if not rows:
        raise DatasetError("no data rows (an empty episode)", file=file)
    return header, rows, lines


def _resolve_header(
    header: list[str], mapping: Mapping[str, str], drop: Collection[str], file: str
) -> dict[str, int]:
    """Our column name -> index of the CSV column that holds it."""
    for ours in mapping:
        if ours not in _OURS:
            raise ConfigError(
                f"mapping names unknown column '{ours}' (columns: {', '.join(_OURS)})"
                f"{suggest(ours, _OURS)}"
            )
    theirs_to_ours: dict[str, str] = {}
    for ours, theirs in mapping.items():
        if theirs in theirs_to_ours:
            raise ConfigError(
                f"mapping sends file column '{theirs}' to both '{theirs_to_ours[theirs]}' "
                f"and '{ours}'"
            )
        theirs_to_ours[theirs] = ours
    for ours, theirs in mapping.items():
        if theirs not in header:
            raise DatasetError(
                f"column '{theirs}' (mapped to '{ours}') is not in the file "
                f"(columns: {', '.join(header)}){suggest(theirs, header)}",
                file=file,
                field=theirs,
            )
    for name in drop:
        if name not in header:
            raise DatasetError(
                f"column to drop is not in the file{suggest(name, header)}", file=file, field=name
            )
    index: dict[str, int] = {}
    names: list[str] = []
    for i, theirs in enumerate(header):
        if theirs in drop:
            continue
        ours = theirs_to_ours.get(theirs, theirs)
        if ours in index:
            raise DatasetError(
                f"two columns give '{ours}' (columns {index[ours] + 1} and {i + 1})",
                file=file,
                field=ours,
            )
        index[ours] = i
        names.append(ours)
    check_column_names(names, file=file, required=[c for c in REQUIRED_COLUMNS if c != "episode"])
    return index


def _parse_float(cell: str) -> float:
    text = cell.strip()
    if not text or "_" in text:
        raise ValueError(text)
    return float(text)


def _parse_int(cell: str) -> int:
    text = cell.strip()
    try:
        return int(text)
    except ValueError:
        value = _parse_float(text)  # accept "3.0" from tools that write ids as floats
        if not value.is_integer():
            raise
        return int(value)


def _cell_error(
    message: str,
    i: int,
    field: str,
    file: str,
    lines: NDArray[np.int64],
    episode: NDArray[np.int64] | None,
) -> DatasetError:
    """Error at data row ``i``: episode and row within it (if known) and CSV line."""
    message = f"{message} (CSV line {int(lines[i])})"
    if episode is None:
        return DatasetError(message, file=file, field=field)
    eid = episode[i]
    first = int(np.argmax(episode == eid))
    return DatasetError(message, file=file, episode=int(eid), row=i - first, field=field)


def _parse_column(
    rows: list[list[str]],
    j: int,
    name: str,
    file: str,
    lines: NDArray[np.int64],
    episode: NDArray[np.int64] | None,
) -> NDArray[Any]:
    """Parse column ``j``: int64 episode ids for ``episode``, float64 otherwise."""
    is_id = name == "episode"
    cells_j = [cells[j] for cells in rows]
    if "_" not in "".join(cells_j):  # Python would read "1_0" as 10
        try:  # fast path; on failure the loop below finds and names the bad cell
            if is_id:
                return np.array([int(c) for c in cells_j], dtype=np.int64)
            return np.array([float(c) for c in cells_j], dtype=np.float64)
        except (ValueError, OverflowError):
            pass
    values = np.empty(len(rows), dtype=np.int64 if is_id else np.float64)
    for i, cells in enumerate(rows):
        cell = cells[j].strip()
        try:
            values[i] = _parse_int(cell) if is_id else _parse_float(cell)
        except (ValueError, OverflowError):
            if not cell:
                what = "missing value"
            elif is_id:
                what = f"wrong type: episode id {cell[:40]!r} is not an integer"
            else:
                what = f"wrong type: {cell[:40]!r} is not a number"
            raise _cell_error(what, i, name, file, lines, episode) from None
    return values


def import_csv(
    path: str | os.PathLike[str],
    *,
    mapping: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    drop: Collection[str] = (),
    metadata: Mapping[str, Any] | None = None,
    split_on_time_reset: bool = False,
    delimiter: str = ",",
) -> Dataset:
    """Read a user's CSV log into a validated :class:`Dataset`.

    The first non-blank line is the header. Row numbers in errors are counted within
    the episode (0-based), and the CSV line number (1-based, header = line 1) is
    given too.

    Parameters
    ----------
    path
        CSV file, UTF-8.
    mapping
        Our column name -> the file's column name, e.g. ``{"angle": "bearing"}``.
        Unmapped file columns must already have our names.
    units
        Our column name -> the unit the file uses, e.g. ``{"angle": "rad",
        "distance": "mm", "left": "rpm"}`` (see ``UNIT_FACTORS``); values are
        converted to the canonical units (``UNITS``). Angles are then wrapped into
        (−180, 180] degrees.
    drop
        File columns to ignore (any other column that is not ours is an error).
    metadata
        Dataset metadata; a ``source`` entry recording file, mapping and units is added.
    split_on_time_reset
        Without an ``episode`` column the whole file is one episode (id 0) and
        time must increase. With this flag a new episode starts wherever time
        goes back (drops), so concatenated logs can be imported as they are.
    delimiter
        Cell separator.

    Raises
    ------
    DatasetError
        For anything wrong with the file (naming file, episode, row, field, line).
    ConfigError
        For an unknown column name in ``mapping`` or ``units`` or an unknown unit.
    """
    file = str(path)
    p = Path(path)
    mapping = dict(mapping or {})
    units = dict(units or {})
    factors = {name: unit_factor(name, unit) for name, unit in units.items()}
    if not p.exists():
        raise DatasetError("no such file", file=file)
    if p.is_dir():
        raise DatasetError("is a directory, not a CSV file", file=file)
    header, rows, line_list = _read_rows(p, file, delimiter)
    lines = np.asarray(line_list, dtype=np.int64)
    index = _resolve_header(header, mapping, set(drop), file)
    n_cells = len(header)
    n = len(rows)
    for i, cells in enumerate(rows):
        if len(cells) != n_cells:
            raise DatasetError(
                f"row has {len(cells)} cells but the header has {n_cells} "
                f"(CSV line {int(lines[i])})",
                file=file,
            )

    # Episode ids come first, so that later errors can name episode and row.
    if "episode" in index:
        episode = _parse_column(rows, index["episode"], "episode", file, lines, None)
    elif split_on_time_reset:
        t = _parse_column(rows, index["t"], "t", file, lines, None)
        episode = np.r_[0, np.cumsum(t[1:] < t[:-1])].astype(np.int64)
    else:
        episode = np.zeros(n, dtype=np.int64)
    columns: dict[str, NDArray[Any]] = {"episode": episode}
    for name in FLOAT_COLUMNS:
        values = _parse_column(rows, index[name], name, file, lines, episode)
        columns[name] = values * factors[name] if name in factors else values
    if "behavior" in index:
        j = index["behavior"]
        columns["behavior"] = np.array([cells[j].strip() for cells in rows], dtype=object)

    # Wrapping would hide absurd angles, so refuse those first.
    angle = columns["angle"]
    with np.errstate(invalid="ignore"):
        huge = np.abs(angle) > MAX_UNWRAPPED_ANGLE
        columns["angle"] = np.where(np.isfinite(angle), wrap_degrees(angle), angle)
    if huge.any():
        i = int(np.argmax(huge))
        raise _cell_error(
            f"absurd angle {angle[i]:g} deg (beyond ±{MAX_UNWRAPPED_ANGLE:g} deg; wrong units?)",
            i,
            "angle",
            file,
            lines,
            episode,
        )

    md = dict(metadata or {})
    md.setdefault("source", {"format": "csv", "file": p.name, "mapping": mapping, "units": units})
    cols, md = check_table(columns, md, file=file, lines=lines)
    return Dataset._trusted(cols, md)
