"""Commands that make, read and convert data: demonstrations in, datasets out.

Usage::

    behavior-hmm collect turn --sim kinematic -o data/turn.parquet
    behavior-hmm collect approach --starts starts.csv --noise 0.005 -o data/approach.parquet
    behavior-hmm inspect data/turn.parquet --plot turn.png      # a dataset
    behavior-hmm inspect models/turn.bhmm                       # a model
    behavior-hmm inspect run.parquet --plot run.png             # a trace (generate -o)
    behavior-hmm import-csv log.csv --map angle=bearing --unit angle=rad \\
        --derive linear_velocity,angular_velocity --resample -o mine.parquet
    behavior-hmm import-bag run1.bag run2.bag --map angle=/object_bearing:data \\
        --map distance=/object_distance --twist /cmd_vel \\
        --derive linear_velocity,angular_velocity -o mine.parquet
    behavior-hmm import-lerobot lerobot/turn -o mine.parquet
    behavior-hmm export-lerobot data/turn.parquet lerobot/turn
    behavior-hmm upgrade models/old.bhmm                        # a model, to format 2

Every file is checked before any work; on an error nothing is written.
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer

from behavior_hmm.cli._common import (
    CONTEXT_SETTINGS,
    EnvKwargsOption,
    EnvOption,
    NoiseOption,
    ParquetOut,
    SimOption,
    TeacherKwargsOption,
    TeacherOption,
    check_noise,
    check_sim,
    collect_with_progress,
    load_model,
    log,
    open_env,
    parse_assignments,
    progress,
    user_errors,
    write_json,
)
from behavior_hmm.cli._trace_files import is_trace_file, read_trace, trace_dataset
from behavior_hmm.errors import ConfigError

app = typer.Typer(context_settings=CONTEXT_SETTINGS)

#: Standard deviations of sensor noise that must fit inside the plausible bounds.
NOISE_SIGMAS = 5.0

MapFileOption = Annotated[
    Path | None,
    typer.Option(
        "--map-file",
        help="TOML mapping file: \\[map] and \\[unit] tables and options (the command line wins)",
    ),
]
UnitOption = Annotated[
    list[str] | None,
    typer.Option(help="CHANNEL=UNIT of your data, e.g. angle=rad, distance=mm (repeatable)"),
]
DeriveOption = Annotated[
    str | None,
    typer.Option(
        help="Velocities to compute from positions by finite differences: "
        "linear_velocity (m/s, = -d distance/dt), angular_velocity (deg/s, = -d angle/dt)"
    ),
]
ResampleOption = Annotated[
    bool,
    typer.Option(
        "--resample", help="Interpolate each episode linearly onto the 16 ms control period"
    ),
]
BehaviorOption = Annotated[str | None, typer.Option(help="Behavior name stored in metadata")]
ChannelOption = Annotated[
    list[str] | None,
    typer.Option(
        "--channel",
        help="NAME:UNIT:LO:HI[:TOL], a robot's own sensor column of your file (e.g. "
        "ir0:m:0:0.1 for an infrared proximity reading in m, normalized from [0, 0.1]; TOL: "
        "its goal tolerance, needed for a goal on it); imported in that unit and declared "
        "in the dataset's metadata (repeatable)",
    ),
]

GoalOption = Annotated[
    str | None,
    typer.Option(
        "--goal",
        help="Where the demonstrations aim, CHANNEL=VALUE[,...] on channels with a goal "
        "tolerance (e.g. x=0,y=0); default: the goal of a registered --behavior",
    ),
]

CommandOption = Annotated[
    list[str] | None,
    typer.Option(
        "--command",
        help="The robot's command channels in action order, replacing our two wheels: "
        "NAME:UNIT:LO:HI[:REST] for a channel of yours (REST: the command that holds the "
        "robot still, default 0), or a known name (left, right); e.g. --command left "
        "--command right --command grip:m/s:-0.05:0.05 (repeatable)",
    ),
]


def max_noise() -> float:
    """The largest ``--noise`` sigma a recorded dataset can pass validation with.

    Noise of sigma times a channel's normalization range must, to ``NOISE_SIGMAS``
    standard deviations, stay within the plausible bounds ``data.read`` enforces
    (``VALUE_BOUNDS``) beyond the channel's range; the angle is wrapped, so it is exempt.
    The distance binds: 0.5 m of slack under 0 m on a 1.2 m range gives about 0.083.
    """
    from behavior_hmm.data._channels import SENSOR_RANGES
    from behavior_hmm.data._validate import VALUE_BOUNDS

    limits = []
    for name, (lo, hi) in SENSOR_RANGES.items():
        if name == "angle":  # readings are wrapped into (-180, 180]
            continue
        bound_lo, bound_hi = VALUE_BOUNDS[name]
        slack = min(lo - bound_lo, bound_hi - hi)
        limits.append(slack / (NOISE_SIGMAS * (hi - lo)))
    return min(limits)


# ------------------------------------------------------------------------ collect


@app.command()
@user_errors
def collect(
    behavior: Annotated[
        str,
        typer.Argument(
            help="turn, approach, retreat, turn-approach, position, or on "
            "behavior_hmm/KheperaGripper-v0 grasp and turn-approach-grasp; with --teacher, "
            "any name for your behavior"
        ),
    ],
    out: ParquetOut,
    starts: Annotated[
        Path | None,
        typer.Option(
            help="CSV of starts: columns angle (deg) and/or distance (m); "
            "default: the behavior's grid (DESIGN §6)"
        ),
    ] = None,
    sim: SimOption = "mujoco",
    seed: Annotated[
        int, typer.Option(help="Seed (>= 0); episode i draws its sensor noise with SEED+i")
    ] = 0,
    noise: NoiseOption = 0.0,
    env: EnvOption = None,
    env_kwargs: EnvKwargsOption = None,
    corrections: Annotated[
        int | None,
        typer.Option(
            help="Corrective demonstrations per start, after the nominal ones: the teacher "
            "corrects a smooth disturbance of its heading (DART-style). Default: the "
            "behavior's own on its default grid (approach: 1), 0 with --starts"
        ),
    ] = None,
    correction_noise: Annotated[
        float | None,
        typer.Option(
            help="Sigma of that disturbance, as a fraction of the top wheel speed "
            "(default: behavior_hmm.teach.DEFAULT_CORRECTION_NOISE)"
        ),
    ] = None,
    teacher: TeacherOption = None,
    teacher_kwargs: TeacherKwargsOption = None,
    goal: Annotated[
        str | None,
        typer.Option(
            help="With --teacher: the goal it drives to, CHANNEL=VALUE[,CHANNEL=VALUE] on "
            "channels of the robot that have a tolerance"
        ),
    ] = None,
) -> None:
    """Record demonstrations of a behavior into a Parquet dataset.

    Our s-curve teacher demonstrates the built-in behaviors; --teacher names your own
    (path/to/file.py:factory or package.module:factory, called as factory(env, **kwargs)
    with --teacher-kwargs JSON), which drives --env from each --starts row to --goal.

    Everything is checked before the first episode runs; on any error nothing is
    written and an existing OUT is left as it was. With --corrections K each start is
    also demonstrated K more times while a smooth disturbance turns the robot off the
    teacher's course and the teacher corrects it (the dataset records its command); the
    approach's default grid comes with one such copy per start.

    Example: behavior-hmm collect turn --sim kinematic -o data/turn.parquet
    """
    import math

    if teacher is not None:
        _collect_with_teacher(
            behavior, out, starts, env, env_kwargs, teacher, teacher_kwargs, goal, seed, noise
        )
        return
    for option, value in (("--teacher-kwargs", teacher_kwargs), ("--goal", goal)):
        if value is not None:
            raise ConfigError(f"{option} needs --teacher (our teacher knows its goals)")
    from behavior_hmm import data
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.errors import DatasetError
    from behavior_hmm.teach import (
        behavior_spec,
        complete_start,
        default_starts,
        plan_phases,
        read_starts,
        scaled_starts,
    )

    spec = behavior_spec(behavior)  # an unknown behavior is refused first
    if env is None and spec.env is not None:  # grasp: our Khepera with a gripper
        env = spec.env
    check_sim(sim)
    check_noise(noise)
    if noise > max_noise():
        raise ConfigError(
            f"--noise {noise:g} is too large: at most {max_noise():.3g}, beyond which the "
            "noisy readings leave the plausible range every dataset is checked against"
        )
    if seed < 0:
        raise ConfigError(f"--seed must be >= 0, got {seed}")
    if corrections is None:
        corrections = spec.corrections if starts is None else 0
    if corrections < 0:
        raise ConfigError(f"--corrections must be >= 0, got {corrections}")
    if correction_noise is not None and not 0.0 < correction_noise <= 0.5:
        raise ConfigError(f"--correction-noise must lie in (0, 0.5], got {correction_noise:g}")
    check_outputs({"--starts": starts}, {"-o": out})
    robot, robot_name = open_env(sim, env, env_kwargs) if env is not None else (None, None)
    far = math.inf if robot is not None and robot_name != spec.env else None
    if starts is not None:
        chosen = read_starts(starts) if far is None else read_starts(starts, far)
    else:
        chosen = default_starts(behavior)
        chosen = chosen if robot is None else scaled_starts(chosen, robot)
    # Check every start against the behavior now, not after minutes of simulation.
    for i, start in enumerate(chosen):
        try:
            full = complete_start(behavior, start, far)
            plan_phases(behavior, full["angle"], full["distance"], full.get("goal_distance"))
        except ConfigError as err:
            values = ", ".join(f"{key} {value:g}" for key, value in start.items())
            raise DatasetError(
                f"start {i + 1} ({values}): {err}",
                file=None if starts is None else str(starts),
                field=None if "distance" in start else "distance",
            ) from None
    log.debug("%d starts of %s on %s", len(chosen), behavior, robot_name or sim)
    try:
        dataset = collect_with_progress(
            behavior, chosen, sim, seed, noise, robot, robot_name, corrections, correction_noise
        )
    except DatasetError as err:  # the recorded data failed validation: say which data
        hint = f"; nothing written to {out}" + (" (try a smaller --noise)" if noise else "")
        raise DatasetError(
            err.reason + hint,
            file="recorded demonstrations",
            episode=err.episode,
            row=err.row,
            field=err.field,
        ) from None
    data.write(dataset, out)
    typer.echo(f"wrote {out}: {len(dataset)} episodes, {dataset.n_samples} rows")


def _collect_with_teacher(
    name: str,
    out: Path,
    starts: Path | None,
    env: str | None,
    env_kwargs: str | None,
    teacher: str,
    teacher_kwargs: str | None,
    goal: str | None,
    seed: int,
    noise: float,
) -> None:
    """``collect NAME --teacher T --env ENV --starts CSV --goal ch=v -o OUT``."""
    import math

    from behavior_hmm import data
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.runtime import Robot, parse_env_kwargs
    from behavior_hmm.teach import read_starts
    from behavior_hmm.teach._collect import collect_with_teacher
    from behavior_hmm.teach._external import load_teacher

    if env is None:
        raise ConfigError("--teacher needs --env (the robot your teacher drives)")
    if starts is None:
        raise ConfigError("--teacher needs --starts (a CSV with a column per start channel)")
    if goal is None:
        raise ConfigError("--teacher needs --goal, e.g. --goal x=0,y=0")
    check_noise(noise)
    if seed < 0:
        raise ConfigError(f"--seed must be >= 0, got {seed}")
    check_outputs({"--starts": starts}, {"-o": out})
    target = parse_assignments(goal, "--goal")
    made, env_name = open_env("mujoco", env, env_kwargs)
    robot = Robot(made)
    chosen = read_starts(starts, math.inf, channels=robot.start_channels or robot.channels)
    tutor = load_teacher(teacher, made, parse_env_kwargs(teacher_kwargs, "--teacher-kwargs"))
    with progress() as bar:
        task = bar.add_task(f"collect {name} ({env_name})", total=len(chosen))
        dataset = collect_with_teacher(
            name,
            robot,
            tutor,
            target,
            chosen,
            seed=seed,
            noise=noise,
            env_name=env_name,
            teacher_name=teacher,
            progress=lambda done, total: bar.update(task, completed=done, total=total),
        )
    data.write(dataset, out)
    typer.echo(f"wrote {out}: {len(dataset)} episodes, {dataset.n_samples} rows")


# ------------------------------------------------------------------------ inspect


@app.command()
@user_errors
def inspect(
    dataset_file: Annotated[
        Path,
        typer.Argument(help="A dataset (Parquet), a trace (generate -o) or a model (.bhmm)"),
    ],
    plot: Annotated[
        Path | None,
        typer.Option(
            help="Plot of the demonstrations or of a trace's run, .png, .svg, .pdf, ... "
            "(a dataset's default: DATA.png; a trace is plotted only when asked)"
        ),
    ] = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the summary as JSON")
    ] = None,
) -> None:
    """Summarize a dataset, a trace or a model, and plot a dataset or a trace.

    For a dataset: episodes, durations, channel ranges, and a PNG of the demonstrations
    as time-vs-angle and time-vs-distance curves (thesis figures 6.8-6.10). For a trace
    (generate -o): steps, duration, start, goal, whether it was reached and why the run
    ended, and the final errors (deg, m); --plot draws the run. For a model: its kind,
    behavior, inputs, sizes, the preset its parameters follow and every parameter.

    Example: behavior-hmm inspect models/turn.bhmm
    """
    import zipfile

    from behavior_hmm import data
    from behavior_hmm._atomic import all_or_none
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.viz import plot_demonstrations, plot_trace

    if dataset_file.suffix.lower() in (".csv", ".tsv", ".txt"):
        raise ConfigError(
            f"{dataset_file}: inspect reads Parquet datasets; "
            "convert a CSV log first with 'behavior-hmm import-csv'"
        )
    is_model = dataset_file.is_file() and zipfile.is_zipfile(dataset_file)
    is_trace = not is_model and is_trace_file(dataset_file)
    if is_model and plot is not None:
        raise ConfigError(f"--plot draws datasets; {dataset_file} is a model file")
    if is_model or is_trace:
        png = plot
    else:
        png = plot if plot is not None else dataset_file.with_suffix(".png")
    check_outputs({"DATA": dataset_file}, {"--plot": png, "--json": json_out}, plots=("--plot",))
    with all_or_none():  # the plot and the JSON, or neither
        if is_model:
            summary = _model_summary(dataset_file)
            _print_model_summary(dataset_file, summary)
        elif is_trace:
            trace, summary = read_trace(dataset_file)
            _print_trace_summary(dataset_file, summary)
            if png is not None:
                plot_trace(trace, png)
        else:
            dataset = data.read(dataset_file)
            summary = data.summarize(dataset)
            _print_summary(dataset_file, summary)
            assert png is not None
            plot_demonstrations(dataset, png)
        if json_out is not None:
            write_json(json_out, json.dumps(summary, indent=2, default=str) + "\n")
    if png is not None:
        log.info("plot: %s", png)
    if json_out is not None:
        log.info("summary: %s", json_out)


@app.command()
@user_errors
def upgrade(
    model_file: Annotated[Path, typer.Argument(help="A model file (.bhmm) of an older format")],
    out: Annotated[
        Path | None,
        typer.Option("-o", "--out", help="Write the upgraded model here (default: in place)"),
    ] = None,
) -> None:
    """Convert a model file to the current format, without loss.

    Format 1 stored the Behavior-HMM's tables densely (an M x M table for M observation
    categories); format 2 stores only their counts, sparsely. The probabilities follow
    from the counts, so the upgraded model behaves exactly as the old one. A complex
    behavior's components are upgraded with it. The file is replaced atomically (or
    written to --out); on an error nothing is written.

    Example: behavior-hmm upgrade models/turn.bhmm
    """
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.models._upgrade import upgrade as upgrade_file

    if out is not None:
        check_outputs({"MODEL": model_file}, {"--out": out})
    old, new = upgrade_file(model_file, out)
    target = model_file if out is None else out
    if old == new:
        log.info("%s is already format %d; written as it is to %s", model_file, new, target)
    else:
        log.info("upgraded %s from format %d to %d: %s", model_file, old, new, target)


def _model_summary(path: Path) -> dict[str, Any]:
    """What ``inspect`` shows of a model: kind, behavior, sizes, preset, parameters."""
    from behavior_hmm.models import describe_params

    model = load_model(path)
    params = {k: v for k, v in model.get_params().items() if k != "components"}
    summary: dict[str, Any] = {
        "kind": model.kind,
        "behavior": model.behavior_,
        "inputs": list(model.inputs_),
        "preset": describe_params(model.kind, params),
        "params": params,
        "observation_categories": int(model.observations_.n_categories_),
        "default_goal": dict(model.default_goal_),
        "max_steps": int(model.max_steps_),
        "train_data": model.train_data_,
        "provenance": dict(getattr(model, "provenance_", None) or {}),
    }
    summary["updates"] = len(getattr(model, "updates_", None) or [])
    if model.kind == "SBLM":
        summary["primitives"] = int(model.primitives_.n_categories_)
        rows = getattr(model, "rehearsal_", None)
        summary["rehearsal_rows"] = 0 if rows is None else rows.n_rows
    else:
        summary["components"] = list(model.names_)
    return summary


def _console() -> Any:
    from rich.console import Console

    # File names and metadata are the user's text: never read them as rich markup.
    return Console(highlight=False)


def _print_model_summary(path: Path, summary: dict[str, Any]) -> None:
    from rich.table import Table

    console = _console()
    console.print(str(path), style="bold", markup=False)
    for key in ("kind", "behavior", "inputs", "preset", "primitives", "components"):
        if key in summary:
            value = summary[key]
            text = ", ".join(value) if isinstance(value, list) else str(value)
            console.print(f"  {key}: {text}", markup=False)
    console.print(f"  observation categories: {summary['observation_categories']}")
    goal = ", ".join(f"{k} {v:g}" for k, v in summary["default_goal"].items())
    console.print(f"  default goal: {goal}; step limit {summary['max_steps']}", markup=False)
    if summary.get("train_data"):
        console.print(f"  trained on: {summary['train_data']}", markup=False)
    if "rehearsal_rows" in summary:
        console.print(
            f"  updates: {summary['updates']}; training rows kept for the next: "
            f"{summary['rehearsal_rows']:,} (at most {summary['params']['rehearsal']} "
            "a primitive)"
        )
    elif summary["updates"]:
        console.print(f"  components added: {summary['updates']}")
    table = Table(title="parameters")
    table.add_column("parameter")
    table.add_column("value")
    for name, value in summary["params"].items():
        table.add_row(name, repr(value))
    console.print(table)


def _with_units(values: Any) -> str:
    """``{"angle": 0.5, "distance": 0.1}`` as ``angle 0.5 deg, distance 0.1 m``."""
    from behavior_hmm.data import UNITS

    if not isinstance(values, dict) or not values:
        return "-"
    parts = []
    for name, value in values.items():
        unit = UNITS.get(name, "")
        number = _fmt(float(value)) if isinstance(value, int | float) else str(value)
        parts.append(f"{name} {number}{' ' + unit if unit else ''}")
    return ", ".join(parts)


def _print_trace_summary(path: Path, summary: dict[str, Any]) -> None:
    console = _console()
    console.print(str(path), style="bold", markup=False)
    lines = [
        f"steps: {summary['steps']}, duration_s: {_fmt(summary.get('duration_s'))}",
        f"channels: {', '.join(summary['channels'])}",
        f"start: {_with_units(summary.get('start'))}",
        f"goal: {_with_units(summary.get('goal'))}",
        f"reached: {'yes' if summary.get('goal_reached') else 'no'}",
        f"reason: {summary.get('reason') or '-'}",
        f"final errors: {_with_units(summary.get('final_errors'))}",
    ]
    if "plan_changes" in summary:
        lines.append(
            f"plan changes: {summary['plan_changes']}, "
            f"held readings: {summary.get('held_readings', 0)}"
        )
    if summary.get("fault_channels"):
        lines.append(f"fault channels: {', '.join(map(str, summary['fault_channels']))}")
    for line in lines:
        console.print(f"  {line}", markup=False)


def _print_summary(path: Path, summary: dict[str, Any]) -> None:
    from rich.table import Table

    console = _console()
    console.print(str(path), style="bold", markup=False)
    meta = summary.get("metadata", {})
    for key in ("behavior", "simulator", "seed", "noise"):
        if key in meta:
            console.print(f"  {key}: {meta[key]}", markup=False)
    source = meta.get("source")
    if isinstance(source, dict) and "file" in source:
        console.print(f"  imported from: {source['file']}", markup=False)
    console.print(f"  episodes: {summary['episodes']}, samples: {summary['samples']}")
    for key in ("samples_per_episode", "duration_s"):
        stats = summary.get(key, {})
        console.print(f"  {key}: " + ", ".join(f"{k} {_fmt(v)}" for k, v in stats.items()))
    if summary.get("sample_period_s") is not None:
        console.print(f"  sample_period_s: {_fmt(summary['sample_period_s'])}")
    if summary.get("behaviors"):
        console.print(f"  behaviors: {', '.join(summary['behaviors'])}", markup=False)
    table = Table(title="channels")
    for col in ("channel", "unit", "min", "max"):
        table.add_column(col)
    for name, stats in summary.get("channels", {}).items():
        table.add_row(name, str(stats.get("unit", "")), _fmt(stats["min"]), _fmt(stats["max"]))
    console.print(table)


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return "" if value is None else str(value)


# ------------------------------------------------------------------------ imports


def pairs(items: list[str], option: str) -> dict[str, str]:
    """``["angle=bearing", ...]`` -> ``{"angle": "bearing"}``; one-line errors."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise ConfigError(f"{option} expects KEY=VALUE, got '{item}'")
        if key.strip() in out:
            raise ConfigError(f"{option} gives '{key.strip()}' twice")
        out[key.strip()] = value.strip()
    return out


