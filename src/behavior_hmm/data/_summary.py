"""A short numeric description of a dataset (for ``behavior-hmm inspect``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from behavior_hmm.data._channels import UNITS
from behavior_hmm.data._dataset import Dataset


def _stats(values: np.ndarray) -> dict[str, float]:
    return {
        "min": float(np.min(values)),
        "median": float(np.median(values)),
        "max": float(np.max(values)),
    }


def summarize(ds: Dataset) -> dict[str, Any]:
    """Describe ``ds`` as a JSON-ready dict.

    Returns
    -------
    dict
        ``episodes``, ``samples``, ``samples_per_episode`` and ``duration_s``
        (min/median/max), ``sample_period_s`` (median time step, ``None`` if no
        episode has two samples), ``channels`` (unit, min, max of each numeric
        channel except ``t``, declared channels included), ``behaviors``
        (sub-behavior names present) and ``metadata``.
    """
    offsets = ds.offsets
    t = ds.t
    first, last = offsets[:-1], offsets[1:] - 1
    same = ds.episode_ids.repeat(ds.lengths)
    dt = np.diff(t)[same[1:] == same[:-1]]
    units = {**UNITS, **{spec.name: spec.unit for spec in ds.channel_specs}}
    channels = {}
    for name in ds.numeric_channels[1:]:
        col = ds.column(name)
        channels[name] = {"unit": units[name], "min": float(col.min()), "max": float(col.max())}
    return {
        "episodes": len(ds),
        "samples": ds.n_samples,
        "samples_per_episode": _stats(ds.lengths),
        "duration_s": _stats(t[last] - t[first]),
        "sample_period_s": float(np.median(dt)) if len(dt) else None,
        "channels": channels,
        "behaviors": ds.behaviors,
        "metadata": ds.metadata,
    }
