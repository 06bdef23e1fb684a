"""The LeRobot importer refuses hostile folders in one line (DatasetError / ConfigError).

Each case starts from a valid folder written by ``export_lerobot`` and tampers with one
file. Never a traceback, never a hang (an alarm fails a test that waits), never a table
read before its footer's bounds are checked.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import tempfile
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from behavior_hmm.data import CONTROL_PERIOD, DataImportWarning, Dataset, export_lerobot
from behavior_hmm.data import _lerobot as lerobot
from behavior_hmm.data._lerobot import import_lerobot
from behavior_hmm.errors import ConfigError, DatasetError

DATA = "data/chunk-000/file-000.parquet"
INFO = "meta/info.json"
OURS = "meta/behavior_hmm.json"
TASKS = "meta/tasks.parquet"


def _episode(angle0: float, n: int, behavior: bool) -> dict[str, Any]:
    """A slow turn then a short approach at the control period (no SamplingWarning)."""
    k = np.arange(n)
    angle = angle0 * (1.0 - k / n)
    distance = 0.5 - 0.002 * k
    omega = np.full(n, -angle0 / (n * CONTROL_PERIOD))
    v = np.full(n, 0.002 / CONTROL_PERIOD)
    ep: dict[str, Any] = {
        "t": k * CONTROL_PERIOD,
        "distance": distance,
        "linear_velocity": v,
        "angle": angle,
        "angular_velocity": omega,
        "left": (v - np.deg2rad(omega) * 0.05) / 0.008,
        "right": (v + np.deg2rad(omega) * 0.05) / 0.008,
    }
    if behavior:
        ep["behavior"] = np.where(k < n // 2, "turn", "approach").astype(object)
    return ep


def _dataset(behavior: bool = False) -> Dataset:
    eps = [_episode(a, 20 + 5 * i, behavior) for i, a in enumerate((60.0, -40.0, 20.0))]
    md: dict[str, Any] = {"behavior": "turn", "seed": 3}
    if behavior:
        md = {"behavior": "turn_approach", "behaviors": ["turn", "approach"]}
    return Dataset.from_episodes(eps, md)


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return export_lerobot(_dataset(), tmp_path_factory.mktemp("base") / "lr")


@pytest.fixture(scope="module")
def base_complex(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return export_lerobot(_dataset(behavior=True), tmp_path_factory.mktemp("base") / "lr")


@pytest.fixture
def folder(base: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(base, tmp_path / "lr"))


@pytest.fixture
def complex_folder(base_complex: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(base_complex, tmp_path / "lr"))


@pytest.fixture(autouse=True)
def no_hang() -> Iterator[None]:
    """Fail (rather than hang) a test that waits more than 60 s."""

    def stop(signum: int, frame: object) -> None:
        raise AssertionError("the import hung")

    previous = signal.signal(signal.SIGALRM, stop)
    signal.alarm(60)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def _edit_json(folder: Path, rel: str, edit: Callable[[Any], Any]) -> None:
    path = folder / rel
    doc = json.loads(path.read_text())
    path.write_text(json.dumps(edit(doc)))


def _set(rel_key: str, value: Any) -> Callable[[Any], Any]:
    def edit(doc: Any) -> Any:
        *parents, last = rel_key.split("/")
        node = doc
        for key in parents:
            node = node[key]
        node[last] = value
        return doc

    return edit


def _edit_table(path: Path, edit: Callable[[pa.Table], pa.Table]) -> None:
    pq.write_table(edit(pq.read_table(path)), path)


def _replace(name: str, array: pa.Array) -> Callable[[pa.Table], pa.Table]:
    def edit(table: pa.Table) -> pa.Table:
        i = table.schema.get_field_index(name)
        return table.set_column(i, name, array)

    return edit


def _refused(folder: Path, *needles: str, error: type[Exception] = DatasetError) -> str:
    """The import's error; each needle is in its single line."""
    with pytest.raises(error) as info:
        import_lerobot(folder)
    line = str(info.value)
    assert "\n" not in line
    for needle in needles:
        assert needle in line, (needle, line)
    return line


