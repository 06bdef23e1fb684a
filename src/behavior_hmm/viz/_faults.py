"""Tables (markdown) and figures of ``experiment faults``."""

from __future__ import annotations

import os
from typing import Any

from matplotlib.figure import Figure

from behavior_hmm.viz._reports import write_results_files
from behavior_hmm.viz._traces import _save

_TASK_LABEL = {"turn": "turn", "approach": "approach", "turn-approach": "turn & approach"}
_COLOURS = {"turn": "tab:blue", "approach": "tab:orange", "turn-approach": "tab:green"}
_MARKERS = ("o", "s", "^", "D")
#: Fault kinds whose levels are categories, not a scale: drawn as points, not lines.
_CATEGORICAL = frozenset({"dropout"})


def _task_label(entry: dict[str, Any]) -> str:
    name = _TASK_LABEL.get(entry["task"], entry["task"])
    return f"{name} {{{', '.join(entry['inputs'])}}}"


def _cells(entry: dict[str, Any], kind: str) -> list[dict[str, Any]]:
    return [c for c in entry["cells"] if c["fault"] == kind]


def _cell_text(cell: dict[str, Any]) -> str:
    text = f"{cell['goal_reached']}/{cell['n']} · {cell['success_rate_mean']:.1f} %"
    notes = []
    if cell.get("applied") is not None and cell["applied"] < cell["n"]:
        notes.append(f"hit {cell['applied']}")
    stops = cell["reasons"].get("sensor_fault", 0)
    if stops:
        notes.append(f"{stops} sensor-fault stop{'s' if stops > 1 else ''}")
    refused = cell["reasons"].get("unreachable", 0)
    if refused:
        notes.append(f"{refused} refused")
    return text + (f" ({', '.join(notes)})" if notes else "")


def faults_markdown(results: dict[str, Any]) -> str:
    """One markdown table per fault kind: goal reached k/n and mean success % per task."""
    tasks = results["tasks"]
    lines = [
        f"Goal reached (of {tasks[0]['baseline']['n']} test starts) · mean success rate, "
        f"{results.get('preset', 'default')} preset, {results['sim']} sim, "
        f"seed {results['seed']}.",
        "",
        "| no fault | " + " | ".join(_task_label(t) for t in tasks) + " |",
        "| --- |" + " --- |" * len(tasks),
        "| — | "
        + " | ".join(
            f"{t['baseline']['goal_reached']}/{t['baseline']['n']} · "
            f"{t['baseline']['success_rate_mean']:.1f} %"
            for t in tasks
        )
        + " |",
        "",
    ]
    for kind in results["faults"]:
        head = f"**{kind['title']}** ({kind['unit']}"
        if kind.get("nominal") is not None:
            head += f"; trained at {kind['nominal']:g}"
        if kind["kind"] == "dropout":
            channels = ", ".join(
                f"{_TASK_LABEL.get(t['task'], t['task'])}: {t['dropout_channel']}" for t in tasks
            )
            head += f" — {channels}"
        lines += [head + ")", ""]
        lines.append("| level | " + " | ".join(_task_label(t) for t in tasks) + " |")
        lines.append("| --- |" + " --- |" * len(tasks))
        per_task = [_cells(t, kind["kind"]) for t in tasks]
        for i, level in enumerate(kind["levels"]):
            label = per_task[0][i]["label"] if per_task and per_task[0] else str(level)
            row = " | ".join(_cell_text(cells[i]) for cells in per_task)
            lines.append(f"| {label} | {row} |")
        lines.append("")
    return "\n".join(lines)


def _numeric(kind: dict[str, Any]) -> bool:
    """Whether a kind's levels form a scale (drawn to scale) rather than categories."""
    if kind["kind"] in _CATEGORICAL or kind["kind"].startswith("push_"):
        return False
    return all(isinstance(v, int | float) for v in kind["levels"])


