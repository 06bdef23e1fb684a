"""LeRobot datasets (v3.0 layout): export, the files LeRobot reads, import, round trips."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from behavior_hmm.data import (
    SENSOR_CHANNELS,
    Dataset,
    SamplingWarning,
    export_lerobot,
    import_lerobot,
)
from behavior_hmm.errors import ConfigError, DatasetError
from behavior_hmm.teach import collect


@pytest.fixture(scope="module")
def turn_demos() -> Dataset:
    starts = [{"angle": a, "distance": 0.5} for a in (-120.0, -40.0, 60.0, 150.0)]
    return collect("turn", starts, sim="kinematic", seed=0)


@pytest.fixture(scope="module")
def complex_demos() -> Dataset:
    starts = [{"angle": a, "distance": 0.4} for a in (-90.0, 45.0)]
    return collect("turn-approach", starts, sim="kinematic", seed=0)


def _same_episodes(got: Dataset, want: Dataset) -> None:
    assert len(got) == len(want)
    assert got.lengths.tolist() == want.lengths.tolist()
    assert got.episode_ids.tolist() == want.episode_ids.tolist()
    np.testing.assert_allclose(got.t, want.t, atol=1e-9)
    # float32 in the LeRobot files
    np.testing.assert_allclose(got.sensors, want.sensors, rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(got.commands, want.commands, rtol=1e-6, atol=1e-6)


def test_export_then_import_gives_the_same_episodes(turn_demos: Dataset, tmp_path: Path) -> None:
    folder = export_lerobot(turn_demos, tmp_path / "turn")
    back = import_lerobot(folder)
    _same_episodes(back, turn_demos)
    md = back.metadata
    assert md["behavior"] == "turn" and md["seed"] == 0
    assert md["source"]["format"] == "lerobot" and md["source"]["codebase_version"] == "v3.0"


def test_complex_demonstrations_keep_their_sub_behaviors(
    complex_demos: Dataset, tmp_path: Path
) -> None:
    back = import_lerobot(export_lerobot(complex_demos, tmp_path / "ta"))
    _same_episodes(back, complex_demos)
    assert back.behavior is not None and complex_demos.behavior is not None
    assert back.behavior.tolist() == complex_demos.behavior.tolist()


def test_odd_episode_ids_and_start_times_survive(turn_demos: Dataset, tmp_path: Path) -> None:
    cols = turn_demos.to_columns()
    cols["episode"] = cols["episode"] * 7 + 3
    cols["t"] = cols["t"] + 12.5
    ds = Dataset(cols, turn_demos.metadata)
    back = import_lerobot(export_lerobot(ds, tmp_path / "odd"))
    _same_episodes(back, ds)


def test_the_layout_is_lerobot_v3(complex_demos: Dataset, tmp_path: Path) -> None:
    root = export_lerobot(complex_demos, tmp_path / "ta", task="ignored: sub-behaviors")
    info = json.loads((root / "meta" / "info.json").read_text())
    assert info["codebase_version"] == "v3.0"
    assert info["fps"] == 62.5
    assert info["total_episodes"] == len(complex_demos)
    assert info["total_frames"] == complex_demos.n_samples
    assert info["total_tasks"] == 2 and info["splits"] == {"train": "0:2"}
    assert info["data_path"] == "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
    features = info["features"]
    assert features["observation.state"] == {
        "dtype": "float32",
        "shape": [4],
        "names": list(SENSOR_CHANNELS),
    }
    assert features["action"]["names"] == ["left", "right"]
    for name in ("timestamp", "frame_index", "episode_index", "index", "task_index"):
        assert features[name]["shape"] == [1]

    data = pq.read_table(root / "data" / "chunk-000" / "file-000.parquet")
    assert data.column_names == list(features)
    assert data.schema.field("observation.state").type == pa.list_(pa.float32(), 4)
    n0 = int(complex_demos.lengths[0])
    assert data.column("frame_index").to_pylist()[: n0 + 1] == [*range(n0), 0]
    assert data.column("index").to_pylist() == list(range(complex_demos.n_samples))
    ts = data.column("timestamp").to_numpy()
    np.testing.assert_allclose(np.diff(ts[:n0]), 0.016, atol=1e-4)  # LeRobot's tolerance

    episodes = pq.read_table(root / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    rows = episodes.to_pylist()
    assert [r["length"] for r in rows] == complex_demos.lengths.tolist()
    assert [r["dataset_from_index"] for r in rows] == complex_demos.offsets[:-1].tolist()
    assert [r["dataset_to_index"] for r in rows] == complex_demos.offsets[1:].tolist()
    assert rows[0]["tasks"] == ["turn", "approach"]
    assert rows[0]["stats/action/count"] == [n0]
    assert len(rows[0]["stats/observation.state/mean"]) == 4

    tasks = pq.read_table(root / "meta" / "tasks.parquet")
    assert tasks.column("task").to_pylist() == ["turn", "approach"]
    pandas_md = json.loads(tasks.schema.metadata[b"pandas"])
    assert pandas_md["index_columns"] == ["task"]  # pandas reads the task text as the index

    stats = json.loads((root / "meta" / "stats.json").read_text())
    assert set(stats) == set(features)
    assert set(stats["action"]) >= {"min", "max", "mean", "std", "count"}
    assert stats["observation.state"]["count"] == [complex_demos.n_samples]


def test_a_simple_dataset_has_one_task(turn_demos: Dataset, tmp_path: Path) -> None:
    root = export_lerobot(turn_demos, tmp_path / "t", task="turn toward the object")
    tasks = pq.read_table(root / "meta" / "tasks.parquet")
    assert tasks.column("task").to_pylist() == ["turn toward the object"]
    data = pq.read_table(root / "data" / "chunk-000" / "file-000.parquet")
    assert set(data.column("task_index").to_pylist()) == {0}


def test_irregular_time_steps_are_refused_and_nothing_is_left(
    turn_demos: Dataset, tmp_path: Path
) -> None:
    cols = turn_demos.to_columns()
    cols["t"][5:] += 0.004
    ds = Dataset(cols)
    with pytest.raises(DatasetError, match=r"not regular.*resample") as info:
        export_lerobot(ds, tmp_path / "out")
    assert info.value.episode == 0 and info.value.row == 5
    assert list(tmp_path.iterdir()) == []


def test_a_folder_that_is_not_empty_is_refused(turn_demos: Dataset, tmp_path: Path) -> None:
    folder = tmp_path / "full"
    folder.mkdir()
    (folder / "keep.txt").write_text("mine")
    with pytest.raises(DatasetError, match="not an empty folder"):
        export_lerobot(turn_demos, folder)
    assert [p.name for p in folder.iterdir()] == ["keep.txt"]
    empty = tmp_path / "empty"
    empty.mkdir()
    assert import_lerobot(export_lerobot(turn_demos, empty)).n_samples == turn_demos.n_samples


def _foreign(root: Path, fps: int = 50) -> Path:
    """A dataset another LeRobot user recorded: their names, radians, 50 fps, no ours."""
    (root / "meta" / "episodes" / "chunk-000").mkdir(parents=True)
    (root / "data" / "chunk-000").mkdir(parents=True)
    lengths = [40, 55]
    state, action, ts, frame, ep = [], [], [], [], []
    for e, n in enumerate(lengths):
        k = np.arange(n)
        bearing = np.radians(90.0 - 1.5 * k) * (1 if e == 0 else -1)
        state.append(np.stack([bearing, np.full(n, 0.4), np.zeros(n)], axis=1))
        action.append(np.tile([-1.0, 1.0] if e == 0 else [1.0, -1.0], (n, 1)))
        ts.append(k / fps)
        frame.append(k)
        ep.append(np.full(n, e))
    s = np.concatenate(state).astype(np.float32)
    a = np.concatenate(action).astype(np.float32)
    table = pa.table(
        {
            "observation.state": pa.FixedSizeListArray.from_arrays(pa.array(s.ravel()), 3),
            "action": pa.FixedSizeListArray.from_arrays(pa.array(a.ravel()), 2),
            "timestamp": pa.array(np.concatenate(ts).astype(np.float32)),
            "frame_index": pa.array(np.concatenate(frame)),
            "episode_index": pa.array(np.concatenate(ep)),
            "index": pa.array(np.arange(sum(lengths))),
            "task_index": pa.array(np.zeros(sum(lengths), dtype=np.int64)),
        }
    )
    pq.write_table(table, root / "data" / "chunk-000" / "file-000.parquet")
    info = {
        "codebase_version": "v3.0",
        "fps": fps,
        "features": {
            "observation.state": {
                "dtype": "float32",
                "shape": [3],
                "names": {"motors": ["bearing", "range", "yaw_rate"]},
            },
            "action": {"dtype": "float32", "shape": [2], "names": ["wl", "wr"]},
            "timestamp": {"dtype": "float32", "shape": [1], "names": None},
            "frame_index": {"dtype": "int64", "shape": [1], "names": None},
            "episode_index": {"dtype": "int64", "shape": [1], "names": None},
            "index": {"dtype": "int64", "shape": [1], "names": None},
            "task_index": {"dtype": "int64", "shape": [1], "names": None},
        },
    }
    (root / "meta" / "info.json").write_text(json.dumps(info))
    return root


FOREIGN_MAP = {
    "angle": "observation.state:bearing",
    "distance": "observation.state:1",
    "angular_velocity": "observation.state:yaw_rate",
    "left": "action:wl",
    "right": "action:1",
}


def test_a_foreign_dataset_imports_with_a_mapping(tmp_path: Path) -> None:
    root = _foreign(tmp_path / "theirs")
    kw = {"mapping": FOREIGN_MAP, "units": {"angle": "rad", "angular_velocity": "rad/s"}}
    with pytest.warns(SamplingWarning, match="20 ms"):
        raw = import_lerobot(root, derive="linear_velocity", **kw)  # type: ignore[arg-type]
    assert raw.lengths.tolist() == [40, 55]
    np.testing.assert_allclose(raw.episode(0).channel("angle")[:3], [90.0, 88.5, 87.0], atol=1e-4)
    np.testing.assert_allclose(raw.t[:3], [0.0, 0.02, 0.04])  # snapped onto frame_index / fps
    ds = import_lerobot(root, derive="linear_velocity", resample=True, **kw)  # type: ignore[arg-type]
    np.testing.assert_allclose(np.diff(ds.episode(0).t), 0.016, atol=1e-12)
    assert ds.metadata["source"]["mapping"]["right"] == "action:1"


@pytest.mark.parametrize(
    ("mapping", "match"),
    [
        ({}, "no feature for channel.*distance"),
        ({**FOREIGN_MAP, "angle": "observation.state:heading"}, "no element 'heading'"),
        ({**FOREIGN_MAP, "angle": "observation.state"}, "vector of 3; name an element"),
        ({**FOREIGN_MAP, "angle": "observation.bearing"}, "no feature 'observation.bearing'"),
        ({**FOREIGN_MAP, "anlge": "action:0"}, "did you mean 'angle'"),
        ({**FOREIGN_MAP, "angle": "timestamp:0"}, "scalar"),
    ],
)
def test_bad_mappings(tmp_path: Path, mapping: dict[str, str], match: str) -> None:
    root = _foreign(tmp_path / "theirs")
    with pytest.raises(ConfigError, match=match):
        import_lerobot(root, mapping=mapping, derive="linear_velocity")


def test_not_a_lerobot_dataset(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match=r"no meta/info\.json"):
        import_lerobot(tmp_path)
    with pytest.raises(DatasetError, match="no such folder"):
        import_lerobot(tmp_path / "nope")
