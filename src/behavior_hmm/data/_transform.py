"""What every import shares after reading: derived velocities, resampling, validation.

The readers (CSV, ROS bags, LeRobot datasets) turn a user's file into columns in
canonical units (``UNITS``); :func:`finish` then derives missing velocities, resamples
onto the control period when asked, validates, and warns when a log's sample period is
not the controller's.

Sign conventions of derived velocities (see docs/usage.md, "Importing robot data"):

``linear_velocity = −d(distance)/dt``
    The rate at which the robot closes on the object (m/s). Our sensor is the forward
    speed along the heading; the two agree when the robot faces the object (|angle|
    small, as in an approach) or does not translate (a turn in place: both 0).
    Otherwise the derived value is the forward speed times cos(angle): the part of the
    motion that changes the distance.
``angular_velocity = −d(angle)/dt``
    The bearing of a fixed object turns opposite to the robot's yaw, so minus its rate
    (deg/s, the angle unwrapped across ±180°) is the yaw rate, counter-clockwise
    positive as the sensor. It is exact for a robot turning in place; while the robot
    also drives, the bearing changes by v·sin(angle)/D besides (D the centre distance),
    which this estimate attributes to the yaw.

Derivatives are central finite differences over the time stamps (one-sided at an
episode's ends; ``numpy.gradient``), so irregular time steps are fine. Derivation runs
on the log's own samples, before any resampling.
"""

from __future__ import annotations

import warnings
from collections.abc import Collection, Mapping, Sequence
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data._channels import CONTROL_PERIOD, UNITS
from behavior_hmm.data._units import wrap_degrees
from behavior_hmm.data._validate import FLOAT_COLUMNS, check_table
from behavior_hmm.errors import ConfigError, DatasetError

#: Channels that :func:`derive_velocities` can compute, and what each is derived from.
DERIVABLE: Final[dict[str, str]] = {
    "linear_velocity": "distance",
    "angular_velocity": "angle",
}

#: Relative difference between a log's median sample period and the control period
#: beyond which an import without resampling warns.
PERIOD_TOLERANCE: Final[float] = 0.02


class DataImportWarning(UserWarning):
    """Something an import did that the user should know of (the command line prints it)."""


class SamplingWarning(DataImportWarning):
    """A log's sample period differs from the control period and it was not resampled."""


def parse_derive(items: str | Collection[str] | None) -> tuple[str, ...]:
    """``"linear_velocity,angular_velocity"`` (or a list of names) -> checked names."""
    if items is None:
        return ()
    raw = [items] if isinstance(items, str) else list(items)
    names: list[str] = []
    for item in raw:
        for name in str(item).split(","):
            name = name.strip()
            if not name:
                continue
            if name not in DERIVABLE:
                raise ConfigError(f"cannot derive '{name}' (derivable: {', '.join(DERIVABLE)})")
            if name not in names:
                names.append(name)
    return tuple(names)


def check_units_of_derived(units: Collection[str], derive: Collection[str]) -> None:
    """Refuse a unit for a derived channel (derived values are in canonical units)."""
    for name in derive:
        if name in units:
            raise ConfigError(
                f"--unit {name}: the channel is derived (--derive), in {UNITS[name]}; "
                "give units for the positions it is derived from"
            )


def _starts(episode: NDArray[np.int64]) -> NDArray[np.int64]:
    return np.flatnonzero(np.r_[True, episode[1:] != episode[:-1]]).astype(np.int64)


