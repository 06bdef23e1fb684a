"""Learning-curve plots: test error versus iteration, one line per setting (figs 6.5-6.7, A.1)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import EngFormatter
from numpy.typing import ArrayLike

from behavior_hmm.errors import ConfigError
from behavior_hmm.viz._traces import _save, new_figure, root_figure

#: File stem of each sweep's figure and the thesis figure it stands for.
SWEEP_FIGURES: dict[str, str] = {
    "learning_rate": "fig. 6.5",
    "momentum": "fig. 6.6",
    "hidden": "fig. 6.7",
    "hidden_two_inputs": "fig. A.1",
}


def _as_curves(curves: Mapping[str, ArrayLike]) -> dict[str, np.ndarray]:
    if not curves:
        raise ConfigError("no learning curves to plot")
    arrays: dict[str, np.ndarray] = {}
    for label, values in curves.items():
        arr = np.asarray(values, dtype=np.float64)
        if arr.ndim != 1 or arr.size == 0:
            raise ConfigError(f"learning curve {label!r} must be a non-empty 1-D array")
        arrays[str(label)] = arr
    return arrays


def draw_learning_curves(
    curves: Mapping[str, ArrayLike],
    *,
    x: ArrayLike | None = None,
    title: str = "",
    xlabel: str = "epoch",
    ylabel: str = "test RMS error (normalized commands)",
    logy: bool | None = None,
    ax: Axes | None = None,
) -> Figure:
    """Draw one error curve per label on ``ax`` (a new figure if ``None``); return the figure.

    Parameters
    ----------
    curves
        Label -> errors (1-D; NaN entries leave a gap).
    x
        The x value of every point, shared by the curves (default: 1, 2, ...).
    logy
        Logarithmic error axis; ``None`` picks it when the finite errors are
        positive and span more than a factor of 10.
    """
    arrays = _as_curves(curves)
    finite = np.concatenate([a[np.isfinite(a)] for a in arrays.values()])
    if logy is None:
        logy = bool(finite.size and finite.min() > 0 and finite.max() > 10 * finite.min())
    if ax is None:
        ax = new_figure((7.0, 4.5)).add_subplot()
    fig = root_figure(ax)
    for label, arr in arrays.items():
        xs = np.arange(1, arr.size + 1) if x is None else np.asarray(x, dtype=np.float64)
        if xs.shape != arr.shape:
            raise ConfigError(f"learning curve {label!r}: {arr.size} errors for {xs.size} x values")
        ax.plot(xs, arr, label=label, linewidth=1.4)
    if logy:
        ax.set_yscale("log")
    ax.xaxis.set_major_formatter(EngFormatter(sep=""))
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=9)
    return fig


def plot_learning_curves(
    curves: Mapping[str, ArrayLike],
    path: str | os.PathLike[str] | None = None,
    title: str = "",
    *,
    x: ArrayLike | None = None,
    xlabel: str = "epoch",
    ylabel: str = "test RMS error (normalized commands)",
    logy: bool | None = None,
    ax: Axes | None = None,
) -> Figure:
    """Plot one error curve per label (:func:`draw_learning_curves`) and return the figure.

    Draws into ``ax`` (default a new figure); when ``path`` is given also writes it
    atomically (its folder is created if needed).
    """
    _as_curves(curves)  # refuse bad input before touching the file system
    fig = draw_learning_curves(
        curves, x=x, title=title, xlabel=xlabel, ylabel=ylabel, logy=logy, ax=ax
    )
    if path is not None:
        _save(fig, path, dpi=110)
    return fig


def sweep_curves(
    entries: Mapping[str, Any], iterations: list[int]
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Curves of one sweep with the untrained network's error at iteration 0 prepended."""
    curves = {}
    for label, entry in entries.items():
        first = entry.get("initial_test_error")
        values = [np.nan if v is None else v for v in entry["test_error"]]
        curves[label] = np.array([np.nan if first is None else first, *values], dtype=float)
    return curves, np.array([0, *iterations], dtype=float)


def plot_generator_sweeps(
    report: Mapping[str, Any], out_dir: str | os.PathLike[str]
) -> dict[str, str]:
    """One PNG per sweep of :func:`~behavior_hmm.evaluate.run_generator_sweeps`.

    Test error against iterations (training samples presented), from the untrained
    network at iteration 0, as the thesis's figures 6.5-6.7 and A.1. Returns the
    written paths by sweep name (``generator_sweep_<sweep>.png``).
    """
    out = Path(out_dir)
    figures: dict[str, str] = {}
    n_train = int(report["n_train"])
    iterations = list(
        report.get("iterations") or [n_train * (e + 1) for e in range(report["epochs"])]
    )
    xlabel = str(report.get("iteration_label", "iteration (training samples presented)"))
    for name, entries in report["sweeps"].items():
        curves, x = sweep_curves(entries, iterations)
        title = report.get("titles", {}).get(name, name)
        thesis = f"thesis {SWEEP_FIGURES[name]}; " if name in SWEEP_FIGURES else ""
        title = (
            f"{title}\n({thesis}primitive {report['primitive']}, "
            f"{n_train} training samples per epoch)"
        )
        path = out / f"generator_sweep_{name}.png"
        plot_learning_curves(
            curves, path, title, x=x, xlabel=xlabel, ylabel="test RMS error (normalized commands)"
        )
        figures[name] = str(path)
    return figures
