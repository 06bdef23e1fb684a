"""Import users' CSV logs: column mapping, units, derived velocities, resampling.

The cells are parsed by pyarrow's CSV reader (``pyarrow.csv``); this module finds each
record's line in the file first, so that every error names the CSV line, and checks
what pyarrow does not: ragged rows, NUL bytes, the header, the episode ids.
"""

from __future__ import annotations

import csv
import io
import math
import os
from array import array
from collections.abc import Callable, Collection, Mapping, Sequence
from pathlib import Path
from typing import Any, Final

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pa_csv
from numpy.typing import NDArray

from behavior_hmm._safe_read import read_text
from behavior_hmm.data._channels import (
    COMMAND_CHANNELS,
    CONTROL_PERIOD,
    SENSOR_CHANNELS,
    ChannelSpec,
    channel_from_metadata,
)
from behavior_hmm.data._dataset import Dataset
from behavior_hmm.data._transform import (
    DERIVABLE,
    _rename_episode,
    check_units_of_derived,
    finish,
    parse_derive,
)
from behavior_hmm.data._transform import (
    resample as resample_columns,
)
from behavior_hmm.data._units import (
    MAX_UNWRAPPED_ANGLE,
    unit_factor,
    wrap_imported_angles,
)
from behavior_hmm.data._validate import (
    BEHAVIOR_NAME_PATTERN,
    FLOAT_COLUMNS,
    OPTIONAL_COLUMNS,
    REQUIRED_COLUMNS,
    check_table,
    declared_channels,
    declared_commands,
    own_channels_only,
    suggest,
)
from behavior_hmm.errors import ConfigError, DatasetError

#: A number as pyarrow's float parser reads it (used only to find a bad cell quickly).
_NUMBER_RE = r"(?i)^[+-]?((\d+\.?\d*|\.\d+)(e[+-]?\d+)?|nan|inf|infinity)$"

_MIB: Final[int] = 1024 * 1024

# The bounds below keep an import (read, parse, validate, derive, resample) under 1 GiB
# and about 10 s at its worst (measured: 1,000,000 rows resampled, or 250,000 rows of
# 64 columns, each under 1 GiB peak together with the package's own 150 MiB).

#: A CSV log read whole (bytes on disk).
MAX_CSV_BYTES: Final[int] = 64 * _MIB
#: Lines of a CSV log (header and blank lines included): about 4.4 hours at 16 ms.
MAX_CSV_LINES: Final[int] = 1_000_000
#: Columns of a CSV log.
MAX_COLUMNS: Final[int] = 1024
#: Cells of a CSV log (data rows times columns), and of a resampled one.
MAX_CSV_CELLS: Final[int] = 12_000_000
#: Rows a resampled log may have in all (as many as a log may have lines).
MAX_RESAMPLED_ROWS: Final[int] = MAX_CSV_LINES
#: Rows a resampled episode may have per row of its own: at 16 ms, its samples may be
#: 16 s apart on average.
MAX_RESAMPLE_FACTOR: Final[int] = 1000
#: Characters of an episode id that is a name (``run-a``).
MAX_ID_CHARS: Final[int] = 128
#: Characters of a value of the user's quoted in an error message (then ``...``).
SHOWN_CHARS: Final[int] = 80
#: Column names listed in one error message (then ``and N more``).
SHOWN_NAMES: Final[int] = 12

#: How to declare a column of the log as a robot's own sensor channel.
_DECLARE = "declare a robot's own sensor channel with --channel NAME:UNIT:LO:HI"


def _shown(value: object, limit: int = SHOWN_CHARS) -> str:
    """``value`` quoted for an error message, cut to ``limit`` characters (``...``)."""
    text = value if isinstance(value, str) else str(value)
    if len(text) > limit:
        text = text[:limit] + "..."
    return repr(text)


def _name(value: str, limit: int = SHOWN_CHARS) -> str:
    """A column name for an error message (a ``field``), cut to ``limit`` characters."""
    return value if len(value) <= limit else value[:limit] + "..."


def _names(values: Sequence[str], most: int = SHOWN_NAMES) -> str:
    """``a, b, c`` (each name cut), at most ``most`` of them, then ``and N more``."""
    shown = [_name(v) for v in values[:most]]
    if len(values) > most:
        shown.append(f"and {len(values) - most:,} more")
    return ", ".join(shown)


def _suggest(name: str, candidates: Sequence[str]) -> str:
    """:func:`suggest` with the suggestion cut (a header's names are the user's)."""
    hint = suggest(name[: 4 * SHOWN_CHARS], [c[: 4 * SHOWN_CHARS] for c in candidates])
    return hint if len(hint) <= SHOWN_CHARS + 20 else ""


