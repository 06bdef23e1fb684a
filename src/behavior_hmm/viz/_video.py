"""Top-down videos of a rollout: robot, fading trail, object, teacher path and a text box.

:func:`render_rollout` draws one matplotlib figure (Agg, no pyplot) and updates its moving
artists frame by frame over a cached background (blitting), then writes an MP4 (libx264,
yuv420p, through imageio-ffmpeg) or a looping GIF (Pillow), atomically. imageio,
imageio-ffmpeg and Pillow are the ``video`` extra and are imported only when needed.
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import PathCollection
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle
from matplotlib.path import Path as Path2D
from numpy.typing import ArrayLike

from behavior_hmm._atomic import atomic_write_with
from behavior_hmm.errors import ConfigError

__all__ = [
    "frame_grid",
    "frame_times",
    "goal_text",
    "render_frame",
    "render_rollout",
    "render_trace",
    "trace_labels",
]

#: The message when imageio, imageio-ffmpeg or Pillow is missing.
VIDEO_EXTRA_MESSAGE = "writing videos needs the video extra: pip install 'behavior-hmm[video]'"
#: Video formats, by file suffix.
VIDEO_SUFFIXES = (".mp4", ".gif")
#: How long the last frame is held, in seconds of video.
HOLD_S = 0.5
#: Age (s of the run) over which the trail's alpha falls by a factor e.
TRAIL_FADE_S = 2.0
_TRAIL_ALPHA = (0.08, 0.95)  # oldest floor, newest
_LABEL_COLOURS = ("C0", "C1", "C2", "C4", "C5", "C6", "C8", "C9", "C3", "C7")
_DEG = "\N{DEGREE SIGN}"
_MAX_FRAMES = 100_000


def _import_or_config_error(name: str) -> Any:
    import importlib

    try:
        return importlib.import_module(name)
    except ImportError:
        raise ConfigError(VIDEO_EXTRA_MESSAGE) from None


def _video_format(path: str | os.PathLike[str]) -> str:
    suffix = Path(path).suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        raise ConfigError(
            f"video file must end in .mp4 or .gif, not {suffix or 'no suffix'!r}: {path}"
        )
    return suffix[1:]


def frame_times(t: ArrayLike, fps: float = 25.0, speed: float = 1.0) -> np.ndarray:
    """Indices into ``t`` shown by the frames of a video (before the final hold).

    Frame ``k`` shows the last sample at or before ``t[0] + k / fps * speed``; the last
    sample is always shown (an extra frame when the grid misses it).
    """
    times = _as_times(t)
    _positive(fps=fps, speed=speed)
    step = speed / fps
    span = float(times[-1] - times[0])
    n = math.floor(span / step + 1e-9) + 1
    if n > _MAX_FRAMES:
        raise ConfigError(
            f"{n} video frames ({span:g} s at fps={fps:g}, speed={speed:g}); "
            f"at most {_MAX_FRAMES}: raise speed or lower fps"
        )
    grid = times[0] + np.arange(n) * step
    idx = np.searchsorted(times, grid + 1e-9 * max(1.0, step), side="right") - 1
    idx = np.clip(idx, 0, len(times) - 1)
    if idx[-1] != len(times) - 1:
        idx = np.append(idx, len(times) - 1)
    return idx


def _as_times(t: ArrayLike) -> np.ndarray:
    times = np.asarray(t, dtype=np.float64)
    if times.ndim != 1 or len(times) == 0:
        raise ConfigError(f"t must be a non-empty 1-D array, got shape {times.shape}")
    if not np.all(np.isfinite(times)):
        raise ConfigError("t must be finite")
    if np.any(np.diff(times) < 0):
        raise ConfigError("t must be non-decreasing")
    return times


def _as_pose(pose: ArrayLike, name: str) -> np.ndarray:
    arr = np.asarray(pose, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3 or len(arr) == 0:
        raise ConfigError(f"{name} must have shape (n, 3) (x m, y m, yaw rad), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(f"{name} must be finite")
    return arr


def _positive(**values: float) -> None:
    for name, value in values.items():
        if not (math.isfinite(value) and value > 0):
            raise ConfigError(f"{name} must be a positive number, got {value!r}")


def _nice_length(span: float) -> float:
    """A round length (1, 2 or 5 times a power of ten) near a fifth of ``span``."""
    raw = max(span / 5.0, 1e-9)
    power = 10.0 ** math.floor(math.log10(raw))
    return max(m * power for m in (1.0, 2.0, 5.0) if m * power <= raw)


def _length_text(metres: float) -> str:
    if metres >= 1.0:
        return f"{metres:g} m"
    if metres >= 0.01:
        return f"{metres * 100:g} cm"
    return f"{metres * 1000:g} mm"


def goal_text(goal: Mapping[str, float] | None) -> str:
    """``"goal: angle 0°, distance 0.01 m"`` (angles in degrees, distances in metres)."""
    if not goal:
        return ""
    from behavior_hmm.data import UNITS

    parts = []
    for name, value in goal.items():
        unit = UNITS.get(name, "")
        value = float(value) + 0.0  # no "-0"
        if unit == "deg":
            parts.append(f"{name} {value:.3g}{_DEG}")
        else:
            parts.append(f"{name} {value:.3g}{' ' + unit if unit else ''}")
    return "goal: " + ", ".join(parts)


@dataclass
class _Run:
    t: np.ndarray
    pose: np.ndarray
    labels: list[str] | None
    goal: Mapping[str, float] | None
    object_xy: tuple[float, float]
    object_radius: float
    body_radius: float
    teacher_pose: np.ndarray | None
    title: str


class _Scene:
    """One figure; :meth:`frame` redraws only the moving artists over a cached background.

    ``shown`` are the sample indices that frames will show; the trail is cut into pieces
    at those indices (and where the label changes), so each frame draws whole pieces.
    """

    def __init__(self, run: _Run, shown: np.ndarray, *, dpi: int, size_in: float) -> None:
        self.run = run
        r = run.body_radius
        xy = [run.pose[:, :2] - r, run.pose[:, :2] + r]
        ox, oy = run.object_xy
        ro = run.object_radius
        xy.append(np.array([[ox - ro, oy - ro], [ox + ro, oy + ro]]))
        if run.teacher_pose is not None:
            xy += [run.teacher_pose[:, :2] - r, run.teacher_pose[:, :2] + r]
        pts = np.vstack(xy)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        span = float(max(hi - lo))
        half = span / 2 + max(0.6 * r, 0.06 * span)
        centre = (lo + hi) / 2

        # layout, in points (1/72 in): fonts and margins scale with the figure's width
        fs = max(6.0, 9.0 * size_in / 5.0)
        width = max(2 * round(size_in * dpi / 2), 64)
        w_pt = width / dpi * 72
        left, right, bottom = 5.6 * fs, 1.6 * fs, 3.6 * fs
        side = w_pt - left - right
        goal_line = goal_text(run.goal)
        n_lines = 1 + (run.labels is not None) + bool(goal_line)
        legend_rows = 3 + (run.teacher_pose is not None)
        box_h = max(n_lines * 1.35 * fs + 0.9 * fs, legend_rows * 1.25 * fs * 0.8 + 0.4 * fs)
        title_h = 1.9 * fs if run.title else 0.0
        h_pt = bottom + side + 1.0 * fs + box_h + title_h + 0.6 * fs
        height = 2 * round(h_pt / 72 * dpi / 2)
        h_pt = height / dpi * 72
        self.size = (width, height)

        fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
        self.canvas = FigureCanvasAgg(fig)
        self.fig = fig
        ax = fig.add_axes((left / w_pt, bottom / h_pt, side / w_pt, side / h_pt))
        self.ax = ax
        ax.set_xlim(centre[0] - half, centre[0] + half)
        ax.set_ylim(centre[1] - half, centre[1] + half)
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel("x (m)", fontsize=fs, labelpad=2)
        ax.set_ylabel("y (m)", fontsize=fs, labelpad=2)
        ax.tick_params(labelsize=fs * 0.85)
        ax.grid(alpha=0.25, lw=0.6)
        ax.set_facecolor("#fbfbf8")

        lw = max(1.0, 1.6 * size_in / 5.0)
        ax.add_patch(Circle(run.object_xy, ro, fc="#d62728", ec="#7f1010", lw=lw * 0.6, zorder=3))
        x0, y0 = run.pose[0, :2]
        ax.plot([x0], [y0], marker="x", ms=fs * 0.8, color="0.35", mew=lw * 0.8, zorder=2)
        handles: list[Any] = [
            Line2D([], [], marker="o", ls="", color="C0", mec="k", ms=fs * 0.8, label="robot"),
            Line2D([], [], marker="o", ls="", color="#d62728", ms=fs * 0.7, label="object"),
            Line2D([], [], marker="x", ls="", color="0.35", ms=fs * 0.7, label="start"),
        ]
        if run.teacher_pose is not None:
            (teacher,) = ax.plot(
                run.teacher_pose[:, 0],
                run.teacher_pose[:, 1],
                ls="--",
                lw=lw,
                color="0.45",
                alpha=0.55,
                zorder=1,
                label="teacher",
            )
            handles.append(teacher)
        scale = _nice_length(2 * half)
        sx = centre[0] + half - 0.05 * half - scale
        sy = centre[1] - half + 0.07 * half
        ax.plot([sx, sx + scale], [sy, sy], color="k", lw=lw * 1.5, solid_capstyle="butt")
        ax.text(
            sx + scale / 2,
            sy + 0.025 * half,
            _length_text(scale),
            ha="center",
            va="bottom",
            fontsize=fs * 0.85,
        )

        # the trail: pieces between shown samples and label changes, one colour each
        names = list(dict.fromkeys(run.labels)) if run.labels is not None else []
        self.colour = {n: _LABEL_COLOURS[k % len(_LABEL_COLOURS)] for k, n in enumerate(names)}
        cuts = set(np.asarray(shown, dtype=int).tolist()) | {0, len(run.t) - 1}
        if run.labels is not None:
            cuts |= {k - 1 for k in range(1, len(run.labels)) if run.labels[k] != run.labels[k - 1]}
        ends = np.array(sorted(cuts), dtype=int)
        p = run.pose[:, :2]
        self.piece_end = ends[1:]
        self.piece_paths = [Path2D(p[a : b + 1]) for a, b in itertools.pairwise(ends)]
        self.piece_rgba = np.array(
            [
                to_rgba(self.colour[run.labels[b]] if run.labels is not None else "C0")
                for b in self.piece_end
            ]
        ).reshape(-1, 4)
        self.trail = PathCollection(
            [],
            facecolors="none",
            linewidths=lw * 1.6,
            capstyle="round",
            joinstyle="round",
            zorder=2,
            animated=True,
        )
        ax.add_collection(self.trail, autolim=False)
        self.body = Circle((x0, y0), r, lw=lw, ec="k", zorder=4, animated=True)
        ax.add_patch(self.body)
        (self.heading,) = ax.plot(
            [], [], color="k", lw=lw * 1.3, solid_capstyle="round", zorder=5, animated=True
        )

        # header: title; a text box (time, label, goal); the legend on the right.
        # The box and the goal are static; time and label are drawn over it each frame,
        # in a monospace font so the blank lines of the static text reserve their width.
        top = 1.0 - 0.6 * fs / h_pt
        if run.title:
            fig.text(0.5, top, run.title, ha="center", va="top", fontsize=fs * 1.1, weight="bold")
            top -= title_h / h_pt
        time_width = len(f"t = {run.t[-1]:.2f} s")
        label_width = max((len(f"active: {n}") for n in names), default=0)
        static = [" " * time_width] + ([" " * label_width] if run.labels is not None else [])
        text_style: dict[str, Any] = {
            "ha": "left",
            "va": "top",
            "fontsize": fs,
            "family": "DejaVu Sans Mono",
            "linespacing": 1.35,
        }
        box_x = left / w_pt
        box_y = top - 0.45 * fs / h_pt
        fig.text(
            box_x,
            box_y,
            "\n".join([*static, goal_line] if goal_line else static),
            bbox={"boxstyle": "round,pad=0.4", "fc": "white", "ec": "0.6", "lw": 0.8},
            **text_style,
        )
        self.info = fig.text(box_x, box_y, "", animated=True, **text_style)
        fig.legend(
            handles=handles,
            loc="upper right",
            bbox_to_anchor=(1.0 - right / w_pt, top),
            fontsize=fs * 0.8,
            ncol=1,
            frameon=False,
            handlelength=1.4,
            borderaxespad=0.0,
            labelspacing=0.25,
        )
        self.background: Any = None

    def info_text(self, i: int) -> str:
        run = self.run
        lines = [f"t = {run.t[i]:.2f} s"]
        if run.labels is not None:
            lines.append(f"active: {run.labels[i]}")
        return "\n".join(lines)

    def frame(self, i: int) -> np.ndarray:
        """The RGB image (height, width, 3) showing sample ``i`` (one of ``shown``)."""
        if self.background is None:
            self.canvas.draw()
            self.background = self.canvas.copy_from_bbox(self.fig.bbox)
        run = self.run
        x, y, yaw = run.pose[i]
        r = run.body_radius
        colour = self.colour.get(run.labels[i], "C0") if run.labels is not None else "C0"

        count = int(np.searchsorted(self.piece_end, i, side="right"))
        ages = run.t[i] - run.t[self.piece_end[:count]]
        lo, hi = _TRAIL_ALPHA
        rgba = self.piece_rgba[:count].copy()
        rgba[:, 3] = lo + (hi - lo) * np.exp(-ages / TRAIL_FADE_S)
        self.trail.set_paths(self.piece_paths[:count])
        self.trail.set_edgecolor(cast(Any, rgba))  # an (n, 4) array is fine
        self.body.center = (x, y)
        self.body.set_facecolor(to_rgba(colour, 0.55))
        self.heading.set_data([x, x + 1.15 * r * math.cos(yaw)], [y, y + 1.15 * r * math.sin(yaw)])
        self.info.set_text(self.info_text(i))

        self.canvas.restore_region(self.background)
        for artist in (self.trail, self.body, self.heading):
            self.ax.draw_artist(artist)
        self.fig.draw_artist(self.info)
        buf = np.asarray(self.canvas.buffer_rgba())
        w, h = self.size
        return np.ascontiguousarray(buf[:h, :w, :3])


def _make_run(
    t: ArrayLike,
    pose: ArrayLike,
    labels: Sequence[str] | None,
    goal: Mapping[str, float] | None,
    object_xy: tuple[float, float],
    object_radius: float,
    body_radius: float,
    teacher_pose: ArrayLike | None,
    title: str,
) -> _Run:
    times = _as_times(t)
    poses = _as_pose(pose, "pose")
    if len(poses) != len(times):
        raise ConfigError(f"pose has {len(poses)} rows but t has {len(times)}")
    names = None
    if labels is not None:
        names = [str(label) for label in labels]
        if len(names) != len(times):
            raise ConfigError(f"labels has {len(names)} entries but t has {len(times)}")
    teacher = _as_pose(teacher_pose, "teacher_pose") if teacher_pose is not None else None
    _positive(object_radius=object_radius, body_radius=body_radius)
    ox, oy = (float(v) for v in object_xy)
    if not (math.isfinite(ox) and math.isfinite(oy)):
        raise ConfigError(f"object_xy must be finite, got {object_xy!r}")
    return _Run(
        times, poses, names, goal, (ox, oy), object_radius, body_radius, teacher, str(title)
    )


def render_frame(
    at: float,
    *,
    t: ArrayLike,
    pose: ArrayLike,
    labels: Sequence[str] | None = None,
    goal: Mapping[str, float] | None = None,
    object_xy: tuple[float, float] = (0.0, 0.0),
    object_radius: float = 0.02,
    body_radius: float = 0.035,
    teacher_pose: ArrayLike | None = None,
    title: str = "",
    dpi: int = 100,
    size_in: float = 5.0,
) -> np.ndarray:
    """One frame as an RGB array (height, width, 3): the last state at or before ``at`` s.

    Takes the drawing arguments of :func:`render_rollout`; needs no video extra.
    """
    run = _make_run(
        t, pose, labels, goal, object_xy, object_radius, body_radius, teacher_pose, title
    )
    _positive(dpi=dpi, size_in=size_in)
    i = int(np.clip(np.searchsorted(run.t, at + 1e-12, side="right") - 1, 0, len(run.t) - 1))
    return _Scene(run, np.array([i]), dpi=int(dpi), size_in=size_in).frame(i)


def render_rollout(
    path: str | os.PathLike[str],
    *,
    t: ArrayLike,
    pose: ArrayLike,
    labels: Sequence[str] | None = None,
    goal: Mapping[str, float] | None = None,
    object_xy: tuple[float, float] = (0.0, 0.0),
    object_radius: float = 0.02,
    body_radius: float = 0.035,
    teacher_pose: ArrayLike | None = None,
    title: str = "",
    fps: float = 25.0,
    speed: float = 1.0,
    dpi: int = 100,
    size_in: float = 5.0,
) -> Path:
    """Write a top-down video of a rollout to ``path`` (.mp4 or .gif) and return it.

    Parameters
    ----------
    path
        ``.mp4`` (H.264, yuv420p) or ``.gif`` (loops forever); written atomically.
    t
        Times (n,) in s.
    pose
        (n, 3): x (m), y (m), yaw (rad) of the robot's centre and heading.
    labels
        Active primitive or component name per step (n,), shown and used as colour.
    goal
        Goal of the run, shown as text, e.g. ``{"angle": 0.0, "distance": 0.01}``
        (angle in degrees, distance in metres).
    object_xy, object_radius
        The object (m), drawn as a filled circle.
    body_radius
        The robot's radius (m); line widths and margins scale from it.
    teacher_pose
        (m, 3) the teacher's path from the same start, drawn faint and dashed.
    title
        Shown above the view.
    fps, speed
        Video frames per second and playback speed versus real time: frame ``k``
        shows the state at ``t[0] + k / fps * speed``; the last state is always shown and
        held for about 0.5 s.
    dpi, size_in
        Resolution and width of the frame (``size_in * dpi`` pixels wide, made even).

    Raises
    ------
    ConfigError
        A suffix other than .mp4/.gif, inconsistent arrays, or the video extra missing.
    """
    target = Path(path)
    fmt = _video_format(target)
    run = _make_run(
        t, pose, labels, goal, object_xy, object_radius, body_radius, teacher_pose, title
    )
    _positive(fps=fps, speed=speed, dpi=dpi, size_in=size_in)
    if fmt == "mp4":
        ffmpeg = _import_or_config_error("imageio_ffmpeg")
    else:
        pil_image = _import_or_config_error("PIL.Image")

    indices = frame_times(run.t, fps, speed)
    scene = _Scene(run, indices, dpi=int(dpi), size_in=size_in)
    hold = max(1, round(HOLD_S * fps))

    def frames() -> Iterator[np.ndarray]:
        for i in indices:
            yield scene.frame(int(i))

    if fmt == "mp4":

        def write(tmp: Path) -> None:
            _write_mp4(ffmpeg, tmp, frames(), scene.size, fps, hold)

    else:

        def write(tmp: Path) -> None:
            # the palette: frames spread over the run, and each label's first frame
            picks = set(np.linspace(0, len(indices) - 1, 8).round().astype(int).tolist())
            if run.labels is not None:
                shown = [run.labels[int(i)] for i in indices]
                picks |= {shown.index(name) for name in list(dict.fromkeys(shown))[:8]}
            samples = [scene.frame(int(indices[k])) for k in sorted(picks)]
            _write_gif(pil_image, tmp, frames(), samples, len(indices), fps, hold)

    atomic_write_with(target, write)
    return target


def _write_mp4(
    ffmpeg: Any,
    tmp: Path,
    frames: Iterator[np.ndarray],
    size: tuple[int, int],
    fps: float,
    hold: int,
) -> None:
    writer = ffmpeg.write_frames(
        str(tmp),
        size,
        fps=float(fps),
        codec="libx264",
        pix_fmt_in="rgb24",
        pix_fmt_out="yuv420p",
        quality=None,
        macro_block_size=2,
        output_params=["-crf", "20", "-preset", "medium", "-movflags", "+faststart", "-f", "mp4"],
    )
    writer.send(None)
    try:
        last = None
        for frame in frames:
            writer.send(frame)
            last = frame
        for _ in range(hold):
            writer.send(last)
    finally:
        writer.close()


def _write_gif(
    pil_image: Any,
    tmp: Path,
    frames: Iterator[np.ndarray],
    samples: Sequence[np.ndarray],
    count: int,
    fps: float,
    hold: int,
) -> None:
    """A looping GIF with one palette (taken from ``samples``) and frame-to-frame deltas."""
    # GIF times frames in centiseconds: round the running time, not each frame
    ends_cs = np.round(np.arange(1, count + hold + 1) * 100.0 / fps).astype(int)
    cs = np.diff(ends_cs, prepend=0)
    durations = [10 * int(c) for c in cs[:count]]
    durations[-1] += 10 * int(cs[count:].sum())
    palette = pil_image.fromarray(np.concatenate(list(samples))).quantize(
        256, method=pil_image.Quantize.FASTOCTREE, dither=pil_image.Dither.NONE
    )
    images = (
        pil_image.fromarray(frame).quantize(palette=palette, dither=pil_image.Dither.NONE)
        for frame in frames
    )
    first = next(images)
    first.save(
        tmp,
        format="GIF",
        save_all=True,
        append_images=images,
        duration=durations,
        loop=0,
        optimize=True,
    )


def frame_grid(
    path_in_video: str | os.PathLike[str], out_png: str | os.PathLike[str], n: int = 6
) -> Path:
    """Save ``n`` evenly spaced frames of a video (first and last included) as a PNG grid."""
    if n < 1:
        raise ConfigError(f"n must be at least 1, got {n}")
    if Path(out_png).suffix.lower() != ".png":
        raise ConfigError(f"frame grid must be a .png file: {out_png}")
    _video_format(path_in_video)
    iio = _import_or_config_error("imageio.v3")
    pil_image = _import_or_config_error("PIL.Image")
    source = Path(path_in_video)
    if not source.is_file():
        raise ConfigError(f"no such video: {source}")
    count = sum(1 for _ in iio.imiter(source))
    if count == 0:
        raise ConfigError(f"video has no frames: {source}")
    wanted = sorted(set(np.linspace(0, count - 1, min(n, count)).round().astype(int).tolist()))
    picked: list[np.ndarray] = []
    for k, frame in enumerate(iio.imiter(source)):
        if k in wanted:
            picked.append(np.asarray(frame)[..., :3])
    rows = max(1, math.isqrt(len(picked)))
    cols = -(-len(picked) // rows)
    h, w = picked[0].shape[:2]
    gap = max(2, w // 80)
    grid = np.full((rows * h + (rows - 1) * gap, cols * w + (cols - 1) * gap, 3), 255, np.uint8)
    for k, frame in enumerate(picked):
        r, c = divmod(k, cols)
        grid[r * (h + gap) : r * (h + gap) + h, c * (w + gap) : c * (w + gap) + w] = frame[:h, :w]
    target = Path(out_png)
    atomic_write_with(target, lambda tmp: pil_image.fromarray(grid).save(tmp, format="PNG"))
    return target


def trace_labels(trace: Any) -> list[str]:
    """The active primitive (an SBLM: ``primitive k``) or component (a CBLM) per step."""
    out = []
    for component, state in zip(trace.component, trace.state, strict=False):
        out.append(component or (f"primitive {state}" if state >= 0 else ""))
    return out


def render_trace(
    trace: Any,
    path: str | os.PathLike[str],
    *,
    robot: Any = None,
    teacher_pose: ArrayLike | None = None,
    title: str = "",
    fps: float = 25.0,
    speed: float = 1.0,
) -> Path:
    """The top-down video of one run (``trace.pose``), sized from the robot's env.

    ``robot`` is the env the run came from: its ``unwrapped.body_radius`` and
    ``object_radius`` (m) size the drawing when it has them.
    """
    pose = trace.pose_array
    if not len(pose):
        raise ConfigError("this run has no poses (the env reports no info['pose']): no video")
    base = getattr(robot, "unwrapped", robot)
    body = getattr(base, "body_radius", None)
    if body is None:
        spec = getattr(base, "robot_spec", None) or {}
        track = spec.get("track_width") if isinstance(spec, Mapping) else None
        body = 0.6 * float(track) if track else 0.035
    radius = getattr(base, "object_radius", None) or body * 0.6
    n = len(pose)
    return render_rollout(
        path,
        t=np.asarray(trace.t, dtype=np.float64)[:n],
        pose=pose,
        labels=trace_labels(trace)[:n],
        goal=dict(trace.goal),
        object_radius=float(radius),
        body_radius=float(body),
        teacher_pose=teacher_pose,
        title=title,
        fps=fps,
        speed=speed,
    )
