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
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer

from behavior_hmm.errors import ConfigError, DatasetError, ModelFileError

train_app = typer.Typer(no_args_is_help=True, help="Learn a behavior from demonstrations.")
experiment_app = typer.Typer(no_args_is_help=True, help="Reproduce the thesis's experiments.")

SIMS = ("mujoco", "kinematic")


def parse_assignments(text: str, option: str) -> dict[str, float]:
    """Parse ``angle=120,distance=0.5`` into ``{"angle": 120.0, "distance": 0.5}``."""
    out: dict[str, float] = {}
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        key, sep, value = item.partition("=")
        if not sep:
            raise ConfigError(f"{option} expects CHANNEL=VALUE[,CHANNEL=VALUE], got '{text}'")
        try:
            number = float(value)
        except ValueError:
            raise ConfigError(f"{option}: '{value}' is not a number (in '{item}')") from None
        if number != number or number in (float("inf"), float("-inf")):
            raise ConfigError(f"{option}: '{value}' is not a finite number")
        out[key.strip()] = number
    if not out:
        raise ConfigError(f"{option} is empty; e.g. {option} angle=0")
    return out


def load_model(path: Path) -> Any:
    """Load an SBLM or CBLM file, whichever it holds."""
    from behavior_hmm.models import _modelfile

    header, _ = _modelfile.load(path)
    kind = header["kind"]
    if kind == "SBLM":
        from behavior_hmm.models import SBLM

        return SBLM.load(path)
    if kind == "CBLM":
        from behavior_hmm import models

        return models.CBLM.load(path)
    raise ModelFileError(f"{path}: unknown model kind '{kind}'")


