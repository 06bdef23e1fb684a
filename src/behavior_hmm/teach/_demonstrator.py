"""Closed-loop s-curve demonstrators: the teacher that produces training data.

A demonstration is a sequence of *phases* (turn, approach, retreat). Each phase
plans a rest-to-rest jerk-limited profile with ruckig for one axis (the bearing
angle or the distance) and tracks it in closed loop (feed-forward profile
velocity + proportional feedback on the tracking error) so that it ends within
tolerance of its goal even though the robot's wheels are mismatched. The
teacher steers on the simulator's noise-free state (like the thesis's Webots
supervisor); the recorded sensor readings carry whatever noise the env adds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Final

import numpy as np

from behavior_hmm.data import (
    ANGLE_TOLERANCE_DEG,
    CONTROL_PERIOD,
    DISTANCE_TOLERANCE_M,
    SENSOR_CHANNELS,
)
from behavior_hmm.errors import ConfigError, SimulationError
from behavior_hmm.teach._profiles import DISTANCE_LIMITS, TURN_LIMITS, Limits, SCurve

_DIST: Final = SENSOR_CHANNELS.index("distance")
_ANGLE: Final = SENSOR_CHANNELS.index("angle")

#: Behaviors the teacher can demonstrate (the names used on the command line).
BEHAVIORS: Final[tuple[str, ...]] = ("turn", "approach", "retreat", "turn-approach", "position")

#: The sub-behavior each phase kind is tagged with in the ``behavior`` column.
PHASES: Final[tuple[str, ...]] = ("turn", "approach", "retreat")


def wrap_deg(angle: float) -> float:
    """Wrap an angle in degrees into (-180, 180]."""
    wrapped = math.fmod(angle + 180.0, 360.0)
    if wrapped <= 0.0:
        wrapped += 360.0
    return wrapped - 180.0


@dataclass(frozen=True)
class TeacherConfig:
    """Gains, limits and tolerances of the s-curve teacher.

    Parameters
    ----------
    turn_limits, distance_limits
        Profile limits for the bearing angle (deg-based) and the distance (m-based).
    angle_gain, distance_gain, heading_gain
        Proportional feedback gains (1/s) on the angle tracking error, the
        distance tracking error and, while approaching or retreating, the bearing.
    approach_target
        Distance (m) an approach aims at; inside the 0.01 m goal tolerance, short of contact.
    settle_angle, settle_distance
        Tighter tolerances (deg, m) a phase must reach after its profile ends.
    stop_steps
        Zero-command rows appended at the end: every demonstration ends commanding a stop.
    max_extra_time
        Seconds allowed after a profile ends before the teacher reports a failure.
    """

    turn_limits: Limits = TURN_LIMITS
    distance_limits: Limits = DISTANCE_LIMITS
    angle_gain: float = 3.0
    distance_gain: float = 3.0
    heading_gain: float = 2.0
    approach_target: float = 0.004
    settle_angle: float = 0.5
    settle_distance: float = 0.002
    stop_steps: int = 4
    max_extra_time: float = 4.0

    def __post_init__(self) -> None:
        for name in ("angle_gain", "distance_gain", "heading_gain", "max_extra_time"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"teacher parameter '{name}' must be > 0")
        if not 0.0 <= self.approach_target < DISTANCE_TOLERANCE_M:
            raise ConfigError("approach_target must lie inside the distance tolerance")
        if self.stop_steps < 0:
            raise ConfigError("stop_steps must be >= 0")

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe description, stored in dataset metadata."""
        out: dict[str, Any] = {}
        for key, value in self.__dict__.items():
            out[key] = value.__dict__.copy() if isinstance(value, Limits) else value
        return out


@dataclass(frozen=True)
class Phase:
    """One sub-behavior of a demonstration: its name and goal (deg for turn, m otherwise)."""

    name: str
    target: float


