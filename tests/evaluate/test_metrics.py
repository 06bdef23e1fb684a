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