# -- 1. meta/behavior_hmm.json: every key typed ---------------------------------------------


@pytest.mark.parametrize("value", [["a", "b"], "turn", 3, True])
def test_metadata_that_is_not_an_object_is_refused(folder: Path, value: Any) -> None:
    _edit_json(folder, OURS, _set("metadata", value))
    line = _refused(folder, str(folder / OURS), "field 'metadata'", "must be a JSON object")
    assert "TypeError" not in line


@pytest.mark.parametrize(
    ("key", "value", "needle"),
    [
        ("format", 2, "must be 1"),
        ("format", "1", "must be 1"),
        ("episode_ids", "0,1,2", "list of integer episode ids"),
        ("episode_ids", [0, "1", 2], "episode id 1 must be an integer"),
        ("episode_ids", [0, 1.5, 2], "episode id 1 must be an integer"),
        ("episode_ids", [0, 10**30, 2], "within int64"),
        ("episode_ids", [0, 1, 1], "episode id 1 appears twice"),
        ("episode_ids", [0, 1], "lists 2 episode ids but the data files hold episodes 0..2"),
        ("t0", [0.0, "x", 1.0], "start time 1 must be a number"),
        ("t0", [0.0, True, 1.0], "start time 1 must be a number"),
        ("t0", [0.0, 1e300, 1.0], "within ±1e+10"),
        ("t0", {"0": 1.0}, "a list of episode start times"),
        ("t0", [0.0], "lists 1 start times"),
        ("behavior_from_task", "yes", "true or false"),
        ("behavior_name", 7, "a behavior name"),
        ("behavior_name", "", "a behavior name"),
        ("units", ["deg"], "a JSON object of channel -> unit"),
        ("units", {"angle": "rad"}, "unit of 'angle' is \"rad\"; this reader takes 'deg'"),
    ],
)
def test_each_key_of_our_file_is_typed(folder: Path, key: str, value: Any, needle: str) -> None:
    _edit_json(folder, OURS, _set(key, value))
    _refused(folder, str(folder / OURS), f"field '{key}'", needle)


@pytest.mark.parametrize("doc", [[], "x", None, 1])
def test_our_file_must_hold_an_object(folder: Path, doc: Any) -> None:
    (folder / OURS).write_text(json.dumps(doc))
    _refused(folder, str(folder / OURS), "must hold a JSON object")


def test_a_bad_behavior_name_is_refused_by_the_validator(folder: Path) -> None:
    _edit_json(folder, OURS, _set("behavior_name", "Not A Name!"))
    _refused(folder, "invalid behavior name")


# -- 2. episode_index: integers, none null, none negative -----------------------------------


@pytest.mark.parametrize(
    ("array", "needle"),
    [
        (lambda n: pa.array(["0"] * n), "wrong type string (expected integers)"),
        (lambda n: pa.array([0.0] * (n - 1) + [float("nan")]), "wrong type double"),
        (lambda n: pa.array([0] * 5 + [None] * (n - 5), type=pa.int64()), "row 5"),
        (lambda n: pa.array([0] * 7 + [-3] * (n - 7), type=pa.int64()), "negative index -3"),
        (lambda n: pa.array([2**64 - 1] * n, type=pa.uint64()), "too large for int64"),
    ],
)
def test_bad_episode_index_columns(
    folder: Path, array: Callable[[int], pa.Array], needle: str
) -> None:
    n = pq.read_metadata(folder / DATA).num_rows
    _edit_table(folder / DATA, _replace("episode_index", array(n)))
    _refused(folder, str(folder / DATA), "field 'episode_index'", needle)


def test_a_missing_episode_index_column_is_refused(folder: Path) -> None:
    _edit_table(folder / DATA, lambda t: t.drop_columns(["episode_index"]))
    _refused(folder, str(folder / DATA), "no 'episode_index' column")


