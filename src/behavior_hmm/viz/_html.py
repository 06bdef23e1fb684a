"""A self-contained HTML evaluation report that explains itself.

The page defines every score it shows, lists every case with its start and goal in
physical units, and plots every run (the steered channels and the wheel commands,
generated against the teacher's demonstration from the same start, and the active
primitive or component by name) as small PNGs embedded as data URIs. Videos of the
runs, when given, are linked (relative to the report's folder), not embedded. The page
has no script and loads nothing from outside.
"""

from __future__ import annotations

import base64
import html
import io
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any
from urllib.parse import quote

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from behavior_hmm._atomic import atomic_write_bytes
from behavior_hmm.data import CHANNELS, CONTROL_PERIOD
from behavior_hmm.data._channels import TOLERANCES
from behavior_hmm.errors import ConfigError

#: Resolution of the embedded run figures (dots per inch): small pages, legible plots.
RUN_FIGURE_DPI = 80
#: Width of one run figure (inches); its height grows with the steered channels.
RUN_FIGURE_WIDTH = 6.4
#: Video files a report links as ``<video>`` and as ``<img>``.
VIDEO_SUFFIXES = (".mp4", ".webm")
IMAGE_SUFFIXES = (".gif", ".png", ".webp")

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em 2em; color: #222; max-width: 1180px; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; } h2 { font-size: 1.2em; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.88em; }
th, td { border: 1px solid #ccc; padding: 3px 7px; text-align: right; }
th { background: #f3f3f3; } td.l, th.l { text-align: left; } td.nw { white-space: nowrap; }
.fail { color: #b00; font-weight: bold; } .note { color: #555; font-size: 0.9em; }
.warn { color: #8a5a00; background: #fff6e0; padding: 0.4em 0.6em; }
dl.defs { display: grid; grid-template-columns: max-content 1fr; gap: 0.25em 1em;
  font-size: 0.9em; margin: 0.5em 0; }
dl.defs dt { font-weight: bold; } dl.defs dd { margin: 0; }
.runs { display: flex; flex-wrap: wrap; gap: 0.8em; }
.run { border: 1px solid #ddd; border-radius: 4px; padding: 0.4em 0.6em; width: min-content; }
.run h3 { font-size: 0.88em; font-weight: normal; margin: 0.1em 0 0.3em; }
.run .media { display: flex; gap: 0.6em; align-items: flex-start; }
.run img, .run video { border: 1px solid #eee; display: block; }
.run .video a { font-size: 0.8em; }
"""


def format_values(values: Mapping[str, float] | None) -> str:
    """A start or goal in physical units: ``"120°, 0.50 m"``.

    The bearing reads in degrees and the distance to the object in metres; any other
    channel is named, with its unit (``"linear_velocity 0.10 m/s"``).
    """
    if not values:
        return "–"
    parts = []
    for name, value in values.items():
        v = float(value)
        if name == "angle":
            parts.append(f"{_fixed(v, 0)}°")
        elif name == "distance":
            parts.append(f"{_fixed(v, 2)} m")
        else:
            spec = CHANNELS.get(name)
            unit = f" {spec.unit}" if spec is not None else ""
            parts.append(f"{name} {_fixed(v, 2)}{unit}")
    return ", ".join(parts)


def _fixed(v: float, decimals: int) -> str:
    """``v`` with at least ``decimals`` decimals and up to 3 more where they matter."""
    if not math.isfinite(v):
        return str(v)
    for d in range(decimals, decimals + 4):
        if abs(round(v, d) - v) < 1e-9 * max(1.0, abs(v)):
            break
    text = f"{v:.{d}f}"
    return "0" if decimals == 0 and text in ("-0", "0") else text.replace("-0.00", "0.00")


def _png(fig: Figure) -> tuple[str, int, int]:
    """A figure as a base64 PNG (palette-quantized: a quarter of the size), width, height."""
    from PIL import Image

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    rgba = np.asarray(canvas.buffer_rgba())
    image = Image.fromarray(rgba[..., :3]).quantize(colors=64, dither=Image.Dither.NONE)
    buf = io.BytesIO()
    image.save(buf, format="png", optimize=True)
    return base64.b64encode(buf.getvalue()).decode("ascii"), image.width, image.height


def _series(trace: Any, name: str) -> np.ndarray:
    """One channel of a run, one value per step (a refused run: where it stood; else NaN)."""
    n = len(trace.t)
    channels = list(getattr(trace, "channels", []))
    if name in channels and len(trace.readings) == n:
        return np.asarray(trace.channel(name), dtype=np.float64)
    final = getattr(trace, "final_observation", None)
    if name in channels and final is not None:
        return np.full(n, float(final[channels.index(name)]))
    return np.full(n, np.nan)


def _active(trace: Any, kind: str) -> tuple[list[str], str]:
    """The active primitive (SBLM, ``"P3"``) or component (CBLM) by name at each step."""
    n = len(trace.t)
    components = [str(c) for c in getattr(trace, "component", [])]
    if len(components) == n and any(components):
        return components, "component"
    what = "component" if kind == "CBLM" else "primitive"
    states = [int(s) for s in getattr(trace, "state", [])]
    if len(states) != n:  # refused before any motion: nothing was active
        return [""] * n, what
    return [f"P{s}" if s >= 0 else "" for s in states], what


def _timeline(
    ax: Any, t: np.ndarray, labels: list[str], what: str, colours: dict[str, int]
) -> None:
    """The active primitive or component as a band of named, coloured segments.

    ``colours`` (label -> palette index) is shared by every run of a page, so a
    component keeps its colour; a primitive ``"P<k>"`` is coloured by ``k``.
    """
    from matplotlib import colormaps

    ax.set_yticks([])
    ax.set_ylim(0, 1)
    ax.set_ylabel(what)
    ax.grid(alpha=0.3, axis="x")
    if not any(labels):
        ax.text(
            0.5,
            0.5,
            f"no {what} active",
            transform=ax.transAxes,
            ha="center",
            va="center",
            fontsize=7.5,
        )
        return
    palette = colormaps["tab20"]
    span = max(float(t[-1] - t[0]), CONTROL_PERIOD)
    k = 0
    while k < len(labels):
        j = k
        while j + 1 < len(labels) and labels[j + 1] == labels[k]:
            j += 1
        label = labels[k]
        if label:
            number = label[1:]
            index = (
                int(number)
                if label[0] == "P" and number.isdigit()
                else colours.setdefault(label, len(colours))
            )
            begin = float(t[k])
            end = float(t[j + 1]) if j + 1 < len(t) else float(t[j]) + CONTROL_PERIOD
            ax.broken_barh(
                [(begin, end - begin)],
                (0.1, 0.8),
                facecolors=palette((2 * index + 1) % 20),
                edgecolors="0.5",
                linewidth=0.5,
            )
            if end - begin > 0.018 * span * max(3, len(label)):
                ax.text((begin + end) / 2, 0.5, label, ha="center", va="center", fontsize=7)
        k = j + 1


def _steered(trace: Any, inputs: Sequence[str]) -> list[str]:
    """The channels a run steers: its goal's, else the model's inputs it records."""
    channels = list(getattr(trace, "channels", []))
    names = [c for c in trace.goal if c in channels] or [c for c in inputs if c in channels]
    return names or channels[:1]


def _run_figure(
    trace: Any,
    demo: Mapping[str, np.ndarray],
    inputs: Sequence[str],
    kind: str,
    alt: str,
    colours: dict[str, int],
) -> str:
    """The compact figure of one run as an ``<img>`` with a PNG data URI."""
    steered = _steered(trace, inputs)
    heights = [1.0] * len(steered) + [1.15, 0.45]
    fig = Figure(
        figsize=(RUN_FIGURE_WIDTH, 0.55 + 0.95 * sum(heights)),
        layout="constrained",
        dpi=RUN_FIGURE_DPI,
    )
    axes = fig.subplots(len(heights), 1, sharex=True, height_ratios=heights)
    t = np.asarray(trace.t, dtype=np.float64)
    marker = "o" if len(t) == 1 else None  # a refused run is one point, not a line
    names = list(getattr(trace, "command_channels", ("left", "right")))
    td = np.arange(len(demo[names[0]])) * CONTROL_PERIOD
    for ax, name in zip(axes, steered, strict=False):
        if name in demo:
            ax.plot(td, demo[name], "k--", lw=1.1, label="teacher")
        ax.plot(t, _series(trace, name), "C2", lw=1.5, marker=marker, label="generated")
        if name in trace.goal:
            ax.axhline(trace.goal[name], color="0.4", lw=0.8, ls=":", label="goal")
        spec = (getattr(trace, "channel_specs", None) or {}).get(name) or CHANNELS.get(name)
        ax.set_ylabel(f"{name} ({spec.unit})" if spec is not None else name)
        ax.legend(loc="best", fontsize=7.5, ncol=3, frameon=False)
        ax.grid(alpha=0.3)
    ax = axes[len(steered)]
    commands = trace.command_array
    if len(commands) != len(t):
        commands = np.zeros((len(t), len(names)))
    for j, side in enumerate(names):
        if side in demo:
            ax.plot(td[: len(demo[side])], demo[side], f"C{j % 10}--", lw=1.0)
        ax.plot(t, commands[:, j], f"C{j % 10}", lw=1.4, marker=marker, label=side)
    ax.plot([], [], "k--", lw=1.0, label="teacher")
    ax.set_ylabel("wheels (rad/s)" if names == ["left", "right"] else "commands")
    ax.legend(loc="best", fontsize=7.5, ncol=3, frameon=False)
    ax.grid(alpha=0.3)
    _timeline(axes[-1], t, *_active(trace, kind), colours)
    axes[-1].set_xlabel("time (s)")
    for ax in axes:
        ax.tick_params(labelsize=7.5)
        ax.yaxis.label.set_size(8)
        ax.xaxis.label.set_size(8)
    data, width, height = _png(fig)
    return (
        f"<img class='plot' alt='{html.escape(alt)}' width='{width}' height='{height}' "
        f"src='data:image/png;base64,{data}'>"
    )


def _video_html(path: str | os.PathLike[str], folder: Path, k: int) -> str:
    """A run's video, linked relative to the report's folder (never embedded)."""
    source = Path(path)
    suffix = source.suffix.lower()
    if suffix not in VIDEO_SUFFIXES + IMAGE_SUFFIXES:
        raise ConfigError(
            f"video of case {k}: {source.name} is neither a video "
            f"({', '.join(VIDEO_SUFFIXES)}) nor an animation ({', '.join(IMAGE_SUFFIXES)})"
        )
    try:
        link = Path(os.path.relpath(source.resolve(), folder.resolve())).as_posix()
    except ValueError:  # another drive (Windows): only an absolute link reaches it
        link = source.resolve().as_uri()
    href = html.escape(quote(link, safe="/:"))
    label = html.escape(f"video of run {k}")
    if suffix in VIDEO_SUFFIXES:
        return (
            f"<div class='video'><video controls preload='metadata' width='300' "
            f"src='{href}' title='{label}'></video>"
            f"<a href='{href}'>{html.escape(source.name)}</a></div>"
        )
    return (
        f"<div class='video'><a href='{href}'>"
        f"<img alt='{label}' width='300' src='{href}'></a></div>"
    )


def _definitions(result: Mapping[str, Any], columns: set[str]) -> str:
    """The definitions of every score and column the page shows."""
    scale = float(result["command_scale"])
    motor = float(result["motor_max"])
    unit = "component" if result.get("kind") == "CBLM" else "motion primitive"
    goal_channels = sorted({c for case in result["cases"] for c in case.get("goal") or {}})
    tolerances = ", ".join(
        f"{name} ±{format_values({name: TOLERANCES[name]})}"
        if name in ("angle", "distance")
        else f"{name} ±{TOLERANCES[name]:g} {CHANNELS[name].unit}"
        for name in goal_channels
        if name in TOLERANCES
    )
    items = [
        (
            "success %",
            "100·(1 − EDM) of the wheel commands generated from a start against the "
            "teacher's demonstration from the same start (thesis ch. 6). Both left/right "
            f"command sequences are divided by {scale:.3g} rad/s (the largest command in "
            "the behavior's training demonstrations), aligned at t = 0, the shorter "
            "padded with zeros (stopped); EDM is their root-mean-square difference. "
            "Clamped at 0; 100 % repeats the teacher's commands exactly.",
        ),
        (
            "all-zero floor %",
            "the success % of a robot that never moves (all commands zero) against the "
            "same demonstrations. Read every score beside it: only what lies above the "
            "floor was learned.",
        ),
        (
            "motor-max %",
            "the same score with the commands divided by the motor limit "
            f"({motor:.3g} rad/s) instead of the largest demonstrated command; lenient "
            "(its floor, in brackets, is high), so not the headline.",
        ),
        (
            "goal reached",
            "the final noise-free state lies within tolerance of the goal"
            + (f" ({tolerances})" if tolerances else "")
            + "; otherwise the reason the run ended.",
        ),
        (
            "duration ×",
            "generated steps ÷ the teacher's steps from the same start (1: as long as "
            "the teacher; above 1: slower, or it overshot and came back).",
        ),
        (
            "command jump ×",
            "the largest change of either wheel command within one control period "
            f"({CONTROL_PERIOD * 1000:g} ms) ÷ the teacher's from the same start (the "
            "teacher is jerk-limited; 1: no harder jolt than the teacher).",
        ),
        ("switches", f"changes of the active {unit} along a run."),
    ]
    if "angle_err" in columns:
        items.append(
            ("final angle err", "|final bearing − goal| after the stop, noise-free (degrees).")
        )
    if "distance_err" in columns:
        items.append(
            ("final distance err", "|final distance − goal| after the stop, noise-free (metres).")
        )
    if "components" in columns:
        items.append(("components", "the components the CBLM ran, in order."))
    if "pushed" in columns:
        items.append(("pushed", "the run was still going when the push came."))
    body = "".join(f"<dt>{html.escape(k)}</dt><dd>{html.escape(v)}</dd>" for k, v in items)
    return f"<dl class='defs'>{body}</dl>"


def _case_columns(result: Mapping[str, Any]) -> set[str]:
    """The optional case columns that hold something for this evaluation."""
    cases = result["cases"]
    columns = set()
    if any(c.get("final_angle_error_deg") is not None for c in cases):
        columns.add("angle_err")
    if any(c.get("final_distance_error_m") is not None for c in cases):
        columns.add("distance_err")
    if any(c.get("components") for c in cases):
        columns.add("components")
    if any("pushed" in c for c in cases):
        columns.add("pushed")
    return columns


def _outcome(case: Mapping[str, Any]) -> str:
    if case.get("goal_reached"):
        return "yes"
    reason = str(case.get("reason") or "").replace("_", " ")
    return f"<span class='fail'>no</span>{f' ({html.escape(reason)})' if reason else ''}"


def components_text(names: Sequence[str], most: int = 6) -> str:
    """The components a CBLM ran, in order: ``"turn → approach"``; a long chain shortened."""
    names = list(names)
    if len(names) <= most:
        return " → ".join(names)
    return " → ".join([*names[: most - 2], "…", names[-1]]) + f" ({len(names)} in all)"


def _num(value: Any, fmt: str) -> str:
    if value is None:
        return ""
    v = float(value)
    return format(v, fmt) if math.isfinite(v) else "–"


def write_evaluation_report(
    result: Mapping[str, Any],
    traces: Mapping[str, Sequence[Any]] | None,
    path: str | os.PathLike[str],
    max_runs: int | None = None,
    *,
    videos: Mapping[int, str | os.PathLike[str]] | None = None,
) -> Path:
    """Write an HTML report of ``evaluate_model``'s result (with its ``keep_traces`` runs).

    The page defines every score, then holds the summary (the model and any baselines,
    each score beside its all-zero floor), every case (start and goal in physical
    units; columns with nothing to show for this behavior are left out) and a compact
    figure of every run: the steered channels and the wheel commands, generated against
    the teacher's demonstration from the same start, and the active primitive or
    component by name. Figures are embedded (the file stands alone); videos are linked.

    Parameters
    ----------
    result
        ``evaluate_model(..., keep_traces=True)``'s result, ``"_traces"`` popped.
    traces
        ``result.pop("_traces")``: ``{"model": [(trace, demonstration), ...], ...}``;
        None: tables only.
    path
        The HTML file to write (atomically).
    max_runs
        Plot only the first ``max_runs`` runs (default: every run).
    videos
        Case index -> video of that run (``.mp4``/``.webm``, shown as ``<video>``; or an
        animation, ``.gif``, shown as ``<img>``), linked relative to the report's folder:
        keep them beside it.

    Raises
    ------
    ConfigError
        A video names a case the result does not have, or is of an unknown type.
    """
    e = html.escape
    target = Path(path)
    cases = list(result["cases"])
    kind = str(result.get("kind") or "model")
    inputs = list(result.get("inputs") or [])
    sim = result.get("sim")
    where = f"{sim} sim" if sim else "your robot"
    title = f"{result['behavior']}: {kind} on {', '.join(inputs) or 'its inputs'} ({where})"
    videos = {int(k) if isinstance(k, np.integer) else k: v for k, v in (videos or {}).items()}
    for k in videos:
        if isinstance(k, bool) or not (isinstance(k, int) and 0 <= k < len(cases)):
            raise ConfigError(
                f"a video for case {k!r}, but the result has cases 0..{len(cases) - 1}"
            )
    video_html = {k: _video_html(p, target.parent, k) for k, p in videos.items()}
    baselines = dict(result.get("baselines") or {})
    columns = _case_columns(result)
    parts = [
        "<!doctype html>",
        "<html lang='en'><head><meta charset='utf-8'>",
        "<meta name='viewport' content='width=device-width, initial-scale=1'>",
        f"<title>{e(title)}</title><style>{_STYLE}</style></head><body>",
        f"<h1>behavior-hmm evaluation: {e(title)}</h1>",
        f"<p class='note'>{len(cases)} test starts, seed {result.get('seed', 0)}, sensor "
        f"noise {result.get('noise', 0.0):g}. Commands normalized by "
        f"{float(result['command_scale']):.3g} rad/s (largest demonstrated command); motor "
        f"limit {float(result['motor_max']):.3g} rad/s.</p>",
    ]
    if result.get("command_scale_at_motor_limit"):
        parts.append(
            "<p class='warn'>The demonstrations reached the motor limit: the headline "
            "success % is then the lenient motor-max variant.</p>"
        )
    parts += ["<h2>What the numbers mean</h2>", _definitions(result, columns)]

    pushed = "pushed" in result or any("pushed" in r for r in baselines.values())
    summary_head = (
        "<table><tr><th class='l'></th><th>success %</th><th>all-zero floor %</th>"
        "<th>goals reached</th><th>motor-max % (floor)</th><th>duration ×</th>"
        "<th>command jump × (median / max)</th><th>switches (mean / max)</th>"
        + ("<th>pushed</th>" if pushed else "")
        + "</tr>"
    )
    parts += ["<h2>Summary</h2>", summary_head]
    for name, r in [(f"model ({kind})", result), *baselines.items()]:
        parts.append(
            f"<tr><td class='l'>{e(name)}</td><td>{_num(r['success_rate_mean'], '.1f')}</td>"
            f"<td>{_num(r['zero_floor_mean'], '.1f')}</td>"
            f"<td>{r['goal_reached']}/{r['n']}</td>"
            f"<td>{_num(r['success_rate_motor_max_mean'], '.1f')} "
            f"({_num(r['zero_floor_motor_max_mean'], '.1f')})</td>"
            f"<td>{_num(r['duration_ratio_mean'], '.2f')}</td>"
            f"<td>{_num(r.get('command_jump_ratio_median'), '.1f')} / "
            f"{_num(r.get('command_jump_ratio_max'), '.1f')}</td>"
            f"<td>{_num(r.get('switches_mean'), '.1f')} / {r.get('switches_max', '')}</td>"
            + (f"<td>{r.get('pushed', '')}</td>" if pushed else "")
            + "</tr>"
        )
    parts.append("</table>")
    if baselines:
        parts.append(
            "<p class='note'>Baselines run from the same starts and are scored against the "
            "same demonstrations; their success % per case is in the cases table.</p>"
        )

    parts.append("<h2>Cases</h2>")
    head = [
        "<th>run</th><th class='l'>start</th><th class='l'>goal</th><th>success %</th>"
        "<th>all-zero floor %</th><th>motor-max %</th><th class='l'>goal reached</th>"
    ]
    if "angle_err" in columns:
        head.append("<th>final angle err (°)</th>")
    if "distance_err" in columns:
        head.append("<th>final distance err (m)</th>")
    head.append("<th>duration ×</th><th>command jump ×</th><th>switches</th>")
    if "pushed" in columns:
        head.append("<th>pushed</th>")
    if "components" in columns:
        head.append("<th class='l'>components</th>")
    head += [f"<th>{e(name)} %</th>" for name in baselines]
    parts.append("<table><tr>" + "".join(head) + "</tr>")
    model_runs = list((traces or {}).get("model") or [])
    n_plots = len(model_runs) if max_runs is None else min(len(model_runs), max(0, max_runs))
    for k, case in enumerate(cases):
        run = f"<a href='#run-{k}'>{k}</a>" if k < n_plots or k in video_html else str(k)
        row = [
            f"<td>{run}</td><td class='l nw'>{e(format_values(case.get('start')))}</td>",
            f"<td class='l nw'>{e(format_values(case.get('goal')))}</td>",
            f"<td>{_num(case['success_rate'], '.1f')}</td>",
            f"<td>{_num(case['zero_floor'], '.1f')}</td>",
            f"<td>{_num(case.get('success_rate_motor_max'), '.1f')}</td>",
            f"<td class='l'>{_outcome(case)}</td>",
        ]
        if "angle_err" in columns:
            row.append(f"<td>{_num(case.get('final_angle_error_deg'), '.2f')}</td>")
        if "distance_err" in columns:
            row.append(f"<td>{_num(case.get('final_distance_error_m'), '.3f')}</td>")
        row.append(
            f"<td>{_num(case['duration_ratio'], '.2f')}</td>"
            f"<td>{_num(case.get('command_jump_ratio'), '.1f')}</td>"
            f"<td>{case.get('switches', '')}</td>"
        )
        if "pushed" in columns:
            row.append(f"<td>{'yes' if case.get('pushed') else 'no'}</td>")
        if "components" in columns:
            row.append(f"<td class='l'>{e(components_text(case.get('components') or []))}</td>")
        for r in baselines.values():
            other = r.get("cases") or []
            row.append(
                f"<td>{_num(other[k]['success_rate'], '.1f') if k < len(other) else ''}</td>"
            )
        parts.append("<tr>" + "".join(row) + "</tr>")
    parts.append("</table>")

    shown = [k for k in range(len(cases)) if k < n_plots or k in video_html]
    if shown:
        what = "component" if kind == "CBLM" else "motion primitive"
        parts.append(
            "<h2>Runs</h2><p class='note'>Solid: generated; dashed: the teacher's "
            "demonstration from the same start; dotted: the goal. Bottom band: the active "
            f"{what}{'' if kind == 'CBLM' else ' (P3: primitive 3)'} by name.</p>"
            "<div class='runs'>"
        )
        # a component keeps its colour on every run (in the order the cases name them)
        colours: dict[str, int] = {}
        for case in cases:
            for name in case.get("components") or []:
                colours.setdefault(name, len(colours))
        for k in shown:
            case = cases[k]
            caption = (
                f"Run {k}: {format_values(case.get('start'))} → "
                f"{format_values(case.get('goal'))}; {_num(case['success_rate'], '.1f')} % "
                f"(floor {_num(case['zero_floor'], '.1f')} %); "
                + ("goal reached" if case.get("goal_reached") else f"failed ({case.get('reason')})")
            )
            if case.get("components"):
                caption += f"; {components_text(case['components'])}"
            figure = ""
            if k < n_plots:
                trace, demo = model_runs[k]
                figure = _run_figure(trace, demo, inputs, kind, caption, colours)
            parts.append(
                f"<section class='run' id='run-{k}'><h3>{e(caption)}</h3>"
                f"<div class='media'>{figure}{video_html.get(k, '')}</div></section>"
            )
        parts.append("</div>")
    if n_plots < len(cases) and model_runs:
        parts.append(f"<p class='note'>Runs {n_plots}..{len(cases) - 1} not plotted.</p>")
    parts.append("</body></html>\n")
    atomic_write_bytes(target, "\n".join(parts).encode("utf-8"))
    return target
