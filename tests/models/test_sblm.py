from __future__ import annotations

import io
import pickle
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from behavior_hmm.data import Dataset
from behavior_hmm.errors import ConfigError, ModelFileError, NotFittedError
from behavior_hmm.models import SBLM
from behavior_hmm.models._modelfile import VERSION


def test_fit_returns_self_and_learns_attributes(turn_data: Dataset) -> None:
    model = SBLM(inputs=("angle",), epochs=5)
    assert model.fit(turn_data) is model
    assert model.primitives_.n_categories_ >= 2
    assert model.observations_.n_categories_ >= 2
    assert model.hmm_.n_states_ == model.primitives_.n_categories_
    assert model.command_scale_ == pytest.approx(np.abs(turn_data.commands).max())
    assert model.default_goal_ == {"angle": 0.0}
    assert model.behavior_ == "turn"


def test_not_fitted_and_bad_params(kinematic_env: Any) -> None:
    with pytest.raises(NotFittedError):
        SBLM().generate(kinematic_env, start={"angle": 30})
    with pytest.raises(ConfigError, match="unknown input 'heading'"):
        SBLM(inputs=("heading",)).fit(None)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="unknown parameter"):
        SBLM().set_params(colour="red")


def test_same_seed_gives_byte_identical_model_file(turn_data: Dataset, tmp_path: Path) -> None:
    a = SBLM(inputs=("angle",), epochs=5, random_state=3).fit(turn_data)
    b = SBLM(inputs=("angle",), epochs=5, random_state=3).fit(turn_data)
    a.save(tmp_path / "a.bhmm")
    b.save(tmp_path / "b.bhmm")
    assert (tmp_path / "a.bhmm").read_bytes() == (tmp_path / "b.bhmm").read_bytes()


def test_save_load_generate_gives_identical_trace(
    turn_model: SBLM, tmp_path: Path, kinematic_env: Any
) -> None:
    path = tmp_path / "turn.bhmm"
    turn_model.save(path)
    loaded = SBLM.load(path)
    start = {"angle": 75.0, "distance": 0.5}
    a = turn_model.generate(kinematic_env, start=start, seed=1)
    b = loaded.generate(kinematic_env, start=start, seed=1)
    assert len(a) == len(b) > 10
    np.testing.assert_array_equal(a.command_array, b.command_array)
    assert a.state == b.state and a.observation == b.observation


def _rewrite_member(src: Path, dst: Path, member: str, data: bytes) -> None:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for info in zin.infolist():
            zout.writestr(info, data if info.filename == member else zin.read(info.filename))


def test_corrupted_tampered_and_hostile_files_are_refused(turn_model: SBLM, tmp_path: Path) -> None:
    good = tmp_path / "good.bhmm"
    turn_model.save(good)
    raw = good.read_bytes()
    cases = {
        "truncated.bhmm": raw[: len(raw) // 2],
        "empty.bhmm": b"",
        "random.bhmm": np.random.default_rng(0).bytes(4096),
        "pickle.bhmm": pickle.dumps({"kind": "SBLM"}),
    }
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
    # tampered arrays: flip one byte inside arrays.npz (checksum no longer matches)
    with zipfile.ZipFile(good) as zf:
        arrays = bytearray(zf.read("arrays.npz"))
        header = zf.read("model.json")
    arrays[len(arrays) // 2] ^= 0xFF
    _rewrite_member(good, tmp_path / "tampered.bhmm", "arrays.npz", bytes(arrays))
    # edited JSON: another version, and garbage
    assert f'"version": {VERSION}'.encode() in header
    _rewrite_member(
        good,
        tmp_path / "version.bhmm",
        "model.json",
        header.replace(f'"version": {VERSION}'.encode(), b'"version": 9'),
    )
    _rewrite_member(good, tmp_path / "json.bhmm", "model.json", b"{not json")
    # an extra member
    buf = io.BytesIO(raw)
    with zipfile.ZipFile(buf, "a") as zf:
        zf.writestr("payload.pkl", pickle.dumps(object))
    (tmp_path / "extra.bhmm").write_bytes(buf.getvalue())
    names = [*cases, "tampered.bhmm", "version.bhmm", "json.bhmm", "extra.bhmm", "missing.bhmm"]
    for name in names:
        with pytest.raises(ModelFileError):
            SBLM.load(tmp_path / name)


def test_bad_goals_are_refused(turn_model: SBLM) -> None:
    with pytest.raises(ConfigError, match="not an input"):
        turn_model.resolve_goal({"distance": 0.0})
    with pytest.raises(ConfigError, match="unknown goal channel"):
        turn_model.resolve_goal({"heading": 0.0})
    with pytest.raises(ConfigError, match="not in"):
        turn_model.resolve_goal({"angle": 400.0})
    assert turn_model.resolve_goal({"angle": 10}) == {"angle": 10.0}
