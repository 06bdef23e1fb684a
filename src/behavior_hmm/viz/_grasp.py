"""Figures, tables and videos of ``experiment grasp`` (issue 28, thesis chapter 5)."""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Final, SupportsFloat

import gymnasium
import numpy as np

from behavior_hmm._atomic import atomic_write_with
from behavior_hmm.evaluate._grasp import COMPOSED, check_targets, gripper_env
from behavior_hmm.viz._reports import write_results_files
from behavior_hmm.viz._traces import _save, new_figure

#: Colour of each component on the paths.
COMPONENT_COLORS: Final[dict[str, str]] = {
    "turn": "tab:blue",
    "approach": "tab:orange",
    "grasp": "tab:green",
    "": "0.6",
}
#: File names of the figures in the output folder.
FIGURES: Final[dict[str, str]] = {
    "paths": "grasp_paths.png",
    "nudged_paths": "grasp_paths_nudged.png",
    "gripper": "grasp_gripper.png",
    "stages": "grasp_stages.png",
}
#: The composed test start filmed (index into the 15 test starts): the object behind.
VIDEO_START: Final[int] = 0


def plot_grasp_paths(runs: Sequence[Mapping[str, Any]], *, title: str) -> Any:
    """Top-down paths (m) of composed runs, one panel each, coloured by component.

    The object rests at the origin (grey circle, 1.5 cm); a cross marks where it ended
    (lifted: green, else red); a dashed arrow marks a nudge's direction.
    """
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle

    n = len(runs)
    cols = min(5, max(1, n))
    rows = math.ceil(n / cols)
    fig = new_figure((2.6 * cols, 2.6 * rows + 0.6))
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    for ax, run in zip(axes, runs, strict=False):
        xy = np.asarray(run["xy"], dtype=np.float64).reshape(-1, 2)
        comp = list(run["component"])
        k = 0
        while k < len(xy):
            j = k
            while j + 1 < len(xy) and comp[j + 1] == comp[k]:
                j += 1
            color = COMPONENT_COLORS.get(comp[k], "0.3")
            ax.plot(xy[k : j + 2, 0], xy[k : j + 2, 1], color=color, lw=1.6)
            k = j + 1
        if len(xy):
            ax.plot(xy[0, 0], xy[0, 1], "o", color="black", ms=3)
        ax.add_patch(Circle((0.0, 0.0), 0.0075, color="0.5", alpha=0.6))
        end = run.get("object_end")
        if end is not None:
            ax.plot(end[0], end[1], "x", color="tab:green" if run["lifted"] else "tab:red", ms=6)
        start = run["start"]
        mark = "lifted" if run["lifted"] else "not lifted"
        ax.set_title(f"{start['angle']:g}°, {start['distance']:g} m: {mark}", fontsize=8)
        ax.set_aspect("equal", adjustable="datalim")
        ax.tick_params(labelsize=6)
        ax.grid(alpha=0.3)
    for ax in axes[n:]:
        ax.set_axis_off()
    handles = [
        Line2D([], [], color=c, lw=2, label=name or "stopped")
        for name, c in COMPONENT_COLORS.items()
    ]
    handles.append(Line2D([], [], color="0.5", marker="o", ls="", label="object (start)"))
    handles.append(Line2D([], [], color="tab:green", marker="x", ls="", label="object (end)"))
    fig.legend(handles=handles, loc="outside lower center", ncols=len(handles), fontsize=8)
    fig.suptitle(title, fontsize=10)
    return fig


