"""The robot contract (docs/robots.md, DESIGN §9): any Gymnasium env, read by channel name.

:class:`Robot` is the one adapter between an env and everything that drives one (the
control loop, the teacher, the evaluation): it checks the contract once, reads
observations by channel name, and hands out the control period, the robot's geometry
and, where the env offers them, the noise-free observation and the pose.
:func:`make_robot_env` builds an env from what ``--env`` names.
"""

from __future__ import annotations

import importlib
import importlib.util
import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data._channels import (
    CHANNELS,
    SENSOR_CHANNELS,
    ChannelSpec,
    channel_from_metadata,
)
from behavior_hmm.data._transform import DERIVABLE
from behavior_hmm.errors import ConfigError

FloatArray = NDArray[np.float64]

#: Channels our own teacher and built-in behaviors (turn, approach, ...) need; the robot
#: contract itself requires none (version 2, docs/robots.md).
REQUIRED_CHANNELS: tuple[str, ...] = ("angle", "distance")


@dataclass(frozen=True)
class RobotSpec:
    """A differential-drive (or skid-steer) robot's geometry.

    Attributes
    ----------
    wheel_radius
        m.
    track_width
        Distance between the left and right wheels' contact lines (m); for a skid-steer
        robot, the effective track that relates wheel speeds to yaw rate.
    max_wheel_speed
        Largest wheel speed command (rad/s).
    """

    wheel_radius: float
    track_width: float
    max_wheel_speed: float

    @property
    def max_linear_speed(self) -> float:
        """Top speed (m/s): both wheels at ``max_wheel_speed``."""
        return self.wheel_radius * self.max_wheel_speed

    @property
    def max_yaw_rate(self) -> float:
        """Top turning rate in place (deg/s)."""
        return math.degrees(2.0 * self.max_linear_speed / self.track_width)

    def to_dict(self) -> dict[str, float]:
        return {
            "wheel_radius": self.wheel_radius,
            "track_width": self.track_width,
            "max_wheel_speed": self.max_wheel_speed,
        }


def _field(source: Any, name: str) -> float:
    value = source.get(name) if isinstance(source, Mapping) else getattr(source, name, None)
    if value is None:
        raise ConfigError(f"the env's robot_spec has no '{name}' (docs/robots.md)")
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"robot_spec {name} must be a number, got {value!r}") from None
    if not (math.isfinite(out) and out > 0):
        raise ConfigError(f"robot_spec {name} must be > 0, got {out}")
    return out


def robot_spec(env: Any) -> RobotSpec:
    """The ``env.unwrapped.robot_spec`` of a contract env, checked."""
    source = getattr(env.unwrapped, "robot_spec", None)
    if source is None:
        raise ConfigError(
            f"{type(env.unwrapped).__name__} has no robot_spec (wheel_radius, track_width, "
            "max_wheel_speed); see docs/robots.md"
        )
    return RobotSpec(
        *(_field(source, n) for n in ("wheel_radius", "track_width", "max_wheel_speed"))
    )


def control_period(env: Any) -> float:
    """``env.unwrapped.control_period`` (s), checked."""
    period = getattr(env.unwrapped, "control_period", None)
    if period is None:
        raise ConfigError(
            f"{type(env.unwrapped).__name__} has no control_period (seconds); see docs/robots.md"
        )
    out = float(period)
    if not (math.isfinite(out) and 0.0 < out <= 10.0):
        raise ConfigError(f"control_period must be in (0, 10] s, got {out}")
    return out


def ordered_channels(names: Sequence[str]) -> tuple[str, ...]:
    """The data contract's channels first, in their canonical order, then the others."""
    known = [c for c in SENSOR_CHANNELS if c in names]
    return (*known, *(c for c in names if c not in SENSOR_CHANNELS))


