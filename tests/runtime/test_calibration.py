"""Wheel calibration on line (``wheel_calibration``): each wheel's gain is estimated from
the measured body speed and yaw rate, and the commands are divided by it."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pytest

from behavior_hmm.data import Dataset
from behavior_hmm.errors import ConfigError
from behavior_hmm.models import SBLM
from behavior_hmm.models._presets import preset_params
from behavior_hmm.runtime import (
    StepOutput,
    Trace,
    WheelCalibration,
    reference_gains,
    run_policy,
    wheel_response,
)
from behavior_hmm.sim import RobotParams, make_env

R, W, TOP = 0.021, 0.053, 10.0  # our Khepera's wheel radius, track (m), top speed (rad/s)


def measured(wheels: np.ndarray) -> tuple[float, float]:
    """Body speed (m/s) and yaw rate (deg/s) of wheels turning at ``wheels`` (rad/s)."""
    left, right = wheels
    return R * (left + right) / 2.0, math.degrees(R * (right - left) / W)


def drive(
    calibration: WheelCalibration,
    gains: np.ndarray,
    commands: np.ndarray,
    noise: tuple[float, float] = (0.0, 0.0),
    seed: int = 0,
) -> np.ndarray:
    """Run ``commands`` through the calibration on wheels with ``gains`` and a lag of
    ``calibration.lag`` cycles, the readings with Gaussian ``noise`` (σ of the body
    speed, m/s, and of the yaw rate, deg/s); return the commands it sent."""
    rng = np.random.default_rng(seed)
    sent: list[np.ndarray] = []
    for u in commands:
        if len(sent) >= calibration.lag:
            speed, yaw_rate = measured(gains * sent[-calibration.lag])
            speed += noise[0] * rng.standard_normal()
            yaw_rate += noise[1] * rng.standard_normal()
            calibration.observe(speed, yaw_rate)
        sent.append(calibration.correct(u))
    return np.asarray(sent)


def wandering(seed: int) -> np.ndarray:
    """400 cycles about 3 rad/s per wheel, a new command every 10 cycles."""
    rng = np.random.default_rng(seed)
    return 3.0 + np.repeat(rng.normal(0.0, 0.3, (40, 2)), 10, axis=0)


#: Sensor noise 0.02 of our channels' ranges: 0.006 m/s on the speed, 3.6 deg/s on the yaw rate.
NOISE_002 = (0.006, 3.6)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_difference_within_the_readings_noise_is_left_alone(seed: int) -> None:
    # equal wheels read through noise: the estimate wanders (by up to 0.03 here), and
    # correcting it would curve a straight command; it stays within its errors
    calibration = WheelCalibration(R, W, TOP)
    commands = wandering(seed)
    sent = drive(calibration, np.ones(2), commands, noise=NOISE_002, seed=seed)
    assert np.ptp(np.log(calibration.measured_gains)) > 0.0  # it did wander
    np.testing.assert_array_equal(sent, commands)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_mismatch_beyond_the_readings_noise_is_corrected(seed: int) -> None:
    calibration = WheelCalibration(R, W, TOP)
    gains = np.array([0.8, 1.2])
    drive(calibration, gains, wandering(seed), noise=NOISE_002, seed=seed)
    np.testing.assert_allclose(calibration.gains, gains, atol=0.03)


def test_the_gains_converge_and_the_wheels_turn_as_asked() -> None:
    calibration = WheelCalibration(R, W, TOP)
    gains = np.array([0.8, 1.2])
    sent = drive(calibration, gains, np.tile([3.0, 2.0], (200, 1)))
    np.testing.assert_allclose(calibration.gains, gains, rtol=1e-3)
    # the first commands are the behavior's own (gains 1 before anything is measured) ...
    np.testing.assert_array_equal(sent[0], [3.0, 2.0])
    # ... and once calibrated the wheels turn at the speeds asked for
    np.testing.assert_allclose(gains * sent[-1], [3.0, 2.0], rtol=1e-3)


def test_a_wheel_that_never_turns_keeps_gain_one() -> None:
    calibration = WheelCalibration(R, W, TOP)
    drive(calibration, np.array([0.7, 1.3]), np.tile([0.0, 3.0], (200, 1)))
    np.testing.assert_allclose(calibration.measured_gains, [1.0, 1.3], rtol=1e-3)
    np.testing.assert_allclose(calibration.gains, [1.0 / 1.15, 1.3 / 1.15], rtol=1e-3)


def test_a_gain_both_wheels_share_is_left_alone() -> None:
    calibration = WheelCalibration(R, W, TOP)
    sent = drive(calibration, np.array([0.6, 0.6]), np.tile([3.0, 3.0], (200, 1)))
    np.testing.assert_allclose(calibration.measured_gains, [0.6, 0.6], rtol=1e-3)
    np.testing.assert_allclose(sent[-1], [3.0, 3.0], rtol=1e-9)


def test_a_wheel_learns_only_from_commands_it_has_held() -> None:
    calibration = WheelCalibration(R, W, TOP)
    ramp = np.column_stack([np.linspace(0.1, 5.0, 100), np.full(100, 3.0)])
    drive(calibration, np.array([0.8, 1.2]), ramp)
    # the speeding-up left wheel has learned nothing; the steady right one has
    assert calibration.measured_gains[0] == pytest.approx(1.0)
    assert calibration.measured_gains[1] == pytest.approx(1.2, rel=1e-3)
    # its command then held: it learns
    drive(calibration, np.array([0.8, 1.2]), np.tile([5.0, 3.0], (100, 1)))
    np.testing.assert_allclose(calibration.measured_gains, [0.8, 1.2], rtol=1e-3)


def test_gains_stay_within_bounds_and_commands_within_the_top_speed() -> None:
    calibration = WheelCalibration(R, W, TOP)
    sent = drive(calibration, np.array([0.1, 1.0]), np.tile([8.0, 8.0], (200, 1)))
    assert calibration.measured_gains[0] == pytest.approx(0.5)  # the lower bound, not 0.1
    assert sent[-1][0] == pytest.approx(TOP)  # 8 / (0.5 / 0.75) = 12 rad/s asked, 10 sent
    calibration.reset()
    np.testing.assert_array_equal(calibration.gains, [1.0, 1.0])


@pytest.mark.parametrize(
    "kwargs",
    [
        {"lag": 0},
        {"steady": -1},
        {"forget": 0.0},
        {"forget": 1.5},
        {"prior": 0.0},
        {"bounds": (1.2, 2.0)},
    ],
)
def test_bad_settings_are_refused(kwargs: dict[str, object]) -> None:
    with pytest.raises(ConfigError, match="wheel calibration"):
        WheelCalibration(R, W, TOP, **kwargs)  # type: ignore[arg-type]


class Straight:
    """Drives both wheels at 3 rad/s, never done."""

    goal = {"angle": 0.0}  # noqa: RUF012 - read-only
    channels = ("angle",)

    def reset(self) -> None:
        pass

    def step(self, reading: Mapping[str, float]) -> StepOutput:
        return StepOutput(np.array([3.0, 3.0]), -1, False, 0, "", False, False)


def test_a_mismatched_robot_drives_straight_once_calibrated() -> None:
    env = make_env("kinematic", params=RobotParams(wheel_mismatch=0.4))
    start = {"angle": 0.0, "distance": 0.8}
    plain = run_policy(Straight(), env, start=start, max_steps=120)
    calibrated = run_policy(Straight(), env, start=start, max_steps=120, wheel_calibration=True)
    angle = plain.channels.index("angle")

    def turned(trace: Trace) -> float:
        """Degrees the bearing changed over the run's last 50 cycles."""
        bearing = trace.reading_array[:, angle]
        return float(abs(bearing[-1] - bearing[-51]))

    # 0.4 of mismatch turns the robot about 27°/s: 20° in the last 0.8 s; calibrated
    # (after its first 10 cycles: 8 of a held command, 2 of lag) it drives straight
    assert turned(plain) > 15.0
    assert turned(calibrated) < 0.5
    assert abs(calibrated.final_observation[angle]) < 0.2 * abs(plain.final_observation[angle])
    assert plain.wheel_gains is None and "wheel_gains" not in plain.summary()
    assert calibrated.wheel_gains == pytest.approx([0.8, 1.2], rel=0.02)
    assert calibrated.summary()["wheel_gains"] == calibrated.wheel_gains
    # the trace holds the commands sent: the weaker left wheel is driven harder
    last = calibrated.command_array[-1]
    assert last[0] > 3.0 > last[1]


