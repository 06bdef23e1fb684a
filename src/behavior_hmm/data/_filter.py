"""Causal second-order low-pass filter, offline over an episode and online per sample.

Both paths give the same numbers: scipy designs the Butterworth biquad and runs it
offline (``sosfilt``); the online path is a hand-written transposed-direct-form-II
update with the same operations in the same order (~0.2 µs a sample instead of
~25 µs for a per-sample ``sosfilt`` call). Both start at the steady state of the
first sample, so a constant signal passes unchanged.

Angles jump from +180 to −180 when the object passes behind the robot; with
``wrap="deg"`` the filter runs on the unwrapped angle and wraps its output back
into (−180, 180].
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Final, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import butter, group_delay, sos2tf, sosfilt, sosfilt_zi

from behavior_hmm.data._channels import CHANNELS, CONTROL_PERIOD, SENSOR_RANGES
from behavior_hmm.data._normalize import Normalizer
from behavior_hmm.data._units import wrap_degree, wrap_degrees
from behavior_hmm.errors import ConfigError

if TYPE_CHECKING:
    from behavior_hmm.data._dataset import Dataset

#: Channels holding angles in degrees; the pipeline filters them with ``wrap="deg"``.
ANGLE_CHANNELS: Final[frozenset[str]] = frozenset(n for n, s in CHANNELS.items() if s.wraps)

#: Default cut-off frequency of the low-pass filter, Hz (the ``default`` preset; the thesis
#: gives none and the ``thesis`` preset keeps the 4 Hz this project started from). The
#: jerk-limited demonstrations change slowly (nominal scores within 0.2 points of 4 Hz's;
#: docs/algorithms.md), while sensor noise of 0.01 × a channel's range (3.6 deg, 12 mm)
#: passes a 4 Hz filter strongly enough to switch primitives every few cycles.
DEFAULT_CUTOFF_HZ: Final[float] = 2.0


def _unwrap_degrees(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Remove 360° jumps along axis 0 (same arithmetic as :class:`OnlineFilter`)."""
    u = x.copy()
    if len(x) > 1:
        turns = np.cumsum(np.round(np.diff(x, axis=0) / 360.0), axis=0)
        u[1:] = x[1:] + (-360.0 * turns)
    return u