def check_delimiter(delimiter: object) -> str:
    """``delimiter`` if it is one ASCII character that can separate cells of numbers."""
    if not isinstance(delimiter, str):
        raise ConfigError(f"delimiter must be a string, got {type(delimiter).__name__}")
    if len(delimiter) != 1:
        raise ConfigError(f"delimiter must be one character, got {_shown(delimiter)}")
    if delimiter != "\t" and not (delimiter.isascii() and delimiter.isprintable()):
        raise ConfigError(
            f"delimiter must be one ASCII character (e.g. ',', ';' or a tab), got {delimiter!r}"
        )
    if delimiter.isalnum() or delimiter in '".+-':
        raise ConfigError(
            f"delimiter {delimiter!r} can be part of a number or a quoted cell; "
            "give another one (e.g. ',', ';' or a tab)"
        )
    return delimiter


def _check_columns(n: int, file: str) -> None:
    if n > MAX_COLUMNS:
        raise DatasetError(
            f"the header has {n:,} columns (limit {MAX_COLUMNS:,}); not a log this reads",
            file=file,
        )


def _check_line_count(text: str, file: str) -> None:
    """Refuse a log of more than :data:`MAX_CSV_LINES` lines before splitting it."""
    breaks = text.count("\n") + text.count("\r") - text.count("\r\n")
    n = breaks + (0 if text.endswith(("\n", "\r")) or not text else 1)
    if n > MAX_CSV_LINES:
        raise DatasetError(
            f"{n:,} lines (limit {MAX_CSV_LINES:,}, {_hours(MAX_CSV_LINES)} at "
            f"{CONTROL_PERIOD * 1000:g} ms); split the log into smaller files",
            file=file,
        )


def _hours(rows: int) -> str:
    return f"about {rows * CONTROL_PERIOD / 3600:.1f} hours"


#: ASCII whitespace (what ``str.strip`` strips among the ASCII characters).
_BLANK = np.zeros(256, dtype=bool)
_BLANK[[9, 10, 11, 12, 13, 28, 29, 30, 31, 32]] = True


def _records(text: str, delimiter: str, file: str) -> tuple[list[str], bytes, NDArray[np.int64]]:
    """Header cells, the bytes pyarrow is to parse, and each data record's CSV line.

    Blank (or whitespace-only) lines are skipped; a record's line is the line on which
    it ends. Without quotes in the file every line is one record, and the text given to
    pyarrow holds the non-blank lines only (found by numpy, without a Python object per
    line); with quotes (cells may span lines) Python's csv module finds the records'
    lines and pyarrow gets the whole text.
    """
    _check_line_count(text, file)
    if '"' not in text:
        return _unquoted_records(text, delimiter, file)
    found = array("q")
    head: list[str] | None = None
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=delimiter, strict=True)
    try:
        for cells in reader:
            if not cells or (len(cells) == 1 and not cells[0].strip()):
                continue
            if head is None:
                _check_columns(len(cells), file)
                head = [c.strip() for c in cells]
                continue
            if len(cells) != len(head):
                raise DatasetError(
                    f"row has {len(cells):,} cells but the header has {len(head):,} "
                    f"(CSV line {reader.line_num})",
                    file=file,
                )
            found.append(reader.line_num)
    except csv.Error as exc:
        reason = " ".join(str(exc).split())[:160]
        raise DatasetError(
            f"not a valid CSV file ({reason}; CSV line {reader.line_num})", file=file
        ) from None
    if head is None:
        raise DatasetError("empty file (no header line)", file=file)
    lines = np.frombuffer(found, dtype=np.int64) if found else np.zeros(0, dtype=np.int64)
    if not len(lines):
        raise DatasetError("no data rows (an empty episode)", file=file)
    return head, text.encode("utf-8"), lines.copy()


#: Bytes of a log scanned at a time (each scan makes a few arrays of 8 bytes per byte).
_SCAN_CHUNK: Final[int] = 4 * _MIB


def _per_line(
    raw: NDArray[np.uint8],
    starts: NDArray[np.int64],
    mark: Callable[[NDArray[np.uint8]], NDArray[np.bool_]],
) -> NDArray[np.int64]:
    """How many bytes ``mark`` marks on each line (starting at ``starts``), chunk by chunk.

    Each line's segment runs to the next line's start, so it holds its line break and is
    never empty (``reduceat`` would misread an empty one).
    """
    out = np.empty(len(starts), dtype=np.int64)
    i = 0
    while i < len(starts):
        j = max(int(np.searchsorted(starts, starts[i] + _SCAN_CHUNK, side="left")), i + 1)
        a = int(starts[i])
        b = int(starts[j]) if j < len(starts) else len(raw)
        out[i:j] = np.add.reduceat(mark(raw[a:b]), starts[i:j] - a, dtype=np.int64)
        i = j
    return out


