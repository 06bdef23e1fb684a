"""Fitted models shared by the model tests (kinematic robot)."""

from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from behavior_hmm.models import CBLM, SBLM, load
from behavior_hmm.teach import collect


@pytest.fixture(scope="session")
def ta_model(turn_model: SBLM) -> CBLM:
    """A small turn & approach CBLM over the shared turn SBLM (6 starts)."""
    starts = [{"distance": d, "angle": a} for d in (0.3, 0.5) for a in (-90.0, 0.0, 120.0)]
    approach_data = collect("approach", starts, sim="kinematic", seed=0)
    approach = SBLM(inputs=("distance", "angle"), epochs=30, random_state=0).fit(approach_data)
    ta_data = collect("turn-approach", starts, sim="kinematic", seed=0)
    model = CBLM(inputs=("distance", "angle"), components=[turn_model, approach])
    return model.fit(ta_data)


@pytest.fixture(scope="session")
def half_and_grown(turn_data: Any) -> tuple[SBLM, SBLM]:
    """A turn SBLM fitted on the first half of the shared turn demonstrations, and a copy
    grown by ``partial_fit`` on the second half (the learned arrays' growth)."""
    n = len(turn_data)
    model = SBLM(inputs=("angle",), epochs=2, random_state=0).fit(
        turn_data.subset(np.arange(n // 2))
    )
    grown = copy.deepcopy(model).partial_fit(turn_data.subset(np.arange(n // 2, n)))
    return model, grown


@pytest.fixture
def saved_and_grown(
    turn_model: SBLM, half_and_grown: tuple[SBLM, SBLM], tmp_path: Path
) -> Callable[[str], tuple[np.ndarray, np.ndarray]]:
    """For a learned array's attribute name: assert that the shared turn SBLM's array
    survives save and load unchanged, and return the half-grid model's array before and
    after its growth (both learned)."""

    def check(name: str) -> tuple[np.ndarray, np.ndarray]:
        path = tmp_path / "turn.bhmm"
        turn_model.save(path)
        np.testing.assert_array_equal(getattr(load(path), name), getattr(turn_model, name))
        model, grown = half_and_grown
        before, after = getattr(model, name), getattr(grown, name)
        assert before is not None and after is not None
        return before, after

    return check
