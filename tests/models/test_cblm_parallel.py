"""CBLM(parallel=True): run two components at once where the teacher did (thesis 7.2)."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest

from behavior_hmm.data import Dataset
from behavior_hmm.errors import DatasetError, ModelFileError
from behavior_hmm.models import CBLM, SBLM
from behavior_hmm.models import load as load_model
from behavior_hmm.sim import make_env
from behavior_hmm.teach import collect

GRID = [
    {"angle": float(a), "distance": d}
    for a in range(-160, 161, 40)
    if a
    for d in (0.2, 0.4, 0.6, 0.8)
]
START = {"angle": 110.0, "distance": 0.65}


@pytest.fixture(scope="module")
def components(turn_model: SBLM) -> list[SBLM]:
    approach = SBLM(inputs=("distance", "angle"), epochs=60, random_state=0).fit(
        collect("approach", sim="kinematic")
    )
    return [turn_model, approach]


@pytest.fixture(scope="module")
def parallel_data() -> Dataset:
    return collect("turn-approach-parallel", GRID, sim="kinematic")


@pytest.fixture(scope="module")
def model(components: list[SBLM], parallel_data: Dataset) -> CBLM:
    return CBLM(components, inputs=("distance", "angle")).fit(parallel_data)


def test_it_learns_where_the_teacher_ran_both_and_each_ones_command(model: CBLM) -> None:
    assert model.names_ == ["turn", "approach"]
    assert set(np.unique(model.parallel_).tolist()) == {-1, 1}  # approach beside turn
    assert 0.2 < np.mean(model.parallel_ >= 0) < 0.9
    turn, approach = model.directions_  # unit vectors (their sign does not matter)
    assert abs(turn @ np.array([-1.0, 1.0])) / 2**0.5 > 0.999  # the wheels' difference
    assert abs(approach @ np.array([1.0, 1.0])) / 2**0.5 > 0.999  # their sum


def test_it_turns_while_it_drives_and_arrives_sooner(model: CBLM, tmp_path: Path) -> None:
    both = model.generate(make_env("kinematic"), START)
    model.save(tmp_path / "m.bhmm")
    one_at_a_time = load_model(tmp_path / "m.bhmm")
    one_at_a_time.parallel = False
    alone = one_at_a_time.generate(make_env("kinematic"), START)
    for trace in (both, alone):
        assert trace.goal_reached and trace.reason == "goal"
    labels = np.asarray(both.component)
    paired = labels == "turn+approach"
    assert paired.sum() > 50 and "turn+approach" not in set(np.asarray(alone.component))
    commands = both.command_array
    left, right = commands[paired, 0], commands[paired, 1]
    assert np.mean(((left + right) / 2 > 0.2) & (np.abs(right - left) / 2 > 0.05)) > 0.5
    assert len(labels) < 0.92 * len(alone.component)
    # the hand-over keeps the approach running: no stop between turning and approaching
    last = int(np.flatnonzero(paired)[-1])
    assert labels[last + 1] == "approach"
    assert np.all(commands[last - 5 : last + 20].sum(axis=1) > 0.5)


def test_files_keep_what_it_learned_and_refuse_a_bad_partner(
    model: CBLM, components: list[SBLM], tmp_path: Path
) -> None:
    path = tmp_path / "parallel.bhmm"
    model.save(path)
    back = load_model(path)
    assert np.array_equal(back.parallel_, model.parallel_)
    assert np.array_equal(back.directions_, model.directions_)
    # a model of sequential demonstrations stores nothing of it: its file as before
    sequential = CBLM(components, inputs=("distance", "angle")).fit(
        collect("turn-approach", GRID[:8], sim="kinematic")
    )
    sequential.save(tmp_path / "sequential.bhmm")
    with zipfile.ZipFile(tmp_path / "sequential.bhmm") as zf:
        assert not any("parallel" in name for name in zf.namelist())
    assert (load_model(tmp_path / "sequential.bhmm").parallel_ == -1).all()
    bad = model.parallel_.copy()
    bad[0] = 2  # no component 2
    model.parallel_, kept = bad, model.parallel_
    try:
        model.save(tmp_path / "bad.bhmm")
    finally:
        model.parallel_ = kept
    with pytest.raises(ModelFileError, match="parallel must name a component"):
        load_model(tmp_path / "bad.bhmm")


def test_a_pair_tag_must_name_two_components(
    components: list[SBLM], parallel_data: Dataset
) -> None:
    for bad in ("turn+grasp", "turn+turn"):
        columns = parallel_data.to_columns()
        tags = np.asarray(columns["behavior"]).astype(object)
        tags[tags == "turn+approach"] = bad
        columns["behavior"] = tags
        with pytest.raises(DatasetError, match="not a component or two at once"):
            CBLM(components, inputs=("distance", "angle")).fit(
                Dataset(columns, parallel_data.metadata)
            )


def test_the_plans_component_runs_beside_the_one_that_pre_empts_it(model: CBLM) -> None:
    from behavior_hmm.models._policy import make_policy

    policy = make_policy(model, None)
    assert policy._pairs == {(0, 1)}  # approach ran beside turn; never the other way round
    # a category that asks for no partner (an aligned approach's start, where the plan says
    # approach and the bearing gap makes turn pre-empt it): approach runs beside turn only
    # when pre-emption asked for it (``_wanted``)
    policy._partners = np.full_like(policy._partners, -1)
    reading = {"angle": 9.0, "distance": 0.15, "linear_velocity": 0.0, "angular_velocity": 0.0}
    policy._now = {"angle": 9.0, "distance": 0.15}
    turn = policy._children[0]
    turn.renew({"angle": 0.0}, 1.0)
    turn.reset()
    policy._active, policy._child = 0, turn
    out = turn.step(reading)
    assert policy._with_beside(out, reading, 0) is out and policy._beside == -1
    policy._wanted = 1
    fused = policy._with_beside(out, reading, 0)
    assert policy._beside == 1 and fused.component == "turn+approach"