class Robot:
    """An env that meets the robot contract, read by channel name.

    Parameters
    ----------
    env
        A Gymnasium env whose ``observation_space`` is a ``spaces.Dict`` keyed by channel
        name (scalars as ``Box(shape=(1,))`` or ``shape=()``), or a ``Box`` whose env
        names its entries in ``env.unwrapped.sensor_channels`` (our raw KheperaEnv).

    Attributes
    ----------
    channels
        The env's sensor channels, contract channels first in canonical order, with
        ``linear_velocity`` and ``angular_velocity`` estimated from ``distance`` and
        ``angle`` when the robot does not measure them (:attr:`derived`).
    control_period
        Seconds per step.
    spec
        The robot's geometry (:class:`RobotSpec`).
    """

    def __init__(self, env: Any) -> None:
        from gymnasium import spaces

        self.env = env
        space = env.observation_space
        base = env.unwrapped
        declared = getattr(base, "sensor_channels", None)
        #: Declarations of the channels the robot brings (contract version 2).
        self.channel_specs: dict[str, ChannelSpec] = _declared_channels(declared, base)
        if isinstance(space, spaces.Dict):
            names = list(space.spaces)
            self._keys: list[str] | None = names
        elif declared is not None and all(isinstance(c, str) for c in declared):
            names = list(declared)
            self._keys = None
        else:
            raise ConfigError(
                f"{type(base).__name__}'s observation_space must be a gymnasium.spaces.Dict "
                f"keyed by channel name, got {type(space).__name__} (docs/robots.md)"
            )
        unknown = [c for c in self.channel_specs if c not in names]
        if unknown:
            raise ConfigError(
                f"{type(base).__name__} declares sensor channel(s) {', '.join(unknown)} that "
                f"its observation_space lacks (its channels: {', '.join(names)})"
            )
        # velocities a robot does not measure are estimated from its positions, as an
        # imported log's are (data._transform.derive_velocities)
        self.derived = tuple(c for c in DERIVABLE if c not in names and DERIVABLE[c] in names)
        self.channels = ordered_channels([*names, *self.derived])
        own = [c for c in self.channels if c in names]
        self._own = own
        self._order = [names.index(c) for c in own]
        self._slots = [self.channels.index(c) for c in own]
        self._previous: dict[str, FloatArray | None] = {"obs": None, "true": None}
        # (slot of the derived velocity, slot of the position it comes from, wraps?)
        self._derivations = [
            (
                self.channels.index(name),
                self.channels.index(DERIVABLE[name]),
                name == "angular_velocity",
            )
            for name in self.derived
        ]
        self.control_period = control_period(env)
        self.start_channels = _start_channels(base, self.channels)
        #: The robot's command channels in action order (version 2: its
        #: ``command_channels``; version 1: the two wheels).
        self.command_specs: tuple[ChannelSpec, ...] = _declared_commands(base)
        k = len(self.command_specs)
        action = getattr(env, "action_space", None)
        if action is not None and tuple(getattr(action, "shape", ())) != (k,):
            listed = ", ".join(spec.name for spec in self.command_specs)
            raise ConfigError(
                f"the action_space must be Box(shape=({k},)) ({listed}), got {action}"
            )
        #: The command that holds the robot still (each command channel's ``rest``).
        self.rest = np.array([spec.rest for spec in self.command_specs], dtype=np.float64)

    @property
    def command_channels(self) -> tuple[str, ...]:
        """Names of the command channels, in action order."""
        return tuple(spec.name for spec in self.command_specs)

    @property
    def spec(self) -> RobotSpec:
        """The robot's wheel geometry (``env.unwrapped.robot_spec``): only our own teacher
        and the motor-limit score need it; an env without one is refused when asked."""
        return robot_spec(self.env)

    def require(self, channels: Sequence[str], who: str) -> None:
        """Refuse a robot that lacks one of ``channels`` that ``who`` needs."""
        missing = [c for c in channels if c not in self.channels]
        if missing:
            raise ConfigError(
                f"{type(self.env.unwrapped).__name__} has no {', '.join(missing)} channel; "
                f"{who} reads {', '.join(channels)} (its channels: {', '.join(self.channels)})"
            )

    @property
    def name(self) -> str:
        """The env's id or class name (for provenance)."""
        spec = getattr(self.env, "spec", None)
        env_id = getattr(spec, "id", None)
        return str(env_id) if env_id else type(self.env.unwrapped).__name__

    @property
    def ranges(self) -> dict[str, tuple[float, float]]:
        """Normalization range of each channel: the env's ``channel_ranges``, else the spec's."""
        own = getattr(self.env.unwrapped, "channel_ranges", None) or {}
        out: dict[str, tuple[float, float]] = {}
        for c in self.channels:
            if c in own:
                lo, hi = own[c]
                out[c] = (float(lo), float(hi))
            elif c in self.channel_specs:
                out[c] = self.channel_specs[c].range
            elif c in CHANNELS:
                out[c] = CHANNELS[c].range
        return out

    def read(self, obs: Any, stream: str = "obs") -> FloatArray:
        """An observation as a float64 array in :attr:`channels` order.

        ``stream`` (``"obs"`` or ``"true"``) keeps the previous reading of each for the
        velocities the robot does not measure (backward differences; 0 after a reset).
        """
        if self._keys is None:
            values = np.asarray(obs, dtype=np.float64).reshape(-1)[self._order]
        elif not isinstance(obs, Mapping):
            raise ConfigError(f"the env returned {type(obs).__name__}, not a dict of channels")
        else:
            try:
                values = np.array(
                    [np.asarray(obs[c], dtype=np.float64).reshape(-1)[0] for c in self._own]
                )
            except KeyError as exc:
                raise ConfigError(f"the env's observation lacks channel {exc}") from None
        if not self.derived:
            return values
        out = np.zeros(len(self.channels))
        out[self._slots] = values
        previous = self._previous[stream]
        self._previous[stream] = out
        if previous is not None:
            for slot, source, wraps in self._derivations:
                change = out[source] - previous[source]
                if wraps:
                    change = (change + 180.0) % 360.0 - 180.0
                out[slot] = -change / self.control_period
        return out

    def as_dict(self, values: FloatArray) -> dict[str, float]:
        """``{channel: value}`` of an array in :attr:`channels` order."""
        return dict(zip(self.channels, values.tolist(), strict=True))

    def _outcome(self, obs: Any, info: Mapping[str, Any]) -> tuple[FloatArray, FloatArray, Any]:
        reading = self.read(obs)
        true = info.get("true_observation")
        true_reading = reading if true is None else self.read(true, "true")
        return reading, true_reading, info.get("pose")

    def reset(
        self, *, seed: int | None = None, options: Mapping[str, Any] | None = None
    ) -> tuple[FloatArray, FloatArray, Any]:
        """Reset; the reading, the noise-free reading (the reading itself if the env has
        none) and the pose ``(x, y, yaw)`` (None if the env gives none)."""
        obs, info = self.env.reset(seed=seed, options=dict(options or {}))
        self._previous = {"obs": None, "true": None}
        return self._outcome(obs, info)

    def step(self, command: FloatArray) -> tuple[FloatArray, FloatArray, Any]:
        """Send one command per command channel (``left``, ``right`` rad/s for wheels)
        for one control period; as :meth:`reset`."""
        obs, _, _, _, info = self.env.step(np.asarray(command, dtype=np.float64))
        return self._outcome(obs, info)


