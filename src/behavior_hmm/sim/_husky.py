"""A Clearpath Husky (skid-steer, four wheels) facing one object, simulated in PyBullet.

Optional extra: needs ``pip install 'behavior-hmm[pybullet]'``.  PyBullet is imported only
when a :class:`HuskyEnv` is built, never when :mod:`behavior_hmm` is imported.

The environment follows the robot contract of this package: a ``Dict`` observation keyed
by sensor channel, ``(left, right)`` wheel speeds (rad/s) as the action, ``reset`` options
``angle``/``distance``/``noise``/``push``, and ``robot_spec``, ``control_period``,
``channel_ranges`` and ``start_scale`` on the unwrapped env.

Examples
--------
>>> from behavior_hmm.sim._husky import make_husky
>>> env = make_husky()  # doctest: +SKIP
>>> obs, info = env.reset(seed=0, options={"angle": 30.0, "distance": 2.0})  # doctest: +SKIP
>>> round(float(obs["angle"][0]), 6), round(float(obs["distance"][0]), 6)  # doctest: +SKIP
(30.0, 2.0)
>>> env.close()  # doctest: +SKIP
"""

from __future__ import annotations

import contextlib
import ctypes
import math
import os
import sys
from collections.abc import Iterator, Mapping, Sequence
from typing import Any, Final, SupportsFloat

import gymnasium
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from behavior_hmm.data._channels import CONTROL_PERIOD, SENSOR_CHANNELS
from behavior_hmm.data._units import wrap_degree
from behavior_hmm.errors import ConfigError, SimulationError
from behavior_hmm.sim._options import check_noise, number, parse_action, parse_pushes, reset_options

#: Sensor channels of the observation ``Dict``, in canonical order.
CHANNELS: Final[tuple[str, ...]] = SENSOR_CHANNELS
#: Physics substeps per control period (``p.setTimeStep(CONTROL_PERIOD / PHYSICS_SUBSTEPS)``).
PHYSICS_SUBSTEPS: Final[int] = 4

#: Wheel radius of ``husky/husky.urdf`` (collision cylinder, m).
WHEEL_RADIUS: Final[float] = 0.17775
#: Geometric track (distance between the left and right wheel centres, m).
GEOMETRIC_TRACK: Final[float] = 2 * 0.2854
#: Effective track of the skid-steer robot (m): ``2 r w_wheel / w_yaw`` measured by turning
#: in place with opposite wheel speeds (0.63 m from 0.3 to 4 rad/s, 0.64 m at 5.6 rad/s).
EFFECTIVE_TRACK: Final[float] = 0.63
#: Largest wheel speed command (rad/s): a top speed of 0.995 m/s.
MAX_WHEEL_SPEED: Final[float] = 5.6
#: Largest torque (N m) each wheel's velocity motor may apply.
MOTOR_FORCE: Final[float] = 40.0
#: Radius (m) and height (m) of the fixed cylinder the robot faces (centred on the origin).
OBJECT_RADIUS: Final[float] = 0.15
OBJECT_HEIGHT: Final[float] = 0.6
#: Half length of the chassis collision box (1.0074 m long, centred on the base): the
#: front surface lies this far ahead of the robot's centre.
HALF_LENGTH: Final[float] = 0.5 * 1.0074
#: Largest start distance (m) ``reset`` accepts, also the top of the distance range.
MAX_START_DISTANCE: Final[float] = 6.0
#: Start used when ``reset`` gets no ``angle`` / ``distance`` option.
DEFAULT_START: Final[dict[str, float]] = {"angle": 0.0, "distance": 2.5}

#: Normalization range of each channel (physical units); sensor noise ``sigma`` has standard
#: deviation ``sigma * (hi - lo)``.  Top speed is 1.0 m/s and the fastest turn in place
#: (opposite wheels at 5.6 rad/s) about 178 deg/s.
CHANNEL_RANGES: Final[dict[str, tuple[float, float]]] = {
    "distance": (0.0, MAX_START_DISTANCE),
    "linear_velocity": (-1.2, 1.2),
    "angle": (-180.0, 180.0),
    "angular_velocity": (-180.0, 180.0),
}
#: How to scale the Khepera start grid (distances 0.1 - 1.0 m) for this robot.
START_SCALE: Final[dict[str, float]] = {"distance": 5.0, "angle": 1.0}

