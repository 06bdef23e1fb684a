"""Stopping and the sensor-fault policy of the control loop (issue 11).

A Gymnasium wrapper injects faults into the kinematic env's observations (NaN on a
channel at chosen steps) or into ``step`` (an exception), and records every action
the loop sent, so the tests can see the wheels being stopped.
"""

from __future__ import annotations

import copy
from collections.abc import Iterable, Mapping
from types import SimpleNamespace
from typing import Any

import gymnasium
import numpy as np
import pyarrow.parquet as pq
import pytest

from behavior_hmm.data import SENSOR_CHANNELS, Dataset
from behavior_hmm.errors import ConfigError, UnreachableGoalError
from behavior_hmm.evaluate._baselines import BehaviorCloning
from behavior_hmm.models import CBLM, SBLM
from behavior_hmm.models._policy import make_policy, perform
from behavior_hmm.models._policy import read_channels as channels_read
from behavior_hmm.runtime import DEFAULT_FAULT_HOLD_S, SensorHold, run_policy
from behavior_hmm.sim import make_env
from behavior_hmm.teach import collect

TURN_START = {"angle": 90.0, "distance": 0.5}
APPROACH_START = {"angle": 0.0, "distance": 0.8}
#: control periods a reading is held with the default 0.1 s at 16 ms
HOLD = 6


class Faulty(gymnasium.Wrapper[Any, Any, Any, Any]):
    """NaN on ``faults[channel]`` steps (step 0 = the reset's reading); raise in ``step``.

    ``raise_after``: the ``step`` call after that many successful ones raises ``error``
    (every later call too when ``always``). ``actions`` records every action received.
    """

    def __init__(
        self,
        env: Any,
        faults: Mapping[str, Iterable[int]] | None = None,
        *,
        raise_after: int | None = None,
        error: BaseException | None = None,
        always: bool = False,
    ) -> None:
        super().__init__(env)
        self.faults = {SENSOR_CHANNELS.index(c): set(s) for c, s in (faults or {}).items()}
        self.raise_after = raise_after
        self.error = error if error is not None else RuntimeError("motor bus down")
        self.always = always
        self.actions: list[np.ndarray] = []
        self.k = 0
        self.raised = 0

    def reset(self, **kwargs: Any) -> Any:
        self.k = 0
        self.actions = []
        obs, info = self.env.reset(**kwargs)
        return self._faulty(obs), info

    def step(self, action: Any) -> Any:
        self.actions.append(np.array(action, dtype=np.float64))
        if self.raise_after is not None and self.k >= self.raise_after:
            if self.always or not self.raised:
                self.raised += 1
                raise self.error
        self.k += 1
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._faulty(obs), reward, terminated, truncated, info

    def _faulty(self, obs: np.ndarray) -> np.ndarray:
        out = np.array(obs, dtype=np.float64)
        for j, steps in self.faults.items():
            if self.k in steps:
                out[j] = np.nan
        return out


def faulty_env(faults: Mapping[str, Iterable[int]] | None = None, **kwargs: Any) -> Faulty:
    return Faulty(make_env("kinematic"), faults, **kwargs)


@pytest.fixture(scope="module")
def approach_model() -> SBLM:
    starts = [{"distance": float(x)} for x in np.arange(0.1, 1.01, 0.1)]
    data = collect("approach", starts, sim="kinematic", seed=0)
    return SBLM(inputs=("distance",), epochs=30, random_state=0).fit(data)


@pytest.fixture(scope="module")
def bc_model(turn_data: Dataset) -> BehaviorCloning:
    return BehaviorCloning(inputs=("angle",), epochs=30).fit(turn_data)


def assert_stopped(env: Faulty) -> None:
    assert len(env.actions) > 0
    assert np.all(env.actions[-1] == 0.0)


# ------------------------------------------------------------- stopping on exceptions


