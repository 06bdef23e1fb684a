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
    assert goal_fallbacks(counts(), LATEST, GOAL).tolist() == [2, 3]
    scores = -np.abs(LATEST[:, 0])
    assert goal_candidates(scores, counts(), LATEST, GOAL).tolist() == [0, 1]


class Controller:
    """The goal part of a controller, as retarget reads and sets it."""

    def __init__(self) -> None:
        self.goal = {"angle": 0.0}
        self.goal_candidates = np.array([0, 1])
        self.goal_fallbacks = np.array([2, 3])
        self.goal_category = 0
        self.stop: set[int] = {0}

    def planned_from(self, category: int) -> None:
        pass

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