@contextmanager
def _reported_warnings() -> Iterator[None]:
    """Log each import warning as one ``warning: ...`` line on stderr."""
    from behavior_hmm.data._transform import DataImportWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", DataImportWarning)
        try:
            yield
        finally:
            ours = [w for w in caught if issubclass(w.category, DataImportWarning)]
            others = [w for w in caught if not issubclass(w.category, DataImportWarning)]
    for w in ours:
        log.warning("warning: %s", " ".join(str(w.message).split()))
    for w in others:  # not ours: let Python report it as usual
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def _merged(
    map_: list[str] | None, unit: list[str] | None, map_file: Path | None, kind: str
) -> tuple[dict[str, str], dict[str, str], dict[str, Any]]:
    """Mapping, units and options: the mapping file's, overridden key by key by the options."""
    from behavior_hmm.data._mapfile import MapFile, read_map_file

    loaded = read_map_file(map_file, kind) if map_file is not None else MapFile()
    mapping = {**loaded.map, **pairs(map_ or [], "--map")}
    units = {**loaded.unit, **pairs(unit or [], "--unit")}
    return mapping, units, loaded.options


def _derive(option: str | None, options: dict[str, Any]) -> tuple[str, ...]:
    from behavior_hmm.data._transform import parse_derive

    return parse_derive(option if option is not None else options.get("derive"))