@pytest.mark.parametrize("always", [False, True])
def test_env_error_mid_run_stops_the_wheels_and_propagates(turn_model: SBLM, always: bool) -> None:
    # step 31 raises (and with `always` every later step too, the stop included)
    env = faulty_env(raise_after=30, always=always)
    with pytest.raises(RuntimeError, match="motor bus down"):
        turn_model.generate(env, start=TURN_START, seed=0)
    assert len(env.actions) == 32  # 30 steps, the failing 31st, then the stop
    assert np.any(env.actions[-2] != 0.0)  # the wheels were running
    assert_stopped(env)


def test_keyboard_interrupt_stops_the_wheels(turn_model: SBLM) -> None:
    env = faulty_env(raise_after=10, error=KeyboardInterrupt())
    with pytest.raises(KeyboardInterrupt):
        turn_model.generate(env, start=TURN_START, seed=0)
    assert len(env.actions) == 12
    assert_stopped(env)


def test_controller_error_stops_the_wheels(turn_model: SBLM) -> None:
    class Breaks:
        def __init__(self, inner: Any) -> None:
            self.inner, self.goal, self.n = inner, inner.goal, 0
            self.channels = inner.channels

        def reset(self) -> None:
            self.inner.reset()

        def step(self, reading: Mapping[str, float]) -> Any:
            self.n += 1
            if self.n > 20:
                raise ValueError("controller bug")
            return self.inner.step(reading)

    env = faulty_env()
    with pytest.raises(ValueError, match="controller bug"):
        run_policy(Breaks(make_policy(turn_model, None)), env, start=TURN_START)
    assert len(env.actions) == 21  # 20 commands, then the stop
    assert np.any(env.actions[-2] != 0.0)
    assert_stopped(env)


def test_refusal_before_any_motion_sends_nothing(turn_model: SBLM) -> None:
    env = faulty_env()
    with pytest.raises(UnreachableGoalError):
        turn_model.generate(env, start={"angle": -90.0}, goal={"angle": 120.0})
    assert env.actions == []  # nothing commanded: the robot is at rest after the reset


# ------------------------------------------------------------- the sensor-fault policy


def test_channels_read() -> None:
    turn = SimpleNamespace(inputs_=("angle",), stop_at_rest=True)
    bare = SimpleNamespace(inputs_=("angle",), stop_at_rest=False)
    assert channels_read(turn) == ("linear_velocity", "angle", "angular_velocity")
    assert channels_read(bare) == ("angle",)
    inner = SimpleNamespace(inputs_=("angle", "distance"), components_=[bare])
    outer = SimpleNamespace(inputs_=("distance",), components_=[inner, bare])
    assert channels_read(outer) == ("distance", "angle")
    deep = SimpleNamespace(inputs_=("distance",), components_=[inner, turn])
    assert channels_read(deep) == SENSOR_CHANNELS


def test_sensor_hold_counts_steps() -> None:
    hold = SensorHold(SENSOR_CHANNELS, ("angle",), hold_steps=2)
    good = np.array([0.5, 0.0, 10.0, 0.0])
    nan_angle = np.array([np.nan, 0.0, np.nan, 1.0])  # distance is not guarded
    assert hold(good)[1] == 0
    for _ in range(2):
        seen, held = hold(nan_angle)
        assert held == 1 and seen[2] == 10.0 and np.isnan(seen[0]) and not hold.faulted
    hold(nan_angle)
    assert hold.faulted == ["angle"]
    first = SensorHold(SENSOR_CHANNELS, ("angle",), hold_steps=5)
    first(nan_angle)  # no good value yet: a fault at once
    assert first.faulted == ["angle"]


def test_single_nan_mid_turn_is_held(turn_model: SBLM) -> None:
    env = faulty_env({"angle": [40]})
    trace = turn_model.generate(env, start=TURN_START, seed=0)
    assert trace.reason == "goal" and trace.goal_reached
    assert trace.held_readings == 1
    assert trace.held[40] == 1 and np.isnan(trace.readings[40][2])  # recorded as received
    assert trace.summary()["held_readings"] == 1
    assert_stopped(env)


def test_single_nan_on_distance_during_approach_is_held(approach_model: SBLM) -> None:
    env = faulty_env({"distance": [100]})
    trace = approach_model.generate(env, start=APPROACH_START, seed=0)
    assert trace.reason == "goal" and trace.goal_reached
    assert trace.held_readings == 1
    assert_stopped(env)


