"""Tiny synthetic demonstrations (s-curve-like ramps); no simulator needed."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from behavior_hmm.data import CONTROL_PERIOD, Dataset


def smoothstep(n: int) -> np.ndarray:
    """0 -> 1 with zero slope at both ends, like a jerk-limited profile."""
    s = np.linspace(0.0, 1.0, n)
    return s * s * (3.0 - 2.0 * s)


def make_episode(
    angle0: float = 90.0, distance0: float = 0.5, n: int = 40, behavior: str | None = None
) -> dict[str, Any]:
    """A turn-then-approach demonstration in physical units."""
    half = n // 2
    turn = np.r_[smoothstep(half), np.ones(n - half)]
    approach = np.r_[np.zeros(half), smoothstep(n - half)]
    angle = angle0 * (1.0 - turn)
    distance = distance0 * (1.0 - approach) + 0.005
    dt = max(CONTROL_PERIOD, 3.0 / n)  # short episodes last 3 s, so speeds stay plausible
    omega = np.gradient(angle, dt)
    v = -np.gradient(distance, dt)
    ep: dict[str, Any] = {
        "t": np.arange(n) * dt,
        "distance": distance,
        "linear_velocity": v,
        "angle": angle,
        "angular_velocity": omega,
        "left": (v - np.deg2rad(omega) * 0.05) / 0.008,
        "right": (v + np.deg2rad(omega) * 0.05) / 0.008,
    }
    if behavior is not None:
        ep["behavior"] = np.where(turn < 1.0, "turn", "approach").astype(object)
    return ep


@pytest.fixture
def episode_factory() -> Callable[..., dict[str, Any]]:
    return make_episode


@pytest.fixture
def small_ds() -> Dataset:
    """Four episodes of a simple behavior."""
    eps = [
        make_episode(a, d, n=60 + 10 * i)
        for i, (a, d) in enumerate([(90, 0.5), (-60, 0.3), (150, 0.8), (-170, 0.2)])
    ]
    return Dataset.from_episodes(
        eps, {"behavior": "turn_approach", "simulator": "kinematic", "robot": {"r": 0.008}}
    )


@pytest.fixture
def complex_ds() -> Dataset:
    """Three episodes with a per-row ``behavior`` column."""
    eps = [make_episode(a, 0.4, n=24, behavior="x") for a in (120.0, -45.0, 10.0)]
    return Dataset.from_episodes(
        eps, {"behavior": "turn_approach", "behaviors": ["turn", "approach"], "seed": 7}
    )
