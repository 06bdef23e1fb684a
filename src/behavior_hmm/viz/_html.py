"""A self-contained HTML evaluation report (tables plus embedded plots)."""

from __future__ import annotations

import base64
import html
import io
import os
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from behavior_hmm._atomic import atomic_write_bytes
from behavior_hmm.data import CONTROL_PERIOD, SENSOR_CHANNELS
from behavior_hmm.viz._traces import run_series

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em; color: #222; max-width: 1100px; }
table { border-collapse: collapse; margin: 1em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 4px 8px; text-align: right; }
th { background: #f3f3f3; } td.l, th.l { text-align: left; }
.fail { color: #b00; font-weight: bold; } .note { color: #555; font-size: 0.9em; }
img { max-width: 100%; border: 1px solid #eee; margin: 0.5em 0; }
"""


def _png(fig: Figure) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _run_figure(trace: Any, demo: dict[str, np.ndarray], title: str) -> str:
    """Commands and the goal channels of one run against its demonstration (base64 PNG)."""
    channels = [c for c in ("angle", "distance") if c in trace.goal] or ["angle"]
    fig = Figure(figsize=(9, 2.4 * (len(channels) + 1)), layout="constrained")
    axes = fig.subplots(len(channels) + 1, 1, sharex=True)
    t, readings, commands = run_series(trace)  # a refused run: one step, no reading
    marker = "o" if len(t) == 1 else None
    td = np.arange(len(demo["left"])) * CONTROL_PERIOD
    for ax, name in zip(axes, channels, strict=False):
        ax.plot(td, demo[name], "k--", lw=1.2, label="demonstrated")
        ax.plot(
            t, readings[:, SENSOR_CHANNELS.index(name)], lw=1.6, marker=marker, label="generated"
        )
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    ax = axes[-1]
    for j, side in enumerate(("left", "right")):
        ax.plot(td, demo[side], f"C{j}--", lw=1)
        ax.plot(t, commands[:, j], f"C{j}", lw=1.5, marker=marker, label=f"{side} (rad/s)")
    ax.set_xlabel("time (s)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    axes[0].legend(fontsize=8)
    fig.suptitle(title)
    return _png(fig)


def _summary_rows(result: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    return [("model", result), *result.get("baselines", {}).items()]


def write_evaluation_report(
    result: dict[str, Any],
    traces: dict[str, list[Any]] | None,
    path: str | os.PathLike[str],
    max_runs: int = 6,
) -> Path:
    """Write an HTML report of ``evaluate_model``'s result (with ``keep_traces`` runs).

    The page holds the summary (each score beside its all-zero floor and the motor-limit
    variant), every case, and plots of the first ``max_runs`` runs against their
    demonstrations; images are embedded, so the file stands alone.
    """
    e = html.escape
    title = f"{result['behavior']} on {', '.join(result['inputs'])} ({result['sim']})"
    parts = [
        f"<!doctype html><html><head><meta charset='utf-8'><title>{e(title)}</title>",
        f"<style>{_STYLE}</style></head><body>",
        f"<h1>behavior-hmm evaluation: {e(title)}</h1>",
        f"<p class='note'>seed {result['seed']}, sensor noise {result['noise']}, commands "
        f"normalized by {result['command_scale']:.3g} rad/s (largest demonstrated command; "
        f"motor limit {result['motor_max']:.3g}). Read every score beside its all-zero floor.</p>",
        "<table><tr><th class='l'></th><th>success %</th><th>zero floor %</th>"
        "<th>goals reached</th><th>motor-max % (floor)</th><th>duration ×</th>"
        "<th>command jump × teacher's (median / max)</th><th>switches (max)</th></tr>",
    ]
    for name, r in _summary_rows(result):
        parts.append(
            f"<tr><td class='l'>{e(name)}</td><td>{r['success_rate_mean']:.1f}</td>"
            f"<td>{r['zero_floor_mean']:.1f}</td><td>{r['goal_reached']}/{r['n']}</td>"
            f"<td>{r['success_rate_motor_max_mean']:.1f} ({r['zero_floor_motor_max_mean']:.1f})"
            f"</td><td>{r['duration_ratio_mean']:.2f}</td>"
            f"<td>{r.get('command_jump_ratio_median', float('nan')):.1f} / "
            f"{r.get('command_jump_ratio_max', float('nan')):.1f}</td>"
            f"<td>{r.get('switches_max', '')}</td></tr>"
        )
    parts.append(
        "</table><h2>Cases</h2><table><tr><th class='l'>start</th><th class='l'>goal</th>"
        "<th>success %</th><th>floor %</th><th>goal</th><th>angle err (deg)</th>"
        "<th>distance err (m)</th><th>duration ×</th><th>jump ×</th><th>switches</th>"
        "<th class='l'>components</th></tr>"
    )
    for case in result["cases"]:
        ok = "yes" if case["goal_reached"] else "<span class='fail'>no</span>"
        angle = case.get("final_angle_error_deg")
        dist = case.get("final_distance_error_m")
        parts.append(
            f"<tr><td class='l'>{e(str(case['start']))}</td><td class='l'>{e(str(case['goal']))}"
            f"</td><td>{case['success_rate']:.1f}</td><td>{case['zero_floor']:.1f}</td>"
            f"<td>{ok}</td><td>{'' if angle is None else f'{angle:.2f}'}</td>"
            f"<td>{'' if dist is None else f'{dist:.4f}'}</td>"
            f"<td>{case['duration_ratio']:.2f}</td>"
            f"<td>{case.get('command_jump_ratio', float('nan')):.1f}</td>"
            f"<td>{case.get('switches', '')}</td>"
            f"<td class='l'>{e(' → '.join(case.get('components', [])))}</td></tr>"
        )
    parts.append("</table>")
    if traces and traces.get("model"):
        parts.append("<h2>Runs (solid: generated, dashed: demonstrated)</h2>")
        for k, (trace, demo) in enumerate(traces["model"][:max_runs]):
            caption = f"start {trace.start}: {result['cases'][k]['success_rate']:.1f} %"
            parts.append(
                f"<img alt='{e(caption)}' src='data:image/png;base64,"
                f"{_run_figure(trace, demo, caption)}'>"
            )
    parts.append("</body></html>")
    target = Path(path)
    atomic_write_bytes(target, "\n".join(parts).encode("utf-8"))
    return target