_URDF = "husky/husky.urdf"
_WHEELS_LEFT = ("front_left_wheel", "rear_left_wheel")
_WHEELS_RIGHT = ("front_right_wheel", "rear_right_wheel")
# Links without <inertial> in the URDF: PyBullet gives each 1 kg; URDF semantics is massless.
_MASSLESS_LINKS = (
    "base_footprint",
    "imu_link",
    "top_plate_link",
    "user_rail_link",
    "front_bumper_link",
    "rear_bumper_link",
)
_TINY_MASS = 0.01
_TINY_INERTIA = 1.0e-6
# Sideways friction of the front wheels relative to rolling direction (PyBullet's
# anisotropic friction along the axle).  The rear axle gets less, scaled by the static load
# ratio, so both axles resist sideways sliding equally and the robot turns about its centre
# instead of circling about its heavier rear axle.
_FRONT_LATERAL_FRICTION = 0.3
_SETTLE_TIME = 1.0  # s, to let the robot sink into its soft wheel contacts once
_OVERLAP_TOLERANCE = 0.005  # m of penetration into the object a start may have

_RESET_OPTIONS = ("angle", "distance", "noise", "push")
# Generous finite observation bounds (noise may push a reading past the physical range).
_OBS_BOUNDS: Final[dict[str, tuple[float, float]]] = {
    "distance": (-100.0, 1000.0),
    "linear_velocity": (-100.0, 100.0),
    "angle": (-180.0, 180.0),
    "angular_velocity": (-1.0e5, 1.0e5),
}

Obs = dict[str, NDArray[np.float64]]
Action = NDArray[np.float64]


def _flush_c_stdout() -> None:
    with contextlib.suppress(Exception):
        ctypes.CDLL(None).fflush(None)


@contextlib.contextmanager
def _quiet_stdout() -> Iterator[None]:
    """Send C-level writes to file descriptor 1 to /dev/null (restored afterwards).

    PyBullet's ``loadURDF`` prints a "No inertial data for link" warning per massless link
    straight to fd 1, bypassing ``sys.stdout``.  Not thread-safe (fd 1 is process-wide).
    """
    sys.stdout.flush()
    _flush_c_stdout()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        _flush_c_stdout()  # C stdio buffers its output; drop it before fd 1 comes back
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


def _import_pybullet() -> tuple[Any, Any]:
    try:
        import pybullet
        import pybullet_data
    except ImportError as exc:
        raise ConfigError(
            "the Husky env needs pybullet: pip install 'behavior-hmm[pybullet]'"
        ) from exc
    return pybullet, pybullet_data


