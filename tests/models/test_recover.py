"""Recovery (SBLM ``recover``): a run that leaves its demonstrations is steered back.

The robot is the 2-D point mass with velocity commands; the demonstrations are five
smooth strokes from x = -40 to the goal at the origin, within 4 units of the x axis. A
start 40 units above them is far from every demonstrated reading.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from point_mass_testing import stroke

from behavior_hmm.data import Dataset
from behavior_hmm.errors import ConfigError, ModelFileError
from behavior_hmm.evaluate._lasa import GOAL, lasa_dataset, lasa_env
from behavior_hmm.models import SBLM

# the point mass has no velocity channels: its stop rule reads the tolerance only
pytestmark = pytest.mark.filterwarnings("ignore:stop_at_rest is off")

FAR = {"x": -30.0, "y": 40.0}
DEMONSTRATED = {"x": -40.0, "y": 0.0}


def _data(offsets: tuple[float, ...] = (-4.0, -2.0, 0.0, 2.0, 4.0)) -> Dataset:
    return lasa_dataset([stroke(y0) for y0 in offsets], "stroke")


@pytest.fixture(scope="module")
def model() -> SBLM:
    return SBLM.from_preset("default", inputs=("x", "y"), random_state=0).fit(_data())


def _run(model: SBLM, recover: bool, start: dict[str, float]) -> Any:
    model.set_params(recover=recover)
    try:
        return model.generate(lasa_env(), start=start, goal=GOAL, max_steps=500)
    finally:
        model.set_params(recover=False)


def test_the_reach_is_how_far_the_demonstrations_lie_from_their_prototypes(model: SBLM) -> None:
    # every demonstrated reading is within it, the far start (40 units, 0.67 normalized) not
    assert 0.0 < model.reach_radius_ < 0.2
    anchors = model.observations_.prototypes_[:, -1, :]
    far = np.array([FAR["x"], FAR["y"]]) / 60.0
    assert np.min(np.linalg.norm(anchors - far, axis=1)) > 3 * model.reach_radius_


def test_a_start_far_from_the_demonstrations_reaches_the_goal_only_with_recover(
    model: SBLM,
) -> None:
    without = _run(model, False, FAR)
    with_ = _run(model, True, FAR)
    assert not without.goal_reached
    assert with_.goal_reached
    assert np.hypot(*np.asarray(with_.final_observation)[:2]) < 1.0


def test_recover_leaves_a_run_within_the_demonstrations_alone(model: SBLM) -> None:
    without = _run(model, False, DEMONSTRATED)
    with_ = _run(model, True, DEMONSTRATED)
    assert without.goal_reached and with_.goal_reached
    # never steered; it stops a few cycles sooner, judged where the point mass is rather
    # than where its lagging filtered readings are (tests/models/test_goal_arrival.py)
    n = len(with_.commands)
    assert len(without.commands) - 5 <= n <= len(without.commands)
    ramp = n - 8  # then both ramp to rest (SOFT_STOP_CYCLES), one a few cycles sooner
    np.testing.assert_array_equal(without.commands[:ramp], with_.commands[:ramp])


def test_the_reach_is_saved_and_an_older_file_refuses_recover(model: SBLM, tmp_path: Path) -> None:
    path = tmp_path / "m.bhmm"
    model.save(path)
    loaded = SBLM.load(path)
    assert loaded.reach_radius_ == model.reach_radius_
    # a file from before reach_radius_ was learned: the model runs, recover says why not
    old = tmp_path / "old.bhmm"
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(old, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename.endswith(".json") and b"reach_radius" in data:
                state = json.loads(data)
                state.get("state", state).pop("reach_radius")
                data = json.dumps(state).encode()
            dst.writestr(item, data)
    older = SBLM.load(old)
    assert getattr(older, "reach_radius_", None) is None
    assert older.generate(lasa_env(), start=DEMONSTRATED, goal=GOAL, max_steps=500).goal_reached
    older.set_params(recover=True)
    with pytest.raises(ConfigError, match="reach_radius_"):
        older.generate(lasa_env(), start=DEMONSTRATED, goal=GOAL, max_steps=500)


def test_a_negative_reach_in_a_file_is_refused(model: SBLM, tmp_path: Path) -> None:
    path = tmp_path / "m.bhmm"
    model.save(path)
    bad = tmp_path / "bad.bhmm"
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(bad, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename.endswith(".json") and b"reach_radius" in data:
                data = data.replace(b'"reach_radius": ', b'"reach_radius": -')
            dst.writestr(item, data)
    with pytest.raises(ModelFileError, match="reach_radius"):
        SBLM.load(bad)


def test_partial_fit_widens_the_reach_to_the_new_demonstrations(model: SBLM) -> None:
    grown = SBLM.from_preset("default", inputs=("x", "y"), random_state=0).fit(_data((0.0,)))
    before = grown.reach_radius_
    grown.partial_fit(_data((-4.0, 4.0)))
    assert grown.reach_radius_ >= before


def test_recover_must_be_true_or_false() -> None:
    with pytest.raises(ConfigError, match="recover must be true or false"):
        SBLM(recover="yes").check_params()  # type: ignore[arg-type]
