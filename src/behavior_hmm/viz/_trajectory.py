"""Top-down trajectories: where the robot went, with its outline every second."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, FancyArrow

from behavior_hmm.viz._traces import _save, new_figure, root_figure, run_title, wrap_title

#: Colour of the object (the target every behavior is defined against).
OBJECT_COLOR = "#c0392b"

#: How the teacher's path is drawn.
TEACHER_PATH: dict[str, Any] = {"color": "k", "ls": "--", "lw": 1.1}


def _own_axes(ax: Axes | None, size: tuple[float, float] = (5.0, 5.0)) -> tuple[Figure, Axes]:
    if ax is not None:
        return root_figure(ax), ax
    fig = new_figure(size)
    return fig, fig.add_subplot()


def replay_pose(
    env: Any,
    start: Mapping[str, float],
    commands: Any,
    *,
    seed: int | None = 0,
) -> np.ndarray:
    """The poses (n, 3) an env goes through from ``start`` under recorded wheel commands.

    Replays, say, the teacher's commands (``reference_demonstration(...)["left"]`` and
    ``["right"]``, or an (n, 2) array) open loop in the env they were recorded in, with the
    same ``seed``: in a deterministic simulator this is the teacher's own path, for
    :func:`plot_trajectory`'s ``reference_pose``. Row ``k`` is the pose at step ``k``
    (before its command), as in a trace. Empty if the env reports no pose.
    """
    from behavior_hmm.runtime import Robot

    if isinstance(commands, Mapping):
        commands = np.column_stack([commands["left"], commands["right"]])
    commands = np.asarray(commands, dtype=np.float64).reshape(-1, 2)
    options = {k: float(v) for k, v in start.items() if k in ("angle", "distance")}
    robot = Robot(env)
    _, _, pose = robot.reset(seed=seed, options=options)
    poses = []
    for command in commands:
        if pose is None:
            return np.zeros((0, 3))
        poses.append(np.asarray(pose, dtype=np.float64))
        _, _, pose = robot.step(command)
    return np.asarray(poses, dtype=np.float64).reshape(-1, 3)


def _pose_rows(poses: Any) -> np.ndarray:
    """An (n, 3) pose array from an array, a trace (``pose_array``) or x / y / yaw columns."""
    if hasattr(poses, "pose_array"):
        return np.asarray(poses.pose_array, dtype=np.float64).reshape(-1, 3)
    if isinstance(poses, Mapping):
        yaw = poses.get("yaw", np.zeros(len(poses["x"])))
        return np.column_stack([poses["x"], poses["y"], yaw]).astype(np.float64)
    return np.asarray(poses, dtype=np.float64).reshape(-1, 3)


Limits = tuple[tuple[float, float], tuple[float, float]]


def _scene_limits(paths: Sequence[np.ndarray], radius: float, object_radius: float) -> Limits:
    """x and y limits (m) around the object, the paths and the robot's outlines."""
    xy = np.concatenate([np.zeros((1, 2)), *(p[:, :2] for p in paths if len(p))])
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    margin = max(radius, object_radius) + 0.08 * float(np.max(hi - lo))
    lo, hi = lo - margin, hi + margin
    # never a sliver: each side at least a third of the other
    extent = hi - lo
    need = np.maximum(extent, extent[::-1] / 3.0)
    mid = 0.5 * (lo + hi)
    return (
        (float(mid[0] - need[0] / 2), float(mid[0] + need[0] / 2)),
        (float(mid[1] - need[1] / 2), float(mid[1] + need[1] / 2)),
    )


def _scene_size(limits: Limits | None) -> tuple[float, float]:
    """Figure size (in) that shows ``limits`` at equal scale, with room for the labels."""
    if limits is None:
        return (5.0, 5.0)
    (x0, x1), (y0, y1) = limits
    scale = 5.5 / max(x1 - x0, y1 - y0)
    return (max((x1 - x0) * scale, 3.0) + 1.2, max((y1 - y0) * scale, 1.6) + 1.7)


def _set_limits(ax: Axes, limits: Limits | None) -> None:
    if limits is None:  # the caller's axes: keep the data in view at equal scale
        ax.set_aspect("equal", adjustable="datalim")
        return
    ax.set_xlim(*limits[0])
    ax.set_ylim(*limits[1])
    ax.set_aspect("equal", adjustable="box")