def _unquoted_records(
    text: str, delimiter: str, file: str
) -> tuple[list[str], bytes, NDArray[np.int64]]:
    """:func:`_records` for a file without quotes: one record per line."""
    data = text.encode("utf-8")
    if b"\r" in data:  # one line break each, so the line numbers stay
        data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    if not data.endswith(b"\n"):
        data += b"\n"
    raw = np.frombuffer(data, dtype=np.uint8)
    ends = np.flatnonzero(raw == ord("\n"))
    starts = np.r_[0, ends[:-1] + 1].astype(np.int64)
    filled = _per_line(raw, starts, lambda chunk: ~_BLANK[chunk]) > 0
    numbered = np.flatnonzero(filled)
    if not len(numbered):
        raise DatasetError("empty file (no header line)", file=file)
    first = int(numbered[0])
    header_text = data[starts[first] : ends[first]].decode("utf-8")
    n = header_text.count(delimiter) + 1
    _check_columns(n, file)
    header = [c.strip() for c in header_text.split(delimiter)]
    code = ord(delimiter)
    cells = _per_line(raw, starts, lambda chunk: chunk == code)[numbered] + 1
    ragged = np.flatnonzero(cells[1:] != n)
    if len(ragged):
        i = int(ragged[0]) + 1
        raise DatasetError(
            f"row has {int(cells[i]):,} cells but the header has {n:,} "
            f"(CSV line {int(numbered[i]) + 1})",
            file=file,
        )
    lines = (numbered[1:] + 1).astype(np.int64)
    if not len(lines):
        raise DatasetError("no data rows (an empty episode)", file=file)
    if len(numbered) == len(starts):
        return header, data, lines
    keep = np.repeat(filled, np.diff(np.r_[starts, len(raw)]))
    return header, raw[keep].tobytes(), lines


def _parse_table(body: bytes, n_cols: int, delimiter: str, quoted: bool, file: str) -> pa.Table:
    """All cells as strings (header included as row 0), by pyarrow."""
    names = [f"f{j}" for j in range(n_cols)]

    def invalid(row: Any) -> str:
        if not str(row.text).strip():
            return "skip"  # a whitespace-only line
        return "error"

    try:
        return pa_csv.read_csv(
            io.BytesIO(body),
            read_options=pa_csv.ReadOptions(column_names=names, block_size=1 << 24),
            parse_options=pa_csv.ParseOptions(
                delimiter=delimiter,
                newlines_in_values=quoted,
                quote_char='"' if quoted else False,
                invalid_row_handler=invalid,
            ),
            convert_options=pa_csv.ConvertOptions(
                column_types=dict.fromkeys(names, pa.string()),
                strings_can_be_null=False,
                quoted_strings_can_be_null=False,
            ),
        )
    except (pa.ArrowInvalid, pa.ArrowTypeError) as exc:
        text = " ".join(str(exc).split())[:160]
        raise DatasetError(f"not a valid CSV file ({text})", file=file) from None


