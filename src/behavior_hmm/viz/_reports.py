"""Experiment reports: JSON, figures and a markdown table for docs/results.md."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from behavior_hmm._atomic import atomic_write_bytes
from behavior_hmm.viz._traces import plot_complex_run, plot_generated_vs_demonstrated


def write_simple_report(results: dict[str, Any], out_dir: str | os.PathLike[str]) -> str:
    """Write ``results.json``, the figures and ``table.md`` of the simple experiment.

    Returns the markdown table (thesis vs SBLM vs behavior cloning, with the floors).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figures = results.get("figures", {})
    names = []
    for behavior, series in figures.items():
        channel = "angle" if behavior == "turn" else "distance"
        png = out / f"{behavior}_generated_vs_demonstrated.png"
        plot_generated_vs_demonstrated(
            series, channel, png, f"{behavior}: generated (solid) vs demonstrated (dashed)"
        )
        names.append(png.name)
    public = {k: v for k, v in results.items() if k != "figures"}
    atomic_write_bytes(out / "results.json", json.dumps(public, indent=1, default=float).encode())
    table = simple_table(results)
    atomic_write_bytes(out / "table.md", table.encode())
    return table


def simple_table(results: dict[str, Any]) -> str:
    """Markdown table of the simple experiment's rows."""
    lines = [
        "| behavior | inputs | thesis % | SBLM % | SBLM goals | BC % | BC goals | zero floor % "
        "| SBLM motor-max % (floor) | primitives / obs. categories |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in results["rows"]:
        lines.append(
            f"| {r['behavior']} | {', '.join(r['inputs'])} | {r['thesis']:.1f} "
            f"| **{r['sblm']:.1f}** | {r['sblm_goal_reached']}/{r['n']} | {r['bc']:.1f} "
            f"| {r['bc_goal_reached']}/{r['n']} | {r['zero_floor']:.1f} "
            f"| {r['sblm_motor_max']:.1f} ({r['zero_floor_motor_max']:.1f}) "
            f"| {r['primitives']} / {r['observations']} |"
        )
    return "\n".join(lines) + "\n"


def write_complex_report(results: dict[str, Any], out_dir: str | os.PathLike[str]) -> str:
    """Write ``results.json``, the figure-6.10 analogue and ``table.md``; return the table."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for i, run in enumerate(results.get("figure", [])):
        plot_complex_run(run, out / f"turn_approach_{i}.png")
    public = {k: v for k, v in results.items() if k != "figure"}
    atomic_write_bytes(out / "results.json", json.dumps(public, indent=1, default=float).encode())
    table = complex_table(results)
    atomic_write_bytes(out / "table.md", table.encode())
    return table


def complex_table(results: dict[str, Any]) -> str:
    """Markdown tables of the complex experiment."""
    ta = results["turn_approach"]
    bc = ta["baselines"]["bc"]
    lines = [
        "| behavior | inputs | thesis % | CBLM % | CBLM goals | BC % | BC goals | zero floor % "
        "| CBLM motor-max % (floor) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
        f"| turn & approach | distance, angle | 79.8 | **{ta['success_rate_mean']:.1f}** "
        f"| {ta['goal_reached']}/{ta['n']} | {bc['success_rate_mean']:.1f} "
        f"| {bc['goal_reached']}/{bc['n']} | {ta['zero_floor_mean']:.1f} "
        f"| {ta['success_rate_motor_max_mean']:.1f} ({ta['zero_floor_motor_max_mean']:.1f}) |",
        "",
        "| composition | success % | zero floor % | goals (need approach) | goals (need retreat) |",
        "| --- | --- | --- | --- | --- |",
    ]
    for key, label in (
        ("position", "position = CBLM{turn, approach, retreat}"),
        ("nested_position", "position = CBLM{CBLM{turn, approach}, retreat}"),
    ):
        p = results[key]
        lines.append(
            f"| {label} | {p['success_rate_mean']:.1f} | {p['zero_floor_mean']:.1f} "
            f"| {p['approach_goal_reached']}/{p['approach_n']} "
            f"| {p['retreat_goal_reached']}/{p['retreat_n']} |"
        )
    r = results["retreat"]
    lines.append(
        f"| retreat (SBLM, 15 test starts) | {r['success_rate_mean']:.1f} "
        f"| {r['zero_floor_mean']:.1f} | | {r['goal_reached']}/{r['n']} |"
    )
    lines.append("")
    lines.append(
        f"Training the turn & approach CBLM from its components: "
        f"{results['turn_approach_train_s']:.1f} s, "
        f"{results['turn_approach_observations']} observation categories."
    )
    return "\n".join(lines) + "\n"