def _declared_channels(declared: Any, base: Any) -> dict[str, ChannelSpec]:
    """``env.unwrapped.sensor_channels`` as declarations: mappings ``{"name", "unit",
    "range", ...}`` (version 2); plain names (version 1) declare nothing."""
    if declared is None or isinstance(declared, str | bytes):
        return {}
    try:
        entries = list(declared)
    except TypeError:
        raise ConfigError(
            f"{type(base).__name__}.sensor_channels must be a sequence, got {declared!r}"
        ) from None
    out: dict[str, ChannelSpec] = {}
    for entry in entries:
        if isinstance(entry, str):
            continue
        spec = channel_from_metadata(entry)
        if spec.kind != "sensor":
            raise ConfigError(f"sensor channel {spec.name!r} is declared as a {spec.kind}")
        if spec.name in out:
            raise ConfigError(f"sensor channel {spec.name!r} is declared twice")
        out[spec.name] = spec
    return out


def _declared_commands(base: Any) -> tuple[ChannelSpec, ...]:
    """``env.unwrapped.command_channels``: mappings ``{"name", "unit", "range", "rest",
    "label"}`` in action order (version 2); absent, the wheels ``left``, ``right``."""
    from behavior_hmm.data._channels import COMMAND_CHANNELS, command_from_declaration

    declared = getattr(base, "command_channels", None)
    if declared is None:
        return tuple(CHANNELS[c] for c in COMMAND_CHANNELS)
    if isinstance(declared, str | bytes | Mapping):
        raise ConfigError(
            f"{type(base).__name__}.command_channels must be a sequence of mappings "
            '({"name", "unit", "range"}), one per action entry'
        )
    out: list[ChannelSpec] = []
    for entry in declared:
        spec = command_from_declaration(entry)
        if any(s.name == spec.name for s in out):
            raise ConfigError(f"command channel {spec.name!r} is declared twice")
        out.append(spec)
    if not out:
        raise ConfigError(f"{type(base).__name__}.command_channels is empty")
    return tuple(out)


