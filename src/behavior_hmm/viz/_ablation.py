"""The ablation table (markdown) and figure of ``experiment ablation``."""

from __future__ import annotations

import os
from typing import Any

from matplotlib.figure import Figure
from matplotlib.transforms import ScaledTranslation

from behavior_hmm.viz._reports import _spread, write_results_files
from behavior_hmm.viz._traces import _save


def ablation_markdown(results: dict[str, Any]) -> str:
    """One markdown table per task: success, goals, floor, jolts, switches, training time.

    With several seeds (``results["seeds"]``) success and goals are the mean ± 95 %
    interval over them; the other columns are the first seed's, but ``train s``, the
    mean over seeds (from ``results["timings"]``, "—" when absent, as in a results.json).
    """
    lines: list[str] = []
    sim = results["sim"]
    seeds = results.get("seeds") or []
    timings = (results.get("timings") or {}).get("train_s") or {}
    if len(seeds) > 1:
        lines.append(
            f"Success and goals: mean ± 95 % interval (Student's t) over {len(seeds)} seeds "
            f"({seeds[0]}..{seeds[-1]}); the other columns: seed {seeds[0]}."
        )
        lines.append("")
    for entry in results["tasks"]:
        inputs = ", ".join(entry["inputs"])
        n = entry["rows"][0]["n"]
        seconds = timings.get(entry["task"]) or [None] * len(entry["rows"])
        lines.append(
            f"**{entry['task']}** {{{inputs}}} ({sim}, {n} test starts; "
            f"thesis's own figure {entry['thesis']:.1f} %)"
        )
        lines.append("")
        lines.append(
            "| row | success % | goals reached | zero floor % | jump × teacher's (median / max) "
            "| max switches | train s |"
        )
        lines.append("| --- | --- | --- | --- | --- | --- | --- |")
        for row, took in zip(entry["rows"], seconds, strict=True):
            label = row["label"]
            if not row["switched"] and not row.get("options"):
                label = f"**{label} preset**"
            if row.get("chosen_inputs"):
                label += f" (chose {row['chosen_inputs']})"
            if "over_seeds" in row:
                success = _spread(row["over_seeds"], "success_rate_mean")
                goals = f"{_spread(row['over_seeds'], 'goal_reached')} of {row['n']}"
            else:
                success = f"{row['success_rate_mean']:.1f}"
                goals = f"{row['goal_reached']}/{row['n']}"
            jump = (
                f"{row['command_jump_ratio_median']:.1f} / {row['command_jump_ratio_max']:.1f}"
                if "command_jump_ratio_median" in row
                else "—"
            )
            train = f"{sum(took) / len(took):.1f}" if took else "—"
            lines.append(
                f"| {label} | {success} | {goals} | {row['zero_floor_mean']:.1f} | {jump} "
                f"| {row['switches_max']} | {train} |"
            )
        lines.append("")
    return "\n".join(lines)


def plot_ablation(results: dict[str, Any]) -> Figure:
    """Success rate per row, one panel per task, thesis rows above default rows.

    Bars are the mean success rate (%); the grey line is the all-zero floor, the dashed
    line the thesis's own figure; each bar is labelled with goals reached. With several
    seeds, bars and labels are the means over them and the whiskers the 95 % intervals.
    """
    tasks = results["tasks"]
    heights = [max(3.0, 0.28 * len(t["rows"]) + 1.2) for t in tasks]
    fig = Figure(figsize=(8.5, sum(heights)), layout="constrained")
    axes = fig.subplots(len(tasks), 1, squeeze=False, height_ratios=heights)[:, 0]
    for ax, entry in zip(axes, tasks, strict=True):
        rows = entry["rows"]
        labels = [r["label"] for r in rows]
        spread = [_over_seeds(r) for r in rows]
        values = [v[0] for v in spread]
        errors = [v[1] for v in spread]
        colours = [
            "tab:orange"
            if r["preset"] == "thesis"
            else "tab:green"
            if r.get("options")
            else "tab:blue"
            for r in rows
        ]
        positions = list(range(len(rows)))[::-1]
        ax.barh(positions, values, xerr=errors, color=colours, alpha=0.85, error_kw={"lw": 0.8})
        for y, row, (value, error, goals) in zip(positions, rows, spread, strict=True):
            text = f"{value:.1f} % ({goals}/{row['n']})"
            if "over_seeds" in row:
                text = f"{value:.1f} ± {error:.1f} % ({goals:.1f}/{row['n']})"
            if row.get("chosen_inputs"):  # inputs="auto": the channels it chose
                text += "\nchose " + row["chosen_inputs"].replace("; ", "\n")
            ax.text(value + error + 0.5, y, text, va="center", fontsize=7)
        floor = rows[0]["zero_floor_mean"]
        ax.axvline(floor, color="grey", lw=1.2, label=f"all-zero floor {floor:.1f} %")
        ax.axvline(
            entry["thesis"], color="k", ls="--", lw=1.0, label=f"thesis {entry['thesis']:.1f} %"
        )
        ax.set_yticks(positions, labels, fontsize=7)
        # room for the labels after the whiskers
        ax.set_xlim(0, max(112.0, *(v + e + 30.0 for v, e in zip(values, errors, strict=True))))
        ax.set_xlabel("success rate (%)")
        inputs = ", ".join(entry["inputs"])
        ax.set_title(
            f"{entry['task']} on {inputs}: thesis + each (orange), default − each (blue)"
            + (", default + option (green)" if any(r.get("options") for r in rows) else ""),
            fontsize=9,
        )
        # the legend 0.4 inch below the axes, under the x label, however tall the panel
        below = ax.transAxes + ScaledTranslation(0.0, -0.4, fig.dpi_scale_trans)
        ax.legend(
            loc="upper center",
            bbox_to_anchor=(0.5, 0.0),
            bbox_transform=below,
            ncol=2,
            fontsize=7,
            frameon=False,
        )
    return fig


def _over_seeds(row: dict[str, Any]) -> tuple[float, float, float]:
    """A row's success % and its 95 % interval (0 for one seed), and its goals reached."""
    if "over_seeds" not in row:
        return row["success_rate_mean"], 0.0, row["goal_reached"]
    over = row["over_seeds"]
    return (
        over["success_rate_mean"]["mean"],
        over["success_rate_mean"]["ci95"],
        over["goal_reached"]["mean"],
    )


def write_ablation_report(results: dict[str, Any], out: str | os.PathLike[str]) -> str:
    """Write ``results.json``, ``table.md`` and ``ablation.png`` into ``out``; return the table.

    The wall-clock ``timings`` go to ``timings.json``, not results.json.
    """
    table = ablation_markdown(results)
    folder = write_results_files(out, results, table + "\n")
    _save(plot_ablation(results), folder / "ablation.png", dpi=110)
    return table
