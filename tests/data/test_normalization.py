"""Normalization of sensors and wheel commands into [−1, 1]."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from behavior_hmm.data import SENSOR_CHANNELS, SENSOR_RANGES, CommandScaler, Dataset, Normalizer
from behavior_hmm.errors import ConfigError, DatasetError, NotFittedError


def test_range_ends_map_to_minus_one_and_one() -> None:
    norm = Normalizer()
    lo = [SENSOR_RANGES[c][0] for c in SENSOR_CHANNELS]
    hi = [SENSOR_RANGES[c][1] for c in SENSOR_CHANNELS]
    np.testing.assert_allclose(norm.transform([lo, hi]), [[-1] * 4, [1] * 4], atol=1e-15)
    np.testing.assert_allclose(norm.transform([0.6, 0.0, 0.0, 0.0]), [0.0] * 4, atol=1e-15)


def test_outside_values_are_not_clipped_unless_asked() -> None:
    assert Normalizer(("distance",)).transform([[2.4]])[0, 0] == pytest.approx(3.0)
    assert Normalizer(("distance",), clip=True).transform([[2.4]])[0, 0] == 1.0


def test_custom_ranges_and_channel_order() -> None:
    norm = Normalizer(["angle", "distance"], {"distance": (0.0, 2.0)})
    assert norm.channels == ("angle", "distance")
    np.testing.assert_allclose(norm.transform([90.0, 1.5]), [0.5, 0.5])


@settings(max_examples=50, deadline=None)
@given(arrays(np.float64, (7, 4), elements=st.floats(-1e4, 1e4)))
def test_round_trip(x: np.ndarray) -> None:
    norm = Normalizer()
    np.testing.assert_allclose(norm.inverse_transform(norm.transform(x)), x, rtol=1e-12, atol=1e-9)


def test_dict_round_trip_through_json() -> None:
    norm = Normalizer(("angle", "linear_velocity"), {"angle": (-90.0, 90.0)})
    again = Normalizer.from_dict(json.loads(json.dumps(norm.to_dict())))
    assert again == norm
    x = np.array([[10.0, 0.05]])
    np.testing.assert_array_equal(again.transform(x), norm.transform(x))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"channels": ("angle",), "ranges": {"angle": (1.0, 1.0)}}, "lo < hi"),
        ({"channels": ("angle",), "ranges": {"angle": (0.0, float("inf"))}}, "finite"),
        ({"channels": ("angle",), "ranges": {"distance": (0.0, 1.0)}}, "not among"),
        ({"channels": ("battery",)}, "no normalization range"),
        ({"channels": ()}, "at least one"),
        ({"channels": ("angle", "angle")}, "repeat"),
    ],
)
def test_bad_configuration(kwargs: dict, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        Normalizer(**kwargs)


@pytest.mark.parametrize(
    "d",
    [
        None,
        {},
        {"channels": "angle"},
        {"channels": ["angle"], "ranges": {"angle": 5}},
        {"channels": ["angle"], "clip": "yes"},
        {"channels": [3]},
    ],
)
def test_from_dict_refuses_malformed(d: object) -> None:
    with pytest.raises(ConfigError):
        Normalizer.from_dict(d)  # type: ignore[arg-type]


def test_shape_mismatch() -> None:
    with pytest.raises(ConfigError, match="expected 2 values"):
        Normalizer(("angle", "distance")).transform(np.zeros((3, 3)))


def test_command_scaler_fits_largest_absolute_command(small_ds: Dataset) -> None:
    scaler = CommandScaler().fit(small_ds)
    assert scaler.scale_ == np.max(np.abs(small_ds.commands))
    y = scaler.transform(small_ds.commands)
    assert np.max(np.abs(y)) == 1.0
    np.testing.assert_allclose(scaler.inverse_transform(y), small_ds.commands, rtol=1e-15)
    assert CommandScaler().fit([[0.5, -2.0], [1.0, 1.0]]).scale_ == 2.0


def test_command_scaler_contract() -> None:
    scaler = CommandScaler()
    assert scaler.get_params() == {"units": None}
    with pytest.raises(NotFittedError):
        scaler.transform([[1.0, 1.0]])
    with pytest.raises(DatasetError, match="zero"):
        scaler.fit(np.zeros((4, 2)))
    with pytest.raises(DatasetError, match="NaN"):
        scaler.fit([[np.nan, 1.0]])
    with pytest.raises(DatasetError, match="no commands"):
        scaler.fit(np.zeros((0, 2)))
    assert scaler.fit([[3.0, 1.0]]) is scaler


def test_command_channels_of_one_unit_share_a_scale_and_others_get_their_own() -> None:
    wheels_and_gripper = np.array([[3.0, -4.0, 0.01], [1.0, 2.0, 0.03]])
    scaler = CommandScaler(["rad/s", "rad/s", "m"]).fit(wheels_and_gripper)
    assert scaler.scales_.tolist() == [4.0, 4.0, 0.03]
    assert scaler.transform(wheels_and_gripper)[1].tolist() == pytest.approx([0.25, 0.5, 1.0])
    again = CommandScaler.from_dict(json.loads(json.dumps(scaler.to_dict())))
    assert again.transform([[4.0, 4.0, 0.03]]).tolist() == [[1.0, 1.0, 1.0]]
    # one unit: one scalar scale, as the thesis normalizes (DESIGN §6)
    assert CommandScaler().fit(wheels_and_gripper[:, :2]).to_dict() == {"scale": 4.0}


def test_command_scaler_dict_round_trip() -> None:
    scaler = CommandScaler().fit([[3.0, -4.0]])
    again = CommandScaler.from_dict(json.loads(json.dumps(scaler.to_dict())))
    assert again.scale_ == 4.0
    for bad in (
        {},
        {"scale": 0},
        {"scale": -1.0},
        {"scale": float("nan")},
        {"scale": True},
        {"scale": "4"},
    ):
        with pytest.raises(ConfigError):
            CommandScaler.from_dict(bad)