class HuskyEnv(gymnasium.Env[dict[str, Any], Action]):
    """A Clearpath Husky (``husky/husky.urdf``) and one fixed cylinder, in PyBullet.

    Observation: a ``Dict`` of ``Box(shape=(1,), float64)`` per channel: ``distance`` (m,
    from the robot's front surface to the object's surface, measured along the line between
    their centres, i.e. the gap once the robot faces the object; never below 0 before
    noise), ``linear_velocity`` (m/s, base velocity along the heading), ``angle`` (deg in
    (-180, 180], bearing of the object from the heading, counter-clockwise positive) and
    ``angular_velocity`` (deg/s, yaw rate, counter-clockwise positive).  Action: ``(left,
    right)`` wheel speeds (rad/s, positive rolls forward), clipped to ``±max_wheel_speed``;
    ``left`` drives both left wheels, ``right`` both right wheels (velocity motors, at
    most :data:`MOTOR_FORCE` N m each).  One step advances :data:`CONTROL_PERIOD` (16 ms) in
    :data:`PHYSICS_SUBSTEPS` physics steps.

    The reward is always 0.0 and ``terminated`` always False; ``truncated`` becomes True
    after ``max_episode_steps`` steps.

    Parameters
    ----------
    noise
        Sensor noise ``sigma``: Gaussian with std ``sigma * (hi - lo)`` of each channel's
        range in :attr:`channel_ranges`, drawn from ``np_random``.
    max_episode_steps
        Steps after which ``truncated`` is True.
    render_mode
        Only None (no rendering).

    Attributes
    ----------
    robot_spec
        ``wheel_radius`` (m), ``track_width`` (m, the effective skid-steer track
        ``2 r w_wheel / w_yaw``), ``geometric_track`` (m) and ``max_wheel_speed`` (rad/s).
    control_period
        Seconds per step.
    channel_ranges
        Channel -> (lo, hi) normalization range in the channel's units.
    start_scale
        Suggested factors for the Khepera start grid (``{"distance": 5.0, "angle": 1.0}``).

    Notes
    -----
    ``reset(seed, options)`` options (all optional):

    ``angle`` (deg, in [-180, 180]) and ``distance`` (m, in [0, 6])
        Start at rest with exactly this noise-free bearing and distance; the robot is
        placed on the -x axis facing ``-angle``.  Default angle 0, distance 2.5.  The
        chassis corners and the wheels reach up to 7.5 cm beyond the front surface's
        distance at oblique bearings: a start closer than that, which would put the robot
        into the object, raises :class:`~behavior_hmm.errors.ConfigError`.
    ``noise``
        Sensor noise sigma for this episode (overrides the constructor's).
    ``push``
        A dict or a list of dicts ``{"step": k, "angle": dA, "distance": dD}``: right
        after step ``k`` (k >= 1) the robot is turned about its centre by ``-dA`` (deg) and
        moved along the line to the object by ``-dD`` (m, never past distance 0), so the
        bearing changes by ``dA`` and the distance by ``dD``; its velocities are kept in its
        own frame.  The observation of step ``k`` already shows the push.

    Any other option raises :class:`~behavior_hmm.errors.ConfigError` (a ``ValueError``).

    ``info`` (reset and step): ``t`` (s), ``step``, ``true_observation`` (noise-free
    ``Dict``), ``pose`` (x m, y m, yaw rad), ``wheel_speeds`` (actual left, right in rad/s,
    each the mean of its two wheels) and ``commands`` (the clipped left, right commands).

    Skid-steer turning needs the wheels to slide sideways.  PyBullet resolves friction of
    articulated bodies along world-fixed axes, which made the yaw rate of a turn in place
    depend on the heading (50 - 120 deg/s) with its default cone friction; the pyramid
    model (``enableConeFriction=0``) with sideways wheel friction scaled down to 0.3 (front)
    and 0.3 x the front/rear load ratio (0.59, rear) turns at a steady rate near its centre
    (over a full turn in place the centre still strays within 6 cm when turning fast and
    within 20 cm when turning slowly).
    The six links without inertial data in the URDF get a negligible mass.

    Each env owns one PyBullet ``DIRECT`` client; call :meth:`close` to release it.
    """

    metadata: dict[str, Any] = {  # noqa: RUF012 - gymnasium convention
        "render_modes": [],
        "render_fps": 1.0 / CONTROL_PERIOD,
    }

    def __init__(
        self,
        noise: float = 0.0,
        max_episode_steps: int = 4000,
        render_mode: str | None = None,
    ) -> None:
        if isinstance(max_episode_steps, bool) or not isinstance(
            max_episode_steps, int | np.integer
        ):
            raise ConfigError(f"max_episode_steps must be an integer, got {max_episode_steps!r}")
        if max_episode_steps < 1:
            raise ConfigError(f"max_episode_steps must be >= 1, got {max_episode_steps}")
        if render_mode is not None:
            raise ConfigError(
                f"the Husky env cannot render; render_mode must be None, got {render_mode!r}"
            )
        self.noise = check_noise(noise, "noise")
        self.max_episode_steps = int(max_episode_steps)
        self.render_mode = render_mode

        self.control_period = CONTROL_PERIOD
        #: Radius (m) of the cylindrical object at the origin (for plots and videos).
        self.object_radius = OBJECT_RADIUS
        #: Half the chassis length (m): the robot's size in plots and videos.
        self.body_radius = HALF_LENGTH
        #: Scaled starts keep this far off the object: at an oblique bearing the corners
        #: and wheels reach up to 7.5 cm past the front (docs/robots.md).
        self.start_offset = {"distance": 0.1}
        self.channel_ranges: dict[str, tuple[float, float]] = dict(CHANNEL_RANGES)
        self.start_scale: dict[str, float] = dict(START_SCALE)
        self.robot_spec: dict[str, float] = {
            "wheel_radius": WHEEL_RADIUS,
            "track_width": EFFECTIVE_TRACK,
            "geometric_track": GEOMETRIC_TRACK,
            "max_wheel_speed": MAX_WHEEL_SPEED,
        }
        lim = MAX_WHEEL_SPEED
        self.action_space = spaces.Box(-lim, lim, shape=(2,), dtype=np.float64)
        self.observation_space = spaces.Dict(
            [
                (name, spaces.Box(lo, hi, shape=(1,), dtype=np.float64))
                for name, (lo, hi) in _OBS_BOUNDS.items()
            ]
        )

        self._p, self._data = _import_pybullet()
        self._client: int | None = None
        self._contact = HALF_LENGTH + OBJECT_RADIUS
        self._ready = False
        self._step = 0
        self._sigma = self.noise
        self._std = np.zeros(len(CHANNELS))
        self._pushes: dict[int, list[tuple[float, float]]] = {}
        self._commands = (0.0, 0.0)
        self._build_world()

    # ------------------------------------------------------------------ world
    def _build_world(self) -> None:
        p = self._p
        cid = int(p.connect(p.DIRECT))
        self._client = cid
        try:
            p.setAdditionalSearchPath(self._data.getDataPath(), physicsClientId=cid)
            p.setGravity(0.0, 0.0, -9.81, physicsClientId=cid)
            p.setTimeStep(CONTROL_PERIOD / PHYSICS_SUBSTEPS, physicsClientId=cid)
            p.setPhysicsEngineParameter(
                enableConeFriction=0, deterministicOverlappingPairs=1, physicsClientId=cid
            )
            p.loadURDF("plane.urdf", physicsClientId=cid)
            with _quiet_stdout():
                robot = int(p.loadURDF(_URDF, [0.0, 0.0, 0.0], physicsClientId=cid))
            self._robot = robot
            shape = p.createCollisionShape(
                p.GEOM_CYLINDER, radius=OBJECT_RADIUS, height=OBJECT_HEIGHT, physicsClientId=cid
            )
            self._object = p.createMultiBody(
                baseMass=0.0,
                baseCollisionShapeIndex=shape,
                basePosition=[0.0, 0.0, 0.5 * OBJECT_HEIGHT],
                physicsClientId=cid,
            )
            self._configure_robot()
            self._settle()
        except BaseException:
            self.close()
            raise

    def _configure_robot(self) -> None:
        p, cid, robot = self._p, self._client, self._robot
        joints: dict[str, int] = {}
        links: dict[str, int] = {p.getBodyInfo(robot, physicsClientId=cid)[0].decode(): -1}
        for j in range(p.getNumJoints(robot, physicsClientId=cid)):
            info = p.getJointInfo(robot, j, physicsClientId=cid)
            joints[info[1].decode()] = j
            links[info[12].decode()] = j
        self._left = [joints[name] for name in _WHEELS_LEFT]
        self._right = [joints[name] for name in _WHEELS_RIGHT]
        self._wheels = self._left + self._right
        for name in _MASSLESS_LINKS:
            p.changeDynamics(
                robot,
                links[name],
                mass=_TINY_MASS,
                localInertiaDiagonal=[_TINY_INERTIA] * 3,
                physicsClientId=cid,
            )
        # Static load split between the axles from the centre of mass (robot at yaw 0).
        mass, moment = 0.0, 0.0
        for link in links.values():
            m = float(p.getDynamicsInfo(robot, link, physicsClientId=cid)[0])
            if link == -1:
                x = p.getBasePositionAndOrientation(robot, physicsClientId=cid)[0][0]
            else:
                x = p.getLinkState(robot, link, physicsClientId=cid)[0][0]
            mass += m
            moment += m * x
        x_com = moment / mass
        x_front = p.getLinkState(robot, joints["front_left_wheel"], physicsClientId=cid)[0][0]
        x_rear = p.getLinkState(robot, joints["rear_left_wheel"], physicsClientId=cid)[0][0]
        load_ratio = (x_com - x_rear) / (x_front - x_com)  # front / rear normal force
        for name in (*_WHEELS_LEFT, *_WHEELS_RIGHT):
            lateral = _FRONT_LATERAL_FRICTION * (1.0 if name.startswith("front") else load_ratio)
            p.changeDynamics(
                robot,
                joints[name],
                lateralFriction=1.0,
                anisotropicFriction=[1.0, lateral, 1.0],
                physicsClientId=cid,
            )
        self._drive(0.0, 0.0)

    def _settle(self) -> None:
        """Let the robot sink into its soft wheel contacts once; remember its rest pose."""
        p, cid, robot = self._p, self._client, self._robot
        p.resetBasePositionAndOrientation(
            robot, [-(self._contact + 10.0), 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], physicsClientId=cid
        )
        for _ in range(round(_SETTLE_TIME / CONTROL_PERIOD) * PHYSICS_SUBSTEPS):
            p.stepSimulation(physicsClientId=cid)
        pos, quat = p.getBasePositionAndOrientation(robot, physicsClientId=cid)
        roll, pitch, _ = p.getEulerFromQuaternion(quat)
        self._rest_z = float(pos[2])
        self._rest_tilt = (float(roll), float(pitch))
        self._rest_state = int(p.saveState(physicsClientId=cid))

    def _drive(self, left: float, right: float) -> None:
        self._p.setJointMotorControlArray(
            self._robot,
            self._wheels,
            self._p.VELOCITY_CONTROL,
            targetVelocities=[left, left, right, right],
            forces=[MOTOR_FORCE] * 4,
            physicsClientId=self._client,
        )

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Obs, dict[str, Any]]:
        """Start an episode at rest; see the class notes for ``options``."""
        super().reset(seed=seed)
        self._check_open()
        angle, distance, sigma, pushes = self._parse_options(options)
        self._sigma = sigma
        ranges = [self.channel_ranges[name] for name in CHANNELS]
        self._std = np.array([sigma * (hi - lo) for lo, hi in ranges])
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
        left, right = parse_action(action)
        if not (math.isfinite(left) and math.isfinite(right)):
            raise ConfigError(f"action must be finite, got ({left}, {right})")
        lim = MAX_WHEEL_SPEED
        left = min(max(left, -lim), lim)
        right = min(max(right, -lim), lim)
        self._commands = (left, right)
        self._drive(left, right)
        p, cid = self._p, self._client
        for _ in range(PHYSICS_SUBSTEPS):
            p.stepSimulation(physicsClientId=cid)
        self._step += 1
        if self._pushes and self._step in self._pushes:
            for d_angle, d_distance in self._pushes.pop(self._step):
                self._displace(d_angle, d_distance)
        obs, info = self._observe()
        return obs, 0.0, False, self._step >= self.max_episode_steps, info

    def render(self) -> None:
        """No rendering (``render_mode`` is always None)."""
        return None

    def close(self) -> None:
        """Disconnect the PyBullet client (idempotent)."""
        self._ready = False
        client, self._client = getattr(self, "_client", None), None
        if client is not None:
            with contextlib.suppress(Exception):
                self._p.disconnect(physicsClientId=client)

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            self.close()

    # ------------------------------------------------------------------ extras
    def push(self, angle: float = 0.0, distance: float = 0.0) -> Obs:
        """Push the robot now: bearing changes by ``angle`` (deg), distance by ``distance`` (m).

        Returns the noise-free observation after the push.
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
    def _check_open(self) -> None:
        if self._client is None:
            raise SimulationError("the Husky env is closed")

    def _parse_options(
        self, options: Mapping[str, Any] | None
    ) -> tuple[float, float, float, dict[int, list[tuple[float, float]]]]:
        options = reset_options(options, _RESET_OPTIONS)
        angle = number(options.get("angle", DEFAULT_START["angle"]), "start angle")
        distance = number(options.get("distance", DEFAULT_START["distance"]), "start distance")
        if not 0.0 <= distance <= MAX_START_DISTANCE:
            raise ConfigError(f"start distance {distance:g} m not in [0, {MAX_START_DISTANCE:g}] m")
        if not -180.0 <= angle <= 180.0:
            raise ConfigError(f"start angle {angle:g} deg not in [-180, 180]")
        sigma = check_noise(options["noise"], "noise option") if "noise" in options else self.noise
        return angle, distance, sigma, parse_pushes(options.get("push"))

    def _place(self, angle: float, distance: float) -> None:
        """Restore the settled robot and put it at rest at this bearing and distance."""
        p, cid, robot = self._p, self._client, self._robot
        p.restoreState(stateId=self._rest_state, physicsClientId=cid)
        # Robot on the -x axis; the object (origin) lies straight ahead at yaw 0, so a
        # bearing of `angle` needs yaw = -angle.
        roll, pitch = self._rest_tilt
        quat = p.getQuaternionFromEuler([roll, pitch, -math.radians(angle)])
        position = [-(distance + self._contact), 0.0, self._rest_z]
        p.resetBasePositionAndOrientation(robot, position, quat, physicsClientId=cid)
        p.resetBaseVelocity(robot, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], physicsClientId=cid)
        for j in self._wheels:
            p.resetJointState(robot, j, 0.0, 0.0, physicsClientId=cid)
        self._drive(0.0, 0.0)
        points = p.getClosestPoints(robot, self._object, 0.0, physicsClientId=cid)
        depth = -min((float(point[8]) for point in points), default=0.0)
        if depth > _OVERLAP_TOLERANCE:
            self._ready = False
            raise ConfigError(
                f"start angle {angle:g} deg, distance {distance:g} m puts the robot "
                f"{depth:.3f} m into the object (its corners and wheels reach beyond the "
                "front surface); start farther away"
            )

    def _displace(self, d_angle: float, d_distance: float) -> None:
        p, cid, robot = self._p, self._client, self._robot
        (x, y, z), quat = p.getBasePositionAndOrientation(robot, physicsClientId=cid)
        if d_distance != 0.0:
            r = math.hypot(x, y)
            new_r = self._contact + max(0.0, max(0.0, r - self._contact) + d_distance)
            x, y = x * new_r / r, y * new_r / r
        turn = -math.radians(d_angle)
        spin = p.getQuaternionFromEuler([0.0, 0.0, turn])
        _, quat = p.multiplyTransforms([0.0, 0.0, 0.0], spin, [0.0, 0.0, 0.0], quat)
        velocity, omega = p.getBaseVelocity(robot, physicsClientId=cid)
        c, s = math.cos(turn), math.sin(turn)

        def rotate(v: Sequence[float]) -> list[float]:
            return [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]]

        p.resetBasePositionAndOrientation(robot, [x, y, z], quat, physicsClientId=cid)
        p.resetBaseVelocity(robot, rotate(velocity), rotate(omega), physicsClientId=cid)

    def _state(self) -> tuple[float, float, float, float, float, float]:
        p, cid, robot = self._p, self._client, self._robot
        (x, y, _), quat = p.getBasePositionAndOrientation(robot, physicsClientId=cid)
        (vx, vy, _), (_, _, wz) = p.getBaseVelocity(robot, physicsClientId=cid)
        yaw = p.getEulerFromQuaternion(quat)[2]
        return float(x), float(y), float(yaw), float(vx), float(vy), float(wz)

    def _sensors(
        self, x: float, y: float, yaw: float, vx: float, vy: float, wz: float
    ) -> tuple[float, float, float, float]:
        distance = math.hypot(x, y) - self._contact
        if distance < 0.0:  # soft contact: a range sensor cannot read below 0
            distance = 0.0
        linear = vx * math.cos(yaw) + vy * math.sin(yaw) + 0.0  # no -0.0
        bearing = wrap_degree(math.degrees(math.atan2(-y, -x) - yaw))
        return distance, linear, bearing, math.degrees(wz) + 0.0

    @staticmethod
    def _as_dict(values: Sequence[float]) -> Obs:
        return {
            name: np.array([v], dtype=np.float64) for name, v in zip(CHANNELS, values, strict=True)
        }

    def _true_observation(self) -> Obs:
        return self._as_dict(self._sensors(*self._state()))

    def _observe(self) -> tuple[Obs, dict[str, Any]]:
        x, y, yaw, vx, vy, wz = state = self._state()
        if not math.isfinite(sum(state)):
            self._ready = False
            raise SimulationError(
                f"non-finite simulator state at step {self._step} "
                f"(x={x}, y={y}, yaw={yaw}, vx={vx}, vy={vy}, wz={wz}); reset the environment"
            )
        true = np.array(self._sensors(*state))
        if self._sigma > 0.0:
            noisy = true + self.np_random.standard_normal(len(CHANNELS)) * self._std
            noisy[2] = wrap_degree(float(noisy[2]))
        else:
            noisy = true
        joints = self._p.getJointStates(self._robot, self._wheels, physicsClientId=self._client)
        speeds = [float(js[1]) for js in joints]
        info = {
            "t": self._step * CONTROL_PERIOD,
            "step": self._step,
            "true_observation": self._as_dict(true.tolist()),
            "pose": (x, y, math.remainder(yaw, math.tau)),
            "wheel_speeds": (0.5 * (speeds[0] + speeds[1]), 0.5 * (speeds[2] + speeds[3])),
            "commands": self._commands,
        }
        return self._as_dict(noisy.tolist()), info


def make_husky(**kwargs: Any) -> HuskyEnv:
    """Build a :class:`HuskyEnv` (``noise``, ``max_episode_steps``, ``render_mode``).

    Raises
    ------
    ConfigError
        If PyBullet is not installed (``pip install 'behavior-hmm[pybullet]'``).
    """
    return HuskyEnv(**kwargs)
