"""ROS 1 and ROS 2 bags written by rosbags' own writers, imported, trained on, performed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")

from bag_writing import (
    FLOAT_TOPICS,
    TRACK_WIDTH,
    WHEEL_RADIUS,
    write_bag,
    write_floats,
)

from behavior_hmm.data import Dataset, import_bags
from behavior_hmm.data._bags import parse_topic_field
from behavior_hmm.errors import ConfigError, DatasetError
from behavior_hmm.models import SBLM
from behavior_hmm.sim import make_env
from behavior_hmm.teach import collect

ALL_FLOATS = {c: f"{t}:data" for c, t in FLOAT_TOPICS.items()}
RADIANS = {"angle": "rad", "angular_velocity": "rad/s"}


@pytest.fixture(scope="module")
def turn_demos() -> Dataset:
    starts = [{"angle": float(a), "distance": 0.5} for a in range(-170, 181, 40)]
    return collect("turn", starts, sim="kinematic", seed=0)


def _same_episodes(got: Dataset, want: Dataset, atol: float = 1e-9) -> None:
    assert got.lengths.tolist() == want.lengths.tolist()
    np.testing.assert_allclose(got.t, want.t, atol=1e-9)
    np.testing.assert_allclose(got.commands, want.commands, atol=atol)
    np.testing.assert_allclose(got.column("distance"), want.column("distance"), atol=atol)
    np.testing.assert_allclose(got.column("angle"), want.column("angle"), atol=atol)


def _reaches_the_goal(ds: Dataset) -> None:
    model = SBLM(inputs=("angle",), epochs=60, random_state=0).fit(ds)
    trace = model.generate(make_env("kinematic"), start={"angle": 100})
    assert trace.goal_reached, trace.reason


def test_ros2_bag_of_float64_topics_trains_a_turn(turn_demos: Dataset, tmp_path: Path) -> None:
    bag = write_bag(turn_demos, tmp_path / "turn_ros2", ros=2)
    ds = import_bags([bag], mapping=ALL_FLOATS, units=RADIANS, split_gap=0.5)
    _same_episodes(ds, turn_demos)
    np.testing.assert_allclose(ds.sensors, turn_demos.sensors, atol=1e-9)
    source = ds.metadata["source"]
    assert source["format"] == "rosbag" and source["bags"] == ["turn_ros2"]
    assert source["mapping"]["angle"] == "/object_bearing:data"
    assert len(source["episodes"]) == len(turn_demos)
    _reaches_the_goal(ds)


def test_ros1_bag_with_a_twist_and_derived_velocities_trains_a_turn(
    turn_demos: Dataset, tmp_path: Path
) -> None:
    bag = write_bag(
        turn_demos, tmp_path / "turn.bag", ros=1, twist=True, velocities=False, counter=True
    )
    ds = import_bags(
        [bag],
        mapping={"angle": "/object_bearing", "distance": "/object_distance:data"},
        units={"angle": "rad"},
        twist="/cmd_vel",
        wheel_radius=WHEEL_RADIUS,
        track_width=TRACK_WIDTH,
        episode_topic="/episode",
        derive="linear_velocity,angular_velocity",
    )
    _same_episodes(ds, turn_demos)
    # the turn is in place: the derived yaw rate is the recorded one, up to differencing
    err = np.abs(ds.column("angular_velocity") - turn_demos.column("angular_velocity"))
    assert np.median(err) < 0.5 and err.max() < 5.0
    assert np.abs(ds.column("linear_velocity")).max() < 1e-3
    assert ds.metadata["robot"] == {"wheel_radius": WHEEL_RADIUS, "track_width": TRACK_WIDTH}
    _reaches_the_goal(ds)


def test_each_bag_is_one_episode_by_default(turn_demos: Dataset, tmp_path: Path) -> None:
    one = write_bag(turn_demos.subset([0]), tmp_path / "a.bag", ros=1)
    two = write_bag(turn_demos.subset([1]), tmp_path / "b", ros=2)
    ds = import_bags([one, two], mapping=ALL_FLOATS, units=RADIANS)
    assert ds.episode_ids.tolist() == [0, 1]
    _same_episodes(ds, turn_demos.subset([0, 1]))
    # without splitting, all episodes of one bag are one (long) episode
    many = write_bag(turn_demos.subset([0, 1]), tmp_path / "c.bag", ros=1, gap_s=0.2)
    assert len(import_bags([many], mapping=ALL_FLOATS, units=RADIANS)) == 1


def test_topics_are_aligned_by_zero_order_hold(tmp_path: Path) -> None:
    ms = 1_000_000
    base = 10**12
    # /slow at 20 Hz from 5 ms, /fast at 100 Hz from 0 ms: each value is its own stamp (s)
    slow = [(base + 5 * ms + k * 50 * ms, 0.005 + k * 0.05) for k in range(10)]
    fast = [(base + k * 10 * ms, k * 0.01) for k in range(50)]
    topics = {"/slow": slow, "/fast": fast}
    bag = write_floats(tmp_path / "rates.bag", 1, topics)
    mapping = {c: "/fast" for c in ("linear_velocity", "angular_velocity", "left", "right")}
    mapping |= {"distance": "/slow", "angle": "/fast"}
    ds = import_bags([bag], mapping=mapping)
    ticks = 0.005 + 0.016 * np.arange(len(ds.t))  # from the first instant both have data
    np.testing.assert_allclose(ds.t, ticks - 0.005, atol=1e-12)
    assert ticks[-1] <= 0.49 + 1e-9 < ticks[-1] + 0.016  # up to the last message
    np.testing.assert_allclose(ds.column("angle"), np.floor(ticks / 0.01 + 1e-9) * 0.01)
    slow_held = 0.005 + np.floor((ticks - 0.005) / 0.05 + 1e-9) * 0.05
    np.testing.assert_allclose(ds.column("distance"), slow_held)


def test_split_gap_and_counter_split_one_bag(turn_demos: Dataset, tmp_path: Path) -> None:
    bag = write_bag(turn_demos.subset([0, 1, 2]), tmp_path / "three.bag", ros=1, counter=True)
    mapping = ALL_FLOATS
    assert len(import_bags([bag], mapping=mapping, units=RADIANS, split_gap=0.5)) == 3
    by_counter = import_bags([bag], mapping=mapping, units=RADIANS, episode_topic="/episode")
    _same_episodes(by_counter, turn_demos.subset([0, 1, 2]))


def test_parse_topic_field() -> None:
    tf = parse_topic_field("/odom:twist.twist.linear.x")
    assert (tf.topic, tf.path) == ("/odom", ["twist", "twist", "linear", "x"])
    assert parse_topic_field("/scan:ranges[3]").path == ["ranges", 3]
    assert parse_topic_field("/angle").field == "data"
    for bad in (":data", "/a:", "/a:x..y", "/a:1x"):
        with pytest.raises(ConfigError):
            parse_topic_field(bad)


# --- errors: one line naming the bag, the topic and the field -------------------------------


@pytest.fixture(scope="module")
def small_bag(turn_demos: Dataset, tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("bags")
    return write_bag(turn_demos.subset([0]), folder / "small.bag", ros=1, twist=True)


def _error(bag: Path, **kw: object) -> DatasetError:
    with pytest.raises(DatasetError) as info:
        import_bags([bag], **kw)  # type: ignore[arg-type]
    assert "\n" not in str(info.value)
    assert str(bag) in str(info.value)
    return info.value


TWIST = {"twist": "/cmd_vel", "wheel_radius": WHEEL_RADIUS, "track_width": TRACK_WIDTH}
SENSORS = {c: t for c, t in ALL_FLOATS.items() if c not in ("left", "right")}


def test_missing_topic(small_bag: Path) -> None:
    err = _error(small_bag, mapping={**SENSORS, "angle": "/object_bering:data"}, **TWIST)
    assert "no topic /object_bering" in str(err) and "did you mean '/object_bearing'" in str(err)
    assert err.field == "/object_bering:data"


def test_missing_field(small_bag: Path) -> None:
    err = _error(small_bag, mapping=SENSORS, **{**TWIST, "twist": "/cmd_vel:twist"})
    assert "no field 'twist'" in str(err) and "fields: linear, angular" in str(err)
    assert "/cmd_vel" in str(err)


def test_field_that_is_not_a_number(small_bag: Path) -> None:
    mapping = {**SENSORS, "left": "/cmd_vel:linear", "right": "/cmd_vel:angular.z"}
    err = _error(small_bag, mapping=mapping)
    assert "not a number" in str(err) and "Vector3" in str(err)
    assert err.field == "/cmd_vel:linear"


def test_absurd_values_name_the_topic(small_bag: Path) -> None:
    # the yaw rate (rad/s, down to about -0.8 in this clockwise turn) read as the distance:
    # below -0.5 m, absurd
    mapping = {**SENSORS, "distance": "/yaw_rate:data"}
    err = _error(small_bag, mapping=mapping, units={"angle": "rad"}, **TWIST)
    assert "absurd value" in str(err)
    assert err.field == "distance (/yaw_rate:data)"


def test_not_a_bag(tmp_path: Path) -> None:
    fake = tmp_path / "fake.bag"
    fake.write_bytes(b"not a bag at all")
    err = _error(fake, mapping=SENSORS, **TWIST)
    assert "not a readable ROS bag" in str(err)
    err = _error(tmp_path / "nope.bag", mapping=SENSORS, **TWIST)
    assert "no such bag" in str(err)
    (tmp_path / "x.db3").write_bytes(b"")
    err = _error(tmp_path / "x.db3", mapping=SENSORS, **TWIST)
    assert "folder" in str(err)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"mapping": SENSORS}, "no topic for channel.*left, right.*--twist"),
        ({"mapping": {**SENSORS, "anlge": "/a"}, **TWIST}, "did you mean 'angle'"),
        ({"mapping": {**SENSORS, "t": "/a"}, **TWIST}, "unknown channel"),
        ({"mapping": SENSORS, **TWIST, "units": {"left": "rpm"}}, "only mapped channels"),
        ({"mapping": SENSORS, **TWIST, "units": {"angle": "furlong"}}, "unknown unit"),
        ({"mapping": SENSORS, **TWIST, "split_gap": -1.0}, "--split-gap"),
        ({"mapping": SENSORS, **TWIST, "derive": "angle"}, "cannot derive 'angle'"),
        ({"mapping": SENSORS, **TWIST, "derive": "linear_velocity"}, "mapped too"),
        ({"mapping": {**SENSORS, "left": "/l"}, **TWIST}, "do not --map it too"),
        ({"mapping": SENSORS, "twist": "/cmd_vel"}, "wheel_radius"),
    ],
)
def test_bad_options(small_bag: Path, kw: dict[str, object], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        import_bags([small_bag], **kw)  # type: ignore[arg-type]


def test_without_rosbags_the_error_says_how_to_install_it(
    small_bag: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import sys

    for name in ("rosbags", "rosbags.highlevel", "rosbags.typesys"):
        monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(ConfigError, match=r"pip install 'behavior-hmm\[bags\]'"):
        import_bags([small_bag], mapping=SENSORS, **TWIST)  # type: ignore[arg-type]
