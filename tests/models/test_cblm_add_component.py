"""``CBLM.add_component`` (issue 29, thesis 7.1): a new behavior joins a fitted CBLM.

A turn-approach CBLM gains retreat from "position" demonstrations (turn, then back away
to 1 m) alone; no component is retrained and the turn-approach demonstrations are not
used again.
"""

from __future__ import annotations

import copy
import io
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from behavior_hmm.data import Dataset
from behavior_hmm.data._channels import CHANNELS
from behavior_hmm.errors import ConfigError, DatasetError, NotFittedError
from behavior_hmm.hmm import BehaviorHMM
from behavior_hmm.models import CBLM, SBLM
from behavior_hmm.teach import collect

ANGLES = [float(a) for a in range(-160, 181, 40)]
#: starts of the old task (turn, then approach to the object; from its demonstrations)
OLD_STARTS = [
    {"angle": a, "distance": d} for a in (-160.0, -80.0, 0.0, 40.0, 120.0) for d in (0.2, 0.5, 0.8)
]
OLD_STARTS += [{"angle": a, "distance": 0.0} for a in (-120.0, 80.0)]
#: starts of the new one (turn, then back away to 1 m; from its demonstrations)
NEW_STARTS = [
    {"angle": a, "distance": d} for a in (-120.0, -40.0, 0.0, 40.0, 120.0) for d in (0.1, 0.4)
]
NEW_GOAL = {"distance": 1.0}
COUNTS = ("A_counts_", "B_counts_", "C_counts_", "pi_counts_", "start_counts_")


def _retagged(dataset: Dataset, behavior: str) -> Dataset:
    episodes = [ep.to_dict() for ep in dataset.episodes()]
    return Dataset.from_episodes(episodes, metadata={**dataset.metadata, "behavior": behavior})


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    d = tmp_path_factory.mktemp("add_component")
    turn = SBLM(inputs=("angle",), epochs=60).fit(
        collect("turn", [{"angle": a} for a in range(-170, 181, 20)], sim="kinematic")
    )
    approach = SBLM(inputs=("distance", "angle"), epochs=60).fit(
        collect("approach", [{"distance": x} for x in np.arange(0.1, 1.01, 0.1)], sim="kinematic")
    )
    retreat = SBLM(inputs=("distance", "angle"), epochs=60).fit(
        collect(
            "retreat",
            [{"distance": x, "goal_distance": 1.0} for x in np.arange(0.0, 0.91, 0.1)],
            sim="kinematic",
        )
    )
    for name, model in (("turn", turn), ("approach", approach), ("retreat", retreat)):
        model.save(d / f"{name}.bhmm")
    starts = [{"angle": a, "distance": x} for a in ANGLES for x in (0.2, 0.5, 0.8)]
    starts += [{"angle": 0.0, "distance": x} for x in (0.2, 0.5, 0.8)]
    starts += [{"angle": a, "distance": 0.0} for a in ANGLES]
    old_data = collect("turn-approach", starts, sim="kinematic")
    old = CBLM([SBLM.load(d / "turn.bhmm"), SBLM.load(d / "approach.bhmm")]).fit(old_data)
    old.save(d / "old.bhmm")
    starts = [{**s, "goal_distance": 1.0} for s in NEW_STARTS]
    starts += [{"angle": a, "distance": 0.7, "goal_distance": 1.0} for a in ANGLES]
    new_data = collect("position", starts, sim="kinematic")
    updated = CBLM.load(d / "old.bhmm").add_component(
        SBLM.load(d / "retreat.bhmm"), new_data, source="new.parquet"
    )
    updated.save(d / "updated.bhmm")
    return {"dir": d, "old_data": old_data, "new_data": new_data, "updated": updated}


def _embedded(path: Path, index: int) -> bytes:
    """The bytes of component ``index`` as the model file embeds them."""
    with zipfile.ZipFile(path) as archive:
        arrays = np.load(io.BytesIO(archive.read("arrays.npz")), allow_pickle=False)
        return bytes(arrays[f"component.{index}"].tobytes())


