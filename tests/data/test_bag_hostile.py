"""Hostile ROS bags: every one refused in one line, never a hang, a traceback or a huge grid.

Named pipes among a bag's files, damage that shows only while iterating (a corrupt MCAP
chunk, a corrupt ROS 1 message, a text time stamp in a .db3), and messages so far apart
that the alignment grid would be huge. Bags are written by rosbags' own writers
(``bag_writing``) and then damaged here, in ``tmp_path``.
"""

from __future__ import annotations

import os
import sqlite3
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rosbags")

from bag_writing import FLOAT_TOPICS, write_floats

import behavior_hmm.data._bags as bags_mod
from behavior_hmm.data import import_bags
from behavior_hmm.data._bags import MAX_ALIGNED_ROWS, MAX_ROWS_PER_MESSAGE
from behavior_hmm.errors import ConfigError, DatasetError

ALL_FLOATS = {c: f"{t}:data" for c, t in FLOAT_TOPICS.items()}
START = 1_700_000_000 * 10**9


def _topics(n: int = 40, step_ns: int = 16_000_000) -> dict[str, list[tuple[int, float]]]:
    return {t: [(START + i * step_ns, 0.1) for i in range(n)] for t in FLOAT_TOPICS.values()}


def _refused(bag: Path, *needles: str, **options: Any) -> DatasetError:
    start = time.perf_counter()
    with pytest.raises(DatasetError) as info:
        import_bags([bag], mapping=ALL_FLOATS, **options)
    assert time.perf_counter() - start < 10
    text = str(info.value)
    assert "\n" not in text
    for needle in needles:
        assert needle in text, (needle, text)
    return info.value


