"""Motion of the simulated robot: directions, drift, contact, backend agreement, the MJCF file."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from behavior_hmm.sim import MODEL_XML, KheperaEnv, RobotParams, make_env, wrap_degrees
from behavior_hmm.sim._mujoco import MujocoBackend

BACKENDS = ("mujoco", "kinematic")


@pytest.fixture(params=BACKENDS)
def backend(request: pytest.FixtureRequest) -> str:
    return str(request.param)


def drive(env: KheperaEnv, left: float, right: float, seconds: float) -> list[dict]:
    """Hold a command; return the info of every step."""
    action = np.array([left, right])
    steps = round(seconds / env.params.control_period)
    return [env.step(action)[4] for _ in range(steps)]


def test_equal_commands_drift_counter_clockwise(backend: str) -> None:
    env = make_env(backend)
    _, info = env.reset(options={"angle": 0.0, "distance": 1.0})
    yaw0 = info["pose"][2]
    infos = drive(env, -5.0, -5.0, 3.0)  # backwards, away from the object
    dyaw = math.degrees(infos[-1]["pose"][2] - yaw0)
    # right gain 1.005, left 0.995: yaw rate = r * 0.05 / track ~ 1.13 deg/s backwards -> cw
    assert -4.5 < dyaw < -2.0
    straight = make_env(backend, params=RobotParams(wheel_mismatch=0.0))
    straight.reset(options={"angle": 0.0, "distance": 1.0})
    infos = drive(straight, -5.0, -5.0, 3.0)
    assert abs(math.degrees(infos[-1]["pose"][2])) < 0.05


def test_turn_in_place_right_faster_turns_left_toward_object(backend: str) -> None:
    env = make_env(backend)
    env.reset(options={"angle": 60.0, "distance": 0.4})
    observations = [env.step(np.array([-2.0, 2.0]))[0] for _ in range(30)]
    angular = np.array([o[3] for o in observations])
    angles = np.array([o[2] for o in observations])
    assert (angular[1:] > 0).all()
    assert (np.diff(angles) < 0).all() and angles[-1] < 60.0 - 20.0
    # Turning in place barely moves the robot.
    assert abs(observations[-1][0] - 0.4) < 2e-3
    assert abs(observations[-1][1]) < 2e-3


def test_driving_forward_reduces_distance(backend: str) -> None:
    env = make_env(backend)
    env.reset(options={"angle": 0.0, "distance": 0.8})
    observations = [env.step(np.array([6.0, 6.0]))[0] for _ in range(60)]
    distances = np.array([o[0] for o in observations])
    assert (np.diff(distances) < 0).all()
    assert observations[-1][1] == pytest.approx(6.0 * 0.021, rel=0.03)
    assert abs(observations[-1][2]) < 2.0


def test_driving_into_the_object_is_stable(backend: str) -> None:
    env = make_env(backend)
    env.reset(options={"angle": 0.0, "distance": 0.05})
    infos = drive(env, 3.0, 3.0, 2.0)
    true = np.array([i["true_observation"] for i in infos])
    assert np.isfinite(true).all()
    assert true[:, 0].min() >= 0.0
    assert true[-40:, 0].max() < 1e-3  # touching, and staying there
    assert abs(true[-1, 1]) < 0.01  # stopped by the object
    assert abs(true[-1, 2]) < 3.0  # still facing it
    # Backing away works afterwards.
    infos = drive(env, -6.0, -6.0, 1.0)
    assert infos[-1]["true_observation"][0] > 0.05


def test_full_speed_into_the_object_never_breaks(backend: str) -> None:
    # At full speed the MuJoCo wheels out-torque their grip and slip, so the robot may
    # slew around the object; it must never pass through it or blow up.
    env = make_env(backend)
    env.reset(options={"angle": 0.0, "distance": 0.02})
    infos = drive(env, 10.0, 10.0, 3.0) + drive(env, 10.0, 7.0, 1.0)
    true = np.array([i["true_observation"] for i in infos])
    assert np.isfinite(true).all()
    assert true[:, 0].min() >= 0.0
    assert true[40:100, 0].max() < 2e-3  # in contact for a while first
    x, y, _ = infos[-1]["pose"]
    assert math.hypot(x, y) > env.params.contact_distance - 2e-3


def test_grazing_contact_slides_along_the_object(backend: str) -> None:
    env = make_env(backend)
    env.reset(options={"angle": 80.0, "distance": 0.0})
    infos = drive(env, 4.0, 4.0, 2.5)
    true = np.array([i["true_observation"] for i in infos])
    assert np.isfinite(true).all() and true[:, 0].min() >= 0.0
    assert abs(wrap_degrees(true[-1, 2])) > 90.0  # slid past: the object is behind now
    assert true[-1, 0] > 0.01


def test_wheel_speed_follows_first_order_lag(backend: str) -> None:
    params = RobotParams()
    env = make_env(backend, params=params)
    env.reset(options={"distance": 1.0})
    infos = drive(env, 5.0, 5.0, 0.16)
    t = np.array([i["t"] for i in infos])
    left = np.array([i["wheel_speeds"][0] for i in infos])
    target = 5.0 * params.wheel_gains[0]
    expected = target * (1.0 - np.exp(-t / params.motor_time_constant))
    np.testing.assert_allclose(left, expected, atol=0.03 * target)


def _motion(backend: str, left: float, right: float) -> tuple[float, float]:
    env = make_env(backend)
    _, info = env.reset(options={"angle": 180.0, "distance": 0.6})  # facing away
    x0, y0, _ = info["pose"]
    infos = drive(env, left, right, 1.0)
    x, y, _ = infos[-1]["pose"]
    travelled = math.hypot(x - x0, y - y0)
    turned = sum(i["true_observation"][3] for i in infos) * env.params.control_period
    return travelled, turned


@pytest.mark.parametrize(("left", "right"), [(6.0, 6.0), (-4.0, 4.0), (2.0, 6.0)])
def test_backends_agree(left: float, right: float) -> None:
    mj = _motion("mujoco", left, right)
    kin = _motion("kinematic", left, right)
    for a, b in zip(mj, kin, strict=True):
        assert a == pytest.approx(b, rel=0.03, abs=1e-3)


def test_model_file_is_a_valid_mjcf_model() -> None:
    model = mujoco.MjModel.from_xml_path(str(MODEL_XML))
    assert model.nu == 2 and model.nq == 6
    assert model.opt.timestep == pytest.approx(0.002)
    names = {model.geom(i).name for i in range(model.ngeom)}
    assert {"floor", "object", "chassis", "wheel_left", "wheel_right"} <= names


def test_params_resize_the_mujoco_model() -> None:
    params = RobotParams(body_radius=0.05, object_radius=0.08, physics_timestep=0.004)
    env = make_env("mujoco", params=params)
    assert isinstance(env.sim, MujocoBackend)
    model = env.sim.model
    assert model.geom("chassis").size[0] == pytest.approx(0.05)
    assert model.geom("object").size[0] == pytest.approx(0.08)
    assert model.opt.timestep == pytest.approx(0.004)
    _, info = env.reset(options={"distance": 0.1})
    assert info["pose"][0] == pytest.approx(-(0.1 + 0.05 + 0.08))
    infos = drive(env, 3.0, 3.0, 3.0)
    assert infos[-1]["true_observation"][0] < 1e-3
    x, y, _ = infos[-1]["pose"]
    # The sensors and the MuJoCo geometry agree: the chassis geom sits where pose says.
    mujoco.mj_forward(env.sim.model, env.sim.data)  # xpos lags qpos by one mj_step
    np.testing.assert_allclose(env.sim.data.geom("chassis").xpos[:2], [x, y], atol=1e-12)


def test_turning_in_place_against_the_object_stays_physical() -> None:
    """Regression: cylinder-cylinder contact once threw the robot up and spun it at 2000 deg/s
    when the s-curve teacher started a turn while touching the object."""
    from behavior_hmm.sim import make_env
    from behavior_hmm.teach import Teacher

    env = make_env("mujoco")
    teacher = Teacher(env)
    for angle in (-160.0, -120.0, 20.0, 80.0):
        demo = teacher.demonstrate("turn-approach", angle, 0.0, seed=0).as_arrays()
        assert np.max(np.abs(demo["angular_velocity"])) < 120.0  # the teacher turns at 45 deg/s
        assert np.max(np.abs(np.r_[demo["left"], demo["right"]])) < 2.0  # far from 10 rad/s
