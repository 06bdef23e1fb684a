"""RobotParams: defaults, validation and the JSON round trip."""

from __future__ import annotations

import dataclasses
import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from behavior_hmm.errors import ConfigError
from behavior_hmm.sim import CONTROL_PERIOD, RobotParams


def test_defaults_match_the_khepera_like_robot() -> None:
    p = RobotParams()
    assert p.wheel_radius == 0.021
    assert p.axle_track == 0.053
    assert p.body_radius == 0.035
    assert p.max_wheel_speed == 10.0
    assert p.wheel_mismatch == 0.01
    assert p.motor_time_constant == 0.03
    assert p.object_radius == 0.05
    assert p.control_period == CONTROL_PERIOD
    assert p.physics_timestep == 0.002
    assert p.substeps == 8
    assert p.wheel_gains == pytest.approx((0.995, 1.005))
    assert p.contact_distance == pytest.approx(0.085)


def test_frozen() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        RobotParams().wheel_radius = 0.1  # type: ignore[misc]


def test_json_round_trip() -> None:
    p = RobotParams(wheel_radius=0.03, wheel_mismatch=-0.02, physics_timestep=0.004)
    text = json.dumps(p.to_dict())
    assert RobotParams.from_dict(json.loads(text)) == p


def test_ints_become_floats() -> None:
    p = RobotParams(max_wheel_speed=12)
    assert isinstance(p.max_wheel_speed, float)
    assert isinstance(p.to_dict()["max_wheel_speed"], float)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"wheel_radius": 0.0}, "wheel_radius must be > 0"),
        ({"axle_track": -0.05}, "axle_track must be > 0"),
        ({"body_radius": float("nan")}, "body_radius must be finite"),
        ({"max_wheel_speed": float("inf")}, "max_wheel_speed must be finite"),
        ({"wheel_mismatch": 1.0}, "wheel_mismatch must lie in"),
        ({"motor_time_constant": 0.0}, "motor_time_constant must be > 0"),
        ({"physics_timestep": 0.003}, "must divide"),
        ({"physics_timestep": 0.032}, "must divide"),
        ({"object_radius": "0.05"}, "object_radius must be a number"),
        ({"wheel_radius": True}, "wheel_radius must be a number"),
    ],
)
def test_invalid_values_raise_config_error(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        RobotParams(**kwargs)  # type: ignore[arg-type]


def test_from_dict_rejects_unknown_keys_and_non_mappings() -> None:
    with pytest.raises(ConfigError, match="unknown RobotParams field"):
        RobotParams.from_dict({"wheel_radius": 0.02, "mass": 1.0})
    with pytest.raises(ConfigError, match="must be a mapping"):
        RobotParams.from_dict([("wheel_radius", 0.02)])  # type: ignore[arg-type]


@settings(max_examples=50, deadline=None)
@given(
    st.dictionaries(
        st.sampled_from([f.name for f in dataclasses.fields(RobotParams)] + ["bogus"]),
        st.one_of(st.floats(allow_nan=True), st.integers(), st.text(max_size=3), st.none()),
        max_size=4,
    )
)
def test_from_dict_returns_params_or_config_error(data: dict[str, object]) -> None:
    try:
        p = RobotParams.from_dict(data)
    except ConfigError:
        return
    assert RobotParams.from_dict(p.to_dict()) == p
