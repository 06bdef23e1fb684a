"""``behavior-hmm demo``: the whole pipeline in one command, the place to start.

Usage::

    behavior-hmm demo                                  # MuJoCo, into demo-output/
    behavior-hmm demo --sim kinematic -o demo-output   # faster, no physics

Collects demonstrations, learns turn and approach, composes turn & approach, learns the
thesis's third behavior, grasp, on the Khepera with a gripper (MuJoCo), scores each against
the teacher and writes datasets, models, plots, reports and videos.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated, Any

import typer

from behavior_hmm.cli._common import (
    CONTEXT_SETTINGS,
    SeedOption,
    SimOption,
    check_sim,
    collect_with_progress,
    log,
    progress,
    spinner,
    user_errors,
)
from behavior_hmm.errors import ConfigError
from behavior_hmm.viz._html import format_values

app = typer.Typer(context_settings=CONTEXT_SETTINGS)

#: The thesis's own success rates (%), shown beside ours.
THESIS_SUCCESS = {"turn": 90.9, "approach": 82.6, "turn-approach": 79.8}


@app.command()
@user_errors
def demo(
    out: Annotated[
        Path, typer.Option("-o", "--out", help="Folder for datasets, models and plots")
    ] = Path("demo-output"),
    sim: SimOption = "mujoco",
    seed: SeedOption = 0,
) -> None:
    """Run the whole pipeline on the default simulator and report.

    Collects the default turn, approach and turn & approach demonstrations, learns turn
    {angle} and approach {distance, angle} (SBLM), composes them into turn & approach
    (CBLM, components untouched), learns grasp {arm, fingers, object_present} on the
    Khepera with a gripper (behavior_hmm/KheperaGripper-v0, MuJoCo whatever --sim says),
    scores each on its 15 test starts against the teacher (with the all-zero floor beside
    it), and writes the data's plots, an HTML report per behavior (every run plotted), and
    one run of each as a plot and, for the wheeled behaviors, a top-down video (GIF; Pillow
    comes with matplotlib).

    Example: behavior-hmm demo --sim kinematic -o demo-output
    """
    from behavior_hmm import data
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.evaluate import evaluate_model
    from behavior_hmm.models import CBLM, SBLM
    from behavior_hmm.sim import make_env
    from behavior_hmm.teach import behavior_spec, default_starts, test_starts
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
        dataset = collect_with_progress(
            behavior,
            default_starts(behavior),
            sim,
            seed,
            0.0,
            corrections=behavior_spec(behavior).corrections,
        )
        data.write(dataset, out / f"{behavior}.parquet")
        plot_demonstrations(dataset, out / f"{behavior}_demonstrations.png")
        datasets[behavior] = dataset
    t0 = time.perf_counter()
    with spinner("train turn, approach and turn & approach"):
        turn = SBLM(inputs=("angle",), random_state=seed).fit(datasets["turn"])
        approach = SBLM(inputs=("distance", "angle"), random_state=seed).fit(datasets["approach"])
        both = CBLM([turn, approach], inputs=("distance", "angle")).fit(datasets["turn-approach"])
    log.info("trained turn, approach and turn & approach in %.1f s", time.perf_counter() - t0)
    models: dict[str, Any] = {"turn": turn, "approach": approach, "turn-approach": both}
    env = make_env(sim)
    rows: list[tuple[str, ...]] = []
    videos: list[Path] = []
    grasp_rows = _grasp(out, seed)
    for behavior, model in models.items():
        model.save(out / f"{behavior}.bhmm")
        starts = test_starts(behavior)
        with progress() as bar:
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
        where = format_values(trace.start)
        render_trace(
            trace, out / f"{behavior}_run.gif", robot=env, title=f"{behavior} from {where}"
        )
        videos.append(out / f"{behavior}_run.gif")
        rows.append(
            (
                behavior,
                ",".join(model.inputs_),
                f"{result['success_rate_mean']:.1f}",
                f"{THESIS_SUCCESS[behavior]:.1f}",
                f"{result['zero_floor_mean']:.1f}",
                f"{result['goal_reached']}/{result['n']}",
            )
        )
    _print_table(rows + grasp_rows, sim)
    log.info("videos: %s", ", ".join(str(v) for v in videos))
    log.info("reports: %s/<behavior>_report.html; datasets, models and plots: %s", out, out)


def _grasp(out: Path, seed: int) -> list[tuple[str, ...]]:
    """Collect, learn and score grasp on the Khepera with a gripper; its table row."""
    from behavior_hmm import data
    from behavior_hmm.evaluate import evaluate_model
    from behavior_hmm.models import SBLM
    from behavior_hmm.runtime import make_robot_env
    from behavior_hmm.sim import GRIPPER_ENV_ID
    from behavior_hmm.teach import default_starts, test_starts
    from behavior_hmm.viz import plot_demonstrations, plot_trace, write_evaluation_report

    dataset = collect_with_progress("grasp", default_starts("grasp"), "mujoco", seed, 0.0)
    data.write(dataset, out / "grasp.parquet")
    plot_demonstrations(dataset, out / "grasp_demonstrations.png")
    inputs = ("arm", "fingers", "object_present")
    with spinner("train grasp"):
        model = SBLM(inputs=inputs, random_state=seed).fit(dataset)
    model.save(out / "grasp.bhmm")
    env = make_robot_env(GRIPPER_ENV_ID)
    starts = test_starts("grasp")
    with progress() as bar:
        task = bar.add_task(f"evaluate grasp ({GRIPPER_ENV_ID})", total=len(starts))

        def report(done: int, total: int) -> None:
            bar.update(task, completed=done)

        result = evaluate_model(
            model, starts, sim=None, env=env, seed=seed, progress=report, keep_traces=True
        )
    write_evaluation_report(result, result.pop("_traces"), out / "grasp_report.html")
    trace = model.generate(env, start=starts[len(starts) // 2], seed=seed)
    plot_trace(trace, out / "grasp_run.png")
    return [
        (
            "grasp (gripper robot)",
            ",".join(inputs),
            f"{result['success_rate_mean']:.1f}",
            "-",
            f"{result['zero_floor_mean']:.1f}",
            f"{result['goal_reached']}/{result['n']}",
        )
    ]


def _print_table(rows: list[tuple[str, ...]], sim: str) -> None:
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
    console = Console()
    # a pipe or a log gets the whole table, not columns cut to 80 characters
    Console(width=max(console.width, 110)).print(table)


def _full_start(behavior: str, start: dict[str, float]) -> dict[str, float]:
    from behavior_hmm.teach import complete_start

    return {k: v for k, v in complete_start(behavior, start).items() if not k.startswith("goal")}