def _start_channels(base: Any, channels: Sequence[str]) -> tuple[str, ...] | None:
    """``env.unwrapped.start_channels`` (checked), or None: the behavior's goal channels."""
    value = getattr(base, "start_channels", None)
    if value is None:
        return None
    if isinstance(value, str) or not all(isinstance(c, str) for c in value):
        raise ConfigError(
            f"{type(base).__name__}.start_channels must be a sequence of channel names"
        )
    unknown = [c for c in value if c not in channels]
    if unknown:
        raise ConfigError(
            f"start channel(s) {', '.join(unknown)} are not channels of "
            f"{type(base).__name__} (its channels: {', '.join(channels)})"
        )
    return tuple(value)


# -- building an env from what --env names ----------------------------------------------


def load_factory(target: str, option: str = "--env") -> Any:
    """``package.module:factory`` or ``path/to/file.py:factory`` -> the callable.

    ``option`` (``--env``, ``--teacher``) names what the user gave in the errors.
    """
    where, _, attr = target.rpartition(":")
    if not where or not attr.isidentifier():
        raise ConfigError(
            f"{option} {target!r}: expected {'ID, ' if option == '--env' else ''}"
            "package.module:factory or file.py:factory"
        )
    if where.endswith(".py"):
        path = Path(where)
        if not path.is_file():
            raise ConfigError(f"{option}: no such file {where}")
        name = f"_behavior_hmm_{option.strip('-')}_{abs(hash(str(path.resolve())))}"
        spec = importlib.util.spec_from_file_location(name, path)
        if spec is None or spec.loader is None:
            raise ConfigError(f"{option}: cannot import {where}")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        try:
            spec.loader.exec_module(module)
        except Exception as exc:
            del sys.modules[name]
            raise ConfigError(f"{option}: importing {where} failed: {exc}") from exc
    else:
        try:
            module = importlib.import_module(where)
        except ImportError as exc:
            raise ConfigError(f"{option}: cannot import module {where!r}: {exc}") from exc
    factory = getattr(module, attr, None)
    if not callable(factory):
        raise ConfigError(f"{option}: {where} has no callable {attr!r}")
    return factory


def parse_env_kwargs(text: str | None, option: str = "--env-kwargs") -> dict[str, Any]:
    """``--env-kwargs JSON`` (or ``--teacher-kwargs``) -> a dict (a JSON object).

    Parsed as every JSON the package reads: nesting bounded before the parser recurses,
    NaN and Infinity refused.
    """
    from behavior_hmm._safe_read import config_error, parse_json

    if not text:
        return {}
    value = parse_json(text, file=option, error=config_error)
    if not isinstance(value, dict):
        shown = text if len(text) <= 80 else text[:77] + "..."
        raise ConfigError(f"{option} must be a JSON object, got {shown!r}")
    return value


def make_robot_env(target: str, kwargs: Mapping[str, Any] | None = None) -> Any:
    """The env ``--env`` names: a registered Gymnasium id, ``package.module:factory`` or
    ``path/to/file.py:factory``, built with ``kwargs`` (``--env-kwargs``)."""
    import gymnasium

    import behavior_hmm.sim  # noqa: F401  (registers our ids)

    options = dict(kwargs or {})
    if ":" in target and (target.rpartition(":")[0].endswith(".py") or "/" not in target):
        if target in gymnasium.registry:
            return gymnasium.make(target, **options)
        factory = load_factory(target)
        try:
            return factory(**options)
        except TypeError as exc:
            raise ConfigError(f"--env {target}: {exc}") from exc
    if target not in gymnasium.registry:
        ours = sorted(k for k in gymnasium.registry if k.startswith("behavior_hmm/"))
        raise ConfigError(
            f"--env {target!r} is not a registered Gymnasium id, package.module:factory or "
            f"file.py:factory (ours: {', '.join(ours)})"
        )
    try:
        return gymnasium.make(target, **options)
    except TypeError as exc:
        raise ConfigError(f"--env {target}: {exc}") from exc
