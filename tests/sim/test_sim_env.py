"""KheperaEnv interface: gymnasium conformance, reset placement, options, pushes, errors."""

from __future__ import annotations

import importlib
import math
import warnings

import gymnasium
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from hypothesis import given, settings
from hypothesis import strategies as st

import behavior_hmm.sim as sim
from behavior_hmm.data import ARENA_MAX_DISTANCE, SENSOR_CHANNELS, noise_std
from behavior_hmm.errors import ConfigError, SimulationError
from behavior_hmm.sim import (
    ENV_ID,
    KINEMATIC_ENV_ID,
    KheperaEnv,
    RobotParams,
    make_env,
    wrap_degrees,
)
from behavior_hmm.sim._mujoco import MujocoBackend

BACKENDS = ("mujoco", "kinematic")
STOP = np.zeros(2)


def angle_diff(a: float, b: float) -> float:
    """Smallest absolute difference between two angles (deg)."""
    return abs(wrap_degrees(a - b))


@pytest.fixture(params=BACKENDS)
def backend(request: pytest.FixtureRequest) -> str:
    return str(request.param)


@pytest.fixture(scope="module")
def kin_env() -> KheperaEnv:
    return make_env("kinematic")


# ---------------------------------------------------------------- gymnasium conformance
@pytest.mark.parametrize("render_mode", [None, "rgb_array"])
def test_check_env(backend: str, render_mode: str | None) -> None:
    env = make_env(backend, render_mode=render_mode)
    with warnings.catch_warnings():
        # Our action space is in physical units (rad/s) on purpose.
        warnings.filterwarnings("ignore", message=".*symmetric and normalized space.*")
        warnings.filterwarnings("ignore", message=".*alternative render modes.*")
        check_env(env.unwrapped)


def test_spaces_and_observation_layout(backend: str) -> None:
    env = make_env(backend)
    assert env.observation_space.shape == (4,)
    assert env.observation_space.dtype == np.float64
    assert env.action_space.shape == (2,)
    assert isinstance(env.action_space, gymnasium.spaces.Box)
    np.testing.assert_array_equal(env.action_space.high, [10.0, 10.0])
    np.testing.assert_array_equal(env.action_space.low, [-10.0, -10.0])
    assert sim.SENSOR_CHANNELS == ("distance", "linear_velocity", "angle", "angular_velocity")
    obs, info = env.reset(seed=0)
    assert obs.dtype == np.float64 and obs.shape == (4,)
    assert set(info) >= {"t", "step", "true_observation", "pose", "wheel_speeds", "commands"}
    assert info["t"] == 0.0 and info["step"] == 0
    obs, reward, terminated, truncated, info = env.step(np.array([1.0, 1.0]))
    assert reward == 0.0 and terminated is False and truncated is False
    assert info["t"] == pytest.approx(0.016) and info["step"] == 1


def test_registered_ids_make_the_right_backend() -> None:
    for env_id, backend in ((ENV_ID, "mujoco"), (KINEMATIC_ENV_ID, "kinematic")):
        env = gymnasium.make(env_id, noise=0.01)
        assert isinstance(env.unwrapped, KheperaEnv)
        assert env.unwrapped.backend == backend
        assert env.unwrapped.noise == 0.01
        # the robot contract: a Dict of (1,) arrays by channel, info's truth alike
        obs, info = env.reset(seed=3, options={"angle": 45.0})
        assert list(obs) == list(SENSOR_CHANNELS) and obs["angle"].shape == (1,)
        assert info["true_observation"]["angle"][0] == pytest.approx(45.0)
        assert env.unwrapped.control_period == 0.016
        assert set(env.unwrapped.robot_spec) == {"wheel_radius", "track_width", "max_wheel_speed"}
        env.close()


def test_make_honors_max_episode_steps_beyond_the_default() -> None:
    env = gymnasium.make(KINEMATIC_ENV_ID, max_episode_steps=4100)
    env.reset(seed=0)
    truncated = [env.step(np.zeros(2))[3] for _ in range(4100)]
    assert not any(truncated[:-1]) and truncated[-1]
    env = gymnasium.make(KINEMATIC_ENV_ID, max_episode_steps=3)
    env.reset(seed=0)
    assert [env.step(np.zeros(2))[3] for _ in range(3)] == [False, False, True]


