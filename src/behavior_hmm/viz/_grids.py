"""Generated-vs-demonstrated figures drawn as the thesis draws them.

* :func:`plot_thesis_starts`: one axes per start, every input set overlaid on the
  teacher's demonstration (thesis figures 6.8 and 6.9);
* :func:`plot_start_grid`: the same, one panel per test start (appendix B.1, B.2);
* :func:`plot_complex_grid`: angle and distance of turn & approach per test start, the
  generated run coloured by the active component (appendix B.3).

Panels come from :func:`simple_panels`, which regroups the per-input-set series of
``run_simple_experiment`` (``figures["test_starts"]`` / ``["thesis_starts"]``) by start.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure, SubFigure
from matplotlib.lines import Line2D

from behavior_hmm.data import CONTROL_PERIOD, UNITS
from behavior_hmm.errors import ConfigError
from behavior_hmm.viz._traces import _save, new_figure, root_figure

#: Colour of the demonstration in every figure here.
DEMO_STYLE: dict[str, Any] = {"color": "k", "ls": "--", "lw": 1.3}


def inputs_label(inputs: Sequence[str]) -> str:
    """``("angle", "angular_velocity")`` -> ``"{angle, angular velocity}"``."""
    return "{" + ", ".join(name.replace("_", " ") for name in inputs) + "}"


def start_label(start: Mapping[str, float], channel: str) -> str:
    """The start on the steered channel: ``"angle 100°"``, ``"distance 0.70 m"``."""
    value = float(start[channel])
    return f"angle {value:g}°" if channel == "angle" else f"{channel} {value:.2f} m"


def simple_panels(series: Sequence[Mapping[str, Any]], behavior: str) -> list[dict[str, Any]]:
    """Regroup one behavior's per-input-set series into one panel per start.

    Parameters
    ----------
    series
        ``_figure_series`` dicts (``behavior``, ``inputs``, ``channel``, ``runs``), one
        per input set; those of other behaviors are skipped. All must have the same
        starts in the same order.

    Returns
    -------
    list of dict
        Per start: ``start``, ``channel``, ``demonstrated`` (from the first input set;
        the teacher's run does not depend on the model), and ``generated`` /
        ``success_rate`` / ``goal_reached`` by input-set label.
    """
    mine = [s for s in series if s["behavior"] == behavior]
    if not mine:
        raise ConfigError(f"no figure series for behavior '{behavior}'")
    n = len(mine[0]["runs"])
    panels: list[dict[str, Any]] = []
    for k in range(n):
        first = mine[0]["runs"][k]
        panel: dict[str, Any] = {
            "start": first["start"],
            "channel": mine[0]["channel"],
            "demonstrated": np.asarray(first["demonstrated"]),
            "generated": {},
            "success_rate": {},
            "goal_reached": {},
        }
        for s in mine:
            if len(s["runs"]) != n or s["runs"][k]["start"] != first["start"]:
                raise ConfigError(f"figure series of '{behavior}' do not share their starts")
            label = inputs_label(s["inputs"])
            run = s["runs"][k]
            panel["generated"][label] = np.asarray(run["generated"])
            panel["success_rate"][label] = float(run["success_rate"])
            panel["goal_reached"][label] = bool(run["goal_reached"])
        panels.append(panel)
    return panels


def _times(n: int) -> np.ndarray:
    return np.arange(n) * CONTROL_PERIOD


def draw_start_panel(
    panel: Mapping[str, Any],
    *,
    ax: Axes,
    title: str | None = None,
    legend: bool = False,
    fontsize: float = 8.0,
) -> Figure:
    """One start: the demonstration (black, dashed) and each input set's generated run.

    Each input set's success rate is written in its colour in the panel's empty corner
    (a "*" marks a run that did not reach its goal). Returns the axes' figure.
    """
    channel = str(panel["channel"])
    demo = np.asarray(panel["demonstrated"], dtype=float)
    ax.plot(_times(demo.size), demo, label="teacher", zorder=3, **DEMO_STYLE)
    lines = []
    for i, (label, gen) in enumerate(panel["generated"].items()):
        gen = np.asarray(gen, dtype=float)
        color = f"C{i % 10}"
        ax.plot(_times(gen.size), gen, color=color, lw=1.6, alpha=0.9, label=label)
        rate = panel.get("success_rate", {}).get(label)
        reached = panel.get("goal_reached", {}).get(label, True)
        if rate is not None:
            lines.append((f"{rate:.1f} %{'' if reached else ' *'}", color))
    # Success rates where the curves are not: the demonstration ends at the goal, so
    # put them on the side of the start value.
    span = np.concatenate([demo, *(np.asarray(g, float) for g in panel["generated"].values())])
    lo, hi = float(np.nanmin(span)), float(np.nanmax(span))
    top = bool(demo.size) and bool(demo[-1] < 0.5 * (lo + hi))
    for j, (text, color) in enumerate(lines):
        y = 0.95 - 0.11 * j if top else 0.05 + 0.11 * (len(lines) - 1 - j)
        ax.text(
            0.97,
            y,
            text,
            color=color,
            transform=ax.transAxes,
            ha="right",
            va="top" if top else "bottom",
            fontsize=fontsize + 0.5,
        )
    ax.grid(alpha=0.3)
    ax.tick_params(labelsize=fontsize)
    ax.set_title(title if title is not None else start_label(panel["start"], channel), fontsize=9)
    if legend:
        ax.legend(fontsize=fontsize, loc="center right")
    return root_figure(ax)


def _legend_handles(panel: Mapping[str, Any]) -> list[Line2D]:
    handles = [Line2D([], [], label="demonstrated (teacher)", **DEMO_STYLE)]
    for i, label in enumerate(panel["generated"]):
        handles.append(Line2D([], [], color=f"C{i % 10}", lw=1.6, label=f"generated, {label}"))
    if panel.get("success_rate"):
        handles.append(Line2D([], [], ls="", label="%: success rate (* goal missed)"))
    return handles


def _legend_columns(handles: Sequence[Line2D], width_in: float, fontsize: float = 9.0) -> int:
    """Columns of a figure legend: one row if it fits ``width_in`` inches, else more rows."""
    entry = [len(str(h.get_label())) * fontsize * 0.55 / 72.0 + 0.9 for h in handles]
    n = len(handles)
    for rows in range(1, n + 1):
        cols = -(-n // rows)
        # a legend fills its columns one after another, the first n % cols one longer
        sizes = [n // cols + (c < n % cols) for c in range(cols)]
        bounds = np.cumsum([0, *sizes])
        widths = [max(entry[a:b], default=0.0) for a, b in itertools.pairwise(bounds)]
        if sum(widths) <= 0.95 * width_in:
            return cols
    return 1


def plot_thesis_starts(
    panels: Sequence[Mapping[str, Any]],
    path: str | os.PathLike[str] | None = None,
    *,
    title: str = "",
    fig: Figure | SubFigure | None = None,
) -> Figure:
    """Thesis figures 6.8 / 6.9: one axes per start, input sets overlaid on the demonstration.

    ``panels`` from :func:`simple_panels`; drawn into ``fig`` (a figure or subfigure;
    default a new figure), written when ``path`` is given. Returns the (root) figure.
    """
    if not panels:
        raise ConfigError("no panels to plot")
    channel = str(panels[0]["channel"])
    owner = fig if fig is not None else new_figure((5.2 * len(panels), 4.4))
    axes = owner.subplots(1, len(panels), squeeze=False)[0]
    for k, (ax, panel) in enumerate(zip(axes, panels, strict=True)):
        draw_start_panel(
            panel,
            ax=ax,
            title=f"({chr(97 + k)}) from {start_label(panel['start'], channel)}",
            fontsize=9,
        )
        ax.set_xlabel("time (s)")
    axes[0].set_ylabel(f"{channel} ({UNITS[channel]})")
    owner.legend(
        handles=_legend_handles(panels[0]),
        loc="outside lower center",
        ncol=_legend_columns(_legend_handles(panels[0]), owner.bbox.width / owner.dpi),
        fontsize=9,
    )
    if title:
        owner.suptitle(title)
    figure = root_figure(owner)
    if path is not None:
        _save(figure, path)
    return figure


def plot_start_grid(
    panels: Sequence[Mapping[str, Any]],
    path: str | os.PathLike[str] | None = None,
    *,
    title: str = "",
    ncols: int = 3,
    fig: Figure | SubFigure | None = None,
) -> Figure:
    """Appendix B.1 / B.2: one panel per start (:func:`draw_start_panel`), ``ncols`` wide.

    Drawn into ``fig`` (default a new figure), written when ``path`` is given.
    """
    if not panels:
        raise ConfigError("no panels to plot")
    channel = str(panels[0]["channel"])
    ncols = max(1, min(ncols, len(panels)))
    nrows = -(-len(panels) // ncols)
    owner = fig if fig is not None else new_figure((3.7 * ncols, 2.45 * nrows + 0.9))
    axes = owner.subplots(nrows, ncols, squeeze=False)
    for k, ax in enumerate(axes.flat):
        if k >= len(panels):
            ax.set_visible(False)
            continue
        draw_start_panel(panels[k], ax=ax)
        if k + ncols >= len(panels):  # the lowest panel of its column
            ax.set_xlabel("time (s)", fontsize=9)
    owner.supylabel(f"{channel} ({UNITS[channel]})", fontsize=10)
    owner.legend(
        handles=_legend_handles(panels[0]),
        loc="outside lower center",
        ncol=_legend_columns(_legend_handles(panels[0]), owner.bbox.width / owner.dpi),
        fontsize=9,
    )
    if title:
        owner.suptitle(title)
    figure = root_figure(owner)
    if path is not None:
        _save(figure, path)
    return figure


def component_colors(names: Sequence[str]) -> dict[str, str]:
    """A fixed colour per component name (turn, approach, ... in order of appearance)."""
    return {name: f"C{i % 10}" for i, name in enumerate(dict.fromkeys(n for n in names if n))}


def draw_complex_channel(
    run: Mapping[str, Any],
    channel: str,
    *,
    ax: Axes,
    colors: Mapping[str, str],
    fontsize: float = 8.0,
) -> Figure:
    """One channel of a complex run: demonstration dashed, generated coloured by component."""
    demo = np.asarray(run[f"demo_{channel}"], dtype=float)
    ax.plot(_times(demo.size), demo, zorder=3, **DEMO_STYLE)
    t = np.asarray(run["t"], dtype=float)
    values = np.asarray(run[channel], dtype=float)
    comp = list(run["component"])
    start = 0
    for k in range(1, len(comp) + 1):
        if k == len(comp) or comp[k] != comp[start]:
            stop = min(k + 1, len(comp))  # overlap one sample so the line is continuous
            ax.plot(t[start:stop], values[start:stop], color=colors.get(comp[start], "0.5"), lw=1.7)
            start = k
    ax.grid(alpha=0.3)
    ax.tick_params(labelsize=fontsize)
    return root_figure(ax)


def _complex_handles(colors: Mapping[str, str]) -> list[Line2D]:
    handles = [Line2D([], [], label="demonstrated (teacher)", **DEMO_STYLE)]
    for name, color in colors.items():
        handles.append(Line2D([], [], color=color, lw=1.7, label=f"generated, {name} active"))
    return handles


def _min_span(ax: Axes, values: Sequence[np.ndarray], span: float) -> None:
    """Widen the y axis to at least ``span`` so numerical noise is not magnified."""
    finite = np.concatenate([np.asarray(v, dtype=float) for v in values])
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return
    lo, hi = float(finite.min()), float(finite.max())
    if hi - lo < span:
        mid = 0.5 * (lo + hi)
        ax.set_ylim(mid - 0.6 * span, mid + 0.6 * span)


def plot_complex_grid(
    runs: Sequence[Mapping[str, Any]],
    path: str | os.PathLike[str] | None = None,
    *,
    title: str = "",
    ncols: int = 3,
    fig: Figure | SubFigure | None = None,
) -> Figure:
    """Appendix B.3: per start, angle (upper) and distance (lower) of turn & approach.

    ``runs`` are the ``figure`` entries of ``run_complex_experiment`` (``start``, ``t``,
    ``angle``, ``distance``, ``component``, ``demo_angle``, ``demo_distance`` and
    optionally ``success_rate`` / ``goal_reached``). Drawn into ``fig`` (default a new
    figure, sized for the grid), written when ``path`` is given.
    """
    if not runs:
        raise ConfigError("no runs to plot")
    colors = component_colors([name for run in runs for name in run["component"]])
    ncols = max(1, min(ncols, len(runs)))
    nrows = -(-len(runs) // ncols)
    owner = fig if fig is not None else new_figure((4.0 * ncols, 3.6 * nrows + 1.2), layout=None)
    width, height = owner.bbox.width / owner.dpi, owner.bbox.height / owner.dpi
    # Fixed margins (in inches) rather than a layout engine, so that each start's two
    # axes stay glued together while the starts stay apart.
    outer = owner.add_gridspec(
        nrows,
        ncols,
        left=0.7 / width,
        right=1 - 0.15 / width,
        top=1 - 0.75 / height,
        bottom=0.75 / height,
        hspace=0.32,
        wspace=0.3,
    )
    for k, run in enumerate(runs):
        inner = outer[k // ncols, k % ncols].subgridspec(2, 1, hspace=0.06)
        ax_angle = owner.add_subplot(inner[0])
        ax_dist = owner.add_subplot(inner[1], sharex=ax_angle)
        draw_complex_channel(run, "angle", ax=ax_angle, colors=colors)
        draw_complex_channel(run, "distance", ax=ax_dist, colors=colors)
        _min_span(ax_angle, [run["angle"], run["demo_angle"]], 5.0)
        _min_span(ax_dist, [run["distance"], run["demo_distance"]], 0.05)
        ax_angle.tick_params(labelbottom=False)
        ax_angle.set_ylabel("angle (deg)", fontsize=8)
        ax_dist.set_ylabel("distance (m)", fontsize=8)
        start = run["start"]
        text = f"angle {start['angle']:g}°, distance {start['distance']:.2f} m"
        if "success_rate" in run:
            mark = "" if run.get("goal_reached", True) else ", goal missed"
            text += f": success {run['success_rate']:.1f} %{mark}"
        ax_angle.set_title(text, fontsize=9)
        if k + ncols >= len(runs):  # the lowest start of its column
            ax_dist.set_xlabel("time (s)", fontsize=9)
    owner.legend(
        handles=_complex_handles(colors),
        loc="lower center",
        bbox_to_anchor=(0.5, 0.05 / height),
        ncol=len(colors) + 1,
        fontsize=9,
    )
    if title:
        owner.suptitle(title, y=1 - 0.15 / height)
    figure = root_figure(owner)
    if path is not None:
        _save(figure, path)
    return figure
