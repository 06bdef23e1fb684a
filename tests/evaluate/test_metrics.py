from __future__ import annotations

import numpy as np
import pytest

from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate._metrics import edm, success_rate, zero_floor


def test_identical_sequences_score_100() -> None:
    demo = np.column_stack([np.sin(np.linspace(0, 3, 50)), -np.sin(np.linspace(0, 3, 50))])
    assert success_rate(demo, demo, scale=1.0) == pytest.approx(100.0)


def test_shorter_sequence_is_padded_with_zeros() -> None:
    demo = np.ones((10, 2))
    half = np.ones((5, 2))
    # the padded half differs by 1 on half of the entries: EDM = sqrt(0.5)
    assert success_rate(half, demo, scale=1.0) == pytest.approx(100 * (1 - np.sqrt(0.5)))


def test_scale_normalizes_and_score_is_clamped_at_zero() -> None:
    demo = np.full((4, 2), 2.0)
    assert success_rate(np.zeros((4, 2)), demo, scale=2.0) == pytest.approx(0.0)
    assert success_rate(-demo, demo, scale=1.0) == 0.0
    assert zero_floor(demo, scale=4.0) == pytest.approx(50.0)


def test_bad_scale_and_shapes() -> None:
    with pytest.raises(ConfigError):
        success_rate(np.zeros((2, 2)), np.zeros((2, 2)), scale=0.0)
    with pytest.raises(ConfigError):
        edm(np.zeros(3), np.zeros(4))


def test_command_jump_is_the_largest_change_in_one_period() -> None:
    from behavior_hmm.evaluate._metrics import command_jump, command_jump_ratio

    smooth = np.column_stack([np.linspace(0, 1, 11), np.linspace(0, 1, 11)])  # 0.1 per step
    jolt = smooth.copy()
    jolt[5:] += 0.5  # one 0.6 rad/s step
    assert command_jump(smooth) == pytest.approx(0.1)
    assert command_jump(jolt) == pytest.approx(0.6)
    assert command_jump_ratio(jolt, smooth) == pytest.approx(6.0)
    assert command_jump_ratio(smooth, smooth) == pytest.approx(1.0)
    assert command_jump(np.zeros((1, 2))) == 0.0
    assert np.isfinite(command_jump_ratio(jolt, np.zeros((5, 2))))


def test_switches_count_changes_of_the_active_state() -> None:
    from behavior_hmm.evaluate._metrics import switches

    assert switches([3, 3, 4, 4, 1, 1, 1]) == 2
    assert switches([-1, 2, 2, -1]) == 0  # -1: nothing active
    assert switches([]) == 0
