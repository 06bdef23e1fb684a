"""Any teacher (robot contract, version 2): a plain object that drives a robot to a goal.

A teacher is made by ``factory(env, **kwargs)`` and offers

- ``reset(start, goal)``: dicts of channel -> value, called after the env was reset at
  ``start``;
- ``step(observation, info) -> (command, done)``: ``observation`` is ``{channel:
  value}`` (physical units, the robot's channels), ``info`` holds
  ``"true_observation"`` (the same without sensor noise, where the env gives one) and
  ``"pose"``; ``command`` is one float per command channel, in the action's order;
  ``done`` says the teacher holds the goal reached: that step's command is not sent and
  the demonstration ends.

It is named on the command line as ``--teacher path/to/file.py:factory`` or
``--teacher package.module:factory`` with ``--teacher-kwargs JSON``. Our jerk-limited
teacher (:class:`~behavior_hmm.teach.Teacher`) stays the default for the built-in
behaviors; :func:`teacher_demonstration` runs any other one.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any, Final

import numpy as np

from behavior_hmm.errors import ConfigError

#: Longest demonstration of a teacher (control periods) unless the caller says otherwise:
#: 2 minutes at 16 ms.
DEFAULT_TEACHER_STEPS: Final[int] = 7500


def load_teacher(target: str, env: Any, kwargs: Mapping[str, Any] | None = None) -> Any:
    """The teacher ``--teacher`` names, built for ``env`` with ``kwargs`` (``--teacher-kwargs``).

    Raises
    ------
    ConfigError
        If the factory cannot be found or imported, fails, or returns an object without
        ``reset`` and ``step``.
    """
    from behavior_hmm.runtime._robot import load_factory

    factory = load_factory(target, "--teacher")
    try:
        teacher = factory(env, **dict(kwargs or {}))
    except TypeError as exc:
        raise ConfigError(f"--teacher {target}: {exc}") from exc
    check_teacher(teacher, target)
    return teacher


def check_teacher(teacher: Any, name: str = "the teacher") -> None:
    """Refuse an object that lacks a callable ``reset`` or ``step``."""
    missing = [m for m in ("reset", "step") if not callable(getattr(teacher, m, None))]
    if missing:
        raise ConfigError(
            f"{name} returned {type(teacher).__name__}, which has no {' or '.join(missing)}(); "
            "a teacher offers reset(start, goal) and step(observation, info) -> (command, done)"
        )


def teacher_demonstration(
    teacher: Any,
    env: Any,
    start: Mapping[str, float],
    goal: Mapping[str, float],
    *,
    seed: int | None = None,
    noise: float | None = None,
    max_steps: int = DEFAULT_TEACHER_STEPS,
    name: str = "the teacher",
) -> dict[str, np.ndarray]:
    """Run ``teacher`` in ``env`` from ``start`` to ``goal``: the demonstration's columns.

    Returns ``t`` (s), one column per robot channel (as the robot reads it, noisy if the
    env adds noise) and one per command channel (``left``, ``right`` for wheels).

    Raises
    ------
    ConfigError
        A command of the wrong length or not finite, or a teacher that has not said
        ``done`` within ``max_steps`` (naming the start).
    """
    from behavior_hmm.runtime import Robot
    from behavior_hmm.runtime._loop import start_options

    robot = env if isinstance(env, Robot) else Robot(env)
    reading, true, pose = robot.reset(seed=seed, options=start_options(start, noise, None, robot))
    teacher.reset(dict(start), dict(goal))
    readings: list[np.ndarray] = []
    commands: list[np.ndarray] = []
    where = ", ".join(f"{k}={v:g}" for k, v in start.items())
    for _ in range(max_steps):
        info = {"true_observation": robot.as_dict(true), "pose": pose}
        step = teacher.step(robot.as_dict(reading), info)
        command, done = _checked(step, name, where, len(robot.command_channels))
        if done:
            break
        readings.append(reading)
        commands.append(command)
        reading, true, pose = robot.step(command)
    else:
        raise ConfigError(
            f"{name} did not finish from {where} within {max_steps} steps "
            f"({max_steps * robot.control_period:g} s); its step() never returned done"
        )
    robot.step(robot.rest)  # the robot is always commanded to stop at the end
    if not readings:
        raise ConfigError(f"{name} was done at once from {where}: no demonstration to record")
    table = np.asarray(readings, dtype=np.float64)
    u = np.asarray(commands, dtype=np.float64)
    columns: dict[str, np.ndarray] = {"t": np.arange(len(table)) * robot.control_period}
    for j, channel in enumerate(robot.channels):
        columns[channel] = table[:, j]
    for j, channel in enumerate(robot.command_channels):
        columns[channel] = u[:, j]
    return columns


def _checked(out: Any, name: str, where: str, k: int) -> tuple[np.ndarray, bool]:
    try:
        command, done = out
    except (TypeError, ValueError):
        raise ConfigError(
            f"{name}.step() must return (command, done), got {type(out).__name__}"
        ) from None
    u = np.asarray(command, dtype=np.float64).reshape(-1)
    if u.shape != (k,):
        raise ConfigError(
            f"{name}.step() returned {u.size} commands from {where}; the robot takes {k}"
        )
    if not all(math.isfinite(float(v)) for v in u):
        raise ConfigError(f"{name}.step() returned a non-finite command from {where}")
    return u, bool(done)


#: ``teacher_for(env)``: a teacher for an env (a loaded ``--teacher``, built per env).
TeacherFactory = Callable[[Any], Any]