def _resolve_header(
    header: list[str],
    mapping: Mapping[str, str],
    drop: Collection[str],
    derive: Collection[str],
    file: str,
    extra: Sequence[str] = (),
    commands: Sequence[str] = COMMAND_CHANNELS,
) -> dict[str, int]:
    """Our column name -> index of the CSV column that holds it.

    Every unexpected column is named in one line; so is every missing one. ``extra``
    are the declared channels: ours too, and required; ``commands`` the command
    channels (default our wheels), which are required.
    """
    needed = [*(c for c in REQUIRED_COLUMNS if c not in COMMAND_CHANNELS), *commands]
    ours_all = (*needed, *OPTIONAL_COLUMNS, *extra)
    ours_listed = _names(ours_all, 4 * SHOWN_NAMES)
    for ours in mapping:
        if ours not in ours_all:
            raise ConfigError(
                f"mapping names unknown column '{_name(ours)}' (columns: {ours_listed})"
                f"{_suggest(ours, ours_all)}"
            )
    theirs_to_ours: dict[str, str] = {}
    for ours, theirs in mapping.items():
        if theirs in theirs_to_ours:
            raise ConfigError(
                f"mapping sends file column '{_name(theirs)}' to both "
                f"'{theirs_to_ours[theirs]}' and '{ours}'"
            )
        theirs_to_ours[theirs] = ours
    in_file = set(header)
    for ours, theirs in mapping.items():
        if theirs not in in_file:
            raise DatasetError(
                f"column '{_name(theirs)}' (mapped to '{ours}') is not in the file "
                f"(columns: {_names(header)}){_suggest(theirs, header)}",
                file=file,
                field=_name(theirs),
            )
    for name in drop:
        if name not in in_file:
            raise DatasetError(
                f"column to drop is not in the file{_suggest(name, header)}",
                file=file,
                field=_name(name),
            )
    index: dict[str, int] = {}
    unknown: list[str] = []
    for i, theirs in enumerate(header):
        if theirs in drop:
            continue
        ours = theirs_to_ours.get(theirs, theirs)
        if ours in index:
            raise DatasetError(
                f"two columns give '{_name(ours)}' (columns {index[ours] + 1} and {i + 1})",
                file=file,
                field=_name(ours),
            )
        index[ours] = i
        if ours not in ours_all:
            unknown.append(ours)
    for name in derive:
        if name in index:
            raise ConfigError(
                f"--derive {name}: the file has a '{name}' column already "
                f"(ignore it with --drop {_name(header[index[name]])} to derive it instead)"
            )
    if own_channels_only(index, extra):  # a robot of its own: none of our four sensors
        needed = [c for c in needed if c not in SENSOR_CHANNELS]
    required = [c for c in needed if c != "episode" and c not in derive]
    missing = [c for c in required if c not in index]
    missing_extra = [c for c in extra if c not in index]
    if len(unknown) == 1:
        name = unknown[0]
        hint = _suggest(name, missing + missing_extra or ours_all)
        expected = f" (expected columns: {ours_listed}; or {_DECLARE})"
        raise DatasetError(
            f"unexpected column{hint + f' (or {_DECLARE})' if hint else expected}",
            file=file,
            field=_name(name),
        )
    if unknown:
        described = []
        for name in unknown[:SHOWN_NAMES]:
            close = _suggest(name, missing + missing_extra or ours_all).removeprefix("; ")
            described.append(f"'{_name(name)}'" + (f" ({close})" if close else ""))
        if len(unknown) > SHOWN_NAMES:
            described.append(f"and {len(unknown) - SHOWN_NAMES:,} more")
        raise DatasetError(
            f"unexpected columns {', '.join(described)}: map them with --map OURS=THEIRS or "
            f"ignore them with --drop (expected columns: {ours_listed}; or {_DECLARE})",
            file=file,
        )
    derivable = [c for c in missing if c in DERIVABLE]
    hint = (
        f"; derive {', '.join(derivable)} from positions with --derive {','.join(derivable)}"
        if derivable
        else ""
    )
    if len(missing) == 1:
        raise DatasetError(
            f"missing column (a dataset needs: {', '.join(needed)}){hint}",
            file=file,
            field=missing[0],
        )
    if missing:
        raise DatasetError(
            f"missing columns {', '.join(repr(m) for m in missing)} "
            f"(a dataset needs: {', '.join(needed)}){hint}",
            file=file,
        )
    if missing_extra:
        name = missing_extra[0]
        raise DatasetError(
            f"missing column of a declared channel (the file has no '{name}' column: map "
            f"one with --map {name}=THEIRS or do not declare it){_suggest(name, header)}",
            file=file,
            field=name,
        )
    return index


def _cell_error(
    message: str,
    i: int,
    field: str,
    file: str,
    lines: NDArray[np.int64],
    episode: NDArray[np.int64] | None,
    names: list[str] | None = None,
) -> DatasetError:
    """Error at data row ``i``: episode and row within it (if known) and CSV line."""
    message = f"{message} (CSV line {int(lines[i])})"
    if episode is None:
        return DatasetError(message, file=file, field=field)
    eid = int(episode[i])
    first = int(np.argmax(episode == eid))
    shown: int | str = _name(names[eid]) if names is not None else eid
    return DatasetError(message, file=file, episode=shown, row=i - first, field=field)


def _first_bad(cells: pa.Array, typ: pa.DataType) -> int:
    """Index of the first cell pyarrow cannot cast to ``typ`` (the column's cast failed).

    A bisection over prefixes of the column: about 21 casts for 2,000,000 cells, never
    one Python call per cell.
    """

    def fails(k: int) -> bool:  # does the cast of the first k cells fail?
        try:
            pc.cast(cells.slice(0, k), typ)
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
            return True
        return False

    lo, hi = 0, len(cells)  # the first k cells cast for k = lo; they fail for k = hi
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if fails(mid):
            hi = mid
        else:
            lo = mid
    return hi - 1


def _floats(
    cells: pa.Array,
    name: str,
    file: str,
    lines: NDArray[np.int64],
    episode: NDArray[np.int64],
    names: list[str] | None,
) -> NDArray[np.float64]:
    try:
        out: NDArray[np.float64] = pc.cast(cells, pa.float64()).to_numpy(zero_copy_only=False)
        return out
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        i = _first_bad(cells, pa.float64())
    cell = cells[i].as_py()
    what = "missing value" if not cell else f"wrong type: {_shown(cell)} is not a number"
    raise _cell_error(what, i, name, file, lines, episode, names)


