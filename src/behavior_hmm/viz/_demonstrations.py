"""Time-series plots of demonstrations (like the thesis's figures 6.8-6.10)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from behavior_hmm._atomic import atomic_write_with
from behavior_hmm._paths import plot_format
from behavior_hmm.data import UNITS, Dataset
from behavior_hmm.errors import BehaviorHMMError, ConfigError

#: Channels that :func:`plot_demonstrations` shows by default (when they vary).
DEFAULT_PLOT_CHANNELS: tuple[str, ...] = ("angle", "distance")

_LABELS = {
    "t": "time",
    "distance": "distance",
    "linear_velocity": "linear velocity",
    "angle": "angle",
    "angular_velocity": "angular velocity",
    "left": "left wheel",
    "right": "right wheel",
}


def _default_channels(ds: Dataset) -> list[str]:
    varying = [c for c in DEFAULT_PLOT_CHANNELS if np.ptp(ds.column(c)) > 0]
    return varying or ["angle"]


def plot_demonstrations(
    ds: Dataset,
    path: str | os.PathLike[str],
    channels: Sequence[str] | None = None,
    *,
    title: str | None = None,
    dpi: int = 120,
) -> Path:
    """Plot each channel against time, one line per episode, and write a PNG.

    Lines are coloured by the episode's starting value of the first channel
    (a colour bar shows the scale). Uses matplotlib's object API without pyplot,
    so it works headless and leaves the global backend alone. The file is written
    atomically.

    Parameters
    ----------
    ds
        Demonstrations.
    path
        Output PNG file.
    channels
        Channels to plot, one subplot each (default: ``angle`` and ``distance``,
        those that vary).
    title
        Figure title (default: the dataset's ``behavior`` metadata and size).
    dpi
        Resolution.

    Returns
    -------
    Path
        The file written.
    """
    chans = list(channels) if channels is not None else _default_channels(ds)
    if not chans:
        raise ConfigError("no channels to plot")
    for c in chans:
        if c not in _LABELS or c == "t":
            known = ", ".join(k for k in _LABELS if k != "t")
            raise ConfigError(f"cannot plot channel '{c}' (channels: {known})")

    offsets = ds.offsets.tolist()
    key = ds.column(chans[0])[ds.offsets[:-1]]
    lo, hi = float(key.min()), float(key.max())
    if lo == hi:
        lo, hi = lo - 1.0, hi + 1.0
    norm = Normalize(lo, hi)
    cmap = colormaps["viridis"]

    fig = Figure(figsize=(7.0, 2.6 * len(chans) + 0.6), layout="constrained")
    axes = fig.subplots(len(chans), 1, sharex=True, squeeze=False)[:, 0]
    t = ds.t
    for ax, c in zip(axes, chans, strict=True):
        y = ds.column(c)
        for i in range(len(ds)):
            a, b = offsets[i], offsets[i + 1]
            ax.plot(t[a:b] - t[a], y[a:b], color=cmap(norm(key[i])), linewidth=1.0, alpha=0.85)
        ax.set_ylabel(f"{_LABELS[c]} ({UNITS[c]})")
        ax.grid(True, linewidth=0.4, alpha=0.5)
        if c == "angle":
            ax.axhline(0.0, color="0.3", linewidth=0.6)
    axes[-1].set_xlabel("time since episode start (s)")
    bar = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=list(axes), shrink=0.9)
    bar.set_label(f"start {_LABELS[chans[0]]} ({UNITS[chans[0]]})")
    if title is None:
        behavior = ds.metadata.get("behavior")
        name = f"'{behavior}' demonstrations" if behavior else "Demonstrations"
        title = f"{name}: {len(ds)} episodes, {ds.n_samples} samples"
    fig.suptitle(title)

    target = Path(path)
    try:
        fmt = plot_format(target)
        atomic_write_with(target, lambda tmp: fig.savefig(tmp, format=fmt, dpi=dpi))
    except OSError as exc:
        raise BehaviorHMMError(f"{path}: cannot write plot ({exc.strerror or exc})") from None
    return target