def _check_sim(sim: str) -> str:
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
    ) -> None:
        """Learn a simple behavior (SBLM) from demonstrations."""
        import time

        from behavior_hmm import data as bdata
        from behavior_hmm.models import SBLM

        dataset = bdata.read(data)
        t0 = time.perf_counter()
        model = SBLM(inputs=_inputs(inputs), random_state=seed).fit(dataset)
        model.train_data_ = str(data)
        model.save(out)
        typer.echo(
            f"wrote {out}: {model.behavior_} on {','.join(model.inputs_)}, "
            f"{model.primitives_.n_categories_} primitives, "
            f"{model.observations_.n_categories_} observation categories "
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
    ) -> None:
        """Compose learned behaviors (CBLM) from demonstrations tagged per row."""
        import time

        from behavior_hmm import data as bdata
        from behavior_hmm.models import CBLM

        components = [load_model(path) for path in component]
        dataset = bdata.read(data)
        t0 = time.perf_counter()
        model = CBLM(components, inputs=_inputs(inputs)).fit(dataset)
        model.train_data_ = str(data)
        model.save(out)
        typer.echo(
            f"wrote {out}: {model.behavior_} over {', '.join(model.names_)} on "
            f"{','.join(model.inputs_)}, {model.observations_.n_categories_} observation "
            f"categories ({time.perf_counter() - t0:.1f} s); components unchanged"
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
        sim: Annotated[str, typer.Option(help="mujoco or kinematic")] = "mujoco",
        seed: Annotated[int, typer.Option(help="Seed of the sensor-noise draws")] = 0,
        noise: Annotated[float, typer.Option(help="Sensor noise (sigma x channel range)")] = 0.0,
        out: Annotated[Path | None, typer.Option("-o", "--out", help="Trace (Parquet)")] = None,
        plot: Annotated[Path | None, typer.Option(help="PNG of the run")] = None,
    ) -> None:
        """Perform a learned behavior from a start to a goal in the simulator."""
        from behavior_hmm.sim import make_env
        from behavior_hmm.teach import check_start

        _check_sim(sim)
        model = load_model(model_file)
        begin = parse_assignments(start, "--start")
        check_start(begin)
        target = parse_assignments(goal, "--goal") if goal is not None else None
        if target is not None:
            model.resolve_goal(target)  # refuse a bad goal before any motion
        env = make_env(sim)
        trace = model.generate(env, start=begin, goal=target, seed=seed, noise=noise)
        summary = trace.summary()
        typer.echo(json.dumps(summary, default=float))
        if out is not None:
            trace.write(out)
            typer.echo(f"trace: {out}")
        if plot is not None:
            from behavior_hmm.viz import plot_trace

            plot_trace(trace, plot)
            typer.echo(f"plot: {plot}")
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
        sim: Annotated[str, typer.Option(help="mujoco or kinematic")] = "mujoco",
        seed: Annotated[int, typer.Option(help="Seed")] = 0,
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
    ) -> None:
        """Score a model (and baselines) against the teacher from test starts."""
        from behavior_hmm._atomic import atomic_write_bytes
        from behavior_hmm.evaluate import evaluate_model
        from behavior_hmm.teach import read_starts, test_starts

        _check_sim(sim)
        if noise < 0:
            raise ConfigError(f"--noise must be >= 0, got {noise}")
        model = load_model(model_file)
        chosen = read_starts(starts) if starts is not None else test_starts(model.behavior_)
        baselines = _baselines(baseline or [], model, data, seed)
        with progress() as bar:
            task = bar.add_task(f"evaluate {model.behavior_} ({sim})", total=None)
            result = evaluate_model(
                model,
                chosen,
                sim=sim,
                seed=seed,
                noise=noise,
                baselines=baselines,
                progress=lambda d, t: bar.update(task, completed=d, total=t),
                keep_traces=report is not None,
            )
        traces = result.pop("_traces", None)
        text = json.dumps(result, indent=1, default=float)
        if json_out is not None:
            atomic_write_bytes(json_out, text.encode())
        if report is not None:
            from behavior_hmm.viz import write_evaluation_report

            write_evaluation_report(result, traces, report)
            typer.echo(f"report: {report}")
        _print_evaluation(result)

    @experiment_app.command("simple")
    @wrap
    def experiment_simple(
        out: Annotated[Path, typer.Option("-o", "--out", help="Folder for results")] = Path(
            "results/simple"
        ),
        sim: Annotated[str, typer.Option(help="mujoco or kinematic")] = "mujoco",
        seed: Annotated[int, typer.Option(help="Seed")] = 0,
        noise: Annotated[float, typer.Option(help="Sensor noise in evaluation")] = 0.0,
    ) -> None:
        """Thesis tables 6.3 and 6.4: SBLM vs the thesis and behavior cloning."""
        from behavior_hmm.evaluate._experiments import run_simple_experiment
        from behavior_hmm.viz import write_simple_report

        _check_sim(sim)
        results = _with_progress(
            progress, f"experiment simple ({sim})", run_simple_experiment, sim, seed, noise
        )
        typer.echo(write_simple_report(results, out))
        typer.echo(f"results: {out}/results.json, figures and table.md")

    @experiment_app.command("complex")
    @wrap
    def experiment_complex(
        out: Annotated[Path, typer.Option("-o", "--out", help="Folder for results")] = Path(
            "results/complex"
        ),
        sim: Annotated[str, typer.Option(help="mujoco or kinematic")] = "mujoco",
        seed: Annotated[int, typer.Option(help="Seed")] = 0,
        noise: Annotated[float, typer.Option(help="Sensor noise in evaluation")] = 0.0,
    ) -> None:
        """Thesis table 6.5 and fig 6.10, plus position over {turn, approach, retreat}."""
        from behavior_hmm.evaluate._experiments import run_complex_experiment
        from behavior_hmm.viz import write_complex_report

        _check_sim(sim)
        results = _with_progress(
            progress, f"experiment complex ({sim})", run_complex_experiment, sim, seed, noise
        )
        typer.echo(write_complex_report(results, out))
        typer.echo(f"results: {out}/results.json, figures and table.md")

    @experiment_app.command("categorization")
    @wrap
    def experiment_categorization(
        out: Annotated[Path, typer.Option("-o", "--out", help="Folder for results")] = Path(
            "results/categorization"
        ),
        sim: Annotated[str, typer.Option(help="mujoco or kinematic")] = "mujoco",
        seed: Annotated[int, typer.Option(help="Seed")] = 0,
    ) -> None:
        """Thesis §6.1: turn primitives at vigilance 0.85 and 0.75 (table 6.1, figs 6.1-6.4)."""
        from behavior_hmm.evaluate._categorization import (
            TABLE_6_1_STARTS,
            run_categorization_experiment,
        )
        from behavior_hmm.teach import collect
        from behavior_hmm.viz._categories import write_categorization_report

        _check_sim(sim)
        train = collect("turn", sim=sim, seed=seed)
        samples = collect(
            "turn", [{"angle": a} for a in TABLE_6_1_STARTS], sim=sim, seed=seed + 1000
        )
        results = run_categorization_experiment(train, samples)
        typer.echo(write_categorization_report(results, out))
        typer.echo(f"figures and categorization.json in {out}")

    @experiment_app.command("generators")
    @wrap
    def experiment_generators(
        out: Annotated[Path, typer.Option("-o", "--out", help="Folder for results")] = Path(
            "results/generators"
        ),
        sim: Annotated[str, typer.Option(help="mujoco or kinematic")] = "mujoco",
        epochs: Annotated[int, typer.Option(help="Epochs per setting")] = 100,
        seed: Annotated[int, typer.Option(help="Seed")] = 0,
    ) -> None:
        """Thesis §6.2: learning rate, momentum and hidden-layer sweeps (figs 6.5-6.7)."""
        from behavior_hmm.cobart import CobART
        from behavior_hmm.data import CommandScaler, SignalPipeline
        from behavior_hmm.evaluate import run_generator_sweeps
        from behavior_hmm.generators import make_windows
        from behavior_hmm.teach import collect
        from behavior_hmm.viz import plot_generator_sweeps

        _check_sim(sim)
        data = collect("turn", sim=sim, seed=seed)
        x = SignalPipeline(("angle",)).transform(data)
        primitives = CobART.motion_primitives().fit(x, data.lengths).labels_
        windows = make_windows(x, data.lengths, 10)
        y = CommandScaler().fit(data.commands).transform(data.commands)
        report = run_generator_sweeps(windows, y, primitives, out, epochs=epochs, random_state=seed)
        figures = plot_generator_sweeps(report, out)
        for name, entries in report["sweeps"].items():
            typer.echo(f"{name} sweep (primitive {report['primitive']}, {report['n_train']} rows):")
            for label, entry in entries.items():
                typer.echo(
                    f"  {label:16s} best test RMS {entry['best_test_error']:.4f} "
                    f"at epoch {entry['best_epoch']}, final {entry['final_test_error']:.4f}"
                )
        typer.echo("figures: " + ", ".join(figures.values()))

    app.add_typer(experiment_app, name="experiment")


def _with_progress(
    progress: Callable[[], Any],
    label: str,
    experiment: Callable[..., dict[str, Any]],
    sim: str,
    seed: int,
    noise: float,
) -> dict[str, Any]:
    """Run an experiment function under a progress bar."""
    with progress() as bar:
        task = bar.add_task(label, total=None)
        return experiment(
            sim=sim,
            seed=seed,
            noise=noise,
            progress=lambda d, t: bar.update(task, completed=d, total=t),
        )


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
    for col in ("", "success %", "goal reached", "zero floor %", "motor-max %", "duration x"):
        table.add_column(col)
    rows = [("SBLM", result)] + [(n, r) for n, r in result["baselines"].items()]
    for name, r in rows:
        table.add_row(
            name,
            f"{r['success_rate_mean']:.1f}",
            f"{r['goal_reached']}/{r['n']}",
            f"{r['zero_floor_mean']:.1f}",
            f"{r['success_rate_motor_max_mean']:.1f}",
            f"{r['duration_ratio_mean']:.2f}",
        )
    Console().print(table)
