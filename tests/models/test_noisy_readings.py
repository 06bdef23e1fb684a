"""On noisy readings a primitive is not dropped for every category the noise shows,
and a complex behavior's running component finishes its goal before the plan's next.

Sensor noise carries the observation window for a cycle or a few into categories the
running primitive was never seen in: it is held through such a category until that has
lasted the readings' filter lag (``SimplePolicy._outlier``). A complex behavior's
components ask it whether the readings are noisy. Clean readings change nothing.
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
import pytest

from behavior_hmm.models import CBLM, SBLM

SIGMA_ANGLE = 3.6  # deg: noise 0.01 of the bearing's 360 deg range
SIGMA_DISTANCE = 0.01  # m: noise 0.01 of the distance's 1 m range


def _reading(angle: float, distance: float = 0.5) -> dict[str, float]:
    return {"angle": angle, "distance": distance, "angular_velocity": 0.0, "linear_velocity": 0.0}


def _primitives(model: SBLM, readings: np.ndarray, hold: bool) -> list[int]:
    """The primitive of every cycle of an open-loop run fed ``readings`` of the bearing."""
    policy = model.policy({"angle": 0.0})
    if not hold:
        policy._outlier_cycles = 0
    policy.reset()
    return [policy.step(_reading(float(a))).state for a in readings]


def _switches(states: list[Any]) -> int:
    return sum(1 for a, b in itertools.pairwise(states) if a != b)


def test_the_hold_lasts_the_filter_lag(turn_model: SBLM) -> None:
    lag = turn_model.pipeline_.filters[0].lag_samples
    assert turn_model.policy({"angle": 0.0})._outlier_cycles == math.ceil(lag) > 0


def test_a_noisy_turn_switches_primitives_less(turn_model: SBLM) -> None:
    clean = np.linspace(150.0, 10.0, 300)
    held = free = 0
    for seed in range(5):
        noisy = clean + np.random.default_rng(seed).normal(0.0, SIGMA_ANGLE, clean.size)
        held += _switches(_primitives(turn_model, noisy, hold=True))
        free += _switches(_primitives(turn_model, noisy, hold=False))
    assert held < 0.8 * free


def test_clean_readings_switch_primitives_as_before(turn_model: SBLM) -> None:
    clean = np.linspace(150.0, 10.0, 300)
    states = _primitives(turn_model, clean, hold=True)
    assert states == _primitives(turn_model, clean, hold=False)
    assert _switches(states) > 3


def test_the_components_ask_the_complex_behavior_whether_the_readings_are_noisy(
    ta_model: CBLM,
) -> None:
    """A component keeps no noise estimate of its own (it does not confirm its goal):
    its hold follows the complex behavior's judgement, whose noise estimate it keeps."""
    policy = ta_model.policy(None)
    policy.reset()
    rng = np.random.default_rng(0)
    children = list(policy._children.values())
    assert all(not child._noisy() for child in children)  # nothing read yet
    for a in np.linspace(-90.0, -30.0, 40) + rng.normal(0.0, SIGMA_ANGLE, 40):
        policy.step(_reading(float(a), 0.5 + float(rng.normal(0.0, SIGMA_DISTANCE))))
    assert all(child._noisy() for child in children)
    policy.reset()
    for a in np.linspace(-90.0, -30.0, 40):
        policy.step(_reading(float(a)))
    assert not any(child._noisy() for child in children)


def test_a_policy_started_at_values_filters_from_them(turn_model: SBLM) -> None:
    policy = turn_model.policy({"angle": 0.0})

    def first_filtered(values: dict[str, float]) -> float:
        policy.reset()
        policy.start_at(values)
        return float(policy._pipe.step(np.array([30.0]))[0]) * 180.0  # bearing, deg

    # from its steady state at 10 deg, a 2 Hz filter moves a fraction of the way to 30
    assert 10.0 < first_filtered({"angle": 10.0}) < 11.0
    # nothing to start at: the filter starts at its first reading, as after reset
    assert first_filtered({}) == pytest.approx(30.0)
    assert first_filtered({"angle": math.nan}) == pytest.approx(30.0)