def test_a_robot_that_cannot_be_calibrated_runs_uncorrected_with_a_warning() -> None:
    env = make_env("kinematic")
    env.__class__ = type("NoGeometry", (type(env),), {"robot_spec": None})
    with pytest.warns(RuntimeWarning, match="wheel_calibration is off: .*no wheel geometry"):
        trace = run_policy(
            Straight(),
            env,
            start={"angle": 0.0, "distance": 0.8},
            max_steps=5,
            wheel_calibration=True,
        )
    assert trace.wheel_gains is None
    np.testing.assert_array_equal(trace.command_array, np.tile([3.0, 3.0], (5, 1)))


def test_the_model_parameter_is_checked_and_reaches_the_loop(turn_model: SBLM) -> None:
    with pytest.raises(ConfigError, match="wheel_calibration must be true or false"):
        SBLM(inputs=("angle",), wheel_calibration="yes").check_params()  # type: ignore[arg-type]
    env = make_env("kinematic", params=RobotParams(wheel_mismatch=0.3))
    start = {"angle": 90.0, "distance": 0.5}
    # on in the default preset, off in the thesis's
    assert turn_model.wheel_calibration is True
    assert preset_params("thesis", "SBLM")["wheel_calibration"] is False
    assert preset_params("thesis", "CBLM")["wheel_calibration"] is False
    calibrated = turn_model.generate(env, start=start)
    turn_model.set_params(wheel_calibration=False)
    try:
        plain = turn_model.generate(env, start=start)
    finally:
        turn_model.set_params(wheel_calibration=True)
    assert plain.wheel_gains is None
    assert calibrated.goal_reached and calibrated.wheel_gains is not None
    # turning in place, the right wheel's larger gain is seen and corrected
    assert calibrated.wheel_gains[1] > calibrated.wheel_gains[0]


