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
from behavior_hmm.data._dataset import Dataset
from behavior_hmm.data._validate import check_column_names, check_table, declared_channels
from behavior_hmm.errors import DatasetError

#: Schema metadata key under which the dataset metadata (JSON) is stored.
METADATA_KEY: Final[bytes] = b"behavior_hmm"


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


def _metadata_from_schema(schema: pa.Schema, file: str) -> dict[str, Any]:
    raw = (schema.metadata or {}).get(METADATA_KEY)
    if raw is None:
        return {}
    try:
        md = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise DatasetError(
            f"metadata is not valid JSON ({_one_line(exc)})", file=file, field="metadata"
        ) from None
    if not isinstance(md, dict):
        raise DatasetError("metadata is not a JSON object", file=file, field="metadata")
    return md


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
    p = Path(path)
    if not p.exists():
        raise DatasetError("no such file", file=file)
    if p.is_dir():
        raise DatasetError("is a directory, not a Parquet file", file=file)
    try:
        with pq.ParquetFile(p, page_checksum_verification=True) as pf:
            table = pf.read()
    except Exception as exc:  # any failure to parse means "not a dataset"
        raise DatasetError(f"not a readable Parquet file ({_one_line(exc)})", file=file) from None
    metadata = _metadata_from_schema(table.schema, file)
    extra = [spec.name for spec in declared_channels(metadata, file=file)]
    check_column_names(table.column_names, file=file, extra=extra)

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