def _episode_ids(
    cells: pa.Array, file: str, lines: NDArray[np.int64]
) -> tuple[NDArray[np.int64], list[str] | None]:
    """Integer ids (as given), or names mapped to 0, 1, ... in order of appearance.

    Ids are either all integers (``3`` or ``3.0``) or all names (``run-a``); a mix
    is refused at its first non-integer cell.
    """
    empty = pc.equal(pc.utf8_length(cells), 0).to_numpy(zero_copy_only=False)
    if empty.any():
        raise _cell_error("missing value", int(np.argmax(empty)), "episode", file, lines, None)
    try:
        ids: NDArray[np.int64] = pc.cast(cells, pa.int64()).to_numpy(zero_copy_only=False)
        return ids, None
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        pass
    numeric = pc.match_substring_regex(cells, _NUMBER_RE).to_numpy(zero_copy_only=False)
    if numeric.all():
        try:
            values = pc.cast(cells, pa.float64()).to_numpy(zero_copy_only=False)
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
            values = np.full(len(cells), np.nan)
        ok = np.isfinite(values) & (np.abs(values) < 2.0**63)
        ok[ok] = values[ok] == np.round(values[ok])
        if ok.all():
            return values.astype(np.int64), None
        i = int(np.argmax(~ok))
        cell = cells[i].as_py()
        raise _cell_error(
            f"wrong type: episode id {_shown(cell)} is not an integer",
            i,
            "episode",
            file,
            lines,
            None,
        )
    if numeric.any():
        i = int(np.argmax(~numeric))
        cell = cells[i].as_py()
        raise _cell_error(
            f"wrong type: episode id {_shown(cell)} is not an integer (the other ids are "
            "numbers; ids are either all integers or all names)",
            i,
            "episode",
            file,
            lines,
            None,
        )
    long = pc.greater(pc.utf8_length(cells), MAX_ID_CHARS).to_numpy(zero_copy_only=False)
    if long.any():
        i = int(np.argmax(long))
        raise _cell_error(
            f"episode id {_shown(cells[i].as_py())} is longer than {MAX_ID_CHARS} characters",
            i,
            "episode",
            file,
            lines,
            None,
        )
    encoded = pc.dictionary_encode(cells)
    codes = encoded.indices.to_numpy(zero_copy_only=False).astype(np.int64)
    return codes, [str(v) for v in encoded.dictionary.to_pylist()]


def _behavior_names(
    cells: pa.Array,
    file: str,
    lines: NDArray[np.int64],
    episode: NDArray[np.int64],
    names: list[str] | None,
) -> NDArray[Any]:
    """The ``behavior`` cells, each a valid behavior name (checked before any is echoed)."""
    ok = pc.match_substring_regex(cells, BEHAVIOR_NAME_PATTERN).to_numpy(zero_copy_only=False)
    if not ok.all():
        i = int(np.argmax(~ok))
        raise _cell_error(
            f"invalid behavior name {_shown(cells[i].as_py())} (expected a lowercase "
            f"identifier like 'turn', matching {BEHAVIOR_NAME_PATTERN})",
            i,
            "behavior",
            file,
            lines,
            episode,
            names,
        )
    return np.array(cells.to_pylist(), dtype=object)


def _columns(
    table: pa.Table,
    index: Mapping[str, int],
    lines: NDArray[np.int64],
    *,
    file: str,
    split_on_time_reset: bool,
    wanted: Sequence[str],
    factors: Mapping[str, float],
) -> tuple[dict[str, NDArray[Any]], list[str] | None]:
    """The columns (episode ids, ``wanted`` floats in canonical units, behavior names) of
    the cells pyarrow parsed, each cell typed and checked; the episodes' names if given.
    """
    if table.num_rows != len(lines) + 1:
        raise DatasetError(
            f"not a valid CSV file (found {table.num_rows - 1:,} data rows, expected "
            f"{len(lines):,})",
            file=file,
        )
    table = table.slice(1)  # row 0 is the header

    def cells(name: str) -> pa.Array:
        column = table.column(index[name]).combine_chunks()
        return pc.utf8_trim_whitespace(column)

    # Episode ids come first, so that later errors can name episode and row.
    names: list[str] | None = None
    n = len(lines)
    if "episode" in index:
        episode, names = _episode_ids(cells("episode"), file, lines)
    elif split_on_time_reset:
        t = _floats(cells("t"), "t", file, lines, np.zeros(n, dtype=np.int64), None)
        episode = np.r_[0, np.cumsum(t[1:] < t[:-1])].astype(np.int64)
    else:
        episode = np.zeros(n, dtype=np.int64)
    columns: dict[str, NDArray[Any]] = {"episode": episode}
    for name in wanted:
        values = _floats(cells(name), name, file, lines, episode, names)
        columns[name] = values * factors[name] if name in factors else values
    if "behavior" in index:
        columns["behavior"] = _behavior_names(cells("behavior"), file, lines, episode, names)
    return columns, names


