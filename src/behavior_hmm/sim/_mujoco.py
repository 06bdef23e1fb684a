"""MuJoCo backend: the MJCF robot in ``assets/khepera.xml`` sized from :class:`RobotParams`."""

from __future__ import annotations

import math
from importlib import resources

import mujoco

from behavior_hmm.errors import SimulationError
from behavior_hmm.sim._kinematic import State
from behavior_hmm.sim._params import RobotParams

#: The MJCF model shipped with the package.
MODEL_XML = resources.files("behavior_hmm.sim").joinpath("assets", "khepera.xml")

# Chassis cylinder: absolute height of its bottom and top above the floor (m).
_CHASSIS_BOTTOM = 0.003
_CHASSIS_TOP = 0.029

# qpos / qvel layout fixed by the joint order in the XML.
_X, _Y, _Z, _YAW, _WHEEL_L, _WHEEL_R = range(6)


def load_spec(params: RobotParams) -> mujoco.MjSpec:
    """The MJCF model as an editable spec, resized to ``params`` (not yet compiled)."""
    spec = mujoco.MjSpec.from_string(MODEL_XML.read_text(encoding="utf-8"))
    spec.option.timestep = params.physics_timestep
    r = params.wheel_radius
    spec.geom("object").size = [params.object_radius, 0.05, 0.0]
    # A contact takes the larger friction of its two geoms: set both to the same value.
    for name in ("object", "chassis"):
        spec.geom(name).friction = [params.contact_friction, 0.005, 0.0001]
    chassis = spec.geom("chassis")
    half_height = 0.5 * (_CHASSIS_TOP - _CHASSIS_BOTTOM)
    chassis.size = [params.body_radius, half_height, 0.0]
    chassis.pos = [0.0, 0.0, _CHASSIS_BOTTOM + half_height - r]
    spec.geom("front_marker").pos = [0.7 * params.body_radius, 0.0, _CHASSIS_TOP + 0.001 - r]
    home = [-(params.contact_distance + 0.5), 0.0, r]
    spec.body("chassis").pos = home
    # Slide joints measure from their `ref`; with ref = the body's pos, qpos is in world frame.
    for axis, value in zip("xyz", home, strict=True):
        spec.joint(axis).ref = value
    for side, sign in (("left", 1.0), ("right", -1.0)):
        spec.body(f"wheel_{side}").pos = [0.0, sign * 0.5 * params.axle_track, 0.0]
        spec.geom(f"wheel_{side}").size = [r, 0.0, 0.0]
    return spec


def build_model(params: RobotParams) -> mujoco.MjModel:
    """Compile the robot for ``params`` and set its velocity actuators.

    The velocity gain is ``kv = I_eff / motor_time_constant`` where ``I_eff`` is a wheel's
    effective inertia (armature + wheel + half the robot's mass reflected through the
    wheel radius), so a wheel follows a step command with the requested time constant
    when driving straight (turning in place reflects a similar inertia).  The force range
    is ``kv * 2 * max_wheel_speed``: the motor is never saturated inside the command range.
    """
    model = load_spec(params).compile()
    set_wheel_motors(model, params)
    return model


def set_wheel_motors(model: mujoco.MjModel, params: RobotParams) -> None:
    """Set the gains and force ranges of actuators 0 and 1 (left, right wheel) in place.

    See :func:`build_model`; the gripper robot's model shares its chassis and wheels.
    """
    r = params.wheel_radius
    mass = float(model.body("chassis").subtreemass[0])
    kvs = []
    for side in ("left", "right"):
        joint = model.joint(f"wheel_{side}")
        wheel_inertia = float(model.body(f"wheel_{side}").inertia[1])
        inertia = float(model.dof_armature[joint.dofadr[0]]) + wheel_inertia + 0.5 * mass * r * r
        kvs.append(inertia / params.motor_time_constant)
    for i, kv in enumerate(kvs):
        model.actuator_gainprm[i, 0] = kv
        model.actuator_biasprm[i, 2] = -kv
        limit = kv * 2.0 * params.max_wheel_speed
        model.actuator_forcerange[i] = (-limit, limit)