def plot_trajectory(
    trace: Any,
    ax: Axes | None = None,
    *,
    reference_pose: Any = None,
    body_radius: float | None = None,
    object_radius: float | None = None,
    every_s: float = 1.0,
    color: str = "C0",
    label: str | None = None,
    title: str | None = None,
    legend: bool | None = None,
    path: str | os.PathLike[str] | None = None,
) -> Figure:
    """Draw one run's x–y path (m) with the robot's outline and heading every ``every_s``.

    The object sits at the origin; outlines grow darker with time, the start is marked
    with a cross.

    Parameters
    ----------
    trace
        A :class:`~behavior_hmm.runtime.Trace` with poses (``trace.pose``; envs that report
        ``info["pose"]``).
    ax
        Axes to draw into; default a new figure.
    reference_pose
        The teacher's path from the same start, drawn dashed: an (m, 3) array (see
        :func:`replay_pose`), x / y columns, or a trace with poses.
    body_radius, object_radius
        Sizes (m) of the robot outline and the object at the origin; default from the
        path's scale.
    label
        Legend label of the path (default ``"model"``).
    title
        Axes title; default (on a figure of its own) the start, goal and outcome; ``""``
        for none.
    legend
        Draw a legend; default on a figure of its own or with a teacher's path.
    path
        File to write (atomically), or None to only draw.

    Returns
    -------
    Figure
        The figure drawn (the root figure of ``ax`` when given).
    """
    own = ax is None
    pose = np.asarray(trace.pose_array, dtype=np.float64)
    if not len(pose):
        raise ValueError("the trace has no poses (its env reports no info['pose'])")
    t = np.asarray(trace.t, dtype=np.float64)[: len(pose)]
    span = float(np.ptp(pose[:, :2], axis=0).max()) if len(pose) > 1 else 0.0
    reach = float(np.hypot(pose[0, 0], pose[0, 1]))
    radius = body_radius or max(0.03 * max(span, reach), 1e-3)
    ref = None if reference_pose is None else _pose_rows(reference_pose)
    limits = None
    if own:  # a figure shaped like the scene: the object, the path and the outlines
        paths = [pose] if ref is None else [pose, ref]
        limits = _scene_limits(paths, radius, object_radius or radius * 0.6)
    fig, ax = _own_axes(ax, _scene_size(limits))
    if ref is not None and len(ref):
        ax.plot(ref[:, 0], ref[:, 1], zorder=2, **TEACHER_PATH)
    ax.plot(pose[:, 0], pose[:, 1], color=color, lw=1.6, zorder=2.5, label=label)
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
    ax.plot(*pose[0, :2], marker="x", color=color, ms=7, mew=1.5, ls="", zorder=4)
    ax.add_patch(Circle((0.0, 0.0), object_radius or radius * 0.6, color=OBJECT_COLOR, zorder=3))
    _set_limits(ax, limits)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(alpha=0.3)
    has_ref = ref is not None and len(ref) > 0
    if legend or (legend is None and (own or has_ref)):
        every = f"every {every_s:g} s" if math.isfinite(every_s) else "at start and end"
        handles = [Line2D([], [], color=color, lw=1.6, label=label or "model")]
        if has_ref:
            handles.append(Line2D([], [], label="teacher", **TEACHER_PATH))
        handles += [
            Line2D([], [], color=color, marker="x", ls="", ms=7, mew=1.5, label="start"),
            Line2D(
                [], [], color=color, marker="o", mfc="none", ls="", ms=9, label=f"robot {every}"
            ),
            Line2D([], [], color=OBJECT_COLOR, marker="o", ls="", ms=9, label="object"),
        ]
        if own:  # under the axes, off the path
            fig.legend(
                handles=handles,
                loc="outside lower center",
                ncol=len(handles) if fig.get_figwidth() > 6.0 else 3,
                fontsize=8,
                frameon=False,
            )
        else:
            ax.legend(handles=handles, loc="best", fontsize=8)
    if title is None and own:
        title = run_title(trace)
    if title:
        width = ax.get_position().width * fig.get_figwidth()
        ax.set_title(wrap_title(title, width, 10.0), fontsize=10)
    if path is not None:
        _save(fig, path)
    return fig


def plot_trajectories(
    runs: Sequence[tuple[Any, bool]],
    ax: Axes | None = None,
    *,
    body_radius: float | None = None,
    object_radius: float | None = None,
    every_s: float = math.inf,
    title: str | None = None,
    path: str | os.PathLike[str] | None = None,
) -> Figure:
    """Overlay several runs ``(trace, goal_reached)``: green reached the goal, red did not.

    Each run shows its path and the robot's outline at the start and the end (and every
    ``every_s`` seconds, when given). Draws into ``ax`` (default a new figure), writes
    ``path`` when given, and returns the figure.
    """
    own = ax is None
    drawn = [(trace, bool(reached)) for trace, reached in runs if len(trace.pose)]
    limits = None
    if own and drawn:
        paths = [np.asarray(trace.pose_array, dtype=np.float64) for trace, _ in drawn]
        radius = body_radius or 0.03 * float(np.abs(np.concatenate(paths)[:, :2]).max())
        limits = _scene_limits(paths, radius, object_radius or radius * 0.6)
    fig, ax = _own_axes(ax, _scene_size(limits))
    for trace, reached in drawn:
        plot_trajectory(
            trace,
            ax,
            body_radius=body_radius,
            object_radius=object_radius,
            every_s=every_s,
            color="tab:green" if reached else "tab:red",
            legend=False,
            title="",
        )
    if own:
        _set_limits(ax, limits)
        outcomes = {reached for _, reached in drawn}
        handles = [
            Line2D([], [], color=c, lw=1.6, label=f"goal {word} ({sum(r == ok for _, r in drawn)})")
            for ok, c, word in ((True, "tab:green", "reached"), (False, "tab:red", "missed"))
            if ok in outcomes
        ]
        handles.append(Line2D([], [], color=OBJECT_COLOR, marker="o", ls="", ms=9, label="object"))
        fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8)
    if title:
        ax.set_title(title)
    if path is not None:
        _save(fig, path)
    return fig