def test_reimport_does_not_error() -> None:
    importlib.reload(sim)
    importlib.reload(sim)
    assert ENV_ID in gymnasium.registry and KINEMATIC_ENV_ID in gymnasium.registry


def test_make_env_aliases_and_errors() -> None:
    assert make_env("kinematic").backend == "kinematic"
    assert make_env(KINEMATIC_ENV_ID, noise=0.02).noise == 0.02
    assert make_env(ENV_ID).backend == "mujoco"
    p = RobotParams(wheel_mismatch=0.0)
    assert make_env("kinematic", params=p).params is p
    with pytest.raises(ConfigError, match="unknown simulator 'webots'"):
        make_env("webots")


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"backend": "bullet"}, "unknown backend"),
        ({"noise": -0.1}, "noise must be >= 0"),
        ({"noise": float("nan")}, "noise must be finite"),
        ({"max_episode_steps": 0}, "max_episode_steps must be >= 1"),
        ({"max_episode_steps": 2.5}, "max_episode_steps must be an integer"),
        ({"render_mode": "human"}, "unknown render_mode"),
        ({"params": {"wheel_radius": 0.02}}, "params must be a RobotParams"),
    ],
)
def test_constructor_validation(kwargs: dict[str, object], match: str) -> None:
    kwargs = {"backend": "kinematic", **kwargs}
    with pytest.raises(ConfigError, match=match):
        KheperaEnv(**kwargs)  # type: ignore[arg-type]


# ---------------------------------------------------------------- reset placement
@pytest.mark.parametrize("angle", [-179.5, -90.0, -3.0, 0.0, 45.0, 120.0, 180.0])
@pytest.mark.parametrize("distance", [0.0, 0.3, ARENA_MAX_DISTANCE])
def test_reset_places_robot_exactly(backend: str, angle: float, distance: float) -> None:
    env = make_env(backend, noise=0.05)  # noise must not touch the true observation
    _, info = env.reset(seed=1, options={"angle": angle, "distance": distance})
    true = info["true_observation"]
    assert abs(true[0] - distance) <= 1e-9
    assert abs(true[2] - angle) <= 1e-9
    assert true[1] == 0.0 and true[3] == 0.0
    assert info["wheel_speeds"] == (0.0, 0.0)


def test_reset_minus_180_reads_as_180(backend: str) -> None:
    env = make_env(backend)
    obs, _ = env.reset(options={"angle": -180.0, "distance": 0.4})
    assert obs[2] == pytest.approx(180.0, abs=1e-9)


def test_reset_defaults_and_random_start(kin_env: KheperaEnv) -> None:
    obs, _ = kin_env.reset(seed=0)
    np.testing.assert_allclose(obs, [0.5, 0.0, 0.0, 0.0], atol=1e-12)
    a, _ = kin_env.reset(seed=7, options={"random": True})
    b, _ = kin_env.reset(seed=7, options={"random": True})
    c, _ = kin_env.reset(seed=8, options={"random": True})
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert 0.0 <= a[0] <= ARENA_MAX_DISTANCE and -180.0 <= a[2] <= 180.0
    d, _ = kin_env.reset(seed=7, options={"random": True, "distance": 0.25})
    assert d[0] == pytest.approx(0.25)


@settings(max_examples=50, deadline=None)
@given(
    angle=st.floats(-180.0, 180.0),
    distance=st.floats(0.0, ARENA_MAX_DISTANCE),
)
def test_reset_exact_for_any_start(angle: float, distance: float) -> None:
    env = make_env("kinematic")
    obs, _ = env.reset(options={"angle": angle, "distance": distance})
    assert abs(obs[0] - distance) <= 1e-9
    assert angle_diff(obs[2], angle) <= 1e-9
    assert -180.0 < obs[2] <= 180.0


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"distance": 1.5}, r"start outside the arena: distance 1\.5 m > 1\.2 m"),
        ({"distance": -0.1}, r"start outside the arena: distance -0\.1 m < 0 m"),
        ({"angle": 200.0}, r"start outside the arena: angle 200 deg"),
        ({"angle": -180.5}, r"start outside the arena: angle -180\.5 deg"),
        ({"angle": float("nan")}, "start angle must be finite"),
        ({"distance": "far"}, "start distance must be a number"),
        ({"angel": 10.0}, "unknown reset option"),
        ({"random": "yes"}, "random option must be True or False"),
        ({"noise": -1.0}, "noise option must be >= 0"),
        ({"push": 3}, "push option must be a dict"),
        ({"push": {"step": 0, "angle": 1.0}}, "push step must be an integer >= 1"),
        ({"push": {"step": 2, "yaw": 1.0}}, "unknown push key"),
        ({"push": [{"step": 2, "distance": float("inf")}]}, "push distance must be finite"),
    ],
)
def test_reset_option_validation(
    kin_env: KheperaEnv, options: dict[str, object], match: str
) -> None:
    with pytest.raises(ConfigError, match=match):
        kin_env.reset(options=options)


