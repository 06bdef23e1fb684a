"""Top-down trajectories: where the robot went, with its outline every second."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Circle, FancyArrow

#: Colour of the object (the target every behavior is defined against).
OBJECT_COLOR = "#c0392b"


def _own_axes(ax: Axes | None, size: tuple[float, float] = (5.0, 5.0)) -> tuple[Figure, Axes]:
    if ax is not None:
        return ax.figure, ax  # type: ignore[return-value]
    fig = Figure(figsize=size, layout="constrained")
    return fig, fig.add_subplot()


def plot_trajectory(
    trace: Any,
    ax: Axes | None = None,
    *,
    reference_pose: np.ndarray | None = None,
    body_radius: float | None = None,
    object_radius: float | None = None,
    every_s: float = 1.0,
    color: str = "C0",
    label: str | None = None,
    title: str | None = None,
) -> Figure:
    """Draw one run's x–y path (m) with the robot's outline and heading every ``every_s``.

    Parameters
    ----------
    trace
        A :class:`~behavior_hmm.runtime.Trace` with poses (``trace.pose``; envs that report
        ``info["pose"]``).
    ax
        Axes to draw into; default a new figure.
    reference_pose
        (m, 3) the teacher's path from the same start, drawn dashed.
    body_radius, object_radius
        Sizes (m) of the robot outline and the object at the origin; default from the
        path's scale.
    """
    fig, ax = _own_axes(ax)
    pose = np.asarray(trace.pose_array, dtype=np.float64)
    if not len(pose):
        raise ValueError("the trace has no poses (its env reports no info['pose'])")
    t = np.asarray(trace.t, dtype=np.float64)[: len(pose)]
    span = float(np.ptp(pose[:, :2], axis=0).max()) if len(pose) > 1 else 0.0
    reach = float(np.hypot(pose[0, 0], pose[0, 1]))
    radius = body_radius or max(0.03 * max(span, reach), 1e-3)
    if reference_pose is not None and len(reference_pose):
        ref = np.asarray(reference_pose, dtype=np.float64)
        ax.plot(ref[:, 0], ref[:, 1], color="0.45", ls="--", lw=1.0, label="teacher")
    ax.plot(pose[:, 0], pose[:, 1], color=color, lw=1.6, label=label)
    stride = every_s if math.isfinite(every_s) else max(float(t[-1]), 1e-9) * 2.0
    marks = np.unique(np.searchsorted(t, np.arange(0.0, t[-1] + 1e-9, stride)))
    marks = np.union1d(marks, [len(pose) - 1])
    for k in marks:
        x, y, yaw = pose[int(k)]
        alpha = 0.25 + 0.75 * (k / max(len(pose) - 1, 1))
        ax.add_patch(Circle((x, y), radius, fill=False, ec=color, lw=1.0, alpha=alpha))
        ax.add_patch(
            FancyArrow(
                x,
                y,
                radius * math.cos(yaw),
                radius * math.sin(yaw),
                width=radius * 0.08,
                head_width=radius * 0.35,
                head_length=radius * 0.35,
                length_includes_head=True,
                color=color,
                alpha=alpha,
            )
        )
    ax.plot(*pose[0, :2], marker="x", color=color, ms=6)
    ax.add_patch(Circle((0.0, 0.0), object_radius or radius * 0.6, color=OBJECT_COLOR, zorder=3))
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(alpha=0.3)
    if title:
        ax.set_title(title)
    return fig


def plot_trajectories(
    runs: Sequence[tuple[Any, bool]],
    ax: Axes | None = None,
    *,
    body_radius: float | None = None,
    object_radius: float | None = None,
    every_s: float = math.inf,
    title: str | None = None,
) -> Figure:
    """Overlay several runs ``(trace, goal_reached)``: green reached the goal, red did not.

    Each run shows its path and the robot's outline at the start and the end (and every
    ``every_s`` seconds, when given).
    """
    fig, ax = _own_axes(ax)
    for trace, reached in runs:
        if not len(trace.pose):
            continue
        plot_trajectory(
            trace,
            ax,
            body_radius=body_radius,
            object_radius=object_radius,
            every_s=every_s,
            color="tab:green" if reached else "tab:red",
        )
    if title:
        ax.set_title(title)
    return fig
