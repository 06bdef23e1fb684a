"""Simulator speed: real-time factors of both backends and of a bare MuJoCo loop.

Usage::

    python -m behavior_hmm.benchmarks.sim            # full run, prints JSON
    python -m behavior_hmm.benchmarks.sim --quick    # fewer, shorter repeats

Every figure is simulated seconds per wall-clock second (median over repeats) for the
same varying wheel command, starting 1.0 m from the object.  ``bare_mujoco_rtf`` steps
the very same MjModel/MjData with ``mj_step(m, d, nstep)`` and nothing else, measured in
the same run, so ``mujoco_env_over_bare`` is the share of speed the environment keeps.
``*_make_rtf`` go through ``gymnasium.make`` (with its passive checker wrappers).
"""

from __future__ import annotations

import json
import math
import statistics
import sys
import time
from collections.abc import Callable

import gymnasium
import mujoco
import numpy as np

from behavior_hmm.sim import ENV_ID, KINEMATIC_ENV_ID, RobotParams, make_env
from behavior_hmm.sim._mujoco import MujocoBackend

_START = {"angle": 30.0, "distance": 1.0}


def _commands(steps: int, dt: float) -> list[np.ndarray]:
    """A slowly varying (left, right) command sequence (rad/s), one per control step."""
    out = []
    for i in range(steps):
        t = i * dt
        out.append(np.array([3.0 + 2.0 * math.sin(1.3 * t), 3.0 + 2.5 * math.cos(0.9 * t)]))
    return out


def _median_rtf(run_once: Callable[[], float], sim_seconds: float, repeats: int) -> float:
    return statistics.median(sim_seconds / run_once() for _ in range(repeats))


def _env_runner(env: gymnasium.Env, commands: list[np.ndarray]) -> Callable[[], float]:
    def once() -> float:
        env.reset(seed=0, options=_START)
        t0 = time.perf_counter()
        for action in commands:
            env.step(action)
        return time.perf_counter() - t0

    return once


def run(quick: bool = False) -> dict[str, float]:
    """Measure the simulators; returns real-time factors (higher is faster).

    Parameters
    ----------
    quick
        3 repeats of 5 simulated seconds instead of 7 repeats of 20 s.
    """
    repeats, sim_seconds = (3, 5.0) if quick else (7, 20.0)
    params = RobotParams()
    dt = params.control_period
    steps = round(sim_seconds / dt)
    sim_seconds = steps * dt
    commands = _commands(steps, dt)
    results: dict[str, float] = {}

    mj_env = make_env("mujoco")
    assert isinstance(mj_env.sim, MujocoBackend)
    model, data = mj_env.sim.model, mj_env.sim.data
    nstep = params.substeps
    gain_left, gain_right = params.wheel_gains
    plain = [(float(a[0]) * gain_left, float(a[1]) * gain_right) for a in commands]

    def bare_once() -> float:
        mj_env.reset(seed=0, options=_START)  # same start state as the env runs
        ctrl = data.ctrl
        t0 = time.perf_counter()
        for left, right in plain:
            ctrl[0] = left
            ctrl[1] = right
            mujoco.mj_step(model, data, nstep=nstep)
        return time.perf_counter() - t0

    # Interleave bare and env repeats so machine load affects both alike.
    bare, env_times = [], []
    env_once = _env_runner(mj_env, commands)
    for _ in range(repeats):
        bare.append(sim_seconds / bare_once())
        env_times.append(sim_seconds / env_once())
    results["bare_mujoco_rtf"] = statistics.median(bare)
    results["mujoco_rtf"] = statistics.median(env_times)
    results["mujoco_env_over_bare"] = results["mujoco_rtf"] / results["bare_mujoco_rtf"]

    kin_env = make_env("kinematic")
    results["kinematic_rtf"] = _median_rtf(_env_runner(kin_env, commands), sim_seconds, repeats)

    for key, env_id in (("mujoco_make_rtf", ENV_ID), ("kinematic_make_rtf", KINEMATIC_ENV_ID)):
        wrapped = gymnasium.make(env_id)
        results[key] = _median_rtf(_env_runner(wrapped, commands), sim_seconds, repeats)
        wrapped.close()

    results["mujoco_step_us"] = 1e6 * dt / results["mujoco_rtf"]
    results["kinematic_step_us"] = 1e6 * dt / results["kinematic_rtf"]
    results["simulated_seconds"] = sim_seconds
    results["repeats"] = float(repeats)
    return results


if __name__ == "__main__":
    print(json.dumps(run(quick="--quick" in sys.argv[1:]), indent=2))