def demonstrations(
    gains: np.ndarray, episodes: int = 3
) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Commands and (v, ω) readings of wheels with ``gains``: each episode ramps up, holds
    and turns, the readings trailing the commands by ``CALIBRATION_LAG`` cycles."""
    from behavior_hmm.runtime._calibration import CALIBRATION_LAG

    rows, readings, lengths = [], [], []
    for e in range(episodes):
        u = np.vstack(
            [
                np.column_stack([np.linspace(0, 3, 20), np.linspace(0, 3, 20)]),
                np.tile([3.0, 3.0 + 0.2 * e], (60, 1)),
                np.tile([-2.0, 2.0], (40, 1)),
            ]
        )
        delayed = np.vstack([np.zeros((CALIBRATION_LAG, 2)), u[:-CALIBRATION_LAG]])
        readings.append(np.array([measured(gains * c) for c in delayed]))
        rows.append(u)
        lengths.append(len(u))
    return np.vstack(rows), np.vstack(readings), lengths


def test_the_demonstrated_gains_come_back_from_the_demonstrations() -> None:
    gains = np.array([0.95, 1.05])
    commands, readings, lengths = demonstrations(gains)
    sums = wheel_response(commands, readings[:, 0], readings[:, 1], lengths)
    np.testing.assert_allclose(reference_gains(sums, R, W), gains, rtol=1e-9)
    # sums add up: two halves give the sums of the whole
    half = wheel_response(commands[:240], readings[:240, 0], readings[:240, 1], lengths[:2])
    rest = wheel_response(commands[240:], readings[240:, 0], readings[240:, 1], lengths[2:])
    np.testing.assert_allclose(half + rest, sums, rtol=1e-12)
    # a wheel never seen turning keeps gain 1
    still = wheel_response(np.zeros((50, 2)), np.zeros(50), np.zeros(50), [50])
    np.testing.assert_array_equal(reference_gains(still, R, W), [1.0, 1.0])


def test_the_demonstrated_robot_is_restored_not_an_ideal_one() -> None:
    demonstrated = np.array([0.95, 1.05])
    # the same robot as demonstrated: the learned commands go out unchanged
    same = WheelCalibration(R, W, TOP, reference=demonstrated)
    sent = drive(same, demonstrated, np.tile([3.0, 2.9], (200, 1)))
    np.testing.assert_allclose(sent[-1], [3.0, 2.9], rtol=1e-4)  # the prior's fading trace
    # a robot whose right wheel is 20 % stronger than demonstrated: it is brought back
    changed = WheelCalibration(R, W, TOP, reference=demonstrated)
    stronger = demonstrated * np.array([1.0, 1.2])
    sent = drive(changed, stronger, np.tile([3.0, 2.9], (200, 1)))
    turned = stronger * sent[-1]
    expected = demonstrated * np.array([3.0, 2.9])
    np.testing.assert_allclose(turned / turned.mean(), expected / expected.mean(), rtol=1e-4)


def test_models_keep_how_the_demonstrated_wheels_answered(
    turn_model: SBLM, turn_data: Dataset, tmp_path: Path
) -> None:
    from behavior_hmm.errors import ModelFileError
    from behavior_hmm.models import CBLM, _modelfile
    from behavior_hmm.models._sblm import demonstrated_wheel_response

    sums = turn_model.wheel_response_
    np.testing.assert_array_equal(sums, demonstrated_wheel_response(turn_data))
    # turning in place on the kinematic robot: both wheels answer alike
    spec = make_env("kinematic").unwrapped.robot_spec
    gains = reference_gains(sums, spec["wheel_radius"], spec["track_width"])
    assert gains[1] / gains[0] == pytest.approx(1.005 / 0.995, rel=1e-3)  # mismatch 0.01
    turn_model.save(tmp_path / "t.bhmm")
    assert SBLM.load(tmp_path / "t.bhmm").wheel_response_.tobytes() == sums.tobytes()
    # a CBLM's are its components' added up
    composed = CBLM()
    composed.components_ = [turn_model, turn_model]
    np.testing.assert_array_equal(composed.wheel_response_, 2 * sums)
    # a file whose sums are not 2 x 3 is refused
    header, arrays = _modelfile.load(tmp_path / "t.bhmm")
    arrays = {**arrays, "wheel_response": np.zeros((3, 3))}
    _modelfile.dump(tmp_path / "bad.bhmm", "SBLM", header["params"], header["state"], arrays)
    with pytest.raises(ModelFileError, match="wheel_response"):
        SBLM.load(tmp_path / "bad.bhmm")
