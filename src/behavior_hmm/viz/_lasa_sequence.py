"""Tables and the R-matrix heat map of ``experiment incremental --lasa`` (issue 29)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Final

import numpy as np
from matplotlib.figure import Figure

from behavior_hmm.evaluate._lasa_sequence import (
    LASA_SCHEMES,
    TARGET_LASA_BWT,
    check_lasa_targets,
)
from behavior_hmm.viz._incremental import plot_r_matrices, scheme_panels
from behavior_hmm.viz._reports import write_results_files
from behavior_hmm.viz._traces import _save

#: How each scheme is named in the tables and the figure.
LASA_SCHEME_LABELS: Final[dict[str, str]] = {
    "incremental": "incremental (an SBLM per shape)",
    "grown": "one SBLM grown by partial_fit",
    "bc_strong_finetuned": "BC-strong fine-tuned shape by shape",
}

#: File name of the heat map in the output folder.
LASA_FIGURE_NAME: Final[str] = "incremental_lasa_R.png"


def plot_lasa_sequence(results: Mapping[str, Any]) -> Figure:
    """Heat maps of ``R[k, i]`` (score %, shape i after stage k), one panel per scheme."""
    settings = results["settings"]
    return plot_r_matrices(
        scheme_panels(results, {s: LASA_SCHEME_LABELS[s] for s in LASA_SCHEMES}),
        list(results["sequence"]),
        f"LASA shapes learned one after another: R[k, i] (SBLM: {settings['sblm_preset']} "
        f"preset, seed {settings['seed']})",
        label="score % (commands against the test demonstration)",
    )


def _cell(entry: Mapping[str, Any], k: int, i: int) -> str:
    return f"{entry['R'][k][i]:.1f} ({entry['goals'][k][i]}/{entry['n'][i]})"


def lasa_sequence_markdown(results: Mapping[str, Any]) -> str:
    """The summary metrics, a row per shape (when learned, at the end) and the targets."""
    schemes = [s for s in LASA_SCHEMES if s in results["schemes"]]
    names = list(results["sequence"])
    settings = results["settings"]
    timings = results.get("timings") or {}
    last = len(names) - 1
    lines = [
        f"Sequence: the {len(names)} shapes {names[0]} … {names[-1]} in this order; SBLM: "
        f"{settings['sblm_preset']} preset, seed {settings['seed']}. Stage k learns shape "
        f"k from its demonstrations {', '.join(map(str, settings['train']))}; R[k, i]: "
        f"score % of shape i after stage k from the starts of its demonstrations "
        f"{', '.join(map(str, settings['test']))} (goals reached within "
        f"{settings['reach']:g} unit / starts).",
        "",
        "| scheme | ACC % | BWT (points) | forgetting (points) | REM | FWT (points) "
        "| worst drop (points) | goals at the end | median DTW at the end | train s, total "
        "| model size at the end |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for scheme in schemes:
        entry = results["schemes"][scheme]
        m = entry["metrics"]
        fwt = "—" if m["fwt"] is None else f"{m['fwt']:+.2f}"
        reached = sum(int(v) for v in entry["goals"][last])
        seconds = timings.get(f"{scheme}_s")
        total = f"{float(np.sum(seconds)):.1f}" if seconds else "—"
        kept = entry["model_bytes"][-1] / 1e6
        unit = " of weights" if scheme == "bc_strong_finetuned" else " of model files"
        dtw = float(np.median([float(v) for v in entry["dtw"][last]]))
        lines.append(
            f"| {LASA_SCHEME_LABELS[scheme]} | {m['acc']:.1f} | {m['bwt']:+.2f} "
            f"| {m['forgetting']:.2f} | {m['rem']:.3f} | {fwt} | {m['worst_drop']:+.2f} "
            f"| {reached}/{sum(entry['n'])} | {dtw:.0f} | {total} | {kept:.2f} MB{unit} |"
        )
    lines.append("")
    header = "| shape | floor % | learned (incremental) | end: " + " | end: ".join(
        LASA_SCHEME_LABELS[s] for s in schemes
    )
    rule = "| --- | --- | --- |" + " --- |" * len(schemes)
    joint = results["schemes"].get("grown", {}).get("joint")
    if joint is not None:
        header += " | one SBLM fit on every shape"
        rule += " --- |"
    lines += [header + " |", rule]
    inc = results["schemes"]["incremental"]
    for i, name in enumerate(names):
        row = f"| {name} | {results['floor'][i]:.1f} | {_cell(inc, i, i)} | " + " | ".join(
            _cell(results["schemes"][s], last, i) for s in schemes
        )
        if joint is not None:
            j = joint[i]
            row += f" | {j['score']:.1f} ({j['reached']}/{j['n']})"
        lines.append(row + " |")
    lines.append("")
    targets = check_lasa_targets(results)
    identical = inc.get("refit_identical") or []
    never = ", ".join(targets["never_reached"]) or "none"
    lines += [
        "| issue 29 target (LASA sequence) | measured | met |",
        "| --- | --- | --- |",
        f"| BWT ≥ {TARGET_LASA_BWT:+.1f} points | {targets['bwt']:+.2f} "
        f"| {'yes' if targets['bwt_met'] else '**no**'} |",
        "| every earlier shape still reaches its goal (each test start that reached it "
        f"when learned) | shapes that lost a goal: {', '.join(targets['lost']) or 'none'} "
        f"| {'yes' if targets['kept_met'] else '**no**'} |",
        "",
        f"Test starts that missed the goal already when their shape was learned: {never}. "
        f"Each shape's SBLM fitted again at the end equals the one learned at its stage "
        f"byte for byte: {sum(identical)} of {len(identical)}.",
    ]
    grown = results["schemes"].get("grown", {})
    if "clipped_share" in grown:
        clipped = [
            f"{name} {share:.1%}"
            for name, share in zip(names, grown["clipped_share"], strict=True)
            if share > 0
        ]
        lines += [
            "",
            f"The grown SBLM's command scale is its first shape's, {grown['command_scale']:.1f} "
            "units/s; training commands beyond it, which partial_fit clips: "
            + (", ".join(clipped) or "none")
            + ".",
        ]
    return "\n".join(lines) + "\n"


def write_lasa_sequence_report(results: dict[str, Any], out_dir: str | os.PathLike[str]) -> str:
    """Write ``results.json``, ``timings.json``, ``table.md`` and the heat map; the table."""
    table = lasa_sequence_markdown(results)
    folder = write_results_files(out_dir, results, table)
    _save(plot_lasa_sequence(results), Path(folder) / LASA_FIGURE_NAME)
    return table
