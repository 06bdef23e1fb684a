"""Goal braking (SBLM ``goal_braking``) and settling (CBLM ``settle_cycles``).

A generator that arrives at its goal too fast is the situation goal braking exists for;
here it is made certain by replacing the approach generator's output with a constant
cruise command, and the robot is a one-dimensional point that drives toward the object
exactly as commanded (no simulator): what the policy does is all that is tested.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from behavior_hmm.data import DISTANCE_TOLERANCE_M
from behavior_hmm.evaluate._metrics import command_jump
from behavior_hmm.models import CBLM, SBLM
from behavior_hmm.teach import collect

WHEEL_RADIUS_M = 0.0205
PERIOD_S = 0.016


@pytest.fixture(scope="module")
def approach_data() -> Any:
    return collect(
        "approach", [{"distance": x} for x in np.arange(0.1, 1.01, 0.15)], sim="kinematic"
    )


@pytest.fixture(scope="module")
def approach(approach_data: Any) -> SBLM:
    return SBLM(inputs=("distance", "angle"), epochs=30).fit(approach_data)


def _cruise(
    model: SBLM, braking: bool, cruise: float, lag_s: float = 0.0
) -> tuple[np.ndarray, list[float], bool, float]:
    """Drive a point robot from 0.15 m with the policy's generator stuck at ``cruise``.

    The wheels follow the command with a first-order lag of ``lag_s`` seconds (0: at
    once). Returns the commands, the distances, whether the policy finished and the
    robot's speed (m/s) when it did.
    """
    model.set_params(goal_braking=braking)
    policy = model.policy({"distance": 0.0})
    policy._generator = _Stuck(cruise)  # a generator that never slows down by itself
    d, u, wheels = 0.15, np.zeros(2), np.zeros(2)
    commands, distances, done = [], [], False
    for _ in range(600):
        v = WHEEL_RADIUS_M * float(np.mean(wheels))
        out = policy.step(
            {"distance": d, "angle": 0.0, "linear_velocity": v, "angular_velocity": 0.0}
        )
        if out.done:
            done = True
            commands.append(np.zeros(2))
            break
        u = out.command
        commands.append(u)
        wheels = u if lag_s == 0 else wheels + (u - wheels) * min(1.0, PERIOD_S / lag_s)
        d = max(d - WHEEL_RADIUS_M * float(np.mean(wheels)) * PERIOD_S, -0.05)
        distances.append(d)
    return np.array(commands), distances, done, v


class _Stuck:
    """Stands in for a model's motion generators: the same output for any input."""

    def __init__(self, value: float) -> None:
        self.value = np.array([value, value])

    def step(self, x: Any, state: int) -> np.ndarray:
        return self.value.copy()

    def reset(self) -> None:
        pass


def test_braking_ramps_to_rest_inside_the_goal(approach: SBLM) -> None:
    cruise = 0.6  # normalized: 0.6 x the demonstrations' largest command
    commands, distances, done, _ = _cruise(approach, True, cruise)
    policy = approach.policy({"distance": 0.0})
    rate = policy._rate
    assert rate > 0
    assert done, "the braked robot must stop at its goal"
    # never a change larger than the rate limit, the stop included
    assert command_jump(commands) <= rate * (1 + 1e-9)
    # at rest inside the goal's tolerance and never through the object
    assert abs(distances[-1]) <= DISTANCE_TOLERANCE_M
    assert min(distances) > -DISTANCE_TOLERANCE_M
    # it was cruising, then ramped down at the rate limit
    top = cruise * approach.command_scale_
    assert np.max(commands) == pytest.approx(top)
    ramp = np.diff(commands[:, 0])[np.argmax(commands[:, 0]) :]
    assert np.all(ramp <= 1e-12) and np.min(ramp) == pytest.approx(-rate)