def test_components_are_byte_identical(setup: dict[str, Any]) -> None:
    d = setup["dir"]
    files = [(d / f"{n}.bhmm").read_bytes() for n in ("turn", "approach", "retreat")]
    for i in range(2):
        assert _embedded(d / "old.bhmm", i) == files[i]
    for i in range(3):
        assert _embedded(d / "updated.bhmm", i) == files[i]
    loaded = CBLM.load(d / "updated.bhmm")
    assert loaded.names_ == ["turn", "approach", "retreat"]
    for i, model in enumerate(loaded.components_):
        model.save(d / f"again.{i}.bhmm")
        assert (d / f"again.{i}.bhmm").read_bytes() == files[i]


def test_tables_are_old_counts_plus_the_new_episodes(setup: dict[str, Any]) -> None:
    d, new, updated = setup["dir"], setup["new_data"], setup["updated"]
    old = CBLM.load(d / "old.bhmm")
    assert updated.hmm_.n_states_ == 3
    k_old, k_new = old.observations_.n_categories_, updated.observations_.n_categories_
    assert k_new > k_old
    # every old category keeps its index: won again (count up, prototype moved) or not
    grew = updated.observations_.counts_[:k_old] - old.observations_.counts_
    assert np.all(grew >= 0)
    still = grew == 0
    np.testing.assert_array_equal(
        updated.observations_.prototypes_[:k_old][still], old.observations_.prototypes_[still]
    )
    np.testing.assert_array_equal(updated.observations_.dcm_scale_, old.observations_.dcm_scale_)
    assert old.pipeline_.to_dict() == updated.pipeline_.to_dict()
    # the new episodes, counted alone on the grown categories
    index = {"turn": 0, "approach": 1, "retreat": 2}
    states = np.array([index[t] for t in new.behavior])
    labels = updated.observations_.predict(updated.pipeline_.transform(new), new.lengths)
    counted = BehaviorHMM(n_states=3, n_observations=k_new, counting=updated.counting).fit(
        states, labels, new.lengths
    )
    for name in COUNTS:
        before = _dense(getattr(old.hmm_, name))
        grown = np.zeros_like(_dense(getattr(counted, name)))
        grown[tuple(slice(0, n) for n in before.shape)] = before
        expected = grown + _dense(getattr(counted, name))
        np.testing.assert_array_equal(_dense(getattr(updated.hmm_, name)), expected)
    a = np.exp(updated.hmm_.log_A_)
    assert a[0, 1] > 0 and a[0, 2] > 0  # turn hands over to approach and to retreat
    assert a[1, 2] == 0 and a[2, 1] == 0  # never approach and retreat in one episode


def test_derived_attributes(setup: dict[str, Any]) -> None:
    d, new, updated = setup["dir"], setup["new_data"], setup["updated"]
    old = CBLM.load(d / "old.bhmm")
    assert old.behavior_ == "turn-approach" and updated.behavior_ == "position"
    np.testing.assert_array_equal(updated.effects_[:2], old.effects_)
    assert updated.effects_.shape == (3, 2)
    assert updated.effects_[2, 0] > 0  # retreat raises the distance
    assert updated.rest_values_ == old.rest_values_
    assert updated.default_goal_ == old.default_goal_ == {"angle": 0.0, "distance": 0.0}
    peak = float(np.max(np.abs(new.commands)))
    assert updated.command_scale_ == max(old.command_scale_, peak)
    np.testing.assert_array_equal(updated.command_scales_, np.maximum(old.command_scales_, peak))
    assert updated.delta_scale_ >= old.delta_scale_
    assert updated.handover_cycles_ == old.handover_cycles_ > 0
    steps = max(old.max_steps_, 2 * int(new.lengths.max()))
    assert updated.max_steps_ == max(steps, sum(c.max_steps_ for c in updated.components_))
    assert updated.provenance_ == old.provenance_
    assert updated.get_params() == {**old.get_params(), "components": updated.components_}
    (record,) = updated.updates_
    assert record["component"] == "retreat" and record["source"] == "new.parquet"
    assert record["episodes"] == len(new) and record["rows"] == new.n_samples
    assert record["env"] == "kinematic"
    assert record["new_observations"] == (
        updated.observations_.n_categories_ - old.observations_.n_categories_
    )
    assert old.updates_ == []
    with zipfile.ZipFile(d / "old.bhmm") as archive:  # a CBLM never updated: no record
        assert b'"updates"' not in archive.read("model.json")


