"""The ablation table (markdown) and figure of ``experiment ablation``."""

from __future__ import annotations

import os
from typing import Any

from matplotlib.figure import Figure

from behavior_hmm.viz._reports import write_results_files
from behavior_hmm.viz._traces import _save


def ablation_markdown(results: dict[str, Any]) -> str:
    """One markdown table per task: success, goals reached and floor per row."""
    lines: list[str] = []
    sim = results["sim"]
    for entry in results["tasks"]:
        inputs = ", ".join(entry["inputs"])
        lines.append(
            f"**{entry['task']}** {{{inputs}}} ({sim}, {entry['rows'][0]['n']} test starts; "
            f"thesis's own figure {entry['thesis']:.1f} %)"
        )
        lines.append("")
        lines.append("| row | success % | goals reached | zero floor % | max switches | train s |")
        lines.append("| --- | --- | --- | --- | --- | --- |")
        for row in entry["rows"]:
            label = row["label"]
            if not row["switched"]:
                label = f"**{label} preset**"
            lines.append(
                f"| {label} | {row['success_rate_mean']:.1f} | {row['goal_reached']}/{row['n']} "
                f"| {row['zero_floor_mean']:.1f} | {row['switches_max']} | {row['train_s']:.1f} |"
            )
        lines.append("")
    return "\n".join(lines)


def plot_ablation(results: dict[str, Any]) -> Figure:
    """Success rate per row, one panel per task, thesis rows above default rows.

    Bars are the mean success rate (%); the grey line is the all-zero floor, the dashed
    line the thesis's own figure; each bar is labelled with goals reached.
    """
    tasks = results["tasks"]
    heights = [max(3.0, 0.28 * len(t["rows"]) + 1.2) for t in tasks]
    fig = Figure(figsize=(8.5, sum(heights)), layout="constrained")
    axes = fig.subplots(len(tasks), 1, squeeze=False, height_ratios=heights)[:, 0]
    for ax, entry in zip(axes, tasks, strict=True):
        rows = entry["rows"]
        labels = [r["label"] for r in rows]
        values = [r["success_rate_mean"] for r in rows]
        colours = ["tab:orange" if r["preset"] == "thesis" else "tab:blue" for r in rows]
        positions = list(range(len(rows)))[::-1]
        ax.barh(positions, values, color=colours, alpha=0.85)
        for y, row in zip(positions, rows, strict=True):
            ax.text(
                row["success_rate_mean"] + 0.5,
                y,
                f"{row['success_rate_mean']:.1f} % ({row['goal_reached']}/{row['n']})",
                va="center",
                fontsize=7,
            )
        floor = rows[0]["zero_floor_mean"]
        ax.axvline(floor, color="grey", lw=1.2, label=f"all-zero floor {floor:.1f} %")
        ax.axvline(
            entry["thesis"], color="k", ls="--", lw=1.0, label=f"thesis {entry['thesis']:.1f} %"
        )
        ax.set_yticks(positions, labels, fontsize=7)
        ax.set_xlim(0, 112)
        ax.set_xlabel("success rate (%)")
        inputs = ", ".join(entry["inputs"])
        ax.set_title(
            f"{entry['task']} on {inputs}: thesis preset + each addition (orange), "
            "default − each (blue)",
            fontsize=9,
        )
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2, fontsize=7, frameon=False)
    return fig


def write_ablation_report(results: dict[str, Any], out: str | os.PathLike[str]) -> str:
    """Write ``results.json``, ``table.md`` and ``ablation.png`` into ``out``; return the table."""
    table = ablation_markdown(results)
    folder = write_results_files(out, results, table + "\n")
    _save(plot_ablation(results), folder / "ablation.png", dpi=110)
    return table