@pytest.mark.parametrize(
    ("column", "array", "needle"),
    [
        ("timestamp", lambda n: pa.array(["0"] * n), "wrong type string (expected numbers)"),
        ("timestamp", lambda n: pa.array([0.0] * (n - 1) + [None]), "missing value (null)"),
        ("frame_index", lambda n: pa.array([0.5] * n), "wrong type double (expected integers)"),
        (
            "observation.state",
            lambda n: pa.array([[1.0, 2.0, 3.0, 4.0]] * (n - 1) + [[1.0, None, 3.0, 4.0]]),
            "missing value (null)",
        ),
        (
            "observation.state",
            lambda n: pa.array([[1.0, 2.0, 3.0, 4.0]] * (n - 1) + [[1.0, 2.0]]),
            "row 74, field 'observation.state': vectors of different lengths (2 here, 4 before)",
        ),
        ("action", lambda n: pa.array([["a", "b"]] * n), "expected numbers"),
    ],
)
def test_bad_value_columns(
    folder: Path, column: str, array: Callable[[int], pa.Array], needle: str
) -> None:
    n = pq.read_metadata(folder / DATA).num_rows
    _edit_table(folder / DATA, _replace(column, array(n)))
    _refused(folder, str(folder / DATA), needle)


# -- 3. t0 ----------------------------------------------------------------------------------


def test_t0_holding_strings_is_refused(folder: Path) -> None:
    _edit_json(folder, OURS, _set("t0", ["0", "1", "2"]))
    _refused(folder, str(folder / OURS), "field 't0'", "start time 0 must be a number", '"0"')


# -- 4. fps ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("value", "shown"),
    [
        (10**400, "found a 401-digit number"),
        ("62.5", 'found "62.5"'),
        (True, "found true"),
        (0, "found 0"),
        (-62.5, "found -62.5"),
        (1e300, "found 1e+300"),
        (10_001, "found 10001"),
        (None, "found null"),
        ([62.5], "found [62.5]"),
    ],
)
def test_fps_outside_its_range_is_refused(folder: Path, value: Any, shown: str) -> None:
    _edit_json(folder, INFO, _set("fps", value))
    _refused(
        folder,
        str(folder / INFO),
        "field 'fps'",
        "0 < fps <= 10000",
        shown,
    )


def test_missing_fps_is_refused(folder: Path) -> None:
    _edit_json(folder, INFO, lambda doc: {k: v for k, v in doc.items() if k != "fps"})
    _refused(folder, str(folder / INFO), "field 'fps'", "(missing)")


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity", "1e999"])
def test_non_finite_fps_literals_are_refused(folder: Path, literal: str) -> None:
    path = folder / INFO
    text = json.dumps(json.loads(path.read_text()))
    path.write_text(text.replace('"fps": 62.5', f'"fps": {literal}'))
    _refused(folder, str(path))


# -- 5. features: names and shapes match the data ---------------------------------------------


STATE_NAMES = "features/observation.state/names"
STATE_SHAPE = "features/observation.state/shape"