@dataclass
class Demonstration:
    """Rows recorded during one demonstration (one future dataset episode)."""

    t: list[float] = field(default_factory=list)
    sensors: list[np.ndarray] = field(default_factory=list)
    commands: list[tuple[float, float]] = field(default_factory=list)
    behavior: list[str] = field(default_factory=list)
    final_observation: np.ndarray | None = None

    def as_arrays(self) -> dict[str, np.ndarray]:
        """Columns of the demonstration keyed by the data-contract names."""
        sensors = np.asarray(self.sensors, dtype=np.float64).reshape(-1, len(SENSOR_CHANNELS))
        commands = np.asarray(self.commands, dtype=np.float64).reshape(-1, 2)
        columns: dict[str, np.ndarray] = {"t": np.asarray(self.t, dtype=np.float64)}
        for i, name in enumerate(SENSOR_CHANNELS):
            columns[name] = sensors[:, i]
        columns["left"] = commands[:, 0]
        columns["right"] = commands[:, 1]
        columns["behavior"] = np.asarray(self.behavior, dtype=object)
        return columns


def plan_phases(
    behavior: str,
    angle: float,
    distance: float,
    goal_distance: float | None = None,
    retreat_distance: float = 1.0,
) -> list[Phase]:
    """The phases the teacher runs for ``behavior`` from a start (deg, m).

    ``turn-approach`` turns only if the bearing is outside the angle tolerance and
    approaches only if the distance is outside the distance tolerance; ``position``
    turns if needed, then approaches or retreats to ``goal_distance``.
    """
    turn_needed = abs(angle) > ANGLE_TOLERANCE_DEG
    if behavior == "turn":
        return [Phase("turn", 0.0)]
    if behavior == "approach":
        return [Phase("approach", 0.0)]
    if behavior == "retreat":
        target = retreat_distance if goal_distance is None else goal_distance
        if target <= distance:
            raise ConfigError(
                f"retreat needs a goal distance beyond the start ({target} m <= {distance} m)"
            )
        return [Phase("retreat", target)]
    if behavior == "turn-approach":
        phases = [Phase("turn", 0.0)] if turn_needed else []
        if distance > DISTANCE_TOLERANCE_M:
            phases.append(Phase("approach", 0.0))
        return phases
    if behavior == "position":
        if goal_distance is None:
            raise ConfigError("position needs a goal distance (a goal_distance column)")
        phases = [Phase("turn", 0.0)] if turn_needed else []
        if distance > goal_distance + DISTANCE_TOLERANCE_M:
            phases.append(Phase("approach", goal_distance))
        elif distance < goal_distance - DISTANCE_TOLERANCE_M:
            phases.append(Phase("retreat", goal_distance))
        return phases
    raise ConfigError(f"unknown behavior '{behavior}'; choose one of {', '.join(BEHAVIORS)}")


