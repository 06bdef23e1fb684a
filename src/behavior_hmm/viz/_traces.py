"""Plots of generated runs: one run in detail, and generated-vs-demonstrated overlays.

Every plot function draws with matplotlib's object API (never pyplot), into the axes
or figure it is given or a new figure, returns the :class:`~matplotlib.figure.Figure`
and, when given a ``path``, also writes it there (atomically).
"""

from __future__ import annotations

import os
import re
import textwrap
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure, SubFigure

from behavior_hmm._atomic import atomic_write_with
from behavior_hmm._paths import plot_format
from behavior_hmm.data import CONTROL_PERIOD, SENSOR_CHANNELS, UNITS
from behavior_hmm.errors import ConfigError

#: How the teacher's run is drawn wherever it is overlaid on a generated one.
TEACHER_STYLE: dict[str, Any] = {"color": "k", "ls": "--", "lw": 1.2}

#: Light colours of the active primitive / component bands (black text reads on them).
BAND_COLORS = colormaps["Set3"]


def _save(fig: Figure, path: str | os.PathLike[str], dpi: int = 120) -> Path:
    target = Path(path)
    fmt = plot_format(target)  # the format the extension names (checked by the CLI)
    atomic_write_with(target, lambda tmp: fig.savefig(tmp, format=fmt, dpi=dpi))
    return target