def _mcap_bag(path: Path, n: int = 400) -> Path:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    f64 = store.types["std_msgs/msg/Float64"]
    with Writer(path, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
        conns = [
            writer.add_connection(t, "std_msgs/msg/Float64", typestore=store)
            for t in FLOAT_TOPICS.values()
        ]
        for i in range(n):
            for conn in conns:
                raw = store.serialize_cdr(f64(data=0.1), "std_msgs/msg/Float64")
                writer.write(conn, START + i * 16_000_000, raw)
    return path


def test_the_undamaged_bags_import(tmp_path: Path) -> None:
    assert import_bags([write_floats(tmp_path / "a.bag", 1, _topics())], mapping=ALL_FLOATS)
    assert import_bags([write_floats(tmp_path / "b", 2, _topics())], mapping=ALL_FLOATS)
    assert import_bags([_mcap_bag(tmp_path / "m")], mapping=ALL_FLOATS)


# -- named pipes among the bag's files -----------------------------------------------

fifo_only = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")


@fifo_only
def test_a_fifo_as_the_db3_is_refused_without_waiting(tmp_path: Path) -> None:
    bag = write_floats(tmp_path / "r2", 2, _topics())
    db = next(bag.glob("*.db3"))
    db.unlink()
    os.mkfifo(db)
    _refused(bag, str(db), "named pipe")


@fifo_only
def test_a_fifo_as_the_metadata_yaml_is_refused_without_waiting(tmp_path: Path) -> None:
    bag = write_floats(tmp_path / "r2", 2, _topics())
    (bag / "metadata.yaml").unlink()
    os.mkfifo(bag / "metadata.yaml")
    _refused(bag, "metadata.yaml", "named pipe")


@fifo_only
def test_a_fifo_as_the_mcap_file_is_refused(tmp_path: Path) -> None:
    bag = _mcap_bag(tmp_path / "m", n=10)
    mcap = next(bag.glob("*.mcap"))
    mcap.unlink()
    os.mkfifo(mcap)
    _refused(bag, str(mcap), "named pipe")


@fifo_only
def test_a_fifo_as_a_ros1_bag_is_refused(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "pipe.bag")
    _refused(tmp_path / "pipe.bag", "named pipe")


def test_a_device_as_the_db3_is_refused(tmp_path: Path) -> None:
    if not Path("/dev/zero").exists():
        pytest.skip("no /dev/zero here")
    bag = write_floats(tmp_path / "r2", 2, _topics())
    db = next(bag.glob("*.db3"))
    db.unlink()
    db.symlink_to("/dev/zero")
    _refused(bag, "a device")


def test_hostile_metadata_yaml_is_refused(tmp_path: Path) -> None:
    bag = write_floats(tmp_path / "r2", 2, _topics())
    (bag / "metadata.yaml").write_text("[" * 10_000 + "]" * 10_000, encoding="utf-8")
    _refused(bag, "metadata.yaml", "nested more than 32")
    (bag / "metadata.yaml").write_text("just text", encoding="utf-8")
    _refused(bag, "metadata.yaml", "not a rosbag2 metadata file")
    (bag / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  relative_file_paths: [[1]]\n", encoding="utf-8"
    )
    _refused(bag, "not a file name")


# -- damage that shows only while iterating ------------------------------------------


def test_a_text_time_stamp_in_the_db3_is_refused(tmp_path: Path) -> None:
    bag = write_floats(tmp_path / "r2", 2, _topics())
    db = next(bag.glob("*.db3"))
    with sqlite3.connect(db) as con:
        con.execute("UPDATE messages SET timestamp = 'abc' WHERE id = 3")
    con.close()
    _refused(bag, str(bag), "damaged bag", "time stamp 'abc'", "message ")


def test_a_float_time_stamp_in_the_db3_is_refused(tmp_path: Path) -> None:
    bag = write_floats(tmp_path / "r2", 2, _topics())
    db = next(bag.glob("*.db3"))
    with sqlite3.connect(db) as con:
        con.execute("UPDATE messages SET timestamp = 1.5 WHERE id = 3")
    con.close()
    _refused(bag, "damaged bag", "not a number of nanoseconds")


def test_a_corrupt_ros1_message_record_is_refused(tmp_path: Path) -> None:
    bag = write_floats(tmp_path / "r1.bag", 1, _topics())
    data = bytearray(bag.read_bytes())
    first = data.find(b"op=\x02")  # the first message data record
    assert first > 0
    data[first + 40 : first + 60] = b"\xff" * 20
    bag.write_bytes(bytes(data))
    _refused(bag, str(bag), "damaged bag")


def test_a_corrupt_ros1_message_body_is_refused(tmp_path: Path) -> None:
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    arr = store.types["std_msgs/msg/Float64MultiArray"]
    bag = tmp_path / "body.bag"
    with Writer(bag) as writer:
        conn = writer.add_connection("/arr", "std_msgs/msg/Float64MultiArray", typestore=store)
        for i in range(5):
            layout = store.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
            msg = arr(layout=layout, data=np.array([0.1, 0.2]))
            raw = bytes(store.serialize_ros1(msg, "std_msgs/msg/Float64MultiArray"))
            if i == 3:  # an array length far past the message's end
                raw = raw[:8] + b"\xff\xff\xff\x7f" + raw[12:]
            writer.write(conn, START + i * 16_000_000, raw)
    mapping = {c: "/arr:data[0]" for c in ALL_FLOATS}
    start = time.perf_counter()
    with pytest.raises(DatasetError) as info:
        import_bags([bag], mapping=mapping)
    assert time.perf_counter() - start < 10
    text = str(info.value)
    assert "message 3 on /arr" in text and str(bag) in text and "\n" not in text


@pytest.mark.parametrize("where", [0.3, 0.5, 0.7])
def test_a_corrupt_mcap_chunk_is_refused(tmp_path: Path, where: float) -> None:
    """Whether rosbags raises on the damage or reads a shorter bag (fewer messages than
    the bag's own index lists), the bag is refused in one line naming it."""
    bag = _mcap_bag(tmp_path / "m")
    mcap = next(bag.glob("*.mcap"))
    data = bytearray(mcap.read_bytes())
    at = int(len(data) * where)
    data[at : at + 64] = b"\x00" * 64
    mcap.write_bytes(bytes(data))
    with pytest.raises(DatasetError) as info:
        import_bags([bag], mapping=ALL_FLOATS)
    assert "\n" not in str(info.value) and str(bag) in str(info.value)
    assert "damaged bag" in str(info.value)


def test_a_truncated_mcap_is_refused(tmp_path: Path) -> None:
    bag = _mcap_bag(tmp_path / "m")
    mcap = next(bag.glob("*.mcap"))
    mcap.write_bytes(mcap.read_bytes()[: mcap.stat().st_size // 2])
    _refused(bag, str(bag))


# -- grids bounded by the data they came from ------------------------------------------


def test_twelve_messages_a_day_apart_are_refused_before_allocating(tmp_path: Path) -> None:
    day = 86_400 * 10**9
    topics = {t: [(START + k * day, 0.1) for k in range(12)] for t in FLOAT_TOPICS.values()}
    bag = write_floats(tmp_path / "days", 2, topics)
    err = _refused(bag, "MAX_ALIGNED_ROWS", "86,400 s", "--split-gap")
    assert f"{MAX_ALIGNED_ROWS:,}" in str(err)


def test_a_grid_of_2_to_the_62_ns_is_refused_before_allocating(tmp_path: Path) -> None:
    topics = {t: [(1, 0.1), (2**62, 0.2)] for t in FLOAT_TOPICS.values()}
    _refused(write_floats(tmp_path / "huge", 2, topics), "MAX_ALIGNED_ROWS")


def test_a_grid_sparse_in_messages_is_refused(tmp_path: Path) -> None:
    """Under MAX_ALIGNED_ROWS but more rows than its messages justify."""
    step = 16_000_000 * MAX_ROWS_PER_MESSAGE * 20  # 3 messages per topic, 6 topics
    topics = {t: [(START + k * step, 0.1) for k in range(3)] for t in FLOAT_TOPICS.values()}
    _refused(write_floats(tmp_path / "sparse", 2, topics), "MAX_ROWS_PER_MESSAGE")


def test_a_grid_past_the_bound_over_several_bags_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(bags_mod, "MAX_ALIGNED_ROWS", 60)
    bag = write_floats(tmp_path / "a", 2, _topics(40))
    with pytest.raises(DatasetError, match="MAX_ALIGNED_ROWS"):
        import_bags([bag, bag], mapping=ALL_FLOATS)


def test_split_gap_makes_such_a_bag_importable(tmp_path: Path) -> None:
    day = 86_400 * 10**9
    topics = {
        t: [(START + k * day + i * 16_000_000, 0.1) for k in range(3) for i in range(10)]
        for t in FLOAT_TOPICS.values()
    }
    ds = import_bags([write_floats(tmp_path / "d", 2, topics)], mapping=ALL_FLOATS, split_gap=1)
    assert ds.lengths.tolist() == [10, 10, 10]


@pytest.mark.parametrize("period", [0.0, -1.0, float("nan"), 1e-12, 1e6])
def test_a_bad_alignment_period_is_a_config_error(tmp_path: Path, period: float) -> None:
    bag = write_floats(tmp_path / "a", 2, _topics())
    with pytest.raises(ConfigError, match="alignment period"):
        import_bags([bag], mapping=ALL_FLOATS, period=period)
