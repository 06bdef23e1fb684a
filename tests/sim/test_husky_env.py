"""HuskyEnv (PyBullet Clearpath Husky): robot contract, physics signs, pushes, closed loop."""

from __future__ import annotations

import math
import subprocess
import sys
import warnings
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

pytest.importorskip("pybullet")

from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

from behavior_hmm.errors import ConfigError, SimulationError
from behavior_hmm.sim._husky import CHANNELS, HuskyEnv, make_husky

STOP = np.zeros(2)


def angle_diff(a: float, b: float) -> float:
    """Smallest absolute difference between two angles (deg)."""
    return abs((a - b + 180.0) % 360.0 - 180.0)


def values(obs: dict[str, np.ndarray]) -> dict[str, float]:
    return {name: float(obs[name][0]) for name in CHANNELS}


def true_values(info: dict[str, Any]) -> dict[str, float]:
    return values(info["true_observation"])


@pytest.fixture(scope="module")
def env() -> Iterator[HuskyEnv]:
    environment = make_husky()
    yield environment
    environment.close()


def run(env: HuskyEnv, action: Any, steps: int) -> tuple[dict[str, float], dict[str, Any]]:
    obs: dict[str, np.ndarray] = {}
    info: dict[str, Any] = {}
    for _ in range(steps):
        obs, _, _, _, info = env.step(np.asarray(action, dtype=np.float64))
    return values(obs), info


# ---------------------------------------------------------------- contract
def test_spaces_and_attributes(env: HuskyEnv) -> None:
    space = env.observation_space
    assert isinstance(space, spaces.Dict)
    assert tuple(space.keys()) == CHANNELS
    for name in CHANNELS:
        box = space[name]
        assert isinstance(box, spaces.Box)
        assert box.shape == (1,) and box.dtype == np.float64
    assert isinstance(env.action_space, spaces.Box) and env.action_space.shape == (2,)
    unwrapped: Any = env.unwrapped  # the contract's attributes live on the unwrapped env
    assert unwrapped is env
    spec = unwrapped.robot_spec
    assert set(spec) >= {"wheel_radius", "track_width", "max_wheel_speed"}
    lim = spec["max_wheel_speed"]
    np.testing.assert_array_equal(env.action_space.high, [lim, lim])
    np.testing.assert_array_equal(env.action_space.low, [-lim, -lim])
    assert 0.9 <= spec["wheel_radius"] * lim <= 1.1  # about 1 m/s top speed
    assert spec["track_width"] > spec["geometric_track"]
    assert unwrapped.control_period == pytest.approx(0.016)
    assert set(unwrapped.channel_ranges) == set(CHANNELS)
    for lo, hi in unwrapped.channel_ranges.values():
        assert lo < hi
    assert unwrapped.start_scale["distance"] > 1.0

    obs, info = env.reset(seed=0)
    assert space.contains(obs)
    assert set(info) >= {"t", "step", "true_observation", "pose", "wheel_speeds", "commands"}
    obs, reward, terminated, truncated, info = env.step(np.array([1.0, 1.0]))
    assert space.contains(obs) and space.contains(info["true_observation"])
    assert reward == 0.0 and terminated is False and truncated is False
    assert info["t"] == pytest.approx(0.016) and info["step"] == 1
    assert len(info["pose"]) == 3


def test_gymnasium_check_env() -> None:
    husky = make_husky()
    try:
        with warnings.catch_warnings():
            # The action space is in physical units (rad/s) on purpose.
            warnings.filterwarnings("ignore", message=".*symmetric and normalized space.*")
            warnings.filterwarnings("ignore", message=".*render.*")
            check_env(husky)
    finally:
        husky.close()


def test_commands_are_clipped(env: HuskyEnv) -> None:
    env.reset(options={"angle": 0.0, "distance": 5.0})
    _, info = run(env, [100.0, -100.0], 1)
    lim = env.robot_spec["max_wheel_speed"]
    assert info["commands"] == (lim, -lim)


