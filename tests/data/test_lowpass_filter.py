"""The causal low-pass filter: online == offline, angle wrapping, the signal pipeline."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from behavior_hmm.data import (
    CONTROL_PERIOD,
    Dataset,
    LowPassFilter,
    Normalizer,
    SignalPipeline,
    wrap_degrees,
)
from behavior_hmm.errors import ConfigError

FS = 1.0 / CONTROL_PERIOD


def _online(filt: LowPassFilter, x: np.ndarray) -> np.ndarray:
    on = filt.online()
    return np.array([on.step(v) for v in (x.tolist() if x.ndim == 1 else x)])


@pytest.mark.parametrize("wrap", [None, "deg"])
def test_online_equals_offline_on_random_signals(
    rng: np.random.Generator, wrap: str | None
) -> None:
    filt = LowPassFilter(4.0, wrap=wrap)
    x = rng.normal(0.0, 60.0, 2000)
    if wrap:
        x = wrap_degrees(np.cumsum(x))  # wanders over many turns, crossing ±180
    np.testing.assert_allclose(_online(filt, x), filt.filter_episode(x), rtol=0, atol=1e-12)


@settings(max_examples=50, deadline=None)
@given(
    arrays(
        np.float64,
        st.tuples(st.integers(1, 60), st.integers(1, 3)),
        elements=st.floats(-180.0, 180.0),
    ),
    st.floats(0.5, 30.0),
    st.sampled_from([None, "deg"]),
)
def test_online_equals_offline_multichannel(x: np.ndarray, cutoff: float, wrap: str | None) -> None:
    filt = LowPassFilter(cutoff, wrap=wrap)
    np.testing.assert_allclose(_online(filt, x), filt.filter_episode(x), rtol=0, atol=1e-9)
    # each column filtered alone gives the same as all together
    for j in range(x.shape[1]):
        np.testing.assert_array_equal(filt.filter_episode(x[:, j]), filt.filter_episode(x)[:, j])


def test_constant_passes_unchanged() -> None:
    y = LowPassFilter().filter_episode(np.full(50, 37.5))
    np.testing.assert_allclose(y, 37.5, rtol=1e-12)
    y = LowPassFilter(wrap="deg").filter_episode(np.full(50, 180.0))
    np.testing.assert_allclose(y, 180.0, rtol=1e-12)


def test_attenuates_high_and_keeps_low_frequencies() -> None:
    t = np.arange(2000) * CONTROL_PERIOD
    filt = LowPassFilter(4.0)
    slow = filt.filter_episode(np.sin(2 * np.pi * 0.3 * t))[500:]
    fast = filt.filter_episode(np.sin(2 * np.pi * 20.0 * t))[500:]
    assert np.max(np.abs(slow)) > 0.99
    assert np.max(np.abs(fast)) < 0.06


@pytest.mark.parametrize("cutoff", [1.0, 2.0, 4.0])
def test_a_ramp_comes_out_lag_samples_behind(cutoff: float) -> None:
    """A signal changing steadily trails by ``lag_samples`` (√2 / (2π f_c) seconds for a
    second-order Butterworth, to the bilinear transform's warping)."""
    filt = LowPassFilter(cutoff)
    ramp = 0.25 * np.arange(600.0)
    trail = (ramp - filt.filter_episode(ramp))[-100:] / 0.25
    np.testing.assert_allclose(trail, filt.lag_samples, rtol=1e-6)
    analog = np.sqrt(2) / (2 * np.pi * cutoff) / CONTROL_PERIOD
    assert filt.lag_samples == pytest.approx(analog, rel=0.02)


def test_is_causal(rng: np.random.Generator) -> None:
    x = rng.normal(size=300)
    y = x.copy()
    y[200:] += 50.0
    filt = LowPassFilter()
    np.testing.assert_array_equal(filt.filter_episode(x)[:200], filt.filter_episode(y)[:200])


def test_angle_wrap_filters_through_the_jump() -> None:
    # The object passes behind the robot: the angle goes 170 -> 180 -> -180 -> -170.
    continuous = np.linspace(170.0, 190.0, 200)
    wrapped = wrap_degrees(continuous)
    assert wrapped.min() < -150  # the raw signal jumps
    filt = LowPassFilter(wrap="deg")
    y = filt.filter_episode(wrapped)
    assert np.all((y > -180.0) & (y <= 180.0))
    expected = wrap_degrees(LowPassFilter().filter_episode(continuous))
    np.testing.assert_allclose(y, expected, atol=1e-9)
    # without wrapping, the filter would smear the jump through 0°
    assert np.min(np.abs(LowPassFilter().filter_episode(wrapped))) < 90.0
    np.testing.assert_allclose(_online(filt, wrapped), y, rtol=0, atol=1e-12)


def test_reset_starts_a_new_episode(rng: np.random.Generator) -> None:
    filt = LowPassFilter()
    on = filt.online()
    for v in rng.normal(size=50).tolist():
        on.step(v)
    x = rng.normal(size=40)
    on.reset(x[0])
    np.testing.assert_allclose([on.step(v) for v in x.tolist()], filt.filter_episode(x), atol=1e-12)


def test_online_channel_count_is_fixed() -> None:
    on = LowPassFilter().online()
    assert on.step([1.0, 2.0]).shape == (2,)
    with pytest.raises(ConfigError, match="2 channels"):
        on.step([1.0, 2.0, 3.0])
    with pytest.raises(ConfigError, match="scalar"):
        on.step(1.0)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"cutoff_hz": 0.0},
        {"cutoff_hz": 31.25},
        {"cutoff_hz": float("nan")},
        {"fs": -1.0},
        {"wrap": "rad"},
        {"cutoff_hz": "4"},
    ],
)
def test_bad_filter_parameters(kwargs: dict) -> None:
    with pytest.raises(ConfigError):
        LowPassFilter(**kwargs)


