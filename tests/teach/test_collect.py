"""``behavior_hmm.teach.collect``: the teacher run over many starts, as a dataset."""

from __future__ import annotations

import numpy as np
import pytest

from behavior_hmm.data import COMMAND_CHANNELS, SENSOR_CHANNELS, Dataset
from behavior_hmm.errors import ConfigError
from behavior_hmm.sim import RobotParams, make_env
from behavior_hmm.teach import TeacherConfig, collect, complete_start

STARTS = [{"angle": 90.0}, {"angle": -30.0, "distance": 0.3}]


def test_collect_returns_one_episode_per_start_with_metadata() -> None:
    calls: list[tuple[int, int]] = []
    ds = collect(
        "turn",
        STARTS,
        sim="kinematic",
        seed=4,
        noise=0.0,
        progress=lambda done, total: calls.append((done, total)),
    )
    assert isinstance(ds, Dataset)
    assert len(ds) == 2
    assert ds.episode_ids.tolist() == [0, 1]
    assert calls == [(1, 2), (2, 2)]
    md = ds.metadata
    assert (md["behavior"], md["simulator"], md["seed"], md["noise"]) == (
        "turn",
        "kinematic",
        4,
        0.0,
    )
    assert md["starts"] == [{"angle": 90.0, "distance": 0.5}, {"angle": -30.0, "distance": 0.3}]
    assert md["robot"] == RobotParams().to_dict()
    assert md["teacher"] == TeacherConfig().to_dict()
    first = [float(ep.channel("angle")[0]) for ep in ds]
    assert first == pytest.approx([90.0, -30.0])
    assert ds.behaviors == ["turn"]
    for ep in ds:
        assert np.all(np.diff(ep.t) > 0)
        assert abs(ep.channel("angle")[-1]) <= 3.0
        assert ep.channel("left")[-1] == 0.0 and ep.channel("right")[-1] == 0.0


def test_turn_approach_rows_are_tagged_with_sub_behaviors() -> None:
    ds = collect("turn-approach", [{"angle": 60.0, "distance": 0.2}], sim="kinematic")
    tags = ds.behavior
    assert tags is not None
    assert tags[0] == "turn" and tags[-1] == "approach"
    switch = int(np.argmax(tags == "approach"))
    assert np.all(tags[:switch] == "turn") and np.all(tags[switch:] == "approach")


def test_same_seed_same_data_and_noise_only_in_sensors() -> None:
    a = collect("turn", STARTS, sim="kinematic", seed=2, noise=0.01).to_columns()
    b = collect("turn", STARTS, sim="kinematic", seed=2, noise=0.01).to_columns()
    c = collect("turn", STARTS, sim="kinematic", seed=3, noise=0.01).to_columns()
    clean = collect("turn", STARTS, sim="kinematic", seed=2, noise=0.0).to_columns()
    for name in a:
        assert np.array_equal(a[name], b[name]), name
    for name in SENSOR_CHANNELS:
        assert not np.array_equal(a[name], c[name]), name
        assert not np.array_equal(a[name], clean[name]), name
    for name in COMMAND_CHANNELS:  # the teacher steers on the noise-free state
        assert np.array_equal(a[name], clean[name]), name


def test_a_given_env_is_used() -> None:
    params = RobotParams(wheel_mismatch=-0.05)
    env = make_env("kinematic", params=params)
    ds = collect("approach", [{"distance": 0.2}], sim="kinematic", env=env)
    assert ds.metadata["robot"]["wheel_mismatch"] == pytest.approx(-0.05)
    assert ds.column("distance")[-1] <= 0.01


def test_default_starts_are_used_without_starts() -> None:
    ds = collect("approach", None, sim="kinematic")
    assert len(ds) == 2 * 19  # each start once nominally, once corrected (BehaviorSpec)
    assert len(ds.metadata["starts"]) == 19
    assert ds.metadata["starts"][0] == {"angle": 0.0, "distance": 0.1}


@pytest.mark.parametrize(
    ("behavior", "starts", "kwargs", "match"),
    [
        ("spin", STARTS, {}, "unknown behavior"),
        ("turn", STARTS, {"noise": -0.5}, "noise"),
        ("turn", [], {}, "no starts"),
        ("approach", [{"angle": 10.0}], {}, "needs a distance"),
        ("turn", [{"angle": 200.0}], {}, "outside the arena"),
        ("turn", [{"angle": 0.0, "distance": 2.0}], {}, "outside the arena"),
        ("turn", STARTS, {"sim": "webots"}, "simulator"),
    ],
)
def test_bad_arguments_raise_config_error(
    behavior: str, starts: list[dict[str, float]], kwargs: dict[str, object], match: str
) -> None:
    options: dict[str, object] = {"sim": "kinematic", **kwargs}
    with pytest.raises(ConfigError, match=match):
        collect(behavior, starts, **options)  # type: ignore[arg-type]


def test_complete_start_fills_defaults() -> None:
    assert complete_start("turn", {"angle": 45.0}) == {"angle": 45.0, "distance": 0.5}
    assert complete_start("approach", {"distance": 0.4}) == {"angle": 0.0, "distance": 0.4}
    assert complete_start("position", {"distance": 0.4, "goal_distance": 0.8}) == {
        "angle": 0.0,
        "distance": 0.4,
        "goal_distance": 0.8,
    }
    with pytest.raises(ConfigError, match="needs a distance"):
        complete_start("turn-approach", {"angle": 45.0})
    with pytest.raises(ConfigError, match="outside the arena"):
        complete_start("turn", {"angle": 45.0, "goal_distance": 1.3})


def test_negative_seed_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="seed"):
        collect("turn", STARTS, sim="kinematic", seed=-1)