class Teacher:
    """Demonstrates behaviors on a simulator env by tracking s-curve profiles.

    Parameters
    ----------
    env
        A ``behavior_hmm.sim.KheperaEnv`` (either backend).
    config
        Gains, limits and tolerances.
    """

    def __init__(self, env: Any, config: TeacherConfig | None = None) -> None:
        self.env = env
        self.config = config or TeacherConfig()
        robot = env.unwrapped.params
        self._half_track_over_r = robot.axle_track / (2.0 * robot.wheel_radius)
        self._inv_r = 1.0 / robot.wheel_radius
        self._max_wheel = robot.max_wheel_speed

    def demonstrate(
        self,
        behavior: str,
        angle: float,
        distance: float,
        *,
        goal_distance: float | None = None,
        seed: int | None = None,
        noise: float | None = None,
    ) -> Demonstration:
        """Run one demonstration from a start (deg, m); raises if the goal is not reached."""
        phases = plan_phases(behavior, angle, distance, goal_distance)
        options: dict[str, Any] = {"angle": float(angle), "distance": float(distance)}
        if noise is not None:
            options["noise"] = float(noise)
        obs, info = self.env.reset(seed=seed, options=options)
        demo = Demonstration()
        step = 0
        done: list[Phase] = []
        pending = phases
        while pending:
            phase = pending[0]
            obs, info, step = self._run_phase(phase, obs, info, step, demo)
            done.append(phase)
            # Re-plan from where the robot really is: e.g. turning while touching the
            # object can push it off, so an approach becomes necessary after all.
            if behavior not in ("turn-approach", "position"):
                break
            true = info["true_observation"]
            names = {p.name for p in done}
            pending = [
                p
                for p in plan_phases(behavior, true[_ANGLE], true[_DIST], goal_distance)
                if p.name not in names
            ]
        phases = done
        last = phases[-1].name if phases else _default_tag(behavior)
        for _ in range(self.config.stop_steps):
            demo.t.append(step * CONTROL_PERIOD)
            demo.sensors.append(np.array(obs, dtype=np.float64))
            demo.commands.append((0.0, 0.0))
            demo.behavior.append(last)
            obs, _, _, _, info = self.env.step(np.zeros(2))
            step += 1
        demo.final_observation = np.array(info["true_observation"], dtype=np.float64)
        self._check_goal(behavior, phases, demo.final_observation, angle, distance)
        return demo

    # -- internals -------------------------------------------------------------------------

    def _run_phase(
        self, phase: Phase, obs: np.ndarray, info: dict[str, Any], step: int, demo: Demonstration
    ) -> tuple[np.ndarray, dict[str, Any], int]:
        cfg = self.config
        true = info["true_observation"]
        if phase.name == "turn":
            profile = SCurve(wrap_deg(true[_ANGLE]), phase.target, cfg.turn_limits)
        else:
            # An approach to the object itself stops just short of contact.
            touch = phase.name == "approach" and phase.target == 0.0
            target = cfg.approach_target if touch else phase.target
            profile = SCurve(true[_DIST], target, cfg.distance_limits)
        limit = profile.duration + cfg.max_extra_time
        k = 0
        while True:
            t_phase = k * CONTROL_PERIOD
            true = info["true_observation"]
            if t_phase >= profile.duration and self._settled(phase, profile.target, true):
                return obs, info, step
            if t_phase > limit:
                raise SimulationError(
                    f"teacher could not finish '{phase.name}' within {limit:.1f} s "
                    f"(angle {true[_ANGLE]:.2f} deg, distance {true[_DIST]:.4f} m)"
                )
            left, right = self._command(phase, profile, t_phase, true)
            demo.t.append(step * CONTROL_PERIOD)
            demo.sensors.append(np.array(obs, dtype=np.float64))
            demo.commands.append((left, right))
            demo.behavior.append(phase.name)
            obs, _, _, _, info = self.env.step(np.array([left, right]))
            step += 1
            k += 1

    def _settled(self, phase: Phase, target: float, true: np.ndarray) -> bool:
        if phase.name == "turn":
            return abs(wrap_deg(true[_ANGLE] - target)) <= self.config.settle_angle
        return abs(true[_DIST] - target) <= self.config.settle_distance

    def _command(
        self, phase: Phase, profile: SCurve, t: float, true: np.ndarray
    ) -> tuple[float, float]:
        cfg = self.config
        position, velocity = profile.at(t)
        if phase.name == "turn":
            # The bearing falls as the robot yaws counter-clockwise: d(angle)/dt = -yaw rate.
            error = wrap_deg(true[_ANGLE] - position)
            yaw_deg = -velocity + cfg.angle_gain * error
            forward = 0.0
        else:
            # The distance falls as the robot drives forward: d(distance)/dt = -forward speed.
            forward = -velocity + cfg.distance_gain * (true[_DIST] - position)
            yaw_deg = cfg.heading_gain * wrap_deg(true[_ANGLE])
        yaw = math.radians(yaw_deg)
        right = forward * self._inv_r + yaw * self._half_track_over_r
        left = forward * self._inv_r - yaw * self._half_track_over_r
        clip = self._max_wheel
        return float(np.clip(left, -clip, clip)), float(np.clip(right, -clip, clip))

    def _check_goal(
        self,
        behavior: str,
        phases: list[Phase],
        final: np.ndarray,
        angle: float,
        distance: float,
    ) -> None:
        start = f"start angle {angle:g} deg, distance {distance:g} m"
        for phase in phases:
            if phase.name == "turn" and abs(wrap_deg(final[_ANGLE])) > ANGLE_TOLERANCE_DEG:
                raise SimulationError(
                    f"teacher missed the {behavior} goal from {start}: "
                    f"final angle {final[_ANGLE]:.2f} deg"
                )
            if phase.name != "turn":
                goal = phase.target
                if abs(final[_DIST] - goal) > DISTANCE_TOLERANCE_M:
                    raise SimulationError(
                        f"teacher missed the {behavior} goal from {start}: "
                        f"final distance {final[_DIST]:.4f} m, goal {goal:g} m"
                    )


def _default_tag(behavior: str) -> str:
    return "turn" if behavior in ("turn", "turn-approach", "position") else behavior
