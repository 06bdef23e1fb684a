"""Evaluation protocol (DESIGN §6): generate from test starts, compare with the teacher."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from behavior_hmm.errors import ConfigError, UnreachableGoalError
from behavior_hmm.evaluate._executor import Executor
from behavior_hmm.evaluate._metrics import (
    command_jump_ratio,
    path_metrics,
    success_rate,
    switches,
    zero_floor,
)
from behavior_hmm.runtime import Robot

Progress = Callable[[int, int], None]
#: ``case_options(i, start, reference)``: extra ``generate`` keyword arguments for case i.
CaseOptions = Callable[[int, dict[str, float], dict[str, np.ndarray]], Mapping[str, Any]]


def split_start(start: Mapping[str, float]) -> tuple[dict[str, float], dict[str, float]]:
    """Split a starts-CSV row into the start (angle, distance) and a per-case goal."""
    begin = {k: float(v) for k, v in start.items() if not k.startswith("goal_")}
    goal = {k[len("goal_") :]: float(v) for k, v in start.items() if k.startswith("goal_")}
    return begin, goal


def reference_demonstration(
    behavior: str,
    start: Mapping[str, float],
    goal: Mapping[str, float],
    env: Any,
    *,
    seed: int,
    noise: float,
) -> dict[str, np.ndarray]:
    """The teacher's demonstration (dataset columns) from ``start`` in ``env``."""
    from behavior_hmm.teach import Teacher, complete_start

    full = complete_start(behavior, dict(start), math.inf)
    demo = Teacher(env).demonstrate(
        behavior,
        full["angle"],
        full["distance"],
        goal_distance=goal.get("distance"),
        seed=seed,
        noise=noise,
    )
    return demo.as_arrays()