@pytest.mark.parametrize(
    ("edits", "field", "needle"),
    [
        (
            {STATE_NAMES: ["distance", "linear_velocity", "angle"]},
            "names",
            "lists 3 names but 'shape' says 4 values per frame",
        ),
        (
            {STATE_NAMES: ["distance", "linear_velocity", "angle"], STATE_SHAPE: None},
            "names",
            "lists 3 names but LR/data/chunk-000/file-000.parquet holds 4 values per frame",
        ),
        (
            {STATE_NAMES: ["distance", 1, "angle", 2]},
            "names",
            "element 1 must be a name (a string), found 1",
        ),
        ({STATE_NAMES: "distance"}, "names", 'found "distance"'),
        ({STATE_NAMES: {"a": ["x"], "b": ["y"]}}, "names", "with one axis"),
        ({STATE_NAMES: ["distance", "angle", "angle", "x"]}, "names", "names 'angle' twice"),
        ({STATE_SHAPE: [3]}, "names", "lists 4 names but 'shape' says 3 values per frame"),
        (
            {STATE_SHAPE: [3], STATE_NAMES: None},
            "shape",
            "says 3 values per frame but LR/data/chunk-000/file-000.parquet holds 4",
        ),
        ({STATE_SHAPE: [0]}, "shape", "positive sizes"),
        ({STATE_SHAPE: "4"}, "shape", "positive sizes"),
    ],
)
@pytest.mark.parametrize("mapped", [False, True])
def test_feature_names_and_shapes_must_fit_the_data(
    folder: Path, edits: dict[str, Any], field: str, needle: str, mapped: bool
) -> None:
    # mapped: the elements by index, so the import reaches the data even without names
    mapping = {
        "distance": "observation.state:0",
        "linear_velocity": "observation.state:1",
        "angle": "observation.state:2",
        "angular_velocity": "observation.state:3",
    }
    for key, value in edits.items():
        _edit_json(folder, INFO, _set(key, value))
    needle = needle.replace("LR", str(folder))
    if not mapped and None in edits.values():
        # no names, or 3 names and no shape to hold them against: a channel is not found
        with pytest.raises(ConfigError, match="no feature for channel"):
            import_lerobot(folder)
        return
    with pytest.raises(DatasetError) as info:
        import_lerobot(folder, mapping=mapping if mapped else None)
    line = str(info.value)
    assert line.startswith(f"{folder / INFO}, field 'features.observation.state.{field}': ")
    assert needle in line, line


def test_a_feature_that_is_not_an_object_is_refused(folder: Path) -> None:
    _edit_json(folder, INFO, _set("features/action", ["left", "right"]))
    _refused(folder, str(folder / INFO), "field 'features.action'", "must be a JSON object")


@pytest.mark.parametrize("value", [None, [], {}, "x"])
def test_features_must_be_a_table(folder: Path, value: Any) -> None:
    _edit_json(folder, INFO, _set("features", value))
    _refused(folder, str(folder / INFO), "field 'features'")


def test_a_feature_missing_from_the_data_is_refused(folder: Path) -> None:
    _edit_table(folder / DATA, lambda t: t.drop_columns(["action"]))
    _refused(folder, str(folder / DATA), "no 'action' feature")


def test_codebase_version_must_be_a_string(folder: Path) -> None:
    _edit_json(folder, INFO, _set("codebase_version", 3))
    _refused(folder, str(folder / INFO), "field 'codebase_version'")


# -- 6. tasks.parquet -------------------------------------------------------------------------


def _tasks(index: pa.Array, text: pa.Array) -> pa.Table:
    return pa.table({"task_index": index, "task": text})


@pytest.mark.parametrize(
    ("table", "needle"),
    [
        (
            _tasks(pa.array(["0", "1"]), pa.array(["turn", "approach"])),
            "field 'task_index': wrong type string (expected integers)",
        ),
        (
            _tasks(pa.array([0, None], type=pa.int64()), pa.array(["turn", "approach"])),
            "row 1, field 'task_index': missing value (null)",
        ),
        (
            _tasks(pa.array([0, 0]), pa.array(["turn", "approach"])),
            "task_index 0 appears twice",
        ),
        (
            _tasks(pa.array([0, 1]), pa.array(["turn", None])),
            "missing task text (null)",
        ),
        (pa.table({"task_index": pa.array([0, 1])}), "text column 'task'"),
    ],
)
def test_bad_tasks_tables(complex_folder: Path, table: pa.Table, needle: str) -> None:
    pq.write_table(table, complex_folder / TASKS)
    _refused(complex_folder, str(complex_folder / TASKS), needle)


def test_a_task_index_missing_from_the_tasks_is_refused(complex_folder: Path) -> None:
    pq.write_table(_tasks(pa.array([0]), pa.array(["turn"])), complex_folder / TASKS)
    line = _refused(complex_folder, str(complex_folder / DATA), "task_index 1 is not in")
    assert "episode 0" in line and "field 'task_index'" in line


