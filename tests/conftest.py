"""Shared test configuration: one printed, replayable seed for every test run."""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import pytest
from hypothesis import settings

from behavior_hmm.data import Dataset
from behavior_hmm.models import SBLM
from behavior_hmm.teach import collect

SEED = int(os.environ.get("BEHAVIOR_HMM_TEST_SEED", "12345"))

# Batch commands run in-process unless a test asks for workers: starting worker
# interpreters costs about 3 s per command, and the executor tests pass --workers 2.
os.environ.setdefault("BEHAVIOR_HMM_WORKERS", "1")

# Hypothesis: in CI (env CI set) the same examples every run, so a red build replays;
# elsewhere random examples, to find new failures. Select one with --hypothesis-profile.
settings.register_profile("ci", derandomize=True, print_blob=True)
settings.register_profile("dev")
settings.load_profile("ci" if os.environ.get("CI") else "dev")


def pytest_report_header(config: pytest.Config) -> str:
    return f"behavior-hmm test seed: {SEED} (replay with BEHAVIOR_HMM_TEST_SEED={SEED})"


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator; the seed is printed in the pytest header."""
    return np.random.default_rng(SEED)


# Small fitted models shared by the model, runtime and evaluation tests (kinematic robot).


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