def evaluate_model(
    model: Any,
    starts: Sequence[Mapping[str, float]],
    *,
    sim: str | None = "mujoco",
    seed: int = 0,
    noise: float = 0.0,
    baselines: Mapping[str, Any] | None = None,
    progress: Progress | None = None,
    keep_traces: bool = False,
    env: Any | None = None,
    case_options: CaseOptions | None = None,
    push: Mapping[str, float] | None = None,
    executor: Executor | None = None,
    teacher: Any | None = None,
    reference: Any | None = None,
) -> dict[str, Any]:
    """Run ``model`` (and baselines) from every start and score them against the teacher.

    The reference of each start is our jerk-limited teacher's run for the model's
    behavior, or ``teacher``'s run (any teacher, :mod:`behavior_hmm.teach._external`),
    or a recorded demonstration (``reference``: a dataset whose episodes are the
    references and whose first readings are the starts).

    Parameters
    ----------
    model
        A fitted SBLM or CBLM (anything with ``generate``, ``command_scale_``, ``behavior_``).
    starts
        Start dicts (``angle``, ``distance``, optional ``goal_<channel>``).
    sim, seed, noise
        Simulator backend, seed (case ``i`` uses ``seed + i``) and sensor noise.
        ``sim=None``: a robot of the user's own, ``env``, which then also runs the
        teacher's reference demonstrations (its starts may lie beyond our arena).
    baselines
        Fitted baselines by name, evaluated on the same starts and references.
    progress
        Called as ``progress(done, total)``: runs done of ``len(starts)`` × runners
        (with an executor, in steps of one start case: all its runners).
    keep_traces
        Also return the traces and reference demonstrations under ``"_traces"``.
    env
        Run the model and baselines in this env (e.g. other robot parameters, or a
        wrapper injecting sensor faults) instead of ``make_env(sim)``. The teacher's
        reference demonstrations (and the motor-limit normalization) then still come
        from a nominal ``make_env(sim)``: every run is scored against the same
        undisturbed demonstration. Default: one ``make_env(sim)`` for both.
    case_options
        Called as ``case_options(i, start, reference)`` before case ``i`` (``start``: the
        completed start, ``reference``: the demonstration's columns); returns extra
        keyword arguments for every runner's ``generate`` in that case (e.g. ``pushes``).
    push
        ``{"at": fraction, "angle": deg, "distance": m}``: in every case, at that fraction
        of the teacher's duration from the same start, the robot is displaced by
        ``angle`` degrees of bearing (its sign drawn per case from ``seed``) and
        ``distance`` metres (the env's ``push`` option). Each case records ``pushed``
        (the run was still going at that step); ``goal_reached`` is judged at the end,
        after the push.
    teacher
        A teacher object (``reset(start, goal)``, ``step(observation, info)``) run in
        the reference env from every start to the case's goal (default: the model's).
    reference
        A :class:`~behavior_hmm.data.Dataset` of recorded demonstrations: episode ``i``
        is case ``i``'s reference and its first reading on the start channels (the
        robot's ``start_channels``, default the model's goal channels) is the start;
        ``starts`` must then be empty.
    executor
        Runs the start cases as independent tasks (each: the teacher's reference, then
        every runner from that start, in a fresh ``make_env(sim)``); the model and
        baselines must pickle. The result is identical to the default, in this process
        one case after another. An ``env``, ``sim=None`` or ``case_options`` (objects
        of the caller's that need not pickle, and an ``env`` whose state the caller may
        read afterwards) keep the cases in this process whatever ``executor`` says.

    Returns
    -------
    dict
        The evaluation JSON contract: ``behavior``, ``inputs``, ``n``, ``success_rate_mean``,
        ``goal_reached``, ``zero_floor_mean``, ``success_rate_motor_max_mean``, ``cases``
        and ``baselines`` (same summary per baseline). Every case also holds ``path``:
        DTW, discrete Fréchet and (2-D) swept area between the generated and the
        reference path on the goal channels (:func:`path_metrics`), and
        ``final_errors`` on every goal channel.
    """
    from behavior_hmm.sim import make_env

    if teacher is not None and reference is not None:
        raise ConfigError("give a teacher or a reference dataset, not both")
    if reference is not None and starts:
        raise ConfigError("a reference dataset brings its own starts; give no starts")
    if push is not None:
        _check_push(push)  # before any case runs, in whichever process
    # the caller's own objects (a robot, a hook, a teacher) stay in this process
    own = env is not None or sim is None or case_options is not None
    pool = None if own or teacher is not None or reference is not None else executor
    if sim is None:
        if env is None:
            raise ConfigError("evaluate_model needs sim or env")
        reference_env = env
    else:
        reference_env = make_env(sim)
    if env is None:
        env = reference_env
    robot = Robot(reference_env)
    behavior = str(model.behavior_)
    recorded: list[dict[str, np.ndarray] | None] = [None] * len(starts)
    if reference is not None:
        starts, recorded = _recorded_cases(reference, model, robot)  # type: ignore[assignment]
    elif teacher is None:
        from behavior_hmm.teach import behavior_spec

        try:
            behavior_spec(behavior)
        except ConfigError:
            raise ConfigError(
                f"the model's behavior '{behavior}' has no teacher of ours; score it against "
                "your own teacher (--teacher) or recorded demonstrations (--reference DATASET)"
            ) from None
    if not starts:
        raise ConfigError("no starts to evaluate")
    try:
        motor_max: float | None = robot.spec.max_wheel_speed
    except ConfigError:  # a robot without wheel geometry: no motor-limit variant
        motor_max = None
    scale = float(model.command_scale_)
    # one scale per command channel (channels of one unit share one: the wheels, scale)
    scales = tuple(float(v) for v in getattr(model, "command_scales_", (scale, scale)))
    commands = tuple(getattr(model, "command_channels", ("left", "right")))
    runners = {"model": model, **dict(baselines or {})}
    tasks = [
        _Case(
            index=i,
            row=row,
            behavior=behavior,
            runners=runners,
            sim=sim,
            seed=seed,
            noise=noise,
            push=push,
            scale=scale if len(set(scales)) == 1 else scales,
            motor_max=motor_max,
            keep_traces=keep_traces,
            commands=commands,
            external=teacher is not None or reference is not None,
            recorded=recorded[i],
        )
        for i, row in enumerate(starts)
    ]
    total = len(starts) * len(runners)
    outcomes: list[_CaseOutcome]
    if pool is None:
        done = 0

        def ran() -> None:
            nonlocal done
            done += 1
            if progress is not None:
                progress(done, total)

        outcomes = [
            _run_case(task, env, reference_env, case_options, ran, teacher) for task in tasks
        ]
    else:

        def cases_done(finished: int, _: int) -> None:
            if progress is not None:
                progress(finished * len(runners), total)

        outcomes = pool.map(_case_task, tasks, cases_done)
    cases: dict[str, list[dict[str, Any]]] = {name: [] for name in runners}
    traces: dict[str, list[Any]] = {name: [] for name in runners}
    for scores, runs in outcomes:  # in case order, whoever ran them
        for name in runners:
            cases[name].append(scores[name])
            if keep_traces:
                traces[name].append(runs[name])
    result = _summary(cases["model"])
    result.update(
        {
            "behavior": behavior,
            "kind": str(getattr(model, "kind", type(model).__name__)),
            "inputs": list(getattr(model, "inputs_", [])),
            "sim": sim,
            "seed": seed,
            "noise": noise,
            "command_scale": scale,
            "motor_max": motor_max,
            # a demonstration that saturated the motors makes the headline the lenient
            # motor-limit variant (DESIGN §6): flag it rather than report it silently
            "command_scale_at_motor_limit": motor_max is not None
            and bool(scale >= 0.999 * motor_max),
            "reference": "recorded" if reference is not None else "teacher",
            "cases": cases["model"],
            "baselines": {
                name: {**_summary(cases[name]), "cases": cases[name]}
                for name in runners
                if name != "model"
            },
        }
    )
    if keep_traces:
        result["_traces"] = traces
    return result