def _metadata(behavior: str | None, goal: str | None, options: dict[str, Any]) -> dict[str, Any]:
    """The imported dataset's behavior and goal: ``--goal`` (else the mapping file's
    ``goal`` table), else the goal of a registered behavior.

    The goal travels in the metadata (``goal``), so a model learns where the
    demonstrations aim without knowing the behavior's name (docs/robots.md); the dataset's
    checks refuse a goal on a channel without a tolerance.
    """
    from behavior_hmm.teach import BEHAVIORS

    name = behavior if behavior is not None else options.get("behavior")
    out: dict[str, Any] = {} if name is None else {"behavior": name}
    if goal is not None:
        out["goal"] = parse_assignments(goal, "--goal")
    elif "goal" in options:
        out["goal"] = dict(options["goal"])
    elif name is not None and str(name) in BEHAVIORS:
        out["goal"] = dict(BEHAVIORS[str(name)].goal)
    return out


def _declared(
    channel: list[str] | None, command: list[str] | None, options: dict[str, Any]
) -> tuple[list[dict[str, Any]], list[dict[str, Any] | str] | None]:
    """The sensor and command channels ``--channel`` / ``--command`` declare, else the
    mapping file's ``channel`` / ``command`` lists (the same NAME:UNIT:LO:HI strings)."""
    channels = channel if channel else list(options.get("channel", []))
    commands = command if command else list(options.get("command", []))
    return channel_options(channels), command_options(commands) if commands else None