def import_csv(
    path: str | os.PathLike[str],
    *,
    mapping: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    drop: Collection[str] = (),
    metadata: Mapping[str, Any] | None = None,
    split_on_time_reset: bool = False,
    delimiter: str = ",",
    derive: Collection[str] | str = (),
    resample: bool = False,
    period: float = CONTROL_PERIOD,
    channels: Sequence[ChannelSpec | Mapping[str, Any]] | None = None,
    commands: Sequence[ChannelSpec | Mapping[str, Any] | str] | None = None,
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
        File columns to ignore (any other column that is not ours is an error; all
        such columns are named in one message).
    metadata
        Dataset metadata; a ``source`` entry recording file, mapping and units is added
        (and, for episode ids that are names, ``episode_ids``: the names by integer id).
    split_on_time_reset
        Without an ``episode`` column the whole file is one episode (id 0) and
        time must increase. With this flag a new episode starts wherever time
        goes back (drops), so concatenated logs can be imported as they are.
    delimiter
        Cell separator.
    derive
        Velocity columns the file lacks, computed from positions by finite differences
        (``"linear_velocity"``, ``"angular_velocity"``; see ``data._transform`` for
        the sign conventions).
    resample
        Interpolate each episode linearly onto ``period`` (default the control period,
        16 ms). Without it a log whose median sample period differs from the control
        period by more than 2 % raises a :class:`SamplingWarning` (a warning).
    period
        The resampling period (s).
    channels
        A robot's own sensor channels the file holds besides ours (e.g. eight infrared
        proximity readings): :class:`ChannelSpec` objects or declarations ``{"name":
        "ir0", "unit": "m", "range": [0, 0.1]}``. Their columns are imported in the
        declared units (no conversion), checked like ours (finite, within the spec's
        ``bounds``), and declared in ``metadata["channels"]`` (after any the given
        ``metadata`` declares already).
    commands
        The robot's command channels in action order, replacing our two wheels:
        declarations ``{"name": "gripper", "unit": "m", "range": [0, 0.03], "rest":
        0.0}`` or names of known ones (``"left"``, ``"right"``); e.g. the wheels and a
        gripper. Declared in ``metadata["commands"]``; a declared channel's column is
        imported in its declared unit.

    Episode ids may be integers or names (``run-a``); names become ids 0, 1, ... in
    order of appearance and are kept in ``metadata["source"]["episode_ids"]``.

    Raises
    ------
    DatasetError
        For anything wrong with the file (naming file, episode, row, field, line).
    ConfigError
        For an unknown column name in ``mapping`` or ``units``, an unknown unit, or a
        malformed channel declaration.
    """
    file = str(path)
    p = Path(path)
    mapping = _string_pairs(mapping, "mapping")
    units = _string_pairs(units, "units")
    drop = _string_list(drop, "drop")
    derived = parse_derive(derive)
    md = dict(metadata or {})
    extras = _extra_channels(md, channels, file)
    extra_names = [spec.name for spec in extras]
    if commands is not None:
        md["commands"] = [
            spec.to_metadata() for spec in declared_commands({"commands": list(commands)})
        ]
    command_specs = declared_commands(md, file=file)
    command_names = [spec.name for spec in command_specs]
    own_commands = [spec for spec in command_specs if spec.name not in COMMAND_CHANNELS]
    for name, unit in units.items():
        if len(name) > SHOWN_CHARS or len(unit) > SHOWN_CHARS:
            raise ConfigError(f"unit {_shown(unit)} for column {_shown(name)}: no such unit")
    factors = {
        name: _extra_unit(spec, unit)
        if (spec := _find([*extras, *own_commands], name))
        else unit_factor(name, unit)
        for name, unit in units.items()
    }
    check_units_of_derived(units, derived)
    delimiter = check_delimiter(delimiter)
    if resample:
        _check_period(period)
    if p.is_dir():  # (a FIFO, a device or a socket: refused by read_text, never opened)
        raise DatasetError("is a directory, not a CSV file", file=file)
    text = read_text(p, limit=MAX_CSV_BYTES, file=file)
    header, body, lines = _records(text, delimiter, file)
    if len(lines) * len(header) > MAX_CSV_CELLS:
        raise DatasetError(
            f"{len(lines):,} rows of {len(header):,} columns make {len(lines) * len(header):,} "
            f"cells (limit {MAX_CSV_CELLS:,}); split the log into smaller files",
            file=file,
        )
    index = _resolve_header(
        header, mapping, set(drop), derived, file, extra_names, commands=command_names
    )
    own_only = own_channels_only(index, extra_names)  # none of our four sensors
    quoted = '"' in text
    del text  # pyarrow parses ``body``
    columns, names = _columns(
        _parse_table(body, len(header), delimiter, quoted, file),
        index,
        lines,
        file=file,
        split_on_time_reset=split_on_time_reset,
        wanted=[
            name
            for name in (*FLOAT_COLUMNS, *extra_names, *command_names)
            if name not in derived
            and (name not in COMMAND_CHANNELS or name in command_names)
            and not (own_only and name in SENSOR_CHANNELS)
        ],
        factors=factors,
    )
    del body  # the cells are columns now: free them before finish copies those
    episode = columns["episode"]

    if "angle" in columns:  # a robot of its own may have no bearing
        angle = columns["angle"]
        columns["angle"], absurd = wrap_imported_angles(angle)
        if absurd is not None:
            i = absurd
            raise _cell_error(
                f"absurd angle {angle[i]:g} deg (beyond ±{MAX_UNWRAPPED_ANGLE:g} deg; "
                "wrong units?)",
                i,
                "angle",
                file,
                lines,
                episode,
                names,
            )

    source: dict[str, Any] = {"format": "csv", "file": p.name, "mapping": mapping, "units": units}
    if names is not None:
        source["episode_ids"] = names
    md.setdefault("source", source)
    if extras:
        md["channels"] = [spec.to_metadata() for spec in extras]
    if resample:
        # validate the log's own rows first, then bound the grid before it is made
        raw = dict(columns)
        for name in derived:
            raw[name] = np.zeros(len(raw["episode"]))  # placeholder, as finish does
        try:
            checked, _ = check_table(raw, md, file=file, lines=lines)
        except DatasetError as err:
            raise _rename_episode(err, names) from None
        del raw
        check_resampling(
            checked["episode"],
            checked["t"],
            period,
            columns=len(checked),
            file=file,
            lines=lines,
            names=names,
        )
        if extras:
            return _finish_resampling_extras(
                checked, columns, md, extras, file, lines, derived, period, names
            )
        del checked
    cols, md = finish(
        columns,
        md,
        file=file,
        lines=lines,
        derive=derived,
        resample_to=period if resample else None,
        episode_names=names,
    )
    return Dataset._trusted(cols, md)


def _find(specs: Sequence[ChannelSpec], name: str) -> ChannelSpec | None:
    return next((spec for spec in specs if spec.name == name), None)


def _extra_channels(
    md: dict[str, Any],
    channels: Sequence[ChannelSpec | Mapping[str, Any]] | None,
    file: str,
) -> tuple[ChannelSpec, ...]:
    """The metadata's declared channels followed by ``channels`` (checked, no repeats)."""
    given: list[ChannelSpec] = []
    for item in channels or ():
        try:
            spec = item if isinstance(item, ChannelSpec) else channel_from_metadata(item)
        except ConfigError:
            raise
        except (TypeError, ValueError) as exc:  # e.g. a range that is not numbers
            reason = " ".join(str(exc).split())[: 2 * SHOWN_CHARS]
            raise ConfigError(f"channel declaration {_shown(repr(item))}: {reason}") from None
        given.append(spec)
    try:
        declared_channels({"channels": given})
    except DatasetError as err:
        raise ConfigError(f"channel declaration: {err.reason}") from None
    already = declared_channels(md, file=file)
    return declared_channels({"channels": [*already, *given]}, file=file)


