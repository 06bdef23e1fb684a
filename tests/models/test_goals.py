"""Goal categories: the candidates a plan ends in, and the fallbacks near the goal."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from scipy.sparse import csr_array

from behavior_hmm.errors import UnreachableGoalError
from behavior_hmm.models._goals import (
    FALLBACK_MARGIN,
    GOAL_VALUE_MARGIN,
    goal_candidates,
    goal_fallbacks,
)
from behavior_hmm.models._policy import retarget

# six categories on one channel; the goal at 0. Category 5 was never entered.
LATEST = np.array([[0.0], [0.04], [0.07], [-0.12], [0.25], [0.06]])
GOAL = np.array([0.0])


def counts() -> csr_array:
    c = np.zeros((6, 6))
    for i, j in ((0, 1), (1, 2), (2, 3), (3, 4), (4, 0)):
        c[i, j] = 1.0
    return csr_array(c)


def test_fallbacks_are_the_entered_categories_past_the_margin_nearest_first() -> None:
    assert GOAL_VALUE_MARGIN < 0.07 and 0.12 < FALLBACK_MARGIN < 0.25
    assert goal_fallbacks(counts(), LATEST, GOAL, current=4).tolist() == [2, 3]
    # only those nearer the goal than where the robot is: a plan never leads away from it
    assert goal_fallbacks(counts(), LATEST, GOAL, current=3).tolist() == [2]
    assert goal_fallbacks(counts(), LATEST, GOAL, current=2).tolist() == []
    scores = -np.abs(LATEST[:, 0])
    assert goal_candidates(scores, counts(), LATEST, GOAL).tolist() == [0, 1]


class Controller:
    """The goal part of a controller, as retarget reads and sets it."""

    def __init__(self) -> None:
        self.goal = {"angle": 0.0}
        self.goal_candidates = np.array([0, 1])
        self.near = {4: np.array([2, 3]), 2: np.array([], dtype=np.int64)}
        self.goal_category = 0
        self.stop: set[int] = {0}

    def planned_from(self, category: int) -> None:
        pass

    def goal_fallbacks(self, category: int) -> np.ndarray:
        return self.near[category]

    def aim_at(self, candidate: int) -> None:
        self.goal_category, self.stop = candidate, {0, 1}

    def aim_near(self, fallback: int) -> None:
        self.goal_category, self.stop = fallback, {0, 1, fallback}


class Plans:
    """A Behavior-HMM that can plan from category 4 to category 3 only."""

    def can_plan(self, current: int, goal: int) -> bool:
        return (current, goal) == (4, 3)


def test_with_no_candidate_reachable_a_simple_behavior_plans_to_the_nearest_fallback() -> None:
    controller: Any = Controller()
    retarget(controller, Plans(), 4, may_raise=True, near=True)
    assert controller.goal_category == 3 and controller.stop == {0, 1, 3}
    with pytest.raises(UnreachableGoalError, match="no observation path"):
        retarget(Controller(), Plans(), 4, may_raise=True)  # without: unreachable
    with pytest.raises(UnreachableGoalError):
        retarget(Controller(), Plans(), 2, may_raise=True, near=True)  # none from 2


@pytest.mark.parametrize("fallback", [True, False])
def test_a_turn_asked_past_its_demonstrations_turns_toward_the_goal_or_refuses(
    turn_model: Any, monkeypatch: pytest.MonkeyPatch, fallback: bool
) -> None:
    """From 10 deg to -30 deg: the turns were shown from both sides toward 0 deg only,
    so no category near -30 deg is reachable from 10 deg. With ``goal_fallback`` (default)
    the run plans to the reachable category nearest the goal (toward 0 deg, nearer to
    -30 deg than the start); the thesis refuses before any motion."""
    from behavior_hmm.models._policy import SimplePolicy

    monkeypatch.setattr(turn_model, "goal_fallback", fallback)
    reading = {"angle": 10.0, "distance": 0.5, "angular_velocity": 0.0, "linear_velocity": 0.0}
    policy = SimplePolicy(turn_model, {"angle": -30.0})
    if not fallback:
        with pytest.raises(UnreachableGoalError, match="no observation path"):
            policy.step(reading)
        return
    policy.step(reading)
    assert policy.goal_category not in set(policy.goal_candidates.tolist())
    _, latest, at_goal = turn_model._goal_readings({"angle": -30.0})
    _, _, at_start = turn_model._goal_readings({"angle": 10.0})
    aimed = abs(float(latest[policy.goal_category, 0] - at_goal[0]))
    assert aimed < abs(float(at_start[0] - at_goal[0]))  # toward the goal
    assert GOAL_VALUE_MARGIN < aimed <= FALLBACK_MARGIN
