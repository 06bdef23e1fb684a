"""Model files of format 1 (dense Behavior-HMM tables) are refused with a pointer to the
upgrade, which converts them without loss: the bytes a current save writes."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest
from model_versions import as_version_1

from behavior_hmm.errors import ModelFileError
from behavior_hmm.models import CBLM, SBLM, _modelfile, load
from behavior_hmm.models._upgrade import upgrade


def test_version_1_is_refused_with_the_upgrade_named(
    turn_model: SBLM, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    turn_model.save(tmp_path / "turn.bhmm")
    old = as_version_1(tmp_path / "turn.bhmm", tmp_path / "old.bhmm", monkeypatch)
    with pytest.raises(ModelFileError, match=r"version 1 is not supported.*behavior-hmm upgrade"):
        SBLM.load(old)


@pytest.mark.parametrize("kind", ["SBLM", "CBLM"])
def test_upgrade_gives_the_bytes_of_a_current_save(
    kind: str,
    turn_model: SBLM,
    ta_model: CBLM,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    model = turn_model if kind == "SBLM" else ta_model
    current = tmp_path / "current.bhmm"
    model.save(current)
    old = as_version_1(current, tmp_path / "old.bhmm", monkeypatch)
    with zipfile.ZipFile(old) as zf:  # the dense tables of format 1, components too
        assert b'"version": 1' in zf.read("model.json")
    _, arrays = _modelfile.loads(old.read_bytes(), "old", versions=frozenset({1}))
    assert arrays["hmm.C"].shape == (model.hmm_.n_observations_,) * 2
    for key in [k for k in arrays if k.startswith("component.")]:
        header, _ = _modelfile.loads(arrays[key].tobytes(), key, versions=frozenset({1}))
        assert header["version"] == 1
    assert upgrade(old, tmp_path / "new.bhmm") == (1, _modelfile.VERSION)
    assert (tmp_path / "new.bhmm").read_bytes() == current.read_bytes()
    back = load(tmp_path / "new.bhmm")
    goal = back.goal_category(back.default_goal_)
    for start in range(0, back.hmm_.n_observations_, 7):
        if model.hmm_.can_plan(start, goal):
            assert back.hmm_.plan(start, goal) == model.hmm_.plan(start, goal)


@pytest.fixture
def turn_files(
    turn_model: SBLM, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> tuple[Path, Path]:
    """The turn model saved now, and the same model as format 1 stored it."""
    current = tmp_path / "current.bhmm"
    turn_model.save(current)
    return current, as_version_1(current, tmp_path / "old.bhmm", monkeypatch)


def test_upgrade_in_place_and_of_a_current_file(turn_files: tuple[Path, Path]) -> None:
    current, old = turn_files
    upgrade(old)
    assert old.read_bytes() == current.read_bytes()
    assert upgrade(current) == (_modelfile.VERSION, _modelfile.VERSION)
    assert old.read_bytes() == current.read_bytes()


def test_upgrade_refuses_tables_that_disagree_and_writes_nothing(
    turn_files: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _, old = turn_files
    header, arrays = _modelfile.loads(old.read_bytes(), "old", versions=frozenset({1}))
    arrays["hmm.C"] = arrays["hmm.C"][::-1].copy()  # probabilities that no longer match
    with monkeypatch.context() as patch:
        patch.setattr(_modelfile, "VERSION", 1)
        tampered = _modelfile.dumps(header["kind"], header["params"], header["state"], arrays)
    old.write_bytes(tampered)
    with pytest.raises(ModelFileError, match=r"old\.bhmm: array 'C' does not match"):
        upgrade(old, tmp_path / "new.bhmm")
    assert not (tmp_path / "new.bhmm").exists()
    assert old.read_bytes() == tampered


def test_upgrade_refuses_what_is_no_model(tmp_path: Path) -> None:
    path = tmp_path / "noise.bhmm"
    path.write_bytes(np.random.default_rng(0).bytes(256))
    with pytest.raises(ModelFileError, match=r"noise\.bhmm: "):
        upgrade(path)