def test_save_load_round_trip(setup: dict[str, Any], kinematic_env: Any) -> None:
    d, updated = setup["dir"], setup["updated"]
    loaded = CBLM.load(d / "updated.bhmm")
    assert loaded.updates_ == updated.updates_
    assert loaded.behavior_ == updated.behavior_
    assert loaded.max_steps_ == updated.max_steps_
    np.testing.assert_array_equal(loaded.effects_, updated.effects_)
    np.testing.assert_array_equal(loaded.command_scales_, updated.command_scales_)
    start = {"angle": -40.0, "distance": 0.4}
    a = updated.generate(kinematic_env, start=start, goal=NEW_GOAL, seed=2, max_steps=400)
    b = loaded.generate(kinematic_env, start=start, goal=NEW_GOAL, seed=2, max_steps=400)
    np.testing.assert_array_equal(a.command_array, b.command_array)
    # demonstrations of the new component alone keep the composed behavior's name
    again = CBLM.load(d / "old.bhmm")
    alone = collect(
        "retreat", [{"distance": x, "goal_distance": 1.0} for x in (0.1, 0.4)], sim="kinematic"
    )
    again.add_component(SBLM.load(d / "retreat.bhmm"), alone)
    assert again.behavior_ == "turn-approach" and again.names_[-1] == "retreat"
    assert "source" not in again.updates_[0]


def test_performs_the_new_behavior_and_still_the_old_one(
    setup: dict[str, Any], kinematic_env: Any
) -> None:
    updated = setup["updated"]
    old = CBLM.load(setup["dir"] / "old.bhmm")
    rates = {}
    for label, model, starts, goal in (
        ("old model, old task", old, OLD_STARTS, None),
        ("updated, old task", updated, OLD_STARTS, None),
        ("updated, new task", updated, NEW_STARTS, NEW_GOAL),
    ):
        traces = [model.generate(kinematic_env, start=s, goal=goal, seed=0) for s in starts]
        reached = [t.goal_reached for t in traces]
        rates[label] = f"{sum(reached)}/{len(reached)}"
        assert all(reached), (label, [s for s, r in zip(starts, reached, strict=True) if not r])
        if goal is not None:
            assert all("retreat" in t.component for t in traces)
            assert not any("approach" in t.component for t in traces)
    print("goal reached:", rates)


def test_refusals(setup: dict[str, Any]) -> None:
    d, new = setup["dir"], setup["new_data"]
    turn, retreat = SBLM.load(d / "turn.bhmm"), SBLM.load(d / "retreat.bhmm")
    model = CBLM.load(d / "old.bhmm")
    before = (d / "old.bhmm").read_bytes()
    with pytest.raises(ConfigError, match=r"^turn is already a component"):
        model.add_component(turn, new)
    other_commands = copy.deepcopy(retreat)
    other_commands.command_specs_ = (CHANNELS["left"],)
    with pytest.raises(ConfigError, match=r"^component retreat commands left; the CBLM commands"):
        model.add_component(other_commands, new)
    other_inputs = copy.deepcopy(retreat)
    other_inputs.inputs_ = ("distance", "angular_velocity")
    with pytest.raises(ConfigError, match="reads angular_velocity, which neither"):
        model.add_component(other_inputs, new)
    with pytest.raises(ConfigError, match="fitted SBLM or CBLM"):
        model.add_component(SBLM(), new)
    heading = {"name": "heading", "unit": "deg", "range": [-180.0, 180.0], "wraps": True}
    lacking = Dataset.from_episodes(  # another robot's own channel only: no distance, angle
        [
            {
                "t": ep.t,
                "heading": ep.to_dict()["angle"],
                "left": ep.to_dict()["left"],
                "right": ep.to_dict()["right"],
                "behavior": "retreat",
            }
            for ep in new.episodes()
        ],
        {"channels": [heading]},
    )
    with pytest.raises(ConfigError, match="lack the CBLM's input"):
        model.add_component(retreat, lacking)
    untagged = Dataset.from_episodes(
        [{k: v for k, v in ep.to_dict().items() if k != "behavior"} for ep in new.episodes()],
        metadata=new.metadata,
    )
    with pytest.raises(DatasetError, match="behavior"):
        model.add_component(retreat, untagged)
    turn_only = Dataset.from_episodes(
        [{**ep.to_dict(), "behavior": "turn"} for ep in new.episodes()], metadata=new.metadata
    )
    with pytest.raises(ConfigError, match="never run the new component retreat"):
        model.add_component(retreat, turn_only)
    with pytest.raises(DatasetError, match="'position' is not a component"):
        model.add_component(retreat, _retagged_rows(new, "position"))
    with pytest.raises(ConfigError, match="come from 'mujoco'"):
        model.add_component(retreat, _remetadata(new, env="mujoco"))
    with pytest.raises(ConfigError, match=r"expects a behavior_hmm\.data\.Dataset"):
        model.add_component(retreat, "new.parquet")
    for message in (str(e) for e in _errors(model, retreat, new)):
        assert "\n" not in message
    model.save(d / "check.bhmm")  # nothing changed
    assert (d / "check.bhmm").read_bytes() == before
    with pytest.raises(NotFittedError):
        CBLM([turn]).add_component(retreat, new)


