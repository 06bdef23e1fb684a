"""The rules of a complex behavior's policy, each tested alone (no model, no simulator).

Debounce, pre-emption, repair (and the undone goals it starts from), settling and
forward goals are plain functions and a small class of
``behavior_hmm.models._complex_policy``; these tests give them hand-made goals,
readings and learned effects.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np

from behavior_hmm.data._channels import ChannelSpec
from behavior_hmm.models._complex_policy import (
    Debounce,
    Phase,
    on_the_way,
    preempting_component,
    repair_candidates,
    settles_in_goal,
    undone,
)

SPECS = {
    "angle": ChannelSpec("angle", "deg", (-180.0, 180.0), tolerance=3.0, wraps=True),
    "distance": ChannelSpec("distance", "m", (0.0, 1.0), tolerance=0.01),
}
CHANNELS = ("distance", "angle")
GOAL = {"angle": 0.0, "distance": 0.0}
# learned effect per cycle on (distance, |angle|) of 0 turn (shrinks |angle|), 1 approach
# (shrinks the distance, and |angle| a little), 2 retreat (opens the distance)
EFFECTS = np.array([[0.0, -1.0], [-0.01, -0.02], [0.01, 0.0]])
GOAL_CHANNELS = [("angle",), ("distance", "angle"), ("distance", "angle")]


def never(_: int, __: int) -> bool:
    return False


def test_debounce_holds_until_the_plan_insists() -> None:
    rule = Debounce(3)
    assert rule.holds(1) and rule.holds(1)  # 1, 2 cycles < 3: the running one goes on
    assert not rule.holds(1)  # the third cycle in a row: switch


def test_debounce_restarts_its_count_when_the_plan_changes_its_mind() -> None:
    rule = Debounce(3)
    assert rule.holds(1) and rule.holds(1)
    assert rule.holds(2)  # another component: counted from 1 again
    assert rule.holds(2) and not rule.holds(2)
    rule.clear()
    assert rule.holds(2)  # cleared: from 1 again


def test_debounce_of_the_thesis_switches_at_once() -> None:
    assert not Debounce(0).holds(1)
    assert not Debounce(1).holds(1)


def test_preemption_runs_the_component_that_closes_a_gap_the_plan_misses() -> None:
    # 9 deg off with only approach planned: approach does not turn, turn runs first
    values = {"angle": 9.0, "distance": 0.3}
    args = (GOAL, values, SPECS, CHANNELS, EFFECTS, GOAL_CHANNELS)
    assert preempting_component(*args, planned=[1], follows=never) == 0
    # the plan has turn: nothing to pre-empt
    assert preempting_component(*args, planned=[0, 1], follows=never) is None
    # a component that cannot start from here is not chosen
    assert preempting_component(*args, planned=[1], follows=never, unable={0}) is None


def test_preemption_leaves_a_gap_within_tolerance_alone() -> None:
    values = {"angle": 2.0, "distance": 0.3}  # 2 deg: inside the 3 deg tolerance
    args = (GOAL, values, SPECS, CHANNELS, EFFECTS, GOAL_CHANNELS)
    assert preempting_component(*args, planned=[1], follows=never) is None
    # a tolerance scaled down (a parent's repair) makes 2 deg a gap
    assert preempting_component(*args, planned=[1], follows=never, tolerance=0.5) == 0


def test_preemption_leaves_a_component_the_demonstrations_run_later_to_the_plan() -> None:
    # 3 cm short and 109 deg off, turn planned: approach (the distance gap) comes after
    # turn in the demonstrations, so the plan runs first
    values = {"angle": 109.0, "distance": 0.03}
    args = (GOAL, values, SPECS, CHANNELS, EFFECTS, GOAL_CHANNELS)
    assert preempting_component(*args, planned=[0], follows=never) == 1
    after_turn = lambda k, other: (k, other) == (1, 0)  # noqa: E731
    assert preempting_component(*args, planned=[0], follows=after_turn) is None


def test_preemption_needs_a_substantial_share_of_the_best_effect() -> None:
    # approach turns a little (0.02): under 10 % of turn's effect (1.0), it does not
    # count as closing the angle, so the planned approach leaves the gap to turn
    values = {"angle": 9.0, "distance": 0.3}
    args = (GOAL, values, SPECS, CHANNELS, EFFECTS, GOAL_CHANNELS)
    assert preempting_component(*args, planned=[1], follows=never) == 0
    strong = EFFECTS.copy()
    strong[1, 1] = -0.2  # 20 % of turn's: the planned approach closes the angle too
    args = (GOAL, values, SPECS, CHANNELS, strong, GOAL_CHANNELS)
    assert preempting_component(*args, planned=[1], follows=never) is None


def test_repair_tries_the_components_that_close_each_missed_channel_in_order() -> None:
    values = {"angle": 10.0, "distance": 0.2}
    args = (GOAL, values, SPECS, CHANNELS, EFFECTS, GOAL_CHANNELS)
    # angle first (the goal's order): turn (1.0), then approach (0.02); then distance:
    # only approach shrinks it (retreat grows it)
    assert repair_candidates(*args) == [0, 1, 1]
    assert repair_candidates(*args, unable={0}) == [1, 1]


def test_repair_moves_a_channel_toward_its_goal_in_either_direction() -> None:
    goal = {"distance": 0.5}
    closer = {"angle": 0.0, "distance": 0.3}  # too close: only retreat opens the distance
    assert repair_candidates(goal, closer, SPECS, CHANNELS, EFFECTS, GOAL_CHANNELS) == [2]
    farther = {"angle": 0.0, "distance": 0.7}
    assert repair_candidates(goal, farther, SPECS, CHANNELS, EFFECTS, GOAL_CHANNELS) == [1]
    inside = {"angle": 0.0, "distance": 0.505}
    assert repair_candidates(goal, inside, SPECS, CHANNELS, EFFECTS, GOAL_CHANNELS) == []


def test_repair_needs_a_component_whose_goal_states_the_channel() -> None:
    values = {"angle": 10.0, "distance": 0.0}
    only_distance = [("distance",), ("distance",), ("distance",)]
    assert repair_candidates(GOAL, values, SPECS, CHANNELS, EFFECTS, only_distance) == []


def test_undone_names_the_finished_components_whose_goal_no_longer_holds() -> None:
    finished = {0: {"angle": 0.0}, 1: {"distance": 0.1, "angle": 0.0}}
    assert undone(finished, {"angle": 1.0, "distance": 0.1}, SPECS) == []
    assert undone(finished, {"angle": 20.0, "distance": 0.1}, SPECS) == [0, 1]  # pushed
    assert undone(finished, {"angle": 1.0, "distance": 0.2}, SPECS) == [1]


def _child(goal: dict[str, float], own: dict[str, float], braking: bool, braked: bool) -> Any:
    model = SimpleNamespace(default_goal_=own)
    return SimpleNamespace(goal=goal, model=model, braking=braking, braked=braked)


def test_a_component_settles_into_its_own_goal_inside_the_complex_goal() -> None:
    own = {"distance": 0.0, "angle": 0.0}
    inside = {"distance": 0.005, "angle": 0.0}
    # heading for the goal its demonstrations stop at
    assert settles_in_goal(_child(own, own, False, False), GOAL, 1.0, SPECS)
    # braking into a goal inside the tolerance
    assert settles_in_goal(_child(inside, {"distance": 0.3}, True, False), GOAL, 1.0, SPECS)
    # one only passed at speed, not braking: not one to settle in
    assert not settles_in_goal(_child(inside, {"distance": 0.3}, False, False), GOAL, 1.0, SPECS)


def test_a_component_does_not_settle_outside_the_goal_or_once_braked() -> None:
    own = {"distance": 0.0, "angle": 0.0}
    outside = {"distance": 0.05, "angle": 0.0}
    assert not settles_in_goal(_child(outside, outside, True, False), GOAL, 1.0, SPECS)
    assert not settles_in_goal(_child(own, own, True, True), GOAL, 1.0, SPECS)
    # no channel in common with the complex goal
    assert not settles_in_goal(
        _child({"angle": 0.0}, own, True, False), {"distance": 0.0}, 1.0, SPECS
    )


def test_forward_goals_keep_a_channel_the_sub_goal_would_send_back() -> None:
    values = {"distance": 0.49, "angle": 5.0}
    goal = {"distance": 0.63, "angle": 0.0}
    # 0.39 m lies behind the robot, away from 0.63 m: it keeps 0.49; the angle wraps: kept
    kept = on_the_way({"distance": 0.39, "angle": 20.0}, values, goal, SPECS)
    assert kept == {"distance": 0.49, "angle": 20.0}
    # a sub-goal on the way is left as it is
    assert on_the_way({"distance": 0.55}, values, goal, SPECS) == {"distance": 0.55}
    # a channel the complex goal does not state is left as it is
    assert on_the_way({"distance": 0.39}, values, {"angle": 0.0}, SPECS) == {"distance": 0.39}


def test_the_phases_are_named() -> None:
    names = {p.value for p in Phase}
    assert names == {"choosing", "running", "settling", "paused", "stopping"}


# -- the reach rule: turn, approach and grasp on (distance, |angle|, arm) -------------------

GRIP_SPECS = {
    **SPECS,
    "arm": ChannelSpec("arm", "deg", (0.0, 80.0), tolerance=3.0),
}
GRIP_CHANNELS = ("distance", "angle", "arm")
# per cycle on (distance, |angle|, arm): turn shrinks |angle|, approach the distance,
# grasp moves the arm (down, then up: a small net effect) and neither wheel channel
GRIP_EFFECTS = np.array([[0.0, -0.4, 0.0], [-8e-4, -4e-4, 0.0], [1e-5, -2e-4, -4e-4]])
GRIP_GOALS = [{"angle": 0.0}, {"distance": 0.0}, {"arm": 80.0}]
GRIP_GOAL_CHANNELS = [tuple(g) for g in GRIP_GOALS]
# where the demonstrations start each one: turn anywhere 0.1-0.5 m away, approach facing
# the object (|angle| <= 0.3 deg) from 0.1-0.5 m, grasp 4 mm from it, arm up
REACH = np.array(
    [
        [[0.1, 0.5], [30.0, 180.0], [80.0, 80.0]],
        [[0.1, 0.5], [0.0, 0.3], [80.0, 80.0]],
        [[0.0036, 0.0037], [0.1, 0.13], [80.0, 80.0]],
    ]
)


def _fix(comp: int, values: dict[str, float], unable: tuple[int, ...] = ()) -> int | None:
    from behavior_hmm.models._complex_policy import reach_fix

    return reach_fix(
        comp,
        values,
        GRIP_SPECS,
        GRIP_CHANNELS,
        GRIP_EFFECTS,
        REACH,
        GRIP_GOAL_CHANNELS,
        GRIP_GOALS,
        unable=unable,
    )


def test_a_grasp_out_of_reach_gets_an_approach_first() -> None:
    # the object nudged 2 cm away: approach first
    assert _fix(2, {"distance": 0.022, "angle": 0.5, "arm": 80.0}) == 1
    # within half a tolerance of where grasps start: none
    assert _fix(2, {"distance": 0.008, "angle": 0.5, "arm": 80.0}) is None
    # turned 4 deg off (outside turn's own goal): turn first
    assert _fix(2, {"distance": 0.004, "angle": -4.0, "arm": 80.0}) == 0
    # 2.5 deg off: out of the grasp's reach, but turn's goal already holds: nothing to run
    assert _fix(2, {"distance": 0.004, "angle": -2.5, "arm": 80.0}) is None
    # approach cannot start from here: no other component brings the distance back
    assert _fix(2, {"distance": 0.022, "angle": 0.5, "arm": 80.0}, unable=(1,)) is None


def test_a_component_is_not_held_to_what_it_moves_or_starts_anywhere_on() -> None:
    # turn starts at any distance 0.1-0.5 m (40 tolerances wide): not needed
    assert _fix(0, {"distance": 0.9, "angle": 120.0, "arm": 80.0}) is None
    # approach moves the distance itself: from 2 cm it is not sent elsewhere
    assert _fix(1, {"distance": 0.02, "angle": 0.2, "arm": 80.0}) is None
    # an arm down is out of approach's reach, but nothing lifts it (grasp's net effect
    # lowers it): none
    assert _fix(1, {"distance": 0.3, "angle": 0.2, "arm": 10.0}) is None


def test_a_grasp_is_held_to_its_reach_only_until_it_has_begun() -> None:
    from behavior_hmm.models._complex_policy import not_begun

    def begun(arm: float) -> bool:
        values = {"distance": 0.02, "angle": 0.0, "arm": arm}
        return not not_begun(2, values, GRIP_SPECS, GRIP_CHANNELS, REACH, GRIP_GOAL_CHANNELS)

    assert not begun(80.0)  # fingers opening, arm still up
    assert not begun(78.6)  # within half a tolerance
    assert begun(70.0)  # lowering: its own work has begun
    # an approach starts anywhere on its goal's distance: never held while it runs
    approach = {"distance": 0.19, "angle": 3.2, "arm": 80.0}
    assert not not_begun(1, approach, GRIP_SPECS, GRIP_CHANNELS, REACH, GRIP_GOAL_CHANNELS)
