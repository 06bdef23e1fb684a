"""Behaviors declared once: the shipped ones are entries, a user's own needs no edit in src/."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from behavior_hmm.errors import ConfigError
from behavior_hmm.models import SBLM
from behavior_hmm.sim import make_env
from behavior_hmm.teach import (
    BEHAVIORS,
    BehaviorSpec,
    Phase,
    behavior_spec,
    collect,
    default_starts,
    register_behavior,
)
from behavior_hmm.teach import test_starts as shipped_starts


@pytest.fixture
def face_left() -> Iterator[BehaviorSpec]:
    """A behavior of a user's own: turn until the object is 90 deg to the left."""
    spec = BehaviorSpec(
        name="face-left",
        goal={"angle": 90.0},
        phases=lambda angle, distance, goal_distance: [Phase("turn", 90.0)],
        train_starts=lambda: [{"angle": float(a)} for a in range(-170, 180, 20)],
        test_starts=lambda: [{"angle": a} for a in (-150.0, -75.0, 15.0, 135.0, 170.0)],
        start_defaults={"distance": 0.5},
    )
    register_behavior(spec)
    yield spec
    del BEHAVIORS["face-left"]


def test_the_shipped_behaviors_are_entries() -> None:
    assert list(BEHAVIORS)[:5] == ["turn", "approach", "retreat", "turn-approach", "position"]
    assert behavior_spec("turn").goal == {"angle": 0.0}
    assert behavior_spec("approach").goal_channels == ("distance",)
    assert len(default_starts("turn")) == 36 and len(shipped_starts("approach")) == 15


def test_an_unknown_behavior_is_a_clear_error() -> None:
    with pytest.raises(ConfigError, match=r"unknown behavior 'trun'.*did you mean 'turn'"):
        behavior_spec("trun")
    with pytest.raises(ConfigError, match="unknown behavior"):
        collect("trun", sim="kinematic")
    with pytest.raises(ConfigError, match="goal channel 'speed'"):
        BehaviorSpec("bad", {"speed": 1.0}, lambda a, d, g: [], list)
    with pytest.raises(ConfigError, match="unknown phase"):
        Phase("jump", 1.0)
    with pytest.raises(ConfigError, match="already registered"):
        register_behavior(BehaviorSpec("turn", {"angle": 5.0}, lambda a, d, g: [], list))


@pytest.mark.slow
def test_a_registered_behavior_collects_trains_and_reaches_its_goal(
    face_left: BehaviorSpec,
) -> None:
    data = collect("face-left", sim="kinematic")
    assert data.metadata["goal"] == {"angle": 90.0}
    ends = [ep.channel("angle")[-1] for ep in data.episodes()]
    assert all(abs(a - 90.0) <= 3.0 for a in ends)
    model = SBLM(inputs=("angle",), random_state=0).fit(data)
    assert model.default_goal_ == {"angle": 90.0}
    env = make_env("kinematic")
    for start in shipped_starts("face-left"):
        trace = model.generate(env, start={**start, "distance": 0.5}, seed=0)
        assert trace.goal_reached, (start, trace.final_errors())
        assert trace.final_errors()["angle"] <= 3.0
