"""Parquet episode files: round trip, crash-safe writes, and every kind of bad file."""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import behavior_hmm.data._parquet as parquet_mod
from behavior_hmm.data import METADATA_KEY, REQUIRED_COLUMNS, Dataset, read, write
from behavior_hmm.errors import DatasetError


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


def test_round_trip_is_identical(tmp_path: Path, small_ds: Dataset) -> None:
    path = write(small_ds, tmp_path / "turn.parquet")
    back = read(path)
    assert back == small_ds
    assert back.metadata == small_ds.metadata
    assert back.t.dtype == np.float64 and back.episode_ids.dtype == np.int64
    assert _leftovers(tmp_path) == []


def test_round_trip_with_behavior_column(tmp_path: Path, complex_ds: Dataset) -> None:
    back = read(write(complex_ds, tmp_path / "ta.parquet"), behaviors=["turn", "approach"])
    assert back == complex_ds
    assert back.episode(0).behavior.tolist() == complex_ds.episode(0).behavior.tolist()


def test_file_layout(tmp_path: Path, complex_ds: Dataset) -> None:
    path = write(complex_ds, tmp_path / "ta.parquet")
    table = pq.read_table(path)
    assert table.column_names == [*REQUIRED_COLUMNS, "behavior"]
    assert table.schema.field("episode").type == pa.int64()
    assert table.schema.field("angle").type == pa.float64()
    assert table.schema.field("behavior").type == pa.string()
    md = json.loads(table.schema.metadata[METADATA_KEY])
    assert md["schema_version"] == 1 and md["seed"] == 7


def test_write_replaces_old_file(tmp_path: Path, small_ds: Dataset) -> None:
    path = tmp_path / "d.parquet"
    write(small_ds, path)
    write(small_ds.subset([0]), path)
    assert len(read(path)) == 1


