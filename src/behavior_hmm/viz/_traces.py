"""Plots of generated runs: one run in detail, and generated-vs-demonstrated overlays."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from behavior_hmm._atomic import atomic_write_with
from behavior_hmm.data import CONTROL_PERIOD, SENSOR_CHANNELS, UNITS


def _save(fig: Figure, path: str | os.PathLike[str], dpi: int = 120) -> Path:
    target = Path(path)
    atomic_write_with(target, lambda tmp: fig.savefig(tmp, format="png", dpi=dpi))
    return target


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
    t = np.asarray(trace.t)
    readings = trace.reading_array
    commands = trace.command_array
    channels = [c for c in ("angle", "distance") if c in trace.goal] or ["angle", "distance"]
    fig = Figure(figsize=(8, 2.2 * (len(channels) + 2)), layout="constrained")
    axes = fig.subplots(len(channels) + 2, 1, sharex=True)
    for ax, name in zip(axes, channels, strict=False):
        ax.plot(t, readings[:, SENSOR_CHANNELS.index(name)], label="generated")
        if name in trace.goal:
            ax.axhline(trace.goal[name], color="k", lw=0.8, ls=":", label="goal")
        ax.set_ylabel(f"{name} ({UNITS[name]})")
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    ax = axes[len(channels)]
    ax.plot(t, commands[:, 0], label="left")
    ax.plot(t, commands[:, 1], label="right")
    if reference is not None:
        tr = np.arange(len(reference)) * CONTROL_PERIOD
        ax.plot(tr, reference[:, 0], "C0--", lw=1, label="left (demo)")
        ax.plot(tr, reference[:, 1], "C1--", lw=1, label="right (demo)")
    ax.set_ylabel("wheel command (rad/s)")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8, ncol=2)
    ax = axes[-1]
    ax.step(t, trace.state, where="post", lw=1)
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

    The background shows which component was active (generated run).
    """
    t = np.asarray(run["t"])
    fig = Figure(figsize=(8, 5.5), layout="constrained")
    axes = fig.subplots(2, 1, sharex=True)
    names = list(dict.fromkeys(n for n in run["component"] if n))
    colors = {name: f"C{i + 2}" for i, name in enumerate(names)}
    comp = list(run["component"])
    for ax, channel in zip(axes, ("angle", "distance"), strict=True):
        demo = np.asarray(run[f"demo_{channel}"])
        ax.plot(np.arange(len(demo)) * CONTROL_PERIOD, demo, "k--", lw=1.2, label="demonstrated")
        ax.plot(t, run[channel], lw=1.8, label="generated")
        start = 0
        for k in range(1, len(comp) + 1):
            if k == len(comp) or comp[k] != comp[start]:
                if comp[start]:
                    ax.axvspan(t[start], t[k - 1], color=colors[comp[start]], alpha=0.12, lw=0)
                start = k
        ax.set_ylabel(f"{channel} ({UNITS[channel]})")
        ax.grid(alpha=0.3)
    for name, color in colors.items():
        axes[0].plot([], [], color=color, alpha=0.4, lw=8, label=f"{name} active")
    axes[0].legend(loc="best", fontsize=8)
    axes[1].set_xlabel("time (s)")
    start_text = ", ".join(f"{k} {v:g}" for k, v in run["start"].items())
    fig.suptitle(f"turn & approach from {start_text}: generated vs demonstrated")
    return _save(fig, path)