def _extra_unit(spec: ChannelSpec, unit: str) -> float:
    """A declared channel takes no unit conversion: only its declared unit is accepted."""
    if unit != spec.unit:
        raise ConfigError(
            f"unit '{unit}' for column '{spec.name}': a declared channel is imported in its "
            f"declared unit ({spec.unit}) without conversion; declare it in {unit} instead"
        )
    return 1.0


def _finish_resampling_extras(
    checked: dict[str, NDArray[Any]],
    columns: dict[str, NDArray[Any]],
    md: dict[str, Any],
    extras: Sequence[ChannelSpec],
    file: str,
    lines: NDArray[np.int64],
    derived: Collection[str],
    period: float,
    names: list[str] | None,
) -> Dataset:
    """``finish`` with resampling, for a log with declared channels.

    ``finish`` resamples the channels of the data contract only; so the whole log is
    validated on its own rows first (``checked``, by the caller), ``finish`` derives and
    resamples the contract's channels, and each declared channel is resampled onto the
    same time stamps by the same interpolation (carried through ``resample`` as ``left``,
    or as ``angle`` for a wrapping one).
    """
    extra_names = {spec.name for spec in extras}
    standard = {name: values for name, values in columns.items() if name not in extra_names}
    cols, md = finish(
        standard,
        {key: value for key, value in md.items() if key != "channels"},
        file=file,
        lines=lines,
        derive=derived,
        resample_to=period,
        episode_names=names,
    )
    for spec in extras:
        carrier = "angle" if spec.wraps else "left"
        grid = {"episode": checked["episode"], "t": checked["t"], carrier: checked[spec.name]}
        cols[spec.name] = resample_columns(grid, period)[carrier]
    md["channels"] = [spec.to_metadata() for spec in extras]
    try:
        cols, md = check_table(cols, md, file=file)
    except DatasetError as err:
        raise _rename_episode(err, names, " (after resampling)") from None
    return Dataset._trusted(cols, md)


