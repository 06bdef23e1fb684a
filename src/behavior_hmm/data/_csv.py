"""Import users' CSV logs: column mapping, units, derived velocities, resampling.

The cells are parsed by pyarrow's CSV reader (``pyarrow.csv``); this module finds each
record's line in the file first, so that every error names the CSV line, and checks
what pyarrow does not: ragged rows, NUL bytes, the header, the episode ids.
"""

from __future__ import annotations

import csv
import io
import os
import re
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pa_csv
from numpy.typing import NDArray

from behavior_hmm.data._channels import CONTROL_PERIOD, ChannelSpec, channel_from_metadata
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
    FLOAT_COLUMNS,
    OPTIONAL_COLUMNS,
    REQUIRED_COLUMNS,
    check_table,
    declared_channels,
    suggest,
)
from behavior_hmm.errors import ConfigError, DatasetError

_OURS = (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS)

#: A number as pyarrow's float parser reads it (used only to find a bad cell quickly).
_NUMBER_RE = r"(?i)^[+-]?((\d+\.?\d*|\.\d+)(e[+-]?\d+)?|nan|inf|infinity)$"

_LINE_BREAK = re.compile(r"\r\n|\r|\n")

#: How to declare a column of the log as a robot's own sensor channel.
_DECLARE = "declare a robot's own sensor channel with --channel NAME:UNIT:LO:HI"


def _read_text(p: Path, file: str) -> str:
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise DatasetError(f"cannot read file ({exc.strerror or exc})", file=file) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DatasetError(f"not UTF-8 text (byte {exc.start})", file=file) from None
    text = text.removeprefix("\ufeff")
    nul = text.find("\x00")
    if nul >= 0:
        line = len(_LINE_BREAK.findall(text, 0, nul)) + 1
        raise DatasetError(f"not a valid CSV file (NUL byte on line {line})", file=file)
    return text


def _records(text: str, delimiter: str, file: str) -> tuple[list[str], str, NDArray[np.int64]]:
    """Header cells, the text pyarrow is to parse, and each data record's CSV line.

    Blank (or whitespace-only) lines are skipped; a record's line is the line on which
    it ends. Without quotes in the file every line is one record, and the text given to
    pyarrow holds the non-blank lines only; with quotes (cells may span lines) Python's
    csv module finds the records' lines and pyarrow gets the whole text.
    """
    quoted = '"' in text
    if not quoted:
        numbered = [(i + 1, line) for i, line in enumerate(_LINE_BREAK.split(text)) if line.strip()]
        if not numbered:
            raise DatasetError("empty file (no header line)", file=file)
        header = [c.strip() for c in numbered[0][1].split(delimiter)]
        n = len(header)
        for lineno, line in numbered[1:]:
            cells = line.count(delimiter) + 1
            if cells != n:
                raise DatasetError(
                    f"row has {cells} cells but the header has {n} (CSV line {lineno})",
                    file=file,
                )
        lines = np.array([i for i, _ in numbered[1:]], dtype=np.int64)
        body = "\n".join(line for _, line in numbered)
    else:
        found: list[int] = []
        head: list[str] | None = None
        reader = csv.reader(io.StringIO(text, newline=""), delimiter=delimiter, strict=True)
        try:
            for cells in reader:
                if not cells or (len(cells) == 1 and not cells[0].strip()):
                    continue
                if head is None:
                    head = [c.strip() for c in cells]
                    continue
                if len(cells) != len(head):
                    raise DatasetError(
                        f"row has {len(cells)} cells but the header has {len(head)} "
                        f"(CSV line {reader.line_num})",
                        file=file,
                    )
                found.append(reader.line_num)
        except csv.Error as exc:
            raise DatasetError(f"not a valid CSV file ({exc})", file=file) from None
        if head is None:
            raise DatasetError("empty file (no header line)", file=file)
        header = head
        lines = np.array(found, dtype=np.int64)
        body = text
    if not len(lines):
        raise DatasetError("no data rows (an empty episode)", file=file)
    return header, body, lines