def channel_options(items: list[str]) -> list[dict[str, Any]]:
    """``["ir0:m:0:0.1", "x:m:-1:1:0.01", ...]`` -> channel declarations ``{"name", "unit",
    "range"}`` (a fifth part: the goal ``tolerance``)."""
    return [_declaration("--channel", item, "tolerance", "ir0:m:0:0.1") for item in items]


def command_options(items: list[str]) -> list[dict[str, Any] | str]:
    """``["left", "right", "grip:m/s:-0.05:0.05[:REST]"]`` -> the command channels: known
    names as they are, declarations ``{"name", "unit", "range", "rest"}``."""
    out: list[dict[str, Any] | str] = []
    for item in items:
        name = item.strip()
        if ":" not in name:
            out.append(name)
            continue
        out.append(_declaration("--command", item, "rest", "grip:m/s:-0.05:0.05"))
    return out


def _declaration(option: str, item: str, fifth: str, example: str) -> dict[str, Any]:
    """``NAME:UNIT:LO:HI[:FIFTH]`` -> ``{"name", "unit", "range"[, fifth]}``."""
    shown = item if len(item) <= 80 else item[:77] + "..."
    parts = [part.strip() for part in item.split(":")]
    if len(parts) not in (4, 5) or not all(parts):
        raise ConfigError(
            f"{option} expects NAME:UNIT:LO:HI[:{fifth.upper()}] (e.g. {example}), got '{shown}'"
        )
    try:
        numbers = [float(v) for v in parts[2:]]
    except ValueError:
        raise ConfigError(
            f"{option} {shown}: LO, HI and {fifth.upper()} must be numbers (e.g. {example})"
        ) from None
    out: dict[str, Any] = {"name": parts[0], "unit": parts[1], "range": numbers[:2]}
    if len(numbers) == 3:
        out[fifth] = numbers[2]
    return out