def test_a_five_step_burst_is_ridden_out(turn_model: SBLM, approach_model: SBLM) -> None:
    env = faulty_env({"angle": range(40, 45)})
    trace = turn_model.generate(env, start=TURN_START, seed=0)
    assert trace.reason == "goal" and trace.goal_reached
    assert trace.held_readings == 5
    env = faulty_env({"distance": range(100, 105)})
    trace = approach_model.generate(env, start=APPROACH_START, seed=0)
    assert trace.reason == "goal" and trace.goal_reached
    assert trace.held_readings == 5


def test_a_permanent_fault_stops_the_robot(turn_model: SBLM, tmp_path: Any) -> None:
    env = faulty_env({"angle": range(40, 100_000)})
    trace = turn_model.generate(env, start=TURN_START, seed=0)
    assert trace.reason == "sensor_fault" and not trace.goal_reached
    assert trace.fault_channels == ["angle"]
    # readings 40..45 held (0.1 s = 6 periods), reading 46 is the fault and the stop
    assert trace.held_readings == HOLD
    assert len(trace) == 40 + HOLD + 1
    assert np.all(trace.command_array[-1] == 0.0) and np.any(trace.command_array[39] != 0.0)
    assert len(env.actions) == len(trace)  # 46 commands, then the stop
    assert_stopped(env)
    # written with the trace: a per-step column and the count in the summary
    path = tmp_path / "fault.parquet"
    trace.write(path)
    table = pq.read_table(path)
    assert table.column("held").to_pylist()[40:] == [1] * HOLD + [0]
    meta = table.schema.metadata[b"behavior_hmm_trace"].decode()
    assert '"held_readings": 6' in meta and '"reason": "sensor_fault"' in meta


@pytest.mark.parametrize(("hold_s", "held"), [(0.0, 0), (0.05, 3), (0.2, 12)])
def test_the_hold_time_is_a_parameter(turn_model: SBLM, hold_s: float, held: int) -> None:
    env = faulty_env({"angle": range(40, 100_000)})
    trace = turn_model.generate(env, start=TURN_START, seed=0, fault_hold_s=hold_s)
    assert trace.reason == "sensor_fault"
    assert trace.held_readings == held and len(trace) == 40 + held + 1
    assert_stopped(env)


def test_bad_hold_time_is_refused(turn_model: SBLM) -> None:
    env = faulty_env()
    for bad in (-0.1, float("nan"), float("inf")):
        with pytest.raises(ConfigError, match="fault_hold_s"):
            turn_model.generate(env, start=TURN_START, fault_hold_s=bad)
    assert env.actions == []
    assert DEFAULT_FAULT_HOLD_S == 0.1


def test_nan_before_any_good_reading_is_a_fault_at_once(turn_model: SBLM) -> None:
    env = faulty_env({"angle": [0]})
    trace = turn_model.generate(env, start=TURN_START, seed=0)
    assert trace.reason == "sensor_fault" and len(trace) == 1 and trace.held_readings == 0
    assert len(env.actions) == 1
    assert_stopped(env)


def test_nan_on_a_channel_not_read_is_harmless(turn_model: SBLM) -> None:
    # the turn model reads angle and, for its stop-at-rest rule, both velocities
    assert channels_read(turn_model) == ("linear_velocity", "angle", "angular_velocity")
    env = faulty_env({"distance": range(1, 100_000)})
    trace = turn_model.generate(env, start=TURN_START, seed=0)
    assert trace.reason == "goal" and trace.goal_reached and trace.held_readings == 0
    # without stop_at_rest the velocities are not read either
    no_rest = copy.copy(turn_model)
    no_rest.stop_at_rest = False
    assert channels_read(no_rest) == ("angle",)
    env = faulty_env({"angular_velocity": range(1, 100_000), "linear_velocity": range(1, 100_000)})
    trace = no_rest.generate(env, start=TURN_START, seed=0)
    assert trace.reason == "goal" and trace.goal_reached and trace.held_readings == 0
    # with it, they are guarded like the angle
    env = faulty_env({"angular_velocity": range(40, 100_000)})
    trace = turn_model.generate(env, start=TURN_START, seed=0)
    assert trace.reason == "sensor_fault" and trace.fault_channels == ["angular_velocity"]