@dataclass(frozen=True)
class _Case:
    """One start case of an evaluation: everything it needs but its robot (picklable).

    ``index`` is the case's place in the starts (its seed is ``seed + index``, its push
    sign drawn from ``(seed, index)``); ``scale`` and ``motor_max`` (rad/s; None for a
    robot without wheel geometry) normalize the success rates; ``sim=None`` means the
    caller's own robot, whose starts may lie beyond our arena. ``external``: the
    reference comes from a teacher of the user's or a recording (``recorded``, the
    demonstration's columns), and the start is taken as given.
    """

    index: int
    row: Mapping[str, float]
    behavior: str
    runners: Mapping[str, Any]
    sim: str | None
    seed: int
    noise: float
    push: Mapping[str, float] | None
    scale: float | tuple[float, ...]
    motor_max: float | None
    keep_traces: bool
    commands: tuple[str, ...] = ("left", "right")
    external: bool = False
    recorded: dict[str, np.ndarray] | None = None


#: A case's scores by runner, and (``keep_traces``) its ``(trace, reference)`` by runner.
_CaseOutcome = tuple[dict[str, dict[str, Any]], dict[str, tuple[Any, dict[str, np.ndarray]]]]


def _case_task(case: _Case) -> _CaseOutcome:
    """Run one start case in a fresh ``make_env(case.sim)`` (an executor task)."""
    from behavior_hmm.sim import make_env

    assert case.sim is not None  # a robot of the caller's own stays in its process
    env = make_env(case.sim)
    return _run_case(case, env, env, None, None)


