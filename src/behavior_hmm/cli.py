"""The ``behavior-hmm`` command line.

Examples
--------
::

    behavior-hmm demo
    behavior-hmm collect turn -o data/turn.parquet
    behavior-hmm collect approach --starts starts.csv --sim kinematic --noise 0.005 -o a.parquet
    behavior-hmm inspect data/turn.parquet --plot turn.png
    behavior-hmm import-csv log.csv --map angle=heading_err --unit angle=rad -o mine.parquet
    behavior-hmm bench sim --json sim.json

User errors print one line and exit with code 2; nothing half-written is left behind.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer

from behavior_hmm._cli_learn import EnvKwargsOption, EnvOption, check_sim, open_env
from behavior_hmm.errors import BehaviorHMMError, ConfigError

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Learn robot behaviors from unlabeled demonstrations (CobART + Behavior-HMM).",
    pretty_exceptions_enable=False,
)

F = TypeVar("F", bound=Callable[..., Any])


def _user_errors(func: F) -> F:
    """Turn our errors into one line on stderr and exit code 2 (no traceback)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except BehaviorHMMError as err:
            typer.echo(f"error: {' '.join(str(err).split())}", err=True)
            raise typer.Exit(code=2) from None
        except BrokenPipeError:  # output piped into e.g. `head`, which has exited: stop quietly
            import os
            import sys

            try:  # keep Python's final flush of stdout from failing again
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            except (OSError, ValueError):
                pass
            raise typer.Exit(code=141) from None
        except OSError as err:  # a path we cannot read or write: the user's to fix
            where = f"{err.filename}: " if err.filename else ""
            typer.echo(f"error: {where}{err.strerror or err}", err=True)
            raise typer.Exit(code=2) from None
        except KeyboardInterrupt:
            typer.echo("interrupted", err=True)
            raise typer.Exit(code=130) from None

    return wrapper  # type: ignore[return-value]


#: Standard deviations of sensor noise that must fit inside the plausible bounds.
NOISE_SIGMAS = 5.0


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


def _progress() -> Any:
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        transient=False,
    )


def _collect_with_progress(
    behavior: str,
    starts: list[dict[str, float]],
    sim: str,
    seed: int,
    noise: float,
    env: Any = None,
    env_name: str | None = None,
) -> Any:
    """Run the teacher from every start behind a progress bar (one final line when not a TTY)."""
    from behavior_hmm.teach import collect

    with _progress() as bar:
        task = bar.add_task(f"collect {behavior} ({env_name or sim})", total=len(starts))

        def report(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        return collect(
            behavior,
            starts,
            sim=sim,
            seed=seed,
            noise=noise,
            progress=report,
            env=env,
            env_name=env_name,
        )


@app.command()
@_user_errors
def collect(
    behavior: Annotated[
        str, typer.Argument(help="turn, approach, retreat, turn-approach or position")
    ],
    out: Annotated[Path, typer.Option("-o", "--out", help="Output Parquet file")],
    starts: Annotated[
        Path | None,
        typer.Option(help="CSV of starts (columns angle and/or distance); default: DESIGN §6 grid"),
    ] = None,
    sim: Annotated[str, typer.Option(help="Simulator backend: mujoco or kinematic")] = "mujoco",
    seed: Annotated[
        int, typer.Option(help="Seed (>= 0); episode i draws its sensor noise with SEED+i")
    ] = 0,
    noise: Annotated[
        float, typer.Option(help="Sensor noise: sigma x each channel's normalization range")
    ] = 0.0,
    env: EnvOption = None,
    env_kwargs: EnvKwargsOption = None,
) -> None:
    """Record s-curve demonstrations of a behavior into a Parquet dataset.

    Everything is checked before the first episode runs; on any error nothing is
    written and an existing OUT is left as it was.
    """
    import math

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

    behavior_spec(behavior)  # an unknown behavior is refused first
    check_sim(sim)
    if not math.isfinite(noise) or noise < 0:
        raise ConfigError(f"--noise must be a finite number >= 0, got {noise}")
    if noise > max_noise():
        raise ConfigError(
            f"--noise {noise:g} is too large: at most {max_noise():.3g}, beyond which the "
            "noisy readings leave the plausible range every dataset is checked against"
        )
    if seed < 0:
        raise ConfigError(f"--seed must be >= 0, got {seed}")
    check_outputs({"--starts": starts}, {"-o": out})
    robot, robot_name = open_env(sim, env, env_kwargs) if env is not None else (None, None)
    far = math.inf if robot is not None else None
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
    try:
        dataset = _collect_with_progress(behavior, chosen, sim, seed, noise, robot, robot_name)
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


@app.command()
@_user_errors
def inspect(
    dataset_file: Annotated[Path, typer.Argument(help="A dataset (Parquet) or a model (.bhmm)")],
    plot: Annotated[
        Path | None,
        typer.Option(help="Plot of the demonstrations, .png, .svg, .pdf, ... (default: DATA.png)"),
    ] = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the summary as JSON")
    ] = None,
) -> None:
    """Summarize a dataset and plot it, or show a model's preset and effective parameters.

    For a dataset: episodes, durations, channel ranges, and a PNG of the demonstrations
    as time-vs-angle and time-vs-distance curves (thesis figures 6.8-6.10). For a model:
    its kind, behavior, inputs, sizes, the preset its parameters follow and every
    parameter. Example: behavior-hmm inspect models/turn.bhmm
    """
    import zipfile

    from behavior_hmm import data
    from behavior_hmm._atomic import all_or_none, atomic_write_bytes
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.viz import plot_demonstrations

    if dataset_file.suffix.lower() in (".csv", ".tsv", ".txt"):
        raise ConfigError(
            f"{dataset_file}: inspect reads Parquet datasets; "
            "convert a CSV log first with 'behavior-hmm import-csv'"
        )
    is_model = dataset_file.is_file() and zipfile.is_zipfile(dataset_file)
    if is_model and plot is not None:
        raise ConfigError(f"--plot draws datasets; {dataset_file} is a model file")
    png = None if is_model else (plot if plot is not None else dataset_file.with_suffix(".png"))
    check_outputs({"DATA": dataset_file}, {"--plot": png, "--json": json_out}, plots=("--plot",))
    with all_or_none():  # the plot and the JSON, or neither
        if is_model:
            summary = _model_summary(dataset_file)
            _print_model_summary(dataset_file, summary)
        else:
            dataset = data.read(dataset_file)
            summary = data.summarize(dataset)
            _print_summary(dataset_file, summary)
            assert png is not None
            plot_demonstrations(dataset, png)
        if json_out is not None:
            text = json.dumps(summary, indent=2, default=str) + "\n"
            try:
                atomic_write_bytes(json_out, text.encode())
            except OSError as exc:
                raise ConfigError(
                    f"{json_out}: cannot write JSON ({exc.strerror or exc})"
                ) from None
    if png is not None:
        typer.echo(f"plot: {png}")
    if json_out is not None:
        typer.echo(f"summary: {json_out}")


