"""The learning-curve table and figure of ``experiment data-efficiency``."""

from __future__ import annotations

import os
import textwrap
from collections.abc import Mapping, Sequence
from fractions import Fraction
from pathlib import Path
from typing import Any, Final

import numpy as np
from matplotlib.figure import Figure

from behavior_hmm.evaluate._data_efficiency import LEARNERS
from behavior_hmm.viz._reports import write_results_files
from behavior_hmm.viz._traces import _save, new_figure

#: How each learner is named in the table and the figure, and its line style.
LEARNER_LABELS: Final[dict[str, str]] = {"ours": "ours", "bc": "BC", "bc_strong": "BC-strong"}
_STYLES: Final[dict[str, dict[str, Any]]] = {
    "ours": {"color": "tab:blue", "marker": "o"},
    "bc": {"color": "tab:orange", "marker": "s"},
    "bc_strong": {"color": "tab:green", "marker": "^"},
}

#: How each task is named in the table and the figure.
TASK_LABELS: Final[dict[str, str]] = {
    "turn": "turn",
    "approach": "approach",
    "turn-approach": "turn & approach (CBLM)",
}

#: File name of the figure in the output folder.
FIGURE_NAME: Final[str] = "data_efficiency.png"
#: Factor of margin either side of the plotted demonstration counts (log x axis).
_X_MARGIN: Final[float] = 1.35


def fraction_text(fraction: float) -> str:
    """``1/8``, ``1/2``, ``all`` (1), else the number (``0.3``)."""
    if fraction == 1.0:
        return "all"
    exact = Fraction(fraction).limit_denominator(64)
    if abs(float(exact) - fraction) < 1e-9 and exact.numerator == 1:
        return f"1/{exact.denominator}"
    return f"{fraction:g}"


def _rows_of(results: Mapping[str, Any], task: str) -> list[Mapping[str, Any]]:
    return [r for r in results["summary"] if r["behavior"] == task]


def _learners(results: Mapping[str, Any]) -> list[str]:
    rows = results["summary"]
    return [k for k in LEARNERS if rows and all(k in r for r in rows)]


def _cell_text(entry: Mapping[str, Any], seeds: int) -> str:
    success, goals = entry["success"], entry["goals"]
    spread = f" ± {success['sd']:.1f}" if seeds > 1 else ""
    return f"{success['mean']:.1f}{spread} ({goals['mean']:.1f}/{entry['n']})"


def _median_seconds(
    cells: Sequence[Mapping[str, Any]], task: str, fraction: float, learner: str
) -> float | None:
    values = [
        c[learner]
        for c in cells
        if c["behavior"] == task and float(c["fraction"]) == fraction and learner in c
    ]
    return float(np.median(values)) if values else None


#: A cell's command scale this far (relative) from its whole grid's is named in the table.
SCALE_TOLERANCE: Final[float] = 0.01


def _scale_note(results: Mapping[str, Any]) -> str:
    """Which cells were scored on another command scale than the whole grid's."""
    grid = {task: info.get("command_scale") for task, info in results["tasks"].items()}
    cells = [c for c in results["cells"] if grid.get(c["behavior"])]
    if not cells:
        return ""
    ratios = [c["ours"]["command_scale"] / grid[c["behavior"]] for c in cells]
    odd = [
        f"{c['behavior']} {fraction_text(float(c['fraction']))} seed {c['seed']} "
        f"({c['ours']['command_scale']:.2f} of {grid[c['behavior']]:.2f})"
        for c, ratio in zip(cells, ratios, strict=True)
        if abs(ratio - 1.0) > SCALE_TOLERANCE
    ]
    if not odd:
        worst = max(abs(r - 1.0) for r in ratios)
        return (
            "Every cell is scored on its whole grid's command scale (DESIGN §6) to within "
            f"{100 * worst:.2f} %: every subset held a demonstration as fast as the grid's "
            "fastest."
        )
    return (
        f"Scored on a command scale more than {100 * SCALE_TOLERANCE:.0f} % from the whole "
        "grid's (the subset's fastest demonstration is slower or faster; DESIGN §6): "
        + "; ".join(odd)
        + "."
    )


def data_efficiency_markdown(results: Mapping[str, Any]) -> str:
    """One table: per task and fraction, success % (mean ± sd over seeds) and goals."""
    seeds = list(results["seeds"])
    learners = _learners(results)
    cells = (results.get("timings") or {}).get("cells") or []
    preset = results.get("preset", "default")
    spread = " ± sd" if len(seeds) > 1 else ""
    lines = [
        f"Nested subsets of each default grid ({results['sim']}, {preset} preset, seeds "
        f"{seeds[0]}..{seeds[-1]}: each draws its own subsets and trains its own models). "
        f"Success % on the 15 shipped test starts, mean{spread} over the seeds, with the "
        "mean goals reached in brackets; demonstrations: starts of the subset (approach "
        "also trains on each start's corrective copy).",
        "",
    ]
    header = "| task | fraction | demonstrations |"
    rule = "| --- | --- | --- |"
    for learner in learners:
        header += f" {LEARNER_LABELS[learner]} %{spread} (goals) |"
        rule += " --- |"
    header += " all-zero floor % |"
    rule += " --- |"
    if cells:
        header += f" train s, median ({' / '.join(LEARNER_LABELS[k] for k in learners)}) |"
        rule += " --- |"
    lines += [header, rule]
    for task, info in results["tasks"].items():
        for row in _rows_of(results, task):
            fraction = float(row["fraction"])
            text = (
                f"| {TASK_LABELS.get(task, task)} | {fraction_text(fraction)} "
                f"| {row['n_demonstrations']} of {info['grid_size']} |"
            )
            for learner in learners:
                text += f" {_cell_text(row[learner], len(seeds))} |"
            text += f" {row['zero_floor']:.1f} |"
            if cells:
                times = [_median_seconds(cells, task, fraction, k) for k in learners]
                text += " " + " / ".join("—" if t is None else f"{t:.1f}" for t in times) + " |"
            lines.append(text)
    lines.append("")
    thesis = ", ".join(
        f"{TASK_LABELS.get(task, task)} {{{', '.join(info['inputs'])}}} {info['thesis']:.1f} %"
        for task, info in results["tasks"].items()
    )
    lines.append(f"Thesis's own figures (whole grid, Webots, its own data): {thesis}.")
    note = _scale_note(results)
    if note:
        lines += ["", note]
    return "\n".join(lines) + "\n"