def _parse_table(body: str, n_cols: int, delimiter: str, quoted: bool, file: str) -> pa.Table:
    """All cells as strings (header included as row 0), by pyarrow."""
    names = [f"f{j}" for j in range(n_cols)]

    def invalid(row: Any) -> str:
        if not str(row.text).strip():
            return "skip"  # a whitespace-only line
        return "error"

    try:
        return pa_csv.read_csv(
            io.BytesIO(body.encode("utf-8")),
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
) -> dict[str, int]:
    """Our column name -> index of the CSV column that holds it.

    Every unexpected column is named in one line; so is every missing one. ``extra``
    are the declared channels: ours too, and required.
    """
    ours_all = (*_OURS, *extra)
    for ours in mapping:
        if ours not in ours_all:
            raise ConfigError(
                f"mapping names unknown column '{ours}' (columns: {', '.join(ours_all)})"
                f"{suggest(ours, ours_all)}"
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
    unknown: list[str] = []
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
        if ours not in ours_all:
            unknown.append(ours)
    for name in derive:
        if name in index:
            raise ConfigError(
                f"--derive {name}: the file has a '{name}' column already "
                f"(ignore it with --drop {header[index[name]]} to derive it instead)"
            )
    required = [c for c in REQUIRED_COLUMNS if c != "episode" and c not in derive]
    missing = [c for c in required if c not in index]
    missing_extra = [c for c in extra if c not in index]
    if len(unknown) == 1:
        name = unknown[0]
        hint = suggest(name, missing + missing_extra or ours_all)
        expected = f" (expected columns: {', '.join(ours_all)}; or {_DECLARE})"
        raise DatasetError(
            f"unexpected column{hint + f' (or {_DECLARE})' if hint else expected}",
            file=file,
            field=name,
        )
    if unknown:
        described = []
        for name in unknown:
            close = suggest(name, missing + missing_extra or ours_all).removeprefix("; ")
            described.append(f"'{name}'" + (f" ({close})" if close else ""))
        raise DatasetError(
            f"unexpected columns {', '.join(described)}: map them with --map OURS=THEIRS or "
            f"ignore them with --drop (expected columns: {', '.join(ours_all)}; or {_DECLARE})",
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
            f"missing column (a dataset needs: {', '.join(REQUIRED_COLUMNS)}){hint}",
            file=file,
            field=missing[0],
        )
    if missing:
        raise DatasetError(
            f"missing columns {', '.join(repr(m) for m in missing)} "
            f"(a dataset needs: {', '.join(REQUIRED_COLUMNS)}){hint}",
            file=file,
        )
    if missing_extra:
        name = missing_extra[0]
        raise DatasetError(
            f"missing column of a declared channel (the file has no '{name}' column: map "
            f"one with --map {name}=THEIRS or do not declare it){suggest(name, header)}",
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
    shown: int | str = names[eid] if names is not None else eid
    return DatasetError(message, file=file, episode=shown, row=i - first, field=field)


def _first_bad(cells: pa.Array, typ: pa.DataType) -> int:
    """Index of the first cell pyarrow cannot cast to ``typ`` (the column's cast failed)."""
    looks_ok = pc.match_substring_regex(cells, _NUMBER_RE).to_numpy(zero_copy_only=False)
    candidates = np.flatnonzero(~looks_ok).tolist()
    candidates += np.flatnonzero(looks_ok).tolist()  # e.g. an overflowing integer
    for i in candidates:
        try:
            pc.cast(cells.slice(i, 1), typ)
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
            return int(i)
    raise AssertionError("no bad cell found")  # pragma: no cover


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
    what = "missing value" if not cell else f"wrong type: {cell[:40]!r} is not a number"
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
            f"wrong type: episode id {cell[:40]!r} is not an integer",
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
            f"wrong type: episode id {cell[:40]!r} is not an integer (the other ids are "
            "numbers; ids are either all integers or all names)",
            i,
            "episode",
            file,
            lines,
            None,
        )
    encoded = pc.dictionary_encode(cells)
    codes = encoded.indices.to_numpy(zero_copy_only=False).astype(np.int64)
    return codes, [str(v) for v in encoded.dictionary.to_pylist()]


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
    mapping = dict(mapping or {})
    units = dict(units or {})
    derived = parse_derive(derive)
    md = dict(metadata or {})
    extras = _extra_channels(md, channels, file)
    extra_names = [spec.name for spec in extras]
    factors = {
        name: _extra_unit(spec, unit) if (spec := _find(extras, name)) else unit_factor(name, unit)
        for name, unit in units.items()
    }
    check_units_of_derived(units, derived)
    if len(delimiter) != 1:
        raise ConfigError(f"delimiter must be one character, got {delimiter!r}")
    if not p.exists():
        raise DatasetError("no such file", file=file)
    if p.is_dir():
        raise DatasetError("is a directory, not a CSV file", file=file)
    text = _read_text(p, file)
    header, body, lines = _records(text, delimiter, file)
    index = _resolve_header(header, mapping, set(drop), derived, file, extra_names)
    table = _parse_table(body, len(header), delimiter, '"' in text, file)
    if table.num_rows != len(lines) + 1:
        raise DatasetError(
            f"not a valid CSV file (found {table.num_rows - 1} data rows, expected {len(lines)})",
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
    for name in (*FLOAT_COLUMNS, *extra_names):
        if name in derived:
            continue
        values = _floats(cells(name), name, file, lines, episode, names)
        columns[name] = values * factors[name] if name in factors else values
    if "behavior" in index:
        columns["behavior"] = np.array(cells("behavior").to_pylist(), dtype=object)

    angle = columns["angle"]
    columns["angle"], absurd = wrap_imported_angles(angle)
    if absurd is not None:
        i = absurd
        raise _cell_error(
            f"absurd angle {angle[i]:g} deg (beyond ±{MAX_UNWRAPPED_ANGLE:g} deg; wrong units?)",
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
            return _finish_resampling_extras(
                columns, md, extras, file, lines, derived, period, names
            )
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
            raise ConfigError(f"channel declaration {item!r}: {exc}") from None
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
    validated on its own rows first, ``finish`` derives and resamples the contract's
    channels, and each declared channel is resampled onto the same time stamps by the
    same interpolation (carried through ``resample`` as ``left``, or as ``angle`` for
    a wrapping one).
    """
    raw = dict(columns)
    for name in derived:
        raw[name] = np.zeros(len(raw["episode"]))  # placeholder, as finish does
    try:
        checked, _ = check_table(raw, md, file=file, lines=lines)
    except DatasetError as err:
        raise _rename_episode(err, names) from None
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