def new_figure(
    figsize: tuple[float, float], *, layout: Literal["constrained"] | None = "constrained"
) -> Figure:
    """A figure of its own (no pyplot), with an Agg canvas so it can be drawn at once."""
    fig = Figure(figsize=figsize, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def root_figure(owner: Axes | Figure | SubFigure) -> Figure:
    """The top-level figure that axes or a (sub)figure belong to."""
    node: Any = owner.get_figure() if isinstance(owner, Axes) else owner
    while isinstance(node, SubFigure):
        node = node.figure
    if not isinstance(node, Figure):
        raise ConfigError("the axes belong to no figure")
    return node


def value_text(name: str, value: float) -> str:
    """A channel value with its unit: ``"120°"``, ``"0.50 m"``, ``"0.1 m/s"``."""
    unit = UNITS.get(name, "")
    if unit == "deg":
        return f"{value:.3g}°" if abs(value) < 1 else f"{value:.0f}°"
    if unit == "m":
        return f"{value:.2f} m"
    return f"{value:.3g} {unit}".rstrip()


def values_text(values: Mapping[str, float]) -> str:
    """``{"angle": 120, "distance": 0.5}`` -> ``"angle 120°, distance 0.50 m"``."""
    return ", ".join(f"{k.replace('_', ' ')} {value_text(k, v)}" for k, v in values.items())


def outcome_text(trace: Any) -> str:
    """``"goal reached in 3.97 s"``, ``"goal not reached (step limit)"``, ..."""
    duration = float(trace.t[-1]) if len(trace.t) else 0.0
    if trace.goal_reached:
        return f"goal reached in {duration:.2f} s"
    reason = str(trace.reason or "stopped").replace("_", " ")
    faults = list(getattr(trace, "fault_channels", []) or [])
    if faults:
        reason += f" on {', '.join(faults)}"
    return f"goal not reached ({reason})"


def run_title(trace: Any, behavior: str | None = None) -> str:
    """``"turn from angle 120°, distance 0.50 m → goal angle 0°: goal reached in 4.0 s"``."""
    head = f"{behavior} from " if behavior else "from "
    goal = values_text(trace.goal) if trace.goal else "no goal"
    return f"{head}{values_text(trace.start)} → goal {goal}: {outcome_text(trace)}"


def run_series(trace: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (n,), readings (n, 4) and commands (n, k) of a run, all of one length.

    Readings are in ``SENSOR_CHANNELS`` order whatever the robot's channel order (NaN
    for a channel the robot does not have). A run refused before any motion (an
    unreachable goal) records one step and no reading: its reading is then the final
    observation (where it stood), or NaN.
    """
    t = np.asarray(trace.t, dtype=np.float64)
    names = list(getattr(trace, "channels", SENSOR_CHANNELS))
    raw = trace.reading_array
    if len(raw) != len(t):
        final = getattr(trace, "final_observation", None)
        row = np.full(len(names), np.nan) if final is None else np.asarray(final)
        raw = np.tile(row, (len(t), 1))
    readings = np.full((len(t), len(SENSOR_CHANNELS)), np.nan)
    for j, name in enumerate(SENSOR_CHANNELS):
        if name in names:
            readings[:, j] = raw[:, names.index(name)]
    commands = trace.command_array
    if len(commands) != len(t):
        commands = np.zeros((len(t), commands.shape[1]))
    return t, readings, commands


def channel_series(trace: Any, name: str) -> np.ndarray:
    """One channel of a run, one value per step (``trace.channel``); a run refused before
    any motion stood still at its final observation (NaN where there is none)."""
    n = len(trace.t)
    names = list(getattr(trace, "channels", SENSOR_CHANNELS))
    if name in names and len(trace.readings) == n:
        return np.asarray(trace.channel(name), dtype=np.float64)
    final = getattr(trace, "final_observation", None)
    if name in names and final is not None:
        return np.full(n, float(np.asarray(final)[names.index(name)]))
    return np.full(n, np.nan)


def _reference_columns(reference: Any) -> dict[str, np.ndarray]:
    """The teacher's run as columns: a demo's columns dict or an (n, 2) commands array."""
    if reference is None:
        return {}
    if isinstance(reference, Mapping):
        cols = {str(k): np.asarray(v) for k, v in reference.items()}
    else:
        commands = np.asarray(reference, dtype=np.float64)
        if commands.ndim != 2 or commands.shape[1] != 2:
            raise ConfigError(
                "reference must be the demonstration's columns or its (n, 2) commands, "
                f"got an array of shape {commands.shape}"
            )
        cols = {"left": commands[:, 0], "right": commands[:, 1]}
    n = max((len(v) for v in cols.values()), default=0)
    if "t" not in cols:
        cols["t"] = np.arange(n) * CONTROL_PERIOD
    return cols


def segments(labels: Sequence[Any]) -> list[tuple[int, int, Any]]:
    """Runs of equal labels: ``(first, stop, label)`` with ``stop`` exclusive."""
    out: list[tuple[int, int, Any]] = []
    start = 0
    for k in range(1, len(labels) + 1):
        if k == len(labels) or labels[k] != labels[start]:
            out.append((start, k, labels[start]))
            start = k
    return out


def active_names(trace: Any) -> list[str]:
    """Name of what is active at each step: the component (CBLM) or ``"primitive k"``."""
    states = list(trace.state)
    components = list(getattr(trace, "component", []) or [])
    if len(components) == len(states) and any(components):
        return [c or "none" for c in components]
    return [f"primitive {int(s)}" for s in states]


def draw_active_band(
    ax: Axes,
    rows: Sequence[tuple[str, np.ndarray, Sequence[str]]],
    *,
    colors: Mapping[str, Any] | None = None,
    alpha: float = 1.0,
    fontsize: float = 7.5,
) -> dict[str, Any]:
    """Coloured bands naming what is active over time, one row per ``(label, t, names)``.

    Each run of one name is a band in that name's colour with the name written in it
    (shortened to its number, or left out, where the band is too narrow). ``colors``
    fixes the colour of some names (drawn at ``alpha``); the others get light colours.
    Returns the colours by name.
    """
    colors = dict(colors or {})
    for _, _, names in rows:
        for name in dict.fromkeys(names):
            colors.setdefault(name, BAND_COLORS(len(colors) % BAND_COLORS.N))
    t_all = np.concatenate([np.asarray(t, dtype=float) for _, t, _ in rows] + [np.zeros(1)])
    lo, hi = float(t_all.min()), float(t_all.max()) + CONTROL_PERIOD
    fig = root_figure(ax)
    width_in = ax.get_position().width * fig.get_figwidth()
    per_char = fontsize * 0.6 / 72.0 / max(width_in, 1e-6) * (hi - lo)  # seconds per char
    for row, (_, t, names) in enumerate(rows):
        t = np.asarray(t, dtype=float)
        y = len(rows) - 1 - row
        bands = []
        for a, b, name in segments(list(names)):
            x0 = t[a]
            x1 = t[b] if b < len(t) else t[-1] + CONTROL_PERIOD
            ax.broken_barh(
                [(x0, x1 - x0)],
                (y + 0.1, 0.8),
                facecolors=to_rgba(colors[name], alpha),
                edgecolors="0.35",
                lw=0.5,
            )
            bands.append((x0, x1, name))
        # every band of a row written the same way: full names if they all fit, else
        # primitives by their number (the row's label says they are primitives)
        full = all(len(name) * per_char < 0.92 * (x1 - x0) for x0, x1, name in bands)
        for x0, x1, name in bands:
            text = name if full else name.removeprefix("primitive ")
            if len(text) * per_char < 0.92 * (x1 - x0):
                ax.text(0.5 * (x0 + x1), y + 0.5, text, ha="center", va="center", fontsize=fontsize)
    ax.set_ylim(0, len(rows))
    ax.set_yticks([len(rows) - 0.5 - k for k in range(len(rows))], [r[0] for r in rows])
    ax.tick_params(axis="y", length=0, labelsize=8.5)
    ax.grid(alpha=0.3, axis="x")
    return colors


def _panel_axes(
    n_panels: int,
    ratios: Sequence[float],
    fig: Figure | SubFigure | None,
    axes: Sequence[Axes] | None,
    figsize: tuple[float, float],
) -> tuple[Figure | SubFigure | None, list[Axes]]:
    """``n_panels`` stacked axes sharing x: the given ones, or new ones in ``fig``.

    Also returns the (sub)figure that is the plot's own, for its title: None when the
    caller gave the axes (the title then goes over the first of them).
    """
    if axes is not None:
        given = list(np.ravel(np.asarray(axes, dtype=object)))
        if len(given) != n_panels:
            raise ConfigError(f"this plot draws {n_panels} panels, got {len(given)} axes")
        return None, given
    owner = fig if fig is not None else new_figure(figsize)
    made = owner.subplots(
        n_panels, 1, sharex=True, squeeze=False, gridspec_kw={"height_ratios": list(ratios)}
    )
    return owner, list(made[:, 0])


def wrap_title(text: str, width_in: float, fontsize: float = 11.0) -> str:
    """``text`` broken into lines that fit ``width_in`` inches, where it can between its
    parts (before ``" → "``, after ``": "``), else between words."""
    chars = max(int(width_in * 72.0 * 0.95 / (fontsize * 0.55)), 20)
    if len(text) <= chars or "\n" in text:
        return text
    lines: list[str] = []
    for part in re.split(r"(?<=:) | (?=→ )", text):
        if lines and len(lines[-1]) + 1 + len(part) <= chars:
            lines[-1] += " " + part
        else:
            lines.extend(textwrap.wrap(part, chars) or [part])
    return "\n".join(lines)


def _set_title(owner: Figure | SubFigure | None, panels: Sequence[Axes], text: str) -> None:
    if owner is None:
        width = panels[0].get_position().width * root_figure(panels[0]).get_figwidth()
        panels[0].set_title(wrap_title(text, width, 10.0), fontsize=10)
    else:
        owner.suptitle(wrap_title(text, owner.bbox.width / owner.dpi), fontsize=11)


def plot_trace(
    trace: Any,
    path: str | os.PathLike[str] | None = None,
    reference: Mapping[str, Any] | np.ndarray | None = None,
    title: str | None = None,
    *,
    behavior: str | None = None,
    fig: Figure | SubFigure | None = None,
    axes: Sequence[Axes] | None = None,
) -> Figure:
    """Plot one generated run: its goal channels, wheel commands and what was active.

    Panels, top to bottom: each goal channel (the goal dotted), the wheel commands, and
    a band naming the active motion primitive (SBLM, ``"primitive k"``) or component
    (CBLM, ``"turn"``, ``"approach"``) over time; a CBLM run with the teacher's
    demonstration also shows the teacher's phases under it.

    Parameters
    ----------
    trace
        A :class:`~behavior_hmm.runtime.Trace`.
    path
        File to write (atomically; format from the extension), or None to only draw.
    reference
        The teacher's demonstration from the same start, drawn dashed: its columns
        (``reference_demonstration``'s dict: ``angle``, ``distance``, ``left``,
        ``right``, optionally ``t`` and ``behavior``) or just its (n, 2) commands.
    title
        Figure title; default: start, goal and outcome in plain words.
    behavior
        Name of the behavior, for the default title.
    fig, axes
        Draw into this figure (or subfigure), or into these ``n_goal_channels + 2``
        axes; default a new figure.

    Returns
    -------
    Figure
        The figure drawn (the root figure of ``fig`` / ``axes`` when given).
    """
    t, _, commands = run_series(trace)
    demo = _reference_columns(reference)
    marker = "o" if len(t) == 1 else None  # a one-step run is a point, not a line
    own = list(getattr(trace, "channels", SENSOR_CHANNELS))
    channels = [c for c in trace.goal if c in own] or [c for c in ("angle", "distance") if c in own]
    specs = getattr(trace, "channel_specs", None) or {}
    rows: list[tuple[str, np.ndarray, Sequence[str]]] = []
    if len(trace.state) == len(t) and len(t):  # a refused run has no active state
        names = active_names(trace)
        if any(getattr(trace, "component", []) or []):
            rows = [("active\ncomponent", t, names)]
            if "behavior" in demo and len(demo["behavior"]):
                phases = [str(b) for b in demo["behavior"]]
                rows.append(("teacher's\nphase", demo["t"], phases))
        else:
            rows = [("active\nprimitive", t, names)]
    band = 0.75 * max(len(rows), 1) + 0.25
    ratios = [3.0] * (len(channels) + 1) + [band]
    owner, panels = _panel_axes(
        len(channels) + 2, ratios, fig, axes, (8.0, 2.1 * (len(channels) + 1) + 0.7 + 0.7 * band)
    )
    for ax, name in zip(panels, channels, strict=False):
        unit = specs[name].unit if name in specs else UNITS.get(name, "")
        ax.plot(t, channel_series(trace, name), marker=marker, lw=1.6, label="model")
        if name in demo:
            ax.plot(demo["t"], demo[name], label="teacher", **TEACHER_STYLE)
        if name in trace.goal:
            ax.axhline(trace.goal[name], color="tab:green", lw=1.0, ls=":", label="goal")
        ax.set_ylabel(f"{name.replace('_', ' ')} ({unit})" if unit else name)
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    ax = panels[len(channels)]
    names = list(getattr(trace, "command_channels", ("left", "right")))
    style = {**TEACHER_STYLE, "lw": 1.0}
    for j, name in enumerate(names):
        color = f"C{j % 10}"
        ax.plot(t, commands[:, j], color=color, marker=marker, lw=1.4, label=f"{name} (model)")
        if name in demo:
            ax.plot(demo["t"], demo[name], label=f"{name} (teacher)", **{**style, "color": color})
    ax.axhline(0.0, color="0.3", lw=0.6)
    units = {specs[name].unit if name in specs else UNITS.get(name, "") for name in names}
    wheels = names == ["left", "right"]
    unit = units.pop() if len(units) == 1 else ""
    ax.set_ylabel("wheel speed (rad/s)" if wheels else f"command ({unit})" if unit else "command")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8, ncol=2)
    ax = panels[-1]
    if rows:
        draw_active_band(ax, rows)
    else:  # a run refused before any motion has no active state
        ax.set_yticks([])
        reason = str(trace.reason or "no steps").replace("_", " ")
        ax.text(0.5, 0.5, f"nothing ran ({reason})", transform=ax.transAxes, ha="center")
    ax.set_xlabel("time (s)")
    _set_title(owner, panels, title if title is not None else run_title(trace, behavior))
    figure = root_figure(panels[0])
    if path is not None:
        _save(figure, path)
    return figure


def plot_generated_vs_demonstrated(
    runs: Sequence[tuple[str, np.ndarray, np.ndarray]],
    channel: str,
    path: str | os.PathLike[str] | None = None,
    title: str | None = None,
    *,
    ax: Axes | None = None,
) -> Figure:
    """Overlay generated and demonstrated time series of one channel (thesis figs 6.8-6.10).

    Parameters
    ----------
    runs
        ``(label, generated, demonstrated)`` per start; each series sampled every 16 ms.
    channel
        Channel name, for the axis label.
    path
        File to write, or None to only draw.
    ax
        Axes to draw into; default a new figure.
    """
    if ax is None:
        ax = new_figure((8, 4.5)).add_subplot()
    fig = root_figure(ax)
    for i, (label, gen, demo) in enumerate(runs):
        color = f"C{i % 10}"
        ax.plot(np.arange(len(demo)) * CONTROL_PERIOD, demo, color=color, ls="--", lw=1.2)
        ax.plot(np.arange(len(gen)) * CONTROL_PERIOD, gen, color=color, lw=1.6, label=label)
    ax.plot([], [], "k--", lw=1.2, label="teacher (dashed)")
    unit = UNITS.get(channel, "")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"{channel.replace('_', ' ')} ({unit})" if unit else channel)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    if title:
        ax.set_title(title)
    if path is not None:
        _save(fig, path)
    return fig


def plot_complex_run(
    run: Mapping[str, Any],
    path: str | os.PathLike[str] | None = None,
    *,
    fig: Figure | SubFigure | None = None,
    axes: Sequence[Axes] | None = None,
    title: str | None = None,
) -> Figure:
    """Angle and distance of a complex run against the demonstration (thesis fig 6.10).

    The generated run is coloured by the active component (as in the appendix B.3 grid,
    :func:`~behavior_hmm.viz.plot_complex_grid`), over a light band of the same colour;
    a third, narrow panel names the active component over time, and the teacher's phases
    under it when the run has them (``demo_behavior``).

    Parameters
    ----------
    run
        A ``figure`` entry of ``run_complex_experiment`` (``start``, ``t``, ``angle``,
        ``distance``, ``component``, ``demo_angle``, ``demo_distance``, optionally
        ``demo_behavior`` and ``success_rate``).
    path
        File to write, or None to only draw.
    fig, axes
        Draw into this figure (or subfigure) or into these three axes; default a new one.
    """
    from behavior_hmm.viz._grids import _complex_handles, component_colors, draw_complex_channel

    t = np.asarray(run["t"], dtype=float)
    teacher = [str(b) for b in run.get("demo_behavior", [])]
    band = 1.75 if teacher else 1.0
    owner, panels = _panel_axes(3, (3.0, 3.0, band), fig, axes, (8, 5.5 + 0.7 * band))
    comp = [str(c) for c in run["component"]]
    colors = component_colors(comp)
    for ax, channel in zip(panels, ("angle", "distance"), strict=False):
        draw_complex_channel(run, channel, ax=ax, colors=colors, fontsize=10)
        for a, b, name in segments(comp):
            if name:
                x1 = t[b] if b < len(t) else t[-1]
                ax.axvspan(t[a], x1, color=colors[name], alpha=0.08, lw=0)
        ax.set_ylabel(f"{channel} ({UNITS[channel]})")
    panels[0].legend(handles=_complex_handles(colors), loc="best", fontsize=8)
    rows: list[tuple[str, np.ndarray, Sequence[str]]] = [
        ("active\ncomponent", t, [c or "none" for c in comp])
    ]
    if teacher:
        rows.append(("teacher's\nphase", np.arange(len(teacher)) * CONTROL_PERIOD, teacher))
    draw_active_band(panels[2], rows, colors=colors, alpha=0.35)
    panels[2].set_xlabel("time (s)")
    if title is None:
        begin = run["start"]
        text = f"angle {begin['angle']:g}°, distance {begin['distance']:.2f} m"
        score = f" (success {run['success_rate']:.1f} %)" if "success_rate" in run else ""
        title = f"turn & approach from {text}{score}"
    _set_title(owner, panels, title)
    figure = root_figure(panels[0])
    if path is not None:
        _save(figure, path)
    return figure