def plot_data_efficiency(results: Mapping[str, Any]) -> Figure:
    """One panel per task: success % against demonstrations (log 2), ± sd over seeds.

    Lines for ours, BC and BC-strong (error bars: standard deviation over the seeds),
    the thesis's own figure (dashed) and the all-zero floor (dotted).
    """
    tasks = list(results["tasks"])
    learners = _learners(results)
    seeds = list(results["seeds"])
    fig = new_figure((4.2 * len(tasks) + 0.4, 4.4))
    axes = fig.subplots(1, len(tasks), squeeze=False, sharey=True)[0]
    low = 100.0
    for ax, task in zip(axes, tasks, strict=True):
        rows = _rows_of(results, task)
        info = results["tasks"][task]
        x = np.array([float(r["n_demonstrations"]) for r in rows])
        shift = {k: 1.0 + 0.03 * (i - (len(learners) - 1) / 2) for i, k in enumerate(learners)}
        for learner in learners:
            mean = np.array([r[learner]["success"]["mean"] for r in rows])
            sd = np.array([r[learner]["success"]["sd"] for r in rows])
            low = min(low, float(np.min(mean - sd)))
            ax.errorbar(
                x * shift[learner],  # side by side, so the bars do not hide each other
                mean,
                yerr=sd,
                capsize=3,
                linewidth=1.4,
                markersize=5,
                label=LEARNER_LABELS[learner],
                **_STYLES[learner],
            )
        floor = np.array([r["zero_floor"] for r in rows])
        floor_x, floor_y = x, floor
        if x.size == 1:  # one fraction: across the plotted range, not a zero-length line
            floor_x, floor_y = x[0] * np.array([1.0 / _X_MARGIN, _X_MARGIN]), np.repeat(floor, 2)
        ax.plot(floor_x, floor_y, ":", color="grey", linewidth=1.2, label="all-zero floor")
        low = min(low, float(np.min(floor)))
        if info.get("thesis") is not None:
            thesis = float(info["thesis"])
            ax.axhline(
                thesis,
                linestyle="--",
                color="black",
                linewidth=1.0,
                label="thesis's own figure (whole grid)",
            )
        ax.set_xscale("log", base=2)
        ticks: dict[int, list[str]] = {}  # two fractions of a small grid may share a size
        for n, r in zip(x, rows, strict=True):
            ticks.setdefault(int(n), []).append(fraction_text(float(r["fraction"])))
        ax.set_xticks(list(ticks))
        ax.set_xticklabels([f"{n}\n({', '.join(f)})" for n, f in ticks.items()], fontsize=8)
        ax.minorticks_off()
        ax.set_xlim(x.min() / _X_MARGIN, x.max() * _X_MARGIN)
        ax.set_xlabel(f"demonstrations (of {info['grid_size']} grid starts)")
        title = f"{TASK_LABELS.get(task, task)} {{{', '.join(info['inputs'])}}}"
        if info.get("thesis") is not None:
            title += f"; thesis {float(info['thesis']):.1f} %"
        ax.set_title(title, fontsize=10)
        ax.grid(True, alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    first = [LEARNER_LABELS[k] for k in learners]  # the learners, then the reference lines
    order = sorted(range(len(labels)), key=lambda i: (labels[i] not in first, i))
    handles, labels = [handles[i] for i in order], [labels[i] for i in order]
    fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=8)
    axes[0].set_ylabel("success % on 15 test starts")
    axes[0].set_ylim(max(0.0, np.floor(low / 10.0) * 10.0 - 5.0), 101.0)
    preset = results.get("preset", "default")
    spread = f"mean ± sd over {len(seeds)} seeds" if len(seeds) > 1 else f"seed {seeds[0]}"
    title = (
        f"Data efficiency: nested subsets of each grid ({results['sim']}, {preset} preset, "
        f"{spread})"
    )
    # a preset with several parameters set is long: wrapped, not cut at the figure's edges
    fig.suptitle(textwrap.fill(title, width=40 * len(axes)), fontsize=10)
    return fig


def write_data_efficiency_report(results: dict[str, Any], out: str | os.PathLike[str]) -> str:
    """Write ``results.json``, ``timings.json``, ``table.md`` and the figure; the table.

    Parameters
    ----------
    results
        :func:`run_data_efficiency_experiment`'s result (with ``preset`` when known).
    out
        Output folder (created).
    """
    table = data_efficiency_markdown(results)
    folder = write_results_files(out, results, table)
    _save(plot_data_efficiency(results), Path(folder) / FIGURE_NAME)
    return table