def _number(option: float | None, from_file: Any, default: float) -> float:
    if option is not None:
        return float(option)
    if from_file is not None:
        return float(from_file)
    return float(default)


def _wrote(out: Path, dataset: Any) -> None:
    typer.echo(f"wrote {out}: {len(dataset)} episodes, {dataset.n_samples} rows")


@app.command("import-csv")
@user_errors
def import_csv(
    csv_file: Annotated[Path, typer.Argument(help="Your CSV log")],
    out: ParquetOut,
    map_: Annotated[
        list[str] | None,
        typer.Option("--map", help="OURS=THEIRS column mapping, e.g. angle=heading (repeatable)"),
    ] = None,
    unit: UnitOption = None,
    drop: Annotated[
        list[str] | None,
        typer.Option(help="A column of your file to ignore (repeatable)"),
    ] = None,
    split_on_time_reset: Annotated[
        bool,
        typer.Option(
            "--split-on-time-reset",
            help="Without an episode column: start a new episode wherever time drops",
        ),
    ] = False,
    delimiter: Annotated[
        str | None, typer.Option(help="Cell separator, e.g. ';' or 'tab' (default ',')")
    ] = None,
    derive: DeriveOption = None,
    resample: ResampleOption = False,
    map_file: MapFileOption = None,
    behavior: BehaviorOption = None,
    channel: ChannelOption = None,
    command: CommandOption = None,
    goal: GoalOption = None,
) -> None:
    """Convert a CSV log into a validated dataset (same checks as Parquet).

    Our channels are in deg (angle), m (distance), m/s, deg/s and rad/s (wheels); --unit
    says what yours are in. Episode ids may be integers or names (run-a, run-b: numbered
    in order of appearance, the names kept in the metadata). Every column that is not
    ours is named in one error; --drop ignores one, --map renames one, --channel declares
    one as a robot's own sensor channel. A log sampled at another rate than 16 ms gets a
    warning unless --resample.

    Example: behavior-hmm import-csv log.csv --map angle=bearing --unit angle=rad
    --unit t=ms --derive linear_velocity,angular_velocity --resample -o mine.parquet
    """
    from behavior_hmm import data
    from behavior_hmm._paths import check_outputs

    mapping, units, options = _merged(map_, unit, map_file, "csv")
    derived = _derive(derive, options)
    channels, commands = _declared(channel, command, options)
    text = delimiter if delimiter is not None else str(options.get("delimiter", ","))
    sep = "\t" if text in ("tab", "\\t") else text
    if len(sep) != 1:
        raise ConfigError(f"--delimiter must be one character or 'tab', got '{text}'")
    check_outputs({"CSV_FILE": csv_file, "--map-file": map_file}, {"-o": out})
    with _reported_warnings():
        dataset = data.import_csv(
            csv_file,
            mapping=mapping,
            units=units,
            drop=(drop or []) + [str(d) for d in options.get("drop", [])],
            metadata=_metadata(behavior, goal, options),
            split_on_time_reset=split_on_time_reset or bool(options.get("split_on_time_reset")),
            delimiter=sep,
            derive=derived,
            resample=resample or bool(options.get("resample")),
            channels=channels,
            commands=commands,
        )
    data.write(dataset, out)
    _wrote(out, dataset)


