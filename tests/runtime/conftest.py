"""Small fitted models shared by the model, runtime and evaluation tests."""

from __future__ import annotations

from typing import Any

import pytest

from behavior_hmm.data import Dataset
from behavior_hmm.models import SBLM
from behavior_hmm.teach import collect


@pytest.fixture(scope="session")
def turn_data() -> Dataset:
    starts = [{"angle": float(a), "distance": 0.5} for a in range(-170, 181, 20)]
    return collect("turn", starts, sim="kinematic", seed=0)


@pytest.fixture(scope="session")
def turn_model(turn_data: Dataset) -> SBLM:
    return SBLM(inputs=("angle",), epochs=60, random_state=0).fit(turn_data)


@pytest.fixture
def kinematic_env() -> Any:
    from behavior_hmm.sim import make_env

    return make_env("kinematic")
