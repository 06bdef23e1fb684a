"""The table and figure of ``experiment parallel`` (thesis §7.2: parallel behaviors)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any, Final

import numpy as np
from matplotlib.figure import Figure

from behavior_hmm.viz._reports import write_results_files
from behavior_hmm.viz._traces import _save, new_figure

#: File name of the figure in the output folder.
FIGURE_NAME: Final[str] = "parallel.png"

#: Starts whose paths the figure draws (indices into turn & approach's 15 test starts).
PATH_STARTS: Final[tuple[int, ...]] = (0, 3, 10, 13)

_COLOURS: Final[dict[str, str]] = {
    "sequential": "tab:orange",
    "parallel": "tab:blue",
    "one_at_a_time": "tab:grey",
}


def _spread(results: Mapping[str, Any], key: str, field: str, digits: int = 1) -> str:
    entry = results["over_seeds"][key][field]
    if len(results["seeds"]) == 1:
        return f"{entry['mean']:.{0 if field == 'goal_reached' else digits}f}"
    return f"{entry['mean']:.{digits}f} ± {entry['ci95']:.{digits}f}"


def parallel_markdown(results: Mapping[str, Any]) -> str:
    """The comparison table: every row's score, goals, time and path, and the teachers'."""
    seeds = results["seeds"]
    rows = results["rows"]
    n = rows["sequential"]["n"]
    lines = [
        f"Turn & approach's {n} test starts ({results['sim']}, {results.get('preset', 'default')} "
        f"preset; seeds {seeds[0]}..{seeds[-1]}: success, goals, median time and its ratio "
        "as mean ± 95 % interval over the seeds; the other columns: the first seed).",
        "",
        "| run | success % | goals | zero floor % | time to goal, median s | total s "
        "| time ÷ sequential run's (median over starts) | path, median m |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for key, label in results["labels"].items():
        row = rows[key]
        lines.append(
            f"| {label} | {_spread(results, key, 'success_rate_mean')} "
            f"| {_spread(results, key, 'goal_reached')} of {row['n']} "
            f"| {row['zero_floor_mean']:.1f} | {_spread(results, key, 'time_median_s', 2)} "
            f"| {row['time_total_s']:.1f} | {_spread(results, key, 'time_ratio_median', 3)} "
            f"| {row['path_median_m']:.3f} |"
        )
    for key, label in (("sequential", "sequential teacher"), ("parallel", "parallel teacher")):
        row = rows[key]
        ratio = np.median(
            [
                c["teacher_time_s"] / s["teacher_time_s"]
                for c, s in zip(row["cases"], rows["sequential"]["cases"], strict=True)
            ]
        )
        lines.append(
            f"| {label} | — | {n} of {n} | — | {row['teacher_time_median_s']:.2f} "
            f"| {row['teacher_time_total_s']:.1f} | {ratio:.3f} (÷ sequential teacher's) | — |"
        )
    sequential = rows["sequential"]["cases"]
    if all("teacher_turn_s" in c for c in sequential):
        # the sequential teacher with its whole turn beside its approach: the most running
        # the two at once could save with these components' speeds
        bound = np.median(
            [
                max(c["teacher_turn_s"], c["teacher_time_s"] - c["teacher_turn_s"])
                / c["teacher_time_s"]
                for c in sequential
            ]
        )
        lines.append(
            "| bound: the sequential teacher with its whole turn beside its approach | — | — "
            f"| — | — | — | {bound:.3f} (÷ sequential teacher's) | — |"
        )
    lines += [
        "",
        f"The parallel model runs approach beside turn in {results['parallel_categories']} of "
        f"its {results['observation_categories']} observation categories; its components' "
        f"command directions (left, right): turn {results['directions'][0]}, approach "
        f"{results['directions'][1]}.",
    ]
    return "\n".join(lines)


def plot_parallel(results: Mapping[str, Any]) -> Figure:
    """Time to goal per start (the runs and the parallel teacher), and four starts' paths."""
    rows = results["rows"]
    fig = new_figure((11.0, 4.6))
    left, right = fig.subplots(1, 2, width_ratios=[1.5, 1.0])
    cases = rows["sequential"]["cases"]
    x = np.arange(len(cases))
    width = 0.27
    for i, (key, label) in enumerate(results["labels"].items()):
        times = [c["time_s"] for c in rows[key]["cases"]]
        left.bar(x + (i - 1) * width, times, width, color=_COLOURS[key], label=label)
    teacher = [c["teacher_time_s"] for c in rows["parallel"]["cases"]]
    left.plot(x, teacher, "k_", markersize=12, mew=2, label="parallel teacher")
    left.set_xticks(
        x,
        [f"{c['start']['angle']:.0f}°\n{c['start']['distance']:.2f}" for c in cases],
        fontsize=7,
    )
    left.set_ylabel("time to goal (s)")
    left.set_xlabel("start (bearing, distance m)")
    left.legend(fontsize=7, loc="upper right")
    left.set_title("time to goal from each test start", fontsize=9)
    for j in PATH_STARTS:
        if j >= len(cases):
            continue
        for key in ("sequential", "parallel"):
            xy = np.asarray(rows[key]["cases"][j]["xy"])
            right.plot(xy[:, 0], xy[:, 1], color=_COLOURS[key], lw=1.2)
            right.plot(xy[0, 0], xy[0, 1], "o", color="k", ms=3)
    right.plot([], [], color=_COLOURS["sequential"], label="sequential: turn, then approach")
    right.plot([], [], color=_COLOURS["parallel"], label="parallel: turn while approaching")
    right.set_xlabel("x (m)")
    right.set_ylabel("y (m, scale enlarged)")
    right.legend(fontsize=7, loc="best")
    right.set_title("paths from four starts (dots: starts)", fontsize=9)
    return fig


def write_parallel_report(results: Mapping[str, Any], out: str | os.PathLike[str]) -> str:
    """Write ``results.json``, ``timings.json``, ``table.md`` and the figure; return the table."""
    table = parallel_markdown(results)
    folder = write_results_files(out, results, table + "\n")
    _save(plot_parallel(results), folder / FIGURE_NAME, dpi=110)
    return table
