"""A simple component that finds no plan from its best-matching start category starts
from the next plannable one (its complex behavior's ``start_alternatives``)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from behavior_hmm.errors import UnreachableGoalError
from behavior_hmm.models import CBLM, SBLM
from behavior_hmm.models._policy import SimplePolicy, make_policy

READING = {"angle": 60.0, "distance": 0.5, "linear_velocity": 0.0, "angular_velocity": 0.0}


class _NoPlanFrom:
    """A Behavior-HMM from whose category ``blocked`` no plan starts (the rest as is)."""

    def __init__(self, hmm: Any, blocked: int) -> None:
        self._hmm = hmm
        self._blocked = blocked

    def __getattr__(self, name: str) -> Any:
        return getattr(self._hmm, name)

    def can_plan(self, start: int, goal: int) -> bool:
        return start != self._blocked and bool(self._hmm.can_plan(start, goal))

    def plannable_from(self, goals: Any) -> np.ndarray:
        mask = np.array(self._hmm.plannable_from(goals), dtype=bool)
        mask[self._blocked] = False
        return mask


def _blocked_policy(model: SBLM, alternatives: int) -> tuple[SimplePolicy, int]:
    best = SimplePolicy(model, None).step(READING).observation  # the window's best match
    policy = SimplePolicy(model, None)
    policy._hmm = _NoPlanFrom(model.hmm_, best)
    policy.start_alternatives = alternatives
    return policy, best


def test_without_alternatives_a_start_with_no_plan_is_refused(turn_model: SBLM) -> None:
    policy, _ = _blocked_policy(turn_model, 0)
    with pytest.raises(UnreachableGoalError, match="no observation path"):
        policy.step(READING)


def test_with_alternatives_it_starts_from_the_best_plannable_match(turn_model: SBLM) -> None:
    policy, blocked = _blocked_policy(turn_model, 5)
    out = policy.step(READING)
    assert out.observation != blocked and out.state >= 0 and not out.done
    # the best-matching category after the blocked one from which a plan exists
    mismatch = np.asarray(policy._live.mismatch)
    mask = turn_model.hmm_.plannable_from(policy.goal_candidates)
    ranked = [int(k) for k in np.argsort(mismatch, kind="stable") if mask[k] and k != blocked]
    assert out.observation == ranked[0]
    # later cycles in the blocked category go on with the primitive decoded there
    assert policy.step(READING).state == out.state


def test_a_complex_behavior_gives_its_components_its_start_alternatives(
    ta_model: CBLM,
) -> None:
    for alternatives in (5, 0):
        model = ta_model
        saved = model.start_alternatives
        model.start_alternatives = alternatives
        try:
            policy = make_policy(model, None)
        finally:
            model.start_alternatives = saved
        children = list(policy._children.values())
        assert [c.start_alternatives for c in children] == [alternatives] * len(children)
    assert SimplePolicy(ta_model.components_[0], None).start_alternatives == 0  # alone: none