def test_braking_allows_for_the_filters_lag(approach_data: Any) -> None:
    """A slow filter (1 Hz: readings 14 cycles behind a moving robot) at full speed:
    braking starts from where the robot is, not where its filtered readings say it was,
    so it still comes to rest inside the goal and never drives into the object."""
    slow = SBLM(inputs=("distance", "angle"), epochs=30, cutoff_hz=1.0).fit(approach_data)
    assert slow.policy({"distance": 0.0})._lag > 13
    commands, distances, done, _ = _cruise(slow, True, 1.0)
    assert done
    assert abs(distances[-1]) <= DISTANCE_TOLERANCE_M
    assert min(distances) > -DISTANCE_TOLERANCE_M
    assert command_jump(commands) <= slow.policy({"distance": 0.0})._rate * (1 + 1e-9)


def test_without_braking_the_robot_arrives_at_speed(approach: SBLM) -> None:
    commands, distances, done, _ = _cruise(approach, False, 0.6)
    # the stuck generator keeps cruising through the goal (into the object)
    assert min(distances) < -DISTANCE_TOLERANCE_M
    assert np.max(commands[-5:]) == pytest.approx(0.6 * approach.command_scale_) or done


def test_braked_robot_on_slow_wheels_is_done_only_at_rest(approach: SBLM) -> None:
    """With a 0.15 s wheel lag the robot coasts after the ramp: done waits for rest."""
    from behavior_hmm.data._channels import TOLERANCES

    _, distances, done, speed = _cruise(approach, True, 0.6, lag_s=0.15)
    assert done
    assert abs(speed) <= TOLERANCES["linear_velocity"]
    assert abs(distances[-1]) <= DISTANCE_TOLERANCE_M


def test_braking_is_a_parameter_of_the_presets() -> None:
    from behavior_hmm.models._presets import preset_params

    assert preset_params("default", "SBLM")["goal_braking"] is True
    assert preset_params("thesis", "SBLM")["goal_braking"] is False
    assert preset_params("default", "CBLM")["settle_cycles"] == 64
    assert preset_params("thesis", "CBLM")["settle_cycles"] == 0


def test_complex_behavior_finishes_at_rest(kinematic_env: Any) -> None:
    """Turn & approach whose approach arrives too fast: stopped at rest, not at speed."""
    from behavior_hmm.runtime import run_policy

    turn = SBLM(inputs=("angle",), epochs=30).fit(
        collect("turn", [{"angle": a} for a in range(-170, 181, 40)], sim="kinematic")
    )
    approach = SBLM(inputs=("distance", "angle"), epochs=30).fit(
        collect("approach", [{"distance": x} for x in np.arange(0.1, 1.01, 0.15)], sim="kinematic")
    )
    starts = [{"angle": a, "distance": x} for a in (-120.0, 0.0, 80.0) for x in (0.3, 0.7)]
    data = collect("turn-approach", starts, sim="kinematic")
    jumps = {}
    for settle in (64, 0):
        for component in (turn, approach):
            component.set_params(goal_braking=settle > 0)
        policy = CBLM([turn, approach], settle_cycles=settle).fit(data).policy(None)
        policy._children[1]._generator = _Stuck(0.4)  # an approach that never slows down
        trace = run_policy(policy, kinematic_env, start={"angle": 0.0, "distance": 0.3}, seed=0)
        assert trace.goal_reached and "approach" in trace.component
        jumps[settle] = command_jump(trace.command_array) / policy._children[1]._rate
    assert jumps[64] <= 1.0 + 1e-9
    assert jumps[0] > 4.0  # without either, the robot is stopped at speed


def test_command_rates_are_the_robots_kinematics(approach: SBLM, tmp_path: Any) -> None:
    """The learned command-to-rate gains match the robot: d(distance) = -r dt (l + r) / 2."""
    from behavior_hmm.runtime import Robot
    from behavior_hmm.sim import make_env

    spec = Robot(make_env("kinematic")).spec
    per_wheel = -spec.wheel_radius * PERIOD_S / 2.0  # m per cycle per rad/s of one wheel
    distance = approach.command_rates_[:, 0]
    assert distance == pytest.approx([per_wheel, per_wheel], rel=0.15)
    approach.save(tmp_path / "a.bhmm")
    assert np.array_equal(SBLM.load(tmp_path / "a.bhmm").command_rates_, approach.command_rates_)


