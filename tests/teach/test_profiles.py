from __future__ import annotations

import numpy as np
import pytest

from behavior_hmm.errors import ConfigError
from behavior_hmm.teach import TURN_LIMITS, Limits, SCurve


def test_scurve_is_rest_to_rest_and_respects_limits() -> None:
    profile = SCurve(120.0, 0.0, TURN_LIMITS)
    t = np.arange(0.0, profile.duration + 0.5, 0.004)
    pos = np.array([profile.at(x)[0] for x in t])
    vel = np.array([profile.at(x)[1] for x in t])
    assert pos[0] == pytest.approx(120.0)
    assert pos[-1] == pytest.approx(0.0)
    assert vel[0] == pytest.approx(0.0) and vel[-1] == 0.0
    assert np.max(np.abs(vel)) <= TURN_LIMITS.velocity + 1e-9
    acc = np.diff(vel) / 0.004
    assert np.max(np.abs(acc)) <= TURN_LIMITS.acceleration * 1.01
    jerk = np.diff(acc) / 0.004
    # jerk-limited: no acceleration steps (allowing the sampling of the piecewise profile)
    assert np.percentile(np.abs(jerk), 99) <= TURN_LIMITS.jerk * 1.05


def test_zero_length_profile() -> None:
    profile = SCurve(0.3, 0.3, TURN_LIMITS)
    assert profile.duration == 0.0
    assert profile.at(1.0) == (0.3, 0.0)


def test_limits_validated() -> None:
    with pytest.raises(ConfigError, match="jerk"):
        Limits(velocity=1.0, acceleration=1.0, jerk=0.0)