def _run_case(
    case: _Case,
    env: Any,
    reference_env: Any,
    case_options: CaseOptions | None,
    ran: Callable[[], None] | None,
    teacher: Any | None = None,
) -> _CaseOutcome:
    """The reference from the case's start (the teacher's run in ``reference_env``, or
    the recording), then every runner from that start in ``env``, scored against it
    (``ran()`` after each runner)."""
    from behavior_hmm.teach import complete_start
    from behavior_hmm.teach._external import teacher_demonstration

    i, seed, noise = case.index, case.seed, case.noise
    max_distance = None if case.sim is not None else math.inf
    begin, case_goal = split_start(case.row)
    if case.recorded is not None:
        full, demo = begin, case.recorded
    elif teacher is not None:
        full = begin
        goal_of_teacher = case_goal or case.runners["model"].resolve_goal(None)
        demo = teacher_demonstration(
            teacher, reference_env, full, goal_of_teacher, seed=seed + i, noise=noise or None
        )
    else:
        full = complete_start(case.behavior, begin, max_distance)
        demo = reference_demonstration(
            case.behavior, full, case_goal, reference_env, seed=seed + i, noise=noise
        )
    extra = dict(case_options(i, full, demo)) if case_options is not None else {}
    push_step = None
    if case.push is not None:
        push_step, scheduled = _scheduled_push(case.push, len(demo["t"]), seed, i)
        extra["pushes"] = [*extra.get("pushes", []), scheduled]
    ref = np.column_stack([demo[c] for c in case.commands])
    floor = zero_floor(ref, case.scale)
    floor_motor = None if case.motor_max is None else zero_floor(ref, case.motor_max)
    scores: dict[str, dict[str, Any]] = {}
    runs: dict[str, tuple[Any, dict[str, np.ndarray]]] = {}
    for name, runner in case.runners.items():
        goal = case_goal or None
        try:
            trace = runner.generate(
                env, start=full, goal=goal, seed=seed + i, noise=noise or None, **extra
            )
        except UnreachableGoalError as err:
            # refused before any motion: scored as a robot that stayed still
            trace = _refused(runner, full, goal, str(err))
        gen = trace.command_array
        errors = trace.final_errors()
        scores[name] = {
            "start": full,
            "goal": trace.goal,
            "success_rate": success_rate(gen, ref, case.scale),
            "success_rate_motor_max": None
            if case.motor_max is None
            else success_rate(gen, ref, case.motor_max),
            "zero_floor": floor,
            "zero_floor_motor_max": floor_motor,
            "goal_reached": bool(trace.goal_reached),
            "final_angle_error_deg": errors.get("angle"),
            "final_distance_error_m": errors.get("distance"),
            "duration_ratio": len(gen) / max(len(ref), 1),
            "steps": len(gen),
            "reference_steps": len(ref),
            "plan_changes": trace.n_plan_changes,
            "components": _collapsed([c for c in trace.component if c]),
            "reason": trace.reason,
            "command_jump_ratio": command_jump_ratio(gen, ref),
            # primitive changes of an SBLM, component changes of a CBLM
            "switches": _switches(runner, trace),
            "final_errors": errors,
            "path": _path(trace, demo),
        }
        if push_step is not None:
            # the push acts after env step `push_step`; a run ends with one stop step
            scores[name]["pushed"] = len(gen) > push_step
        if case.keep_traces:
            runs[name] = (trace, demo)
        if ran is not None:
            ran()
    return scores, runs


def _summary(cases: list[dict[str, Any]]) -> dict[str, Any]:
    def mean(key: str) -> float | None:
        values = [c[key] for c in cases if c.get(key) is not None]
        return float(np.mean(values)) if values else None

    def median_path(key: str) -> float | None:
        values = [c["path"][key] for c in cases if c.get("path", {}).get(key) is not None]
        return float(np.median(values)) if values else None

    return {
        "n": len(cases),
        "success_rate_mean": mean("success_rate"),
        "success_rate_median": float(np.median([c["success_rate"] for c in cases])),
        "goal_reached": int(sum(c["goal_reached"] for c in cases)),
        "zero_floor_mean": mean("zero_floor"),
        "success_rate_motor_max_mean": mean("success_rate_motor_max"),
        "zero_floor_motor_max_mean": mean("zero_floor_motor_max"),
        "duration_ratio_mean": mean("duration_ratio"),
        "command_jump_ratio_median": float(np.median([c["command_jump_ratio"] for c in cases])),
        "command_jump_ratio_max": float(max(c["command_jump_ratio"] for c in cases)),
        "switches_mean": mean("switches"),
        "switches_max": int(max(c["switches"] for c in cases)),
        "path_dtw_median": median_path("dtw"),
        "path_frechet_median": median_path("frechet"),
        "path_swept_area_median": median_path("swept_area"),
        **(
            {"pushed": int(sum(c["pushed"] for c in cases))}
            if cases and "pushed" in cases[0]
            else {}
        ),
    }