@app.command("import-bag")
@user_errors
def import_bag(
    bags: Annotated[
        list[Path],
        typer.Argument(help="ROS 1 .bag files and/or ROS 2 bag folders (one episode each)"),
    ],
    out: ParquetOut,
    map_: Annotated[
        list[str] | None,
        typer.Option(
            "--map",
            help="CHANNEL=TOPIC:FIELD, e.g. angle=/object_bearing:data or "
            "linear_velocity=/odom:twist.twist.linear.x (repeatable)",
        ),
    ] = None,
    unit: UnitOption = None,
    twist: Annotated[
        str | None,
        typer.Option(
            help="A geometry_msgs/Twist topic (v, omega) giving the wheel speeds, e.g. /cmd_vel"
        ),
    ] = None,
    wheel_radius: Annotated[
        float | None,
        typer.Option(help="Wheel radius (m) for --twist; default the simulated robot's"),
    ] = None,
    track_width: Annotated[
        float | None,
        typer.Option(
            help="Distance between the wheels (m) for --twist; default the simulated robot's"
        ),
    ] = None,
    split_gap: Annotated[
        float | None,
        typer.Option(help="Start a new episode after this many seconds without messages"),
    ] = None,
    episode_topic: Annotated[
        str | None,
        typer.Option(help="Counter topic (TOPIC[:FIELD]): a new episode where it changes"),
    ] = None,
    derive: DeriveOption = None,
    map_file: MapFileOption = None,
    behavior: BehaviorOption = None,
    channel: ChannelOption = None,
    command: CommandOption = None,
    goal: GoalOption = None,
) -> None:
    """Convert ROS 1 / ROS 2 bags into a validated dataset (needs the 'bags' extra).

    Every channel comes from one field of one topic; the topics are aligned onto the
    16 ms control period by their time stamps in the bag (from the first instant
    every mapped topic has a message, each holding its latest message). Each bag is
    one episode unless --split-gap or --episode-topic splits it. Our channels are in
    deg (angle) and m (distance); --unit says what yours are in. --channel declares a
    robot's own sensor channel and --command the command channels (e.g. the wheels
    and a gripper), each mapped from a topic with --map NAME=TOPIC:FIELD.

    Example: behavior-hmm import-bag run.bag --map angle=/object_bearing:data
    --unit angle=rad --map distance=/object_distance:data --twist /cmd_vel
    --derive linear_velocity,angular_velocity -o mine.parquet
    """
    from behavior_hmm import data
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.data._bags import import_bags
    from behavior_hmm.sim import RobotParams

    mapping, units, options = _merged(map_, unit, map_file, "bag")
    channels, commands = _declared(channel, command, options)
    derived = _derive(derive, options)
    spec = RobotParams()
    twist_topic = twist if twist is not None else options.get("twist")
    radius = _number(wheel_radius, options.get("wheel_radius"), spec.wheel_radius)
    track = _number(track_width, options.get("track_width"), spec.axle_track)
    gap = split_gap if split_gap is not None else options.get("split_gap")
    counter = episode_topic if episode_topic is not None else options.get("episode_topic")
    check_outputs({"BAG": bags, "--map-file": map_file}, {"-o": out})
    with _reported_warnings():
        dataset = import_bags(
            bags,
            mapping=mapping,
            units=units,
            twist=twist_topic,
            wheel_radius=radius,
            track_width=track,
            split_gap=None if gap is None else float(gap),
            episode_topic=counter,
            derive=derived,
            metadata=_metadata(behavior, goal, options),
            channels=channels,
            commands=commands,
        )
    data.write(dataset, out)
    _wrote(out, dataset)


