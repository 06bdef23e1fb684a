"""Kinematic backend: a unicycle with first-order wheel lag and a rigid round object."""

from __future__ import annotations

import math

from behavior_hmm.sim._params import RobotParams

#: Body state returned by every backend's ``state()``: x, y (m), yaw (rad, unwrapped),
#: vx, vy (m/s, world frame), yaw rate (rad/s), left and right wheel speeds (rad/s).
State = tuple[float, float, float, float, float, float, float, float]

# Within this gap (m) the robot counts as touching the object.
_TOUCH = 1e-6


class KinematicBackend:
    """Differential-drive kinematics integrated at the physics timestep.

    Each wheel's speed follows its (gain-scaled) command with a first-order lag
    (``motor_time_constant``), integrated exactly over each physics step; the body moves
    as a unicycle (no wheel slip).  The object is a rigid wall: the robot's centre stays
    at least ``body_radius + object_radius`` from the origin, a velocity into the object
    is removed and Coulomb friction (``contact_friction``) slows or stops the sliding
    that remains, so the distance never goes below 0.  The wheels keep turning when
    the robot is blocked (they slip).
    """

    name = "kinematic"

    def __init__(self, params: RobotParams) -> None:
        self.params = params
        self._dt = params.physics_timestep
        self._n = params.substeps
        self._decay = math.exp(-self._dt / params.motor_time_constant)
        self._r = params.wheel_radius
        self._track = params.axle_track
        self._rc = params.contact_distance
        self._mu = params.contact_friction
        self.time = 0.0
        self._x = self._y = self._yaw = 0.0
        self._vx = self._vy = self._wz = 0.0
        self._wl = self._wr = 0.0

    def place(self, x: float, y: float, yaw: float) -> None:
        """Put the robot at rest at ``(x, y)`` (m) with heading ``yaw`` (rad); time 0."""
        self.time = 0.0
        self._x, self._y, self._yaw = x, y, yaw
        self._vx = self._vy = self._wz = 0.0
        self._wl = self._wr = 0.0

    def displace(self, x: float, y: float, dyaw: float) -> None:
        """Move the robot to ``(x, y)`` and turn it by ``dyaw`` (rad), keeping its motion."""
        c, s = math.cos(dyaw), math.sin(dyaw)
        self._vx, self._vy = c * self._vx - s * self._vy, s * self._vx + c * self._vy
        self._x, self._y, self._yaw = x, y, self._yaw + dyaw

    def step(self, left: float, right: float) -> None:
        """Advance one control period with wheel speed targets ``left``/``right`` (rad/s)."""
        decay, dt, r, track, rc, mu = (
            self._decay,
            self._dt,
            self._r,
            self._track,
            self._rc,
            self._mu,
        )
        x, y, yaw, wl, wr = self._x, self._y, self._yaw, self._wl, self._wr
        touch2 = (rc + _TOUCH) ** 2
        rc2 = rc * rc
        vx = vy = wz = 0.0
        for _ in range(self._n):
            wl = left + (wl - left) * decay
            wr = right + (wr - right) * decay
            v = 0.5 * r * (wr + wl)
            wz = r * (wr - wl) / track
            mid = yaw + 0.5 * wz * dt
            vx = v * math.cos(mid)
            vy = v * math.sin(mid)
            d2 = x * x + y * y
            sliding = False
            if d2 <= touch2:
                # Touching the object: no velocity into it; Coulomb friction on the rest.
                d = math.sqrt(d2)
                nx, ny = x / d, y / d
                vn = vx * nx + vy * ny
                if vn < 0.0:
                    tx, ty = vx - vn * nx, vy - vn * ny
                    vt = math.hypot(tx, ty)
                    slip = vt + mu * vn  # vn < 0: friction takes mu * |vn| off the slide
                    if slip > 0.0:
                        vx, vy = tx * slip / vt, ty * slip / vt
                    else:
                        vx = vy = 0.0
                    sliding = True
            x += vx * dt
            y += vy * dt
            yaw += wz * dt
            d2 = x * x + y * y
            if sliding or d2 < rc2:
                # Stay on (or get back to) the object's surface.
                k = rc / math.sqrt(d2)
                x *= k
                y *= k
        self._x, self._y, self._yaw = x, y, yaw
        self._vx, self._vy, self._wz = vx, vy, wz
        self._wl, self._wr = wl, wr
        self.time += self._n * dt

    def state(self) -> State:
        """Current body and wheel state (see :data:`State`)."""
        return (
            self._x,
            self._y,
            self._yaw,
            self._vx,
            self._vy,
            self._wz,
            self._wl,
            self._wr,
        )
