"""Time-series plots of demonstrations (like the thesis's figures 6.8-6.10)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure, SubFigure

from behavior_hmm._atomic import atomic_write_with
from behavior_hmm._paths import plot_format
from behavior_hmm.data import UNITS, Dataset
from behavior_hmm.errors import BehaviorHMMError, ConfigError
from behavior_hmm.viz._traces import new_figure, root_figure

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


def _color_channel(ds: Dataset, chans: Sequence[str], color_by: str | None) -> str:
    """The channel whose start value colours the lines: ``color_by``, or the first of
    ``chans`` whose start varies between episodes (approach: distance; turn: angle)."""
    if color_by is not None:
        if color_by not in _LABELS or color_by == "t":
            known = ", ".join(k for k in _LABELS if k != "t")
            raise ConfigError(f"cannot colour by channel '{color_by}' (channels: {known})")
        return color_by
    firsts = ds.offsets[:-1]
    for c in (*chans, *DEFAULT_PLOT_CHANNELS):
        if np.ptp(ds.column(c)[firsts]) > 0:
            return c
    return chans[0]


def plot_demonstrations(
    ds: Dataset,
    path: str | os.PathLike[str] | None = None,
    channels: Sequence[str] | None = None,
    *,
    title: str | None = None,
    dpi: int = 120,
    color_by: str | None = None,
    fig: Figure | SubFigure | None = None,
    axes: Sequence[Axes] | None = None,
) -> Figure:
    """Plot each channel against time, one line per episode, coloured by where it started.

    Lines are coloured by the episode's starting value of ``color_by`` (default: of the
    first plotted channel whose start varies: the start distance of approach
    demonstrations, the start angle of turn ones), with a colour bar for the scale.
    Uses matplotlib's object API without pyplot, so it works headless and leaves the
    global backend alone.

    Parameters
    ----------
    ds
        Demonstrations.
    path
        Output file (written atomically; format from the extension), or None to only draw.
    channels
        Channels to plot, one subplot each (default: ``angle`` and ``distance``,
        those that vary).
    title
        Figure title (default: the dataset's ``behavior`` metadata and size).
    dpi
        Resolution of the written file.
    color_by
        Channel whose start value colours each episode's lines.
    fig, axes
        Draw into this figure (or subfigure), or into these axes (one per channel);
        default a new figure.

    Returns
    -------
    Figure
        The figure drawn (the root figure of ``fig`` / ``axes`` when given).
    """
    chans = list(channels) if channels is not None else _default_channels(ds)
    if not chans:
        raise ConfigError("no channels to plot")
    for c in chans:
        if c not in _LABELS or c == "t":
            known = ", ".join(k for k in _LABELS if k != "t")
            raise ConfigError(f"cannot plot channel '{c}' (channels: {known})")
    key_channel = _color_channel(ds, chans, color_by)

    offsets = ds.offsets.tolist()
    key = ds.column(key_channel)[ds.offsets[:-1]]
    lo, hi = float(key.min()), float(key.max())
    if lo == hi:
        lo, hi = lo - 1.0, hi + 1.0
    norm = Normalize(lo, hi)
    cmap = colormaps["viridis"]

    if axes is not None:
        panels = list(np.ravel(np.asarray(axes, dtype=object)))
        if len(panels) != len(chans):
            raise ConfigError(f"{len(chans)} channels to plot, got {len(panels)} axes")
        owner: Figure | SubFigure = panels[0].get_figure()
    else:
        owner = fig if fig is not None else new_figure((7.0, 2.6 * len(chans) + 0.6))
        panels = list(owner.subplots(len(chans), 1, sharex=True, squeeze=False)[:, 0])
    t = ds.t
    for ax, c in zip(panels, chans, strict=True):
        y = ds.column(c)
        for i in range(len(ds)):
            a, b = offsets[i], offsets[i + 1]
            ax.plot(t[a:b] - t[a], y[a:b], color=cmap(norm(key[i])), linewidth=1.0, alpha=0.85)
        ax.set_ylabel(f"{_LABELS[c]} ({UNITS[c]})")
        ax.grid(True, linewidth=0.4, alpha=0.5)
        if c == "angle":
            ax.axhline(0.0, color="0.3", linewidth=0.6)
    panels[-1].set_xlabel("time since episode start (s)")
    bar = owner.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=panels, shrink=0.9)
    bar.set_label(f"start {_LABELS[key_channel]} ({UNITS[key_channel]})")
    if title is None:
        behavior = ds.metadata.get("behavior")
        name = f"{behavior} demonstrations" if behavior else "Demonstrations"
        title = f"{name}: {len(ds)} episodes, {ds.n_samples:,} samples"
    if axes is not None:  # the caller's figure keeps its own title
        panels[0].set_title(title)
    else:
        owner.suptitle(title)
    figure = root_figure(owner)

    if path is not None:
        target = Path(path)
        try:
            fmt = plot_format(target)
            atomic_write_with(target, lambda tmp: figure.savefig(tmp, format=fmt, dpi=dpi))
        except OSError as exc:
            raise BehaviorHMMError(f"{path}: cannot write plot ({exc.strerror or exc})") from None
    return figure
