"""Experiment reports: JSON, figures and a markdown table for docs/results.md."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from behavior_hmm._atomic import atomic_write_bytes
from behavior_hmm.viz._traces import plot_generated_vs_demonstrated


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
