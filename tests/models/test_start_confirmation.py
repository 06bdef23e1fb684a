"""A run does not end on one noisy first reading (SBLM ``stop_at_rest``).

A robot at rest 7 deg off its goal reads, under sensor noise 0.01 (3.6 deg), an angle
inside the 3 deg tolerance about one start in eight; the stop rule used to end such a
run at once, with the goal missed. A robot that has not moved now holds still until its
filtered readings have confirmed the goal for ``START_CONFIRM_CYCLES`` readings.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from behavior_hmm.models import SBLM
from behavior_hmm.models._policy import START_CONFIRM_CYCLES


def _reading(angle: float) -> dict[str, float]:
    return {"angle": angle, "distance": 0.5, "angular_velocity": 0.0, "linear_velocity": 0.0}


def _run(policy: Any, angles: list[float]) -> list[Any]:
    policy.reset()
    return [policy.step(_reading(a)) for a in angles]


def test_one_first_reading_inside_the_tolerance_does_not_end_the_run(turn_model: SBLM) -> None:
    # the first reading says 1 deg (noise), every later one the true 7 deg
    outs = _run(turn_model.policy({"angle": 0.0}), [1.0] + [7.0] * 20)
    assert not outs[0].done and not np.any(outs[0].command)
    assert not any(out.done for out in outs)
    assert any(np.any(out.command) for out in outs[1:])  # it turns toward the goal


def test_a_run_that_starts_at_its_goal_ends_after_the_confirmation(turn_model: SBLM) -> None:
    outs = _run(turn_model.policy({"angle": 0.0}), [1.0] * (START_CONFIRM_CYCLES + 3))
    done = [out.done for out in outs]
    assert done.index(True) == START_CONFIRM_CYCLES
    assert not any(np.any(out.command) for out in outs)  # it never moved


def test_the_thesis_stop_rule_ends_at_once(turn_data: Any) -> None:
    model = SBLM(inputs=("angle",), epochs=5, stop_at_rest=False).fit(turn_data)
    outs = _run(model.policy({"angle": 0.0}), [1.0, 7.0, 7.0])
    assert outs[0].done