def test_one_percent_random_nan_steps(
    turn_model: SBLM, approach_model: SBLM, rng: np.random.Generator
) -> None:
    for model, channel, start in (
        (turn_model, "angle", TURN_START),
        (approach_model, "distance", APPROACH_START),
    ):
        steps = 2000
        faults = {int(k) for k in np.flatnonzero(rng.random(steps) < 0.01) if k > 0}
        env = faulty_env({channel: faults})
        trace = model.generate(env, start=start, seed=0)
        assert trace.reason == "goal" and trace.goal_reached
        assert trace.held_readings == sum(1 for k in faults if k < len(trace))
        assert_stopped(env)


def test_behavior_cloning_has_the_same_protection(bc_model: BehaviorCloning) -> None:
    assert bc_model.policy().channels == ("angle",)
    env = faulty_env({"angle": [40]})
    trace = bc_model.generate(env, start=TURN_START, seed=0)
    assert trace.goal_reached and trace.held_readings == 1
    env = faulty_env({"angle": range(40, 100_000)})
    trace = bc_model.generate(env, start=TURN_START, seed=0)
    assert trace.reason == "sensor_fault" and len(trace) == 40 + HOLD + 1
    assert_stopped(env)
    env = faulty_env(raise_after=20)
    with pytest.raises(RuntimeError):
        bc_model.generate(env, start=TURN_START, seed=0)
    assert_stopped(env)


def test_complex_behavior_guards_its_components_channels(turn_model: SBLM) -> None:
    approach = SBLM(inputs=("distance", "angle"), epochs=60, random_state=0).fit(
        collect("approach", [{"distance": x} for x in np.arange(0.1, 1.01, 0.1)], sim="kinematic")
    )
    angles = [float(a) for a in range(-160, 181, 40)]
    starts = [{"angle": a, "distance": x} for a in angles for x in (0.2, 0.5, 0.8)]
    starts += [{"angle": 0.0, "distance": x} for x in (0.2, 0.5, 0.8)]
    starts += [{"angle": a, "distance": 0.0} for a in angles]
    cblm = CBLM([turn_model, approach]).fit(collect("turn-approach", starts, sim="kinematic"))
    # the CBLM reads distance and angle; its components' stop rules read the velocities
    assert cblm.inputs_ == ("distance", "angle")
    assert channels_read(cblm) == SENSOR_CHANNELS
    start = {"angle": 60.0, "distance": 0.5}
    env = faulty_env({"angle": [60], "distance": range(100, 105)})
    trace = cblm.generate(env, start=start, seed=0)
    assert trace.reason == "goal" and trace.held_readings == 6
    env = faulty_env({"angular_velocity": range(60, 100_000)})
    trace = perform(cblm, env, start=start, seed=0)
    assert trace.reason == "sensor_fault" and len(trace) == 60 + HOLD + 1
    assert_stopped(env)


def test_the_controller_never_sees_a_nan_on_a_read_channel(turn_model: SBLM) -> None:
    class Spy:
        def __init__(self, inner: Any) -> None:
            self.inner, self.goal, self.seen = inner, inner.goal, []
            self.channels = inner.channels

        def reset(self) -> None:
            self.inner.reset()

        def step(self, reading: Mapping[str, float]) -> Any:
            self.seen.append([reading[c] for c in SENSOR_CHANNELS])
            return self.inner.step(reading)

    spy = Spy(make_policy(turn_model, None))
    env = faulty_env({"angle": range(30, 34), "distance": range(1, 100_000)})
    trace = run_policy(spy, env, start=TURN_START, max_steps=500)
    seen = np.asarray(spy.seen)
    assert trace.reason == "goal" and trace.held_readings == 4
    assert np.all(np.isfinite(seen[:, 1:])) and np.all(np.isnan(seen[1:, 0]))
    assert np.all(seen[30:34, 2] == seen[29, 2])  # the last good angle, held
