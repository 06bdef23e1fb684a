"""Collect demonstration datasets by running the teacher from many starts."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from behavior_hmm.data import CHANNELS, COMMAND_CHANNELS, SENSOR_CHANNELS, ChannelSpec, Dataset
from behavior_hmm.errors import ConfigError
from behavior_hmm.teach._behaviors import Start, behavior_spec
from behavior_hmm.teach._demonstrator import DISTURBED_CHANNELS, Teacher, TeacherConfig
from behavior_hmm.teach._external import DEFAULT_TEACHER_STEPS
from behavior_hmm.teach._grids import check_start, default_starts

Progress = Callable[[int, int], None]

#: Default sigma of a corrective demonstration's disturbance (x the top wheel speed): at
#: 0.04 every approach pushed 20 deg reaches its goal (45/45, docs/results.md); 0.08, with
#: an earlier disturbance of the common part too, cost turn 17 points.
DEFAULT_CORRECTION_NOISE = 0.04


def complete_start(behavior: str, start: Start, max_distance: float | None = None) -> Start:
    """Fill a start's missing channel with the behavior's default (turn: 0.5 m, others 0 deg).

    ``max_distance`` (m): the farthest start allowed; default our arena's 1.2 m.
    """
    if max_distance is None:
        check_start(start)
    else:
        check_start(start, max_distance)
    return behavior_spec(behavior).complete_start(start)


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
    env_name: str | None = None,
    corrections: int | None = None,
    correction_noise: float = DEFAULT_CORRECTION_NOISE,
) -> Dataset:
    """Demonstrate ``behavior`` from every start and return the dataset.

    Parameters
    ----------
    behavior
        A registered behavior (``turn``, ``approach``, ``retreat``, ``turn-approach``,
        ``position``, or one added with :func:`register_behavior`).
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
        An env that meets the robot contract (docs/robots.md) to use instead of
        ``make_env(sim)``; its starts may reach beyond our arena. ``None``: the
        behavior's own robot if it names one (``grasp``: the Khepera with a gripper).
    env_name
        How the env was named (``--env``), recorded in the metadata.
    corrections
        Corrective demonstrations per start, after the nominal ones (DART-style: the
        teacher corrects a smooth disturbance of its heading, see
        :meth:`Teacher.demonstrate`); their episode ids are listed in the metadata
        (``corrective_episodes``), and a model takes its command scales from the nominal
        episodes only, so the success rate's normalization does not change. ``None``:
        the behavior's own (``BehaviorSpec.corrections``, approach 1) on its default
        grid (``starts=None``), none on starts given.
    correction_noise
        The disturbance's sigma as a fraction of the robot's top wheel speed.
    """
    from behavior_hmm.runtime import Robot, make_robot_env
    from behavior_hmm.sim import make_env

    spec = behavior_spec(behavior)
    if env is None and spec.env is not None:
        env, env_name = make_robot_env(spec.env), env_name or spec.env
    if noise < 0:
        raise ConfigError(f"--noise must be >= 0, got {noise}")
    if seed < 0:
        raise ConfigError(f"--seed must be >= 0, got {seed}")
    if corrections is None:
        corrections = spec.corrections if starts is None else 0
    if isinstance(corrections, bool) or not isinstance(corrections, int) or corrections < 0:
        raise ConfigError(f"--corrections must be an integer >= 0, got {corrections!r}")
    if not 0.0 < correction_noise <= 0.5:
        raise ConfigError(f"--correction-noise must lie in (0, 0.5], got {correction_noise:g}")
    if corrections and spec.components:
        # its teacher corrects the phase it is in, not a heading disturbed while approaching:
        # the disturbed runs end off the goal (turn-approach: 6 deg at sigma 0.02)
        raise ConfigError(
            f"--corrections is for simple behaviors; collect corrective demonstrations of "
            f"{behavior}'s components ({', '.join(spec.components)}) instead"
        )
    chosen = list(default_starts(behavior) if starts is None else starts)
    if not chosen:
        raise ConfigError("no starts to collect")
    own = env is None
    # our robots share the arena; another robot's starts may reach beyond it
    arena = own or spec.env is not None
    full = [complete_start(behavior, s, None if arena else float("inf")) for s in chosen]
    env = make_env(sim, noise=noise) if own else env
    robot = Robot(env)
    tutor = Teacher(env, teacher)
    config = tutor.config
    derived = list(robot.derived)
    extras = [c for c in robot.channels if c not in SENSOR_CHANNELS]
    units = dict(getattr(env.unwrapped, "channel_units", None) or {})
    missing = [c for c in extras if c not in robot.ranges]
    if missing:
        raise ConfigError(
            f"the robot's channel(s) {', '.join(missing)} need a normalization range: "
            "declare env.unwrapped.channel_ranges (docs/robots.md)"
        )
    episodes = []
    runs = [(start, seed + i, 0.0) for i, start in enumerate(full)]
    for k in range(1, corrections + 1):  # corrective copies draw seeds past the nominal ones
        runs += [
            (start, seed + k * len(full) + i, correction_noise) for i, start in enumerate(full)
        ]
    for i, (start, episode_seed, perturbation) in enumerate(runs):
        demo = tutor.demonstrate(
            behavior,
            start["angle"],
            start["distance"],
            goal_distance=start.get("goal_distance"),
            seed=episode_seed,
            noise=noise,
            perturbation=perturbation,
        )
        columns: dict[str, Any] = dict(demo.as_arrays())
        columns["episode"] = i
        episodes.append(columns)
        if progress is not None:
            progress(i + 1, len(runs))
    params = getattr(env.unwrapped, "params", None)
    metadata = {
        "behavior": behavior,
        "goal": dict(spec.goal),
        "simulator": sim if env_name is None else env_name,
        "env": env_name or sim,
        "control_period": robot.control_period,
        "ranges": {c: list(r) for c, r in robot.ranges.items()},
        "seed": seed,
        "noise": noise,
        "robot": params.to_dict() if params is not None else robot.spec.to_dict(),
        "teacher": config.to_dict(),
        "starts": full,
    }
    if extras:
        metadata["channels"] = [
            (
                robot.channel_specs.get(c)
                or CHANNELS.get(c)
                or ChannelSpec(c, str(units.get(c, "1")), robot.ranges[c])
            ).to_metadata()
            for c in extras
        ]
    if robot.command_channels != COMMAND_CHANNELS:
        metadata["commands"] = [spec.to_metadata() for spec in robot.command_specs]
    if corrections:
        metadata["corrections"] = {
            "copies": corrections,
            "noise": correction_noise,
            "disturbs": list(DISTURBED_CHANNELS),
        }
        metadata["corrective_episodes"] = list(range(len(full), len(runs)))
    if derived:  # a robot without velocity sensors: estimated from its positions
        metadata["derived"] = derived
    return Dataset.from_episodes(episodes, metadata=metadata)


def collect_with_teacher(
    name: str,
    env: Any,
    teacher: Any,
    goal: Mapping[str, float],
    starts: Sequence[Mapping[str, float]],
    *,
    seed: int = 0,
    noise: float = 0.0,
    env_name: str | None = None,
    teacher_name: str | None = None,
    progress: Progress | None = None,
    max_steps: int = DEFAULT_TEACHER_STEPS,
) -> Dataset:
    """Demonstrate with any teacher (``--teacher``) from every start; the dataset.

    Parameters
    ----------
    name
        What the behavior is called (free text: recorded as the dataset's ``behavior``).
    env
        An env that meets the robot contract (docs/robots.md, version 2).
    teacher
        ``reset(start, goal)`` and ``step(observation, info) -> (command, done)``
        (:mod:`behavior_hmm.teach._external`).
    goal
        ``{channel: value}`` the teacher drives to; recorded as the dataset's goal.
    starts
        ``{channel: value}`` per demonstration, on the robot's start channels.
    seed
        Episode ``i`` resets the env with seed ``seed + i``.
    noise
        Sensor noise (the env's ``noise`` reset option), 0 for none.
    env_name, teacher_name
        How the env and the teacher were named, recorded in the metadata.
    progress
        Called as ``progress(done, total)`` after each episode.
    max_steps
        A demonstration the teacher has not ended by then is an error.
    """
    from behavior_hmm.data._validate import check_behavior_name
    from behavior_hmm.errors import DatasetError
    from behavior_hmm.runtime import Robot
    from behavior_hmm.teach._external import check_teacher, teacher_demonstration

    try:  # before any demonstration runs, not after the last one
        check_behavior_name(name)
    except DatasetError as err:
        raise ConfigError(f"behavior name: {err.reason}") from None
    if noise < 0:
        raise ConfigError(f"--noise must be >= 0, got {noise}")
    if seed < 0:
        raise ConfigError(f"--seed must be >= 0, got {seed}")
    if not starts:
        raise ConfigError("no starts to collect")
    check_teacher(teacher, teacher_name or "the teacher")
    robot = env if isinstance(env, Robot) else Robot(env)
    contract = [c for c in SENSOR_CHANNELS if c in robot.channels]
    if contract and len(contract) != len(SENSOR_CHANNELS):
        lacking = [c for c in SENSOR_CHANNELS if c not in robot.channels]
        raise ConfigError(
            f"the robot has {', '.join(contract)} but not {', '.join(lacking)}: a dataset holds "
            "all four sensors of the data contract or none (declare other names for yours)"
        )
    ranges = robot.ranges
    own = [c for c in robot.channels if c not in SENSOR_CHANNELS]
    undeclared = [c for c in own if c not in robot.channel_specs and c not in CHANNELS]
    if undeclared:
        raise ConfigError(
            f"the robot's channel(s) {', '.join(undeclared)} are not declared: list them in "
            'env.unwrapped.sensor_channels ({"name", "unit", "range"}, docs/robots.md)'
        )
    specs = [robot.channel_specs.get(c) or CHANNELS[c] for c in own]
    wanted = {str(k): float(v) for k, v in goal.items()}
    known = {s.name: s for s in specs} | {c: CHANNELS[c] for c in contract}
    for channel, _ in wanted.items():
        spec = known.get(channel)
        if spec is None or spec.tolerance is None:
            raise ConfigError(
                f"goal channel '{channel}' is not a channel of the robot with a tolerance "
                f"(its channels: {', '.join(robot.channels)})"
            )
    episodes = []
    for i, start in enumerate(starts):
        columns: dict[str, Any] = dict(
            teacher_demonstration(
                teacher,
                robot,
                start,
                wanted,
                seed=seed + i,
                noise=noise or None,
                max_steps=max_steps,
                name=teacher_name or "the teacher",
            )
        )
        columns["episode"] = i
        episodes.append(columns)
        if progress is not None:
            progress(i + 1, len(starts))
    metadata: dict[str, Any] = {
        "behavior": name,
        "goal": wanted,
        "simulator": env_name or robot.name,
        "env": env_name or robot.name,
        "control_period": robot.control_period,
        "ranges": {c: list(ranges[c]) for c in robot.channels if c in ranges},
        "seed": seed,
        "noise": noise,
        "teacher": {"name": teacher_name or type(teacher).__name__},
        "starts": [dict(s) for s in starts],
    }
    if specs:
        metadata["channels"] = [spec.to_metadata() for spec in specs]
    if robot.command_channels != COMMAND_CHANNELS:
        metadata["commands"] = [spec.to_metadata() for spec in robot.command_specs]
    if robot.derived:
        metadata["derived"] = list(robot.derived)
    return Dataset.from_episodes(episodes, metadata=metadata)