def test_step_before_reset_is_refused(backend: str) -> None:
    env = make_env(backend)
    with pytest.raises(SimulationError, match="reset"):
        env.step(STOP)
    with pytest.raises(SimulationError, match="reset"):
        env.push(angle=10.0)


def test_truncation_at_max_episode_steps() -> None:
    env = make_env("kinematic", max_episode_steps=3)
    env.reset()
    flags = [env.step(STOP)[3] for _ in range(3)]
    assert flags == [False, False, True]
    assert env.elapsed_steps == 3


# ---------------------------------------------------------------- actions
def test_action_clipping(backend: str) -> None:
    env = make_env(backend)
    env.reset(seed=0)
    clipped = [env.step(np.array([100.0, -100.0]))[0] for _ in range(20)]
    _, _, _, _, info = env.step(np.array([100.0, -100.0]))
    assert info["commands"] == (10.0, -10.0)
    assert max(abs(w) for w in info["wheel_speeds"]) <= 10.0 * 1.005 + 0.05
    env.reset(seed=0)
    limit = [env.step(np.array([10.0, -10.0]))[0] for _ in range(20)]
    np.testing.assert_array_equal(clipped, limit)


def test_action_forms_and_bad_actions(kin_env: KheperaEnv) -> None:
    kin_env.reset(seed=0)
    a = kin_env.step([1.0, 2.0])[0]
    kin_env.reset(seed=0)
    b = kin_env.step(np.array([1.0, 2.0], dtype=np.float32))[0]
    np.testing.assert_array_equal(a, b)
    with pytest.raises(ConfigError, match=r"shape \(2,\)"):
        kin_env.step(np.zeros(3))
    with pytest.raises(ConfigError, match="finite"):
        kin_env.step(np.array([np.nan, 0.0]))
    with pytest.raises(ConfigError, match="2 numbers"):
        kin_env.step(["fast", "slow"])


# ---------------------------------------------------------------- noise and determinism
def test_noise_statistics() -> None:
    sigma = 0.01
    env = make_env("kinematic", noise=sigma)
    obs0, info = env.reset(seed=5, options={"angle": 30.0, "distance": 0.6})
    true = info["true_observation"]
    samples = np.array([obs0] + [env.step(STOP)[0] for _ in range(3000)])
    std = noise_std(sigma)
    expected = np.array([std[name] for name in SENSOR_CHANNELS])
    np.testing.assert_allclose(samples.std(axis=0), expected, rtol=0.06)
    assert np.all(np.abs(samples.mean(axis=0) - true) <= 4 * expected / np.sqrt(len(samples)))
    # The noise-free reading stays exact while the robot is at rest.
    np.testing.assert_allclose(env.step(STOP)[4]["true_observation"], true, atol=1e-12)


def test_noise_option_overrides_and_angle_stays_wrapped() -> None:
    env = make_env("kinematic", noise=0.0)
    obs, info = env.reset(seed=0, options={"angle": 179.0, "noise": 0.05})
    angles = [obs[2]] + [env.step(STOP)[0][2] for _ in range(200)]
    assert all(-180.0 < a <= 180.0 for a in angles)
    assert min(angles) < 0.0 < max(angles)  # wrapped across +-180
    obs, info = env.reset(seed=0, options={"angle": 10.0})
    np.testing.assert_array_equal(obs, info["true_observation"])  # back to noise 0


def _rollout(backend: str, seed: int, noise: float) -> np.ndarray:
    env = make_env(backend, noise=noise)
    obs, _ = env.reset(seed=seed, options={"angle": 40.0, "distance": 0.4})
    actions = np.random.default_rng(123).uniform(-10, 10, size=(60, 2))
    return np.array([obs] + [env.step(a)[0] for a in actions])