def test_refuses_motion_the_categories_never_saw(setup: dict[str, Any]) -> None:
    """A CBLM of turn fitted at distance 0 saw the distance move by rounding only."""
    d, old_data = setup["dir"], setup["old_data"]
    at_object = old_data.subset(np.flatnonzero(old_data.lengths > 0)[-len(ANGLES) :])
    assert set(at_object.behavior) == {"turn"}
    # its categories told to follow the distance at its rounding's rate: refused
    tiny = {"dcm_scale": [1e-7, 0.05]}
    turn_alone = CBLM([SBLM.load(d / "turn.bhmm")], observation_params=tiny).fit(at_object)
    with pytest.raises(ConfigError, match="barely moved distance"):
        turn_alone.add_component(SBLM.load(d / "approach.bhmm"), old_data)
    assert turn_alone.names_ == ["turn"] and turn_alone.updates_ == []
    # by default an input the demonstrations barely move gets the scale of a still one
    # (STILL_DCM_RATIO), so the approach that moves it can join
    turn_alone = CBLM([SBLM.load(d / "turn.bhmm")]).fit(at_object)
    turn_alone.add_component(SBLM.load(d / "approach.bhmm"), old_data)
    assert turn_alone.names_ == ["turn", "approach"]


def _errors(model: CBLM, retreat: SBLM, new: Dataset) -> list[Exception]:
    caught = []
    for args in ((retreat, _remetadata(new, env="mujoco")), (model.components_[0], new)):
        try:
            model.add_component(*args)
        except ConfigError as err:
            caught.append(err)
    assert len(caught) == 2
    return caught


def _retagged_rows(dataset: Dataset, tag: str) -> Dataset:
    episodes = [{**ep.to_dict(), "behavior": tag} for ep in dataset.episodes()]
    return Dataset.from_episodes(episodes, metadata=dataset.metadata)


def _remetadata(dataset: Dataset, **meta: Any) -> Dataset:
    episodes = [ep.to_dict() for ep in dataset.episodes()]
    return Dataset.from_episodes(episodes, metadata={**dataset.metadata, **meta})


def _dense(table: Any) -> np.ndarray:
    """A count table as a dense array (B and C are sparse)."""
    return np.asarray(table.toarray() if hasattr(table, "toarray") else table)


def test_a_mirrored_cblm_adds_each_new_demonstration_and_its_image(setup: dict[str, Any]) -> None:
    d = setup["dir"]
    parts = [SBLM.load(d / "turn.bhmm"), SBLM.load(d / "approach.bhmm")]
    old_data, new_data = setup["old_data"], setup["new_data"]
    model = CBLM(parts, mirror=True).fit(old_data.subset([0, 1, 2]))
    before = model.hmm_.start_counts_.sum()
    assert before == 6
    model.add_component(SBLM.load(d / "retreat.bhmm"), new_data.subset([0, 1]))
    assert model.hmm_.start_counts_.sum() == before + 4
