"""Plots of generated runs: one run in detail, and generated-vs-demonstrated overlays."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from behavior_hmm._atomic import atomic_write_with
from behavior_hmm._paths import plot_format
from behavior_hmm.data import CONTROL_PERIOD, SENSOR_CHANNELS, UNITS


def _save(fig: Figure, path: str | os.PathLike[str], dpi: int = 120) -> Path:
    target = Path(path)
    fmt = plot_format(target)  # the format the extension names (checked by the CLI)
    atomic_write_with(target, lambda tmp: fig.savefig(tmp, format=fmt, dpi=dpi))
    return target


def run_series(trace: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (n,), readings (n, 4) and commands (n, 2) of a run, all of one length.

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
        commands = np.zeros((len(t), 2))
    return t, readings, commands


def plot_trace(
    trace: Any,
    path: str | os.PathLike[str],
    reference: np.ndarray | None = None,
    title: str | None = None,
) -> Path:
    """Plot one generated run: goal channels, wheel commands and the active state.

    Parameters
    ----------
    trace
        A :class:`~behavior_hmm.runtime.Trace`.
    path
        PNG file to write (atomically).
    reference
        Optional demonstrated commands (n, 2) from the same start, drawn dashed.
    """
    t, readings, commands = run_series(trace)
    marker = "o" if len(t) == 1 else None  # a one-step run is a point, not a line
    channels = [c for c in ("angle", "distance") if c in trace.goal] or ["angle", "distance"]
    fig = Figure(figsize=(8, 2.2 * (len(channels) + 2)), layout="constrained")
    axes = fig.subplots(len(channels) + 2, 1, sharex=True)
    for ax, name in zip(axes, channels, strict=False):
        ax.plot(t, readings[:, SENSOR_CHANNELS.index(name)], marker=marker, label="generated")
        if name in trace.goal:
            ax.axhline(trace.goal[name], color="k", lw=0.8, ls=":", label="goal")
        ax.set_ylabel(f"{name} ({UNITS[name]})")
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    ax = axes[len(channels)]
    ax.plot(t, commands[:, 0], marker=marker, label="left")
    ax.plot(t, commands[:, 1], marker=marker, label="right")
    if reference is not None:
        tr = np.arange(len(reference)) * CONTROL_PERIOD
        ax.plot(tr, reference[:, 0], "C0--", lw=1, label="left (demo)")
        ax.plot(tr, reference[:, 1], "C1--", lw=1, label="right (demo)")
    ax.set_ylabel("wheel command (rad/s)")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8, ncol=2)
    ax = axes[-1]
    if len(trace.state) == len(t):  # a refused run has no active state
        ax.step(t, trace.state, where="post", lw=1, marker=marker)
    ax.set_ylabel("active state")
    ax.set_xlabel("time (s)")
    ax.grid(alpha=0.3)
    outcome = "goal reached" if trace.goal_reached else f"failed ({trace.reason})"
    fig.suptitle(title or f"start {trace.start} -> goal {trace.goal}: {outcome}")
    return _save(fig, path)


def plot_generated_vs_demonstrated(
    runs: Sequence[tuple[str, np.ndarray, np.ndarray]],
    channel: str,
    path: str | os.PathLike[str],
    title: str,
) -> Path:
    """Overlay generated and demonstrated time series of one channel (thesis figs 6.8-6.10).

    Parameters
    ----------
    runs
        ``(label, generated, demonstrated)`` per start; each series sampled every 16 ms.
    channel
        Channel name, for the axis label.
    """
    fig = Figure(figsize=(8, 4.5), layout="constrained")
    ax = fig.subplots()
    for i, (label, gen, demo) in enumerate(runs):
        color = f"C{i % 10}"
        ax.plot(np.arange(len(demo)) * CONTROL_PERIOD, demo, color=color, ls="--", lw=1.2)
        ax.plot(np.arange(len(gen)) * CONTROL_PERIOD, gen, color=color, lw=1.6, label=label)
    ax.plot([], [], "k--", lw=1.2, label="demonstrated (dashed)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(f"{channel} ({UNITS[channel]})")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title)
    return _save(fig, path)


def plot_complex_run(run: dict[str, Any], path: str | os.PathLike[str]) -> Path:
    """Angle and distance of a complex run against the demonstration (thesis fig 6.10).

    The generated run is coloured by the active component (as in the appendix B.3 grid,
    :func:`~behavior_hmm.viz.plot_complex_grid`), over a light band of the same colour.
    """
    from behavior_hmm.viz._grids import _complex_handles, component_colors, draw_complex_channel

    t = np.asarray(run["t"])
    fig = Figure(figsize=(8, 5.5), layout="constrained")
    axes = fig.subplots(2, 1, sharex=True)
    comp = list(run["component"])
    colors = component_colors(comp)
    for ax, channel in zip(axes, ("angle", "distance"), strict=True):
        draw_complex_channel(run, channel, ax=ax, colors=colors, fontsize=10)
        start = 0
        for k in range(1, len(comp) + 1):
            if k == len(comp) or comp[k] != comp[start]:
                if comp[start]:
                    ax.axvspan(t[start], t[k - 1], color=colors[comp[start]], alpha=0.08, lw=0)
                start = k
        ax.set_ylabel(f"{channel} ({UNITS[channel]})")
    axes[0].legend(handles=_complex_handles(colors), loc="best", fontsize=8)
    axes[1].set_xlabel("time (s)")
    begin = run["start"]
    text = f"angle {begin['angle']:g}°, distance {begin['distance']:.2f} m"
    score = f" (success {run['success_rate']:.1f} %)" if "success_rate" in run else ""
    fig.suptitle(f"turn & approach from {text}{score}")
    return _save(fig, path)
