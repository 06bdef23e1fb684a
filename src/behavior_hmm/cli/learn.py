"""Commands that learn a behavior, perform it and score it.

Usage::

    behavior-hmm train simple data/turn.parquet --inputs angle -o models/turn.bhmm
    behavior-hmm train complex data/ta.parquet --component models/turn.bhmm \\
        --component models/approach.bhmm -o models/ta.bhmm
    behavior-hmm generate models/turn.bhmm --start angle=120 --goal angle=0 --plot run.png
    behavior-hmm evaluate models/turn.bhmm --starts starts.csv --baseline bc --json out.json

Angles are in degrees, distances in metres, wheel speeds in rad/s.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Annotated, Any

import typer

from behavior_hmm.cli._common import (
    CONTEXT_SETTINGS,
    AddressOption,
    ConfigOption,
    EnvKwargsOption,
    EnvOption,
    ExecutorOption,
    NoiseOption,
    PresetOption,
    SeedOption,
    SetOption,
    SimOption,
    TeacherKwargsOption,
    TeacherOption,
    VideoBackendOption,
    WorkersOption,
    behavior_env,
    check_noise,
    check_seed,
    check_sim,
    check_video,
    load_model,
    log,
    make_run_executor,
    model_params,
    open_env,
    parse_assignments,
    parse_start,
    progress,
    spinner,
    user_errors,
    warn_provenance,
    write_video,
)
from behavior_hmm.errors import ConfigError, DatasetError

app = typer.Typer(context_settings=CONTEXT_SETTINGS)
train_app = typer.Typer(
    context_settings=CONTEXT_SETTINGS,
    no_args_is_help=True,
    help="Learn a behavior from demonstrations.\n\n"
    "Example: behavior-hmm train simple data/turn.parquet --inputs angle -o models/turn.bhmm",
)
app.add_typer(train_app, name="train")

ModelFile = Annotated[Path, typer.Argument(help="A model file (.bhmm)")]
ModelOut = Annotated[Path, typer.Option("-o", "--out", help="Model file to write")]


def _inputs(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise ConfigError("--inputs needs at least one channel, e.g. --inputs angle")
    return names


# -------------------------------------------------------------------------- train


@train_app.command("simple")
@user_errors
def train_simple(
    data: Annotated[Path, typer.Argument(help="Demonstrations (Parquet)")],
    out: ModelOut,
    inputs: Annotated[
        str | None,
        typer.Option(
            help="Input channels, e.g. angle,angular_velocity, or auto: chosen from the "
            "demonstrations (required, except with --update: the model's)"
        ),
    ] = None,
    seed: Annotated[
        int | None,
        typer.Option(help="Seed (>= 0) of every random draw (default 0; --update: the model's)"),
    ] = None,
    preset: PresetOption = None,
    config: ConfigOption = None,
    set_: SetOption = None,
    update: Annotated[
        Path | None,
        typer.Option(
            "--update",
            help="A simple behavior's model (.bhmm) to continue with the new demonstrations "
            "(left unchanged; -o gets the result)",
        ),
    ] = None,
) -> None:
    """Learn a simple behavior (SBLM) from demonstrations, or continue one (--update).

    With --update MODEL the model learns the new demonstrations of its behavior on top of
    what it knows (SBLM.partial_fit): its parameters, inputs and seed stay its own, so
    --preset, --config, --set and other --inputs are refused; MODEL is left unchanged.

    Example: behavior-hmm train simple data/turn.parquet --inputs angle --preset thesis
    -o models/turn-thesis.bhmm
    """
    from behavior_hmm import data as bdata
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.models import AUTO_INPUTS, SBLM, describe_params

    if seed is not None:
        check_seed(seed)
    if update is not None:
        _update_simple(data, update, out, inputs, seed, preset, config, set_)
        return
    if inputs is None:
        raise ConfigError("--inputs is required, e.g. --inputs angle (or --update MODEL)")
    check_outputs({"DATA": data, "--config": config}, {"-o": out})
    _, params = model_params(("SBLM",), preset, config, set_)
    auto = inputs.strip().lower() == AUTO_INPUTS  # chosen by the fit from the data
    names = AUTO_INPUTS if auto else _inputs(inputs)
    model = SBLM(**params["SBLM"], inputs=names, random_state=seed or 0)
    model.check_params()  # before any data is read
    dataset = bdata.read(data)
    log.debug("read %s: %d episodes, %d rows", data, len(dataset), dataset.n_samples)
    t0 = time.perf_counter()
    with spinner(f"train simple on {data.name}"):
        model.fit(dataset)
    if auto:
        typer.echo(model.provenance_["inputs_selection"])
    model.set_training_data(data)
    model.save(out)
    typer.echo(
        f"wrote {out}: {model.behavior_} on {','.join(model.inputs_)}, "
        f"{model.primitives_.n_categories_} primitives, "
        f"{model.observations_.n_categories_} observation categories, "
        f"preset {describe_params('SBLM', model.get_params())} "
        f"({time.perf_counter() - t0:.1f} s)"
    )


def _update_simple(
    data: Path,
    update: Path,
    out: Path,
    inputs: str | None,
    seed: int | None,
    preset: str | None,
    config: Path | None,
    set_: list[str] | None,
) -> None:
    """``train simple DATA --update MODEL -o OUT``: MODEL continued on DATA, written to OUT."""
    from behavior_hmm import data as bdata
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.models import SBLM

    _refuse_with_update(preset, config, set_)
    check_outputs({"DATA": data, "--update": update}, {"-o": out})
    model = _model_to_update(update, SBLM, "a simple behavior (SBLM)", inputs)
    if seed is not None and seed != model.random_state:
        raise ConfigError(
            f"--seed {seed}: an update draws from the model's seed ({model.random_state})"
        )
    before = (model.primitives_.n_categories_, model.observations_.n_categories_)
    dataset = bdata.read(data)
    log.debug("read %s: %d episodes, %d rows", data, len(dataset), dataset.n_samples)
    t0 = time.perf_counter()
    with spinner(f"update {update.name} with {data.name}"):
        model.partial_fit(dataset, source=data)
    model.save(out)
    record = model.updates_[-1]
    tuned = ",".join(str(p) for p in record["fine_tuned"]) or "none"
    typer.echo(
        f"wrote {out}: {model.behavior_} on {','.join(model.inputs_)} updated with "
        f"{len(dataset)} demonstrations, {model.primitives_.n_categories_} primitives "
        f"(+{model.primitives_.n_categories_ - before[0]}), "
        f"{model.observations_.n_categories_} observation categories "
        f"(+{model.observations_.n_categories_ - before[1]}), generators fine-tuned: "
        f"{tuned} (with {record.get('rehearsed', 0):,} kept rows) "
        f"({time.perf_counter() - t0:.1f} s); {update} unchanged"
    )


@train_app.command("complex")
@user_errors
def train_complex(
    data: Annotated[Path, typer.Argument(help="Tagged demonstrations (behavior column)")],
    component: Annotated[
        list[Path],
        typer.Option(help="A learned behavior (.bhmm), repeatable (--update: the new one)"),
    ],
    out: ModelOut,
    inputs: Annotated[
        str | None,
        typer.Option(help="Input channels (default distance,angle; --update: the model's)"),
    ] = None,
    preset: PresetOption = None,
    config: ConfigOption = None,
    set_: SetOption = None,
    update: Annotated[
        Path | None,
        typer.Option(
            "--update",
            help="A complex behavior's model (.bhmm) that the one --component joins, learned "
            "from DATA (left unchanged; -o gets the result)",
        ),
    ] = None,
) -> None:
    """Compose learned behaviors (CBLM) from demonstrations tagged per row.

    The preset, config and --set choose the CBLM's own parameters; the components
    keep theirs.

    With --update MODEL a new behavior (the one --component) joins the complex behavior
    MODEL, learned from DATA, demonstrations tagged with it (CBLM.add_component): no
    component is retrained and MODEL's own demonstrations are not needed. The model keeps
    its parameters and inputs, so --preset, --config, --set and other --inputs are
    refused; MODEL is left unchanged.

    Example: behavior-hmm train complex data/ta.parquet --component models/turn.bhmm
    --component models/approach.bhmm --preset thesis -o models/ta.bhmm
    """
    from behavior_hmm import data as bdata
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.models import CBLM, describe_params

    if update is not None:
        _refuse_with_update(preset, config, set_)
        if len(component) != 1:
            raise ConfigError(
                f"--update adds one component at a time: give one --component, not {len(component)}"
            )
        check_outputs({"DATA": data, "--update": update, "--component": component}, {"-o": out})
        model = _model_to_update(update, CBLM, "a complex behavior (CBLM)", inputs)
        new = load_model(component[0])
        dataset = bdata.read(data)
        log.debug("read %s: %d episodes, %d rows", data, len(dataset), dataset.n_samples)
        before = model.observations_.n_categories_
        t0 = time.perf_counter()
        with spinner(f"add {component[0].name} to {update.name} with {data.name}"):
            model.add_component(new, dataset, source=data)
        model.save(out)
        typer.echo(
            f"wrote {out}: {model.behavior_} over {', '.join(model.names_)} on "
            f"{','.join(model.inputs_)}, {model.names_[-1]} added from {len(dataset)} "
            f"demonstrations, {model.observations_.n_categories_} observation categories "
            f"(+{model.observations_.n_categories_ - before}) "
            f"({time.perf_counter() - t0:.1f} s); {update} and components unchanged"
        )
        return
    if inputs is None:
        inputs = "distance,angle"
    check_outputs({"DATA": data, "--component": component, "--config": config}, {"-o": out})
    _, params = model_params(("CBLM",), preset, config, set_)
    CBLM(**params["CBLM"]).check_params()  # before any file is read
    components = [load_model(path) for path in component]
    dataset = bdata.read(data)
    log.debug("read %s: %d episodes, %d rows", data, len(dataset), dataset.n_samples)
    t0 = time.perf_counter()
    with spinner(f"train complex on {data.name}"):
        model = CBLM(components, **params["CBLM"], inputs=_inputs(inputs)).fit(dataset)
    model.set_training_data(data)
    model.save(out)
    typer.echo(
        f"wrote {out}: {model.behavior_} over {', '.join(model.names_)} on "
        f"{','.join(model.inputs_)}, {model.observations_.n_categories_} observation "
        f"categories, preset {describe_params('CBLM', model.get_params())} "
        f"({time.perf_counter() - t0:.1f} s); components unchanged"
    )


# ----------------------------------------------------------------------- generate


@app.command()
@user_errors
def generate(
    model_file: ModelFile,
    start: Annotated[
        str,
        typer.Option(help="Start: angle (deg) and/or distance (m), e.g. angle=120,distance=0.5"),
    ],
    goal: Annotated[
        str | None,
        typer.Option(
            help="Goal: angle (deg) and/or distance (m), e.g. angle=0 "
            "(default: where the demonstrations end)"
        ),
    ] = None,
    sim: SimOption = "mujoco",
    seed: SeedOption = 0,
    noise: NoiseOption = 0.0,
    out: Annotated[
        Path | None, typer.Option("-o", "--out", help="Trace (Parquet; see inspect)")
    ] = None,
    env: EnvOption = None,
    env_kwargs: EnvKwargsOption = None,
    video: Annotated[
        Path | None, typer.Option(help="Video of the run: run.mp4 or run.gif (video extra)")
    ] = None,
    video_backend: VideoBackendOption = "matplotlib",
    plot: Annotated[
        Path | None,
        typer.Option(help="Plot of the run, in its extension's format (.png, .svg, .pdf)"),
    ] = None,
    trajectory: Annotated[
        Path | None,
        typer.Option(help="Top view of the run (x, y in m), the teacher's path dashed (.png)"),
    ] = None,
) -> None:
    """Perform a learned behavior from a start to a goal in the simulator.

    Prints the run's summary as JSON (final errors in deg and m) and exits with 1 when
    the goal is not reached. The trace (-o) and the plot (--plot) are written together,
    or neither is.

    Example: behavior-hmm generate models/turn.bhmm --start angle=120 --goal angle=0
    --sim kinematic --plot run.png -o run.parquet
    """
    from behavior_hmm._atomic import all_or_none
    from behavior_hmm._paths import check_outputs

    check_sim(sim)
    check_seed(seed)
    check_noise(noise)
    check_outputs(
        {"MODEL_FILE": model_file},
        {"-o": out, "--plot": plot, "--video": video, "--trajectory": trajectory},
        plots=("--plot", "--trajectory"),
    )
    if video is not None:
        check_video(video, video_backend)
    begin = parse_start(start, arena=env is None)
    target = parse_assignments(goal, "--goal") if goal is not None else None
    model = load_model(model_file)
    if target is not None:
        model.resolve_goal(target)  # refuse a bad goal before any motion
    robot, robot_name = open_env(sim, behavior_env(model, env), env_kwargs)
    warn_provenance(model, robot, robot_name)
    trace = model.generate(robot, start=begin, goal=target, seed=seed, noise=noise or None)
    summary = trace.summary()
    typer.echo(json.dumps(summary, default=float))
    demo, demo_pose = None, None
    if plot is not None or trajectory is not None or video is not None:
        demo, demo_pose = _teacher_run(model, robot, trace, seed)
    with all_or_none():
        if out is not None:
            trace.write(out)
        if plot is not None:
            from behavior_hmm.viz import plot_trace

            plot_trace(trace, plot, reference=demo)
        if trajectory is not None:
            from behavior_hmm.viz import plot_trajectory

            base = robot.unwrapped
            plot_trajectory(
                trace,
                reference_pose=demo_pose,
                body_radius=getattr(base, "body_radius", None),
                object_radius=getattr(base, "object_radius", None),
                path=trajectory,
            )
        if video is not None:
            write_video(
                trace, video, video_backend, robot, title=model_file.stem, teacher=demo_pose
            )
    if out is not None:
        log.info("trace: %s", out)
    if plot is not None:
        log.info("plot: %s", plot)
    if trajectory is not None:
        log.info("trajectory: %s", trajectory)
    if video is not None:
        log.info("video: %s", video)
    if not trace.goal_reached:
        raise typer.Exit(code=1)


def _refuse_with_update(preset: str | None, config: Path | None, set_: list[str] | None) -> None:
    """``--preset``, ``--config`` and ``--set`` make no sense with ``--update``."""
    for option, value in (("--preset", preset), ("--config", config), ("--set", set_)):
        if value:
            raise ConfigError(f"{option} cannot be used with --update: the model keeps its own")


def _model_to_update(update: Path, kind: type[Any], what: str, inputs: str | None) -> Any:
    """The model ``--update`` names, of ``kind``, reading the ``--inputs`` given (if any)."""
    model: Any = load_model(update)
    if not isinstance(model, kind):
        raise ConfigError(f"--update {update}: a {model.kind}, not {what}")
    if inputs is not None and tuple(_inputs(inputs)) != tuple(model.inputs_):
        raise ConfigError(
            f"--inputs {inputs}: the model reads {','.join(model.inputs_)}; "
            "an update keeps its inputs"
        )
    return model


def _teacher_run(model: Any, robot: Any, trace: Any, seed: int) -> tuple[Any, Any]:
    """The teacher's demonstration from the run's start to its goal, and its path.

    ``(None, None)`` when the teacher cannot demonstrate it (a behavior it does not know,
    or a goal it has no phase for): the plots then show the run alone.
    """
    from behavior_hmm.errors import BehaviorHMMError
    from behavior_hmm.evaluate import reference_demonstration
    from behavior_hmm.viz import replay_pose

    goal = {k: v for k, v in trace.goal.items() if k == "distance"}
    try:
        demo = reference_demonstration(
            str(model.behavior_), trace.start, goal, robot, seed=seed, noise=0.0
        )
    except BehaviorHMMError as err:
        log.debug("no teacher's run to overlay: %s", err)
        return None, None
    pose = replay_pose(robot, trace.start, demo, seed=seed)
    return demo, (pose if len(pose) else None)


# ----------------------------------------------------------------------- evaluate


@app.command()
@user_errors
def evaluate(
    model_file: ModelFile,
    starts: Annotated[
        Path | None,
        typer.Option(
            help="Starts CSV: columns angle (deg), distance (m) and goal_<channel>; "
            "default: the behavior's 15 test starts"
        ),
    ] = None,
    sim: SimOption = "mujoco",
    seed: SeedOption = 0,
    noise: NoiseOption = 0.0,
    baseline: Annotated[
        list[str] | None,
        typer.Option(help="Baselines to run beside the model: bc, bc-strong (repeatable)"),
    ] = None,
    data: Annotated[
        Path | None, typer.Option(help="Training data for baselines (default: the model's)")
    ] = None,
    json_out: Annotated[Path | None, typer.Option("--json", help="Write results")] = None,
    report: Annotated[
        Path | None, typer.Option(help="Write an HTML report (tables and plots)")
    ] = None,
    push: Annotated[
        str | None,
        typer.Option(
            help="Push every run: at=FRACTION of the teacher's duration, angle=DEG of "
            "bearing (sign drawn per case from the seed), distance=M, "
            "e.g. at=0.5,angle=20"
        ),
    ] = None,
    env: EnvOption = None,
    env_kwargs: EnvKwargsOption = None,
    videos: Annotated[
        Path | None,
        typer.Option(help="Folder for one video per run, case_NN.mp4 (video extra)"),
    ] = None,
    video_backend: VideoBackendOption = "matplotlib",
    workers: WorkersOption = None,
    executor: ExecutorOption = "local",
    address: AddressOption = None,
    teacher: TeacherOption = None,
    teacher_kwargs: TeacherKwargsOption = None,
    reference: Annotated[
        Path | None,
        typer.Option(
            help="Recorded demonstrations (Parquet) to score against, without a teacher: "
            "each episode's first reading on the start channels is a start, the episode "
            "its reference"
        ),
    ] = None,
) -> None:
    """Score a model (and baselines) against the teacher from test starts.

    The reference of each start is our teacher's run for the model's behavior, your
    own teacher's (--teacher, with --starts) or a recorded demonstration (--reference).
    Beside the thesis's command score every case records path metrics on the goal
    channels (DTW, discrete Fréchet, swept area; the metrics extra) and the final
    error on each goal channel.

    Every start (and its goal) is checked before the first case runs; --json and
    --report are written together, or neither is. Each case also records the largest
    command change in one period against the teacher's (command_jump_ratio) and the
    primitive (SBLM) or component (CBLM) switches. The start cases run as independent
    tasks (--workers, --executor), with the same results whoever runs them; with --env
    they run in this process.

    Example: behavior-hmm evaluate models/turn.bhmm --push at=0.5,angle=20 --json t.json
    """
    from behavior_hmm._atomic import all_or_none, atomic_write_bytes
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.evaluate import evaluate_model
    from behavior_hmm.teach import read_starts, scaled_starts, test_starts

    check_sim(sim)
    check_seed(seed)
    check_noise(noise)
    pushed = _push(push) if push is not None else None
    if teacher is not None and reference is not None:
        raise ConfigError("give --teacher or --reference, not both")
    if reference is not None and starts is not None:
        raise ConfigError("--reference brings its own starts (each episode's first reading)")
    if teacher is not None and starts is None:
        raise ConfigError("--teacher needs --starts (a CSV with a column per start channel)")
    if teacher_kwargs is not None and teacher is None:
        raise ConfigError("--teacher-kwargs needs --teacher (the factory it is passed to)")
    external = teacher is not None or reference is not None
    if env is not None or external:
        robot, robot_name = open_env(sim, env, env_kwargs)
    else:
        robot, robot_name = None, sim
    inputs: dict[str, Any] = {
        "MODEL_FILE": model_file,
        "--starts": starts,
        "--data": data,
        "--reference": reference,
    }
    outputs = {"--json": json_out, "--report": report}
    check_outputs(inputs, outputs, folders={"--videos": videos} if videos else None)
    if videos is not None:
        check_video(videos / "case_00.mp4", video_backend)
    model = load_model(model_file)
    own = behavior_env(model, None)
    if robot is None and own is not None:  # grasp: on the robot with the gripper
        robot, robot_name = open_env(sim, own, None)
    if baseline and data is None and getattr(model, "train_data_", None):
        # the baselines train on the model's own data file: never write over it
        inputs["the model's training data"] = Path(model.train_data_)
        check_outputs(inputs, outputs)
    teacher_object, recorded = None, None
    if robot is None:
        chosen = read_starts(starts) if starts is not None else test_starts(model.behavior_)
    elif external:
        from behavior_hmm.runtime import Robot

        warn_provenance(model, robot, robot_name)
        chosen = []
        if reference is not None:
            from behavior_hmm.data import read as read_dataset

            recorded = read_dataset(reference)
        else:
            from behavior_hmm.runtime import parse_env_kwargs
            from behavior_hmm.teach._external import load_teacher

            assert teacher is not None and starts is not None
            where = Robot(robot).start_channels or tuple(model.resolve_goal(None))
            chosen = read_starts(starts, math.inf, channels=where)
            for i, row in enumerate(chosen):  # every goal before the first case runs
                goal_of = {k[5:]: v for k, v in row.items() if k.startswith("goal_")}
                if goal_of:
                    try:
                        model.resolve_goal(goal_of)
                    except ConfigError as err:
                        raise DatasetError(f"start {i + 1}: {err}", file=str(starts)) from None
            kwargs = parse_env_kwargs(teacher_kwargs, "--teacher-kwargs")
            teacher_object = load_teacher(teacher, robot, kwargs)
    else:
        warn_provenance(model, robot, robot_name)
        from behavior_hmm.runtime import Robot

        chosen = (
            read_starts(starts, math.inf, channels=Robot(robot).start_channels, goals=model.inputs_)
            if starts is not None
            else scaled_starts(test_starts(model.behavior_), robot)
        )
    if not external:
        _check_cases(model, chosen, starts, arena=robot is None)
    runner = make_run_executor(executor, workers, address)
    baselines = _baselines(baseline or [], model, data, seed)
    with progress() as bar:
        task = bar.add_task(f"evaluate {model.behavior_} ({robot_name})", total=None)
        result = evaluate_model(
            model,
            chosen,
            sim=None if robot is not None else sim,
            env=robot,
            seed=seed,
            noise=noise,
            baselines=baselines,
            progress=lambda d, t: bar.update(task, completed=d, total=t),
            keep_traces=report is not None or videos is not None,
            push=pushed,
            executor=runner,
            teacher=teacher_object,
            reference=recorded,
        )
    traces = result.pop("_traces", None)
    written: dict[int, Path] = {}
    if videos is not None and traces:
        written = _write_videos(videos, traces["model"], video_backend, robot, str(model.behavior_))
    text = json.dumps(result, indent=1, default=float)
    with all_or_none():
        if json_out is not None:
            atomic_write_bytes(json_out, text.encode())
        if report is not None:
            from behavior_hmm.viz import write_evaluation_report

            write_evaluation_report(result, traces, report, videos=written or None)
    if report is not None:
        log.info("report: %s", report)
    _print_evaluation(result, robot_name)


def _write_videos(
    folder: Path, runs: list[tuple[Any, Any]], backend: str, robot: Any, behavior: str
) -> dict[int, Path]:
    """One video per case, ``case_NN.mp4``; a case refused before any motion has none.

    Returns the videos written, by case index (for the report's links).
    """
    written: dict[int, Path] = {}
    folder.mkdir(parents=True, exist_ok=True)
    if robot is not None:
        scene = robot
    else:  # our robot: its sizes (kinematic: no physics needed to draw it)
        from behavior_hmm.sim import make_env

        scene = make_env("kinematic")
    for i, (trace, _) in enumerate(runs):
        from behavior_hmm.viz._html import format_values

        start = format_values(trace.start)
        if not len(trace.pose):  # refused before any motion: nothing to show
            log.warning("no video of case %d (%s): %s", i, start, trace.reason)
            continue
        written[i] = folder / f"case_{i:02d}.mp4"
        write_video(trace, written[i], backend, scene, title=f"{behavior} from {start}")
    log.info("videos: %s/case_00.mp4 ... case_%02d.mp4", folder, len(runs) - 1)
    return written


def _check_cases(
    model: Any, starts: list[dict[str, float]], file: Path | None, arena: bool = True
) -> None:
    """Refuse, before the first case runs, any start the teacher cannot demonstrate or
    whose goal (``goal_<channel>``) the model cannot take (``arena``: our arena's bounds)."""
    from behavior_hmm.evaluate import split_start
    from behavior_hmm.teach import complete_start, plan_phases

    behavior = str(model.behavior_)
    for i, row in enumerate(starts):
        begin, goal = split_start(row)
        try:
            full = complete_start(behavior, begin, None if arena else math.inf)
            plan_phases(behavior, full["angle"], full["distance"], goal.get("distance"))
            if goal:
                model.resolve_goal(goal)
        except ConfigError as err:
            values = ", ".join(f"{key} {value:g}" for key, value in row.items())
            raise DatasetError(
                f"start {i + 1} ({values}): {err}", file=None if file is None else str(file)
            ) from None


def _push(text: str) -> dict[str, float]:
    """``--push at=0.5,angle=20,distance=0.05`` checked (fraction in (0, 1], sizes bounded)."""
    values = parse_assignments(text, "--push")
    unknown = sorted(set(values) - {"at", "angle", "distance"})
    if unknown:
        raise ConfigError(f"--push: unknown key(s) {', '.join(unknown)}; use at, angle, distance")
    at = values.setdefault("at", 0.5)
    if not 0.0 < at <= 1.0:
        raise ConfigError(f"--push at={at:g}: a fraction of the teacher's duration in (0, 1]")
    if abs(values.get("angle", 0.0)) > 180.0:
        raise ConfigError(f"--push angle={values['angle']:g}: at most 180 deg")
    if abs(values.get("distance", 0.0)) > 1.0:
        raise ConfigError(f"--push distance={values['distance']:g}: at most 1 m")
    return values


def _baselines(names: list[str], model: Any, data: Path | None, seed: int) -> dict[str, Any]:
    if not names:
        return {}
    from behavior_hmm import data as bdata
    from behavior_hmm.evaluate._baselines import BASELINES, fit_baselines

    unknown = [n for n in names if n not in BASELINES]
    if unknown:
        raise ConfigError(f"unknown baseline '{unknown[0]}'; available: {', '.join(BASELINES)}")
    source = data or (Path(model.train_data_) if getattr(model, "train_data_", None) else None)
    if source is None:
        raise ConfigError(
            f"--baseline {names[0]} needs the training data: pass --data DATA.parquet"
        )
    try:
        dataset = bdata.read(source)
    except DatasetError as err:
        raise DatasetError(f"baseline training data: {err}") from None
    return fit_baselines(model.inputs_, dataset, seed, list(dict.fromkeys(names)))


def _one_decimal(value: float | None) -> str:
    """A table cell: ``value`` to one decimal, or ``-`` where there is none."""
    return "-" if value is None else f"{value:.1f}"


def _print_evaluation(result: dict[str, Any], robot: str | None = None) -> None:
    from rich.console import Console
    from rich.table import Table

    where = result["sim"] or robot
    table = Table(title=f"{result['behavior']} on {','.join(result['inputs'])} ({where})")
    columns = ["", "success %", "goal reached", "zero floor %", "motor-max %", "duration x"]
    columns += ["jump x (median/max)", "switches (max)"]
    if "pushed" in result:
        columns.append("pushed")
    for col in columns:
        table.add_column(col)
    kind = str(result.get("kind", "model"))
    rows = [(kind, result)] + [(n, r) for n, r in result["baselines"].items()]
    for name, r in rows:
        cells = [
            name,
            f"{r['success_rate_mean']:.1f}",
            f"{r['goal_reached']}/{r['n']}",
            f"{r['zero_floor_mean']:.1f}",
            _one_decimal(r["success_rate_motor_max_mean"]),
            f"{r['duration_ratio_mean']:.2f}",
            f"{r['command_jump_ratio_median']:.1f} / {r['command_jump_ratio_max']:.1f}",
            f"{r['switches_max']}",
        ]
        if "pushed" in result:
            cells.append(f"{r.get('pushed', 0)}/{r['n']}")
        table.add_row(*cells)
    Console().print(table)
