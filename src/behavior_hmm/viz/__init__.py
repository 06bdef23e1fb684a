"""Plots and reports (matplotlib's object API, headless-safe)."""

from behavior_hmm.viz._demonstrations import DEFAULT_PLOT_CHANNELS, plot_demonstrations

__all__ = ["DEFAULT_PLOT_CHANNELS", "plot_demonstrations"]