@pytest.mark.parametrize(
    ("angle", "distance"),
    [(0.0, 0.0), (180.0, 0.0), (-180.0, 0.1), (-135.0, 0.1), (90.0, 0.1), (-5.0, 0.1)]
    + [(a, d) for a in (-150.0, -30.0, 0.0, 30.0, 90.0, 180.0) for d in (0.5, 2.0, 5.0)],
)
def test_reset_places_robot_at_rest(env: HuskyEnv, angle: float, distance: float) -> None:
    obs, info = env.reset(options={"angle": angle, "distance": distance})
    true = true_values(info)
    assert values(obs) == true
    assert angle_diff(true["angle"], angle) < 0.5
    assert true["distance"] == pytest.approx(distance, abs=0.005)
    assert true["linear_velocity"] == 0.0 and true["angular_velocity"] == 0.0
    # At rest: standing still for half a second hardly moves it.
    obs_after, _ = run(env, STOP, 30)
    assert angle_diff(obs_after["angle"], angle) < 0.5
    assert obs_after["distance"] == pytest.approx(distance, abs=0.005)


def test_unknown_and_bad_options_raise(env: HuskyEnv) -> None:
    with pytest.raises(ValueError, match="unknown reset option") as err:
        env.reset(options={"angel": 3.0})
    assert "\n" not in str(err.value)
    with pytest.raises(ConfigError, match="push key"):
        env.reset(options={"push": [{"step": 1, "yaw": 3.0}]})
    with pytest.raises(ConfigError, match="push step"):
        env.reset(options={"push": {"step": 0, "angle": 3.0}})
    with pytest.raises(ConfigError, match="start distance"):
        env.reset(options={"distance": -1.0})
    with pytest.raises(ConfigError, match="into the object"):
        env.reset(options={"angle": 30.0, "distance": 0.0})  # a front corner reaches it
    with pytest.raises(ConfigError, match="noise"):
        env.reset(options={"noise": -0.1})
    env.reset()
    with pytest.raises(ConfigError, match="shape"):
        env.step(np.zeros(3))


# ---------------------------------------------------------------- physics signs
def test_full_forward_approaches_the_object(env: HuskyEnv) -> None:
    env.reset(options={"angle": 0.0, "distance": 4.0})
    lim = env.robot_spec["max_wheel_speed"]
    obs, _ = run(env, [lim, lim], 60)  # ~1 s
    assert obs["distance"] < 4.0 - 0.5
    top = env.robot_spec["wheel_radius"] * lim
    assert obs["linear_velocity"] == pytest.approx(top, rel=0.05)
    assert abs(obs["angle"]) < 1.0 and abs(obs["angular_velocity"]) < 5.0
    lo, hi = env.channel_ranges["linear_velocity"]
    assert lo < -top and top < hi
    # Reverse drives away.
    env.reset(options={"angle": 0.0, "distance": 1.0})
    obs, _ = run(env, [-lim, -lim], 60)
    assert obs["distance"] > 1.5 and obs["linear_velocity"] < -0.9 * top


def test_driving_into_the_object_stops_at_distance_zero(env: HuskyEnv) -> None:
    """The front surface of the collision box is where distance 0 is."""
    env.reset(options={"angle": 0.0, "distance": 0.5})
    obs, info = run(env, [3.0, 3.0], 150)
    x, y, _ = info["pose"]
    gap = math.hypot(x, y) - (0.5 * 1.0074 + 0.15)
    assert obs["distance"] == pytest.approx(0.0, abs=0.005)
    assert abs(gap) < 0.01
    assert abs(obs["linear_velocity"]) < 0.02