def test_crash_halfway_keeps_old_file(
    tmp_path: Path, small_ds: Dataset, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "d.parquet"
    write(small_ds, path)
    before = path.read_bytes()

    def half_then_fail(table: pa.Table, where: Any, **kw: Any) -> None:
        with pq.ParquetWriter(where, table.schema) as w:
            w.write_table(table.slice(0, 10))
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(parquet_mod.pq, "write_table", half_then_fail)
    with pytest.raises(DatasetError, match="No space left") as info:
        write(small_ds.subset([1]), path)
    assert info.value.file == str(path)
    assert path.read_bytes() == before
    assert _leftovers(tmp_path) == []


def test_crash_on_unexpected_error_keeps_old_file(
    tmp_path: Path, small_ds: Dataset, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "d.parquet"
    write(small_ds, path)
    before = path.read_bytes()

    def fail(table: pa.Table, where: Any, **kw: Any) -> None:
        Path(where).write_bytes(b"PAR1 partial")
        raise KeyboardInterrupt

    monkeypatch.setattr(parquet_mod.pq, "write_table", fail)
    with pytest.raises(KeyboardInterrupt):
        write(small_ds, path)
    assert path.read_bytes() == before
    assert _leftovers(tmp_path) == []


def test_write_onto_a_directory_is_a_dataset_error(tmp_path: Path, small_ds: Dataset) -> None:
    (tmp_path / "d.parquet").mkdir()
    with pytest.raises(DatasetError, match="cannot write"):
        write(small_ds, tmp_path / "d.parquet")
    assert _leftovers(tmp_path) == []


# --- bad files --------------------------------------------------------------------------


def _columns(ds: Dataset) -> dict[str, Any]:
    return dict(ds.to_columns())


def _write_raw(
    path: Path, cols: dict[str, Any], metadata: dict[str, Any] | bytes | None = None
) -> Path:
    """Write a Parquet file directly with pyarrow, bypassing our writer's checks."""
    arrays = {k: v if isinstance(v, pa.Array) else pa.array(v) for k, v in cols.items()}
    table = pa.table(arrays)
    if metadata is not None:
        raw = metadata if isinstance(metadata, bytes) else json.dumps(metadata).encode()
        table = table.replace_schema_metadata({METADATA_KEY: raw})
    pq.write_table(table, path)
    return path


def _expect(path: Path, match: str, **where: Any) -> DatasetError:
    with pytest.raises(DatasetError, match=match) as info:
        read(path)
    err = info.value
    assert err.file == str(path)
    for key, value in where.items():
        assert getattr(err, key) == value, (key, str(err))
    assert "\n" not in str(err)
    return err


def test_missing_column(tmp_path: Path, small_ds: Dataset) -> None:
    cols = _columns(small_ds)
    del cols["angular_velocity"]
    _expect(_write_raw(tmp_path / "f.parquet", cols), "missing column", field="angular_velocity")


def test_extra_column(tmp_path: Path, small_ds: Dataset) -> None:
    cols = _columns(small_ds)
    cols["battery"] = np.ones(small_ds.n_samples)
    _expect(_write_raw(tmp_path / "f.parquet", cols), "unexpected column", field="battery")


def test_misnamed_column_suggests_the_right_name(tmp_path: Path, small_ds: Dataset) -> None:
    cols = _columns(small_ds)
    cols["angel"] = cols.pop("angle")
    err = _expect(_write_raw(tmp_path / "f.parquet", cols), "unexpected column", field="angel")
    assert "did you mean 'angle'" in str(err)


def test_duplicate_column(tmp_path: Path, small_ds: Dataset) -> None:
    cols = _columns(small_ds)
    names = [*cols, "t"]
    table = pa.Table.from_arrays(
        [pa.array(v) for v in cols.values()] + [pa.array(cols["t"])], names=names
    )
    pq.write_table(table, tmp_path / "f.parquet")
    _expect(tmp_path / "f.parquet", "twice", field="t")


@pytest.mark.parametrize(
    ("column", "values", "match"),
    [
        ("angle", lambda n: pa.array(["x"] * n), "wrong type string"),
        ("left", lambda n: pa.array([True] * n), "wrong type bool"),
        ("episode", lambda n: pa.array(np.zeros(n)), "wrong type double"),
        ("behavior", lambda n: pa.array(np.zeros(n)), "wrong type double"),
    ],
)
def test_wrong_type(
    tmp_path: Path, small_ds: Dataset, column: str, values: Callable[[int], pa.Array], match: str
) -> None:
    cols = _columns(small_ds)
    cols[column] = values(small_ds.n_samples)
    _expect(_write_raw(tmp_path / "f.parquet", cols), match, field=column)


def test_integer_and_float32_columns_are_accepted(tmp_path: Path, small_ds: Dataset) -> None:
    cols = _columns(small_ds)
    cols["episode"] = cols["episode"].astype(np.int16)
    cols["left"] = np.zeros(small_ds.n_samples, dtype=np.int32)
    cols["distance"] = cols["distance"].astype(np.float32)
    back = read(_write_raw(tmp_path / "f.parquet", cols, small_ds.metadata))
    assert back.column("left").dtype == np.float64
    np.testing.assert_array_equal(back.column("distance"), cols["distance"].astype(np.float64))


@pytest.mark.parametrize(("value", "match"), [(np.nan, "NaN value"), (np.inf, "infinite value")])
def test_nan_and_inf(tmp_path: Path, small_ds: Dataset, value: float, match: str) -> None:
    cols = _columns(small_ds)
    cols["angular_velocity"][small_ds.offsets[2] + 5] = value
    path = _write_raw(tmp_path / "f.parquet", cols)
    _expect(path, match, episode=2, row=5, field="angular_velocity")


def test_null_value(tmp_path: Path, small_ds: Dataset) -> None:
    cols = _columns(small_ds)
    values = cols["right"].tolist()
    values[small_ds.offsets[1] + 3] = None
    cols["right"] = pa.array(values, type=pa.float64())
    _expect(_write_raw(tmp_path / "f.parquet", cols), "null", episode=1, row=3, field="right")


def test_null_episode_id(tmp_path: Path, small_ds: Dataset) -> None:
    cols = _columns(small_ds)
    ids = cols["episode"].tolist()
    ids[4] = None
    cols["episode"] = pa.array(ids, type=pa.int64())
    _expect(_write_raw(tmp_path / "f.parquet", cols), "null", field="episode")


@pytest.mark.parametrize("delta", [0.0, -0.5])
def test_non_increasing_time(tmp_path: Path, small_ds: Dataset, delta: float) -> None:
    cols = _columns(small_ds)
    i = small_ds.offsets[3] + 7
    cols["t"][i] = cols["t"][i - 1] + delta
    path = _write_raw(tmp_path / "f.parquet", cols)
    _expect(path, "time does not increase", episode=3, row=7, field="t")


def test_time_may_restart_between_episodes(tmp_path: Path, small_ds: Dataset) -> None:
    assert small_ds.t[small_ds.offsets[1]] < small_ds.t[small_ds.offsets[1] - 1]
    assert read(write(small_ds, tmp_path / "f.parquet")) == small_ds


def test_empty_file(tmp_path: Path, small_ds: Dataset) -> None:
    cols = {k: v[:0] for k, v in _columns(small_ds).items()}
    _expect(_write_raw(tmp_path / "f.parquet", cols), "empty")


def test_zero_byte_file(tmp_path: Path) -> None:
    (tmp_path / "f.parquet").write_bytes(b"")
    _expect(tmp_path / "f.parquet", "not a readable Parquet file")


@pytest.mark.parametrize(
    ("column", "value", "match"),
    [
        ("distance", 50.0, r"absurd value 50 m"),
        ("distance", -3.0, r"absurd value -3 m"),
        ("angle", 400.0, r"absurd value 400 deg"),
        ("linear_velocity", 12.0, r"absurd value 12 m/s"),
        ("angular_velocity", -1e5, r"absurd value -100000 deg/s"),
        ("left", 5000.0, r"absurd value 5000 rad/s"),
    ],
)
def test_absurd_values(
    tmp_path: Path, small_ds: Dataset, column: str, value: float, match: str
) -> None:
    cols = _columns(small_ds)
    cols[column][small_ds.offsets[1] + 11] = value
    path = _write_raw(tmp_path / "f.parquet", cols)
    _expect(path, match, episode=1, row=11, field=column)


def test_bad_behavior_name(tmp_path: Path, complex_ds: Dataset) -> None:
    cols = _columns(complex_ds)
    cols["behavior"][complex_ds.offsets[1] + 2] = "Turn Left"
    md = {k: v for k, v in complex_ds.metadata.items() if k != "behaviors"}
    path = _write_raw(tmp_path / "f.parquet", cols, md)
    _expect(path, "invalid behavior name 'Turn Left'", episode=1, row=2, field="behavior")


def test_unknown_behavior_from_metadata_list(tmp_path: Path, complex_ds: Dataset) -> None:
    cols = _columns(complex_ds)
    cols["behavior"][complex_ds.offsets[2] + 1] = "trun"
    path = _write_raw(tmp_path / "f.parquet", cols, complex_ds.metadata)
    err = _expect(path, "unknown behavior 'trun'", episode=2, row=1, field="behavior")
    assert "did you mean 'turn'" in str(err)


def test_unknown_behavior_from_argument(tmp_path: Path, complex_ds: Dataset) -> None:
    path = write(complex_ds, tmp_path / "f.parquet")
    with pytest.raises(DatasetError, match="unknown behavior 'approach'") as info:
        read(path, behaviors=["turn", "grasp"])
    assert info.value.file == str(path) and info.value.field == "behavior"


def test_behaviors_required_but_no_column(tmp_path: Path, small_ds: Dataset) -> None:
    path = write(small_ds, tmp_path / "f.parquet")
    with pytest.raises(DatasetError, match="no 'behavior' column"):
        read(path, behaviors=["turn"])


def test_non_contiguous_episodes(tmp_path: Path, small_ds: Dataset) -> None:
    cols = _columns(small_ds)
    a, b = small_ds.offsets[1], small_ds.offsets[2]
    cols["episode"][a + 10 : b] = 0  # episode 1's tail relabelled as episode 0
    cols["t"][a + 10 : b] += 100.0
    path = _write_raw(tmp_path / "f.parquet", cols)
    _expect(path, "not contiguous", episode=0, row=60, field="episode")


@pytest.mark.parametrize("version", [2, 0, "1", None, 1.5])
def test_unsupported_schema_version(tmp_path: Path, small_ds: Dataset, version: Any) -> None:
    md = small_ds.metadata
    md["schema_version"] = version
    path = _write_raw(tmp_path / "f.parquet", _columns(small_ds), md)
    _expect(path, "unsupported schema version", field="schema_version")


@pytest.mark.parametrize(
    ("raw", "match"),
    [
        (b"{not json", "not valid JSON"),
        (b"[1, 2]", "not a JSON object"),
        (b"\xff\xfe", "not valid JSON"),
    ],
)
def test_bad_metadata(tmp_path: Path, small_ds: Dataset, raw: bytes, match: str) -> None:
    path = _write_raw(tmp_path / "f.parquet", _columns(small_ds), raw)
    _expect(path, match, field="metadata")


def test_file_without_our_metadata_is_read(tmp_path: Path, small_ds: Dataset) -> None:
    back = read(_write_raw(tmp_path / "f.parquet", _columns(small_ds)))
    assert back.metadata == {"schema_version": 1}
    np.testing.assert_array_equal(back.sensors, small_ds.sensors)


def test_random_bytes(tmp_path: Path, rng: np.random.Generator) -> None:
    path = tmp_path / "f.parquet"
    path.write_bytes(rng.integers(0, 256, 5000, dtype=np.uint8).tobytes())
    _expect(path, "not a readable Parquet file")


@pytest.mark.parametrize("fraction", [0.1, 0.5, 0.9, 0.999])
def test_truncated_file(tmp_path: Path, small_ds: Dataset, fraction: float) -> None:
    data = write(small_ds, tmp_path / "good.parquet").read_bytes()
    path = tmp_path / "f.parquet"
    path.write_bytes(data[: int(len(data) * fraction)])
    _expect(path, "not a readable Parquet file")


def test_csv_renamed_to_parquet(tmp_path: Path) -> None:
    path = tmp_path / "f.parquet"
    path.write_text("episode,t,distance\n0,0.0,0.5\n")
    _expect(path, "not a readable Parquet file")


def test_missing_file_and_directory(tmp_path: Path) -> None:
    _expect(tmp_path / "nope.parquet", "no such file")
    (tmp_path / "dir.parquet").mkdir()
    _expect(tmp_path / "dir.parquet", "directory")


def test_read_never_changes_the_file(tmp_path: Path, small_ds: Dataset) -> None:
    path = write(small_ds, tmp_path / "f.parquet")
    stat = os.stat(path)
    before = path.read_bytes()
    read(path)
    assert path.read_bytes() == before and os.stat(path).st_mtime_ns == stat.st_mtime_ns