@app.command("import-lerobot")
@user_errors
def import_lerobot(
    folder: Annotated[Path, typer.Argument(help="A LeRobot dataset folder (meta/info.json)")],
    out: ParquetOut,
    map_: Annotated[
        list[str] | None,
        typer.Option(
            "--map",
            help="CHANNEL=FEATURE[:ELEMENT], e.g. angle=observation.state:bearing or "
            "left=action:0 (repeatable); default: elements named like our channels",
        ),
    ] = None,
    unit: UnitOption = None,
    derive: DeriveOption = None,
    resample: ResampleOption = False,
    map_file: MapFileOption = None,
    behavior: BehaviorOption = None,
    channel: ChannelOption = None,
    command: CommandOption = None,
    goal: GoalOption = None,
) -> None:
    """Convert a LeRobot dataset (v3.0 layout, local files only) into a dataset.

    A folder written by export-lerobot needs no mapping: its declared channels and
    commands come back with it. Frames are read from data/**/*.parquet; time is
    'timestamp', episodes 'episode_index'. Our channels are in deg (angle) and m
    (distance); --unit says what yours are in. --channel declares a robot's own sensor
    channel and --command the command channels in action order, each found by name
    among the features' elements (observation.state, action) or mapped with --map
    NAME=FEATURE:ELEMENT.

    Example: behavior-hmm import-lerobot their_robot --map angle=observation.state:bearing
    --map distance=observation.state:range --map left=action:0 --map right=action:1
    --unit angle=rad --derive linear_velocity,angular_velocity --resample -o mine.parquet
    """
    from behavior_hmm import data
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.data._lerobot import import_lerobot as read_lerobot

    mapping, units, options = _merged(map_, unit, map_file, "lerobot")
    channels, commands = _declared(channel, command, options)
    derived = _derive(derive, options)
    check_outputs({"FOLDER": folder, "--map-file": map_file}, {"-o": out})
    with _reported_warnings():
        dataset = read_lerobot(
            folder,
            mapping=mapping,
            units=units,
            derive=derived,
            resample=resample or bool(options.get("resample")),
            metadata=_metadata(behavior, goal, options),
            channels=channels,
            commands=commands,
        )
    data.write(dataset, out)
    _wrote(out, dataset)