def test_filter_dict_round_trip() -> None:
    filt = LowPassFilter(3.0, 50.0, "deg")
    again = LowPassFilter.from_dict(json.loads(json.dumps(filt.to_dict())))
    assert again == filt
    np.testing.assert_array_equal(again.sos, filt.sos)


def test_empty_and_bad_shapes() -> None:
    assert LowPassFilter().filter_episode([]).shape == (0,)
    with pytest.raises(ConfigError):
        LowPassFilter().filter_episode(np.zeros((2, 2, 2)))


# --- pipeline -----------------------------------------------------------------------------


def test_pipeline_online_equals_offline(small_ds: Dataset) -> None:
    pipe = SignalPipeline(("distance", "angle", "angular_velocity"))
    for ep in small_ds.episodes():
        x = ep.columns(pipe.channels)
        on = pipe.online()
        online = np.array([on.step(row) for row in x])
        np.testing.assert_allclose(online, pipe.offline(x), rtol=0, atol=1e-12)


def test_pipeline_is_filter_then_normalize(small_ds: Dataset) -> None:
    pipe = SignalPipeline(("angle", "distance"), cutoff_hz=2.0, ranges={"distance": (0, 1)})
    x = small_ds.episode(0).columns(["angle", "distance"])
    expected = np.stack(
        [
            LowPassFilter(2.0, wrap="deg").filter_episode(x[:, 0]) / 180.0,
            LowPassFilter(2.0).filter_episode(x[:, 1]) * 2.0 - 1.0,
        ],
        axis=1,
    )
    np.testing.assert_allclose(pipe.offline(x), expected, atol=1e-12)
    unfiltered = SignalPipeline(("angle", "distance"), cutoff_hz=None)
    np.testing.assert_allclose(
        unfiltered.offline(x), Normalizer(("angle", "distance")).transform(x)
    )
    on = unfiltered.online()
    np.testing.assert_array_equal(on.step(x[0]), unfiltered.offline(x[:1])[0])


def test_pipeline_transform_restarts_each_episode(small_ds: Dataset) -> None:
    pipe = SignalPipeline(("angle",))
    out = pipe.transform(small_ds)
    assert out.shape == (small_ds.n_samples, 1)
    for i, ep in enumerate(small_ds.episodes()):
        a, b = small_ds.offsets[i], small_ds.offsets[i + 1]
        np.testing.assert_array_equal(out[a:b], pipe.offline(ep.columns(["angle"])))


def test_online_pipeline_reset(small_ds: Dataset) -> None:
    pipe = SignalPipeline(("angle", "distance"))
    on = pipe.online()
    first, second = (small_ds.episode(i).columns(pipe.channels) for i in (0, 1))
    for row in first:
        on.step(row)
    on.reset()
    np.testing.assert_allclose([on.step(r) for r in second], pipe.offline(second), atol=1e-12)
    on.reset(second[0])
    np.testing.assert_allclose([on.step(r) for r in second], pipe.offline(second), atol=1e-12)
    with pytest.raises(ConfigError, match="expected 2 values"):
        on.step([1.0])


def test_pipeline_dict_round_trip() -> None:
    pipe = SignalPipeline(["angle", "linear_velocity"], 3.0, ranges={"angle": (-90.0, 90.0)})
    again = SignalPipeline.from_dict(json.loads(json.dumps(pipe.to_dict())))
    assert again == pipe
    assert again.channels == ("angle", "linear_velocity")
    with pytest.raises(ConfigError):
        SignalPipeline.from_dict({"channels": ["angle"], "cutoff_hz": 100.0})
    with pytest.raises(ConfigError):
        SignalPipeline.from_dict({"cutoff_hz": 3.0})


def test_pipeline_shape_errors() -> None:
    with pytest.raises(ConfigError, match="expected shape"):
        SignalPipeline(("angle",)).offline(np.zeros((5, 2)))