def _scheduled_push(
    push: Mapping[str, float], reference_steps: int, seed: int, case: int
) -> tuple[int, dict[str, float]]:
    """The env push of one case: its step and ``{"step", "angle", "distance"}``.

    The bearing's sign is drawn per case from ``(seed, case)``, so every runner of the
    case gets the same push and the same seed gives the same pushes.
    """
    step = max(1, round(_check_push(push) * reference_steps))
    sign = 1.0 if np.random.default_rng([seed, case]).random() < 0.5 else -1.0
    angle = sign * float(push.get("angle", 0.0))
    return step, {"step": step, "angle": angle, "distance": float(push.get("distance", 0.0))}


def _check_push(push: Mapping[str, float]) -> float:
    """Refuse unknown push keys and an ``at`` outside (0, 1]; return ``at`` (a fraction)."""
    unknown = sorted(set(push) - {"at", "angle", "distance"})
    if unknown:
        raise ConfigError(f"unknown push key(s) {', '.join(unknown)}; use at, angle, distance")
    at = float(push.get("at", 0.5))
    if not 0.0 < at <= 1.0:
        raise ConfigError(f"push at must be a fraction in (0, 1], got {at:g}")
    return at


def _switches(runner: Any, trace: Any) -> int:
    """Primitive changes (SBLM) or component changes (CBLM) along a run; 0 without states."""
    if getattr(runner, "kind", None) == "CBLM":
        return max(0, len(_collapsed([c for c in trace.component if c])) - 1)
    return switches(trace.state) if len(trace.state) else 0


def _collapsed(names: list[str]) -> list[str]:
    """Runs of equal names collapsed: the order in which components were active."""
    out: list[str] = []
    for name in names:
        if not out or out[-1] != name:
            out.append(name)
    return out


def _refused(runner: Any, start: Mapping[str, float], goal: Any, why: str) -> Any:
    """The trace of a run refused before any motion (the goal was unreachable)."""
    from behavior_hmm.runtime import Trace

    goal_now = runner.resolve_goal(goal)
    names = [*start, *(c for c in goal_now if c not in start)]
    trace = Trace(goal=goal_now, start=dict(start), channels=names)
    trace.t.append(0.0)
    trace.command_channels = list(runner.command_channels)
    trace.commands.append(np.asarray(runner.rest_command, dtype=np.float64))
    trace.component.append("")
    trace.plan_changed.append(False)
    trace.final_observation = np.array([start.get(c, np.nan) for c in names], dtype=np.float64)
    trace.channel_specs = {c: runner.channel_spec(c) for c in goal_now}
    trace.reason = f"unreachable: {why}"
    return trace


def _path(trace: Any, demo: Mapping[str, np.ndarray]) -> dict[str, float | None]:
    """:func:`path_metrics` of a run against its reference, on the goal's channels."""
    from behavior_hmm.data._channels import channel

    names = [c for c in trace.goal if c in trace.channels and c in demo]
    if not names or not trace.true_readings:
        return path_metrics(np.zeros((0, 1)), np.zeros((0, 1)))
    true = np.asarray(trace.true_readings, dtype=np.float64).reshape(-1, len(trace.channels))
    generated = true[:, [trace.channels.index(c) for c in names]]
    reference = np.column_stack([np.asarray(demo[c], dtype=np.float64) for c in names])
    wraps = [(trace.channel_specs.get(c) or channel(c)).wraps for c in names]
    return path_metrics(generated, reference, wraps)


def _recorded_cases(
    dataset: Any, model: Any, robot: Robot
) -> tuple[list[dict[str, float]], list[dict[str, np.ndarray]]]:
    """Starts and reference columns of a dataset's episodes (``--reference DATASET``)."""
    goal = model.resolve_goal(None)
    names = list(robot.start_channels or goal)
    missing = [c for c in names if c not in dataset.sensor_channels]
    if missing:
        raise ConfigError(
            f"the reference dataset has no {', '.join(missing)} column to start from "
            f"(start channels: {', '.join(names)})"
        )
    columns = ["t", *dataset.sensor_channels, *dataset.command_channels]
    table = dataset.columns(columns)
    starts: list[dict[str, float]] = []
    demos: list[dict[str, np.ndarray]] = []
    for lo, hi in itertools.pairwise(dataset.offsets):
        demo = {name: np.array(table[lo:hi, j]) for j, name in enumerate(columns)}
        starts.append({c: float(demo[c][0]) for c in names})
        demos.append(demo)
    return starts, demos