@app.command("export-lerobot")
@user_errors
def export_lerobot(
    inputs: Annotated[
        list[Path],
        typer.Argument(
            help="Datasets (Parquet) and/or traces written by 'generate -o'",
            metavar="DATA...",
        ),
    ],
    folder: Annotated[
        Path, typer.Argument(help="New folder for the LeRobot dataset", metavar="FOLDER")
    ],
    task: Annotated[
        str | None,
        typer.Option(help="Task text of every frame (default: the dataset's behavior)"),
    ] = None,
    robot_type: Annotated[
        str, typer.Option(help="robot_type in meta/info.json")
    ] = "differential_drive",
) -> None:
    """Write datasets or generated traces as a LeRobot dataset (v3.0 layout).

    observation.state holds distance, linear_velocity, angle, angular_velocity
    (m, m/s, deg, deg/s) and the channels the dataset declares (or those only, for a
    robot of its own), action its commands (by default the wheel speeds left, right,
    rad/s), each named in meta/info.json; the declarations travel in
    meta/behavior_hmm.json, so import-lerobot gives the same dataset back. Complex
    demonstrations name each frame's sub-behavior as its task. A trace
    (generate -o) is one episode of the readings the controller saw and its commands;
    several inputs are numbered one after another. FOLDER must be new or empty; nothing
    is left behind on failure.

    Example: behavior-hmm export-lerobot data/turn.parquet lerobot/turn
    """
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.data._lerobot import export_lerobot as write_lerobot

    check_outputs({"DATA": inputs}, {}, folders={"FOLDER": folder})
    dataset = _read_inputs(inputs)
    written = write_lerobot(dataset, folder, task=task, robot_type=robot_type)
    typer.echo(
        f"wrote {written}: LeRobot dataset v3.0, {len(dataset)} episodes, "
        f"{dataset.n_samples} frames"
    )


def _without_behavior(ds: Any) -> Any:
    from behavior_hmm.data import Dataset

    cols = ds.to_columns()
    cols.pop("behavior", None)
    return Dataset(cols, ds.metadata)


def _read_inputs(paths: list[Path]) -> Any:
    """Datasets and traces, their episodes numbered one after another."""
    from behavior_hmm import data

    datasets = [trace_dataset(p) if is_trace_file(p) else data.read(p) for p in paths]
    with_names = [ds.has_behavior for ds in datasets]
    if any(with_names) and not all(with_names) and all(len(ds.behaviors) <= 1 for ds in datasets):
        datasets = [_without_behavior(ds) for ds in datasets]  # one behavior: the task says it
    combined = datasets[0]
    for other in datasets[1:]:
        combined = combined.concat(other, renumber=True)
    if len(datasets) > 1:
        combined = combined.with_metadata(sources=[p.name for p in paths])
    return combined
