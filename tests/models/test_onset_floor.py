"""``SBLM(onset_floor=True)``: each primitive's network reads the onset clock no earlier
than the earliest its own training rows held."""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from behavior_hmm.generators import _motion
from behavior_hmm.models import SBLM


def _clocks_read(
    model: SBLM, env: Any, starts: list[dict[str, float]], monkeypatch: pytest.MonkeyPatch
) -> list[tuple[int, float]]:
    """(primitive, clock) of every generator step of runs from ``starts``."""
    seen: list[tuple[int, float]] = []
    original = _motion.MotionGenerators.predict_one

    def recording(self: Any, x: np.ndarray, primitive: int) -> np.ndarray:
        seen.append((int(primitive), float(x[-1])))
        return original(self, x, primitive)

    with monkeypatch.context() as patch:
        patch.setattr(_motion.MotionGenerators, "predict_one", recording)
        for start in starts:
            model.generate(env, start=start, seed=0)
    return seen


def test_floors_are_learned_from_the_training_rows(turn_model: SBLM) -> None:
    floors = turn_model.onset_floor_
    assert floors is not None
    assert floors.shape == (turn_model.primitives_.n_categories_,)
    assert np.all((floors >= 0.0) & (floors <= 1.0))
    # some primitive begins the demonstrations (clock 0), some is met only mid-turn
    assert floors.min() == 0.0 and floors.max() > 0.5
    assert SBLM(inputs=("angle",), onset_clock=0, epochs=1).fit(_few_turns()).onset_floor_ is None


def _few_turns() -> Any:
    from behavior_hmm.teach import collect

    return collect("turn", [{"angle": 90.0, "distance": 0.5}], sim="kinematic", seed=0)


def test_a_network_reads_no_clock_earlier_than_it_was_trained_on(
    turn_model: SBLM, kinematic_env: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    floors = turn_model.onset_floor_
    assert floors is not None
    starts = [{"angle": a, "distance": 0.5} for a in (-95.0, -35.0, 25.0, 65.0, 125.0)]
    off = copy.copy(turn_model)
    off.onset_floor = False
    plain = _clocks_read(off, kinematic_env, starts, monkeypatch)
    # the clock as it runs: mid-turn primitives decoded at these starts read clocks
    # earlier than any row they were trained on
    assert any(clock < floors[p] - 1e-9 for p, clock in plain)
    view = copy.copy(turn_model)
    view.onset_floor = True
    held = _clocks_read(view, kinematic_env, starts, monkeypatch)
    assert all(clock >= floors[p] for p, clock in held)
    # and the runs still reach their goals
    for start in starts:
        assert view.generate(kinematic_env, start=start, seed=0).goal_reached, start


def test_floors_are_saved_and_grown(
    half_and_grown: tuple[SBLM, SBLM],
    saved_and_grown: Callable[[str], tuple[np.ndarray, np.ndarray]],
) -> None:
    before, after = saved_and_grown("onset_floor_")
    grown = half_and_grown[1]
    assert after.shape == (grown.primitives_.n_categories_,)
    # an old primitive's network only gains rows: its floor can only fall
    assert np.all(after[: before.shape[0]] <= before)
    assert np.all((after >= 0.0) & (after <= 1.0))
