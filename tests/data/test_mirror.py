"""Demonstrations and their left–right mirror images (``behavior_hmm.data.mirrored``)."""

from __future__ import annotations

import numpy as np
import pytest

from behavior_hmm.data import (
    CHANNELS,
    ChannelSpec,
    Dataset,
    channel_from_metadata,
    mirror_map,
    mirrored,
)
from behavior_hmm.errors import ConfigError


def _episode(angle0: float, n: int = 5, **extra: list[float]) -> dict[str, object]:
    angle = np.linspace(angle0, 0.0, n)
    return {
        "t": np.arange(n) * 0.016,
        "distance": np.full(n, 0.5),
        "linear_velocity": np.full(n, 0.01),
        "angle": angle,
        "angular_velocity": np.gradient(angle, 0.016),
        "left": np.linspace(-2.0, -1.0, n),
        "right": np.linspace(3.0, 1.0, n),
        **extra,
    }


def test_the_image_negates_odd_channels_keeps_even_ones_and_trades_the_wheels() -> None:
    data = Dataset.from_episodes([_episode(60.0), _episode(-120.0, 4)], {"behavior": "turn"})
    both = mirrored(data)
    assert len(both) == 4
    assert both.episode_ids.tolist() == [0, 1, 2, 3]
    assert both.lengths.tolist() == [5, 5, 4, 4]
    for k in range(2):
        original, image = both.episode(2 * k), both.episode(2 * k + 1)
        source = data.episode(k)
        np.testing.assert_array_equal(original.channel("angle"), source.channel("angle"))
        np.testing.assert_array_equal(image.channel("angle"), -source.channel("angle"))
        np.testing.assert_array_equal(
            image.channel("angular_velocity"), -source.channel("angular_velocity")
        )
        np.testing.assert_array_equal(image.channel("distance"), source.channel("distance"))
        np.testing.assert_array_equal(
            image.channel("linear_velocity"), source.channel("linear_velocity")
        )
        np.testing.assert_array_equal(image.channel("left"), source.channel("right"))
        np.testing.assert_array_equal(image.channel("right"), source.channel("left"))
        np.testing.assert_array_equal(image.channel("t"), source.channel("t"))
    assert both.metadata["mirrored"] is True
    assert both.metadata["behavior"] == "turn"


def test_an_angle_stays_wrapped_and_tags_and_corrective_runs_follow() -> None:
    first = {**_episode(180.0), "behavior": "turn"}
    second = {**_episode(-180.0), "behavior": ["turn"] * 4 + ["approach"]}
    data = Dataset.from_episodes(
        [{**first, "episode": 7}, {**second, "episode": 9}],
        {"behavior": "turn-approach", "corrective_episodes": [9]},
    )
    both = mirrored(data)
    image = both.episode(1).channel("angle")
    assert image[0] == 180.0  # -180 is 180 in (-180, 180]
    assert both.episode(3).channel("angle")[0] == 180.0
    assert both.metadata["corrective_episodes"] == [2, 3]
    assert list(both.behavior[-5:]) == ["turn"] * 4 + ["approach"]


def test_fitting_in_two_parts_sees_the_order_of_the_whole() -> None:
    a = Dataset.from_episodes([_episode(40.0), _episode(-80.0)], {"behavior": "turn"})
    b = Dataset.from_episodes([_episode(150.0)], {"behavior": "turn"})
    whole = mirrored(a.concat(b, renumber=True))
    parts = mirrored(a).concat(mirrored(b), renumber=True)
    np.testing.assert_array_equal(whole.sensors, parts.sensors)
    np.testing.assert_array_equal(whole.commands, parts.commands)


def test_a_channel_without_a_mirror_is_refused_with_its_name() -> None:
    ir = ChannelSpec("ir0", "m", (0.0, 0.1))
    data = Dataset.from_episodes(
        [_episode(30.0, ir0=[0.05] * 5)],
        {"behavior": "turn", "channels": [ir.to_metadata()]},
    )
    with pytest.raises(ConfigError, match="channel 'ir0' declares no mirror"):
        mirrored(data)
    with pytest.raises(ConfigError, match="already mirrored"):
        mirrored(mirrored(Dataset.from_episodes([_episode(30.0)], {"behavior": "turn"})))


def test_declared_mirrors_round_trip_and_pairs_must_name_each_other() -> None:
    left = ChannelSpec("ir_left", "m", (0.0, 0.1), mirror="ir_right")
    right = ChannelSpec("ir_right", "m", (0.0, 0.1), mirror="ir_left")
    assert channel_from_metadata(left.to_metadata()).mirror == "ir_right"
    assert mirror_map([left, right]) == {"ir_left": "ir_right", "ir_right": "ir_left"}
    lone = ChannelSpec("ir_right", "m", (0.0, 0.1), mirror="even")
    with pytest.raises(ConfigError, match="a pair must name each other"):
        mirror_map([left, lone])
    with pytest.raises(ConfigError, match="which these demonstrations do not hold"):
        mirror_map([left])
    with pytest.raises(ConfigError, match="mirror must be 'even', 'odd'"):
        ChannelSpec("ir0", "m", (0.0, 0.1), mirror="sideways!")
    with pytest.raises(ConfigError, match="mirror must be"):
        ChannelSpec("ir0", "m", (0.0, 0.1), mirror="ir0")


def test_every_channel_we_ship_declares_its_mirror() -> None:
    shipped = {
        "distance": "even",
        "linear_velocity": "even",
        "angle": "odd",
        "angular_velocity": "odd",
        "left": "right",
        "right": "left",
        "arm": "even",
        "fingers": "even",
        "object_present": "even",
        "arm_speed": "even",
        "finger_speed": "even",
    }
    assert {name: CHANNELS[name].mirror for name in shipped} == shipped
    # a declaration read back from a file written before mirrors existed is still ours
    old = CHANNELS["arm"].to_metadata()
    del old["mirror"]
    from behavior_hmm.data._channels import known_or_declared

    assert known_or_declared(channel_from_metadata(old)) is CHANNELS["arm"]