def test_same_seed_same_rollout(backend: str) -> None:
    a = _rollout(backend, seed=11, noise=0.02)
    b = _rollout(backend, seed=11, noise=0.02)
    c = _rollout(backend, seed=12, noise=0.02)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_reset_forgets_the_previous_episode(backend: str) -> None:
    env = make_env(backend)
    runs = []
    for _ in range(2):
        env.reset(seed=0, options={"angle": -30.0, "distance": 0.2})
        runs.append([env.step(np.array([4.0, 6.0]))[0] for _ in range(30)])
    np.testing.assert_array_equal(runs[0], runs[1])


# ---------------------------------------------------------------- pushes
def test_public_push_changes_angle_and_distance(backend: str) -> None:
    env = make_env(backend)
    env.reset(options={"angle": 170.0, "distance": 0.5})
    after = env.push(angle=30.0, distance=-0.2)
    assert angle_diff(after[2], -160.0) <= 1e-9
    assert after[0] == pytest.approx(0.3, abs=1e-9)
    obs = env.step(STOP)[0]
    assert angle_diff(obs[2], -160.0) < 1e-3 and obs[0] == pytest.approx(0.3, abs=1e-3)
    # A push into the object stops at contact.
    assert env.push(distance=-1.0)[0] == pytest.approx(0.0, abs=1e-12)


def test_scheduled_pushes(backend: str) -> None:
    env = make_env(backend)
    pushes = [{"step": 5, "angle": -45.0}, {"step": 5, "distance": 0.1}, {"step": 8, "angle": 10}]
    env.reset(options={"angle": 20.0, "distance": 0.3, "push": pushes})
    obs = [env.step(STOP)[0] for _ in range(10)]
    assert obs[3][2] == pytest.approx(20.0, abs=1e-3)
    assert obs[4][2] == pytest.approx(-25.0, abs=1e-3)  # step 5 already shows the push
    assert obs[4][0] == pytest.approx(0.4, abs=1e-3)
    assert obs[7][2] == pytest.approx(-15.0, abs=1e-3)
    # Pushes are per episode: the next reset without the option has none.
    env.reset(options={"angle": 20.0, "distance": 0.3})
    assert [env.step(STOP)[0][2] for _ in range(6)][-1] == pytest.approx(20.0, abs=1e-3)


def test_push_keeps_motion_in_the_robot_frame(backend: str) -> None:
    env = make_env(backend)
    env.reset(options={"angle": 0.0, "distance": 1.0})
    for _ in range(40):
        obs = env.step(np.array([5.0, 5.0]))[0]
    speed = obs[1]
    env.push(angle=90.0)
    obs = env.step(np.array([5.0, 5.0]))[0]
    assert obs[1] == pytest.approx(speed, rel=0.05)


# ---------------------------------------------------------------- failures and rendering
def test_unstable_mujoco_state_raises_simulation_error() -> None:
    env = make_env("mujoco")
    env.reset()
    assert isinstance(env.sim, MujocoBackend)
    env.sim.data.qvel[0] = np.nan
    with pytest.raises(SimulationError, match="MuJoCo became unstable"):
        env.step(STOP)
    with pytest.raises(SimulationError, match="reset"):
        env.step(STOP)  # refused until reset
    env.reset()
    assert np.isfinite(env.step(STOP)[0]).all()


def test_mujoco_warning_counter_is_checked() -> None:
    env = make_env("mujoco")
    env.reset()
    assert isinstance(env.sim, MujocoBackend)
    env.sim.data.warning[mujoco.mjtWarning.mjWARN_CONTACTFULL].number = 1
    with pytest.raises(SimulationError, match="mjWARN_CONTACTFULL"):
        env.step(STOP)


def test_non_finite_kinematic_state_raises_simulation_error() -> None:
    env = make_env("kinematic")
    env.reset()
    env.sim.place(math.nan, 0.0, 0.0)
    with pytest.raises(SimulationError, match="non-finite"):
        env.step(STOP)


def test_render_rgb_array(backend: str) -> None:
    env = make_env(backend, render_mode="rgb_array")
    env.reset(options={"angle": 90.0, "distance": 0.5})
    image = env.render()
    assert image is not None and image.shape == (320, 320, 3) and image.dtype == np.uint8
    env.push(distance=0.4)
    moved = env.render()
    assert moved is not None and not np.array_equal(image, moved)
    assert make_env(backend).render() is None