def test_left_slower_than_right_turns_ccw(env: HuskyEnv) -> None:
    # Object on the left (bearing +30): turning counter-clockwise brings it towards 0.
    env.reset(options={"angle": 30.0, "distance": 3.0})
    obs, _ = run(env, [-2.0, 2.0], 20)
    assert obs["angular_velocity"] > 20.0
    assert 0.0 < obs["angle"] < 30.0 - 5.0
    # And clockwise (left faster) turns it further away.
    env.reset(options={"angle": 30.0, "distance": 3.0})
    obs, _ = run(env, [2.0, -2.0], 20)
    assert obs["angular_velocity"] < -20.0
    assert obs["angle"] > 30.0 + 5.0
    # Forward along an arc: left < right also turns CCW.
    env.reset(options={"angle": 30.0, "distance": 3.0})
    obs, _ = run(env, [1.0, 3.0], 30)
    assert obs["angular_velocity"] > 0.0 and obs["linear_velocity"] > 0.0


def test_effective_track_matches_a_turn_in_place(env: HuskyEnv) -> None:
    r = env.robot_spec["wheel_radius"]
    lo, hi = env.channel_ranges["angular_velocity"]
    for wheel in (1.0, 4.0, env.robot_spec["max_wheel_speed"]):
        env.reset(options={"angle": 0.0, "distance": 4.0})
        rates = []
        for _ in range(150):
            _, _, _, _, info = env.step(np.array([-wheel, wheel]))
            rates.append(true_values(info)["angular_velocity"])
        yaw_rate = math.radians(float(np.mean(rates[30:])))
        track = 2.0 * r * wheel / yaw_rate
        assert track == pytest.approx(env.robot_spec["track_width"], rel=0.05)
        assert lo < -math.degrees(yaw_rate) and math.degrees(yaw_rate) < hi


# ---------------------------------------------------------------- pushes, noise, determinism
def test_push_changes_bearing_and_distance(env: HuskyEnv) -> None:
    push = [{"step": 5, "angle": 25.0, "distance": 0.4}, {"step": 10, "angle": -40.0}]
    env.reset(options={"angle": 10.0, "distance": 2.0, "push": push})
    before, _ = run(env, STOP, 4)
    after, _ = run(env, STOP, 1)
    assert after["angle"] - before["angle"] == pytest.approx(25.0, abs=0.5)
    assert after["distance"] - before["distance"] == pytest.approx(0.4, abs=0.005)
    before, _ = run(env, STOP, 4)
    after, _ = run(env, STOP, 1)
    assert after["angle"] - before["angle"] == pytest.approx(-40.0, abs=0.5)
    assert after["distance"] == pytest.approx(before["distance"], abs=0.005)
    # A push towards the object never goes into it; the push() method does the same.
    pushed = values(env.push(angle=5.0, distance=-10.0))
    assert pushed["distance"] == 0.0
    assert pushed["angle"] - after["angle"] == pytest.approx(5.0, abs=0.5)


def test_push_keeps_motion_in_the_robot_frame(env: HuskyEnv) -> None:
    env.reset(options={"angle": 0.0, "distance": 4.0, "push": {"step": 60, "angle": 90.0}})
    obs, _ = run(env, [4.0, 4.0], 60)
    assert obs["linear_velocity"] > 0.6  # still driving forward after the push
    assert obs["angle"] == pytest.approx(90.0, abs=2.0)


def rollout(env: HuskyEnv, seed: int, options: dict[str, Any]) -> list[np.ndarray]:
    obs, _ = env.reset(seed=seed, options=options)
    out = [np.concatenate([obs[n] for n in CHANNELS])]
    rng = np.random.default_rng(7)
    for _ in range(120):
        obs, _, _, _, _ = env.step(rng.uniform(-5.6, 5.6, size=2))
        out.append(np.concatenate([obs[n] for n in CHANNELS]))
    return out


def test_deterministic(env: HuskyEnv) -> None:
    options = {"angle": 45.0, "distance": 1.5, "noise": 0.01, "push": {"step": 50, "angle": 10.0}}
    first = rollout(env, 3, options)
    run(env, [5.0, -2.0], 100)  # an unrelated history in between
    second = rollout(env, 3, options)
    other = make_husky()
    try:
        third = rollout(other, 3, options)
    finally:
        other.close()
    for a, b, c in zip(first, second, third, strict=True):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(a, c)


