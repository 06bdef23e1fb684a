"""Command-line commands that learn, perform and evaluate behaviors.

Registered on the main app by :func:`register` (``behavior_hmm.cli``)::

    behavior-hmm train simple data/turn.parquet --inputs angle -o models/turn.bhmm
    behavior-hmm generate models/turn.bhmm --start angle=120 --goal angle=0 --plot run.png
    behavior-hmm evaluate models/turn.bhmm --starts starts.csv --baseline bc --json out.json
    behavior-hmm experiment simple          # thesis tables 6.3 / 6.4 on MuJoCo
    behavior-hmm experiment categorization  # thesis §6.1
    behavior-hmm experiment generators      # thesis §6.2
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer

from behavior_hmm.data._channels import ARENA_MAX_DISTANCE
from behavior_hmm.errors import ConfigError, DatasetError

train_app = typer.Typer(no_args_is_help=True, help="Learn a behavior from demonstrations.")
experiment_app = typer.Typer(no_args_is_help=True, help="Reproduce the thesis's experiments.")

SIMS = ("mujoco", "kinematic")

#: Options shared by the commands that simulate and write a folder of results.
OutFolder = Annotated[Path, typer.Option("-o", "--out", help="Folder for results")]
SimOption = Annotated[str, typer.Option(help="mujoco or kinematic")]
SeedOption = Annotated[int, typer.Option(help="Seed")]
#: A robot of the user's own (the robot contract, docs/robots.md), in place of --sim.
EnvOption = Annotated[
    str | None,
    typer.Option(
        "--env",
        help="A robot of your own instead of --sim: a registered Gymnasium id, "
        "package.module:factory or path/to/file.py:factory (docs/robots.md)",
    ),
]
EnvKwargsOption = Annotated[
    str | None,
    typer.Option(
        "--env-kwargs", help="JSON object passed to the --env factory, e.g. '{\"mass\": 2}'"
    ),
]
NoiseOption = Annotated[float, typer.Option(help="Sensor noise in evaluation")]
#: How videos are drawn (``generate --video``, ``evaluate --videos``).
VideoBackendOption = Annotated[
    str,
    typer.Option(
        "--video-backend",
        help="matplotlib (top-down, always works) or mujoco (offscreen 3-D; MUJOCO_GL=egl)",
    ),
]
TaskOption = Annotated[
    list[str] | None,
    typer.Option(help="Only this task (repeatable): turn, approach, turn-approach"),
]

#: The options that choose model parameters, shared by every command that trains.
PresetOption = Annotated[
    str | None,
    typer.Option(
        help="Model parameters: 'thesis' (the method as published) or 'default' (ours); "
        "default: the config file's 'preset', else default"
    ),
]
ConfigOption = Annotated[
    Path | None,
    typer.Option(
        "--config",
        help="TOML file of model parameters: top-level NAME = VALUE, or [sblm] / [cblm] tables",
    ),
]
SetOption = Annotated[
    list[str] | None,
    typer.Option(
        "--set",
        help="One model parameter over the preset and config, NAME=VALUE (repeatable), "
        "e.g. --set batch_size=1 --set cblm.repair=false",
    ),
]


def model_params(
    kinds: tuple[str, ...], preset: str | None, config: Path | None, sets: list[str] | None
) -> tuple[str, dict[str, dict[str, Any]]]:
    """Effective model parameters from ``--preset``, ``--config`` and ``--set`` (checked)."""
    from behavior_hmm.models import CBLM, SBLM, read_config, resolve_params
    from behavior_hmm.models._config import parse_sets

    table = read_config(config) if config is not None else None
    name, params = resolve_params(
        kinds, preset, table, parse_sets(sets or []), config_name=str(config or "config")
    )
    for kind, values in params.items():  # ranges and choices, before any work
        {"SBLM": SBLM, "CBLM": CBLM}[kind](**values).check_params()
    return name, params


#: The channels a ``--start`` may set.
START_KEYS: tuple[str, ...] = ("angle", "distance")


def parse_assignments(
    text: str, option: str, allowed: tuple[str, ...] | None = None
) -> dict[str, float]:
    """Parse ``angle=120,distance=0.5`` into ``{"angle": 120.0, "distance": 0.5}``.

    Every value must be a finite number, no key may repeat, and with ``allowed`` every
    key must be one of those; anything else raises :class:`ConfigError`.
    """
    out: dict[str, float] = {}
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError(f"{option} expects CHANNEL=VALUE[,CHANNEL=VALUE], got '{text}'")
        if allowed is not None and key not in allowed:
            choices = ", ".join(allowed)
            raise ConfigError(f"{option}: unknown channel '{key}'; choose from {choices}")
        if key in out:
            raise ConfigError(f"{option} gives '{key}' twice (in '{text}')")
        try:
            number = float(value)
        except ValueError:
            raise ConfigError(f"{option}: '{value}' is not a number (in '{item}')") from None
        if number != number or number in (float("inf"), float("-inf")):
            raise ConfigError(f"{option}: '{value}' is not a finite number")
        out[key] = number
    if not out:
        raise ConfigError(f"{option} is empty; e.g. {option} angle=0")
    return out


def parse_start(text: str, arena: bool = True) -> dict[str, float]:
    """A ``--start``: angle and/or distance, inside our arena unless ``arena`` is False
    (another robot's, ``--env``) (:class:`ConfigError` if not)."""
    from behavior_hmm.teach import check_start

    start = parse_assignments(text, "--start", START_KEYS)
    check_start(start, ARENA_MAX_DISTANCE if arena else math.inf)
    return start


def warn_provenance(model: Any, env: Any, env_name: str) -> None:
    """Warn (stderr) when ``env`` is not the robot, or not the control period, of training."""
    from behavior_hmm.runtime import Robot

    trained = getattr(model, "provenance_", None) or {}
    was = trained.get("env")
    if was and was != env_name:
        typer.echo(f"warning: the model was trained on {was}, running on {env_name}", err=True)
    period = trained.get("control_period")
    now = Robot(env).control_period
    if period and abs(float(period) - now) > 1e-9:
        typer.echo(
            f"warning: the model was trained at a {float(period) * 1000:g} ms control period, "
            f"{env_name} runs at {now * 1000:g} ms",
            err=True,
        )


def check_seed(seed: int, option: str = "--seed") -> int:
    """Refuse a negative seed before any work (numpy and gymnasium need seeds >= 0)."""
    if seed < 0:
        raise ConfigError(f"{option} must be an integer >= 0, got {seed}")
    return seed


def check_noise(noise: float, option: str = "--noise") -> float:
    """Refuse a sensor-noise sigma that is negative or not finite."""
    if not math.isfinite(noise) or noise < 0:
        raise ConfigError(f"{option} must be a finite number >= 0, got {noise}")
    return noise


def load_model(path: Path) -> Any:
    """Load an SBLM or CBLM file, whichever it holds."""
    from behavior_hmm.models import load

    return load(path)


def open_env(sim: str, env: str | None, env_kwargs: str | None) -> tuple[Any, str]:
    """The env to run on and its name: ``--env`` (with ``--env-kwargs``) or ``--sim``."""
    from behavior_hmm.runtime import Robot, make_robot_env, parse_env_kwargs

    if env is None:
        if env_kwargs:
            raise ConfigError("--env-kwargs needs --env (the factory it is passed to)")
        from behavior_hmm.sim import make_env

        return make_env(check_sim(sim)), sim
    made = make_robot_env(env, parse_env_kwargs(env_kwargs))
    Robot(made)  # the contract is checked now, before anything runs
    return made, env


def check_video(path: Path, backend: str) -> None:
    """Refuse a video file or backend we cannot write, before anything runs."""
    from behavior_hmm.viz._mujoco_video import VIDEO_BACKENDS
    from behavior_hmm.viz._video import _video_format

    if backend not in VIDEO_BACKENDS:
        raise ConfigError(
            f"unknown --video-backend '{backend}'; choose one of {', '.join(VIDEO_BACKENDS)}"
        )
    _video_format(path)


def write_video(trace: Any, path: Path, backend: str, robot: Any, title: str = "") -> None:
    """Render one run's video with ``backend`` (see :func:`check_video`)."""
    if backend == "mujoco":
        from behavior_hmm.viz._mujoco_video import render_trace_mujoco

        render_trace_mujoco(trace, path, robot=robot)
    else:
        from behavior_hmm.viz import render_trace

        render_trace(trace, path, robot=robot, title=title)


def check_sim(sim: str) -> str:
    """Refuse an unknown ``--sim`` with its choices."""
    if sim not in SIMS:
        raise ConfigError(f"unknown simulator '{sim}'; choose one of {', '.join(SIMS)}")
    return sim


def _inputs(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise ConfigError("--inputs needs at least one channel, e.g. --inputs angle")
    return names


def register(app: typer.Typer, wrap: Callable[[Any], Any], progress: Callable[[], Any]) -> None:
    """Add train / generate / evaluate / experiment to ``app``; ``wrap`` handles user errors."""

    @train_app.command("simple")
    @wrap
    def train_simple(
        data: Annotated[Path, typer.Argument(help="Demonstrations (Parquet)")],
        inputs: Annotated[str, typer.Option(help="Input channels, e.g. angle,angular_velocity")],
        out: Annotated[Path, typer.Option("-o", "--out", help="Model file to write")],
        seed: Annotated[int, typer.Option(help="Seed of every random choice")] = 0,
        preset: PresetOption = None,
        config: ConfigOption = None,
        set_: SetOption = None,
    ) -> None:
        """Learn a simple behavior (SBLM) from demonstrations.

        Example: behavior-hmm train simple data/turn.parquet --inputs angle --preset thesis
        -o models/turn-thesis.bhmm
        """
        import time

        from behavior_hmm import data as bdata
        from behavior_hmm._paths import check_outputs
        from behavior_hmm.models import SBLM, describe_params

        check_seed(seed)
        check_outputs({"DATA": data, "--config": config}, {"-o": out})
        _, params = model_params(("SBLM",), preset, config, set_)
        model = SBLM(**params["SBLM"], inputs=_inputs(inputs), random_state=seed)
        model.check_params()  # before any data is read
        dataset = bdata.read(data)
        t0 = time.perf_counter()
        model.fit(dataset)
        model.set_training_data(data)
        model.save(out)
        typer.echo(
            f"wrote {out}: {model.behavior_} on {','.join(model.inputs_)}, "
            f"{model.primitives_.n_categories_} primitives, "
            f"{model.observations_.n_categories_} observation categories, "
            f"preset {describe_params('SBLM', model.get_params())} "
            f"({time.perf_counter() - t0:.1f} s)"
        )

    @train_app.command("complex")
    @wrap
    def train_complex(
        data: Annotated[Path, typer.Argument(help="Tagged demonstrations (behavior column)")],
        component: Annotated[
            list[Path], typer.Option(help="A learned behavior (.bhmm), repeatable")
        ],
        out: Annotated[Path, typer.Option("-o", "--out", help="Model file to write")],
        inputs: Annotated[str, typer.Option(help="Input channels")] = "distance,angle",
        preset: PresetOption = None,
        config: ConfigOption = None,
        set_: SetOption = None,
    ) -> None:
        """Compose learned behaviors (CBLM) from demonstrations tagged per row.

        The preset, config and --set choose the CBLM's own parameters; the components
        keep theirs. Example: behavior-hmm train complex data/ta.parquet --component
        models/turn.bhmm --component models/approach.bhmm --preset thesis -o models/ta.bhmm
        """
        import time

        from behavior_hmm import data as bdata
        from behavior_hmm._paths import check_outputs
        from behavior_hmm.models import CBLM, describe_params

        check_outputs({"DATA": data, "--component": component, "--config": config}, {"-o": out})
        _, params = model_params(("CBLM",), preset, config, set_)
        CBLM(**params["CBLM"]).check_params()  # before any file is read
        components = [load_model(path) for path in component]
        dataset = bdata.read(data)
        t0 = time.perf_counter()
        model = CBLM(components, **params["CBLM"], inputs=_inputs(inputs)).fit(dataset)
        model.set_training_data(data)
        model.save(out)
        typer.echo(
            f"wrote {out}: {model.behavior_} over {', '.join(model.names_)} on "
            f"{','.join(model.inputs_)}, {model.observations_.n_categories_} observation "
            f"categories, preset {describe_params('CBLM', model.get_params())} "
            f"({time.perf_counter() - t0:.1f} s); components unchanged"
        )

    app.add_typer(train_app, name="train")

    @app.command()
    @wrap
    def generate(
        model_file: Annotated[Path, typer.Argument(help="A model file (.bhmm)")],
        start: Annotated[str, typer.Option(help="Start, e.g. angle=120,distance=0.5")],
        goal: Annotated[
            str | None, typer.Option(help="Goal, e.g. angle=0 (default: where demos end)")
        ] = None,
        sim: SimOption = "mujoco",
        seed: Annotated[int, typer.Option(help="Seed of the sensor-noise draws")] = 0,
        noise: Annotated[float, typer.Option(help="Sensor noise (sigma x channel range)")] = 0.0,
        out: Annotated[Path | None, typer.Option("-o", "--out", help="Trace (Parquet)")] = None,
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
    ) -> None:
        """Perform a learned behavior from a start to a goal in the simulator.

        The trace (-o) and the plot (--plot) are written together, or neither is.
        """
        from behavior_hmm._atomic import all_or_none
        from behavior_hmm._paths import check_outputs

        check_sim(sim)
        check_seed(seed)
        check_noise(noise)
        check_outputs(
            {"MODEL_FILE": model_file},
            {"-o": out, "--plot": plot, "--video": video},
            plots=("--plot",),
        )
        if video is not None:
            check_video(video, video_backend)
        begin = parse_start(start, arena=env is None)
        target = parse_assignments(goal, "--goal") if goal is not None else None
        model = load_model(model_file)
        if target is not None:
            model.resolve_goal(target)  # refuse a bad goal before any motion
        robot, robot_name = open_env(sim, env, env_kwargs)
        warn_provenance(model, robot, robot_name)
        trace = model.generate(robot, start=begin, goal=target, seed=seed, noise=noise or None)
        summary = trace.summary()
        typer.echo(json.dumps(summary, default=float))
        with all_or_none():
            if out is not None:
                trace.write(out)
            if plot is not None:
                from behavior_hmm.viz import plot_trace

                plot_trace(trace, plot)
            if video is not None:
                write_video(trace, video, video_backend, robot, title=model_file.stem)
        if out is not None:
            typer.echo(f"trace: {out}")
        if plot is not None:
            typer.echo(f"plot: {plot}")
        if video is not None:
            typer.echo(f"video: {video}")
        if not trace.goal_reached:
            raise typer.Exit(code=1)

    @app.command()
    @wrap
    def evaluate(
        model_file: Annotated[Path, typer.Argument(help="A model file (.bhmm)")],
        starts: Annotated[
            Path | None,
            typer.Option(help="Starts CSV (angle, distance, goal_<channel>); default: 15 tests"),
        ] = None,
        sim: SimOption = "mujoco",
        seed: SeedOption = 0,
        noise: Annotated[float, typer.Option(help="Sensor noise (sigma x channel range)")] = 0.0,
        baseline: Annotated[
            list[str] | None, typer.Option(help="Baselines to run beside the model: bc")
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
    ) -> None:
        """Score a model (and baselines) against the teacher from test starts.

        Every start (and its goal) is checked before the first case runs; --json and
        --report are written together, or neither is. Each case also records the largest
        command change in one period against the teacher's (command_jump_ratio) and the
        primitive (SBLM) or component (CBLM) switches.
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
        robot, robot_name = open_env(sim, env, env_kwargs) if env is not None else (None, sim)
        inputs: dict[str, Any] = {"MODEL_FILE": model_file, "--starts": starts, "--data": data}
        outputs = {"--json": json_out, "--report": report}
        check_outputs(inputs, outputs, folders={"--videos": videos} if videos else None)
        if videos is not None:
            check_video(videos / "case_00.mp4", video_backend)
        model = load_model(model_file)
        if baseline and data is None and getattr(model, "train_data_", None):
            # the baselines train on the model's own data file: never write over it
            inputs["the model's training data"] = Path(model.train_data_)
            check_outputs(inputs, outputs)
        if robot is None:
            chosen = read_starts(starts) if starts is not None else test_starts(model.behavior_)
        else:
            warn_provenance(model, robot, robot_name)
            chosen = (
                read_starts(starts, math.inf)
                if starts is not None
                else scaled_starts(test_starts(model.behavior_), robot)
            )
        _check_cases(model, chosen, starts, arena=robot is None)
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
            )
        traces = result.pop("_traces", None)
        if videos is not None and traces:
            videos.mkdir(parents=True, exist_ok=True)
            if robot is not None:
                scene = robot
            else:  # our robot: its sizes (kinematic: no physics needed to draw it)
                from behavior_hmm.sim import make_env

                scene = make_env("kinematic")
            for i, (trace, _) in enumerate(traces["model"]):
                start = ", ".join(f"{k} {v:g}" for k, v in trace.start.items())
                if not len(trace.pose):  # refused before any motion: nothing to show
                    typer.echo(f"no video of case {i} ({start}): {trace.reason}", err=True)
                    continue
                write_video(
                    trace,
                    videos / f"case_{i:02d}.mp4",
                    video_backend,
                    scene,
                    title=f"{model.behavior_} from {start}",
                )
            typer.echo(f"videos: {videos}/case_00.mp4 ... case_{len(traces['model']) - 1:02d}.mp4")
        text = json.dumps(result, indent=1, default=float)
        with all_or_none():
            if json_out is not None:
                atomic_write_bytes(json_out, text.encode())
            if report is not None:
                from behavior_hmm.viz import write_evaluation_report

                write_evaluation_report(result, traces, report)
        if report is not None:
            typer.echo(f"report: {report}")
        _print_evaluation(result)

    @experiment_app.command("simple")
    @wrap
    def experiment_simple(
        out: OutFolder = Path("results/simple"),
        sim: SimOption = "mujoco",
        seed: SeedOption = 0,
        noise: NoiseOption = 0.0,
        preset: PresetOption = None,
        config: ConfigOption = None,
        set_: SetOption = None,
    ) -> None:
        """Thesis tables 6.3 and 6.4: SBLM vs the thesis and behavior cloning."""
        from behavior_hmm._atomic import all_or_none
        from behavior_hmm._paths import check_outputs
        from behavior_hmm.evaluate._experiments import run_simple_experiment
        from behavior_hmm.viz import write_simple_report

        check_sim(sim)
        check_seed(seed)
        check_noise(noise)
        check_outputs({"--config": config}, {}, folders={"-o": out})
        name, params = model_params(("SBLM",), preset, config, set_)
        results = _with_progress(
            progress,
            f"experiment simple ({sim}, {name} preset)",
            run_simple_experiment,
            sim=sim,
            seed=seed,
            noise=noise,
            sblm_params=params["SBLM"],
        )
        results["preset"] = name
        with all_or_none():  # every file of the report, or none
            table = write_simple_report(results, out)
        typer.echo(table)
        typer.echo(f"results: {out}/results.json, figures and table.md")

    @experiment_app.command("robot")
    @wrap
    def experiment_robot(
        env: Annotated[
            str,
            typer.Option(
                "--env",
                help="The robot: a registered Gymnasium id, package.module:factory or "
                "path/to/file.py:factory (docs/robots.md)",
            ),
        ],
        out: OutFolder = Path("results/robot"),
        env_kwargs: EnvKwargsOption = None,
        seed: SeedOption = 0,
        preset: PresetOption = None,
        config: ConfigOption = None,
        set_: SetOption = None,
    ) -> None:
        """Turn, approach and turn & approach on any robot, composed from its own components.

        Our teacher demonstrates on the robot from the default grids scaled to it
        (env.unwrapped.start_scale); the test starts are scaled the same way.
        Example: behavior-hmm experiment robot --env behavior_hmm/Husky-v0 -o results/husky
        """
        from behavior_hmm._atomic import all_or_none
        from behavior_hmm._paths import check_outputs
        from behavior_hmm.evaluate._robot_experiment import run_robot_experiment
        from behavior_hmm.viz import write_robot_report

        check_seed(seed)
        check_outputs({"--config": config}, {}, folders={"-o": out})
        name, params = model_params(("SBLM", "CBLM"), preset, config, set_)
        robot, robot_name = open_env("mujoco", env, env_kwargs)
        results = _with_progress(
            progress,
            f"experiment robot ({robot_name}, {name} preset)",
            run_robot_experiment,
            env=robot,
            env_name=robot_name,
            seed=seed,
            sblm_params=params["SBLM"],
            cblm_params=params["CBLM"],
        )
        results["preset"] = name
        sizes = {
            "object_radius": getattr(robot.unwrapped, "object_radius", None),
            "body_radius": getattr(robot.unwrapped, "body_radius", None),
        }
        with all_or_none():  # every file of the report, or none
            table = write_robot_report(results, out, **sizes)
        typer.echo(table)
        typer.echo(f"results: {out}/results.json, trajectories.png and table.md")

    @experiment_app.command("complex")
    @wrap
    def experiment_complex(
        out: OutFolder = Path("results/complex"),
        sim: SimOption = "mujoco",
        seed: SeedOption = 0,
        noise: NoiseOption = 0.0,
        preset: PresetOption = None,
        config: ConfigOption = None,
        set_: SetOption = None,
    ) -> None:
        """Thesis table 6.5 and fig 6.10, plus position over {turn, approach, retreat}."""
        from behavior_hmm._atomic import all_or_none
        from behavior_hmm._paths import check_outputs
        from behavior_hmm.evaluate._experiments import run_complex_experiment
        from behavior_hmm.viz import write_complex_report

        check_sim(sim)
        check_seed(seed)
        check_noise(noise)
        check_outputs({"--config": config}, {}, folders={"-o": out})
        name, params = model_params(("SBLM", "CBLM"), preset, config, set_)
        results = _with_progress(
            progress,
            f"experiment complex ({sim}, {name} preset)",
            run_complex_experiment,
            sim=sim,
            seed=seed,
            noise=noise,
            sblm_params=params["SBLM"],
            cblm_params=params["CBLM"],
        )
        results["preset"] = name
        with all_or_none():  # every file of the report, or none
            table = write_complex_report(results, out)
        typer.echo(table)
        typer.echo(f"results: {out}/results.json, figures and table.md")

    @experiment_app.command("ablation")
    @wrap
    def experiment_ablation(
        out: OutFolder = Path("results/ablation"),
        sim: SimOption = "mujoco",
        seed: SeedOption = 0,
        noise: NoiseOption = 0.0,
        task: TaskOption = None,
        departure: Annotated[
            list[str] | None,
            typer.Option(help="Only this departure's rows (repeatable), e.g. onset_clock"),
        ] = None,
    ) -> None:
        """What each departure from the thesis buys: thesis, thesis + each, default, default - each.

        Every row is trained on the same demonstrations and scored from the test starts,
        beside the all-zero floor. Writes results.json, table.md and ablation.png.
        Example: behavior-hmm experiment ablation --sim kinematic --task turn -o results/abl
        """
        from behavior_hmm._atomic import all_or_none
        from behavior_hmm._paths import check_outputs
        from behavior_hmm.evaluate._ablation import run_ablation
        from behavior_hmm.evaluate._ablation import task as ablation_task
        from behavior_hmm.models._presets import departure as named_departure
        from behavior_hmm.viz._ablation import write_ablation_report

        check_sim(sim)
        check_seed(seed)
        check_noise(noise)
        check_outputs({}, {}, folders={"-o": out})
        for name in departure or []:
            named_departure(name)  # refuse bad names before any work
        for name in task or []:
            ablation_task(name)

        results = _with_progress(
            progress,
            f"experiment ablation ({sim})",
            run_ablation,
            sim=sim,
            seed=seed,
            noise=noise,
            tasks=task or None,
            departures=departure or None,
        )
        with all_or_none():  # every file of the report, or none
            table = write_ablation_report(results, out)
        typer.echo(table)
        typer.echo(f"results: {out}/results.json, table.md and ablation.png")

    @experiment_app.command("faults")
    @wrap
    def experiment_faults(
        out: OutFolder = Path("results/faults"),
        sim: SimOption = "mujoco",
        seed: SeedOption = 0,
        task: TaskOption = None,
        fault: Annotated[
            list[str] | None,
            typer.Option(
                help="Only this fault kind (repeatable): noise, wheel_mismatch, motor_lag, "
                "speed_limit, push_bearing, push_distance, dropout"
            ),
        ] = None,
    ) -> None:
        """Fault sweep: goal reached and success rate of the default models under faults.

        Sensor noise, wheel mismatch, motor lag, wheel-speed limits, pushes and NaN
        dropouts, one at a time, from each task's 15 test starts. Writes results.json,
        table.md, faults_goal.png and faults_success.png.
        Example: behavior-hmm experiment faults --sim kinematic --task turn --fault noise
        """
        from behavior_hmm._atomic import all_or_none
        from behavior_hmm._paths import check_outputs
        from behavior_hmm.evaluate._ablation import task as ablation_task
        from behavior_hmm.evaluate._faults import fault_kind, run_faults
        from behavior_hmm.viz._faults import write_faults_report

        check_sim(sim)
        check_seed(seed)
        for name in task or []:
            ablation_task(name)  # refuse bad names before any work
        for name in fault or []:
            fault_kind(name)
        check_outputs({}, {}, folders={"-o": out})
        with progress() as bar:
            job = bar.add_task(f"experiment faults ({sim})", total=None)
            results = run_faults(
                sim=sim,
                seed=seed,
                tasks=task or None,
                faults=fault or None,
                progress=lambda d, t: bar.update(job, completed=d, total=t),
            )
        with all_or_none():  # every file of the report, or none
            table = write_faults_report(results, out)
        typer.echo(table)
        typer.echo(f"results: {out}/results.json, table.md, faults_goal.png, faults_success.png")

    @experiment_app.command("categorization")
    @wrap
    def experiment_categorization(
        out: OutFolder = Path("results/categorization"),
        sim: SimOption = "mujoco",
        seed: SeedOption = 0,
    ) -> None:
        """Thesis §6.1: turn primitives at vigilance 0.85 and 0.75 (table 6.1, figs 6.1-6.4)."""
        from behavior_hmm._atomic import all_or_none
        from behavior_hmm._paths import check_outputs
        from behavior_hmm.evaluate._categorization import (
            TABLE_6_1_STARTS,
            run_categorization_experiment,
        )
        from behavior_hmm.teach import collect
        from behavior_hmm.viz._categories import write_categorization_report

        check_sim(sim)
        check_seed(seed)
        check_outputs({}, {}, folders={"-o": out})
        train = collect("turn", sim=sim, seed=seed)
        samples = collect(
            "turn", [{"angle": a} for a in TABLE_6_1_STARTS], sim=sim, seed=seed + 1000
        )
        results = run_categorization_experiment(train, samples)
        with all_or_none():  # every file of the report, or none
            table = write_categorization_report(results, out)
        typer.echo(table)
        typer.echo(f"figures and categorization.json in {out}")

    @experiment_app.command("generators")
    @wrap
    def experiment_generators(
        out: OutFolder = Path("results/generators"),
        sim: SimOption = "mujoco",
        epochs: Annotated[int, typer.Option(help="Epochs per setting")] = 100,
        seed: SeedOption = 0,
    ) -> None:
        """Thesis §6.2 and appendix A: generator training sweeps (figs 6.5-6.7, A.1).

        One representative turn primitive (the robot moving, its commands changing),
        incremental training; test error against iterations (samples presented).
        """
        from behavior_hmm._atomic import all_or_none
        from behavior_hmm._paths import check_outputs
        from behavior_hmm.cobart import CobART
        from behavior_hmm.data import CommandScaler, SignalPipeline
        from behavior_hmm.evaluate import run_generator_sweeps
        from behavior_hmm.generators import make_windows
        from behavior_hmm.teach import collect
        from behavior_hmm.viz import plot_generator_sweeps

        check_sim(sim)
        check_seed(seed)
        if epochs < 1:
            raise ConfigError(f"--epochs must be an integer >= 1, got {epochs}")
        check_outputs({}, {}, folders={"-o": out})
        data = collect("turn", sim=sim, seed=seed)
        x = SignalPipeline(("angle",)).transform(data)
        primitives = CobART.motion_primitives().fit(x, data.lengths).labels_
        windows = make_windows(x, data.lengths, 10)
        # appendix A: two-input networks (angle and angular velocity, 20 inputs) on the
        # same primitive's rows
        x2 = SignalPipeline(("angle", "angular_velocity")).transform(data)
        windows2 = make_windows(x2, data.lengths, 10)
        y = CommandScaler().fit(data.commands).transform(data.commands)
        with all_or_none():  # the summary and every figure, or none
            report = run_generator_sweeps(
                windows,
                y,
                primitives,
                out,
                epochs=epochs,
                X_two_inputs=windows2,
                inputs_label="angle",
                two_inputs_label="angle, angular velocity",
                random_state=seed,
            )
            figures = plot_generator_sweeps(report, out)
        chosen = report["selection"]["chosen"]
        typer.echo(
            f"primitive {report['primitive']}: {chosen['n_samples']} samples, target std "
            f"{chosen['target_std']:.3f}, RMS {chosen['target_rms']:.3f} (medians "
            f"{report['selection']['median_target_std']:.3f}, "
            f"{report['selection']['median_target_rms']:.3f}); {report['n_train']} training "
            f"samples = iterations per epoch"
        )
        for name, entries in report["sweeps"].items():
            typer.echo(f"{name} sweep:")
            for label, entry in entries.items():
                typer.echo(
                    f"  {label:16s} best test RMS {entry['best_test_error']:.4f} at iteration "
                    f"{entry['best_iteration']} (epoch {entry['best_epoch']}), final "
                    f"{entry['final_test_error']:.4f}"
                )
        typer.echo("figures: " + ", ".join(figures.values()))

    app.add_typer(experiment_app, name="experiment")


def _with_progress(
    progress: Callable[[], Any],
    label: str,
    experiment: Callable[..., dict[str, Any]],
    **kwargs: Any,
) -> dict[str, Any]:
    """Run an experiment function under a progress bar (``kwargs`` passed on)."""
    with progress() as bar:
        task = bar.add_task(label, total=None)
        return experiment(progress=lambda d, t: bar.update(task, completed=d, total=t), **kwargs)


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
    unknown = [n for n in names if n != "bc"]
    if unknown:
        raise ConfigError(f"unknown baseline '{unknown[0]}'; available: bc")
    from behavior_hmm import data as bdata
    from behavior_hmm.evaluate import BehaviorCloning

    source = data or (Path(model.train_data_) if getattr(model, "train_data_", None) else None)
    if source is None:
        raise ConfigError("--baseline bc needs the training data: pass --data DATA.parquet")
    try:
        dataset = bdata.read(source)
    except DatasetError as err:
        raise DatasetError(f"baseline training data: {err}") from None
    return {"bc": BehaviorCloning(inputs=model.inputs_, random_state=seed).fit(dataset)}


def _print_evaluation(result: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"{result['behavior']} on {','.join(result['inputs'])} ({result['sim']})")
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
            f"{r['success_rate_motor_max_mean']:.1f}",
            f"{r['duration_ratio_mean']:.2f}",
            f"{r['command_jump_ratio_median']:.1f} / {r['command_jump_ratio_max']:.1f}",
            f"{r['switches_max']}",
        ]
        if "pushed" in result:
            cells.append(f"{r.get('pushed', 0)}/{r['n']}")
        table.add_row(*cells)
    Console().print(table)
