"""The demonstrations' start-up envelope (``models._envelope``) and ``start_envelope``."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from behavior_hmm.models import SBLM, load
from behavior_hmm.models._envelope import merged_envelope, startup_envelope
from behavior_hmm.models._policy import SimplePolicy
from behavior_hmm.models._presets import departure

REST = np.array([0.0, 0.0])


def test_envelope_is_the_running_maximum_over_the_episodes() -> None:
    # episode 1 ramps the left wheel 0, 1, 2, 2; episode 2 the right wheel backward, 0, -3
    commands = np.array([[0.0, 0.0], [1.0, 0.5], [2.0, 0.0], [2.0, 0.0], [0.0, 0.0], [0.0, -3.0]])
    envelope = startup_envelope(commands, np.array([4, 2]), REST)
    # row t: the largest |command - rest| reached by cycle t; it ends where both channels
    # are at their largest (left 2 at cycle 2, right 3 at cycle 1)
    assert envelope.tolist() == [[0.0, 0.0], [1.0, 3.0], [2.0, 3.0]]


def test_envelope_is_measured_from_rest() -> None:
    commands = np.array([[1.0], [1.5], [3.0]])
    assert startup_envelope(commands, np.array([3]), np.array([1.0])).tolist() == [
        [0.0],
        [0.5],
        [2.0],
    ]


def test_an_episode_that_starts_at_speed_leaves_nothing_to_bound() -> None:
    commands = np.array([[0.0], [1.0], [2.0], [5.0], [5.0]])
    envelope = startup_envelope(commands, np.array([3, 2]), np.array([0.0]))
    assert envelope.tolist() == [[5.0]]  # the top from the first cycle on


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.integers(1, 12), min_size=1, max_size=5),
    st.lists(st.integers(1, 12), min_size=1, max_size=5),
    st.integers(0, 2**32 - 1),
)
def test_merging_two_envelopes_equals_the_envelope_of_both(
    first: list[int], second: list[int], seed: int
) -> None:
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(sum(first), 2))
    b = rng.normal(size=(sum(second), 2))
    together = startup_envelope(np.vstack([a, b]), np.array(first + second), REST)
    merged = merged_envelope(
        startup_envelope(a, np.array(first), REST), startup_envelope(b, np.array(second), REST)
    )
    np.testing.assert_array_equal(merged, together)


def _with_envelope(model: SBLM, on: bool) -> SBLM:
    """``model`` with ``start_envelope`` set to ``on``; wheel calibration off, since it
    rescales the behavior's commands for the robot's wheels after the policy."""
    view = copy.copy(model)
    view.start_envelope = on
    view.wheel_calibration = False
    return view


def _unshown(model: SBLM, states: list[int], cycles: int) -> np.ndarray:
    """Per cycle of a run from rest (the first ``cycles``): whether its primitive's network
    was never trained on a clock as early as that cycle's (``onset_floor_``)."""
    floors = model.onset_floor_
    assert floors is not None
    clock = np.minimum(np.arange(cycles), model.onset_clock) / model.onset_clock
    return np.array([floors[s] > c for s, c in zip(states[:cycles], clock, strict=False)])


def _excess(commands: np.ndarray, envelope: np.ndarray, where: np.ndarray) -> float:
    """How far a run's commands leave the envelope in the cycles ``where`` marks (rad/s;
    <= 0: inside)."""
    n = min(len(commands), len(envelope), len(where))
    away = np.abs(commands[:n]) - envelope[:n]
    return float(away[where[:n]].max(initial=-np.inf))


