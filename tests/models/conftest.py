"""Fitted models shared by the model tests (kinematic robot)."""

from __future__ import annotations

import pytest

from behavior_hmm.models import CBLM, SBLM
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