def test_a_component_starts_filtering_where_the_complex_behavior_is(
    ta_model: CBLM, monkeypatch: Any
) -> None:
    """A component started on noisy readings takes the complex behavior's filtered
    readings as its filters' start, not its first raw reading; on clean readings it
    starts as before."""
    from behavior_hmm.models._policy import GoalTracking
    from behavior_hmm.sim import make_env

    starts: list[dict[str, float]] = []
    original = GoalTracking.start_at

    def start_at(self: GoalTracking, values: dict[str, float]) -> None:
        starts.append(dict(values))
        original(self, values)

    monkeypatch.setattr(GoalTracking, "start_at", start_at)
    env = make_env("kinematic")
    start = {"angle": -120.0, "distance": 0.5}
    clean = ta_model.generate(env, start=start, seed=0)
    assert starts == [] and clean.component.count("approach") > 0
    noisy = ta_model.generate(env, start=start, seed=0, noise=0.01)
    # every component started once the noise is known (the approach after the turn
    # first) starts from the complex behavior's filtered readings
    handovers = sum(1 for a, b in itertools.pairwise(noisy.component) if a != b and b)
    assert 0 < len(starts) <= handovers
    assert abs(starts[0]["angle"]) < SIGMA_ANGLE  # the turn ended at 0 deg


def _run(model: CBLM, angles: np.ndarray, distances: np.ndarray, rule: bool) -> list[Any]:
    """Each cycle's component and command of an open-loop run of ``model`` fed these
    readings of the bearing (deg) and the distance (m), with or without the rule that a
    running component finishes its goal first."""
    policy = model.policy(None)
    if not rule:
        policy._unfinished = lambda *args: False  # type: ignore[method-assign]
    policy.reset()
    steps = [
        policy.step(_reading(float(a), float(d))) for a, d in zip(angles, distances, strict=True)
    ]
    return [(step.component, tuple(step.command)) for step in steps]


def _held(model: CBLM, angle: float, seed: int, rule: bool) -> list[Any]:
    """:func:`_run` of a robot held at ``angle`` and 0.5 m, read with sensor noise 0.01."""
    rng = np.random.default_rng(seed)
    angles = angle + rng.normal(0.0, SIGMA_ANGLE, 200)
    distances = 0.5 + rng.normal(0.0, SIGMA_DISTANCE, 200)
    return _run(model, angles, distances, rule)


def _turn_to_approach(run: list[Any]) -> int:
    return sum(1 for a, b in itertools.pairwise(run) if (a[0], b[0]) == ("turn", "approach"))


def test_a_noisy_turn_is_not_replaced_before_its_goal_holds(ta_model: CBLM) -> None:
    """The demonstrations end the turn at its bearing before they approach: on noisy
    readings the plan's approach waits while the turn's goal does not hold (a robot held
    6 deg off the bearing), where without the rule the noise hands the run back and forth."""
    with_rule = [_held(ta_model, -6.0, seed, rule=True) for seed in range(6)]
    without = [_held(ta_model, -6.0, seed, rule=False) for seed in range(6)]
    assert sum(_turn_to_approach(run) for run in with_rule) == 0
    assert sum(_turn_to_approach(run) for run in without) >= 2
    assert any(name == "turn" for run in with_rule for name, _ in run)


def test_clean_readings_replace_a_running_component_as_before(ta_model: CBLM) -> None:
    """Clean readings that show the approach's motion while the bearing is still 6-10 deg
    off: the plan replaces the turn there, with and without the rule alike."""
    for first, last in ((-40.0, -6.0), (40.0, 6.0), (-90.0, -10.0)):
        angles = np.concatenate([np.linspace(first, last, 60), np.full(140, last)])
        distances = np.concatenate([np.full(60, 0.5), np.linspace(0.5, 0.2, 140)])
        runs = [_run(ta_model, angles, distances, rule) for rule in (True, False)]
        assert runs[0] == runs[1]
        assert _turn_to_approach(runs[0]) == 1