def test_missing_tasks_file_is_refused(complex_folder: Path) -> None:
    (complex_folder / TASKS).unlink()
    _refused(complex_folder, "no meta/tasks.parquet")


def test_the_complex_folder_still_imports(complex_folder: Path) -> None:
    ds = import_lerobot(complex_folder)
    assert ds.behavior is not None and set(ds.behavior.tolist()) == {"turn", "approach"}


# -- 7. absurd angles -------------------------------------------------------------------------


def test_an_absurd_angle_is_refused_not_wrapped(folder: Path) -> None:
    table = pq.read_table(folder / DATA)
    state = np.stack(table.column("observation.state").to_pylist())
    state[23, 2] = 1e9  # episode 1 starts at row 20
    flat = pa.array(state.astype(np.float32).ravel())
    _edit_table(
        folder / DATA, _replace("observation.state", pa.FixedSizeListArray.from_arrays(flat, 4))
    )
    line = _refused(folder, str(folder / DATA), "episode 1, row 3", "absurd angle 1e+09 deg")
    assert "±36000 deg" in line and "field 'angle (observation.state:angle)'" in line


def test_an_angle_in_range_is_still_wrapped(folder: Path) -> None:
    table = pq.read_table(folder / DATA)
    state = np.stack(table.column("observation.state").to_pylist())
    state[0, 2] = 720.0 + 30.0
    flat = pa.array(state.astype(np.float32).ravel())
    _edit_table(
        folder / DATA, _replace("observation.state", pa.FixedSizeListArray.from_arrays(flat, 4))
    )
    ds = import_lerobot(folder)
    assert ds.sensors[0, 2] == pytest.approx(30.0)


# -- 8. deep nesting --------------------------------------------------------------------------


@pytest.mark.parametrize("rel", [INFO, OURS])
def test_deep_nesting_is_refused(folder: Path, rel: str) -> None:
    (folder / rel).write_text('{"metadata": ' + "[" * 100_000 + "]" * 100_000 + "}")
    _refused(folder, str(folder / rel), "nested more than 32 levels deep")


# -- 9. bounds checked on the Parquet footer before reading ---------------------------------


@pytest.fixture
def no_table_read(monkeypatch: pytest.MonkeyPatch) -> None:
    def read(*args: object, **kwargs: object) -> None:
        raise AssertionError("a table was read before its footer was checked")

    monkeypatch.setattr(pq.ParquetFile, "read", read)


def test_too_many_frames_are_refused_from_the_footer(folder: Path, no_table_read: None) -> None:
    """3 M frames of constants: a small file (RLE), refused before reading."""
    n = 1_000_000
    one = pa.array(np.zeros(n, dtype=np.int64))
    state = pa.FixedSizeListArray.from_arrays(pa.array(np.zeros(4 * n, dtype=np.float32)), 4)
    action = pa.FixedSizeListArray.from_arrays(pa.array(np.zeros(2 * n, dtype=np.float32)), 2)
    chunk = pa.table(
        {
            "observation.state": state,
            "action": action,
            "timestamp": pa.array(np.zeros(n, dtype=np.float32)),
            "frame_index": one,
            "episode_index": one,
            "index": one,
            "task_index": one,
        }
    )
    with pq.ParquetWriter(folder / DATA, chunk.schema, compression="zstd") as writer:
        for _ in range(3):
            writer.write_table(chunk, row_group_size=n)
    assert (folder / DATA).stat().st_size < 10 * 2**20
    _refused(
        folder,
        str(folder / DATA),
        "more than 2,000,000 frames (3,000,000 in this one, from its Parquet footer)",
    )