@dataclass(frozen=True)
class LowPassFilter:
    """Second-order Butterworth low-pass filter (causal).

    Parameters
    ----------
    cutoff_hz
        Cut-off frequency, Hz; must be below ``fs / 2``.
    fs
        Sampling rate, Hz (default one sample per 16 ms control period).
    wrap
        ``"deg"`` for angles in degrees: filter the unwrapped angle, wrap the
        output into (−180, 180]. ``None`` for ordinary signals.

    Examples
    --------
    >>> f = LowPassFilter(4.0)
    >>> y = f.filter_episode([1.0, 1.0, 1.0])  # a constant passes unchanged (to rounding)
    >>> bool(np.allclose(y, 1.0, rtol=1e-12))
    True
    """

    cutoff_hz: float = DEFAULT_CUTOFF_HZ
    fs: float = 1.0 / CONTROL_PERIOD
    wrap: Literal["deg"] | None = None
    sos: NDArray[np.float64] = field(init=False, repr=False, compare=False)
    zi: NDArray[np.float64] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if isinstance(self.fs, bool) or not isinstance(self.fs, int | float):
            raise ConfigError(f"sampling rate fs must be a number, got {self.fs!r}")
        if isinstance(self.cutoff_hz, bool) or not isinstance(self.cutoff_hz, int | float):
            raise ConfigError(f"cutoff_hz must be a number, got {self.cutoff_hz!r}")
        if not (math.isfinite(self.fs) and self.fs > 0):
            raise ConfigError(f"sampling rate fs must be positive, got {self.fs} Hz")
        if not (math.isfinite(self.cutoff_hz) and 0 < self.cutoff_hz < self.fs / 2):
            raise ConfigError(
                f"cutoff_hz must be in (0, fs/2) = (0, {self.fs / 2:g}) Hz, got {self.cutoff_hz}"
            )
        if self.wrap not in (None, "deg"):
            raise ConfigError(f"wrap must be None or 'deg', got {self.wrap!r}")
        sos = np.asarray(butter(2, self.cutoff_hz, fs=self.fs, output="sos"), dtype=np.float64)
        object.__setattr__(self, "sos", sos)
        object.__setattr__(self, "zi", np.asarray(sosfilt_zi(sos), dtype=np.float64))

    def filter_episode(self, x: ArrayLike) -> NDArray[np.float64]:
        """Filter one episode causally, starting at the steady state of its first sample.

        Parameters
        ----------
        x
            Samples, shape ``(n,)`` or ``(n, c)`` (``c`` channels filtered independently).

        Returns
        -------
        ndarray
            Filtered samples, same shape.
        """
        a = np.asarray(x, dtype=np.float64)
        if a.ndim not in (1, 2):
            raise ConfigError(f"expected samples of shape (n,) or (n, c), got {a.shape}")
        if len(a) == 0:
            return a.copy()
        u = _unwrap_degrees(a) if self.wrap == "deg" else a
        zi = self.zi * u[0] if u.ndim == 1 else self.zi[:, :, None] * u[0][None, None, :]
        y, _ = sosfilt(self.sos, u, axis=0, zi=zi)
        y = np.asarray(y, dtype=np.float64)
        return wrap_degrees(y) if self.wrap == "deg" else y

    @property
    def lag_samples(self) -> float:
        """How many samples the output of a steadily changing signal trails its input.

        The filter's group delay at 0 Hz: a ramp of slope ``r`` per sample comes out
        ``r * lag_samples`` behind (once the start-up transient has passed).
        """
        _, delay = group_delay(sos2tf(self.sos), w=[0.0])
        return float(delay[0])

    def online(self) -> OnlineFilter:
        """A fresh per-sample filter with the same coefficients."""
        return OnlineFilter(self)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready parameters."""
        return {"cutoff_hz": self.cutoff_hz, "fs": self.fs, "wrap": self.wrap}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> LowPassFilter:
        """Rebuild from :meth:`to_dict` output; raises :class:`ConfigError` if malformed."""
        if not isinstance(d, Mapping):
            raise ConfigError("filter description must be a mapping")
        return cls(
            d.get("cutoff_hz", DEFAULT_CUTOFF_HZ), d.get("fs", 1.0 / CONTROL_PERIOD), d.get("wrap")
        )


class OnlineFilter:
    """:class:`LowPassFilter` one sample at a time, with the offline filter's exact numbers.

    The first :meth:`step` (or :meth:`reset`) fixes the number of channels and
    starts at the steady state of that sample.

    Examples
    --------
    >>> f = LowPassFilter(4.0)
    >>> online = f.online()
    >>> offline = f.filter_episode([1.0, 2.0, 3.0])
    >>> [online.step(v) for v in (1.0, 2.0, 3.0)] == offline.tolist()
    True
    """

    __slots__ = (
        "_a1",
        "_a2",
        "_b0",
        "_b1",
        "_b2",
        "_prev",
        "_ready",
        "_turns",
        "_wrap",
        "_z0",
        "_z1",
        "_zi0",
        "_zi1",
    )

    def __init__(self, filt: LowPassFilter) -> None:
        b0, b1, b2, _a0, a1, a2 = filt.sos[0].tolist()
        self._b0, self._b1, self._b2, self._a1, self._a2 = b0, b1, b2, a1, a2
        self._zi0, self._zi1 = filt.zi[0].tolist()
        self._wrap = filt.wrap == "deg"
        self._z0: list[float] = []
        self._z1: list[float] = []
        self._prev: list[float] = []
        self._turns: list[float] = []
        self._ready = False

    def reset(self, x0: float | ArrayLike) -> None:
        """Set the state to the steady state of ``x0`` (scalar or one value per channel)."""
        values: list[float] = np.asarray(x0, dtype=float).ravel().tolist()
        self._z0 = [self._zi0 * v for v in values]
        self._z1 = [self._zi1 * v for v in values]
        self._prev = list(values)
        self._turns = [0.0] * len(values)
        self._ready = True

    def _step(self, i: int, v: float) -> float:
        """Advance channel ``i`` by sample ``v`` (no checks: the hot path)."""
        if self._wrap:
            r = (v - self._prev[i]) / 360.0
            self._prev[i] = v
            turns = self._turns[i] + round(r) if math.isfinite(r) else math.nan
            self._turns[i] = turns
            v = v + (-360.0 * turns)
        # Transposed direct form II, operation for operation as scipy's sosfilt.
        y = self._b0 * v + self._z0[i]
        self._z0[i] = self._b1 * v - self._a1 * y + self._z1[i]
        self._z1[i] = self._b2 * v - self._a2 * y
        return wrap_degree(y) if self._wrap else y

    def step(self, x: float | ArrayLike) -> Any:
        """Filter one sample: a float for a scalar, an array for one value per channel."""
        if isinstance(x, float | int):
            if not self._ready:
                self.reset(x)
            elif len(self._z0) != 1:
                raise ConfigError(f"filter has {len(self._z0)} channels, got a scalar")
            return self._step(0, float(x))
        values = np.asarray(x, dtype=float).ravel().tolist()
        if not self._ready:
            self.reset(values)
        elif len(values) != len(self._z0):
            raise ConfigError(f"filter has {len(self._z0)} channels, got {len(values)} values")
        return np.array([self._step(i, v) for i, v in enumerate(values)])


@dataclass(frozen=True)
class SignalPipeline:
    """Low-pass filter then normalize several channels, identically offline and online.

    Training data go through :meth:`offline` (or :meth:`transform` for a whole
    dataset); at run time :meth:`online` gives a stepper with the same numbers.

    Parameters
    ----------
    channels
        Channel names, in column order (angles, see ``ANGLE_CHANNELS``, are
        filtered with wrapping).
    cutoff_hz
        Low-pass cut-off, Hz; ``None`` for no filtering.
    fs
        Sampling rate, Hz.
    ranges
        Normalization ranges (see :class:`Normalizer`).
    """

    channels: tuple[str, ...]
    cutoff_hz: float | None = DEFAULT_CUTOFF_HZ
    fs: float = 1.0 / CONTROL_PERIOD
    ranges: Mapping[str, tuple[float, float]] | None = None
    normalizer: Normalizer = field(init=False, repr=False, compare=False)
    filters: tuple[LowPassFilter, ...] | None = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        norm = Normalizer(self.channels, self.ranges)
        object.__setattr__(self, "channels", norm.channels)
        object.__setattr__(self, "ranges", norm.ranges)
        object.__setattr__(self, "normalizer", norm)
        filters = None
        if self.cutoff_hz is not None:
            filters = tuple(
                LowPassFilter(
                    self.cutoff_hz, self.fs, "deg" if c in CHANNELS and CHANNELS[c].wraps else None
                )
                for c in norm.channels
            )
        object.__setattr__(self, "filters", filters)

    @classmethod
    def for_dataset(
        cls, dataset: Dataset, channels: Sequence[str], cutoff_hz: float | None
    ) -> SignalPipeline:
        """The pipeline for ``channels`` of a dataset, at its robot's rate and ranges.

        The sampling rate is ``1 / metadata["control_period"]`` (default 16 ms); each
        channel's normalization range is the robot's (``metadata["ranges"]``, written by
        ``collect`` from the env's ``channel_ranges``), else a channel the dataset
        declares (``metadata["channels"]``), else the data contract's.
        """
        meta = dataset.metadata
        period = float(meta.get("control_period") or CONTROL_PERIOD)
        ranges: dict[str, tuple[float, float]] = {}
        for spec in getattr(dataset, "channel_specs", ()) or ():
            if spec.name in channels and spec.name not in SENSOR_RANGES:
                ranges[spec.name] = spec.range
        for name, pair in dict(meta.get("ranges") or {}).items():
            if name in channels:
                ranges[name] = (float(pair[0]), float(pair[1]))
        return cls(tuple(channels), cutoff_hz, 1.0 / period, ranges or None)

    def offline(self, x: ArrayLike) -> NDArray[np.float64]:
        """Filter and normalize one episode, shape ``(n, k)`` in channel order."""
        a = np.asarray(x, dtype=np.float64)
        if a.ndim != 2 or a.shape[1] != len(self.channels):
            raise ConfigError(
                f"expected shape (n, {len(self.channels)}) for channels {self.channels}, "
                f"got {a.shape}"
            )
        if self.filters is not None:
            a = np.stack([f.filter_episode(a[:, j]) for j, f in enumerate(self.filters)], axis=1)
        return self.normalizer.transform(a)

    def transform(self, ds: Dataset) -> NDArray[np.float64]:
        """Apply :meth:`offline` to every episode of ``ds``; shape ``(n_samples, k)``.

        Each episode is filtered from its own first sample, as at run time.
        """
        x = ds.columns(self.channels)
        offsets = ds.offsets
        out = np.empty_like(x)
        for a, b in zip(offsets[:-1].tolist(), offsets[1:].tolist(), strict=True):
            out[a:b] = self.offline(x[a:b])
        return out

    def online(self) -> OnlinePipeline:
        """A fresh per-sample stepper."""
        return OnlinePipeline(self)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready parameters (store them in the model)."""
        assert self.ranges is not None
        return {
            "channels": list(self.channels),
            "cutoff_hz": self.cutoff_hz,
            "fs": self.fs,
            "ranges": {c: list(self.ranges[c]) for c in self.channels},
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> SignalPipeline:
        """Rebuild from :meth:`to_dict` output; raises :class:`ConfigError` if malformed."""
        if not isinstance(d, Mapping):
            raise ConfigError("pipeline description must be a mapping")
        norm = Normalizer.from_dict({"channels": d.get("channels"), "ranges": d.get("ranges", {})})
        return cls(
            norm.channels,
            d.get("cutoff_hz", DEFAULT_CUTOFF_HZ),
            d.get("fs", 1.0 / CONTROL_PERIOD),
            norm.ranges,
        )


class OnlinePipeline:
    """Per-sample twin of :meth:`SignalPipeline.offline` (same numbers)."""

    __slots__ = ("_filters", "_gain", "_k", "_lo", "_ready")

    def __init__(self, pipeline: SignalPipeline) -> None:
        filters = pipeline.filters
        self._filters = None if filters is None else [f.online() for f in filters]
        norm = pipeline.normalizer
        self._lo: list[float] = norm._lo.tolist()
        self._gain: list[float] = norm._gain.tolist()
        self._k = len(pipeline.channels)
        self._ready = False

    def reset(self, x0: Sequence[float] | ArrayLike | None = None) -> None:
        """Start a new episode; with ``x0`` the filters start at its steady state,
        otherwise at the next sample's."""
        self._ready = False
        if x0 is not None:
            values = self._values(x0)
            if self._filters is not None:
                for f, v in zip(self._filters, values, strict=True):
                    f.reset(v)
            self._ready = True

    def _values(self, x: Sequence[float] | ArrayLike) -> list[float]:
        values: list[float] = np.asarray(x, dtype=float).ravel().tolist()
        if len(values) != self._k:
            raise ConfigError(f"expected {self._k} values per sample, got {len(values)}")
        return values

    def step(self, x: Sequence[float] | ArrayLike) -> NDArray[np.float64]:
        """Filter and normalize one sample (physical units, channel order) -> ``(k,)``."""
        values = self._values(x)
        if not self._ready:
            self.reset(values)
        lo, gain = self._lo, self._gain
        if self._filters is None:
            out = [(v - lo[j]) * gain[j] - 1.0 for j, v in enumerate(values)]
        else:
            filters = self._filters
            out = [(filters[j]._step(0, v) - lo[j]) * gain[j] - 1.0 for j, v in enumerate(values)]
        return np.array(out)
