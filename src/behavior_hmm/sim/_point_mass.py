"""A 2-D point mass driven by velocity commands (robot contract version 2).

The robot of the LASA handwriting experiment (``behavior-hmm experiment lasa``): a point
in the plane whose sensors are its position ``x``, ``y`` (relative to the goal at the
origin) and whose two commands are its x and y velocity, optionally through a
first-order lag. It has no wheels, heading or object: it declares its channels in
``sensor_channels`` and where ``reset`` can place it in ``start_channels``. Gymnasium id
``behavior_hmm/PointMass-v0``.

Examples
--------
>>> env = PointMassEnv(unit="lasa", extent=60.0, tolerance=1.0)
>>> obs, info = env.reset(options={"x": -40.0, "y": 5.0})
>>> obs, *_ = env.step([10.0, 0.0])
>>> round(float(obs["x"][0]), 3)
-39.84
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Final

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from behavior_hmm.data._channels import CONTROL_PERIOD

#: Gymnasium id of the point mass.
POINT_MASS_ENV_ID: Final[str] = "behavior_hmm/PointMass-v0"

FloatArray = NDArray[np.float64]

#: The position is held within this many ``extent`` of the origin on each axis.
WALL: Final[float] = 100.0


class PointMassEnv(gym.Env):
    """A point in the plane; the action is its (x, y) velocity in ``unit`` per second.

    Parameters
    ----------
    unit
        Unit of the position channels (e.g. ``"m"``, ``"lasa"``).
    extent
        Half-width of the declared channel range: ``x`` and ``y`` are declared on
        ``[-extent, extent]`` (the range a model normalizes by); the position is
        held within ``WALL`` × ``extent`` of the origin (the observation space's bounds).
    tolerance
        Goal tolerance of each position channel, in ``unit``.
    max_speed
        Largest commanded speed per axis (``unit``/s); commands are clipped to it.
        ``None``: 5 × ``extent`` per second.
    lag
        Time constant (s) of the first-order lag between the commanded and the actual
        velocity; 0: the velocity follows the command at once.
    control_period
        Seconds per step (the package's 16 ms by default).
    """

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012
    start_channels: tuple[str, ...] = ("x", "y")

    def __init__(
        self,
        unit: str = "m",
        extent: float = 1.0,
        tolerance: float = 0.01,
        max_speed: float | None = None,
        lag: float = 0.0,
        control_period: float = CONTROL_PERIOD,
    ) -> None:
        for name, value in (("extent", extent), ("tolerance", tolerance)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value}")
        if not (math.isfinite(lag) and lag >= 0):
            raise ValueError(f"lag must be >= 0, got {lag}")
        if not (math.isfinite(control_period) and control_period > 0):
            raise ValueError(f"control_period must be > 0, got {control_period}")
        speed = 5.0 * float(extent) if max_speed is None else float(max_speed)
        if not (math.isfinite(speed) and speed > 0):
            raise ValueError(f"max_speed must be a positive number, got {max_speed}")
        self.unit = str(unit)
        self.extent = float(extent)
        self.tolerance = float(tolerance)
        self.max_speed = speed
        self.lag = float(lag)
        self.control_period = float(control_period)
        self.sensor_channels = tuple(
            {
                "name": name,
                "unit": self.unit,
                "range": [-self.extent, self.extent],
                "tolerance": self.tolerance,
            }
            for name in ("x", "y")
        )
        #: its commands: the x and y velocity (unit/s), at rest at 0
        self.command_channels = tuple(
            {"name": name, "unit": f"{self.unit}/s", "range": [-speed, speed]}
            for name in ("vx", "vy")
        )
        self._wall = WALL * self.extent
        box = spaces.Box(-self._wall, self._wall, shape=(1,), dtype=np.float64)
        self.observation_space = spaces.Dict({"x": box, "y": box})
        self.action_space = spaces.Box(-speed, speed, shape=(2,), dtype=np.float64)
        # share of the gap to the command closed each step (1: no lag)
        self._follow = 1.0 if self.lag == 0 else 1.0 - math.exp(-self.control_period / self.lag)
        self._p: FloatArray = np.zeros(2)
        self._v: FloatArray = np.zeros(2)
        self._noise = 0.0

    def _observation(self, p: FloatArray) -> dict[str, FloatArray]:
        return {"x": p[:1].astype(np.float64), "y": p[1:].astype(np.float64)}

    def _observe(self) -> tuple[dict[str, FloatArray], dict[str, Any]]:
        true = self._observation(self._p.copy())
        if self._noise > 0:
            noisy = self._p + self.np_random.normal(0.0, self._noise, size=2)
            return self._observation(noisy), {"true_observation": true}
        return true, {"true_observation": true}

    def reset(
        self, *, seed: int | None = None, options: Mapping[str, Any] | None = None
    ) -> tuple[dict[str, FloatArray], dict[str, Any]]:
        """Place the point at rest at ``options["x"]``, ``options["y"]`` (default 0, 0).

        ``options["noise"]``: standard deviation of Gaussian sensor noise (``unit``),
        drawn from the env's seeded generator; ``info["true_observation"]`` is noise-free.
        """
        super().reset(seed=seed)
        left = dict(options or {})
        p = np.array([float(left.pop("x", 0.0)), float(left.pop("y", 0.0))])
        noise = float(left.pop("noise", 0.0))
        if left:
            raise ValueError(f"unknown reset options {sorted(left)} (known: x, y, noise)")
        if not np.all(np.abs(p) <= self._wall):
            raise ValueError(f"start must lie within ±{self._wall:g}, got x={p[0]}, y={p[1]}")
        if not (math.isfinite(noise) and noise >= 0):
            raise ValueError(f"noise must be >= 0, got {noise}")
        self._p = p
        self._v = np.zeros(2)
        self._noise = noise
        return self._observe()

    def step(self, action: Any) -> tuple[dict[str, FloatArray], float, bool, bool, dict[str, Any]]:
        """Move for one control period at the (lagged, clipped) commanded velocity."""
        command = np.asarray(action, dtype=np.float64).reshape(2)
        command = np.clip(np.nan_to_num(command), -self.max_speed, self.max_speed)
        self._v = self._v + self._follow * (command - self._v)
        self._p = np.clip(self._p + self._v * self.control_period, -self._wall, self._wall)
        obs, info = self._observe()
        return obs, 0.0, False, False, info


def make_point_mass(**kwargs: Any) -> PointMassEnv:
    """The factory of ``behavior_hmm/PointMass-v0`` (keyword arguments of the env)."""
    return PointMassEnv(**kwargs)
