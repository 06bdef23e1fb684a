"""In-memory datasets: all episodes as column arrays plus ``lengths`` (hmmlearn style)."""

from __future__ import annotations

import json
from collections.abc import Collection, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from behavior_hmm.data._channels import CHANNELS, COMMAND_CHANNELS, SENSOR_CHANNELS, ChannelSpec
from behavior_hmm.data._validate import (
    OPTIONAL_COLUMNS,
    REQUIRED_COLUMNS,
    check_column_names,
    check_table,
    declared_channels,
    declared_commands,
    own_channels_only,
    suggest,
)
from behavior_hmm.errors import ConfigError, DatasetError

#: Channels that :meth:`Dataset.columns` and :meth:`Episode.columns` can return for a
#: dataset of the standard channels (a dataset's own: ``Dataset.numeric_channels``).
NUMERIC_CHANNELS: tuple[str, ...] = ("t", *SENSOR_CHANNELS, *COMMAND_CHANNELS)


def _channel_names(
    names: str | Sequence[str], known: Sequence[str] = NUMERIC_CHANNELS
) -> list[str]:
    names = [names] if isinstance(names, str) else list(names)
    for name in names:
        if name not in known:
            raise ConfigError(
                f"unknown channel '{name}' (channels: {', '.join(known)}){suggest(name, known)}"
            )
    return names


def _readonly(a: NDArray[Any]) -> NDArray[Any]:
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Episode:
    """One demonstration: a read-only view into a :class:`Dataset`.

    Attributes
    ----------
    id
        Episode id (the ``episode`` column).
    t
        Time stamps, s, shape ``(n,)``, strictly increasing.
    sensors
        Sensor readings in ``sensor_channels`` order, shape ``(n, len(sensor_channels))``:
        the four of ``SENSOR_CHANNELS`` (m, m/s, deg, deg/s), then the dataset's declared
        channels (in their declared units).
    commands
        Commands in ``command_channels`` order, shape ``(n, k)``: by default the wheel
        speeds ``left``, ``right`` (rad/s).
    behavior
        Active sub-behavior name per row (object array of ``str``), or ``None``.
    sensor_channels
        Names of the ``sensors`` columns (default ``SENSOR_CHANNELS``).
    command_channels
        Names of the ``commands`` columns (default ``COMMAND_CHANNELS``).
    """

    id: int
    t: NDArray[np.float64]
    sensors: NDArray[np.float64]
    commands: NDArray[np.float64]
    behavior: NDArray[np.object_] | None = None
    sensor_channels: tuple[str, ...] = SENSOR_CHANNELS
    command_channels: tuple[str, ...] = COMMAND_CHANNELS

    def __len__(self) -> int:
        return len(self.t)

    @property
    def numeric_channels(self) -> tuple[str, ...]:
        """``t``, the sensor channels and the commands: what :meth:`channel` returns."""
        return ("t", *self.sensor_channels, *self.command_channels)

    def channel(self, name: str) -> NDArray[np.float64]:
        """One channel (``t``, a sensor or a command) as a read-only ``(n,)`` view."""
        (name,) = _channel_names(name, self.numeric_channels)
        if name == "t":
            return self.t
        if name in self.sensor_channels:
            return self.sensors[:, self.sensor_channels.index(name)]
        return self.commands[:, self.command_channels.index(name)]

    def columns(self, names: str | Sequence[str]) -> NDArray[np.float64]:
        """Several channels stacked as a new ``(n, k)`` float64 array."""
        names = _channel_names(names, self.numeric_channels)
        return np.stack([self.channel(n) for n in names], axis=1)

    def to_dict(self) -> dict[str, Any]:
        """Columns of this episode (copies), as accepted by :meth:`Dataset.from_episodes`."""
        out: dict[str, Any] = {"episode": self.id, "t": self.t.copy()}
        for j, name in enumerate(self.sensor_channels):
            out[name] = self.sensors[:, j].copy()
        for j, name in enumerate(self.command_channels):
            out[name] = self.commands[:, j].copy()
        if self.behavior is not None:
            out["behavior"] = self.behavior.copy()
        return out


