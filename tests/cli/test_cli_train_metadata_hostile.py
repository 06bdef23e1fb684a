"""``train simple`` and ``import-bag`` on hostile inputs: one ``error:`` line, exit 2.

The dataset metadata ``train simple`` trusts is validated when the file is read, before
any training; a FIFO given as the dataset or as a bag's file is refused without waiting;
a bag whose alignment grid would be huge or that is damaged inside is refused in one
line.
"""

from __future__ import annotations

import json
import os
import sqlite3
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from cli_testing import Invoke, assert_user_error, files_in

from behavior_hmm.data import METADATA_KEY
from behavior_hmm.data._validate import MAX_ROWS

fifo_only = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")


def _tampered(source: Path, path: Path, **changes: object) -> Path:
    table = pq.read_table(source)
    md = json.loads(table.schema.metadata[METADATA_KEY])
    md.update(changes)
    meta = {METADATA_KEY: json.dumps(md).encode()}
    pq.write_table(table.replace_schema_metadata(meta), path)
    return path


def _train(invoke: Invoke, data: Path, out: Path) -> str:
    start = time.perf_counter()
    result = invoke(["train", "simple", data, "--inputs", "angle", "-o", out])
    assert time.perf_counter() - start < 10  # refused before any training
    line = assert_user_error(result, str(data))
    assert not out.exists()
    return line


@pytest.mark.parametrize(
    ("changes", "needles"),
    [
        ({"goal": {"angle": "abc"}}, ["metadata goal", "finite number"]),
        ({"goal": {"warp": 1.0}}, ["metadata goal", "unknown goal channel"]),
        ({"control_period": "0.016"}, ["metadata control_period"]),
        ({"control_period": -0.016}, ["metadata control_period"]),
        ({"ranges": {"angle": [180, -180]}}, ["metadata ranges", "lo < hi"]),
        ({"corrective_episodes": [2**70]}, ["metadata corrective_episodes"]),
        ({"corrections": {"disturbs": 5}}, ["metadata corrections"]),
        ({"corrections": [1]}, ["metadata corrections"]),
        ({"env": "a\nb"}, ["metadata env"]),
    ],
)
def test_train_simple_refuses_tampered_metadata_before_training(
    invoke: Invoke,
    tmp_path: Path,
    turn_parquet: Path,
    changes: dict[str, object],
    needles: list[str],
) -> None:
    data = _tampered(turn_parquet, tmp_path / "t.parquet", **changes)
    line = _train(invoke, data, tmp_path / "m.bhmm")
    for needle in needles:
        assert needle in line, (needle, line)


def test_train_simple_refuses_deeply_nested_metadata(
    invoke: Invoke, tmp_path: Path, turn_parquet: Path
) -> None:
    table = pq.read_table(turn_parquet)
    raw = b'{"x": ' + b"[" * 50_000 + b"]" * 50_000 + b"}"
    data = tmp_path / "deep.parquet"
    pq.write_table(table.replace_schema_metadata({METADATA_KEY: raw}), data)
    assert "nested more than 32" in _train(invoke, data, tmp_path / "m.bhmm")


@fifo_only
def test_train_simple_refuses_a_fifo_without_waiting(invoke: Invoke, tmp_path: Path) -> None:
    fifo = tmp_path / "data.parquet"
    os.mkfifo(fifo)
    assert "named pipe" in _train(invoke, fifo, tmp_path / "m.bhmm")


def test_train_simple_refuses_a_parquet_bomb_from_its_footer(
    invoke: Invoke, tmp_path: Path
) -> None:
    data = tmp_path / "bomb.parquet"
    table = pa.table({"episode": pa.array(np.zeros(MAX_ROWS + 1, dtype=np.int64))})
    pq.write_table(table, data, compression="zstd")
    assert "MAX_ROWS" in _train(invoke, data, tmp_path / "m.bhmm")


# -- import-bag ---------------------------------------------------------------------------


@pytest.fixture
def float_bag(tmp_path: Path) -> Path:
    pytest.importorskip("rosbags")
    from bag_writing import FLOAT_TOPICS, write_floats

    start = 1_700_000_000 * 10**9
    topics = {t: [(start + i * 16_000_000, 0.1) for i in range(40)] for t in FLOAT_TOPICS.values()}
    return write_floats(tmp_path / "bags" / "r2", 2, topics)


def _import(invoke: Invoke, bag: Path, out: Path, *needles: str) -> str:
    from bag_writing import FLOAT_TOPICS

    args: list[object] = ["import-bag", bag]
    for channel, topic in FLOAT_TOPICS.items():
        args += ["--map", f"{channel}={topic}:data"]
    start = time.perf_counter()
    result = invoke([*args, "-o", out])
    assert time.perf_counter() - start < 10
    line = assert_user_error(result, str(bag), *needles)
    assert files_in(out.parent) == set()
    return line


@fifo_only
def test_import_bag_refuses_a_fifo_db3(invoke: Invoke, tmp_path: Path, float_bag: Path) -> None:
    db = next(float_bag.glob("*.db3"))
    db.unlink()
    os.mkfifo(db)
    (tmp_path / "out").mkdir()
    _import(invoke, float_bag, tmp_path / "out" / "o.parquet", "named pipe")


def test_import_bag_refuses_a_text_time_stamp(
    invoke: Invoke, tmp_path: Path, float_bag: Path
) -> None:
    db = next(float_bag.glob("*.db3"))
    with sqlite3.connect(db) as con:
        con.execute("UPDATE messages SET timestamp = 'abc' WHERE id = 5")
    con.close()
    (tmp_path / "out").mkdir()
    _import(invoke, float_bag, tmp_path / "out" / "o.parquet", "damaged bag", "'abc'")


def test_import_bag_refuses_a_huge_alignment_grid(invoke: Invoke, tmp_path: Path) -> None:
    pytest.importorskip("rosbags")
    from bag_writing import FLOAT_TOPICS, write_floats

    day = 86_400 * 10**9
    start = 1_700_000_000 * 10**9
    topics = {t: [(start + k * day, 0.1) for k in range(12)] for t in FLOAT_TOPICS.values()}
    bag = write_floats(tmp_path / "bags" / "days", 2, topics)
    (tmp_path / "out").mkdir()
    _import(invoke, bag, tmp_path / "out" / "o.parquet", "MAX_ALIGNED_ROWS", "--split-gap")
