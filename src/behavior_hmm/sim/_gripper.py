"""Our Khepera with a gripper in MuJoCo, facing a small graspable cylinder.

The thesis's third simple behavior is *grasp* (chapter 5: "grasping an object which is
located at the backside of a robot may need turn, approach, and grasp behaviors").  This
env adds to the Khepera-like robot of :mod:`behavior_hmm.sim._env` the gripper turret
Webots ships for the thesis's robot (``assets/khepera_gripper.xml``): an arm that swings
the gripper down in front of the robot and up, two fingers that open and close, and a
sensor that says whether the object is between the fingers.

It meets the robot contract version 2 (docs/robots.md) on its own: its sensors, commands
and start channels are declared by name (the channels are declared once, in
:mod:`behavior_hmm.data._channels`).  Gymnasium id ``behavior_hmm/KheperaGripper-v0``.

Examples
--------
>>> env = KheperaGripperEnv()
>>> obs, info = env.reset(options={"angle": 90.0, "distance": 0.3})
>>> [round(float(obs[c][0]), 4) for c in ("distance", "angle", "arm", "fingers")]
[0.3, 90.0, 80.0, 0.005]
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from importlib import resources
from typing import Any, Final, SupportsFloat

import gymnasium
import mujoco
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from behavior_hmm._envs import GRIPPER_ENV_ID
from behavior_hmm.data._channels import (
    ARENA_MAX_DISTANCE,
    ARM_DOWN_DEG,
    ARM_UP_DEG,
    CHANNELS,
    COMMAND_CHANNELS,
    FINGERS_CLOSED_M,
    FINGERS_OPEN_M,
    GRIPPER_COMMANDS,
    GRIPPER_SENSORS,
    SENSOR_CHANNELS,
    noise_std,
)
from behavior_hmm.errors import ConfigError, SimulationError
from behavior_hmm.sim._env import wrap_degrees
from behavior_hmm.sim._mujoco import set_wheel_motors
from behavior_hmm.sim._options import check_noise, number, parse_pushes, reset_options
from behavior_hmm.sim._params import ParamsGeometry, RobotParams

#: The MJCF model shipped with the package.
GRIPPER_XML = resources.files("behavior_hmm.sim").joinpath("assets", "khepera_gripper.xml")

#: Sensors, in observation order: the data contract's four, then the gripper's.
SENSORS: Final[tuple[str, ...]] = (*SENSOR_CHANNELS, *GRIPPER_SENSORS)
#: Commands, in action order: the wheels (rad/s), the arm (deg/s), the fingers (m/s).
COMMANDS: Final[tuple[str, ...]] = (*COMMAND_CHANNELS, *GRIPPER_COMMANDS)
#: Height (m) the object's centre must rise above its resting height to count as lifted.
LIFT_HEIGHT: Final[float] = 0.01

_RESET_OPTIONS = ("angle", "distance", "arm", "fingers", "noise", "push", "nudge", "random")

Obs = dict[str, NDArray[np.float64]]

__all__ = ["COMMANDS", "GRIPPER_ENV_ID", "LIFT_HEIGHT", "SENSORS", "KheperaGripperEnv"]


def _chassis_params() -> RobotParams:
    """The Khepera's geometry (RobotParams defaults) with this model's object radius."""
    return RobotParams(object_radius=0.0075)


class KheperaGripperEnv(ParamsGeometry, gymnasium.Env[Obs, NDArray[np.float64]]):
    """The Khepera-like robot with a gripper turret and a 1.5 cm cylinder to grasp.

    Observation: a ``spaces.Dict`` of ``(1,)`` float64 arrays by channel (:data:`SENSORS`):
    ``distance`` (m, body surface to the object's surface, in the floor plane, never
    below 0 before noise), ``linear_velocity`` (m/s), ``angle`` (deg, bearing of the
    object), ``angular_velocity`` (deg/s), ``arm`` (deg, 0 down at the floor, 80 up),
    ``fingers`` (m, opening between the finger pads) and ``object_present`` (1 when the
    object's axis passes between the finger pads, else 0; a break-beam sensor).
    Action ``(left, right, arm_speed, finger_speed)``: wheel speeds (rad/s), the rate
    (deg/s) at which the arm's target moves and the rate (m/s) at which the fingers'
    target opening moves; the env integrates the two rates into the targets of the arm's
    and fingers' position servos (clipped to the arm's 0-80 deg and the fingers'
    0.005-0.03 m), as a servo turret takes speed commands.  One step is 16 ms.

    The reward is 0.0 and ``terminated`` False: the caller decides when a behavior is
    done.  ``truncated`` becomes True after ``max_episode_steps`` steps.

    Parameters
    ----------
    noise
        Sensor noise sigma (Gaussian, std ``sigma * (hi - lo)`` of each channel's range;
        ``object_present`` stays a clean 0/1).
    max_episode_steps
        Steps after which ``truncated`` is True; ``None``: never.

    Notes
    -----
    ``reset(seed, options)`` options (all optional): ``angle`` (deg) and ``distance``
    (m) of the start as in the Khepera env (robot at rest, object at the origin; default
    0 deg, 0.5 m); ``arm`` (deg, default 80: up) and ``fingers`` (m, default 0.005:
    closed); ``random`` (draw an angle / distance not given); ``noise``; ``push`` as the
    Khepera env's (the robot is moved); ``nudge``: ``{"distance": m, "angle": deg}``, the
    object is moved by ``distance`` along the line from the robot to it, turned by
    ``angle``, the first time the robot stands ready to grasp (within the distance and
    angle tolerances, below 5 mm/s, arm up): the failure the closed loop is for.

    ``info``: ``t`` (s), ``step``, ``true_observation`` (noise-free, as a dict), ``pose``
    (robot x, y m, yaw rad), ``object`` (the object's x, y, z in m), ``lifted`` (the
    object is between the fingers and its centre at least :data:`LIFT_HEIGHT` above
    where it rests), ``nudged`` (the nudge has happened) and ``commands``.
    """

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 - gymnasium convention

    sensor_channels: tuple[str, ...] = SENSORS
    command_channels: tuple[str, ...] = COMMANDS
    start_channels: tuple[str, ...] = ("angle", "distance", "arm", "fingers")

    def __init__(self, noise: float = 0.0, max_episode_steps: int | None = None) -> None:
        if max_episode_steps is not None and (
            isinstance(max_episode_steps, bool) or not isinstance(max_episode_steps, int)
        ):
            raise ConfigError(f"max_episode_steps must be an integer, got {max_episode_steps!r}")
        self.params = _chassis_params()
        self.noise = check_noise(noise, "noise")
        self.max_episode_steps = max_episode_steps
        spec = mujoco.MjSpec.from_string(GRIPPER_XML.read_text(encoding="utf-8"))
        spec.option.timestep = self.params.physics_timestep
        self.model = spec.compile()
        set_wheel_motors(self.model, self.params)
        self.data = mujoco.MjData(self.model)
        self._n = self.params.substeps
        self._dt = self.params.control_period
        self.metadata = {**self.metadata, "render_fps": 1.0 / self._dt}
        m = self.model
        self._q_object = int(m.joint("object").qposadr[0])
        self._v_object = int(m.joint("object").dofadr[0])
        # the chassis' x, y, z, yaw joints (qpos and qvel addresses coincide: 1 dof each)
        self._qx, self._qy, self._qz, self._qyaw = (
            int(m.joint(j).qposadr[0]) for j in ("x", "y", "z", "yaw")
        )
        self._vx, self._vy, self._vyaw = (int(m.joint(j).dofadr[0]) for j in ("x", "y", "yaw"))
        self._q_arm = int(m.joint("arm").qposadr[0])
        self._q_fingers = [int(m.joint(f"finger_{s}").qposadr[0]) for s in ("left", "right")]
        self._object = m.body("object").id
        self._grasp = m.site("grasp").id
        finger = m.geom("finger_left")
        self._pad_half_length = float(finger.size[0])  # along the arm
        self._pad_half_height = float(finger.size[2])
        self._object_rest_z = float(m.body("object").pos[2])
        self._contact = self.params.body_radius + self.params.object_radius
        ranges = {c: CHANNELS[c].range for c in COMMANDS}
        low = np.array([ranges[c][0] for c in COMMANDS])
        high = np.array([ranges[c][1] for c in COMMANDS])
        low[:2], high[:2] = -self.params.max_wheel_speed, self.params.max_wheel_speed
        self.action_space = spaces.Box(low, high, dtype=np.float64)
        self._low, self._high = low, high
        boxes: dict[str, spaces.Space[Any]] = {}
        for c in SENSORS:
            lo, hi = CHANNELS[c].bounds or CHANNELS[c].range
            boxes[c] = spaces.Box(float(lo), float(hi), shape=(1,), dtype=np.float64)
        self.observation_space = spaces.Dict(boxes)  # type: ignore[assignment]
        self._gains = self.params.wheel_gains
        self._ready = False
        self._step = 0
        self._sigma = self.noise
        self._std = np.zeros(len(SENSORS))
        self._pushes: dict[int, list[tuple[float, float]]] = {}
        self._nudge: tuple[float, float] | None = None
        self._nudged = False
        self._arm_target = ARM_UP_DEG
        self._fingers_target = FINGERS_CLOSED_M
        self._commands = np.zeros(len(COMMANDS))
        self._z_rest = self._settle()

    # robot contract: control_period, robot_spec, body_radius, object_radius come from
    # ParamsGeometry; the channels are the class attributes above

    # ------------------------------------------------------------------ gymnasium API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Obs, dict[str, Any]]:
        """Start an episode; see the class notes for ``options``."""
        super().reset(seed=seed)
        angle, distance, arm, fingers, sigma, pushes, nudge = self._parse_options(options)
        self._sigma = sigma
        std = noise_std(sigma)
        self._std = np.array([0.0 if c == "object_present" else std[c] for c in SENSORS])
        self._pushes = pushes
        self._nudge = nudge
        self._nudged = False
        self._step = 0
        self._commands = np.zeros(len(COMMANDS))
        self._place(angle, distance, arm, fingers)
        self._ready = True
        return self._observe()

    def step(self, action: Any) -> tuple[Obs, SupportsFloat, bool, bool, dict[str, Any]]:
        """Apply ``(left, right, arm_speed, finger_speed)`` for one control period."""
        if not self._ready:
            raise SimulationError("call reset() before step()")
        u = np.asarray(action, dtype=np.float64).reshape(-1)
        if u.shape != (len(COMMANDS),):
            raise ConfigError(
                f"action must hold {len(COMMANDS)} values ({', '.join(COMMANDS)}), got {u.size}"
            )
        if not np.all(np.isfinite(u)):
            raise ConfigError(f"action must be finite, got {u.tolist()}")
        u = np.clip(u, self._low, self._high)
        self._commands = u
        dt = self._dt
        self._arm_target = min(ARM_UP_DEG, max(ARM_DOWN_DEG, self._arm_target + u[2] * dt))
        self._fingers_target = min(
            FINGERS_OPEN_M, max(FINGERS_CLOSED_M, self._fingers_target + u[3] * dt)
        )
        ctrl = self.data.ctrl
        ctrl[0] = u[0] * self._gains[0]
        ctrl[1] = u[1] * self._gains[1]
        ctrl[2] = math.radians(self._arm_target)
        ctrl[3] = ctrl[4] = 0.5 * self._fingers_target
        mujoco.mj_step(self.model, self.data, nstep=self._n)
        self._check("stepping")
        self._step += 1
        if self._pushes and self._step in self._pushes:
            for d_angle, d_distance in self._pushes.pop(self._step):
                self._push(d_angle, d_distance)
        if self._nudge is not None and not self._nudged and self._ready_to_grasp():
            self._nudge_object(*self._nudge)
        obs, info = self._observe()
        limit = self.max_episode_steps
        return obs, 0.0, False, limit is not None and self._step >= limit, info

    # ------------------------------------------------------------------ internals
    def _check(self, doing: str) -> None:
        counts = self.data.warning.number.tolist()
        if any(counts):
            self._ready = False
            names = ", ".join(
                f"{mujoco.mjtWarning(i).name} x{n}" for i, n in enumerate(counts) if n
            )
            raise SimulationError(
                f"MuJoCo became unstable while {doing} at t={self.data.time:.3f} s ({names}); "
                "reset the environment"
            )

    def _settle(self) -> float:
        """Chassis height at which the robot rests on its wheels (soft contacts sink a bit)."""
        self._place_at(-1.0, 0.0, 0.0, self.params.wheel_radius, ARM_UP_DEG, FINGERS_CLOSED_M)
        mujoco.mj_step(self.model, self.data, nstep=round(0.5 / self.params.physics_timestep))
        self._check("settling the robot on the floor")
        z = float(self.data.qpos[self._qz])
        self._object_rest_z = float(self.data.qpos[self._q_object + 2])
        return z

    def _place_at(
        self, x: float, y: float, yaw: float, z: float, arm: float, fingers: float
    ) -> None:
        mujoco.mj_resetData(self.model, self.data)
        q = self.data.qpos
        q[self._qx], q[self._qy], q[self._qz], q[self._qyaw] = x, y, z, yaw
        q[self._q_arm] = math.radians(arm)
        for a in self._q_fingers:
            q[a] = 0.5 * fingers
        self._arm_target, self._fingers_target = arm, fingers
        ctrl = self.data.ctrl
        ctrl[:] = 0.0
        ctrl[2] = math.radians(arm)
        ctrl[3] = ctrl[4] = 0.5 * fingers
        mujoco.mj_forward(self.model, self.data)

    def _place(self, angle: float, distance: float, arm: float, fingers: float) -> None:
        # robot on the -x axis; the object (origin) lies straight ahead at yaw 0
        self._place_at(
            -(distance + self._contact), 0.0, -math.radians(angle), self._z_rest, arm, fingers
        )
        self.data.qpos[self._q_object + 2] = self._object_rest_z
        mujoco.mj_forward(self.model, self.data)

    def _parse_options(self, options: Mapping[str, Any] | None) -> tuple[Any, ...]:
        options = reset_options(options, _RESET_OPTIONS)
        randomize = bool(options.get("random", False))
        draw = self.np_random.uniform
        angle = (
            number(options["angle"], "start angle")
            if "angle" in options
            else (float(draw(-180.0, 180.0)) if randomize else 0.0)
        )
        distance = (
            number(options["distance"], "start distance")
            if "distance" in options
            else (float(draw(0.0, ARENA_MAX_DISTANCE)) if randomize else 0.5)
        )
        arm = number(options.get("arm", ARM_UP_DEG), "start arm")
        fingers = number(options.get("fingers", FINGERS_CLOSED_M), "start fingers")
        if not 0.0 <= distance <= ARENA_MAX_DISTANCE:
            raise ConfigError(f"start distance {distance:g} m not in [0, {ARENA_MAX_DISTANCE:g}]")
        if not -180.0 <= angle <= 180.0:
            raise ConfigError(f"start angle {angle:g} deg not in [-180, 180]")
        if not ARM_DOWN_DEG <= arm <= ARM_UP_DEG:
            raise ConfigError(f"start arm {arm:g} deg not in [{ARM_DOWN_DEG:g}, {ARM_UP_DEG:g}]")
        if not FINGERS_CLOSED_M <= fingers <= FINGERS_OPEN_M:
            raise ConfigError(
                f"start fingers {fingers:g} m not in [{FINGERS_CLOSED_M:g}, {FINGERS_OPEN_M:g}]"
            )
        sigma = check_noise(options["noise"], "noise option") if "noise" in options else self.noise
        nudge = None
        if options.get("nudge") is not None:
            given = options["nudge"]
            if not isinstance(given, Mapping) or set(given) - {"distance", "angle"}:
                raise ConfigError(
                    f"nudge must be a dict with 'distance' (m) and 'angle' (deg), got {given!r}"
                )
            nudge = (
                number(given.get("distance", 0.0), "nudge distance"),
                number(given.get("angle", 0.0), "nudge angle"),
            )
        return angle, distance, arm, fingers, sigma, parse_pushes(options.get("push")), nudge

    def _ready_to_grasp(self) -> bool:
        true = self._true_values()
        return (
            true["distance"] <= CHANNELS["distance"].tolerance  # type: ignore[operator]
            and abs(true["angle"]) <= CHANNELS["angle"].tolerance  # type: ignore[operator]
            and abs(true["linear_velocity"]) < 0.005
            and true["arm"] >= ARM_UP_DEG - CHANNELS["arm"].tolerance  # type: ignore[operator]
        )

    def _nudge_object(self, distance: float, angle: float) -> None:
        q = self.data.qpos
        a = self._q_object
        ox, oy = float(q[a]), float(q[a + 1])
        heading = math.atan2(oy - float(q[self._qy]), ox - float(q[self._qx]))
        heading += math.radians(angle)
        q[a] = ox + distance * math.cos(heading)
        q[a + 1] = oy + distance * math.sin(heading)
        self.data.qvel[self._v_object : self._v_object + 6] = 0.0
        mujoco.mj_forward(self.model, self.data)
        self._nudged = True

    def _push(self, d_angle: float, d_distance: float) -> None:
        q = self.data.qpos
        a = self._q_object
        qx, qy = self._qx, self._qy
        dx, dy = float(q[qx] - q[a]), float(q[qy] - q[a + 1])
        r = math.hypot(dx, dy)
        if d_distance != 0.0 and r > 0:
            new_r = self._contact + max(0.0, max(0.0, r - self._contact) + d_distance)
            q[qx], q[qy] = q[a] + dx * new_r / r, q[a + 1] + dy * new_r / r
        q[self._qyaw] -= math.radians(d_angle)
        mujoco.mj_forward(self.model, self.data)

    def _object_between_fingers(self) -> tuple[bool, NDArray[np.float64]]:
        site = self.data.site_xpos[self._grasp]
        frame = self.data.site_xmat[self._grasp].reshape(3, 3)
        centre = self.data.xpos[self._object]
        local = frame.T @ (centre - site)
        half_opening = 0.5 * self._opening()
        inside = (
            abs(local[0]) <= self._pad_half_length
            and abs(local[2]) <= self._pad_half_height
            and abs(local[1]) <= half_opening
        )
        return bool(inside), centre

    def _opening(self) -> float:
        q = self.data.qpos
        return float(q[self._q_fingers[0]] + q[self._q_fingers[1]])

    def _true_values(self) -> dict[str, float]:
        q, v = self.data.qpos, self.data.qvel
        x, y, yaw = float(q[self._qx]), float(q[self._qy]), float(q[self._qyaw])
        a = self._q_object
        ox, oy = float(q[a]), float(q[a + 1])
        distance = max(0.0, math.hypot(ox - x, oy - y) - self._contact)
        vx, vy = float(v[self._vx]), float(v[self._vy])
        linear = vx * math.cos(yaw) + vy * math.sin(yaw) + 0.0
        bearing = wrap_degrees(math.degrees(math.atan2(oy - y, ox - x) - yaw))
        present, _ = self._object_between_fingers()
        return {
            "distance": distance,
            "linear_velocity": linear,
            "angle": bearing,
            "angular_velocity": math.degrees(float(v[self._vyaw])) + 0.0,
            "arm": math.degrees(float(q[self._q_arm])) + 0.0,
            "fingers": self._opening(),
            "object_present": 1.0 if present else 0.0,
        }

    def _observe(self) -> tuple[Obs, dict[str, Any]]:
        values = self._true_values()
        true = np.array([values[c] for c in SENSORS])
        if not np.all(np.isfinite(true)):
            self._ready = False
            raise SimulationError(f"non-finite simulator state at step {self._step}")
        seen = true
        if self._sigma > 0.0:
            seen = true + self.np_random.standard_normal(len(SENSORS)) * self._std
            seen[2] = wrap_degrees(float(seen[2]))
        q = self.data.qpos
        present, centre = self._object_between_fingers()
        info = {
            "t": self._step * self._dt,
            "step": self._step,
            "true_observation": {c: true[j : j + 1].copy() for j, c in enumerate(SENSORS)},
            "pose": (
                float(q[self._qx]),
                float(q[self._qy]),
                math.remainder(float(q[self._qyaw]), math.tau),
            ),
            "object": tuple(float(c) for c in centre),
            "lifted": present and float(centre[2]) >= self._object_rest_z + LIFT_HEIGHT,
            "nudged": self._nudged,
            "commands": tuple(float(c) for c in self._commands),
        }
        return {c: seen[j : j + 1].copy() for j, c in enumerate(SENSORS)}, info


def make_gripper(**kwargs: Any) -> KheperaGripperEnv:
    """The factory of ``behavior_hmm/KheperaGripper-v0`` (keyword arguments of the env)."""
    return KheperaGripperEnv(**kwargs)