class Dataset:
    """Validated demonstrations of one behavior, stored as column arrays.

    Construction validates everything (:func:`validate`), so every ``Dataset`` is
    well-formed. Arrays are read-only; methods return new datasets.

    Parameters
    ----------
    columns
        ``episode`` (int ids, rows of an episode contiguous), ``t`` (s), the sensor
        channels (m, m/s, deg, deg/s), ``left``, ``right`` (rad/s), one column per
        channel the metadata declares, and optionally ``behavior`` (active sub-behavior
        name per row).
    metadata
        JSON-serializable description: ``schema_version`` (set if absent), and e.g.
        ``behavior``, ``simulator``, ``robot``, ``seed``, ``noise``. ``channels`` declares
        a robot's own sensor channels beyond the four, each with unit and range, e.g.
        ``[{"name": "ir0", "unit": "m", "range": [0, 0.1]}]`` (``ChannelSpec.to_metadata``;
        ``ChannelSpec`` objects are accepted too): they become sensor columns after the
        four (``sensor_channels``), validated like them.

    Examples
    --------
    >>> import numpy as np
    >>> ep = {"t": [0.0, 0.016], "distance": [0.5, 0.5], "linear_velocity": [0.0, 0.0],
    ...       "angle": [90.0, 89.0], "angular_velocity": [0.0, -62.5],
    ...       "left": [-1.0, -1.0], "right": [1.0, 1.0]}
    >>> ds = Dataset.from_episodes([ep, ep], {"behavior": "turn"})
    >>> len(ds), ds.n_samples, ds.lengths.tolist()
    (2, 4, [2, 2])
    """

    __slots__ = (
        "_behavior",
        "_command_channels",
        "_command_specs",
        "_commands",
        "_episode",
        "_extras",
        "_ids",
        "_lengths",
        "_metadata_json",
        "_sensor_channels",
        "_sensors",
        "_starts",
        "_t",
    )

    _episode: NDArray[np.int64]
    _t: NDArray[np.float64]
    _sensors: NDArray[np.float64]
    _command_specs: tuple[ChannelSpec, ...]
    _command_channels: tuple[str, ...]
    _sensor_channels: tuple[str, ...]
    _extras: tuple[ChannelSpec, ...]
    _commands: NDArray[np.float64]
    _behavior: NDArray[np.object_] | None
    _metadata_json: str
    _starts: NDArray[np.int64]
    _lengths: NDArray[np.int64]
    _ids: NDArray[np.int64]

    def __init__(
        self, columns: Mapping[str, ArrayLike], metadata: Mapping[str, Any] | None = None
    ) -> None:
        cols, md = check_table(columns, metadata)
        self._set(cols, md)

    @classmethod
    def _trusted(cls, columns: Mapping[str, NDArray[Any]], metadata: dict[str, Any]) -> Dataset:
        """Build from the output of ``check_table`` without validating again."""
        ds = cls.__new__(cls)
        ds._set(columns, metadata)
        return ds

    def _set(self, cols: Mapping[str, NDArray[Any]], md: dict[str, Any]) -> None:
        self._episode = _readonly(np.ascontiguousarray(cols["episode"], dtype=np.int64))
        self._t = _readonly(np.ascontiguousarray(cols["t"], dtype=np.float64))
        self._extras = declared_channels(md)
        # the data contract's four, unless the dataset holds a robot's own channels only
        contract = tuple(c for c in SENSOR_CHANNELS if c in cols)
        self._sensor_channels = (*contract, *(spec.name for spec in self._extras))
        self._sensors = _readonly(np.stack([cols[c] for c in self._sensor_channels], axis=1))
        self._command_specs = declared_commands(md)
        self._command_channels = tuple(spec.name for spec in self._command_specs)
        self._commands = _readonly(np.stack([cols[c] for c in self._command_channels], axis=1))
        behavior = cols.get("behavior")
        self._behavior = None if behavior is None else _readonly(np.asarray(behavior, object))
        self._metadata_json = json.dumps(md, sort_keys=True)
        ep = self._episode
        starts = np.flatnonzero(np.r_[True, ep[1:] != ep[:-1]]).astype(np.int64)
        self._starts = _readonly(starts)
        self._lengths = _readonly(np.diff(np.r_[starts, len(ep)]).astype(np.int64))
        self._ids = _readonly(ep[starts].copy())

    # -- construction -----------------------------------------------------------------

    @classmethod
    def from_episodes(
        cls,
        episodes: Iterable[Episode | Mapping[str, Any]],
        metadata: Mapping[str, Any] | None = None,
    ) -> Dataset:
        """Build a dataset from episodes.

        Parameters
        ----------
        episodes
            :class:`Episode` objects or mappings of columns (``t``, sensors, ``left``,
            ``right``, the channels ``metadata`` declares; optional ``episode`` id,
            default its position; optional ``behavior``, one name per row or one name
            for the whole episode).
        metadata
            See :class:`Dataset`.
        """
        episodes = list(episodes)
        extra = [spec.name for spec in declared_channels(metadata)]
        commands = tuple(spec.name for spec in declared_commands(metadata))
        base = (c for c in REQUIRED_COLUMNS if c not in COMMAND_CHANNELS)
        names_needed: tuple[str, ...] = (*base, *commands, *extra)
        first = episodes[0] if episodes else {}
        first_names = first.to_dict() if isinstance(first, Episode) else first
        if isinstance(first_names, Mapping) and own_channels_only(first_names, extra):
            names_needed = tuple(c for c in names_needed if c not in SENSOR_CHANNELS)
        parts: dict[str, list[NDArray[Any]]] = {c: [] for c in (*names_needed, "behavior")}
        with_behavior: list[bool] = []
        for position, item in enumerate(episodes):
            if isinstance(item, Episode):
                item = item.to_dict()
            if not isinstance(item, Mapping):
                raise DatasetError(
                    f"expected a mapping of columns or an Episode, got {type(item).__name__}",
                    episode=position,
                )
            names = list(item)
            if "episode" not in item:
                names.append("episode")
            eid = item.get("episode", position)
            try:
                check_column_names(names, extra=extra, commands=commands)
            except DatasetError as err:
                raise DatasetError(err.reason, episode=eid, field=err.field) from None
            t = np.asarray(item["t"])
            n = len(t) if t.ndim == 1 else -1
            if n == 0:
                raise DatasetError("empty episode (no rows)", episode=eid)
            if np.ndim(eid) != 0:
                raise DatasetError("episode id must be one integer", episode=position)
            parts["episode"].append(np.full(max(n, 0), eid))
            for name in names_needed[1:]:
                parts[name].append(np.asarray(item[name]))
            with_behavior.append("behavior" in item)
            if "behavior" in item:
                b = item["behavior"]
                b_arr = np.full(max(n, 0), b, dtype=object) if isinstance(b, str) else b
                parts["behavior"].append(np.asarray(b_arr, dtype=object))
        if any(with_behavior) and not all(with_behavior):
            missing = with_behavior.index(False)
            raise DatasetError(
                "'behavior' is given for some episodes but not this one",
                episode=missing,
                field="behavior",
            )
        if not with_behavior:
            raise DatasetError("no episodes (empty dataset)")
        columns: dict[str, Any] = {}
        for name, arrays in parts.items():
            if name == "behavior" and not any(with_behavior):
                continue
            try:
                columns[name] = np.concatenate(arrays)
            except ValueError as exc:
                raise DatasetError(f"columns of different shapes ({exc})", field=name) from None
        return cls(columns, metadata)

    # -- sizes and ids ----------------------------------------------------------------

    def __len__(self) -> int:
        """Number of episodes."""
        return len(self._ids)

    @property
    def n_samples(self) -> int:
        """Number of rows over all episodes."""
        return len(self._t)

    @property
    def lengths(self) -> NDArray[np.int64]:
        """Rows per episode, shape ``(n_episodes,)`` (hmmlearn's ``lengths``)."""
        return self._lengths

    @property
    def offsets(self) -> NDArray[np.int64]:
        """Row where each episode starts, plus ``n_samples`` at the end: ``(n_episodes + 1,)``.

        Episode ``i`` is rows ``offsets[i]:offsets[i + 1]``.
        """
        return np.r_[self._starts, len(self._t)]

    @property
    def episode_ids(self) -> NDArray[np.int64]:
        """Id of each episode, in order, shape ``(n_episodes,)``."""
        return self._ids

    @property
    def has_behavior(self) -> bool:
        """Whether the dataset has a ``behavior`` column (complex demonstrations)."""
        return self._behavior is not None

    @property
    def behaviors(self) -> list[str]:
        """Sorted names in the ``behavior`` column (empty without one)."""
        if self._behavior is None:
            return []
        return sorted(set(self._behavior.tolist()))

    @property
    def sensor_channels(self) -> tuple[str, ...]:
        """Names of the ``sensors`` columns: ``SENSOR_CHANNELS``, then the declared ones."""
        return self._sensor_channels

    @property
    def channel_specs(self) -> list[ChannelSpec]:
        """The :class:`ChannelSpec` of each sensor channel, in ``sensor_channels`` order.

        The four of the data contract come from ``CHANNELS``, the others from the
        metadata's ``channels`` declarations.
        """
        contract = [CHANNELS[n] for n in SENSOR_CHANNELS if n in self._sensor_channels]
        return contract + list(self._extras)

    @property
    def numeric_channels(self) -> tuple[str, ...]:
        """``t``, the sensor channels and the commands: what :meth:`column` returns."""
        return ("t", *self._sensor_channels, *self._command_channels)

    @property
    def command_channels(self) -> tuple[str, ...]:
        """Names of the ``commands`` columns, in action order (default ``left``, ``right``)."""
        return self._command_channels

    @property
    def command_specs(self) -> list[ChannelSpec]:
        """The :class:`ChannelSpec` of each command channel (the metadata's ``commands``)."""
        return list(self._command_specs)

    @property
    def metadata(self) -> dict[str, Any]:
        """A fresh copy of the metadata (editing it changes nothing; see ``with_metadata``)."""
        out: dict[str, Any] = json.loads(self._metadata_json)
        return out

    # -- column access ----------------------------------------------------------------

    @property
    def t(self) -> NDArray[np.float64]:
        """The ``t`` column (s), shape ``(n_samples,)``."""
        return self._t

    @property
    def sensors(self) -> NDArray[np.float64]:
        """All sensor columns in ``sensor_channels`` order, ``(n_samples, 4 + declared)``."""
        return self._sensors

    @property
    def commands(self) -> NDArray[np.float64]:
        """Commands in ``command_channels`` order, shape ``(n_samples, k)``: by default
        the wheel speeds ``left``, ``right`` (rad/s)."""
        return self._commands

    @property
    def behavior(self) -> NDArray[np.object_] | None:
        """The ``behavior`` column (object array of ``str``) or ``None``."""
        return self._behavior

    def column(self, name: str) -> NDArray[np.float64]:
        """One numeric channel as a read-only ``(n_samples,)`` view."""
        (name,) = _channel_names(name, self.numeric_channels)
        if name == "t":
            return self._t
        if name in self._sensor_channels:
            return self._sensors[:, self._sensor_channels.index(name)]
        return self._commands[:, self._command_channels.index(name)]

    def columns(self, names: str | Sequence[str]) -> NDArray[np.float64]:
        """Several channels stacked as a new ``(n_samples, k)`` float64 array."""
        names = _channel_names(names, self.numeric_channels)
        return np.stack([self.column(n) for n in names], axis=1)

    def to_columns(self) -> dict[str, NDArray[Any]]:
        """All columns as writable copies, in file order (``behavior`` last if present).

        File order: ``episode``, ``t``, the sensor channels (``sensor_channels``),
        the command channels (``command_channels``).
        """
        out: dict[str, NDArray[Any]] = {"episode": self._episode.copy(), "t": self._t.copy()}
        for j, name in enumerate(self._sensor_channels):
            out[name] = self._sensors[:, j].copy()
        for j, name in enumerate(self._command_channels):
            out[name] = self._commands[:, j].copy()
        if self._behavior is not None:
            out["behavior"] = self._behavior.copy()
        return out

    # -- episodes ---------------------------------------------------------------------

    def episode(self, i: int) -> Episode:
        """The ``i``-th episode (by position, not id) as a view."""
        n = len(self)
        if not -n <= i < n:
            raise IndexError(f"episode position {i} out of range for {n} episodes")
        i %= n
        a, b = int(self._starts[i]), int(self._starts[i]) + int(self._lengths[i])
        behavior = None if self._behavior is None else self._behavior[a:b]
        return Episode(
            int(self._ids[i]),
            self._t[a:b],
            self._sensors[a:b],
            self._commands[a:b],
            behavior,
            self._sensor_channels,
            self._command_channels,
        )

    def episodes(self) -> Iterator[Episode]:
        """Iterate over the episodes in order."""
        for i in range(len(self)):
            yield self.episode(i)

    def __iter__(self) -> Iterator[Episode]:
        return self.episodes()

    # -- new datasets -----------------------------------------------------------------

    def subset(self, positions: Sequence[int] | NDArray[np.integer[Any]]) -> Dataset:
        """A dataset of the episodes at ``positions`` (e.g. a train/test split), in that order."""
        idx = np.asarray(positions, dtype=np.int64).reshape(-1)
        if len(idx) and (idx.min() < -len(self) or idx.max() >= len(self)):
            raise IndexError(f"episode positions out of range for {len(self)} episodes")
        if len(np.unique(idx % max(len(self), 1))) != len(idx):
            raise ConfigError("subset positions repeat an episode")
        return Dataset.from_episodes([self.episode(int(i)) for i in idx], self.metadata)

    def concat(
        self,
        other: Dataset,
        *,
        renumber: bool = False,
        metadata: Mapping[str, Any] | None = None,
    ) -> Dataset:
        """This dataset's episodes followed by ``other``'s.

        Parameters
        ----------
        renumber
            Give the result's episodes ids ``0 .. n-1``; without it, ids must differ.
        metadata
            Metadata of the result (default: this dataset's).
        """
        if self.has_behavior != other.has_behavior:
            raise DatasetError(
                "cannot concatenate a dataset with a 'behavior' column and one without",
                field="behavior",
            )
        if self._extras != other._extras:
            mine = ", ".join(s.name for s in self._extras) or "none"
            theirs = ", ".join(s.name for s in other._extras) or "none"
            raise DatasetError(
                f"cannot concatenate datasets with different declared channels ({mine} vs "
                f"{theirs}, or different units or ranges)",
                field="channels",
            )
        a, b = self.to_columns(), other.to_columns()
        cols = {name: np.concatenate([a[name], b[name]]) for name in a}
        if renumber:
            counts = np.r_[self._lengths, other._lengths]
            cols["episode"] = np.repeat(np.arange(len(counts), dtype=np.int64), counts)
        else:
            common = np.intersect1d(self._ids, other._ids)
            if len(common):
                raise DatasetError(
                    "episode id is in both datasets (pass renumber=True)",
                    episode=int(common[0]),
                    field="episode",
                )
        return Dataset(cols, self.metadata if metadata is None else metadata)

    def with_metadata(self, updates: Mapping[str, Any] | None = None, /, **kw: Any) -> Dataset:
        """A copy with metadata keys added or replaced (``updates`` and keywords)."""
        md = self.metadata
        md.update(updates or {})
        md.update(kw)
        return Dataset(self.to_columns(), md)

    def check_behaviors(self, known: Collection[str], *, file: str | None = None) -> None:
        """Refuse behavior names outside ``known`` (first offending row named)."""
        check_table(self.to_columns(), self.metadata, file=file, behaviors=known)

    # -- comparison and display -------------------------------------------------------

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Dataset):
            return NotImplemented
        same_behavior = (self._behavior is None and other._behavior is None) or (
            self._behavior is not None
            and other._behavior is not None
            and np.array_equal(self._behavior, other._behavior)
        )
        return (
            same_behavior
            and np.array_equal(self._episode, other._episode)
            and np.array_equal(self._t, other._t)
            and np.array_equal(self._sensors, other._sensors)
            and np.array_equal(self._commands, other._commands)
            and self.metadata == other.metadata
        )

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        md = self.metadata
        extra = f", behavior={md['behavior']!r}" if md.get("behavior") else ""
        if self._behavior is not None:
            extra += f", sub-behaviors={self.behaviors}"
        if self._extras:
            extra += f", channels+={[spec.name for spec in self._extras]}"
        return f"Dataset({len(self)} episodes, {self.n_samples} samples{extra})"


__all__ = ["NUMERIC_CHANNELS", "OPTIONAL_COLUMNS", "Dataset", "Episode"]
