"""The Parquet episode format (DESIGN §4): one row per sample, metadata as JSON.

Columns, in order: ``episode`` (int64), ``t`` (float64, s), the sensor channels
(float64, physical units) followed by the channels the metadata declares (float64, in
their declared units), ``left``, ``right`` (float64, rad/s) and, for complex
demonstrations, ``behavior`` (string). The dataset metadata is stored as JSON
under the schema metadata key ``behavior_hmm``; its ``channels`` entry declares the
extra sensor channels (name, unit, range).
"""

from __future__ import annotations

import json
import os
from collections.abc import Collection
from pathlib import Path
from typing import Any, Final

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from numpy.typing import NDArray

from behavior_hmm._atomic import atomic_write_with
from behavior_hmm._safe_read import MAX_SIDE_FILE_BYTES, check_regular, parse_json
from behavior_hmm.data._dataset import Dataset
from behavior_hmm.data._validate import (
    MAX_ROWS,
    canonical_metadata,
    check_column_names,
    check_table,
    declared_channels,
    declared_commands,
)
from behavior_hmm.errors import BehaviorHMMError, DatasetError

#: Schema metadata key under which the dataset metadata (JSON) is stored.
METADATA_KEY: Final[bytes] = b"behavior_hmm"

#: Most bytes a dataset file's columns may take once decompressed (the footer's
#: uncompressed sizes are checked before the table is read, the columns as they are).
MAX_UNCOMPRESSED_BYTES: Final[int] = 256 * 1024 * 1024

#: Most bytes of the dataset metadata (JSON) a file may carry.
MAX_METADATA_BYTES: Final[int] = MAX_SIDE_FILE_BYTES


def _one_line(exc: BaseException, limit: int = 160) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _to_table(ds: Dataset) -> pa.Table:
    cols = ds.to_columns()
    arrays: dict[str, pa.Array] = {}
    for name, values in cols.items():
        if name == "behavior":
            arrays[name] = pa.array(values.tolist(), type=pa.string())
        else:
            arrays[name] = pa.array(values)
    meta = json.dumps(ds.metadata, sort_keys=True).encode()
    return pa.table(arrays).replace_schema_metadata({METADATA_KEY: meta})


def write(ds: Dataset, path: str | os.PathLike[str]) -> Path:
    """Write ``ds`` to a Parquet file, crash-safely (temp file, fsync, rename).

    If anything fails, an existing file at ``path`` is left intact and no
    temporary file remains.

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    DatasetError
        If the file cannot be written (permissions, disk full, a directory there).
    """
    target = Path(path)
    table = _to_table(ds)
    try:
        atomic_write_with(
            target,
            lambda tmp: pq.write_table(table, tmp, compression="zstd", write_page_checksum=True),
        )
    except OSError as exc:
        raise DatasetError(f"cannot write dataset: {_one_line(exc)}", file=str(path)) from None
    return target


def _metadata_error(reason: str, file: str) -> BehaviorHMMError:
    return DatasetError(f"metadata is {reason}", file=file, field="metadata")


def _metadata_from_schema(schema: pa.Schema, file: str) -> dict[str, Any]:
    raw = (schema.metadata or {}).get(METADATA_KEY)
    if raw is None:
        return {}
    if len(raw) > MAX_METADATA_BYTES:
        raise _metadata_error(
            f"{len(raw):,} bytes, more than MAX_METADATA_BYTES ({MAX_METADATA_BYTES:,})", file
        )
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise _metadata_error(f"not valid JSON (not UTF-8 text: byte {exc.start})", file) from None
    md = parse_json(text, file=file, error=_metadata_error)
    if not isinstance(md, dict):
        raise DatasetError("metadata is not a JSON object", file=file, field="metadata")
    return md


def _check_footer(pf: pq.ParquetFile, file: str) -> None:
    """Refuse, from the footer alone, a file whose table would be too large to read."""
    meta = pf.metadata
    rows = int(meta.num_rows)
    if rows > MAX_ROWS:
        raise DatasetError(
            f"{rows:,} rows, more than MAX_ROWS ({MAX_ROWS:,}); split the dataset", file=file
        )
    size = 0
    for i in range(meta.num_row_groups):
        group = meta.row_group(i)
        columns = sum(
            max(int(group.column(j).total_uncompressed_size), 0) for j in range(group.num_columns)
        )
        size += max(int(group.total_byte_size), columns)
        if size > MAX_UNCOMPRESSED_BYTES:
            raise DatasetError(
                f"its columns take more than MAX_UNCOMPRESSED_BYTES "
                f"({MAX_UNCOMPRESSED_BYTES // (1024 * 1024)} MiB) once decompressed "
                f"(row group {i}); split the dataset",
                file=file,
            )


