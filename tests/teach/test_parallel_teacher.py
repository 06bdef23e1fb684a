"""The parallel teacher (thesis 7.2): turn to the object while driving to it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from behavior_hmm.data import Dataset
from behavior_hmm.data._parquet import read as read_parquet
from behavior_hmm.data._parquet import write as write_parquet
from behavior_hmm.errors import ConfigError, DatasetError
from behavior_hmm.teach import collect
from behavior_hmm.teach import test_starts as shipped_starts
from behavior_hmm.teach._behaviors import BehaviorSpec, behavior_spec
from behavior_hmm.teach._demonstrator import TeacherConfig


def _blocks(tags: np.ndarray) -> list[str]:
    """The tags of an episode, each run of equal tags once, in order."""
    return [str(t) for i, t in enumerate(tags) if i == 0 or t != tags[i - 1]]


def test_it_turns_while_it_drives_and_beats_the_sequential_teacher() -> None:
    start = {"angle": 140.0, "distance": 0.7}
    parallel = collect("turn-approach-parallel", [start], sim="kinematic")
    sequential = collect("turn-approach", [start], sim="kinematic")
    tags = np.asarray(parallel.behavior)
    assert _blocks(tags) == ["turn", "turn+approach", "approach"]
    angle = parallel.columns(["angle"])[:, 0]
    both = tags == "turn+approach"
    # the drive starts once the bearing is within the parallel angle, not before
    assert abs(angle[np.argmax(both)]) <= TeacherConfig().parallel_angle
    assert abs(angle[np.argmax(both) - 1]) > TeacherConfig().parallel_angle
    left, right = parallel.commands[:, 0], parallel.commands[:, 1]
    common, differential = (left + right) / 2, (right - left) / 2
    overlap = both & (np.abs(differential) > 0.1) & (common > 0.1)
    assert overlap.sum() > 0.5 * both.sum()  # turning and driving forward at once
    # it reaches both goals, sooner than turning first and approaching after
    final = parallel.columns(["angle", "distance"])[-1]
    assert abs(final[0]) <= 3.0 and final[1] <= 0.01
    assert parallel.n_samples < 0.9 * sequential.n_samples
    # the sequential teacher never runs the two at once
    assert "turn+approach" not in set(np.asarray(sequential.behavior).tolist())


def test_every_start_of_the_grid_and_the_test_starts_reaches_its_goal() -> None:
    data = collect("turn-approach-parallel", sim="kinematic")  # raises on a missed goal
    assert len(data) == len(behavior_spec("turn-approach-parallel").train_starts())
    assert set(data.behaviors) == {"turn", "approach", "turn+approach"}
    starts = shipped_starts("turn-approach-parallel")
    tests = collect("turn-approach-parallel", starts, sim="kinematic")
    assert len(tests) == 15


def test_pair_tags_are_part_of_the_data_contract(tmp_path: Path) -> None:
    data = collect("turn-approach-parallel", [{"angle": -60.0, "distance": 0.4}], sim="kinematic")
    path = tmp_path / "parallel.parquet"
    write_parquet(data, path)
    back = read_parquet(path)
    assert np.array_equal(np.asarray(back.behavior), np.asarray(data.behavior))
    for bad in ("turn+", "turn+approach+grasp", "Turn+approach"):
        columns = data.to_columns()
        columns["behavior"] = np.asarray(columns["behavior"]).copy()
        columns["behavior"][3] = bad
        with pytest.raises(DatasetError, match="invalid behavior name"):
            Dataset(columns, data.metadata)


def test_a_parallel_behavior_needs_two_components_and_the_angle_a_range() -> None:
    spec = behavior_spec("turn-approach-parallel")
    assert spec.parallel and spec.components == ("turn", "approach")
    with pytest.raises(ConfigError, match="two components"):
        BehaviorSpec(
            "solo",
            {"angle": 0.0},
            spec.phases,
            spec.train_starts,
            components=("turn",),
            parallel=True,
        )
    for angle in (0.0, 90.0, 120.0):
        with pytest.raises(ConfigError, match="parallel_angle"):
            TeacherConfig(parallel_angle=angle)
