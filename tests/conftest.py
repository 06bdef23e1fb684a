"""Shared test configuration: one printed, replayable seed for every test run."""

from __future__ import annotations

import os

import numpy as np
import pytest

SEED = int(os.environ.get("BEHAVIOR_HMM_TEST_SEED", "12345"))


def pytest_report_header(config: pytest.Config) -> str:
    return f"behavior-hmm test seed: {SEED} (replay with BEHAVIOR_HMM_TEST_SEED={SEED})"


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator; the seed is printed in the pytest header."""
    return np.random.default_rng(SEED)
