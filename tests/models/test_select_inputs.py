"""Automatic choice of an SBLM's inputs from the demonstrations (issue 30, item 2)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from behavior_hmm.cli import app
from behavior_hmm.data import CONTROL_PERIOD, Dataset, write
from behavior_hmm.errors import ConfigError
from behavior_hmm.models import InputChoice, load, select_inputs
from behavior_hmm.teach import collect

IR = tuple(f"ir{k}" for k in range(8))
IR_DECLARED = [{"name": name, "unit": "m", "range": [0, 0.1]} for name in IR]


def _walk(rng: np.random.Generator, n: int) -> np.ndarray:
    """A smooth proximity reading in [0, 0.1] m (a clipped random walk)."""
    steps = rng.normal(0.0, 0.002, n)
    return np.clip(0.05 + np.cumsum(steps), 0.0, 0.1)


def _ir_episode(i: int, n: int) -> dict[str, Any]:
    """Eight proximity readings; the wheel commands depend on ir1 and ir5 only."""
    rng = np.random.default_rng(100 + i)
    ep: dict[str, Any] = {name: _walk(rng, n) for name in IR}
    t = np.arange(n) * CONTROL_PERIOD
    ep.update(
        t=t,
        distance=np.full(n, 0.5),
        linear_velocity=np.zeros(n),
        angle=np.zeros(n),
        angular_velocity=np.zeros(n),
    )
    forward = 40.0 * (ep["ir1"] - 0.05)
    turn = 40.0 * (ep["ir5"] - 0.05)
    ep["left"] = forward - turn
    ep["right"] = forward + turn
    return ep


@pytest.fixture(scope="module")
def ir_ds() -> Dataset:
    eps = [_ir_episode(i, 240) for i in range(12)]
    return Dataset.from_episodes(eps, {"behavior": "turn", "channels": IR_DECLARED})


def test_picks_the_two_proximity_readings_that_matter(ir_ds: Dataset) -> None:
    choice = select_inputs(ir_ds, max_inputs=3)
    assert isinstance(choice, InputChoice)
    assert set(choice.inputs) == {"ir1", "ir5"}
    assert choice.scores[choice.inputs] < 0.5 * choice.scores[()]
    assert "ir1" in choice.reason and "ir5" in choice.reason
    # every noise reading was tried next to the pick and refused
    assert all((*choice.inputs, c) in choice.scores for c in IR if c not in choice.inputs)


def test_same_seed_same_pick(ir_ds: Dataset) -> None:
    a = select_inputs(ir_ds, random_state=3)
    b = select_inputs(ir_ds, random_state=3)
    assert a == b


def test_turn_reads_its_goal_and_leaves_out_the_still_forward_speed() -> None:
    """The turn's goal is its angle, so the angle is read first; its forward speed and
    distance keep within 1 % of their ranges (they move by rounding residue only, which
    follows the commands) and are never candidates; the angular velocity is named as an
    echo. Without the onset clock (the thesis preset) the start-up ramp is only in the
    echo, and the criterion takes it; ``echoes="exclude"`` leaves it out."""
    turn = collect("turn", sim="kinematic")
    choice = select_inputs(turn)
    assert choice.inputs == ("angle",)
    assert choice.echoes["angular_velocity"][0] >= 0.9
    assert "angle read first (the goal's channel)" in choice.reason
    assert "distance, linear_velocity left out as still" in choice.reason
    assert not any("linear_velocity" in subset for subset in choice.scores)
    no_clock = select_inputs(turn, onset_clock=0)
    assert no_clock.inputs == ("angle", "angular_velocity")
    assert select_inputs(turn, onset_clock=0, echoes="exclude").inputs == ("angle",)
    with pytest.raises(ConfigError, match="echoes must be one of allow, exclude"):
        select_inputs(turn, echoes="never")


def test_the_goal_channel_is_read_even_where_the_criterion_would_not_take_it() -> None:
    """A goal stated on a proximity reading the commands ignore: it is read all the
    same (first), and the criterion still adds the two readings that matter."""
    eps = [_ir_episode(i, 240) for i in range(12)]
    declared = [{**spec, "tolerance": 0.01} for spec in IR_DECLARED]  # goal channels
    ds = Dataset.from_episodes(
        eps, {"behavior": "turn", "channels": declared, "goal": {"ir3": 0.05}}
    )
    choice = select_inputs(ds, max_inputs=3)
    assert choice.inputs[0] == "ir3" and set(choice.inputs) == {"ir1", "ir3", "ir5"}


def test_cli_inputs_auto_round_trip(tmp_path: Path) -> None:
    data = tmp_path / "turn.parquet"
    write(collect("turn", sim="kinematic"), data)
    out = tmp_path / "turn.bhmm"
    result = CliRunner().invoke(
        app, ["train", "simple", str(data), "--inputs", "auto", "-o", str(out)]
    )
    assert result.exit_code == 0, result.output
    assert "inputs angle chosen automatically" in result.output
    assert "wrote" in result.output
    model = load(out)
    assert model.inputs_ == ("angle",)
    assert "Chose angle" in model.provenance_["inputs_selection"]


def test_sblm_inputs_auto_chooses_at_fit_and_keeps_the_choice(tmp_path: Path) -> None:
    """``SBLM(inputs="auto")`` fits on the channels ``select_inputs`` picks (with the
    SBLM's own cut-off and onset clock), says why in its provenance, and keeps them
    through save, load and ``partial_fit``; a file whose chosen inputs are not channels
    is refused."""
    import json
    import zipfile

    from behavior_hmm.errors import ModelFileError
    from behavior_hmm.models import AUTO_INPUTS, SBLM

    declared = [{**spec, "tolerance": 0.01} for spec in IR_DECLARED]  # goals need one
    ir_ds = Dataset.from_episodes(
        [_ir_episode(i, 240) for i in range(12)], {"behavior": "turn", "channels": declared}
    )
    params = {"epochs": 5, "onset_clock": 0}
    model = SBLM(inputs=AUTO_INPUTS, **params).fit(ir_ds)
    expected = select_inputs(ir_ds, **params)
    assert model.inputs == "auto" and model.auto_inputs
    assert model.inputs_ == expected.inputs and set(model.inputs_) == {"ir1", "ir5"}
    assert expected.reason in model.provenance_["inputs_selection"]
    path = tmp_path / "auto.bhmm"
    model.save(path)
    again = load(path)
    assert again.inputs == "auto" and again.inputs_ == model.inputs_
    assert again.provenance_["inputs_selection"] == model.provenance_["inputs_selection"]
    again.partial_fit(ir_ds.subset([0, 1]))
    assert again.inputs_ == model.inputs_

    with zipfile.ZipFile(path) as zf:
        parts = {name: zf.read(name) for name in zf.namelist()}
    header_name = next(n for n in parts if n.endswith(".json"))
    header = json.loads(parts[header_name])
    header["state"]["inputs"] = ["left"]  # a command channel is never an input
    parts[header_name] = json.dumps(header).encode()
    bad = tmp_path / "bad.bhmm"
    with zipfile.ZipFile(bad, "w") as zf:
        for name, data in parts.items():
            zf.writestr(name, data)
    with pytest.raises(ModelFileError, match="input"):
        load(bad)


def test_the_corrective_demonstrations_show_that_the_approach_reads_its_bearing() -> None:
    """In the nominal approaches the bearing keeps within 1 % of its range (still); the
    corrective ones turn back toward the object, so with them the criterion takes it."""
    from behavior_hmm.models._sblm import nominal_episodes

    approach = collect("approach", sim="kinematic")
    choice = select_inputs(approach)
    assert choice.inputs[:2] == ("distance", "angle")
    assert choice.scores[("distance", "angle")] < 0.5 * choice.scores[("distance",)]
    nominal = approach.subset(np.flatnonzero(nominal_episodes(approach)))
    alone = select_inputs(nominal)
    assert "angle" not in alone.inputs and "angle, angular_velocity left out as still" in (
        alone.reason
    )
