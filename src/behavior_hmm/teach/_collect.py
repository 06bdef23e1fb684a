"""Collect demonstration datasets by running the teacher from many starts."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from behavior_hmm.data import Dataset
from behavior_hmm.errors import ConfigError
from behavior_hmm.teach._demonstrator import BEHAVIORS, Teacher, TeacherConfig
from behavior_hmm.teach._grids import TURN_DISTANCE, Start, check_start, default_starts

Progress = Callable[[int, int], None]


def complete_start(behavior: str, start: Start) -> Start:
    """Fill a start's missing channel with the behavior's default (turn: 0.5 m, others 0 deg)."""
    check_start(start)
    full = dict(start)
    if "angle" not in full:
        full["angle"] = 0.0
    if "distance" not in full:
        if behavior not in ("turn",):
            raise ConfigError(f"a start for '{behavior}' needs a distance")
        full["distance"] = TURN_DISTANCE
    return full


def collect(
    behavior: str,
    starts: Sequence[Start] | None = None,
    *,
    sim: str = "mujoco",
    seed: int = 0,
    noise: float = 0.0,
    teacher: TeacherConfig | None = None,
    progress: Progress | None = None,
    env: Any = None,
) -> Dataset:
    """Demonstrate ``behavior`` from every start and return the dataset.

    Parameters
    ----------
    behavior
        One of ``turn``, ``approach``, ``retreat``, ``turn-approach``, ``position``.
    starts
        Starts as dicts with ``angle`` (deg) and/or ``distance`` (m), optionally
        ``goal_distance``; ``None`` uses the default training grid.
    sim
        Simulator backend, ``mujoco`` or ``kinematic``.
    seed
        Episode ``i`` resets the env with seed ``seed + i`` (sensor noise draws).
    noise
        Gaussian sensor noise, sigma times each channel's normalization range.
    progress
        Called as ``progress(done, total)`` after each episode.
    env
        An already-made env to use instead of ``make_env(sim)``.
    """
    from behavior_hmm.sim import make_env

    if behavior not in BEHAVIORS:
        raise ConfigError(f"unknown behavior '{behavior}'; choose one of {', '.join(BEHAVIORS)}")
    if noise < 0:
        raise ConfigError(f"--noise must be >= 0, got {noise}")
    if seed < 0:
        raise ConfigError(f"--seed must be >= 0, got {seed}")
    chosen = list(default_starts(behavior) if starts is None else starts)
    if not chosen:
        raise ConfigError("no starts to collect")
    full = [complete_start(behavior, s) for s in chosen]
    env = env if env is not None else make_env(sim, noise=noise)
    config = teacher or TeacherConfig()
    tutor = Teacher(env, config)
    episodes = []
    for i, start in enumerate(full):
        demo = tutor.demonstrate(
            behavior,
            start["angle"],
            start["distance"],
            goal_distance=start.get("goal_distance"),
            seed=seed + i,
            noise=noise,
        )
        columns: dict[str, Any] = dict(demo.as_arrays())
        columns["episode"] = i
        episodes.append(columns)
        if progress is not None:
            progress(i + 1, len(full))
    metadata = {
        "behavior": behavior,
        "simulator": sim,
        "seed": seed,
        "noise": noise,
        "robot": env.unwrapped.params.to_dict(),
        "teacher": config.to_dict(),
        "starts": full,
    }
    return Dataset.from_episodes(episodes, metadata=metadata)