def test_too_many_values_are_refused_from_the_footer(
    folder: Path, no_table_read: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(lerobot, "MAX_READ_VALUES", 100)
    _refused(folder, str(folder / DATA), "this reader takes at most 100 values")


def test_too_many_bytes_are_refused_from_the_footer(
    folder: Path, no_table_read: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(lerobot, "MAX_READ_BYTES", 1000)
    _refused(folder, str(folder / DATA), "row group 0 holds", "uncompressed in the columns read")


def test_too_many_bytes_in_all_files_are_refused_from_the_footers(
    folder: Path, no_table_read: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(lerobot, "MAX_TOTAL_READ_BYTES", 1000)
    _refused(folder, str(folder / DATA), "the data files hold more than 0 MiB uncompressed")


def test_row_groups_are_read_in_bounded_batches(
    folder: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    want = import_lerobot(folder)
    pq.write_table(pq.read_table(folder / DATA), folder / DATA, row_group_size=4)
    monkeypatch.setattr(lerobot, "MAX_READ_BYTES", 2000)
    reads: list[list[int]] = []
    read_row_groups = pq.ParquetFile.read_row_groups

    def spy(self: pq.ParquetFile, groups: list[int], **kwargs: Any) -> pa.Table:
        reads.append(list(groups))
        return read_row_groups(self, groups, **kwargs)

    monkeypatch.setattr(pq.ParquetFile, "read_row_groups", spy)
    got = import_lerobot(folder)
    assert len(reads) > 1 and sorted(g for r in reads for g in r) == list(range(19))
    np.testing.assert_array_equal(got.sensors, want.sensors)
    np.testing.assert_array_equal(got.t, want.t)


def test_an_error_names_the_file_row_past_the_first_batch(
    folder: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    table = pq.read_table(folder / DATA)
    values = table.column("timestamp").to_pylist()
    values[50] = None
    table = _replace("timestamp", pa.array(values, type=pa.float32()))(table)
    pq.write_table(table, folder / DATA, row_group_size=4)
    monkeypatch.setattr(lerobot, "MAX_READ_BYTES", 2000)
    _refused(folder, str(folder / DATA), "row 50, field 'timestamp': missing value (null)")


def test_frames_over_several_files_count_together(
    folder: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    table = pq.read_table(folder / DATA)
    pq.write_table(table.slice(0, 20), folder / DATA)
    pq.write_table(table.slice(20), folder / "data/chunk-000/file-001.parquet")
    assert import_lerobot(folder).n_samples == table.num_rows
    monkeypatch.setattr(lerobot, "MAX_FRAMES", 30)
    _refused(folder, "file-001.parquet", "more than 30 frames")


def test_not_parquet_data_is_refused(folder: Path) -> None:
    (folder / DATA).write_bytes(b"PAR1 not really")
    _refused(folder, str(folder / DATA), "not a Parquet file")


def test_an_empty_data_file_gives_no_frames(folder: Path) -> None:
    _edit_table(folder / DATA, lambda t: t.slice(0, 0))
    _refused(folder, "the data files hold no frames")


# -- 10. special files --------------------------------------------------------------------------


@pytest.mark.parametrize("rel", [DATA, INFO, OURS])
def test_a_fifo_is_refused_not_waited_on(folder: Path, rel: str) -> None:
    (folder / rel).unlink()
    os.mkfifo(folder / rel)
    _refused(folder, str(folder / rel), "a named pipe, not a regular file")


def test_a_fifo_tasks_file_is_refused(complex_folder: Path) -> None:
    (complex_folder / TASKS).unlink()
    os.mkfifo(complex_folder / TASKS)
    _refused(complex_folder, str(complex_folder / TASKS), "a named pipe")


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
@pytest.mark.parametrize("rel", [DATA, INFO, OURS])
def test_a_device_symlink_is_refused(folder: Path, rel: str) -> None:
    (folder / rel).unlink()
    (folder / rel).symlink_to("/dev/zero")
    _refused(folder, str(folder / rel), "a device, not a regular file")


def test_a_symlinked_folder_loop_is_not_followed(folder: Path) -> None:
    (folder / "data" / "loop").symlink_to(folder / "data", target_is_directory=True)
    assert import_lerobot(folder).n_samples == pq.read_metadata(folder / DATA).num_rows


def test_a_folder_named_like_info_json_is_refused(folder: Path) -> None:
    (folder / INFO).unlink()
    (folder / INFO).mkdir()
    _refused(folder, str(folder / INFO), "a folder, not a regular file")


def test_a_file_is_not_a_folder(tmp_path: Path) -> None:
    (tmp_path / "f").write_text("x")
    _refused(tmp_path / "f", "not a folder")


# -- 11. any JSON value or column anywhere: a Dataset or one of our errors -------------------

JSON = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(min_value=-(10**20), max_value=10**20)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=6),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4)
    ),
    max_leaves=10,
)

_DELETE = object()


def _paths(doc: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [prefix]
    if isinstance(doc, dict):
        for key, value in doc.items():
            out += _paths(value, (*prefix, key))
    elif isinstance(doc, list):
        for i, value in enumerate(doc):
            out += _paths(value, (*prefix, i))
    return out


def _import_safely(folder: Path) -> None:
    """A Dataset or DatasetError / ConfigError; a numpy warning counts as a failure."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.simplefilter("ignore", DataImportWarning)
        try:
            import_lerobot(folder)
        except (DatasetError, ConfigError) as err:
            assert "\n" not in str(err)


@settings(
    max_examples=50,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(data=st.data())
def test_any_json_value_anywhere_gives_a_dataset_or_our_error(
    base_complex: Path, base: Path, data: st.DataObject
) -> None:
    source = data.draw(st.sampled_from([base, base_complex]))
    rel = data.draw(st.sampled_from([INFO, OURS]))
    doc = json.loads((source / rel).read_text())
    where = data.draw(st.sampled_from(_paths(doc)))
    value = data.draw(st.one_of(JSON, st.just(_DELETE)) if where else JSON)
    if not where:
        doc = value
    else:
        node = doc
        for key in where[:-1]:
            node = node[key]
        if value is _DELETE:
            del node[where[-1]]
        else:
            node[where[-1]] = value
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(shutil.copytree(source, Path(tmp) / "lr"))
        (folder / rel).write_text(json.dumps(doc))
        _import_safely(folder)


def _arrays(n: int) -> st.SearchStrategy[pa.Array]:
    ints = st.one_of(st.none(), st.integers(min_value=-(2**63), max_value=2**63 - 1))
    floats = st.one_of(st.none(), st.floats(width=32))
    texts = st.one_of(st.none(), st.text(max_size=3))
    vectors = st.one_of(st.none(), st.lists(st.floats(width=32), min_size=0, max_size=5))
    return st.one_of(
        st.lists(ints, min_size=n, max_size=n).map(lambda v: pa.array(v, type=pa.int64())),
        st.lists(floats, min_size=n, max_size=n).map(lambda v: pa.array(v, type=pa.float32())),
        st.lists(texts, min_size=n, max_size=n).map(lambda v: pa.array(v, type=pa.string())),
        st.lists(st.booleans(), min_size=n, max_size=n).map(pa.array),
        st.lists(vectors, min_size=n, max_size=n).map(
            lambda v: pa.array(v, type=pa.list_(pa.float32()))
        ),
        st.integers(min_value=0, max_value=2**20).map(
            lambda v: pa.array(np.full(n, v, dtype=np.uint64))
        ),
    )


@settings(
    max_examples=50,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(data=st.data())
def test_any_column_values_give_a_dataset_or_our_error(
    base_complex: Path, base: Path, data: st.DataObject
) -> None:
    source = data.draw(st.sampled_from([base, base_complex]))
    rel = data.draw(st.sampled_from([DATA, TASKS]))
    table = pq.read_table(source / rel)
    name = data.draw(st.sampled_from(table.column_names))
    array = data.draw(_arrays(table.num_rows))
    table = table.set_column(table.schema.get_field_index(name), name, array)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(shutil.copytree(source, Path(tmp) / "lr"))
        pq.write_table(table, folder / rel)
        _import_safely(folder)