def test_noise_only_in_the_observation(env: HuskyEnv) -> None:
    sigma = 0.01
    env.reset(seed=1, options={"angle": 20.0, "distance": 3.0, "noise": sigma})
    quiet = make_husky()
    try:
        quiet.reset(seed=1, options={"angle": 20.0, "distance": 3.0})
        errors = []
        for _ in range(200):
            obs, _, _, _, info = env.step(np.array([0.5, 1.0]))
            q_obs, _, _, _, q_info = quiet.step(np.array([0.5, 1.0]))
            assert true_values(info) == values(q_obs) == true_values(q_info)
            errors.append([values(obs)[n] - true_values(info)[n] for n in CHANNELS])
    finally:
        quiet.close()
    spread = np.std(errors, axis=0)
    expected = [sigma * (hi - lo) for lo, hi in (env.channel_ranges[n] for n in CHANNELS)]
    np.testing.assert_allclose(spread, expected, rtol=0.25)
    # The constructor's noise is the default of every episode.
    noisy = make_husky(noise=0.02)
    try:
        obs, info = noisy.reset(seed=0)
        assert values(obs) != true_values(info)
    finally:
        noisy.close()


# ---------------------------------------------------------------- closed loop
def test_closed_loop_turns_from_90_degrees_within_10_seconds(env: HuskyEnv) -> None:
    spec = env.robot_spec
    obs, _ = env.reset(options={"angle": 90.0, "distance": 2.0})
    gain = 2.0  # 1/s: yaw rate per bearing error
    elapsed = 0.0
    while abs(float(obs["angle"][0])) >= 3.0 or abs(float(obs["angular_velocity"][0])) >= 5.0:
        if elapsed >= 10.0:
            pytest.fail(f"still at bearing {float(obs['angle'][0]):.1f} deg after 10 s")
        bearing = float(obs["angle"][0])
        wheel = gain * math.radians(bearing) * spec["track_width"] / (2 * spec["wheel_radius"])
        obs, _, _, _, info = env.step(np.array([-wheel, wheel]))
        elapsed = info["t"]
    assert elapsed < 10.0
    assert abs(float(obs["distance"][0]) - 2.0) < 0.15  # turned nearly in place


def test_closed_loop_approaches_to_within_5_cm(env: HuskyEnv) -> None:
    spec = env.robot_spec
    r, track = spec["wheel_radius"], spec["track_width"]
    obs, _ = env.reset(options={"angle": 10.0, "distance": 2.0})
    for _ in range(round(15.0 / env.control_period)):
        o = values(obs)
        v = min(1.0, 1.0 * o["distance"])  # m/s
        w = 2.0 * math.radians(o["angle"])  # rad/s
        obs, _, _, _, _ = env.step(np.array([(v - w * track / 2) / r, (v + w * track / 2) / r]))
    final = values(obs)
    assert 0.0 <= final["distance"] < 0.05
    assert abs(final["angle"]) < 3.0


# ---------------------------------------------------------------- lifecycle and packaging
def test_close_is_idempotent_and_final() -> None:
    husky = make_husky()
    husky.reset()
    husky.close()
    husky.close()
    with pytest.raises(SimulationError):
        husky.step(STOP)
    with pytest.raises(SimulationError):
        husky.reset()


def test_load_warnings_do_not_reach_stdout(capfd: pytest.CaptureFixture[str]) -> None:
    husky = make_husky()
    husky.close()
    out, _ = capfd.readouterr()
    assert "inertial" not in out


def test_missing_pybullet_is_a_config_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "pybullet", None)
    with pytest.raises(ConfigError, match=r"pip install 'behavior-hmm\[pybullet\]'"):
        HuskyEnv()


def test_importing_the_module_does_not_import_pybullet() -> None:
    code = (
        "import sys, behavior_hmm, behavior_hmm.sim._husky; "
        "assert 'pybullet' not in sys.modules, 'pybullet imported'"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