def plot_gripper_series(series: Mapping[str, Any], *, title: str) -> Any:
    """Arm angle (deg), finger opening (mm) and object_present over time (s) for one
    grasp: the teacher's demonstration and the learned SBLM's run from the same start."""
    fig = new_figure((7.0, 6.0))
    axes = fig.subplots(3, 1, sharex=True)
    units = {"arm": ("arm (deg)", 1.0), "fingers": ("fingers (mm)", 1000.0)}
    units["object_present"] = ("object present (0/1)", 1.0)
    for ax, (name, (label, scale)) in zip(axes, units.items(), strict=True):
        ax.plot(
            series["teacher_t"],
            np.asarray(series["teacher"][name]) * scale,
            label="teacher",
            color="black",
            lw=1.5,
        )
        ax.plot(
            series["t"],
            np.asarray(series["generated"][name]) * scale,
            label="learned (SBLM)",
            color="tab:green",
            lw=1.5,
            ls="--",
        )
        ax.set_ylabel(label, fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle(title, fontsize=10)
    return fig


def _bar_entries(result: Mapping[str, Any]) -> list[tuple[str, str, int]]:
    """(label, key, row index) of the bar chart's counts."""
    names = result.get("baseline_names", [])
    entries = [
        ("turn\n(goal)", "goal_reached", 0),
        ("approach\n(goal)", "goal_reached", 1),
        ("grasp\n(lifted)", "lifted", 2),
        ("hand-off\nin region", "in_region", 3),
        ("composed\nCBLM lifted", "lifted", 4),
    ]
    for name in names:
        key = name.replace("-", "_")
        entries.append((f"composed\n{name.upper()} lifted", f"{key}_lifted", 4))
    entries += [
        ("nudged\nCBLM lifted", "lifted", 5),
        ("nudged\nteacher lifted", "teacher_lifted", 5),
    ]
    return entries


def plot_stage_bars(result: Mapping[str, Any], *, title: str) -> Any:
    """Per-stage counts (of n starts) and success rates (%), mean and 95 % interval over
    the seeds, each seed's value as a dot."""
    entries = _bar_entries(result)
    summary = result["over_seeds"]
    n = int(result["rows"][0][4]["n"])
    fig = new_figure((11.0, 7.0))
    top, bottom = fig.subplots(2, 1)
    for i, (_, key, j) in enumerate(entries):
        cell = summary[j][key]
        top.bar(
            i,
            cell["mean"],
            yerr=cell["ci95"],
            color="tab:green" if "bc" not in key else "0.6",
            capsize=4,
            alpha=0.8,
        )
        top.plot([i] * len(cell["values"]), cell["values"], "k.", ms=4)
    top.axhline(n, color="black", lw=0.8, ls=":")
    top.set_xticks(range(len(entries)), [e[0] for e in entries], fontsize=8)
    top.set_ylabel(f"of {n} starts")
    top.set_ylim(0, n + 1)
    top.grid(axis="y", alpha=0.3)
    labels: list[str] = []
    rates: list[tuple[str, int, str]] = [
        ("turn", 0, "success"),
        ("approach", 1, "success"),
        ("grasp", 2, "success"),
        ("composed CBLM", 4, "success"),
    ]
    for name in result.get("baseline_names", []):
        rates.append((f"composed {name.upper()}", 4, name.replace("-", "_")))
    rates.append(("nudged CBLM", 5, "success"))
    for i, (label, j, key) in enumerate(rates):
        cell = summary[j][key]
        floor = summary[j]["zero_floor"]
        bottom.bar(
            i - 0.2,
            cell["mean"],
            0.4,
            yerr=cell["ci95"],
            capsize=3,
            color="tab:blue",
            label="success %" if i == 0 else None,
        )
        bottom.bar(
            i + 0.2, floor["mean"], 0.4, color="0.75", label="all-zero floor %" if i == 0 else None
        )
        labels.append(label)
    bottom.set_xticks(range(len(rates)), labels, fontsize=8)
    bottom.set_ylabel("success rate (%)")
    bottom.set_ylim(0, 100)
    bottom.legend(fontsize=8, loc="lower right")
    bottom.grid(axis="y", alpha=0.3)
    fig.suptitle(title, fontsize=10)
    return fig


def _cell(summary: Mapping[str, Any], key: str, spec: str = ".1f") -> str:
    """``mean ± ci (v1, v2, ...)`` of one key over the seeds."""
    cell = summary[key]
    values = ", ".join(format(v, spec) for v in cell["values"])
    if len(cell["values"]) == 1:
        return format(cell["mean"], spec)
    return f"{cell['mean']:{spec}} ± {cell['ci95']:{spec}} ({values})"


def _count(summary: Mapping[str, Any], key: str) -> str:
    return _cell(summary, key, ".3g")


def grasp_table(result: Mapping[str, Any]) -> str:
    """The Markdown tables of :func:`~behavior_hmm.evaluate._grasp.run_grasp_experiment`."""
    preset = result.get("preset", "default")
    seeds = result["seeds"]
    s = result["over_seeds"]
    n = result["rows"][0][4]["n"]
    where = (
        f"{result['env']}, MuJoCo, {preset} preset, seeds {seeds[0]}..{seeds[-1]} "
        f"({len(seeds)}); mean ± 95 % interval (each seed's value)"
    )
    lines = [
        f"Per stage, end to end and nudged ({where}):",
        "",
        "| row | starts | goal reached | lifted (info) | success % | all-zero floor % |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for j in (0, 1, 2, 4, 5):
        row = result["rows"][0][j]
        lifted = _count(s[j], "lifted") if j >= 2 else "—"
        lines.append(
            f"| {row['row']} | {row['n']} | {_count(s[j], 'goal_reached')} | {lifted} | "
            f"{_cell(s[j], 'success')} | {_cell(s[j], 'zero_floor')} |"
        )
    for name in result.get("baseline_names", []):
        key = name.replace("-", "_")
        lines.append(
            f"| turn → approach → grasp ({name.upper()} on the composed data) | {n} | "
            f"{_count(s[4], f'{key}_goal_reached')} | {_count(s[4], f'{key}_lifted')} | "
            f"{_cell(s[4], key)} | {_cell(s[4], 'zero_floor')} |"
        )
    lines.append(f"| nudged: our teacher | {n} | — | {_count(s[5], 'teacher_lifted')} | — | — |")
    h = s[3]
    region = result["handoff_region"]
    lines += [
        "",
        f"Hand-off approach → grasp of the CBLM's composed runs ({where}; goal region "
        f"distance ≤ {region['distance_m']:g} m, |angle| ≤ {region['angle_deg']:g} deg):",
        "",
        "| starts | handed over to grasp | inside the region | lifted, inside | "
        "lifted, outside | teacher inside |",
        "| --- | --- | --- | --- | --- | --- |",
        f"| {n} | {_count(h, 'handed_over')} | {_count(h, 'in_region')} | "
        f"{_count(h, 'lifted_in_region')} | {_count(h, 'lifted_out_of_region')} | "
        f"{_count(h, 'teacher_in_region')} |",
    ]
    targets = check_targets(result)
    lines += [
        "",
        f"Targets (issue 28; lifted of {n}, {where}):",
        "",
        "| target | needed | first seed | per seed | met (first seed) | met (every seed) |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for name, t in targets.items():
        lines.append(
            f"| {name} | ≥ {t['target']} | {t['first_seed']} | "
            f"{', '.join(str(v) for v in t['per_seed'])} | {_yes(t['met_first_seed'])} "
            f"| {_yes(t['met_every_seed'])} |"
        )
    return "\n".join(lines) + "\n"


def _yes(flag: bool) -> str:
    return "yes" if flag else "no"


def write_grasp_report(
    result: Mapping[str, Any], out_dir: str | os.PathLike[str], *, videos: bool = False
) -> str:
    """Write ``results.json``, ``timings.json``, ``table.md``, the figures and (``videos``)
    the training and generated videos into ``out_dir``; return the table.

    Figures (:data:`FIGURES`): the first seed's 15 composed paths and 15 nudged paths,
    one grasp's arm, fingers and object_present (teacher vs learned), and the per-stage
    bar chart with intervals. Videos (MuJoCo offscreen, ``MUJOCO_GL=egl`` or
    ``osmesa``): ``Video_Training_grasp.mp4`` (the teacher's turn → approach → grasp
    from composed test start :data:`VIDEO_START`) and ``Video_Generated_grasp.mp4``
    (the first seed's CBLM from the same start).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    preset = result.get("preset", "default")
    seed = result["seeds"][0]
    where = f"{result['env']}, MuJoCo, {preset} preset, seed {seed}"
    figures = result["_figures"]
    table = grasp_table(result)
    public = {k: v for k, v in result.items() if not k.startswith("_")}
    public["targets_met"] = check_targets(result)
    write_results_files(out, public, table)
    _save(
        plot_grasp_paths(
            figures["composed"],
            title=f"turn → approach → grasp (CBLM) from the test starts\n({where})",
        ),
        out / FIGURES["paths"],
    )
    _save(
        plot_grasp_paths(
            figures["nudged"],
            title=f"object nudged 1-2 cm after the approach, CBLM\n({where})",
        ),
        out / FIGURES["nudged_paths"],
    )
    grasp = figures["grasp"]
    start = grasp["start"]
    _save(
        plot_gripper_series(
            grasp,
            title=f"grasp from {start['angle']:g}°, {start['distance'] * 1000:g} mm: teacher vs "
            f"learned\n({where})",
        ),
        out / FIGURES["gripper"],
    )
    _save(
        plot_stage_bars(
            result,
            title=f"grasp and turn → approach → grasp\n({result['env']}, MuJoCo, {preset} preset, "
            f"{len(result['seeds'])} seeds: mean, 95 % interval, each seed)",
        ),
        out / FIGURES["stages"],
    )
    if videos:
        write_grasp_videos(result["_models"][COMPOSED], out)
    return table


class _Filming(gymnasium.Wrapper[Any, Any, Any, Any]):
    """Renders the gripper env every ``every`` steps and hands each frame to ``sink``."""

    def __init__(
        self, env: Any, renderer: Any, camera: Any, every: int, sink: Callable[[Any], None]
    ) -> None:
        super().__init__(env)
        self._renderer = renderer
        self._camera = camera
        self._every = every
        self._sink = sink
        self._k = 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        self._k = 0
        self._film(info)
        return obs, info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._k += 1
        if self._k % self._every == 0:
            self._film(info)
        return obs, reward, terminated, truncated, info

    def _film(self, info: Mapping[str, Any]) -> None:
        x, y, yaw = info["pose"]
        camera = self._camera
        # from the robot's side, so its body never hides the gripper in front of it
        camera.azimuth = math.degrees(yaw) + 90.0
        camera.lookat[:] = (0.5 * x, 0.5 * y, 0.02)
        camera.distance = max(0.3, 2.0 * math.hypot(x, y))
        self._renderer.update_scene(getattr(self.env.unwrapped, "data"), camera)  # noqa: B009
        self._sink(np.ascontiguousarray(self._renderer.render()))


def write_grasp_videos(
    cblm: Any,
    out_dir: str | os.PathLike[str],
    *,
    start: int = VIDEO_START,
    seed: int = 0,
    size: tuple[int, int] = (480, 480),
) -> dict[str, Path]:
    """The thesis's ``Video_Training_*`` and ``Video_Generated_*`` of turn → approach → grasp.

    The teacher's demonstration and ``cblm``'s run from composed test start ``start``
    (seed ``seed``), rendered by MuJoCo offscreen in the gripper env at real time
    (31.25 frames/s: every second 16 ms step). Raises :class:`ConfigError` when MuJoCo
    cannot make an offscreen OpenGL context (set ``MUJOCO_GL=egl`` or ``osmesa``).
    """
    import mujoco

    from behavior_hmm.teach import Teacher, complete_start, test_starts
    from behavior_hmm.viz._mujoco_video import offscreen_renderer
    from behavior_hmm.viz._video import _import_or_config_error

    ffmpeg = _import_or_config_error("imageio_ffmpeg")
    folder = Path(out_dir)
    row = complete_start(COMPOSED, dict(test_starts(COMPOSED)[start]), math.inf)
    every, fps = 2, 1.0 / 0.032
    written: dict[str, Path] = {}
    for kind in ("Training", "Generated"):
        env = gripper_env()
        renderer = offscreen_renderer(env.unwrapped.model, size, "leave out --videos")
        camera = mujoco.MjvCamera()
        camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        camera.elevation = -30.0
        camera.azimuth = 120.0
        target = folder / f"Video_{kind}_grasp.mp4"

        def film(
            tmp: Path,
            kind: str = kind,
            env: Any = env,
            renderer: Any = renderer,
            camera: Any = camera,
        ) -> None:
            # frames stream into the encoder: a run's ~700 frames are not kept in memory
            last: list[Any] = []
            writer = ffmpeg.write_frames(
                str(tmp),
                size,
                fps=fps,
                codec="libx264",
                pix_fmt_in="rgb24",
                pix_fmt_out="yuv420p",
                quality=None,
                macro_block_size=2,
                output_params=[
                    "-crf",
                    "20",
                    "-preset",
                    "medium",
                    "-movflags",
                    "+faststart",
                    "-f",
                    "mp4",
                ],
            )
            writer.send(None)

            def sink(frame: Any) -> None:
                writer.send(frame)
                last[:] = [frame]

            try:
                filmed = _Filming(env, renderer, camera, every, sink)
                if kind == "Training":
                    Teacher(filmed).demonstrate(COMPOSED, row["angle"], row["distance"], seed=seed)
                else:
                    cblm.generate(filmed, start=row, seed=seed)
                for _ in range(round(fps)):  # hold the last frame a second
                    writer.send(last[0])
            finally:
                writer.close()

        try:
            atomic_write_with(target, film)
        finally:
            renderer.close()
        written[kind] = target
    return written
