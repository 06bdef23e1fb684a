"""Automatic choice of an SBLM's inputs from the demonstrations (issue 30, item 2)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from behavior_hmm.cli import app
from behavior_hmm.data import CONTROL_PERIOD, Dataset, write
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


def test_turn_drops_the_echo_of_its_own_commands() -> None:
    choice = select_inputs(collect("turn", sim="kinematic"))
    assert choice.inputs == ("angle",)
    assert choice.echoes["angular_velocity"][0] >= 0.9


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