def _string_pairs(value: Mapping[str, str] | None, what: str) -> dict[str, str]:
    """``value`` as a dict of strings to strings (the API's arguments typed)."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ConfigError(f"{what} must map names to names, got {type(value).__name__}")
    out: dict[str, str] = {}
    for key, item in value.items():
        if not isinstance(key, str) or not isinstance(item, str):
            raise ConfigError(
                f"{what} must map names to names (strings), got {_shown(repr(key))}: "
                f"{_shown(repr(item))}"
            )
        out[key] = item
    return out


def _string_list(value: Collection[str], what: str) -> list[str]:
    """``value`` as a list of strings (the API's arguments typed)."""
    if isinstance(value, str):
        return [value]
    items = list(value)
    for item in items:
        if not isinstance(item, str):
            raise ConfigError(f"{what} must be column names (strings), got {_shown(repr(item))}")
    return items


def _check_period(period: object) -> float:
    """The resampling period: a finite number of seconds > 0."""
    ok = isinstance(period, int | float) and not isinstance(period, bool)
    if not ok or not math.isfinite(float(period)) or float(period) <= 0.0:  # type: ignore[arg-type]
        raise ConfigError(
            f"resampling period must be a finite number of seconds > 0, got {_shown(repr(period))}"
        )
    return float(period)  # type: ignore[arg-type]


def _count(n: float) -> str:
    """A number of rows for a message: ``625,000,001``, or ``1.2e+20`` past 10**15."""
    return f"{int(n):,}" if n < 1e15 else f"{n:.3g}"


def check_resampling(
    episode: NDArray[np.int64],
    t: NDArray[np.float64],
    period: float,
    *,
    columns: int = len(REQUIRED_COLUMNS),
    file: str,
    lines: NDArray[np.int64] | None = None,
    names: Sequence[str] | None = None,
) -> int:
    """Rows resampling onto ``period`` would make, refused before a grid is allocated.

    Each episode (a run of rows with one id, time strictly increasing: validated) gets
    ``floor((t_last - t_first) / period) + 1`` rows, as :func:`resample` makes them. An
    episode may get at most :data:`MAX_RESAMPLE_FACTOR` times its own rows, the log at
    most :data:`MAX_RESAMPLED_ROWS` in all and :data:`MAX_CSV_CELLS` cells (rows times
    ``columns``); past either the error names the episode and its largest gap between two
    rows.
    """
    most = min(MAX_RESAMPLED_ROWS, MAX_CSV_CELLS // max(columns, 1))
    period = _check_period(period)
    n = len(episode)
    if n == 0:
        return 0
    starts = np.flatnonzero(np.r_[True, episode[1:] != episode[:-1]])
    ends = np.r_[starts[1:], n]
    span = t[ends - 1] - t[starts]
    with np.errstate(over="ignore", invalid="ignore"):
        made = np.floor(span / period + 1e-6) + 1.0
    made = np.where(np.isfinite(made), made, np.inf)
    own = (ends - starts).astype(np.float64)
    limit = own * MAX_RESAMPLE_FACTOR
    over = np.flatnonzero(made > limit)
    total = float(made.sum())
    if len(over):
        k = int(over[0])
        reason = (
            f"would make {_count(made[k])} rows (limit {_count(limit[k])}: "
            f"{MAX_RESAMPLE_FACTOR:,} per row of its {int(own[k]):,})"
        )
    elif total > most:
        k = int(np.argmax(made))
        reason = (
            f"would make {_count(total)} rows in all (limit {most:,}: at most "
            f"{MAX_RESAMPLED_ROWS:,} rows and {MAX_CSV_CELLS:,} cells), {_count(made[k])} of "
            "them in this episode"
        )
    else:
        return int(total)
    a, b = int(starts[k]), int(ends[k])
    where = ""
    if b - a > 1:
        j = int(np.argmax(np.diff(t[a:b])))
        gap = float(t[a + j + 1] - t[a + j])
        where = f"; it has a gap of {gap:.3g} s between its rows {j} and {j + 1}"
        if lines is not None:
            where += f" (CSV lines {int(lines[a + j])} and {int(lines[a + j + 1])})"
    eid = int(episode[a])
    shown: int | str = _name(names[eid]) if names is not None and 0 <= eid < len(names) else eid
    raise DatasetError(
        f"resampling at {period * 1000:g} ms {reason}{where}",
        file=file,
        episode=shown,
        field="t",
    )
