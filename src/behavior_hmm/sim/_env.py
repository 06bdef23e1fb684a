"""The Gymnasium environment: a Khepera-like robot facing one object on a floor."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Final, SupportsFloat

import gymnasium
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from behavior_hmm._envs import ENV_ID, KINEMATIC_ENV_ID
from behavior_hmm.data._channels import (
    ARENA_MAX_DISTANCE,
    SENSOR_CHANNELS,
    SENSOR_RANGES,
    noise_std,
)
from behavior_hmm.errors import ConfigError, SimulationError
from behavior_hmm.sim._kinematic import KinematicBackend
from behavior_hmm.sim._mujoco import MujocoBackend
from behavior_hmm.sim._options import check_noise, number, parse_action, parse_pushes, reset_options
from behavior_hmm.sim._params import ParamsGeometry, RobotParams
from behavior_hmm.sim._render import TopDownRenderer

#: Backend names accepted by :class:`KheperaEnv`.
BACKENDS: Final[tuple[str, ...]] = ("mujoco", "kinematic")
#: Start used when ``reset`` gets no ``angle`` / ``distance`` option.
DEFAULT_START: Final[dict[str, float]] = {"angle": 0.0, "distance": 0.5}

_RESET_OPTIONS = ("angle", "distance", "noise", "push", "random")
# Generous finite observation bounds (the arena itself is 1.2 m; noise may exceed it).
_OBS_LOW = np.array([-100.0, -100.0, -180.0, -1.0e5])
_OBS_HIGH = np.array([1000.0, 100.0, 180.0, 1.0e5])

Obs = NDArray[np.float64]


def wrap_degrees(angle: float) -> float:
    """Wrap an angle (degrees) into (-180, 180]."""
    wrapped = (angle + 180.0) % 360.0 - 180.0
    return 180.0 if wrapped == -180.0 else wrapped


class KheperaEnv(ParamsGeometry, gymnasium.Env[Obs, Obs]):
    """A differential-drive robot and one round object; sensors as in the thesis (§6).

    Observation (float64, shape (4,), order ``SENSOR_CHANNELS``): ``distance`` (m, from
    the robot's body surface to the object's surface, never below 0 before noise),
    ``linear_velocity`` (m/s, body velocity along the heading), ``angle`` (degrees in
    (-180, 180], bearing of the object from the heading, counter-clockwise positive) and
    ``angular_velocity`` (deg/s, yaw rate, counter-clockwise positive), all read from the
    simulated state.  Action: ``(left, right)`` wheel speeds (rad/s), clipped to
    ``±max_wheel_speed``.  One step advances ``params.control_period`` (16 ms).

    The reward is always 0.0 (the learners in this package need none) and ``terminated``
    is always False: the caller decides when a behavior is done; ``truncated`` becomes
    True after ``max_episode_steps`` steps.

    Parameters
    ----------
    backend
        ``"mujoco"`` (MJCF model, contact physics) or ``"kinematic"`` (fast unicycle).
    params
        Robot geometry, motors and timing; default :class:`RobotParams()`.
    noise
        Sensor noise ``sigma``: Gaussian with std ``sigma * (hi - lo)`` of each channel's
        normalization range (``data._channels.noise_std``), drawn from ``np_random``.
    max_episode_steps
        Steps after which ``truncated`` is True.
    render_mode
        None or ``"rgb_array"`` (a top-down image, no OpenGL needed).

    Notes
    -----
    ``reset(seed, options)`` options (all optional):

    ``angle`` (deg, in [-180, 180]) and ``distance`` (m, in [0, 1.2])
        Start so that the noise-free observation is exactly this bearing and distance,
        robot at rest.  The robot is placed on the -x axis facing ``-angle``; default
        angle 0, distance 0.5.
    ``random``
        If True, an ``angle``/``distance`` not given is drawn uniformly from
        [-180, 180) / [0, 1.2] with ``np_random``.
    ``noise``
        Sensor noise sigma for this episode (overrides the constructor's).
    ``push``
        A dict or a list of dicts ``{"step": k, "angle": dA, "distance": dD}``: after
        step ``k`` (k >= 1) the robot is pushed as by :meth:`push`; the observation that
        step returns already shows it.

    ``info`` (reset and step): ``t`` (s), ``step``, ``true_observation`` (noise-free
    sensors), ``pose`` (x m, y m, yaw rad in [-pi, pi]), ``wheel_speeds`` (actual left,
    right in rad/s) and ``commands`` (the clipped left, right commands in rad/s).
    """

    metadata: dict[str, Any] = {  # noqa: RUF012 - gymnasium convention
        "render_modes": ["rgb_array"],
        "render_fps": 62.5,
    }

    def __init__(
        self,
        backend: str = "mujoco",
        params: RobotParams | None = None,
        noise: float = 0.0,
        max_episode_steps: int | None = 4000,
        render_mode: str | None = None,
    ) -> None:
        if backend not in BACKENDS:
            raise ConfigError(f"unknown backend {backend!r}; expected one of {', '.join(BACKENDS)}")
        if params is None:
            params = RobotParams()
        if not isinstance(params, RobotParams):
            raise ConfigError(f"params must be a RobotParams, got {type(params).__name__}")
        if max_episode_steps is not None and (
            isinstance(max_episode_steps, bool)
            or not isinstance(max_episode_steps, int | np.integer)
        ):
            raise ConfigError(f"max_episode_steps must be an integer, got {max_episode_steps!r}")
        if max_episode_steps is not None and max_episode_steps < 1:
            raise ConfigError(f"max_episode_steps must be >= 1, got {max_episode_steps}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(f"unknown render_mode {render_mode!r}; expected None or 'rgb_array'")
        self.backend = backend
        self.params = params
        self.noise = check_noise(noise, "noise")
        self.max_episode_steps = None if max_episode_steps is None else int(max_episode_steps)
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": 1.0 / params.control_period}

        self.sim: MujocoBackend | KinematicBackend = (
            MujocoBackend(params) if backend == "mujoco" else KinematicBackend(params)
        )
        lim = params.max_wheel_speed
        self.action_space = spaces.Box(-lim, lim, shape=(2,), dtype=np.float64)
        self.observation_space = spaces.Box(_OBS_LOW, _OBS_HIGH, dtype=np.float64)

        self._gain_left, self._gain_right = params.wheel_gains
        self._contact = params.contact_distance
        self._dt = params.control_period
        self._renderer: TopDownRenderer | None = None
        self._ready = False
        self._step = 0
        self._sigma = self.noise
        self._std = np.zeros(len(SENSOR_CHANNELS))
        self._pushes: dict[int, list[tuple[float, float]]] = {}
        self._commands = (0.0, 0.0)
        self._place(DEFAULT_START["angle"], DEFAULT_START["distance"])

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Obs, dict[str, Any]]:
        """Start an episode; see the class notes for ``options``."""
        super().reset(seed=seed)
        angle, distance, sigma, pushes = self._parse_options(options)
        self._sigma = sigma
        std = noise_std(sigma)
        self._std = np.array([std[name] for name in SENSOR_CHANNELS])
        self._pushes = pushes
        self._step = 0
        self._commands = (0.0, 0.0)
        self._place(angle, distance)
        self._ready = True
        return self._observe()

    def step(self, action: Any) -> tuple[Obs, SupportsFloat, bool, bool, dict[str, Any]]:
        """Apply ``(left, right)`` wheel speeds (rad/s) for one control period."""
        if not self._ready:
            raise SimulationError("call reset() before step()")
        if type(action) is np.ndarray and action.shape == (2,) and action.dtype.kind == "f":
            left, right = action.tolist()
        else:
            left, right = parse_action(action)
        if not (math.isfinite(left) and math.isfinite(right)):
            raise ConfigError(f"action must be finite, got ({left}, {right})")
        lim = self.params.max_wheel_speed
        left = -lim if left < -lim else (lim if left > lim else left)
        right = -lim if right < -lim else (lim if right > lim else right)
        self._commands = (left, right)
        try:
            self.sim.step(left * self._gain_left, right * self._gain_right)
        except SimulationError:
            self._ready = False
            raise
        self._step += 1
        if self._pushes and self._step in self._pushes:
            for d_angle, d_distance in self._pushes.pop(self._step):
                self._displace(d_angle, d_distance)
        obs, info = self._observe()
        limit = self.max_episode_steps
        return obs, 0.0, False, limit is not None and self._step >= limit, info

    def render(self) -> NDArray[np.uint8] | None:
        """Top-down RGB image when ``render_mode == "rgb_array"``, else None."""
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            self._renderer = TopDownRenderer(self.params)
        x, y, yaw = self.sim.state()[:3]
        return self._renderer.render(x, y, yaw)

    # ------------------------------------------------------------------ robot contract
    #: What each entry of the observation array is (docs/robots.md; the registered ids
    #: give the same channels as a ``spaces.Dict`` through :class:`ChannelDict`).
    sensor_channels: tuple[str, ...] = SENSOR_CHANNELS

    @property
    def channel_ranges(self) -> dict[str, tuple[float, float]]:
        """Normalization range of each channel (the data contract's)."""
        return {name: SENSOR_RANGES[name] for name in SENSOR_CHANNELS}

    # ------------------------------------------------------------------ extras
    def push(self, angle: float = 0.0, distance: float = 0.0) -> Obs:
        """Push the robot now: bearing changes by ``angle`` (deg), distance by ``distance`` (m).

        The robot turns about its centre (so the bearing changes by exactly ``angle``) and
        moves along the line to the object (so the distance changes by ``distance``, but
        never below contact, distance 0).  Its velocities are kept in its own frame.

        Returns
        -------
        numpy.ndarray
            The noise-free observation after the push.
        """
        if not self._ready:
            raise SimulationError("call reset() before push()")
        self._displace(number(angle, "push angle"), number(distance, "push distance"))
        return self._true_observation()

    @property
    def elapsed_steps(self) -> int:
        """Steps taken since the last reset."""
        return self._step

    # ------------------------------------------------------------------ internals
    def _parse_options(
        self, options: Mapping[str, Any] | None
    ) -> tuple[float, float, float, dict[int, list[tuple[float, float]]]]:
        options = reset_options(options, _RESET_OPTIONS)
        randomize = options.get("random", False)
        if not isinstance(randomize, bool | np.bool_):
            raise ConfigError(f"random option must be True or False, got {randomize!r}")
        if "angle" in options:
            angle = number(options["angle"], "start angle")
        elif randomize:
            angle = float(self.np_random.uniform(-180.0, 180.0))
        else:
            angle = DEFAULT_START["angle"]
        if "distance" in options:
            distance = number(options["distance"], "start distance")
        elif randomize:
            distance = float(self.np_random.uniform(0.0, ARENA_MAX_DISTANCE))
        else:
            distance = DEFAULT_START["distance"]
        if not 0.0 <= distance <= ARENA_MAX_DISTANCE:
            raise ConfigError(
                f"start outside the arena: distance {distance:g} m "
                f"{'<' if distance < 0 else '>'} {0.0 if distance < 0 else ARENA_MAX_DISTANCE:g} m"
            )
        if not -180.0 <= angle <= 180.0:
            raise ConfigError(f"start outside the arena: angle {angle:g} deg not in [-180, 180]")
        sigma = check_noise(options["noise"], "noise option") if "noise" in options else self.noise
        return angle, distance, sigma, parse_pushes(options.get("push"))

    def _place(self, angle: float, distance: float) -> None:
        # Robot on the -x axis; the object (origin) then lies straight ahead at yaw 0,
        # so a bearing of `angle` needs yaw = -angle.
        self.sim.place(-(distance + self._contact), 0.0, -math.radians(angle))

    def _displace(self, d_angle: float, d_distance: float) -> None:
        x, y = self.sim.state()[:2]
        if d_distance != 0.0:
            r = math.hypot(x, y)
            new_r = self._contact + max(0.0, max(0.0, r - self._contact) + d_distance)
            x, y = x * new_r / r, y * new_r / r
        self.sim.displace(x, y, -math.radians(d_angle))

    def _true_observation(self) -> Obs:
        x, y, yaw, vx, vy, wz, _, _ = self.sim.state()
        return np.array(self._sensors(x, y, yaw, vx, vy, wz))

    def _sensors(
        self, x: float, y: float, yaw: float, vx: float, vy: float, wz: float
    ) -> tuple[float, float, float, float]:
        distance = math.hypot(x, y) - self._contact
        if distance < 0.0:  # soft contact: a range sensor cannot read below 0
            distance = 0.0
        linear = vx * math.cos(yaw) + vy * math.sin(yaw) + 0.0  # no -0.0
        bearing = wrap_degrees(math.degrees(math.atan2(-y, -x) - yaw))
        return distance, linear, bearing, math.degrees(wz) + 0.0

    def _observe(self) -> tuple[Obs, dict[str, Any]]:
        x, y, yaw, vx, vy, wz, wl, wr = self.sim.state()
        if not math.isfinite(x + y + yaw + vx + vy + wz + wl + wr):
            self._ready = False
            raise SimulationError(
                f"non-finite simulator state at step {self._step} "
                f"(x={x}, y={y}, yaw={yaw}, vx={vx}, vy={vy}, wz={wz}); reset the environment"
            )
        true = np.array(self._sensors(x, y, yaw, vx, vy, wz))
        if self._sigma > 0.0:
            obs = true + self.np_random.standard_normal(4) * self._std
            obs[2] = wrap_degrees(float(obs[2]))
        else:
            obs = true.copy()
        info = {
            "t": self._step * self._dt,
            "step": self._step,
            "true_observation": true,
            "pose": (x, y, math.remainder(yaw, math.tau)),
            "wheel_speeds": (wl, wr),
            "commands": self._commands,
        }
        return obs, info


def make_env(
    sim: str = "mujoco",
    *,
    noise: float = 0.0,
    params: RobotParams | None = None,
    **kwargs: Any,
) -> KheperaEnv:
    """Build a :class:`KheperaEnv` (unwrapped, no gymnasium checker overhead).

    Parameters
    ----------
    sim
        ``"mujoco"`` or ``"kinematic"``, or the gymnasium ids :data:`ENV_ID` /
        :data:`KINEMATIC_ENV_ID`.
    noise
        Sensor noise sigma (see :class:`KheperaEnv`).
    params
        Robot parameters; default :class:`RobotParams()`.
    **kwargs
        Passed on to :class:`KheperaEnv` (``max_episode_steps``, ``render_mode``).
    """
    aliases = {ENV_ID: "mujoco", KINEMATIC_ENV_ID: "kinematic"}
    backend = aliases.get(sim, sim)
    if backend not in BACKENDS:
        raise ConfigError(
            f"unknown simulator {sim!r}; expected 'mujoco', 'kinematic', {ENV_ID!r} "
            f"or {KINEMATIC_ENV_ID!r}"
        )
    return KheperaEnv(backend=backend, params=params, noise=noise, **kwargs)


class ChannelDict(gymnasium.ObservationWrapper[dict[str, Obs], Obs, Obs]):
    """Our env under the robot contract: observations as a ``spaces.Dict`` by channel.

    Each value is a ``(1,)`` float64 array in the channel's units; ``info
    ["true_observation"]`` becomes the same dict. The registered ids build this.
    """

    def __init__(self, env: gymnasium.Env[Obs, Obs]) -> None:
        super().__init__(env)
        self.names: tuple[str, ...] = tuple(env.unwrapped.sensor_channels)  # type: ignore[attr-defined]
        low, high = env.observation_space.low, env.observation_space.high  # type: ignore[attr-defined]
        self.observation_space = spaces.Dict(  # type: ignore[assignment]
            {
                name: spaces.Box(low[j], high[j], shape=(1,), dtype=np.float64)
                for j, name in enumerate(self.names)
            }
        )

    def observation(self, observation: Obs) -> dict[str, Obs]:
        return {name: observation[j : j + 1].copy() for j, name in enumerate(self.names)}

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Obs], dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        return self.observation(np.asarray(obs)), self._info(info)

    def step(self, action: Obs) -> tuple[dict[str, Obs], SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self.observation(np.asarray(obs)), reward, terminated, truncated, self._info(info)

    def _info(self, info: dict[str, Any]) -> dict[str, Any]:
        true = info.get("true_observation")
        if true is not None:
            info = {**info, "true_observation": self.observation(np.asarray(true))}
        return info


def make_contract_env(backend: str = "mujoco", **kwargs: Any) -> ChannelDict:
    """A :class:`KheperaEnv` that meets the robot contract (the registered ids' entry point)."""
    return ChannelDict(KheperaEnv(backend=backend, **kwargs))
