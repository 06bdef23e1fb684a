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

from behavior_hmm.errors import BehaviorHMMError, ConfigError

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Learn robot behaviors from unlabeled demonstrations (CobART + Behavior-HMM).",
    pretty_exceptions_enable=False,
)

F = TypeVar("F", bound=Callable[..., Any])

SIMS = ("mujoco", "kinematic")


def _user_errors(func: F) -> F:
    """Turn our errors into one line on stderr and exit code 2 (no traceback)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except BehaviorHMMError as err:
            typer.echo(f"error: {err}", err=True)
            raise typer.Exit(code=2) from None
        except KeyboardInterrupt:
            typer.echo("interrupted", err=True)
            raise typer.Exit(code=130) from None

    return wrapper  # type: ignore[return-value]


def _check_sim(sim: str) -> str:
    if sim not in SIMS:
        raise ConfigError(f"unknown simulator '{sim}'; choose one of {', '.join(SIMS)}")
    return sim


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
    starts: list[dict[str, float]] | None,
    sim: str,
    seed: int,
    noise: float,
) -> Any:
    from behavior_hmm.teach import collect

    with _progress() as bar:
        task = bar.add_task(f"collect {behavior} ({sim})", total=None)

        def report(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        return collect(behavior, starts, sim=sim, seed=seed, noise=noise, progress=report)


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
    seed: Annotated[int, typer.Option(help="Seed of the sensor-noise draws")] = 0,
    noise: Annotated[
        float, typer.Option(help="Sensor noise: sigma x each channel's normalization range")
    ] = 0.0,
) -> None:
    """Record s-curve demonstrations of a behavior into a Parquet dataset."""
    from behavior_hmm import data
    from behavior_hmm.teach import BEHAVIORS, read_starts

    if behavior not in BEHAVIORS:
        raise ConfigError(f"unknown behavior '{behavior}'; choose one of {', '.join(BEHAVIORS)}")
    _check_sim(sim)
    chosen = read_starts(starts) if starts is not None else None
    dataset = _collect_with_progress(behavior, chosen, sim, seed, noise)
    data.write(dataset, out)
    typer.echo(f"wrote {out}: {len(dataset)} episodes, {dataset.n_samples} rows")


@app.command("import-csv")
@_user_errors
def import_csv(
    csv_file: Annotated[Path, typer.Argument(help="Your CSV log")],
    out: Annotated[Path, typer.Option("-o", "--out", help="Output Parquet file")],
    map_: Annotated[
        list[str] | None,
        typer.Option("--map", help="OURS=THEIRS column mapping, e.g. angle=heading (repeatable)"),
    ] = None,
    unit: Annotated[
        list[str] | None,
        typer.Option(help="CHANNEL=UNIT of your columns, e.g. angle=rad, distance=mm (repeatable)"),
    ] = None,
    behavior: Annotated[str | None, typer.Option(help="Behavior name stored in metadata")] = None,
) -> None:
    """Convert a CSV log into a validated dataset."""
    from behavior_hmm import data

    mapping = _pairs(map_ or [], "--map")
    units = _pairs(unit or [], "--unit")
    metadata: dict[str, Any] = {"source": str(csv_file)}
    if behavior is not None:
        metadata["behavior"] = behavior
    dataset = data.import_csv(csv_file, mapping=mapping, units=units, metadata=metadata)
    data.write(dataset, out)
    typer.echo(f"wrote {out}: {len(dataset)} episodes, {dataset.n_samples} rows")


@app.command()
@_user_errors
def inspect(
    dataset_file: Annotated[Path, typer.Argument(help="A dataset (Parquet)")],
    plot: Annotated[
        Path | None, typer.Option(help="PNG of the demonstrations (default: DATA.png)")
    ] = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the summary as JSON")
    ] = None,
) -> None:
    """Summarize a dataset and plot its demonstrations."""
    from behavior_hmm import data
    from behavior_hmm.viz import plot_demonstrations

    dataset = data.read(dataset_file)
    summary = data.summarize(dataset)
    _print_summary(dataset_file, summary)
    png = plot if plot is not None else dataset_file.with_suffix(".png")
    plot_demonstrations(dataset, png)
    typer.echo(f"plot: {png}")
    if json_out is not None:
        from behavior_hmm._atomic import atomic_write_bytes

        atomic_write_bytes(json_out, json.dumps(summary, indent=2, default=str).encode())


def _print_summary(path: Path, summary: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    console.print(f"[bold]{path}[/bold]")
    meta = summary.get("metadata", {})
    for key in ("behavior", "simulator", "seed", "noise"):
        if key in meta:
            console.print(f"  {key}: {meta[key]}")
    console.print(f"  episodes: {summary['episodes']}, samples: {summary['samples']}")
    for key in ("samples_per_episode", "duration_s"):
        stats = summary.get(key, {})
        console.print(f"  {key}: " + ", ".join(f"{k} {_fmt(v)}" for k, v in stats.items()))
    if summary.get("behaviors"):
        console.print(f"  behaviors: {', '.join(summary['behaviors'])}")
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
    name: Annotated[str, typer.Argument(help="Benchmark name, e.g. sim or cobart")],
    json_out: Annotated[Path | None, typer.Option("--json", help="Write results as JSON")] = None,
    quick: Annotated[bool, typer.Option(help="Fewer repeats (a smoke run)")] = False,
) -> None:
    """Run a benchmark from benchmarks/ and report medians."""
    from benchmarks import run_benchmark

    results = run_benchmark(name, quick=quick)
    text = json.dumps(results, indent=2, sort_keys=True)
    typer.echo(text)
    if json_out is not None:
        from behavior_hmm._atomic import atomic_write_bytes

        atomic_write_bytes(json_out, (text + "\n").encode())


@app.command()
@_user_errors
def demo(
    out: Annotated[Path, typer.Option("-o", "--out", help="Folder for datasets and plots")] = Path(
        "demo-output"
    ),
    sim: Annotated[str, typer.Option(help="Simulator backend: mujoco or kinematic")] = "mujoco",
    seed: Annotated[int, typer.Option(help="Seed")] = 0,
) -> None:
    """Run the whole pipeline on the default simulator and report."""
    from behavior_hmm import data
    from behavior_hmm.viz import plot_demonstrations

    _check_sim(sim)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for behavior in ("turn", "approach", "turn-approach"):
        dataset = _collect_with_progress(behavior, None, sim, seed, 0.0)
        path = out / f"{behavior}.parquet"
        data.write(dataset, path)
        png = out / f"{behavior}.png"
        plot_demonstrations(dataset, png)
        rows.append((behavior, len(dataset), dataset.n_samples, str(path), str(png)))
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"behavior-hmm demo ({sim})")
    for col in ("behavior", "episodes", "rows", "dataset", "plot"):
        table.add_column(col)
    for row in rows:
        table.add_row(*[str(x) for x in row])
    Console().print(table)


def _pairs(items: list[str], option: str) -> dict[str, str]:
    pairs: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise ConfigError(f"{option} expects KEY=VALUE, got '{item}'")
        pairs[key.strip()] = value.strip()
    return pairs


def main() -> None:
    """Entry point of the ``behavior-hmm`` console script."""
    app()
