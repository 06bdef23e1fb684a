"""Figures of the categorization experiment (thesis figs 6.1-6.4)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import FancyArrowPatch

from behavior_hmm.viz._traces import _save, new_figure, root_figure

#: Start angles (deg) span this range; their colour scale.
_ANGLE_NORM = Normalize(-180.0, 180.0)
_ANGLE_CMAP = colormaps["coolwarm"]


def _axes(ax: Axes | None, figsize: tuple[float, float]) -> tuple[Figure, Axes]:
    if ax is None:
        ax = new_figure(figsize).add_subplot()
    return root_figure(ax), ax


def _angle_bar(ax: Axes, label: str) -> None:
    owner = ax.get_figure()
    assert owner is not None
    bar = owner.colorbar(ScalarMappable(norm=_ANGLE_NORM, cmap=_ANGLE_CMAP), ax=ax, pad=0.01)
    bar.set_label(label)
    bar.set_ticks([-180, -90, 0, 90, 180])


def plot_angle_vs_category(
    run: dict[str, Any],
    path: str | os.PathLike[str] | None = None,
    *,
    ax: Axes | None = None,
) -> Figure:
    """Rotational angle versus motion-primitive id, one colour per start (figs 6.1 / 6.3).

    Each training episode's samples are coloured by its start angle (colour bar).
    Draws into ``ax`` (default a new figure), writes ``path`` when given, and returns
    the figure.
    """
    labels = np.asarray(run["labels"])
    angles = np.asarray(run["angles"])
    lengths = np.asarray(run["lengths"])
    starts = np.asarray(run["episode_starts"])
    fig, ax = _axes(ax, (8, 5))
    offsets = np.r_[0, np.cumsum(lengths)]
    for a, b, start in zip(offsets[:-1], offsets[1:], starts, strict=True):
        color = _ANGLE_CMAP(_ANGLE_NORM(start))
        ax.plot(angles[a:b], labels[a:b], ".", ms=2.5, color=color, alpha=0.8)
    ax.set_xlabel("rotational angle (deg)")
    ax.set_ylabel("motion primitive id")
    ax.set_title(
        f"turn demonstrations categorized at vigilance {run['rho']:g}: "
        f"{run['n_primitives']} motion primitives"
    )
    ax.grid(alpha=0.3)
    _angle_bar(ax, "start angle of the demonstration (deg)")
    if path is not None:
        _save(fig, path)
    return fig


def _edge_width(count: float, top: float) -> float:
    return float(0.5 + 2.5 * np.log1p(count) / np.log1p(top))


def plot_transition_diagram(
    run: dict[str, Any],
    path: str | os.PathLike[str] | None = None,
    *,
    ax: Axes | None = None,
) -> Figure:
    """Primitive transition diagram (figs 6.2 / 6.4).

    Nodes sit at the mean rotational angle of their samples (x) and are spread over
    two bands, negative starts above and positive below (as in fig 6.4); arrows show
    observed transitions, their width growing with the logarithm of the transition
    count (a legend gives the scale). Node colour: the primitive's mean angle (colour
    bar). Draws into ``ax`` (default a new figure), writes ``path`` when given, and
    returns the figure.
    """
    labels = np.asarray(run["labels"])
    angles = np.asarray(run["angles"])
    counts = np.asarray(run["transitions"], dtype=float)
    k = counts.shape[0]
    lengths = np.asarray(run["lengths"])
    start_of_row = np.repeat(np.asarray(run["episode_starts"]), lengths)
    mean_angle = np.array(
        [angles[labels == i].mean() if np.any(labels == i) else 0.0 for i in range(k)]
    )
    side = np.array(
        [np.mean(start_of_row[labels == i] > 0) if np.any(labels == i) else 0.5 for i in range(k)]
    )
    order = np.argsort(mean_angle)
    y = np.zeros(k)
    for rank, i in enumerate(order):
        band = -1.0 if side[i] > 0.5 else 1.0
        y[i] = band * (1.0 + (rank % 4) * 0.6)
    fig, ax = _axes(ax, (11, 6))
    off_diagonal = counts[~np.eye(k, dtype=bool)] if k else counts.ravel()
    top = float(off_diagonal.max()) if off_diagonal.size and off_diagonal.max() > 0 else 1.0
    for i in range(k):
        for j in range(k):
            if i == j or counts[i, j] <= 0:
                continue
            ax.add_patch(
                FancyArrowPatch(
                    (mean_angle[i], y[i]),
                    (mean_angle[j], y[j]),
                    arrowstyle="-|>",
                    mutation_scale=9,
                    lw=_edge_width(counts[i, j], top),
                    color="0.35",
                    alpha=0.6,
                    connectionstyle="arc3,rad=0.15",
                    shrinkA=9,
                    shrinkB=9,
                )
            )
    ax.scatter(
        mean_angle,
        y,
        s=260,
        c=_ANGLE_CMAP(_ANGLE_NORM(mean_angle)),
        edgecolors="k",
        zorder=3,
    )
    for i in range(k):
        ax.annotate(str(i), (mean_angle[i], y[i]), ha="center", va="center", fontsize=7, zorder=4)
    present = sorted({int(c) for c in off_diagonal if c > 0})
    middle = round(float(np.median(present))) if present else 0
    scale = sorted({present[0], middle, present[-1]}) if present else []
    handles = [
        Line2D([], [], color="0.35", alpha=0.6, lw=_edge_width(c, top), label=f"{c}") for c in scale
    ]
    if handles:
        ax.legend(
            handles=handles,
            title="transitions counted\n(edge width ∝ log count)",
            loc="upper right",
            fontsize=8,
            title_fontsize=8,
        )
    ax.set_xlabel("mean rotational angle of the primitive (deg)")
    ax.set_yticks([2, -2], ["negative starts", "positive starts"])
    ax.set_ylim(-3.5, 3.5)
    ax.grid(alpha=0.3, axis="x")
    ax.set_title(
        f"motion-primitive transitions at vigilance {run['rho']:g} "
        f"({k} primitives, node number = primitive id)"
    )
    _angle_bar(ax, "mean rotational angle of the primitive (deg)")
    if path is not None:
        _save(fig, path)
    return fig


def write_categorization_report(results: dict[str, Any], out_dir: str | os.PathLike[str]) -> str:
    """Figures per vigilance plus a markdown summary (table 6.1 and the analysis)."""
    import json

    from behavior_hmm._atomic import atomic_write_bytes

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    lines = []
    for run in results["runs"]:
        tag = f"rho{run['rho']:g}".replace(".", "")
        plot_angle_vs_category(run, out / f"categories_{tag}.png")
        plot_transition_diagram(run, out / f"transitions_{tag}.png")
        lines.append(f"**Vigilance {run['rho']:g}**: {run['n_primitives']} motion primitives.\n")
        lines.append("| start angle | sequence of motion primitives |")
        lines.append("| --- | --- |")
        for seq in run["sequences"]:
            lines.append(f"| {seq['start']:g} | {', '.join(map(str, seq['sequence']))} |")
        lines.append("")
        for pair in run["same_direction"]:
            tail = ", ".join(map(str, pair["shared_tail"])) or "none"
            lines.append(f"- same direction {pair['starts']}: shared tail {{{tail}}}")
        for pair in run["opposite_direction"]:
            shared = ", ".join(map(str, pair["shared"])) or "none"
            lines.append(f"- opposite directions {pair['starts']}: shared primitives {{{shared}}}")
        lines.append("")
    text = "\n".join(lines)
    slim = {
        "inputs": results["inputs"],
        "runs": [
            {k: v for k, v in r.items() if k not in ("labels", "angles")} for r in results["runs"]
        ],
    }
    atomic_write_bytes(out / "categorization.json", json.dumps(slim, indent=1).encode())
    atomic_write_bytes(out / "categorization.md", text.encode())
    return text
