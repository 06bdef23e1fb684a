"""EDM / DCM similarities and the matching score."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from behavior_hmm.cobart import (
    DEFAULT_DCM_SCALE,
    cobart_score,
    dcm_similarity,
    edm_similarity,
    suggest_dcm_scale,
)
from behavior_hmm.errors import ConfigError, DatasetError

window = st.integers(2, 8).flatmap(
    lambda i: st.integers(1, 3).flatmap(
        lambda c: st.tuples(*(arrays(np.float64, (i, c), elements=st.floats(-1, 1)),) * 2)
    )
)


def test_edm_is_one_minus_rms_over_scale() -> None:
    p = np.array([0.0, 0.0, 0.0, 0.0])
    z = np.array([0.1, -0.1, 0.1, -0.1])  # RMS 0.1
    assert edm_similarity(p, z) == pytest.approx(0.9)
    assert edm_similarity(p, z, scale=0.5) == pytest.approx(0.8)
    assert edm_similarity(p, p + 3.0) == 0.0  # clamped


def test_dcm_ignores_offset_but_not_rate() -> None:
    t = np.arange(10.0)
    ramp = 0.004 * t
    assert dcm_similarity(ramp, ramp + 0.5) == pytest.approx(1.0)  # same shape, shifted
    flat = np.zeros(10)
    # a ramp of m per step against a flat line: 1 - m / scale
    assert dcm_similarity(ramp, flat, scale=0.005) == pytest.approx(1 - 0.004 / 0.005)
    assert dcm_similarity(0.01 * t, flat, scale=0.005) == 0.0
    # rates compared relative to the scale: half the rate difference, twice the similarity gap
    assert dcm_similarity(0.002 * t, flat, scale=0.005) == pytest.approx(0.6)


def test_dcm_default_scale_separates_robot_speeds() -> None:
    """At ~0.005 normalized units per step (a turning robot), still vs moving differ."""
    t = np.arange(10.0)
    moving = 0.005 * t
    assert dcm_similarity(moving, np.zeros(10)) == pytest.approx(0.0)
    assert dcm_similarity(moving, 0.9 * moving) == pytest.approx(0.9)
    # a 4x larger scale (0.02) hides the difference between still and moving
    assert dcm_similarity(moving, np.zeros(10), scale=0.02) == pytest.approx(0.75)
    assert DEFAULT_DCM_SCALE == 0.005


def test_per_channel_values_and_scales() -> None:
    p = np.zeros((5, 2))
    z = np.c_[np.full(5, 0.2), np.full(5, 0.4)]
    np.testing.assert_allclose(edm_similarity(p, z), [0.8, 0.6])
    np.testing.assert_allclose(edm_similarity(p, z, scale=[0.4, 0.8]), [0.5, 0.5])
    zz = np.c_[np.arange(5) * 0.001, np.arange(5) * 0.01]
    np.testing.assert_allclose(dcm_similarity(p, zz, scale=[0.002, 0.02]), [0.5, 0.5])


def test_batched_prototypes_broadcast() -> None:
    p = np.zeros((4, 1))
    protos = np.stack([np.full((4, 1), v) for v in (0.0, 0.1, 0.5)])
    np.testing.assert_allclose(edm_similarity(p, protos)[:, 0], [1.0, 0.9, 0.5])
    np.testing.assert_allclose(cobart_score(p, protos, b=0.0), [1.0, 0.9, 0.5])


def test_score_weights_dcm_by_b() -> None:
    t = np.arange(6.0)[:, None]
    p, z = 0.003 * t, 0.1 + 0.0 * t
    edm = edm_similarity(p, z)[0]
    dcm = dcm_similarity(p, z)[0]
    assert cobart_score(p, z, b=0.4) == pytest.approx(0.4 * dcm + 0.6 * edm)
    assert cobart_score(p, z, b=0.0) == pytest.approx(edm)
    assert cobart_score(p, z, b=1.0) == pytest.approx(dcm)


def test_single_reading_windows_use_edm_only() -> None:
    assert cobart_score([0.2], [0.0], b=0.9) == pytest.approx(0.8)
    with pytest.raises(ConfigError, match="at least 2"):
        dcm_similarity([0.2], [0.0])


@pytest.mark.parametrize(
    ("p", "z", "kw"),
    [
        (np.zeros(5), np.zeros(4), {}),
        (np.zeros((5, 2)), np.zeros((5, 1)), {}),
        (np.zeros(5), np.zeros(5), {"scale": 0.0}),
        (np.zeros(5), np.zeros(5), {"scale": -1.0}),
        (np.zeros((5, 2)), np.zeros((5, 2)), {"scale": [1.0, 2.0, 3.0]}),
    ],
)
def test_bad_windows_and_scales(p: np.ndarray, z: np.ndarray, kw: dict) -> None:
    with pytest.raises(ConfigError):
        edm_similarity(p, z, **kw)
    with pytest.raises(ConfigError):
        dcm_similarity(p, z, **kw)


@settings(max_examples=50, deadline=None)
@given(window, st.floats(0.0, 1.0), st.floats(1e-3, 2.0), st.floats(1e-4, 0.5))
def test_similarities_stay_in_unit_interval(
    pz: tuple[np.ndarray, np.ndarray], b: float, e: float, s: float
) -> None:
    p, z = pz
    for sim in (edm_similarity(p, z, e), dcm_similarity(p, z, s)):
        assert np.all((0.0 <= sim) & (sim <= 1.0))
    r = cobart_score(p, z, b, e, s)
    assert 0.0 <= r <= 1.0
    assert cobart_score(p, p, b, e, s) == 1.0
    assert cobart_score(p, z, b, e, s) == pytest.approx(cobart_score(z, p, b, e, s))


def test_suggest_dcm_scale_tracks_peak_rate_per_channel() -> None:
    t = np.arange(100.0)
    x = np.c_[0.004 * t, np.r_[np.zeros(50), 0.02 * np.arange(50.0)], np.zeros(100)]
    scale = suggest_dcm_scale(x)
    assert scale[0] == pytest.approx(0.004)
    assert scale[1] == pytest.approx(0.02)  # still samples are ignored
    assert scale[2] == DEFAULT_DCM_SCALE  # never moves: fallback


def test_suggest_dcm_scale_ignores_episode_boundaries() -> None:
    x = np.r_[np.zeros(10), np.ones(10)][:, None]  # a jump only between the episodes
    assert suggest_dcm_scale(x, [10, 10])[0] == DEFAULT_DCM_SCALE
    assert suggest_dcm_scale(x)[0] == pytest.approx(1.0)
    with pytest.raises(DatasetError):
        suggest_dcm_scale(np.full((3, 1), np.nan))