def plot_faults(results: dict[str, Any], metric: str = "goal_reached") -> Figure:
    """One panel per fault kind: ``metric`` per level, one line per task.

    ``metric`` is ``"goal_reached"`` (count of test starts) or ``"success_rate_mean"``
    (%). The dotted line of each task's colour is its no-fault value; a grey dashed
    line marks the value the models were trained at, where it lies on the axis.
    """
    kinds = results["faults"]
    tasks = results["tasks"]
    cols = min(4, len(kinds))
    rows = -(-len(kinds) // cols)
    fig = Figure(figsize=(3.4 * cols, 3.0 * rows + 0.6), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    n = tasks[0]["baseline"]["n"]
    top = n if metric == "goal_reached" else 100.0
    for ax, kind in zip(axes, kinds, strict=False):
        labels = [c["label"] for c in _cells(tasks[0], kind["kind"])]
        scale = _numeric(kind)
        if scale:
            # a numeric level: drawn to scale, the trained value marked
            levels = [float(v) for v in kind["levels"]]
            span = max(levels) - min(levels) or 1.0
            ticks: list[float] = levels
            step = 0.025 * span
        else:
            ticks = [float(i) for i in range(len(labels))]
            step = 0.1
        for t_i, entry in enumerate(tasks):
            cells = _cells(entry, kind["kind"])
            xs = [x + (t_i - (len(tasks) - 1) / 2) * step for x in ticks]
            colour = _COLOURS.get(entry["task"], f"C{t_i}")
            ax.plot(
                xs,
                [c[metric] for c in cells],
                marker=_MARKERS[t_i % len(_MARKERS)],
                ls="none" if kind["kind"] in _CATEGORICAL else "-",
                color=colour,
                label=_task_label(entry),
            )
            ax.axhline(entry["baseline"][metric], color=colour, ls=":", lw=1.0, alpha=0.8)
        ax.set_xticks(ticks, labels, fontsize=8, rotation=30 if len(labels) > 3 else 0)
        if scale:
            pad = 0.08 * span
            ax.set_xlim(min(levels) - pad, max(levels) + pad)
            nominal = kind.get("nominal")
            if nominal is not None and min(levels) < nominal < max(levels):
                ax.axvline(float(nominal), color="grey", lw=0.8, ls="--")
            if kind["kind"] == "speed_limit":
                ax.invert_xaxis()  # the more severe limit to the right
        else:
            ax.set_xlim(-0.4, len(labels) - 0.6)
        ax.set_ylim(-0.05 * top, 1.08 * top)
        if metric == "goal_reached":
            ax.set_yticks(range(0, n + 1, 5 if n >= 10 else 1))
        title = kind["title"]
        if kind.get("nominal") is not None and kind["kind"] != "noise":
            title += f" (trained {kind['nominal']:g})"
        if kind["kind"] == "dropout" and results.get("fault_hold_s") is not None:
            title += f" (held ≤ {results['fault_hold_s']:g} s)"
        ax.set_title(title, fontsize=9)
        ax.set_xlabel(kind["unit"], fontsize=8)
        ax.tick_params(axis="y", labelsize=8)
        ax.grid(alpha=0.3)
        ax.set_ylabel(
            f"goal reached (of {n})" if metric == "goal_reached" else "success %", fontsize=8
        )
    for ax in axes[len(kinds) :]:
        ax.axis("off")
    handles, labels = axes[0].get_legend_handles_labels()
    what = "goal reached" if metric == "goal_reached" else "mean success rate"
    fig.suptitle(
        f"{what} under faults ({results['sim']} sim, {results.get('preset', 'default')} "
        "preset; dotted: no fault)",
        fontsize=10,
    )
    fig.legend(
        handles, labels, loc="outside lower center", ncol=len(tasks), fontsize=8, frameon=False
    )
    return fig


def write_faults_report(results: dict[str, Any], out: str | os.PathLike[str]) -> str:
    """Write ``results.json``, ``table.md``, ``faults_goal.png`` and ``faults_success.png``."""
    table = faults_markdown(results)
    folder = write_results_files(out, results, table + "\n")
    for metric, name in (
        ("goal_reached", "faults_goal.png"),
        ("success_rate_mean", "faults_success.png"),
    ):
        _save(plot_faults(results, metric), folder / name, dpi=110)
    return table
