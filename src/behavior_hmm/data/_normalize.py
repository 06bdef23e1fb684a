"""Normalization of sensor channels and wheel commands into [−1, 1]."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from behavior_hmm._estimator import Estimator
from behavior_hmm.data._channels import SENSOR_CHANNELS, SENSOR_RANGES
from behavior_hmm.errors import ConfigError, DatasetError, NotFittedError


def _check_range(name: str, lo: object, hi: object) -> tuple[float, float]:
    try:
        lo_f, hi_f = float(lo), float(hi)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ConfigError(f"range of '{name}' must be two numbers, got {lo!r}, {hi!r}") from None
    if not (math.isfinite(lo_f) and math.isfinite(hi_f) and lo_f < hi_f):
        raise ConfigError(f"range of '{name}' must be finite with lo < hi, got [{lo_f}, {hi_f}]")
    return lo_f, hi_f


@dataclass(frozen=True)
class Normalizer:
    """Map each channel's physical range ``[lo, hi]`` linearly onto [−1, 1].

    Values outside the range map outside [−1, 1] (nothing is clipped unless
    ``clip=True``). The mapping is ``y = (x − lo) · 2 / (hi − lo) − 1``.

    Parameters
    ----------
    channels
        Channel names, in the column order of the arrays to transform.
    ranges
        ``{channel: (lo, hi)}`` in physical units; channels not given use
        ``SENSOR_RANGES``.
    clip
        Clip the output to [−1, 1] (then ``inverse_transform`` is not exact).

    Examples
    --------
    >>> Normalizer(("angle",)).transform([[90.0], [-180.0]]).ravel().tolist()
    [0.5, -1.0]
    """

    channels: tuple[str, ...] = SENSOR_CHANNELS
    ranges: Mapping[str, tuple[float, float]] | None = None
    clip: bool = False
    _lo: NDArray[np.float64] = field(init=False, repr=False, compare=False)
    _gain: NDArray[np.float64] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        channels = (self.channels,) if isinstance(self.channels, str) else tuple(self.channels)
        if not channels:
            raise ConfigError("Normalizer needs at least one channel")
        if len(set(channels)) != len(channels):
            raise ConfigError(f"channels repeat: {channels}")
        given = dict(self.ranges or {})
        for name in given:
            if name not in channels:
                raise ConfigError(f"range given for '{name}', which is not among {channels}")
        ranges: dict[str, tuple[float, float]] = {}
        for name in channels:
            if name in given:
                pair = given[name]
            elif name in SENSOR_RANGES:
                pair = SENSOR_RANGES[name]
            else:
                raise ConfigError(f"no normalization range for channel '{name}'; pass ranges=")
            if not isinstance(pair, Sequence) or len(pair) != 2:
                raise ConfigError(f"range of '{name}' must be (lo, hi), got {pair!r}")
            ranges[name] = _check_range(name, *pair)
        object.__setattr__(self, "channels", channels)
        object.__setattr__(self, "ranges", ranges)
        lo = np.array([ranges[c][0] for c in channels])
        hi = np.array([ranges[c][1] for c in channels])
        object.__setattr__(self, "_lo", lo)
        object.__setattr__(self, "_gain", 2.0 / (hi - lo))

    @property
    def lo(self) -> NDArray[np.float64]:
        """Lower range end of each channel (physical units), read-only."""
        out = self._lo.view()
        out.flags.writeable = False
        return out

    @property
    def gain(self) -> NDArray[np.float64]:
        """``2 / (hi - lo)`` of each channel: ``y = (x - lo) * gain - 1``, read-only."""
        out = self._gain.view()
        out.flags.writeable = False
        return out

    def _check(self, x: ArrayLike) -> NDArray[np.float64]:
        a = np.asarray(x, dtype=np.float64)
        if a.ndim == 0 or a.shape[-1] != len(self.channels):
            raise ConfigError(
                f"expected {len(self.channels)} values per sample ({', '.join(self.channels)}), "
                f"got shape {a.shape}"
            )
        return a

    def transform(self, x: ArrayLike) -> NDArray[np.float64]:
        """Physical units -> normalized; ``x`` has shape ``(..., k)`` in channel order."""
        y = (self._check(x) - self._lo) * self._gain - 1.0
        return np.clip(y, -1.0, 1.0) if self.clip else y

    def inverse_transform(self, y: ArrayLike) -> NDArray[np.float64]:
        """Normalized -> physical units (exact inverse of :meth:`transform` up to rounding)."""
        return (self._check(y) + 1.0) / self._gain + self._lo

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description; :meth:`from_dict` rebuilds an equal normalizer."""
        assert self.ranges is not None
        return {
            "channels": list(self.channels),
            "ranges": {c: list(self.ranges[c]) for c in self.channels},
            "clip": self.clip,
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Normalizer:
        """Rebuild from :meth:`to_dict` output; raises :class:`ConfigError` if malformed."""
        if not isinstance(d, Mapping) or not isinstance(d.get("channels"), list):
            raise ConfigError("normalizer description needs a 'channels' list")
        ranges = d.get("ranges", {})
        if not isinstance(ranges, Mapping):
            raise ConfigError("normalizer 'ranges' must be a mapping")
        clip = d.get("clip", False)
        if not isinstance(clip, bool):
            raise ConfigError("normalizer 'clip' must be true or false")
        for c in d["channels"]:
            if not isinstance(c, str):
                raise ConfigError(f"channel names must be strings, got {c!r}")
        try:
            pairs = {k: tuple(v) for k, v in ranges.items()}
        except TypeError:
            raise ConfigError("normalizer 'ranges' must map channels to [lo, hi]") from None
        return cls(tuple(d["channels"]), pairs, clip)


class CommandScaler(Estimator):
    """Scale commands into [−1, 1] by the largest absolute training command.

    One scale for channels that share a unit (DESIGN §6: both wheels by the largest
    absolute wheel command, so the demonstrated commands fill [−1, 1]); a channel in
    another unit (a gripper's opening) gets its own; a unit whose commands are all zero
    in the training data (a grasp's wheels) gets scale 1.

    Parameters
    ----------
    units
        The unit of each command column; ``None``: one unit for all (our wheels).

    Attributes
    ----------
    scale_ : float
        Largest absolute command in the training data (in the first unit: rad/s for
        wheels).
    scales_ : ndarray of shape (k,)
        Each column's scale: the largest absolute command among the columns of its unit.
    """

    def __init__(self, units: Sequence[str] | None = None) -> None:
        self.units = units

    def fit(self, commands: ArrayLike | Any) -> CommandScaler:
        """Learn the scales from commands (shape ``(n, k)``) or a ``Dataset``."""
        u = np.asarray(getattr(commands, "commands", commands), dtype=np.float64)
        if u.size == 0:
            raise DatasetError("no commands to fit the scale on")
        if not np.all(np.isfinite(u)):
            raise DatasetError("commands contain NaN or infinite values")
        u = u.reshape(len(u), -1)
        units = list(self.units) if self.units is not None else [""] * u.shape[1]
        if len(units) != u.shape[1]:
            raise DatasetError(f"{len(units)} command units for {u.shape[1]} command columns")
        peak = np.max(np.abs(u), axis=0)
        scales = np.array([max(peak[[j for j, v in enumerate(units) if v == w]]) for w in units])
        if np.all(scales == 0.0) or (np.any(scales == 0.0) and len(set(units)) == 1):
            zero = units[int(np.argmax(scales == 0.0))] or "the"
            raise DatasetError(f"all {zero} commands are zero; there is no scale to learn")
        # a command the behavior never uses (a grasp's wheels, a turn's gripper) is held at
        # rest: any scale maps its zeros to zeros, and 1 keeps its outputs in its own unit
        scales = np.where(scales == 0.0, 1.0, scales)
        self.scale_ = float(scales[0]) if len(set(units)) > 1 else float(np.max(peak))
        self.scales_ = scales
        return self

    def _scale(self) -> NDArray[np.float64] | float:
        if not hasattr(self, "scale_"):
            raise NotFittedError("CommandScaler is not fitted; call fit(commands) first")
        scales = getattr(self, "scales_", None)
        if scales is None or len(set(np.asarray(scales).tolist())) == 1:
            return self.scale_  # one unit: the scalar, bit for bit
        return np.asarray(scales, dtype=np.float64)

    def transform(self, commands: ArrayLike) -> NDArray[np.float64]:
        """Physical units -> normalized (training commands land in [−1, 1])."""
        return np.asarray(commands, dtype=np.float64) / self._scale()

    def inverse_transform(self, y: ArrayLike) -> NDArray[np.float64]:
        """Normalized -> physical units."""
        return np.asarray(y, dtype=np.float64) * self._scale()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready learned state (``scales`` only when the units differ)."""
        scale = self._scale()
        if isinstance(scale, np.ndarray):
            return {"scale": self.scale_, "scales": [float(v) for v in scale]}
        return {"scale": scale}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> CommandScaler:
        """Rebuild a fitted scaler; raises :class:`ConfigError` if malformed."""
        scale = d.get("scale") if isinstance(d, Mapping) else None
        if (
            isinstance(scale, bool)
            or not isinstance(scale, int | float)
            or not math.isfinite(scale)
            or scale <= 0
        ):
            raise ConfigError(f"command scale must be a positive finite number, got {scale!r}")
        out = cls()
        out.scale_ = float(scale)
        scales = d.get("scales")
        if scales is not None:
            values = np.asarray(scales, dtype=np.float64) if isinstance(scales, list) else None
            if values is None or values.ndim != 1 or not np.all(np.isfinite(values) & (values > 0)):
                raise ConfigError(f"command scales must be positive finite numbers, got {scales!r}")
            out.scales_ = values
        return out
