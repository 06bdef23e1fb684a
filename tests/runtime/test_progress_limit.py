"""The step limit and ``progress_limit``: a run still closing in on its goal at its limit
goes on; one that stalls, or that has no progress allowance, stops there."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pytest

from behavior_hmm.data._channels import channel
from behavior_hmm.errors import ConfigError
from behavior_hmm.models import SBLM, preset_params
from behavior_hmm.runtime import StepOutput, run_policy
from behavior_hmm.runtime._loop import PROGRESS_CHECKS, Progress
from behavior_hmm.sim import make_env


class Turner:
    """Turns toward angle 0, stopping within 1°: at a fixed wheel speed (rad/s), or at
    ``gain`` × |angle| (rad/s per degree: the bearing decays exponentially), or stalls
    once |angle| is below ``stall_at``."""

    goal = {"angle": 0.0}  # noqa: RUF012 - read-only
    channels = ("angle",)

    def __init__(
        self, speed: float = 0.0, *, gain: float = 0.0, stall_at: float | None = None
    ) -> None:
        self.speed, self.gain, self.stall_at = speed, gain, stall_at

    def reset(self) -> None:
        pass

    def step(self, reading: Mapping[str, float]) -> StepOutput:
        angle = reading["angle"]
        done = abs(angle) <= 1.0
        turning = self.stall_at is None or abs(angle) > self.stall_at
        w = (self.speed + self.gain * abs(angle)) * np.sign(angle) if turning else 0.0
        return StepOutput(np.array([-w, w]), -1, False, 0, "", False, done)


def test_a_slow_run_that_closes_in_goes_on_to_its_goal() -> None:
    env = make_env("kinematic")
    fixed = run_policy(Turner(0.3), env, start={"angle": 90.0, "distance": 0.5}, max_steps=300)
    assert fixed.reason == "step_limit" and len(fixed) == 300 and not fixed.goal_reached
    longer = run_policy(
        Turner(0.3), env, start={"angle": 90.0, "distance": 0.5}, max_steps=300, progress_limit=4
    )
    assert longer.reason == "goal" and longer.goal_reached
    assert 300 < len(longer) <= 1200
    # the first 300 cycles are those of the fixed run, to the bit
    np.testing.assert_array_equal(np.asarray(longer.commands[:300]), np.asarray(fixed.commands))


def test_a_run_that_stalls_stops_at_its_limit() -> None:
    env = make_env("kinematic")
    stalled = run_policy(
        Turner(2.0, stall_at=40.0),
        env,
        start={"angle": 90.0, "distance": 0.5},
        max_steps=300,
        progress_limit=4,
    )
    assert stalled.reason == "step_limit" and len(stalled) == 300


def test_the_extension_ends_at_the_progress_limit() -> None:
    env = make_env("kinematic")
    # the bearing decays by e every 200 cycles: 22 % a check period, 23° left at 400
    turner = Turner(gain=1 / (200 * 0.7266))  # 0.7266°/cycle per rad/s on these wheels
    trace = run_policy(
        turner, env, start={"angle": 170.0, "distance": 0.5}, max_steps=200, progress_limit=2
    )
    assert trace.reason == "step_limit" and len(trace) == 400
    assert 15.0 < abs(trace.final_observation[2]) < 35.0


def test_progress_checks_the_error_fall_every_period() -> None:
    progress = Progress({"angle": 0.0}, {"angle": channel("angle")}, 100, 3.0)
    period = 100 // PROGRESS_CHECKS
    for k in range(100):  # the angle falls 0.5° a cycle: 12.5° a period
        progress.observe(k, {"angle": 90.0 - 0.5 * k})
    assert progress.goes_on(100)
    for k in range(100, 100 + period):  # then it stands still
        progress.observe(k, {"angle": 40.0})
    assert progress.goes_on(100 + period - 1)  # decided at the last check
    assert not progress.goes_on(100 + period)
    assert not Progress({"angle": 0.0}, {"angle": channel("angle")}, 100, 1.0).goes_on(100)


def test_the_models_parameter_and_its_thesis_value(turn_model: SBLM) -> None:
    assert turn_model.progress_limit == 4.0
    assert preset_params("thesis", "SBLM")["progress_limit"] == 1.0
    assert preset_params("thesis", "CBLM")["progress_limit"] == 1.0
    for bad in (0.5, 11, True, "4"):
        with pytest.raises(ConfigError, match="progress_limit"):
            SBLM(inputs=("angle",), progress_limit=bad).check_params()  # type: ignore[arg-type]


def test_perform_gives_the_model_its_allowance(turn_model: SBLM, monkeypatch: Any) -> None:
    import behavior_hmm.models._policy as policy_module

    seen: dict[str, Any] = {}

    def spy(*args: Any, **kwargs: Any) -> Any:
        seen.update(kwargs)
        raise RuntimeError("stop here")

    monkeypatch.setattr(policy_module, "run_policy", spy)
    with pytest.raises(RuntimeError, match="stop here"):
        policy_module.perform(turn_model, make_env("kinematic"), start={"angle": 90.0})
    assert seen["progress_limit"] == 4.0 and seen["max_steps"] == turn_model.max_steps_