class MujocoBackend:
    """The MJCF robot stepped with ``mj_step(..., nstep=substeps)`` per control period.

    The sensors read the chassis joints (``qpos``/``qvel``) directly.  Any MuJoCo warning
    (``data.warning`` counters, e.g. ``mjWARN_BADQACC``, after which MuJoCo silently
    resets the state) raises :class:`SimulationError`.
    """

    name = "mujoco"

    def __init__(self, params: RobotParams) -> None:
        self.params = params
        self.model = build_model(params)
        self.data = mujoco.MjData(self.model)
        # Live views into MjData (their memory never moves).
        self._qpos = self.data.qpos
        self._qvel = self.data.qvel
        self._ctrl = self.data.ctrl
        self._warnings = self.data.warning.number
        self._n = params.substeps
        self._z_rest = self._settle_height()

    @property
    def time(self) -> float:
        """Simulated time since the last :meth:`place` (s)."""
        return float(self.data.time)

    def _settle_height(self) -> float:
        """Chassis height at which the robot rests on its wheels (soft contacts sink a bit)."""
        far = self.params.contact_distance + 1.0
        self.place_at_height(-far, 0.0, 0.0, self.params.wheel_radius)
        mujoco.mj_step(
            self.model, self.data, nstep=max(1, round(0.5 / self.params.physics_timestep))
        )
        self._check("settling the robot on the floor")
        return float(self._qpos[_Z])

    def place_at_height(self, x: float, y: float, yaw: float, z: float) -> None:
        """Reset the simulation with the chassis at rest at ``(x, y, z)`` and heading ``yaw``."""
        mujoco.mj_resetData(self.model, self.data)
        q = self._qpos
        q[_X], q[_Y], q[_Z], q[_YAW] = x, y, z, yaw
        mujoco.mj_forward(self.model, self.data)

    def place(self, x: float, y: float, yaw: float) -> None:
        """Put the robot at rest on the floor at ``(x, y)`` (m) with heading ``yaw`` (rad)."""
        self.place_at_height(x, y, yaw, self._z_rest)

    def displace(self, x: float, y: float, dyaw: float) -> None:
        """Move the chassis to ``(x, y)`` and turn it by ``dyaw`` (rad), keeping its motion."""
        q, v = self._qpos, self._qvel
        c, s = math.cos(dyaw), math.sin(dyaw)
        vx, vy = float(v[_X]), float(v[_Y])
        v[_X], v[_Y] = c * vx - s * vy, s * vx + c * vy
        q[_X], q[_Y] = x, y
        q[_YAW] += dyaw
        mujoco.mj_forward(self.model, self.data)

    def step(self, left: float, right: float) -> None:
        """Advance one control period with wheel speed targets ``left``/``right`` (rad/s)."""
        ctrl = self._ctrl
        ctrl[0] = left
        ctrl[1] = right
        mujoco.mj_step(self.model, self.data, nstep=self._n)
        if any(self._warnings.tolist()):
            self._check("stepping")

    def _check(self, doing: str) -> None:
        counts = self._warnings.tolist()
        if any(counts):
            names = ", ".join(
                f"{mujoco.mjtWarning(i).name} x{n}" for i, n in enumerate(counts) if n
            )
            raise SimulationError(
                f"MuJoCo became unstable while {doing} at t={self.data.time:.3f} s ({names}); "
                "reset the environment"
            )

    def state(self) -> State:
        """Current body and wheel state: x, y, yaw, vx, vy, yaw rate, left, right."""
        q = self._qpos.tolist()
        v = self._qvel.tolist()
        return (q[_X], q[_Y], q[_YAW], v[_X], v[_Y], v[_YAW], v[_WHEEL_L], v[_WHEEL_R])
