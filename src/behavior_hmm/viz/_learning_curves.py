"""Learning-curve plots: error versus epoch, one line per setting (thesis figures 6.5-6.7)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from numpy.typing import ArrayLike

from behavior_hmm._atomic import atomic_write_with
from behavior_hmm.errors import ConfigError


def plot_learning_curves(
    curves: Mapping[str, ArrayLike],
    path: str | os.PathLike[str],
    title: str,
    *,
    xlabel: str = "epoch",
    ylabel: str = "test RMS error (normalized commands)",
    logy: bool | None = None,
) -> Path:
    """Plot one error curve per label and write a PNG atomically.

    Parameters
    ----------
    curves
        Label -> errors per epoch (1-D; NaN entries, e.g. after early stopping,
        leave a gap). Epochs are numbered from 1 on the x axis.
    path
        Output PNG file; its folder is created if needed.
    title
        Figure title.
    xlabel, ylabel
        Axis labels.
    logy
        Logarithmic error axis; ``None`` picks it when the finite errors are
        positive and span more than a factor of 10.

    Returns
    -------
    Path
        ``path``.
    """
    if not curves:
        raise ConfigError("no learning curves to plot")
    arrays: dict[str, np.ndarray] = {}
    for label, values in curves.items():
        arr = np.asarray(values, dtype=np.float64)
        if arr.ndim != 1 or arr.size == 0:
            raise ConfigError(f"learning curve {label!r} must be a non-empty 1-D array")
        arrays[str(label)] = arr
    finite = np.concatenate([a[np.isfinite(a)] for a in arrays.values()])
    if logy is None:
        logy = bool(finite.size and finite.min() > 0 and finite.max() > 10 * finite.min())

    fig = Figure(figsize=(7.0, 4.5), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    for label, arr in arrays.items():
        ax.plot(np.arange(1, arr.size + 1), arr, label=label, linewidth=1.4)
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    target = Path(path)
    atomic_write_with(target, lambda tmp: fig.savefig(tmp, format="png", dpi=110))
    return target


def plot_generator_sweeps(
    report: Mapping[str, Any], out_dir: str | os.PathLike[str]
) -> dict[str, str]:
    """One PNG per sweep of :func:`~behavior_hmm.evaluate.run_generator_sweeps` (figs 6.5-6.7).

    Returns the written paths by sweep name.
    """
    out = Path(out_dir)
    figures: dict[str, str] = {}
    for name, entries in report["sweeps"].items():
        path = plot_learning_curves(
            {label: entry["test_error"] for label, entry in entries.items()},
            out / f"generator_sweep_{name}.png",
            report.get("titles", {}).get(name, name),
            xlabel="epoch",
            ylabel="test RMS error (normalized commands)",
        )
        figures[name] = str(path)
    return figures