def test_a_network_never_shown_a_start_starts_no_faster_than_the_demonstrations(
    turn_model: SBLM, kinematic_env: Any
) -> None:
    envelope = turn_model.start_envelope_
    assert envelope is not None and envelope.shape[1] == 2
    # starts between the demonstrated ones (every 20 deg from -170): there, networks of
    # primitives met only mid-turn run at rest and leave it faster than any
    # demonstration; bounded, never, while a network shown the starts runs its own
    starts = [{"angle": a, "distance": 0.5} for a in (-95.0, -35.0, 25.0, 65.0, 125.0)]
    plain = [
        _with_envelope(turn_model, False).generate(kinematic_env, start=s, seed=0) for s in starts
    ]
    bounded = [
        _with_envelope(turn_model, True).generate(kinematic_env, start=s, seed=0) for s in starts
    ]
    n = len(envelope)
    excess = [
        _excess(np.asarray(t.commands), envelope, _unshown(turn_model, t.state, n)) for t in plain
    ]
    assert max(excess) > 0.05
    rate = SimplePolicy(turn_model, None)._rate
    for start, run, free in zip(starts, bounded, plain, strict=True):
        unshown = _unshown(turn_model, run.state, n)
        commands = np.asarray(run.commands)
        # bounded until a network shown the starts has taken the run beyond the envelope;
        # from there nothing is (clipped back, the command would jump)
        m = min(len(commands), n)
        beyond = np.any(np.abs(commands[:m]) > envelope[:m] + 1e-12, axis=1) & ~unshown[:m]
        until = int(np.argmax(beyond)) if beyond.any() else m
        assert _excess(commands[:until], envelope, unshown[:until]) <= 1e-12, start
        assert np.abs(np.diff(commands, axis=0)).max() <= rate * (1 + 1e-9), start
        # until the first cycle of a network never shown a start, the run is the same
        first = int(np.argmax(unshown)) if unshown.any() else min(n, len(commands))
        np.testing.assert_array_equal(commands[:first], np.asarray(free.commands)[:first])
        assert run.goal_reached, start  # the envelope only bounds
    # somewhere a network shown the starts leaves rest faster than the envelope
    shown = [
        _excess(np.asarray(t.commands), envelope, ~_unshown(turn_model, t.state, n))
        for t in bounded
    ]
    assert max(shown) > 0.0


def test_a_run_carried_on_at_speed_is_not_bounded(turn_model: SBLM) -> None:
    reading = {"angle": 60.0, "distance": 0.5, "linear_velocity": 0.0, "angular_velocity": 0.0}
    model = _with_envelope(turn_model, True)
    envelope = model.start_envelope_
    assert envelope is not None and model.onset_floor_ is not None
    model.onset_floor_ = np.ones_like(model.onset_floor_)  # no network was shown a start
    from_rest = SimplePolicy(model, None)
    first = from_rest.step(reading).command
    assert np.all(np.abs(first) <= envelope[0] + 1e-12)
    carried = SimplePolicy(model, None)
    carried.carry(np.array([2.0, -2.0]))  # a complex behavior hands over at speed
    command = carried.step(reading).command
    assert np.abs(command).max() > envelope[0].max() + 0.5


def test_the_envelope_is_saved_and_refitted_alike(
    turn_model: SBLM, turn_data: Any, tmp_path: Path
) -> None:
    path = tmp_path / "turn.bhmm"
    turn_model.save(path)
    loaded = load(path)
    np.testing.assert_array_equal(loaded.start_envelope_, turn_model.start_envelope_)
    # partial_fit in two pieces gives the envelope of fit on the whole
    n = len(turn_data)
    first = turn_data.subset(np.arange(n // 2))
    second = turn_data.subset(np.arange(n // 2, n))
    grown = SBLM(inputs=("angle",), epochs=2, random_state=0).fit(first).partial_fit(second)
    whole = startup_envelope(turn_data.commands, turn_data.lengths, grown.rest_command)
    np.testing.assert_array_equal(grown.start_envelope_, whole)


def test_start_envelope_is_a_departure_of_the_default() -> None:
    assert departure("start_envelope").thesis == {"SBLM": {"start_envelope": False}}
    assert SBLM(inputs=("angle",)).start_envelope is True
    assert SBLM.from_preset("thesis", inputs=("angle",)).start_envelope is False
    with pytest.raises(Exception, match="start_envelope must be true or false"):
        SBLM(inputs=("angle",), start_envelope="yes").check_params()  # type: ignore[arg-type]