def _creep(
    model: SBLM, angle: float, command: np.ndarray, monkeypatch: Any
) -> tuple[bool, float, np.ndarray]:
    """Run the turn policy on a robot whose bearing moves exactly as the model's learned
    ``command_rates_`` say, with its generator stuck at ``command`` (rad/s) and no
    category a goal candidate (the stop rule's category test never holds, as in the
    category a primitive crept in, 2.3 deg off, in the case ``_stalled`` names).

    Returns whether the policy finished, the final bearing (deg) and the commands.
    """
    monkeypatch.setattr(
        type(model.policy({"angle": 0.0})),
        "_stop_set",
        property(lambda self: frozenset(), lambda self, value: None),
        raising=False,
    )
    policy = model.policy({"angle": 0.0})
    policy._generator = _Stuck(0.0)
    policy._generator.value = np.asarray(command, dtype=np.float64) / model.command_scales_
    i = list(policy._channels).index("angle")
    u, commands, done = np.zeros(2), [], False
    for _ in range(600):
        rates = u @ model.command_rates_  # each input's change per cycle at this command
        reading = {
            "angle": angle,
            "angular_velocity": float(rates[i]) / PERIOD_S,
            "distance": 0.5,
            "linear_velocity": WHEEL_RADIUS_M * float(np.mean(u)),
        }
        out = policy.step(reading)
        if out.done:
            done = True
            break
        u = out.command
        commands.append(u)
        angle += float((u @ model.command_rates_)[i])
    return done, angle, np.array(commands)


def test_a_run_that_creeps_inside_the_tolerance_without_closing_ends_there(
    turn_model: SBLM, monkeypatch: Any
) -> None:
    """2 deg off (inside the 3 deg tolerance), the generator creeps forward on equal
    wheels, which does not turn the robot: without the stall rule the run never ends
    (the robot creeps on until the step limit, and a complex behavior never gets to its
    next component); with it, it brakes to rest there, within the rate limit."""
    from behavior_hmm.data import ANGLE_TOLERANCE_DEG
    from behavior_hmm.models._policy import STALL_HOLD_CYCLES

    creep = np.array([0.5, 0.5])  # rad/s, both wheels: forward, no turn
    done, angle, commands = _creep(turn_model, 2.0, creep, monkeypatch)
    assert done
    assert abs(angle) <= ANGLE_TOLERANCE_DEG
    assert STALL_HOLD_CYCLES <= len(commands) < 60
    assert np.all(np.abs(commands[-1]) < np.abs(creep))  # ramped down, not cut at speed
    policy = turn_model.policy({"angle": 0.0})
    assert command_jump(np.vstack([commands, np.zeros(2)])) <= policy._rate * (1 + 1e-9)


def test_a_slow_turn_that_closes_on_the_goal_is_not_a_stall(
    turn_model: SBLM, monkeypatch: Any
) -> None:
    """A turn inside the tolerance that closes on its goal (in ~200 cycles, under
    ``STALL_CYCLES``) goes on to the goal instead of stopping where it is."""
    policy = turn_model.policy({"angle": 0.0})
    k = list(policy._channels).index("angle")
    unit = np.array([-1.0, 1.0])
    per_cycle = float((unit @ turn_model.command_rates_)[k])  # deg per cycle at 1 rad/s
    # 2.9 deg closed in ~200 cycles: the sign that reduces the bearing
    command = unit * (-2.9 / 200.0) / per_cycle
    done, angle, _ = _creep(turn_model, 2.9, command, monkeypatch)
    assert done
    assert abs(angle) < 1.0, f"stopped at {angle:.2f} deg: a closing turn was taken for a stall"