def _read_table(pf: pq.ParquetFile, file: str) -> pa.Table:
    """The table, one row group at a time, within ``MAX_ROWS`` and ``MAX_UNCOMPRESSED_BYTES``."""
    parts = []
    rows = 0
    size = 0
    for i in range(pf.num_row_groups):
        part = pf.read_row_group(i)
        rows += part.num_rows
        size += part.nbytes
        if rows > MAX_ROWS or size > MAX_UNCOMPRESSED_BYTES:
            raise DatasetError(
                f"row group {i} decompresses past MAX_ROWS ({MAX_ROWS:,} rows) or "
                f"MAX_UNCOMPRESSED_BYTES ({MAX_UNCOMPRESSED_BYTES // (1024 * 1024)} MiB), "
                "more than its footer states",
                file=file,
            )
        parts.append(part)
    if rows != pf.metadata.num_rows:
        raise DatasetError(
            f"the footer states {pf.metadata.num_rows:,} rows but the row groups hold {rows:,}",
            file=file,
        )
    if not parts:
        return pf.schema_arrow.empty_table()
    return pa.concat_tables(parts)


def _column_to_numpy(table: pa.Table, name: str, file: str) -> NDArray[Any]:
    col = table.column(name)
    typ = col.type
    if pa.types.is_dictionary(typ) and pa.types.is_string(typ.value_type):
        col = col.cast(typ.value_type)
        typ = col.type
    if name == "behavior":
        if not (pa.types.is_string(typ) or pa.types.is_large_string(typ)):
            raise DatasetError(
                f"wrong type {typ} (behavior names are strings)", file=file, field=name
            )
        return np.array(col.to_pylist(), dtype=object)
    if name == "episode":
        if not pa.types.is_integer(typ):
            raise DatasetError(
                f"wrong type {typ} (episode ids are integers)", file=file, field=name
            )
    elif not (pa.types.is_integer(typ) or pa.types.is_floating(typ)):
        raise DatasetError(f"wrong type {typ} (expected numbers)", file=file, field=name)
    return col.to_numpy()


def _first_null(table: pa.Table, name: str) -> int | None:
    col = table.column(name)
    if col.null_count == 0:
        return None
    mask = col.is_null().to_numpy(zero_copy_only=False)
    return int(np.argmax(mask))


def read(path: str | os.PathLike[str], *, behaviors: Collection[str] | None = None) -> Dataset:
    """Read and fully validate a Parquet dataset.

    Parameters
    ----------
    path
        File written by :func:`write` (or any Parquet file with the same columns).
    behaviors
        If given, the only sub-behavior names allowed in the ``behavior`` column
        (which must then exist).

    Raises
    ------
    DatasetError
        For anything wrong with the file, naming file, episode, row and field.
    """
    file = str(path)
    if Path(path).is_dir():
        raise DatasetError("is a directory, not a Parquet file", file=file)
    # a FIFO, a device or a socket is refused before pyarrow opens it (never waited on)
    p = check_regular(path, file=file)
    try:
        with pq.ParquetFile(p, page_checksum_verification=True) as pf:
            _check_footer(pf, file)
            # the metadata is validated like user input before the table is read
            metadata = _metadata_from_schema(pf.schema_arrow, file)
            canonical_metadata(metadata, file=file)
            extra = [spec.name for spec in declared_channels(metadata, file=file)]
            commands = [spec.name for spec in declared_commands(metadata, file=file)]
            check_column_names(pf.schema_arrow.names, file=file, extra=extra, commands=commands)
            table = _read_table(pf, file)
    except BehaviorHMMError:
        raise
    except Exception as exc:  # any failure to parse means "not a dataset"
        raise DatasetError(f"not a readable Parquet file ({_one_line(exc)})", file=file) from None

    # Nulls: locate them by episode and row where the episode column allows it.
    null_at = _first_null(table, "episode")
    if null_at is not None:
        raise DatasetError(
            f"missing value (null) at file row {null_at}", file=file, field="episode"
        )
    columns = {name: _column_to_numpy(table, name, file) for name in table.column_names}
    for name in table.column_names:
        null_at = _first_null(table, name)
        if null_at is not None:
            episode = columns["episode"]
            eid = episode[null_at]
            row = int(null_at - np.argmax(episode == eid))
            raise DatasetError(
                "missing value (null)", file=file, episode=int(eid), row=row, field=name
            )
    cols, md = check_table(columns, metadata, file=file, behaviors=behaviors)
    return Dataset._trusted(cols, md)
