"""Plots and reports (matplotlib's object API, headless-safe)."""

from behavior_hmm.viz._demonstrations import DEFAULT_PLOT_CHANNELS, plot_demonstrations
from behavior_hmm.viz._grids import (
    draw_start_panel,
    plot_complex_grid,
    plot_start_grid,
    plot_thesis_starts,
    simple_panels,
)
from behavior_hmm.viz._html import write_evaluation_report
from behavior_hmm.viz._learning_curves import plot_generator_sweeps, plot_learning_curves
from behavior_hmm.viz._reports import (
    complex_table,
    simple_table,
    write_complex_report,
    write_robot_report,
    write_simple_report,
)
from behavior_hmm.viz._traces import (
    plot_complex_run,
    plot_generated_vs_demonstrated,
    plot_trace,
)
from behavior_hmm.viz._trajectory import plot_trajectories, plot_trajectory, replay_pose
from behavior_hmm.viz._video import frame_grid, render_rollout, render_trace

__all__ = [
    "DEFAULT_PLOT_CHANNELS",
    "complex_table",
    "draw_start_panel",
    "frame_grid",
    "plot_complex_grid",
    "plot_complex_run",
    "plot_demonstrations",
    "plot_generated_vs_demonstrated",
    "plot_generator_sweeps",
    "plot_learning_curves",
    "plot_start_grid",
    "plot_thesis_starts",
    "plot_trace",
    "plot_trajectories",
    "plot_trajectory",
    "render_rollout",
    "render_trace",
    "replay_pose",
    "simple_panels",
    "simple_table",
    "write_complex_report",
    "write_evaluation_report",
    "write_robot_report",
    "write_simple_report",
]
