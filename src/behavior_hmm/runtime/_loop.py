"""The 16 ms control loop shared by every learned behavior and baseline."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from behavior_hmm.data import SENSOR_CHANNELS
from behavior_hmm.errors import ConfigError
from behavior_hmm.models._goals import within_tolerance
from behavior_hmm.runtime._simple import make_controller
from behavior_hmm.runtime._trace import Trace


def start_options(
    start: Mapping[str, float] | None,
    noise: float | None,
    pushes: Sequence[Mapping[str, float]] | None,
) -> dict[str, Any]:
    """``env.reset`` options for a start (deg, m), sensor noise and scheduled pushes."""
    options: dict[str, Any] = {}
    for key, value in (start or {}).items():
        if key not in ("angle", "distance"):
            raise ConfigError(f"unknown start channel '{key}' (use angle and/or distance)")
        options[key] = float(value)
    if noise is not None:
        if noise < 0:
            raise ConfigError(f"noise must be >= 0, got {noise}")
        options["noise"] = float(noise)
    if pushes:
        options["push"] = [dict(p) for p in pushes]
    return options


def run_controller(
    controller: Any,
    env: Any,
    *,
    start: Mapping[str, float] | None = None,
    seed: int | None = None,
    noise: float | None = None,
    max_steps: int = 2000,
    pushes: Sequence[Mapping[str, float]] | None = None,
) -> Trace:
    """Reset ``env`` at ``start`` and run ``controller`` until done or ``max_steps``.

    The robot is always commanded to stop at the end, and the trace's outcome is
    judged on the simulator's noise-free state after that stop.
    """
    obs, info = env.reset(seed=seed, options=start_options(start, noise, pushes))
    controller.reset()
    trace = Trace(goal=dict(controller.goal), start=dict(start or {}))
    reason = "step_limit"
    dt = env.unwrapped.params.control_period
    for k in range(max_steps):
        out = controller.step(obs)
        trace.t.append(k * dt)
        trace.readings.append(np.array(obs, dtype=np.float64))
        trace.true_readings.append(np.array(info["true_observation"], dtype=np.float64))
        trace.observation.append(int(out.observation))
        trace.novel.append(bool(out.novel))
        trace.state.append(int(out.state))
        trace.component.append(out.component)
        trace.commands.append(np.array(out.command, dtype=np.float64))
        trace.plan_changed.append(bool(out.plan_changed))
        if out.done:
            reason = "goal"
            break
        obs, _, _, _, info = env.step(out.command)
    # Always command a stop at the end; judge the outcome on the state after it.
    _, _, _, _, info = env.step(np.zeros(2))
    final = np.array(info["true_observation"], dtype=np.float64)
    trace.final_observation = final
    trace.reason = reason
    values = {name: float(final[j]) for j, name in enumerate(SENSOR_CHANNELS)}
    trace.goal_reached = within_tolerance(values, trace.goal)
    return trace


def run_behavior(
    model: Any,
    env: Any,
    *,
    start: Mapping[str, float] | None = None,
    goal: Mapping[str, float] | None = None,
    seed: int | None = None,
    noise: float | None = None,
    max_steps: int | None = None,
    pushes: Sequence[Mapping[str, float]] | None = None,
) -> Trace:
    """Perform a learned behavior (SBLM or CBLM) in ``env`` from ``start`` to ``goal``.

    Parameters
    ----------
    model
        A fitted SBLM or CBLM.
    env
        A ``behavior_hmm.sim`` env (any backend).
    start
        ``{"angle": deg, "distance": m}`` for ``env.reset``; ``None`` keeps the env default.
    goal
        Goal in physical units (e.g. ``{"angle": 0}``); ``None`` uses the model's default.
    seed, noise
        Passed to ``env.reset`` (sensor noise: sigma times each channel's range).
    max_steps
        Step limit; default the model's ``max_steps_``.
    pushes
        Scheduled pushes ``{"step", "angle", "distance"}`` (see the env's reset options).

    Raises
    ------
    UnreachableGoalError
        Before any motion, when no observation path leads from the start to the goal.
    """
    controller = make_controller(model, goal)
    limit = int(max_steps if max_steps is not None else model.max_steps_)
    if limit < 1:
        raise ConfigError(f"max_steps must be >= 1, got {limit}")
    return run_controller(
        controller, env, start=start, seed=seed, noise=noise, max_steps=limit, pushes=pushes
    )