def _model_summary(path: Path) -> dict[str, Any]:
    """What ``inspect`` shows of a model: kind, behavior, sizes, preset, parameters."""
    from behavior_hmm._cli_learn import load_model
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
    if model.kind == "SBLM":
        summary["primitives"] = int(model.primitives_.n_categories_)
    else:
        summary["components"] = list(model.names_)
    return summary


def _print_model_summary(path: Path, summary: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console(highlight=False)
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
    table = Table(title="parameters")
    table.add_column("parameter")
    table.add_column("value")
    for name, value in summary["params"].items():
        table.add_row(name, repr(value))
    console.print(table)


def _print_summary(path: Path, summary: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    # File names and metadata are the user's text: never read them as rich markup.
    console = Console(highlight=False)
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


@app.command()
@_user_errors
def bench(
    name: Annotated[
        str,
        typer.Argument(
            help="Benchmark: sim, cobart, step, train or hmm (hmm needs the bench extra: hmmlearn)"
        ),
    ],
    json_out: Annotated[Path | None, typer.Option("--json", help="Write results as JSON")] = None,
    quick: Annotated[bool, typer.Option("--quick", help="Fewer repeats (a smoke run)")] = False,
) -> None:
    """Run a benchmark from benchmarks/ and print its results (medians) as JSON."""
    from behavior_hmm._atomic import atomic_write_bytes
    from behavior_hmm._paths import check_outputs
    from benchmarks import run_benchmark

    check_outputs({}, {"--json": json_out})
    results = run_benchmark(name, quick=quick)
    text = json.dumps(results, indent=2, sort_keys=True)
    typer.echo(text)
    if json_out is not None:
        try:
            atomic_write_bytes(json_out, (text + "\n").encode())
        except OSError as exc:
            raise ConfigError(f"{json_out}: cannot write JSON ({exc.strerror or exc})") from None


@app.command()
@_user_errors
def demo(
    out: Annotated[Path, typer.Option("-o", "--out", help="Folder for datasets and plots")] = Path(
        "demo-output"
    ),
    sim: Annotated[str, typer.Option(help="Simulator backend: mujoco or kinematic")] = "mujoco",
    seed: Annotated[int, typer.Option(help="Seed (>= 0)")] = 0,
) -> None:
    """Run the whole pipeline on the default simulator and report.

    Collects the default turn, approach and turn & approach demonstrations, learns turn
    {angle} and approach {distance, angle} (SBLM), composes them into turn & approach
    (CBLM, components untouched), scores each on its 15 test starts against the teacher
    (with the all-zero floor beside it), and writes the data's plots, an HTML report per
    behavior (every run plotted), and one run of each as a plot and a top-down video
    (GIF; Pillow comes with matplotlib).
    Example: behavior-hmm demo --sim kinematic -o demo-output
    """
    import time

    from behavior_hmm import data
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.evaluate import evaluate_model
    from behavior_hmm.models import CBLM, SBLM
    from behavior_hmm.sim import make_env
    from behavior_hmm.teach import default_starts, test_starts
    from behavior_hmm.viz import (
        plot_demonstrations,
        plot_trace,
        render_trace,
        write_evaluation_report,
    )

    check_sim(sim)
    if seed < 0:
        raise ConfigError(f"--seed must be >= 0, got {seed}")
    check_outputs({}, {}, folders={"-o": out})
    out.mkdir(parents=True, exist_ok=True)
    datasets = {}
    for behavior in ("turn", "approach", "turn-approach"):
        dataset = _collect_with_progress(behavior, default_starts(behavior), sim, seed, 0.0)
        data.write(dataset, out / f"{behavior}.parquet")
        plot_demonstrations(dataset, out / f"{behavior}_demonstrations.png")
        datasets[behavior] = dataset
    t0 = time.perf_counter()
    turn = SBLM(inputs=("angle",), random_state=seed).fit(datasets["turn"])
    approach = SBLM(inputs=("distance", "angle"), random_state=seed).fit(datasets["approach"])
    both = CBLM([turn, approach], inputs=("distance", "angle")).fit(datasets["turn-approach"])
    typer.echo(f"trained turn, approach and turn & approach in {time.perf_counter() - t0:.1f} s")
    models: dict[str, Any] = {"turn": turn, "approach": approach, "turn-approach": both}
    thesis = {"turn": 90.9, "approach": 82.6, "turn-approach": 79.8}
    env = make_env(sim)
    rows = []
    videos: list[Path] = []
    for behavior, model in models.items():
        model.save(out / f"{behavior}.bhmm")
        starts = test_starts(behavior)
        with _progress() as bar:
            task = bar.add_task(f"evaluate {behavior} ({sim})", total=len(starts))

            def report(done: int, total: int, task: Any = task, bar: Any = bar) -> None:
                bar.update(task, completed=done)

            result = evaluate_model(
                model, starts, sim=sim, seed=seed, progress=report, keep_traces=True
            )
        write_evaluation_report(result, result.pop("_traces"), out / f"{behavior}_report.html")
        # the run shown: the middle test start, one that needs a turn for turn & approach
        turning = [s for s in starts if abs(s.get("angle", 0.0)) > 30.0] or starts
        first = turning[len(turning) // 2]
        trace = model.generate(env, start=_full_start(behavior, first), seed=seed)
        plot_trace(trace, out / f"{behavior}_run.png")
        where = ", ".join(f"{k} {v:g}" for k, v in trace.start.items())
        render_trace(
            trace, out / f"{behavior}_run.gif", robot=env, title=f"{behavior} from {where}"
        )
        videos.append(out / f"{behavior}_run.gif")
        rows.append(
            (
                behavior,
                ",".join(model.inputs_),
                f"{result['success_rate_mean']:.1f}",
                f"{thesis[behavior]:.1f}",
                f"{result['zero_floor_mean']:.1f}",
                f"{result['goal_reached']}/{result['n']}",
            )
        )
    from rich import box
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    table = Table(
        title=f"behavior-hmm demo ({sim}, default preset)", box=box.SIMPLE_HEAD, show_edge=False
    )
    for col in ("behavior", "inputs", "success %", "thesis's own %", "zero floor %", "goals"):
        table.add_column(col, no_wrap=True)
    for row in rows:
        table.add_row(*[Text(str(x)) for x in row])  # plain text, not rich markup
    Console().print(table)
    typer.echo(f"videos: {', '.join(str(v) for v in videos)}")
    typer.echo(f"reports: {out}/<behavior>_report.html; datasets, models and plots: {out}")


def _full_start(behavior: str, start: dict[str, float]) -> dict[str, float]:
    from behavior_hmm.teach import complete_start

    return {k: v for k, v in complete_start(behavior, start).items() if not k.startswith("goal")}


def _register_learning_commands() -> None:
    from behavior_hmm import _cli_data
    from behavior_hmm._cli_learn import register

    register(app, _user_errors, _progress)
    _cli_data.register(app, _user_errors)


_register_learning_commands()


def _terminated(signum: int, frame: Any) -> None:
    """SIGTERM: stop like Ctrl-C, so every temporary file is removed on the way out."""
    raise KeyboardInterrupt


def main() -> None:
    """Entry point of the ``behavior-hmm`` console script."""
    import signal

    from behavior_hmm._atomic import remove_leftovers

    signal.signal(signal.SIGTERM, _terminated)
    try:
        app()
    finally:
        remove_leftovers()