def _blocks(episode: NDArray[np.int64]) -> list[tuple[int, int]]:
    starts = _starts(episode)
    ends = np.r_[starts[1:], len(episode)]
    return [(int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


def _rate(values: NDArray[np.float64], t: NDArray[np.float64]) -> NDArray[np.float64]:
    if len(values) < 2:
        return np.zeros(len(values))
    out: NDArray[np.float64] = np.gradient(values, t)
    return out


def derive_velocities(
    columns: Mapping[str, NDArray[Any]], which: Collection[str]
) -> dict[str, NDArray[Any]]:
    """Columns with ``which`` velocities computed from positions (module docstring).

    ``columns`` must hold valid ``episode``, ``t`` (strictly increasing per episode),
    ``distance`` (m) and ``angle`` (deg).
    """
    out = dict(columns)
    episode = np.asarray(columns["episode"], dtype=np.int64)
    t = np.asarray(columns["t"], dtype=np.float64)
    for name in which:
        source = np.asarray(columns[DERIVABLE[name]], dtype=np.float64)
        values = np.empty(len(t))
        for a, b in _blocks(episode):
            x = source[a:b]
            if name == "angular_velocity":
                x = np.unwrap(x, period=360.0)
            values[a:b] = -_rate(x, t[a:b])
        out[name] = values + 0.0  # no -0.0
    return out


def median_period(columns: Mapping[str, NDArray[Any]]) -> float | None:
    """Median time step (s) within episodes, or ``None`` when no episode has two rows."""
    episode = np.asarray(columns["episode"])
    t = np.asarray(columns["t"], dtype=np.float64)
    same = episode[1:] == episode[:-1]
    dt = np.diff(t)[same]
    return float(np.median(dt)) if len(dt) else None


def resample(
    columns: Mapping[str, NDArray[Any]], period: float = CONTROL_PERIOD
) -> dict[str, NDArray[Any]]:
    """Each episode linearly interpolated onto ``t0, t0 + period, ...`` (up to its last t).

    Angles are interpolated unwrapped and wrapped again; ``behavior`` names hold the
    latest sample at or before each new time stamp.
    """
    if not period > 0.0:
        raise ConfigError(f"resampling period must be > 0 s, got {period}")
    episode = np.asarray(columns["episode"], dtype=np.int64)
    t = np.asarray(columns["t"], dtype=np.float64)
    parts: dict[str, list[NDArray[Any]]] = {name: [] for name in columns}
    for a, b in _blocks(episode):
        tt = t[a:b]
        n = int(np.floor((tt[-1] - tt[0]) / period + 1e-6)) + 1
        new_t = tt[0] + period * np.arange(n)
        parts["episode"].append(np.full(n, episode[a], dtype=np.int64))
        parts["t"].append(new_t)
        # the data contract's channels, and any other numeric column (a declared
        # command such as a gripper's) by the same linear interpolation
        others = [c for c in columns if c not in (*FLOAT_COLUMNS, "episode", "behavior")]
        for name in (*FLOAT_COLUMNS[1:], *others):
            if name not in columns:
                continue
            x = np.asarray(columns[name][a:b], dtype=np.float64)
            if name == "angle":
                parts[name].append(wrap_degrees(np.interp(new_t, tt, np.unwrap(x, period=360.0))))
            else:
                parts[name].append(np.interp(new_t, tt, x))
        if "behavior" in columns:
            idx = np.searchsorted(tt, new_t + 1e-12, side="right") - 1
            parts["behavior"].append(np.asarray(columns["behavior"][a:b], dtype=object)[idx])
    return {name: np.concatenate(values) for name, values in parts.items()}


def _rename_episode(err: DatasetError, names: Sequence[str] | None, note: str = "") -> DatasetError:
    """``err`` with the episode's original (string) id and a note on derived fields."""
    episode: int | str | None = err.episode
    if names is not None and isinstance(err.episode, int) and 0 <= err.episode < len(names):
        episode = names[err.episode]
    return DatasetError(
        err.reason + note, file=err.file, episode=episode, row=err.row, field=err.field
    )


def finish(
    columns: dict[str, NDArray[Any]],
    metadata: dict[str, Any],
    *,
    file: str,
    lines: NDArray[np.int64] | None = None,
    derive: Collection[str] = (),
    resample_to: float | None = None,
    episode_names: Sequence[str] | None = None,
    what: str = "log",
) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
    """Validate, derive, resample and validate again; warn on a foreign sample period.

    Parameters
    ----------
    columns
        ``episode``, ``t`` and the channels in canonical units; the ``derive`` channels
        are absent.
    metadata
        Dataset metadata; ``source`` gains ``derived`` and ``resampled`` entries.
    file
        Named in errors and the warning.
    lines
        CSV line of each row (errors on the log's own rows name it).
    derive
        Velocities to compute (:data:`DERIVABLE`).
    resample_to
        Period (s) to resample onto, or ``None`` to keep the log's time stamps.
    episode_names
        Original episode ids (strings) by integer id, for error messages.
    what
        What the file is, in the warning ("log", "bag", ...).

    Returns
    -------
    columns, metadata
        As ``check_table`` returns them.
    """
    cols = dict(columns)
    n = len(cols["episode"])
    for name in derive:
        cols[name] = np.zeros(n)  # placeholder: validate the log's own columns first
    try:
        cols, md = check_table(cols, metadata, file=file, lines=lines)
    except DatasetError as err:
        raise _rename_episode(err, episode_names) from None
    source = md.get("source")
    period = median_period(cols)
    if derive:
        cols = derive_velocities(cols, derive)
        if isinstance(source, dict):
            source["derived"] = list(derive)
    if resample_to is not None:
        cols = resample(cols, resample_to)
        if isinstance(source, dict):
            source["resampled"] = {"from_period_s": period, "to_period_s": resample_to}
    elif period is not None and abs(period - CONTROL_PERIOD) > PERIOD_TOLERANCE * CONTROL_PERIOD:
        warnings.warn(
            SamplingWarning(
                f"{file}: the {what}'s sample period is {period * 1000:.4g} ms, not the "
                f"controller's {CONTROL_PERIOD * 1000:.4g} ms; a model trained on it acts at "
                "the wrong rate (resample it onto the control period with --resample)"
            ),
            stacklevel=3,
        )
    if derive or resample_to is not None:
        try:
            cols, md = check_table(cols, md, file=file, lines=None if resample_to else lines)
        except DatasetError as err:
            origin = DERIVABLE.get(err.field or "")
            extra = f" (derived from {origin})" if origin and err.field in derive else ""
            if resample_to is not None:
                extra += " (after resampling)"
            raise _rename_episode(err, episode_names, extra) from None
    return cols, md
