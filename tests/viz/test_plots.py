"""Plot functions draw into the caller's axes or a figure of their own and return it.

Every plot function returns a matplotlib Figure, accepts ``ax=`` (or ``fig=`` /
``axes=`` where it draws several panels) and writes a file only when given a path.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from behavior_hmm.data import CONTROL_PERIOD, SENSOR_CHANNELS, ChannelSpec, Dataset
from behavior_hmm.errors import ConfigError
from behavior_hmm.runtime import Trace
from behavior_hmm.viz import (
    plot_complex_grid,
    plot_complex_run,
    plot_demonstrations,
    plot_generated_vs_demonstrated,
    plot_learning_curves,
    plot_trace,
    plot_trajectories,
    plot_trajectory,
    replay_pose,
)
from behavior_hmm.viz._categories import plot_angle_vs_category, plot_transition_diagram
from behavior_hmm.viz._traces import run_title, value_text, wrap_title

PNG = b"\x89PNG\r\n\x1a\n"


def _figure() -> Figure:
    fig = Figure(figsize=(8, 6))
    FigureCanvasAgg(fig)
    return fig


def _texts(ax: Axes) -> list[str]:
    return [t.get_text() for t in ax.texts]


def _colorbars(fig: Figure) -> list[Axes]:
    return [ax for ax in fig.axes if getattr(ax, "_colorbar", None) is not None]


def _trace(
    *,
    components: list[str] | None = None,
    states: list[int] | None = None,
    goal: dict[str, float] | None = None,
    steps: int = 250,
) -> Trace:
    """A turn from 120° to 0°, driving forward along x, with poses."""
    s = np.linspace(0.0, 1.0, steps)
    trace = Trace(goal=goal or {"angle": 0.0}, start={"angle": 120.0, "distance": 0.5})
    for k in range(steps):
        row = np.zeros(len(SENSOR_CHANNELS))
        row[SENSOR_CHANNELS.index("angle")] = 120.0 * (1 - s[k])
        row[SENSOR_CHANNELS.index("distance")] = 0.5 * (1 - s[k])
        trace.t.append(k * CONTROL_PERIOD)
        trace.readings.append(row)
        trace.true_readings.append(row)
        trace.commands.append(np.array([-1.0, 1.0]))
        trace.pose.append(np.array([-0.6 + 0.5 * s[k], 0.01 * s[k], math.pi * (1 - s[k])]))
        trace.observation.append(0)
        trace.plan_changed.append(False)
    trace.state = states if states is not None else [26] * (steps // 2) + [4] * (steps - steps // 2)
    trace.component = components if components is not None else [""] * steps
    trace.goal_reached = True
    trace.reason = "goal"
    return trace


def _demo(n: int = 270) -> dict[str, Any]:
    s = np.linspace(0.0, 1.0, n)
    return {
        "t": np.arange(n) * CONTROL_PERIOD,
        "angle": 120.0 * (1 - s) ** 2,
        "distance": 0.5 * (1 - s),
        "left": -np.ones(n),
        "right": np.ones(n),
        "behavior": np.array(["turn"] * (n // 2) + ["approach"] * (n - n // 2), dtype=object),
    }


# -- plot_trace ---------------------------------------------------------------------------


def test_plot_trace_returns_the_figure_and_saves_only_when_given_a_path(tmp_path: Path) -> None:
    fig = plot_trace(_trace())
    assert isinstance(fig, Figure)
    assert list(tmp_path.iterdir()) == []
    out = tmp_path / "run.png"
    saved = plot_trace(_trace(), out)  # the old positional call: (trace, path)
    assert isinstance(saved, Figure)
    assert out.read_bytes()[:8] == PNG


def test_plot_trace_draws_every_declared_command_in_its_unit() -> None:
    trace = _trace()
    trace.command_channels = ["left", "right", "grip"]
    trace.commands = [np.array([-1.0, 1.0, 0.01])] * len(trace.t)
    grip = ChannelSpec("grip", "m/s", (-0.02, 0.02), kind="command")
    trace.channel_specs = {"grip": grip}
    demo = {**_demo(), "grip": np.full(270, 0.01)}
    commands = plot_trace(trace, reference=demo).axes[1]
    names = [line.get_label() for line in commands.get_lines()]
    assert {"left (model)", "right (model)", "grip (model)", "grip (teacher)"} <= set(names)
    assert commands.get_ylabel() == "command"  # two units: none named
    trace.command_channels, trace.commands = ["grip"], [np.array([0.01])] * len(trace.t)
    assert plot_trace(trace).axes[1].get_ylabel() == "command (m/s)"


def test_plot_trace_names_the_active_primitives() -> None:
    fig = plot_trace(_trace())
    band = fig.axes[-1]
    assert "primitive" in " ".join(t.get_text() for t in band.get_yticklabels())
    assert _texts(band) == ["primitive 26", "primitive 4"]
    assert band.get_xlabel() == "time (s)"


def test_plot_trace_names_the_active_components_and_the_teachers_phases() -> None:
    comps = ["turn"] * 120 + ["approach"] * 130
    trace = _trace(components=comps, states=[0] * 120 + [1] * 130, goal={"angle": 0, "distance": 0})
    fig = plot_trace(trace, reference=_demo())
    band = fig.axes[-1]
    assert _texts(band) == ["turn", "approach", "turn", "approach"]  # model row, teacher row
    labels = [t.get_text() for t in band.get_yticklabels()]
    assert labels == ["active\ncomponent", "teacher's\nphase"]


def test_plot_trace_overlays_the_teacher_on_every_panel() -> None:
    fig = plot_trace(_trace(goal={"angle": 0.0, "distance": 0.0}), reference=_demo())
    angle, distance, wheels, _ = fig.axes
    for ax in (angle, distance):
        labels = [line.get_label() for line in ax.get_lines()]
        assert labels[:2] == ["model", "teacher"]
    assert {"left (teacher)", "right (teacher)"} <= {ln.get_label() for ln in wheels.get_lines()}
    assert angle.get_ylabel() == "angle (deg)" and distance.get_ylabel() == "distance (m)"


def test_plot_trace_still_takes_the_commands_array_as_reference() -> None:
    demo = _demo()
    commands = np.column_stack([demo["left"], demo["right"]])
    fig = plot_trace(_trace(), None, commands)
    labels = {line.get_label() for ax in fig.axes for line in ax.get_lines()}
    assert "left (teacher)" in labels and "teacher" not in labels
    with pytest.raises(ConfigError, match="reference"):
        plot_trace(_trace(), reference=np.zeros((5, 3)))


def test_plot_trace_title_is_plain_text_with_units() -> None:
    fig = plot_trace(_trace(), behavior="turn")
    title = fig.get_suptitle()
    assert title.startswith("turn from angle 120°, distance 0.50 m → goal angle 0°")
    assert "{" not in title and "goal reached in 3.98 s" in title
    assert value_text("distance", 0.25) == "0.25 m" and value_text("angle", -100.0) == "-100°"
    failed = _trace()
    failed.goal_reached, failed.reason = False, "step_limit"
    assert run_title(failed).endswith("goal not reached (step limit)")
    assert wrap_title("a" * 30 + ": " + "b" * 30, 2.0).count("\n") >= 1


def test_plot_trace_draws_into_given_axes_or_subfigure() -> None:
    fig = _figure()
    axes = fig.subplots(3, 1)
    assert plot_trace(_trace(), axes=axes) is fig
    assert axes[0].get_title().startswith("from angle 120°")  # no suptitle on their figure
    assert not fig.get_suptitle()
    with pytest.raises(ConfigError, match="3 panels"):
        plot_trace(_trace(), axes=axes[:2])
    root = _figure()
    left, _ = root.subfigures(1, 2)
    assert plot_trace(_trace(), fig=left) is root
    assert len(root.axes) == 3


def test_plot_trace_of_a_refused_run() -> None:
    trace = Trace(goal={"angle": 0.0}, start={"angle": 120.0, "distance": 0.5})
    trace.t.append(0.0)
    trace.commands.append(np.zeros(2))
    trace.reason = "unreachable: no path"
    fig = plot_trace(trace)
    assert "nothing ran (unreachable: no path)" in _texts(fig.axes[-1])


# -- trajectories ---------------------------------------------------------------------------


def test_plot_trajectory_draws_into_ax_with_the_teacher_and_units(tmp_path: Path) -> None:
    trace = _trace()
    fig = _figure()
    ax = fig.add_subplot()
    teacher = trace.pose_array + np.array([0.0, 0.02, 0.0])
    out = plot_trajectory(trace, ax, reference_pose=teacher, title="from above")
    assert out is fig
    assert ax.get_xlabel() == "x (m)" and ax.get_ylabel() == "y (m)"
    assert ax.get_title() == "from above"
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend[:2] == ["model", "teacher"] and "robot every 1 s" in legend
    dashed = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
    np.testing.assert_allclose(dashed[0].get_ydata(), teacher[:, 1])
    # outlines every second: at 0, 1, 2, 3 s and the end
    circles = [p for p in ax.patches if type(p).__name__ == "Circle"]
    assert len(circles) == 5 + 1  # and the object
    path = tmp_path / "traj.png"
    own = plot_trajectory(trace, path=path)
    assert own is not fig and path.read_bytes()[:8] == PNG
    assert own.axes[0].get_title().startswith("from angle 120°")


def test_plot_trajectory_needs_poses() -> None:
    trace = _trace()
    trace.pose = []
    with pytest.raises(ValueError, match="no poses"):
        plot_trajectory(trace)


def test_plot_trajectories_returns_the_figure(tmp_path: Path) -> None:
    fig = plot_trajectories([(_trace(), True), (_trace(), False)], path=tmp_path / "all.png")
    assert isinstance(fig, Figure) and (tmp_path / "all.png").read_bytes()[:8] == PNG
    assert [t.get_text() for t in fig.legends[0].get_texts()] == [
        "goal reached (1)",
        "goal missed (1)",
        "object",
    ]


def test_replay_pose_follows_the_commands_in_the_sim() -> None:
    from behavior_hmm.sim import make_env

    env = make_env("kinematic")
    demo = {"left": np.full(60, 3.0), "right": np.full(60, 3.0)}
    pose = replay_pose(env, {"angle": 0.0, "distance": 0.5}, demo)
    assert pose.shape == (60, 3)
    assert pose[0, 0] < 0 and abs(pose[0, 1]) < 1e-9
    assert np.all(np.diff(pose[:, 0]) >= 0) and pose[-1, 0] > pose[0, 0]  # drives to the object


# -- demonstrations -------------------------------------------------------------------------


def _approach() -> Dataset:
    eps = []
    for d0 in (0.3, 0.6, 0.9):
        n = 100
        s = np.linspace(0.0, 1.0, n)
        eps.append(
            {
                "t": np.arange(n) * CONTROL_PERIOD,
                "distance": d0 * (1 - s),
                "linear_velocity": np.zeros(n),
                "angle": np.zeros(n) + 0.1 * s,
                "angular_velocity": np.zeros(n),
                "left": np.ones(n),
                "right": np.ones(n),
            }
        )
    return Dataset.from_episodes(eps, {"behavior": "approach"})


def test_demonstrations_are_coloured_by_start_distance_with_a_colour_bar(tmp_path: Path) -> None:
    fig = plot_demonstrations(_approach())
    assert isinstance(fig, Figure)
    bars = _colorbars(fig)
    assert len(bars) == 1 and bars[0].get_ylabel() == "start distance (m)"
    assert fig.get_suptitle() == "approach demonstrations: 3 episodes, 300 samples"
    assert not list(tmp_path.iterdir())
    turned = plot_demonstrations(_approach(), channels=["angle", "distance"], color_by="angle")
    assert _colorbars(turned)[0].get_ylabel() == "start angle (deg)"
    with pytest.raises(ConfigError, match="colour by"):
        plot_demonstrations(_approach(), color_by="speed")


def test_demonstrations_draw_into_given_axes() -> None:
    fig = _figure()
    axes = fig.subplots(2, 1)
    assert plot_demonstrations(_approach(), channels=["distance", "left"], axes=axes) is fig
    assert [ax.get_ylabel() for ax in axes] == ["distance (m)", "left wheel (rad/s)"]
    assert len(_colorbars(fig)) == 1
    with pytest.raises(ConfigError, match="2 channels"):
        plot_demonstrations(_approach(), channels=["distance", "left"], axes=axes[:1])


# -- categories -----------------------------------------------------------------------------


def _categorization() -> dict[str, Any]:
    starts = [-120.0, -40.0, 50.0, 150.0]
    angles, labels = [], []
    for a0 in starts:
        path = np.linspace(a0, 0.0, 30)
        angles.append(path)
        labels.append(np.digitize(path, [-90, -30, 0, 30, 90]))
    labels_all = np.concatenate(labels)
    k = int(labels_all.max()) + 1
    counts = np.zeros((k, k))
    for a, b in itertools.pairwise(labels_all):
        counts[a, b] += 1
    return {
        "rho": 0.85,
        "n_primitives": k,
        "labels": labels_all,
        "angles": np.concatenate(angles),
        "lengths": [30] * len(starts),
        "episode_starts": starts,
        "transitions": counts,
    }


def test_category_plots_have_colour_bars_and_explain_edge_width(tmp_path: Path) -> None:
    run = _categorization()
    fig = _figure()
    ax = fig.add_subplot()
    assert plot_angle_vs_category(run, ax=ax) is fig
    assert _colorbars(fig)[0].get_ylabel() == "start angle of the demonstration (deg)"
    assert "{" not in ax.get_title()
    diagram = plot_transition_diagram(run, tmp_path / "t.png")
    assert (tmp_path / "t.png").read_bytes()[:8] == PNG
    main = diagram.axes[0]
    legend = main.get_legend()
    assert "edge width" in legend.get_title().get_text()
    assert len(_colorbars(diagram)) == 1


# -- other plots ----------------------------------------------------------------------------


def test_learning_curves_and_overlays_return_the_figure(tmp_path: Path) -> None:
    fig = _figure()
    ax = fig.add_subplot()
    curves = {"a": np.geomspace(1.0, 0.01, 20)}
    assert plot_learning_curves(curves, ax=ax, title="t") is fig
    assert ax.get_title() == "t"
    out = plot_learning_curves(curves, tmp_path / "c.png", "title")
    assert isinstance(out, Figure) and (tmp_path / "c.png").read_bytes()[:8] == PNG
    runs = [("from 100°", np.linspace(100, 0, 50), np.linspace(100, 0, 55))]
    over = plot_generated_vs_demonstrated(runs, "angle", tmp_path / "g.png", "title")
    assert isinstance(over, Figure) and (tmp_path / "g.png").exists()
    fig2 = _figure()
    ax2 = fig2.add_subplot()
    assert plot_generated_vs_demonstrated(runs, "angle", ax=ax2) is fig2
    assert ax2.get_ylabel() == "angle (deg)"


def _complex_run() -> dict[str, Any]:
    return {
        "start": {"angle": 40.0, "distance": 0.5},
        "t": np.arange(60) * CONTROL_PERIOD,
        "angle": np.r_[np.linspace(40.0, 0, 25), np.zeros(35)],
        "distance": np.r_[np.full(25, 0.5), np.linspace(0.5, 0, 35)],
        "component": ["turn"] * 25 + ["approach"] * 35,
        "demo_angle": np.r_[np.linspace(40.0, 0, 27), np.zeros(35)],
        "demo_distance": np.r_[np.full(27, 0.5), np.linspace(0.5, 0, 35)],
        "demo_behavior": ["turn"] * 27 + ["approach"] * 35,
        "success_rate": 88.0,
    }


def test_complex_run_names_the_components(tmp_path: Path) -> None:
    fig = plot_complex_run(_complex_run(), tmp_path / "c.png")
    assert isinstance(fig, Figure) and (tmp_path / "c.png").read_bytes()[:8] == PNG
    assert fig.get_suptitle() == "turn & approach from angle 40°, distance 0.50 m (success 88.0 %)"
    assert _texts(fig.axes[-1]) == ["turn", "approach", "turn", "approach"]
    mine = _figure()
    axes = mine.subplots(3, 1)
    assert plot_complex_run(_complex_run(), axes=axes) is mine


def test_grids_draw_into_a_subfigure() -> None:
    root = _figure()
    _, right = root.subfigures(1, 2)
    assert plot_complex_grid([_complex_run()] * 2, fig=right, title="B.3") is root
    assert len(root.axes) == 4
