"""The R-matrix heat map and markdown tables of ``experiment incremental`` (issue 29)."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Final

import numpy as np
from matplotlib.figure import Figure

from behavior_hmm.evaluate._incremental import (
    SCHEMES,
    TARGET_BWT,
    TARGET_NEW_TASK_GAP,
    TARGET_TIME_SHARE,
    check_targets,
    matrix,
)
from behavior_hmm.viz._reports import write_results_files
from behavior_hmm.viz._traces import _save

#: How each scheme is named in the tables and the figure.
SCHEME_LABELS: Final[dict[str, str]] = {
    "incremental": "incremental (SBLMs + growing CBLM)",
    "full_refit": "full refit every stage (thesis)",
    "bc_strong_finetuned": "BC-strong fine-tuned stage by stage",
}

#: File name of the heat map in the output folder.
FIGURE_NAME: Final[str] = "incremental_R.png"

#: Heat maps label every cell with its score up to this many tasks.
ANNOTATE_UP_TO: Final[int] = 10


def plot_r_matrices(
    panels: Sequence[tuple[str, Any, Any, Sequence[int]]],
    tasks: Sequence[str],
    title: str,
    label: str = "success rate %",
) -> Figure:
    """Heat maps of ``R[k, i]`` (task i after stage k), one panel per scheme.

    ``panels``: ``(title, R, goals, n)`` per scheme (``R`` and ``goals`` as in
    results.json, ``None`` above the diagonal; ``n`` the test starts per task). Up to
    :data:`ANNOTATE_UP_TO` tasks every cell is labelled with its score and goals reached;
    cells of tasks not yet learned are blank. One colour scale (%) is shared.
    """
    n = len(tasks)
    mats = [matrix(r) for _, r, _, _ in panels]
    finite = np.concatenate([m[np.isfinite(m)] for m in mats])
    low = float(np.floor(min(finite.min(), 50.0) / 10.0) * 10.0)
    side = min(max(3.2, 0.75 * n + 1.2), 7.0)
    fig = Figure(figsize=(side * len(panels) + 1.0, side + 0.6), layout="constrained")
    axes = fig.subplots(1, len(panels), squeeze=False)[0]
    image = None
    small = 8 if n <= ANNOTATE_UP_TO else 6
    for ax, (name, _, goals, counts), m in zip(axes, panels, mats, strict=True):
        image = ax.imshow(
            np.ma.masked_invalid(m), cmap="viridis", vmin=low, vmax=100.0, aspect="equal"
        )
        for k in range(n if n <= ANNOTATE_UP_TO else 0):
            for i in range(k + 1):
                value = m[k, i]
                colour = "black" if value > low + 0.6 * (100.0 - low) else "white"
                ax.text(
                    i,
                    k,
                    f"{value:.1f}\n{goals[k][i]}/{counts[i]}",
                    ha="center",
                    va="center",
                    fontsize=7,
                    color=colour,
                )
        ax.set_xticks(range(n), tasks, rotation=35 if n <= ANNOTATE_UP_TO else 90, fontsize=small)
        for tick in ax.get_xticklabels():
            tick.set_horizontalalignment("right" if n <= ANNOTATE_UP_TO else "center")
        ax.set_yticks(range(n), [f"{k + 1}: {t}" for k, t in enumerate(tasks)], fontsize=small)
        ax.set_xlabel("task i (scored on its test starts)")
        ax.set_ylabel("after stage k (task learned)")
        ax.set_title(name, fontsize=9)
    if image is not None:
        fig.colorbar(image, ax=list(axes), shrink=0.8, label=label)
    fig.suptitle(title, fontsize=10)
    return fig


def scheme_panels(
    results: Mapping[str, Any], labels: Mapping[str, str]
) -> list[tuple[str, Any, Any, Sequence[int]]]:
    """:func:`plot_r_matrices`' panels: each scheme of ``labels`` (in their order) that
    ``results`` holds, titled with its label, ACC and BWT."""
    panels = []
    for scheme, label in labels.items():
        entry = results["schemes"].get(scheme)
        if entry is None:
            continue
        m = entry["metrics"]
        name = f"{label}\nACC {m['acc']:.1f} %, BWT {m['bwt']:+.2f}"
        panels.append((name, entry["R"], entry["goals"], entry["n"]))
    return panels


def plot_incremental(results: Mapping[str, Any]) -> Figure:
    """Heat maps of ``R[k, i]`` (success %, task i after stage k), one panel per scheme."""
    preset = results.get("preset", "default")
    return plot_r_matrices(
        scheme_panels(results, {s: SCHEME_LABELS[s] for s in SCHEMES}),
        list(results["sequence"]),
        f"Incremental learning: R[k, i] ({results['sim']}, {preset} preset, seed "
        f"{results['seed']})",
    )


def _fmt(value: float | None, spec: str = ".1f", sign: bool = False) -> str:
    if value is None:
        return "—"
    return format(value, ("+" if sign else "") + spec)


def incremental_markdown(results: Mapping[str, Any]) -> str:
    """The R matrices, the summary metrics, per-stage times and the issue's targets."""
    schemes = [s for s in SCHEMES if s in results["schemes"]]
    tasks = list(results["sequence"])
    timings = results.get("timings") or {}
    preset = results.get("preset", "default")
    lines = [
        f"Sequence: {' → '.join(tasks)} ({results['sim']}, {preset} preset, seed "
        f"{results['seed']}). R[k, i]: success % of task i after stage k on its "
        "shipped test starts (goals reached / starts).",
        "",
    ]
    for scheme in schemes:
        entry = results["schemes"][scheme]
        lines += [f"**R, {SCHEME_LABELS[scheme]}**", ""]
        lines.append("| after stage | " + " | ".join(tasks) + " |")
        lines.append("| --- |" + " --- |" * len(tasks))
        for k, task in enumerate(tasks):
            cells = []
            for i in range(len(tasks)):
                value = entry["R"][k][i]
                if value is None:
                    cells.append("")
                else:
                    text = f"{value:.1f} ({entry['goals'][k][i]}/{entry['n'][i]})"
                    cells.append(f"**{text}**" if i == k else text)
            lines.append(f"| {k + 1}: {task} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += [
        "| scheme | ACC % | BWT (points) | forgetting (points) | FWT (points) "
        "| worst drop (points) | train s, total | train s per stage (median) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for scheme in schemes:
        m = results["schemes"][scheme]["metrics"]
        seconds = timings.get(f"{scheme}_s")
        total = _fmt(float(np.sum(seconds))) if seconds else "—"
        median = _fmt(float(np.median(seconds)), ".2f") if seconds else "—"
        lines.append(
            f"| {SCHEME_LABELS[scheme]} | {m['acc']:.1f} | {m['bwt']:+.2f} "
            f"| {m['forgetting']:.2f} | {_fmt(m['fwt'], '.2f', sign=True)} "
            f"| {m['worst_drop']:+.2f} | {total} | {median} |"
        )
    lines.append("")
    inc = results["schemes"]["incremental"]
    refit = results["schemes"]["full_refit"]
    header = (
        "| stage | task | incremental: what | new task % (incremental / refit) | inc s | refit s"
    )
    rule = "| --- | --- | --- | --- | --- | ---"
    has_bc = "bc_strong_finetuned" in results["schemes"]
    if has_bc:
        header += " | BC-strong new task % | BC s"
        rule += " | --- | ---"
    lines += [header + " |", rule + " |"]
    for k, task in enumerate(tasks):
        row = (
            f"| {k + 1} | {task} | {inc['how'][k]} | {inc['R'][k][k]:.1f} / "
            f"{refit['R'][k][k]:.1f} | {_seconds(timings, 'incremental', k)} "
            f"| {_seconds(timings, 'full_refit', k)}"
        )
        if has_bc:
            bc = results["schemes"]["bc_strong_finetuned"]
            row += f" | {bc['R'][k][k]:.1f} | {_seconds(timings, 'bc_strong_finetuned', k)}"
        lines.append(row + " |")
    lines.append("")
    lines.append(
        "FWT references (trained alone, %): "
        + "; ".join(
            f"{s.replace('_', ' ')} "
            + ", ".join(f"{v:.1f}" for v in results["schemes"][s]["reference"])
            for s in schemes
        )
        + "."
    )
    lines.append("")
    targets = check_targets(results)
    gaps = targets["new_task_gap"]
    lines += [
        "| issue 29 target | measured | met |",
        "| --- | --- | --- |",
        f"| BWT ≥ {TARGET_BWT:+.1f} points | {targets['bwt']:+.2f} (worst task "
        f"{targets['worst_drop']:+.2f}) | {_yes(targets['bwt_met'])} |",
        f"| each new task within {TARGET_NEW_TASK_GAP:.0f} point of a full refit | gaps "
        + ", ".join(f"{g:+.1f}" for g in gaps)
        + f" | {_yes(targets['new_task_met'])} |",
    ]
    if targets["time_share"] is not None:
        medians = targets["median_s"]
        lines.append(
            f"| training time ≤ {TARGET_TIME_SHARE:.2f} × full refit's | "
            f"{targets['time_share']:.2f} × (summed; per stage "
            + ", ".join(f"{v:.2f}" for v in targets["time_share_per_stage"])
            + f"; medians {medians['incremental']:.1f} s vs {medians['full_refit']:.1f} s) "
            f"| {_yes(targets['time_met'])} |"
        )
    return "\n".join(lines) + "\n"


def _seconds(timings: Mapping[str, Any], scheme: str, k: int) -> str:
    values = timings.get(f"{scheme}_s")
    return "—" if not values else f"{values[k]:.1f}"


def _yes(flag: bool | None) -> str:
    return "—" if flag is None else ("yes" if flag else "**no**")


def write_incremental_report(results: dict[str, Any], out_dir: str | os.PathLike[str]) -> str:
    """Write ``results.json``, ``timings.json``, ``table.md`` and the heat map; the table.

    Parameters
    ----------
    results
        :func:`run_incremental_experiment`'s result (with ``preset`` when known).
    out_dir
        Output folder (created).
    """
    table = incremental_markdown(results)
    folder = write_results_files(out_dir, results, table)
    fig = plot_incremental(results)
    _save(fig, Path(folder) / FIGURE_NAME)
    return table
