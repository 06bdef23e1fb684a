"""Every channel of the data contract, declared once (DESIGN §4, §9).

A :class:`ChannelSpec` says what one sensor or command channel is: its unit, its
normalization range, its goal tolerance, whether it wraps (an angle), the units an
imported log may use, the range a value must lie in to be believed, and its plot label.
Every other table of the package (``SENSOR_CHANNELS``, ``UNITS``, ``SENSOR_RANGES``,
the validator's bounds, the importers' unit factors, the filter's angle channels, the
goal tolerances, the plot labels) is derived from :data:`CHANNELS`.

A robot's own sensor channels (e.g. eight infrared proximity readings) are declared
the same way, in a dataset's metadata (``"channels": [{"name": ..., "unit": ...,
"range": [lo, hi]}, ...]``, see :func:`channel_from_metadata`), or from Python with
:func:`register_channel`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, Final, Literal

from behavior_hmm.errors import ConfigError

#: Control period of every recording and of closed-loop generation on our robots (s).
CONTROL_PERIOD: Final[float] = 0.016

_RPM: Final[float] = 2.0 * math.pi / 60.0
_DEG: Final[float] = math.pi / 180.0
#: What a channel's ``mirror`` may say besides another channel's name.
MIRROR_PARITIES: Final[tuple[str, ...]] = ("even", "odd")
#: A channel name: a lowercase identifier.
CHANNEL_NAME: Final[re.Pattern[str]] = re.compile(r"[a-z][a-z0-9_]{0,63}\Z")


@dataclass(frozen=True)
class ChannelSpec:
    """One channel: what it measures and how the package treats it.

    Parameters
    ----------
    name
        Column name (lowercase identifier).
    unit
        Physical unit of the stored values (e.g. ``"m"``, ``"deg/s"``, ``"rad/s"``).
    range
        ``(lo, hi)`` in ``unit``: mapped onto [-1, 1] by normalization; sensor noise
        ``--noise SIGMA`` has standard deviation ``SIGMA * (hi - lo)``.
    kind
        ``"sensor"`` or ``"command"``.
    tolerance
        Goal tolerance in ``unit`` (a goal on this channel is reached within it);
        ``None``: the channel cannot be a goal.
    wraps
        True for an angle in degrees, wrapped into (-180, 180]: differences and the
        low-pass filter wrap too.
    bounds
        Values outside ``(lo, hi)`` are refused on import as absurd (wrong units?);
        default ten times the normalization range around its centre.
    units
        Units an imported log may use for this channel, with the factor converting a
        value in that unit into ``unit``; ``unit`` itself is always accepted.
    label
        Human-readable name for plots and reports (default: ``name`` with spaces).
    rest
        For a command channel: the command that holds the robot still (wheels: 0 rad/s),
        sent whenever a run stops.
    mirror
        What the channel reads in the robot's left–right mirror image: ``"even"`` (the
        same: a distance, a speed forward), ``"odd"`` (negated: a bearing, a yaw rate)
        or the name of the channel it trades places with (the left wheel's command is
        the right wheel's); ``None``: not declared, so demonstrations holding it cannot
        be mirrored (``mirror=True`` of a model, :func:`behavior_hmm.data.mirrored`).
        Not part of equality: it adds to what a channel means, it does not change it.
    """

    name: str
    unit: str
    range: tuple[float, float]
    kind: Literal["sensor", "command"] = "sensor"
    tolerance: float | None = None
    wraps: bool = False
    bounds: tuple[float, float] | None = None
    units: Mapping[str, float] = field(default_factory=dict)
    label: str = ""
    rest: float = 0.0
    mirror: str | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not CHANNEL_NAME.match(self.name):
            raise ConfigError(
                f"channel name {self.name!r} must be a lowercase identifier (a-z, 0-9, _)"
            )
        if self.name in ("t", "episode", "behavior"):
            raise ConfigError(f"'{self.name}' is a reserved column, not a channel")
        if self.kind not in ("sensor", "command"):
            raise ConfigError(f"channel {self.name}: kind must be 'sensor' or 'command'")
        try:
            lo, hi = (float(v) for v in self.range)
        except (TypeError, ValueError):
            raise ConfigError(
                f"channel {self.name}: range must be [lo, hi], got {self.range!r}"
            ) from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ConfigError(f"channel {self.name}: range must satisfy lo < hi, got {lo}, {hi}")
        object.__setattr__(self, "range", (lo, hi))
        if self.tolerance is not None:
            tol = float(self.tolerance)
            if not (math.isfinite(tol) and tol > 0):
                raise ConfigError(f"channel {self.name}: tolerance must be > 0, got {tol}")
            object.__setattr__(self, "tolerance", tol)
        if self.bounds is None:
            mid, half = (lo + hi) / 2.0, (hi - lo) / 2.0
            bounds = (-180.0, 180.0) if self.wraps else (mid - 10.0 * half, mid + 10.0 * half)
            object.__setattr__(self, "bounds", bounds)
        units = {self.unit: 1.0, **{str(k): float(v) for k, v in dict(self.units).items()}}
        object.__setattr__(self, "units", units)
        if not self.label:
            object.__setattr__(self, "label", self.name.replace("_", " "))
        try:
            rest = float(self.rest)
        except (TypeError, ValueError):
            raise ConfigError(f"channel {self.name}: rest must be a number") from None
        if not math.isfinite(rest):
            raise ConfigError(f"channel {self.name}: rest must be finite, got {rest}")
        object.__setattr__(self, "rest", rest)
        if self.mirror is not None and (
            not isinstance(self.mirror, str)
            or not (self.mirror in MIRROR_PARITIES or CHANNEL_NAME.match(self.mirror))
            or self.mirror == self.name
        ):
            raise ConfigError(
                f"channel {self.name}: mirror must be 'even', 'odd' or the name of another "
                f"channel it trades places with, got {self.mirror!r}"
            )

    @property
    def axis_label(self) -> str:
        """``"label (unit)"`` for a plot axis."""
        return f"{self.label} ({self.unit})"

    def error(self, value: float, target: float) -> float:
        """Signed ``value - target`` in the channel's unit (wrapped for an angle)."""
        diff = float(value) - float(target)
        if self.wraps:
            diff = (diff + 180.0) % 360.0 - 180.0
        return diff

    def to_metadata(self) -> dict[str, Any]:
        """The JSON form a dataset's metadata carries (see :func:`channel_from_metadata`)."""
        out: dict[str, Any] = {"name": self.name, "unit": self.unit, "range": list(self.range)}
        if self.kind != "sensor":
            out["kind"] = self.kind
        if self.tolerance is not None:
            out["tolerance"] = self.tolerance
        if self.wraps:
            out["wraps"] = True
        if self.label != self.name.replace("_", " "):
            out["label"] = self.label
        if self.rest != 0.0:
            out["rest"] = self.rest
        if self.mirror is not None:
            out["mirror"] = self.mirror
        return out


_SPECS: tuple[ChannelSpec, ...] = (
    ChannelSpec(
        "distance",
        "m",
        (0.0, 1.2),
        tolerance=0.01,
        bounds=(-0.5, 10.0),
        units={"cm": 1e-2, "mm": 1e-3},
        label="distance to the object",
        mirror="even",
    ),
    ChannelSpec(
        "linear_velocity",
        "m/s",
        (-0.15, 0.15),
        tolerance=0.01,
        bounds=(-5.0, 5.0),
        units={"cm/s": 1e-2, "mm/s": 1e-3},
        label="linear velocity",
        mirror="even",
    ),
    ChannelSpec(
        "angle",
        "deg",
        (-180.0, 180.0),
        tolerance=3.0,
        wraps=True,
        units={"rad": 180.0 / math.pi},
        label="bearing of the object",
        mirror="odd",
    ),
    ChannelSpec(
        "angular_velocity",
        "deg/s",
        (-90.0, 90.0),
        tolerance=5.0,
        bounds=(-3600.0, 3600.0),
        units={"rad/s": 180.0 / math.pi},
        label="angular velocity",
        mirror="odd",
    ),
    ChannelSpec(
        "left",
        "rad/s",
        (-10.0, 10.0),
        kind="command",
        bounds=(-1000.0, 1000.0),
        units={"rpm": _RPM, "deg/s": _DEG},
        label="left wheel",
        mirror="right",
    ),
    ChannelSpec(
        "right",
        "rad/s",
        (-10.0, 10.0),
        kind="command",
        bounds=(-1000.0, 1000.0),
        units={"rpm": _RPM, "deg/s": _DEG},
        label="right wheel",
        mirror="left",
    ),
)

#: Arm angle (deg) of our gripper robot with the gripper up, and down at the floor.
ARM_UP_DEG: Final[float] = 80.0
ARM_DOWN_DEG: Final[float] = 0.0
#: Finger opening (m) of our gripper robot, open and closed (the Webots Khepera gripper's).
FINGERS_OPEN_M: Final[float] = 0.03
FINGERS_CLOSED_M: Final[float] = 0.005

# The channels of our Khepera with a gripper (behavior_hmm/KheperaGripper-v0) beside the
# four of the data contract: known to every dataset and model, required by none.
_GRIPPER_SPECS: tuple[ChannelSpec, ...] = (
    ChannelSpec(
        "arm",
        "deg",
        (ARM_DOWN_DEG, ARM_UP_DEG),
        tolerance=3.0,
        bounds=(-360.0, 360.0),
        units={"rad": 180.0 / math.pi},
        label="arm angle (0 down)",
        mirror="even",
    ),
    ChannelSpec(
        "fingers",
        "m",
        (0.0, 0.035),
        tolerance=0.002,
        bounds=(-0.5, 0.5),
        units={"mm": 1e-3, "cm": 1e-2},
        label="finger opening",
        mirror="even",
    ),
    ChannelSpec(
        "object_present",
        "1",
        (0.0, 1.0),
        tolerance=0.5,
        bounds=(-1.0, 2.0),
        label="object between the fingers",
        mirror="even",
    ),
    ChannelSpec(
        "arm_speed",
        "deg/s",
        (-90.0, 90.0),
        kind="command",
        bounds=(-1000.0, 1000.0),
        units={"rad/s": 180.0 / math.pi},
        label="arm speed",
        mirror="even",
    ),
    ChannelSpec(
        "finger_speed",
        "m/s",
        (-0.03, 0.03),
        kind="command",
        bounds=(-1.0, 1.0),
        units={"mm/s": 1e-3},
        label="finger speed",
        mirror="even",
    ),
)

#: Our gripper robot's own sensors and commands, in observation and action order.
GRIPPER_SENSORS: Final[tuple[str, ...]] = tuple(
    s.name for s in _GRIPPER_SPECS if s.kind == "sensor"
)
GRIPPER_COMMANDS: Final[tuple[str, ...]] = tuple(
    s.name for s in _GRIPPER_SPECS if s.kind == "command"
)

#: Every known channel by name: the four sensors and two wheel commands of the data
#: contract, our gripper robot's, plus any registered with :func:`register_channel`.
CHANNELS: dict[str, ChannelSpec] = {spec.name: spec for spec in _SPECS + _GRIPPER_SPECS}

#: The data contract's sensor channels in their canonical order (our simulator's order).
SENSOR_CHANNELS: Final[tuple[str, ...]] = tuple(s.name for s in _SPECS if s.kind == "sensor")

#: The default command channels (our robots' wheel speeds, rad/s), in order: a dataset
#: or robot that declares none commands these.
COMMAND_CHANNELS: Final[tuple[str, ...]] = tuple(s.name for s in _SPECS if s.kind == "command")


class _Derived(Mapping[str, Any]):
    """A read-only table derived from :data:`CHANNELS` on every access.

    Registering a channel (:func:`register_channel`) updates every such table at once:
    a goal on a registered channel finds its tolerance, a plot its unit.
    """

    def __init__(self, derive: Any, doc: str, fixed: Mapping[str, Any] | None = None) -> None:
        self._derive = derive
        self._fixed = dict(fixed or {})
        self.__doc__ = doc

    def _table(self) -> dict[str, Any]:
        out = dict(self._fixed)
        for spec in CHANNELS.values():
            value = self._derive(spec)
            if value is not None:
                out[spec.name] = value
        return out

    def __getitem__(self, name: str) -> Any:
        spec = CHANNELS.get(name)
        value = None if spec is None else self._derive(spec)
        if value is None:
            if name in self._fixed:
                return self._fixed[name]
            raise KeyError(name)
        return value

    def __iter__(self) -> Iterator[str]:
        return iter(self._table())

    def __len__(self) -> int:
        return len(self._table())

    def __repr__(self) -> str:
        return repr(self._table())


#: Physical unit of every channel (and of the time column); live (see :class:`_Derived`).
UNITS: Final[Mapping[str, str]] = _Derived(
    lambda s: s.unit, "Physical unit of every channel.", fixed={"t": "s"}
)

#: Normalization range (physical units) of each sensor channel, mapped onto [-1, 1]; live.
#: Sensor noise ``--noise SIGMA`` has standard deviation ``SIGMA * (hi - lo)`` per channel.
SENSOR_RANGES: Final[Mapping[str, tuple[float, float]]] = _Derived(
    lambda s: s.range if s.kind == "sensor" else None, "Normalization range of each sensor."
)

#: Goal tolerance (physical units) of every channel that can be a goal (DESIGN §5); live.
TOLERANCES: Final[Mapping[str, float]] = _Derived(
    lambda s: s.tolerance, "Goal tolerance of every channel that can be a goal."
)

#: Physical goal tolerances used by the teacher and the generation stop rule (DESIGN §5).
ANGLE_TOLERANCE_DEG: Final[float] = TOLERANCES["angle"]
DISTANCE_TOLERANCE_M: Final[float] = TOLERANCES["distance"]

#: Largest start distance (m) the arena allows; the object sits at the arena's centre.
ARENA_MAX_DISTANCE: Final[float] = 1.2


def register_channel(spec: ChannelSpec) -> ChannelSpec:
    """Declare a robot's own channel once, for every dataset, model and plot.

    Re-registering an equal spec is harmless; a different spec under a known name is
    refused (a channel means one thing).
    """
    known = CHANNELS.get(spec.name)
    if known is not None and known != spec:
        raise ConfigError(f"channel '{spec.name}' is already declared differently: {known}")
    CHANNELS[spec.name] = spec
    return spec


def channel_from_metadata(entry: Mapping[str, Any]) -> ChannelSpec:
    """A channel declared in a dataset's metadata: ``{"name", "unit", "range", ...}``."""
    if not isinstance(entry, Mapping):
        raise ConfigError(f"a channel declaration must be a mapping, got {entry!r}")
    keys = {"name", "unit", "range", "kind", "tolerance", "wraps", "label", "rest", "mirror"}
    unknown = set(entry) - keys
    if unknown:
        raise ConfigError(f"unknown key(s) {', '.join(sorted(unknown))} in channel {entry!r}")
    for key in ("name", "unit", "range"):
        if key not in entry:
            raise ConfigError(f"channel declaration {dict(entry)!r} needs '{key}'")
    rng = entry["range"]
    if not isinstance(rng, list | tuple) or len(rng) != 2:
        raise ConfigError(f"channel {entry['name']!r}: range must be [lo, hi], got {rng!r}")
    return ChannelSpec(
        name=str(entry["name"]),
        unit=str(entry["unit"]),
        range=(float(rng[0]), float(rng[1])),
        kind=entry.get("kind", "sensor"),
        tolerance=entry.get("tolerance"),
        wraps=bool(entry.get("wraps", False)),
        label=str(entry.get("label", "")),
        rest=entry.get("rest", 0.0),
        mirror=entry.get("mirror"),
    )


def known_or_declared(spec: ChannelSpec) -> ChannelSpec:
    """The registered channel of ``spec``'s name if ``spec`` declares it the same way
    (it then keeps its import units and bounds), else ``spec`` itself."""
    known = CHANNELS.get(spec.name)
    if known is None or spec.mirror not in (None, known.mirror):
        return spec
    mine, theirs = spec.to_metadata(), known.to_metadata()
    mine.pop("mirror", None)
    theirs.pop("mirror", None)
    return known if mine == theirs else spec


def command_from_declaration(entry: ChannelSpec | Mapping[str, Any] | str) -> ChannelSpec:
    """One command channel as a dataset, a model or a robot declares it: a spec, a
    mapping ``{"name", "unit", "range", "rest", "label"}`` (its ``kind`` defaults to
    ``"command"``), or the name of a registered command channel (``"left"``).

    Raises
    ------
    ConfigError
        For an unknown name, a malformed mapping, or a channel that is not a command.
    """
    if isinstance(entry, ChannelSpec):
        spec = entry
    elif isinstance(entry, str):
        if entry not in CHANNELS:
            raise ConfigError(f"unknown command channel {entry[:80]!r}; declare it")
        spec = CHANNELS[entry]
    elif isinstance(entry, Mapping):
        spec = known_or_declared(channel_from_metadata({"kind": "command", **entry}))
    else:
        raise ConfigError(f"a command declaration must be a mapping, got {type(entry).__name__}")
    if spec.kind != "command":
        raise ConfigError(f"'{spec.name}' is a sensor channel, not a command")
    return spec


def channel(name: str, extra: Iterable[ChannelSpec] = ()) -> ChannelSpec:
    """The spec of ``name``: one of ``extra`` (e.g. a dataset's own) or a known channel."""
    for spec in extra:
        if spec.name == name:
            return spec
    try:
        return CHANNELS[name]
    except KeyError:
        raise ConfigError(
            f"unknown channel '{name}' (known: {', '.join(CHANNELS)}; declare a robot's own "
            "channel in the dataset's metadata or with register_channel)"
        ) from None


def within_tolerance(
    values: Mapping[str, float],
    goal: Mapping[str, float],
    scale: float = 1.0,
    specs: Mapping[str, ChannelSpec] | None = None,
) -> bool:
    """True when every goal channel of ``values`` lies within ``scale`` times its tolerance.

    ``specs`` declares channels the registry does not know (a model's or a robot's own);
    the others are looked up in :data:`CHANNELS`.
    """
    for name, target in goal.items():
        spec = specs[name] if specs is not None and name in specs else channel(name)
        tol = spec.tolerance
        if tol is None:
            raise ConfigError(f"channel '{name}' has no goal tolerance; it cannot be a goal")
        # the boundary counts as inside, whatever the decimals (0.99 - 1.0 is -0.01000...09)
        if abs(spec.error(values[name], target)) > scale * tol * (1.0 + 1e-9):
            return False
    return True


def noise_std(
    sigma: float, ranges: Mapping[str, tuple[float, float]] | None = None
) -> dict[str, float]:
    """Per-channel standard deviation (physical units) of ``--noise sigma``."""
    if not sigma >= 0.0:
        raise ValueError(f"noise sigma must be >= 0, got {sigma}")
    table = SENSOR_RANGES if ranges is None else ranges
    return {name: sigma * (hi - lo) for name, (lo, hi) in table.items()}
