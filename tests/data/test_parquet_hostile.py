"""Hostile Parquet datasets: every one refused in one line, before any work starts.

Tampered metadata (read back and trusted by ``train simple``), a FIFO or a device given
as the dataset, metadata nested past the bound, and a small file whose footer promises
more rows or bytes than the reader takes. Every input is built here, in ``tmp_path``.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import behavior_hmm.data._parquet as parquet_mod
from behavior_hmm.data import METADATA_KEY, Dataset, read, write
from behavior_hmm.data._filter import SignalPipeline
from behavior_hmm.data._validate import MAX_ROWS
from behavior_hmm.errors import ConfigError, DatasetError
from behavior_hmm.models import SBLM
from behavior_hmm.models._goals import check_goal
from behavior_hmm.models._sblm import nominal_episodes, without_unseen_corrections

#: Metadata as ``collect`` writes it (with corrective demonstrations).
GOOD_METADATA: dict[str, Any] = {
    "behavior": "turn",
    "goal": {"angle": 0.0},
    "simulator": "kinematic",
    "env": "kinematic",
    "control_period": 0.016,
    "ranges": {
        "distance": [0.0, 1.2],
        "linear_velocity": [-0.2, 0.2],
        "angle": [-180.0, 180.0],
        "angular_velocity": [-360.0, 360.0],
    },
    "seed": 0,
    "noise": 0.0,
    "corrections": {"copies": 1, "noise": 0.1, "disturbs": ["angle"]},
    "corrective_episodes": [1],
}


def _episode(angle: float, n: int = 12) -> dict[str, Any]:
    a = np.linspace(angle, 0.0, n)
    return {
        "t": np.arange(n) * 0.016,
        "distance": np.full(n, 0.5),
        "linear_velocity": np.zeros(n),
        "angle": a,
        "angular_velocity": np.gradient(a, 0.016),
        "left": np.full(n, -1.0),
        "right": np.full(n, 1.0),
    }


@pytest.fixture(scope="module")
def good_ds() -> Dataset:
    return Dataset.from_episodes([_episode(90.0), _episode(-60.0)], GOOD_METADATA)


def _with_metadata(path: Path, source: Path, metadata: object) -> Path:
    """A copy of the Parquet file ``source`` whose metadata JSON is ``metadata``."""
    table = pq.read_table(source)
    raw = metadata if isinstance(metadata, bytes) else json.dumps(metadata).encode()
    pq.write_table(table.replace_schema_metadata({METADATA_KEY: raw}), path)
    return path


@pytest.fixture(scope="module")
def good_file(good_ds: Dataset, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write(good_ds, tmp_path_factory.mktemp("good") / "good.parquet")


def _refused(path: Path, *needles: str) -> DatasetError:
    start = time.perf_counter()
    with pytest.raises(DatasetError) as info:
        read(path)
    assert time.perf_counter() - start < 10
    text = str(info.value)
    assert "\n" not in text
    assert str(path) in text
    for needle in needles:
        assert needle in text, (needle, text)
    return info.value


def test_the_good_file_reads(good_file: Path, good_ds: Dataset) -> None:
    assert read(good_file) == good_ds


# -- tampered metadata (the 18 cases of the hostile tester, and more) -------------------

TAMPERED: list[tuple[str, object, str]] = [
    ("goal", {"angle": "abc"}, "goal angle must be a finite number"),
    ("goal", {"angle": None}, "goal angle must be a finite number"),
    ("goal", {"angle": True}, "goal angle must be a finite number"),
    ("goal", {"angle": 1e300}, "not in [-180, 180]"),
    ("goal", {"angle": 10**400}, "goal angle must be a finite number"),
    ("goal", {"wheel": 1.0}, "unknown goal channel"),
    ("goal", {"left": 1.0}, "unknown goal channel"),
    ("goal", ["angle", 0], "goal must be an object"),
    ("goal", "angle=0", "goal must be an object"),
    ("goal", {"distance": -1.0}, "not in [0, 10]"),
    ("control_period", "0.016", "control_period must be a number"),
    ("control_period", -0.016, "control_period must be a number"),
    ("control_period", 0, "control_period must be a number"),
    ("control_period", 1e9, "control_period must be a number"),
    ("control_period", True, "control_period must be a number"),
    ("ranges", {"angle": [180.0, -180.0]}, "lo < hi"),
    ("ranges", {"angle": [0.0, 0.0]}, "lo < hi"),
    ("ranges", {"angle": ["a", "b"]}, "two finite numbers"),
    ("ranges", {"angle": [0.0]}, "two finite numbers"),
    ("ranges", {"angle": [-1e30, 1e30]}, "must lie within"),
    ("ranges", [[0, 1]], "ranges must be an object"),
    ("ranges", {"Angle Channel": [0, 1]}, "not a channel name"),
    ("corrective_episodes", [2**64], "int64 integers"),
    ("corrective_episodes", [1.5], "int64 integers"),
    ("corrective_episodes", ["1"], "int64 integers"),
    ("corrective_episodes", [[1]], "int64 integers"),
    ("corrective_episodes", 1, "must be a list of episode ids"),
    ("corrective_episodes", {"1": 1}, "must be a list of episode ids"),
    ("corrections", [1, 2], "corrections must be an object"),
    ("corrections", {"disturbs": "angle"}, "disturbs must be a list of channel names"),
    ("corrections", {"disturbs": [["angle"]]}, "disturbs must be a list of channel names"),
    ("corrections", {"copies": -1}, "copies must be an integer >= 0"),
    ("corrections", {"noise": "x"}, "noise must be a number >= 0"),
    ("env", {"a": 1}, "env must be one line of text"),
    ("env", "x" * 5000, "env must be one line of text"),
    ("simulator", "two\nlines", "simulator must be one line of text"),
    ("schema_version", "1", "unsupported schema version"),
    ("behavior", "Not A Name", "invalid behavior name"),
    ("channels", {"name": "ir0"}, "'channels' must be a list"),
]


@pytest.mark.parametrize(("key", "value", "needle"), TAMPERED)
def test_tampered_metadata_is_refused_naming_file_and_key(
    tmp_path: Path, good_file: Path, key: str, value: object, needle: str
) -> None:
    path = _with_metadata(tmp_path / "t.parquet", good_file, {**GOOD_METADATA, key: value})
    err = _refused(path, needle)
    assert key in (err.field or "") or key in str(err)


def test_metadata_is_checked_before_the_table_is_read(
    tmp_path: Path, good_file: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = _with_metadata(tmp_path / "t.parquet", good_file, {**GOOD_METADATA, "goal": "x"})

    def no_read(*args: object, **kwargs: object) -> None:
        raise AssertionError("the table was read before the metadata was checked")

    monkeypatch.setattr(parquet_mod, "_read_table", no_read)
    _refused(path, "field 'metadata goal'")


def test_deeply_nested_metadata_is_refused_without_recursion(
    tmp_path: Path, good_file: Path
) -> None:
    raw = b'{"deep": ' + b"[" * 100_000 + b"]" * 100_000 + b"}"
    _refused(_with_metadata(tmp_path / "t.parquet", good_file, raw), "nested more than 32")


@pytest.mark.parametrize("constant", [b"NaN", b"Infinity", b"-Infinity"])
def test_nan_in_the_metadata_is_refused(tmp_path: Path, good_file: Path, constant: bytes) -> None:
    raw = b'{"control_period": ' + constant + b"}"
    _refused(_with_metadata(tmp_path / "t.parquet", good_file, raw), "not valid JSON")


def test_huge_metadata_is_refused(tmp_path: Path, good_file: Path) -> None:
    raw = json.dumps({"note": "x" * (parquet_mod.MAX_METADATA_BYTES + 1)}).encode()
    _refused(_with_metadata(tmp_path / "t.parquet", good_file, raw), "MAX_METADATA_BYTES")


# -- hypothesis: one key replaced by any JSON value -----------------------------------

JSON_VALUES = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(min_value=-(2**70), max_value=2**70)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=12),
    lambda children: (
        st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=8), children, max_size=4)
    ),
    max_leaves=12,
)
KEYS = st.sampled_from(
    [*GOOD_METADATA, "schema_version", "channels", "behaviors", "source", "derived"]
)
NESTED_KEYS = st.sampled_from(["goal", "ranges", "corrections"])
CHANNEL_KEYS = st.sampled_from(["angle", "distance", "disturbs", "copies", "noise", "ir0"])


def _consumers_accept(ds: Dataset) -> None:
    """What ``train simple`` does with the metadata, before and after training."""
    try:
        SignalPipeline.for_dataset(ds, ("angle",), 2.0)
        nominal_episodes(ds)
        without_unseen_corrections(ds, ("angle",))
    except ConfigError:
        return
    model = SBLM(inputs=("angle",))
    model.rest_values_ = {"angle": 0.0}
    goal = model._default_goal(("angle",), ds.metadata.get("goal"))
    check_goal(goal, ("angle",))


@settings(
    max_examples=50,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(key=KEYS, value=JSON_VALUES)
def test_any_value_for_a_key_reads_or_is_refused(
    tmp_path: Path, good_file: Path, key: str, value: object
) -> None:
    path = _with_metadata(tmp_path / "h.parquet", good_file, {**GOOD_METADATA, key: value})
    try:
        ds = read(path)
    except (DatasetError, ConfigError) as err:
        assert "\n" not in str(err)
        return
    _consumers_accept(ds)


@settings(
    max_examples=50,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(key=NESTED_KEYS, inner=CHANNEL_KEYS, value=JSON_VALUES)
def test_any_value_inside_a_key_reads_or_is_refused(
    tmp_path: Path, good_file: Path, key: str, inner: str, value: object
) -> None:
    md = json.loads(json.dumps(GOOD_METADATA))
    md[key][inner] = value
    path = _with_metadata(tmp_path / "h.parquet", good_file, md)
    try:
        ds = read(path)
    except (DatasetError, ConfigError) as err:
        assert "\n" not in str(err)
        return
    _consumers_accept(ds)


# -- not a regular file ---------------------------------------------------------------


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_a_fifo_is_refused_without_waiting(tmp_path: Path) -> None:
    fifo = tmp_path / "data.parquet"
    os.mkfifo(fifo)
    _refused(fifo, "named pipe")


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="no /dev/zero here")
def test_a_device_is_refused(tmp_path: Path) -> None:
    link = tmp_path / "zero.parquet"
    link.symlink_to("/dev/zero")
    _refused(link, "a device")


# -- decompression bombs: the footer is checked before the table is read --------------


def test_a_file_with_too_many_rows_is_refused_from_its_footer(tmp_path: Path) -> None:
    path = tmp_path / "rows.parquet"
    table = pa.table({"episode": pa.array(np.zeros(MAX_ROWS + 1, dtype=np.int64))})
    pq.write_table(table, path, compression="zstd")
    assert path.stat().st_size < 1024 * 1024
    _refused(path, f"{MAX_ROWS + 1:,} rows", "MAX_ROWS")


def test_a_file_too_large_once_decompressed_is_refused_from_its_footer(
    tmp_path: Path, good_ds: Dataset, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = write(good_ds, tmp_path / "big.parquet")
    monkeypatch.setattr(parquet_mod, "MAX_UNCOMPRESSED_BYTES", 64)

    def no_read(*args: object, **kwargs: object) -> None:
        raise AssertionError("the table was read before its size was checked")

    monkeypatch.setattr(parquet_mod, "_read_table", no_read)
    _refused(path, "MAX_UNCOMPRESSED_BYTES")


def test_row_groups_are_read_within_the_bounds(
    tmp_path: Path, good_ds: Dataset, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A footer that understates the sizes is caught while the row groups are read."""
    path = write(good_ds, tmp_path / "big.parquet")
    monkeypatch.setattr(parquet_mod, "_check_footer", lambda pf, file: None)
    monkeypatch.setattr(parquet_mod, "MAX_ROWS", 5)
    _refused(path, "MAX_ROWS")
