"""Closed-loop s-curve demonstrators: the teacher that produces training data.

A demonstration is a sequence of *phases* (turn, approach, retreat; on a robot with a
gripper also open, lower, close, lift). Each phase plans a rest-to-rest jerk-limited
profile with ruckig for one axis (the bearing angle, the distance, the arm angle or the
finger opening). The wheels track theirs in closed loop (feed-forward profile
velocity + proportional feedback on the tracking error) so that it ends within
tolerance of its goal even though the robot's wheels are mismatched; the gripper's
servos take the profile's velocity as their speed command (a finger closing on the
object stops against it, so its own profile is not fed back). The
teacher steers on the simulator's noise-free state (like the thesis's Webots
supervisor); the recorded sensor readings carry whatever noise the env adds.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Final

import numpy as np

from behavior_hmm.data import ANGLE_TOLERANCE_DEG, DISTANCE_TOLERANCE_M
from behavior_hmm.data._channels import (
    ARM_UP_DEG,
    CHANNELS,
    GRIPPER_COMMANDS,
    GRIPPER_SENSORS,
)
from behavior_hmm.errors import ConfigError, SimulationError
from behavior_hmm.runtime import REQUIRED_CHANNELS, Robot, RobotSpec
from behavior_hmm.teach._behaviors import (
    BEHAVIORS,
    GRIPPER_PHASES,
    PHASE_KINDS,
    Phase,
    behavior_spec,
)
from behavior_hmm.teach._profiles import (
    ARM_LIMITS,
    DISTANCE_LIMITS,
    FINGER_LIMITS,
    TURN_LIMITS,
    Limits,
    SCurve,
)

__all__ = ["BEHAVIORS", "PHASES", "Phase"]

#: The sub-behavior each phase kind is tagged with in the ``behavior`` column.
PHASES: Final[tuple[str, ...]] = PHASE_KINDS

#: The robot the default profile limits were chosen for (our Khepera-like robot): top
#: speed 0.21 m/s, yaw rate 454 deg/s. Other robots get limits scaled to their own.
_REFERENCE_SPEED: Final[float] = 0.021 * 10.0


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
    arm_limits, finger_limits
        Profile limits for a gripper's arm angle (deg-based) and finger opening (m-based).
    angle_gain, distance_gain, heading_gain
        Proportional feedback gains (1/s) on the angle tracking error, the
        distance tracking error and, while approaching or retreating, the bearing.
    approach_target
        Distance (m) an approach aims at; inside the 0.01 m goal tolerance, short of contact.
    settle_angle, settle_distance
        Tighter tolerances (deg, m) a phase must reach after its profile ends.
    settle_arm, settle_fingers
        How close (deg, m) the arm and an opening finger pair must come to their target;
        closing fingers have settled when they stop moving (on the object or closed).
    stop_steps
        Zero-command rows appended at the end: every demonstration ends commanding a stop.
    parallel_angle
        A parallel behavior (``BehaviorSpec.parallel``: turn while driving) starts its drive
        once the bearing is within this angle (deg) of ahead, while its turn goes on; the
        drive's profile then runs at ``cos(bearing)`` times the clock's rate.
    max_extra_time
        Seconds allowed after a profile ends before the teacher reports a failure.
    """

    turn_limits: Limits = TURN_LIMITS
    distance_limits: Limits = DISTANCE_LIMITS
    arm_limits: Limits = ARM_LIMITS
    finger_limits: Limits = FINGER_LIMITS
    angle_gain: float = 3.0
    distance_gain: float = 3.0
    heading_gain: float = 2.0
    approach_target: float = 0.004
    settle_angle: float = 0.5
    settle_distance: float = 0.002
    settle_arm: float = 1.0
    settle_fingers: float = 0.0005
    stop_steps: int = 4
    parallel_angle: float = 80.0
    max_extra_time: float = 4.0

    def __post_init__(self) -> None:
        for name in ("angle_gain", "distance_gain", "heading_gain", "max_extra_time"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"teacher parameter '{name}' must be > 0")
        if not 0.0 <= self.approach_target < DISTANCE_TOLERANCE_M:
            raise ConfigError("approach_target must lie inside the distance tolerance")
        if self.stop_steps < 0:
            raise ConfigError("stop_steps must be >= 0")
        if not 0.0 < self.parallel_angle < 90.0:
            raise ConfigError("parallel_angle must lie in (0, 90) deg: driving must close in")

    def scaled_to(self, spec: RobotSpec) -> TeacherConfig:
        """These settings with profile limits scaled to a robot's top speed and yaw rate.

        Distance profiles scale with the robot's top speed relative to our Khepera-like
        robot's 0.21 m/s (unchanged for it); a turn profile never asks for more than a
        third of the robot's top yaw rate.
        """
        factor = spec.max_linear_speed / _REFERENCE_SPEED
        if abs(factor - 1.0) < 1e-9 and self.turn_limits.velocity <= spec.max_yaw_rate / 3:
            return self
        d = self.distance_limits
        t = self.turn_limits
        turn = min(1.0, spec.max_yaw_rate / 3.0 / t.velocity)
        return dataclasses.replace(
            self,
            distance_limits=Limits(d.velocity * factor, d.acceleration * factor, d.jerk * factor),
            turn_limits=Limits(t.velocity * turn, t.acceleration * turn, t.jerk * turn),
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe description, stored in dataset metadata."""
        out: dict[str, Any] = {}
        for key, value in self.__dict__.items():
            out[key] = value.__dict__.copy() if isinstance(value, Limits) else value
        return out


@dataclass
class Demonstration:
    """Rows recorded during one demonstration (one future dataset episode)."""

    channels: tuple[str, ...] = ()
    command_channels: tuple[str, ...] = ("left", "right")
    t: list[float] = field(default_factory=list)
    sensors: list[np.ndarray] = field(default_factory=list)
    commands: list[tuple[float, ...]] = field(default_factory=list)
    behavior: list[str] = field(default_factory=list)
    final_observation: np.ndarray | None = None

    def as_arrays(self) -> dict[str, np.ndarray]:
        """Columns of the demonstration keyed by the data-contract names."""
        sensors = np.asarray(self.sensors, dtype=np.float64).reshape(-1, len(self.channels))
        k = len(self.command_channels)
        commands = np.asarray(self.commands, dtype=np.float64).reshape(-1, k)
        columns: dict[str, np.ndarray] = {"t": np.asarray(self.t, dtype=np.float64)}
        for i, name in enumerate(self.channels):
            columns[name] = sensors[:, i]
        for i, name in enumerate(self.command_channels):
            columns[name] = commands[:, i]
        columns["behavior"] = np.asarray(self.behavior, dtype=object)
        return columns


def plan_phases(
    behavior: str, angle: float, distance: float, goal_distance: float | None = None
) -> list[Phase]:
    """The phases the teacher runs for ``behavior`` from a start (deg, m): its spec's.

    ``turn-approach`` turns only if the bearing is outside the angle tolerance and
    approaches only if the distance is outside the distance tolerance; ``position``
    turns if needed, then approaches or retreats to ``goal_distance``.
    """
    return behavior_spec(behavior).phases(float(angle), float(distance), goal_distance)


class Teacher:
    """Demonstrates behaviors on a simulator env by tracking s-curve profiles.

    Parameters
    ----------
    env
        Any env that meets the robot contract (docs/robots.md): the teacher plans from
        its ``robot_spec`` and tracks on its noise-free observation.
    config
        Gains, limits and tolerances; default :class:`TeacherConfig` scaled to the
        robot (:meth:`TeacherConfig.scaled_to`).
    """

    def __init__(self, env: Any, config: TeacherConfig | None = None) -> None:
        self.env = env
        self.robot = Robot(env)
        self.robot.require(REQUIRED_CHANNELS, "our teacher")
        commands = self.robot.command_channels
        if commands[:2] != ("left", "right") or not set(commands[2:]) <= set(GRIPPER_COMMANDS):
            raise ConfigError(
                f"our teacher drives two wheels (left, right) and our gripper's arm_speed and "
                f"finger_speed; this robot takes {', '.join(commands)}: give your own (--teacher)"
            )
        self._rest = self.robot.rest.copy()
        spec = self.robot.spec
        self.config = config or TeacherConfig().scaled_to(spec)
        self._half_track_over_r = spec.track_width / (2.0 * spec.wheel_radius)
        self._inv_r = 1.0 / spec.wheel_radius
        self._max_wheel = spec.max_wheel_speed
        self._dt = self.robot.control_period
        self._dist = self.robot.channels.index("distance")
        self._angle = self.robot.channels.index("angle")
        channels, commands = self.robot.channels, self.robot.command_channels
        self._gripper = all(c in channels for c in GRIPPER_SENSORS) and all(
            c in commands for c in GRIPPER_COMMANDS
        )
        self._arm = channels.index("arm") if self._gripper else -1
        self._fingers = channels.index("fingers") if self._gripper else -1
        self._present = channels.index("object_present") if self._gripper else -1
        self._arm_command = commands.index("arm_speed") if self._gripper else -1
        self._finger_command = commands.index("finger_speed") if self._gripper else -1
        self._disturbance: _Disturbance | None = None

    def demonstrate(
        self,
        behavior: str,
        angle: float,
        distance: float,
        *,
        goal_distance: float | None = None,
        seed: int | None = None,
        noise: float | None = None,
        perturbation: float = 0.0,
    ) -> Demonstration:
        """Run one demonstration from a start (deg, m); raises if the goal is not reached.

        ``perturbation`` > 0 makes a *corrective* demonstration (DART-style): while the
        teacher runs its phases, the wheels receive its command plus a smooth random
        disturbance of their difference, which turns the robot (an Ornstein-Uhlenbeck
        process with a 0.5 s correlation time, sigma = ``perturbation`` x the robot's top
        wheel speed on each wheel, opposite signs, drawn from ``seed``); the teacher keeps
        correcting in closed loop, and the dataset records its own command, so the
        generators see how to recover a bearing the nominal demonstrations never leave.
        The disturbance moves the bearing only (:data:`DISTURBED_CHANNELS`); with a common
        part as well, which also varies the speed along the distance profile, approach on
        {distance, angle} learned less (sigma 0.04, training seeds 0-2: 96.5 / 94.4 /
        96.6 % against 96.9 / 96.5 / 96.8 % turning only; measured in development).
        """
        spec = behavior_spec(behavior)
        phases = spec.phases(float(angle), float(distance), goal_distance)
        if not self._gripper and any(p.name in GRIPPER_PHASES for p in phases):
            raise ConfigError(
                f"{behavior} needs a robot with our gripper (sensors "
                f"{', '.join(GRIPPER_SENSORS)}; commands {', '.join(GRIPPER_COMMANDS)}), "
                f"e.g. --env {spec.env or 'behavior_hmm/KheperaGripper-v0'}"
            )
        self._disturbance = (
            _Disturbance(float(perturbation) * self._max_wheel, self._dt, seed)
            if perturbation > 0
            else None
        )
        options: dict[str, Any] = {"angle": float(angle), "distance": float(distance)}
        if noise:
            options["noise"] = float(noise)
        obs, true, _ = self.robot.reset(seed=seed, options=options)
        demo = Demonstration(
            channels=self.robot.channels, command_channels=self.robot.command_channels
        )
        step = 0
        done: list[Phase] = []
        pending = phases
        if spec.parallel and len(phases) == 2:  # a turn and a drive, at once where they can
            obs, true, step = self._run_parallel(phases[0], phases[1], obs, true, step, demo)
            done, pending = phases, []
        while pending:
            phase = pending[0]
            obs, true, step = self._run_phase(phase, obs, true, step, demo)
            done.append(phase)
            # Re-plan from where the robot really is: e.g. turning while touching the
            # object can push it off, so an approach becomes necessary after all.
            if not spec.replan:  # the planned phases in order (grasp: open ... lift)
                pending = pending[1:]
                continue
            names = {p.name for p in done}
            pending = [
                p
                for p in spec.phases(true[self._angle], true[self._dist], goal_distance)
                if p.name not in names
            ]
        phases = done
        last = phases[-1].label if phases else (spec.components or (spec.name,))[0]
        rest = tuple(self._rest.tolist())
        for _ in range(self.config.stop_steps):
            demo.t.append(step * self._dt)
            demo.sensors.append(obs)
            demo.commands.append(rest)
            demo.behavior.append(last)
            obs, true, _ = self.robot.step(self._rest)
            step += 1
        demo.final_observation = true
        self._check_goal(behavior, phases, demo.final_observation, angle, distance)
        return demo

    # -- internals -------------------------------------------------------------------------

    def _run_phase(
        self, phase: Phase, obs: np.ndarray, true: np.ndarray, step: int, demo: Demonstration
    ) -> tuple[np.ndarray, np.ndarray, int]:
        cfg = self.config
        if phase.name in GRIPPER_PHASES:
            return self._run_gripper_phase(phase, obs, true, step, demo)
        if phase.name == "turn":
            # the bearing moves within (-180, 180] without wrapping: a turn never swings
            # the object behind the robot, so the readings stay continuous
            profile = SCurve(wrap_deg(true[self._angle]), phase.target, cfg.turn_limits)
        else:
            # An approach to the object itself stops just short of contact.
            touch = phase.name == "approach" and phase.target == 0.0
            target = cfg.approach_target if touch else phase.target
            profile = SCurve(true[self._dist], target, cfg.distance_limits)
        limit = profile.duration + cfg.max_extra_time
        k = 0
        while True:
            t_phase = k * self._dt
            if t_phase >= profile.duration and self._settled(phase, profile.target, true):
                return obs, true, step
            if t_phase > limit:
                raise SimulationError(
                    f"teacher could not finish '{phase.name}' within {limit:.1f} s "
                    f"(angle {true[self._angle]:.2f} deg, distance {true[self._dist]:.4f} m)"
                )
            command = self._rest.copy()
            command[:2] = self._command(phase, profile, t_phase, true)
            demo.t.append(step * self._dt)
            demo.sensors.append(obs)
            demo.commands.append(tuple(command.tolist()))
            demo.behavior.append(phase.label)
            if self._disturbance is not None and t_phase < profile.duration:
                # disturbed while the profile runs; the teacher settles undisturbed
                command[:2] = self._disturbance.applied(command[:2], self._max_wheel)
            obs, true, _ = self.robot.step(command)
            step += 1
            k += 1

    def _run_parallel(
        self,
        turn: Phase,
        drive: Phase,
        obs: np.ndarray,
        true: np.ndarray,
        step: int,
        demo: Demonstration,
    ) -> tuple[np.ndarray, np.ndarray, int]:
        """Turn and drive at once: the turn's profile from the start, the drive's from the
        cycle the bearing comes within ``parallel_angle`` of ahead (thesis §7.2: "while a
        robot is turning to an object, it can also approach to object in parallel").

        Each cycle the yaw comes from the turn while it runs (then the drive's heading
        hold) and the forward speed from the drive while it runs; rows are tagged with
        what runs: ``turn``, ``turn+approach`` (both) or ``approach``. Driving with the
        object at bearing θ closes the distance at ``cos θ`` of the speed, so the drive's
        profile runs on a clock that advances ``cos θ`` per second: the robot picks up
        speed as it comes to face the object, and its distance follows the profile.
        Driving off-axis moves the bearing too; the turn's feedback takes that up.
        """
        cfg = self.config
        turn_profile = SCurve(wrap_deg(true[self._angle]), turn.target, cfg.turn_limits)
        touch = drive.name == "approach" and drive.target == 0.0
        target = cfg.approach_target if touch else drive.target
        drive_profile: SCurve | None = None
        drive_clock = 0.0  # the drive profile's own time (s), advancing cos(bearing) per s
        limit = (
            turn_profile.duration
            + SCurve(true[self._dist], target, cfg.distance_limits).duration
            + cfg.max_extra_time
        )
        turning, driving = True, True
        k = 0
        while True:
            t = k * self._dt
            bearing = wrap_deg(true[self._angle])
            if drive_profile is None and abs(bearing) <= cfg.parallel_angle:
                drive_profile = SCurve(true[self._dist], target, cfg.distance_limits)
            if turning and t >= turn_profile.duration:
                turning = not self._settled(turn, turn_profile.target, true)
            if driving and drive_profile is not None and drive_clock >= drive_profile.duration:
                driving = not self._settled(drive, drive_profile.target, true)
            if not turning and not driving:
                return obs, true, step
            if t > limit:
                raise SimulationError(
                    f"teacher could not finish turning and driving at once within {limit:.1f} s "
                    f"(angle {true[self._angle]:.2f} deg, distance {true[self._dist]:.4f} m)"
                )
            if turning:
                yaw_deg = self._turn_yaw(turn_profile, t, true)
            else:
                yaw_deg = cfg.heading_gain * wrap_deg(true[self._angle])
            forward = 0.0
            moving = driving and drive_profile is not None
            if moving:
                assert drive_profile is not None
                forward = self._drive_forward(drive_profile, drive_clock, true)
                drive_clock += self._dt * max(0.0, math.cos(math.radians(bearing)))
            command = self._rest.copy()
            command[:2] = self._wheels(forward, yaw_deg)
            demo.t.append(step * self._dt)
            demo.sensors.append(obs)
            demo.commands.append(tuple(command.tolist()))
            tags = [p.label for p, on in ((turn, turning), (drive, moving)) if on]
            demo.behavior.append("+".join(tags) or drive.label)
            obs, true, _ = self.robot.step(command)
            step += 1
            k += 1

    def _run_gripper_phase(
        self, phase: Phase, obs: np.ndarray, true: np.ndarray, step: int, demo: Demonstration
    ) -> tuple[np.ndarray, np.ndarray, int]:
        """Move the arm (lower, lift) or the fingers (open, close) along an s-curve.

        The servo takes the profile's velocity as its speed command; the wheels rest. A
        closing pair has settled when its opening stops changing (on the object, or
        closed); the others when they are within the settle tolerance of the target.
        """
        cfg = self.config
        arm = phase.name in ("lower", "lift")
        axis = self._arm if arm else self._fingers
        profile = SCurve(true[axis], phase.target, cfg.arm_limits if arm else cfg.finger_limits)
        column = self._arm_command if arm else self._finger_command
        limit = profile.duration + cfg.max_extra_time
        before = float(true[axis])
        k = 0
        while True:
            t_phase = k * self._dt
            now = float(true[axis])
            if t_phase >= profile.duration:
                if phase.name == "close":
                    settled = k > 0 and abs(now - before) < 1e-5
                else:
                    tol = cfg.settle_arm if arm else cfg.settle_fingers
                    settled = abs(now - phase.target) <= tol
                if settled:
                    return obs, true, step
            if t_phase > limit:
                raise SimulationError(
                    f"teacher could not finish '{phase.name}' within {limit:.1f} s "
                    f"({'arm' if arm else 'fingers'} at {now:.4g}, target {phase.target:g})"
                )
            command = self._rest.copy()
            command[column] = profile.at(t_phase)[1]
            demo.t.append(step * self._dt)
            demo.sensors.append(obs)
            demo.commands.append(tuple(command.tolist()))
            demo.behavior.append(phase.label)
            before = now
            obs, true, _ = self.robot.step(command)
            step += 1
            k += 1

    def _settled(self, phase: Phase, target: float, true: np.ndarray) -> bool:
        if phase.name == "turn":
            return abs(wrap_deg(true[self._angle] - target)) <= self.config.settle_angle
        return abs(true[self._dist] - target) <= self.config.settle_distance

    def _command(
        self, phase: Phase, profile: SCurve, t: float, true: np.ndarray
    ) -> tuple[float, float]:
        if phase.name == "turn":
            yaw_deg = self._turn_yaw(profile, t, true)
            forward = 0.0
        else:
            forward = self._drive_forward(profile, t, true)
            yaw_deg = self.config.heading_gain * wrap_deg(true[self._angle])
        return self._wheels(forward, yaw_deg)

    def _turn_yaw(self, profile: SCurve, t: float, true: np.ndarray) -> float:
        """Yaw rate (deg/s) tracking a turn's profile at ``t``."""
        position, velocity = profile.at(t)
        # The bearing falls as the robot yaws counter-clockwise: d(angle)/dt = -yaw rate.
        error = wrap_deg(true[self._angle] - position)
        return -velocity + self.config.angle_gain * error

    def _drive_forward(self, profile: SCurve, t: float, true: np.ndarray) -> float:
        """Forward speed (m/s) tracking an approach's or a retreat's profile at ``t``."""
        position, velocity = profile.at(t)
        # The distance falls as the robot drives forward: d(distance)/dt = -forward speed.
        return -velocity + self.config.distance_gain * (true[self._dist] - position)

    def _wheels(self, forward: float, yaw_deg: float) -> tuple[float, float]:
        """Wheel speeds (rad/s, left and right) for a forward speed and a yaw rate."""
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
        angle_now, distance_now = final[self._angle], final[self._dist]
        if any(p.name == "lift" for p in phases):
            # a grasp ends with the object held up: where the robot stood no longer counts
            arm_now, present = final[self._arm], final[self._present]
            if present < 0.5 or abs(arm_now - ARM_UP_DEG) > float(CHANNELS["arm"].tolerance or 0.0):
                raise SimulationError(
                    f"teacher missed the {behavior} goal from {start}: the object is "
                    f"{'held' if present >= 0.5 else 'not between the fingers'} with the arm at "
                    f"{arm_now:.1f} deg (goal {ARM_UP_DEG:g} deg, object held)"
                )
            return
        for phase in phases:
            goal = phase.target
            if phase.name == "turn" and abs(wrap_deg(angle_now - goal)) > ANGLE_TOLERANCE_DEG:
                raise SimulationError(
                    f"teacher missed the {behavior} goal from {start}: "
                    f"final angle {angle_now:.2f} deg, goal {goal:g} deg"
                )
            if phase.name != "turn" and abs(distance_now - goal) > DISTANCE_TOLERANCE_M:
                raise SimulationError(
                    f"teacher missed the {behavior} goal from {start}: "
                    f"final distance {distance_now:.4f} m, goal {goal:g} m"
                )


#: Correlation time (s) of a corrective demonstration's disturbance.
DISTURBANCE_TIME_S: Final[float] = 0.5
#: Channels a corrective demonstration's disturbance moves: it turns the robot, so the
#: bearing; a model whose inputs miss one of them cannot tell a corrective run from a
#: nominal one and learns from the nominal runs only.
DISTURBED_CHANNELS: Final[tuple[str, ...]] = ("angle",)


class _Disturbance:
    """A smooth random turn of the wheel commands (see ``Teacher.demonstrate``)."""

    def __init__(self, sigma: float, period: float, seed: int | None) -> None:
        self._sigma = sigma
        self._decay = math.exp(-period / DISTURBANCE_TIME_S)
        self._innovation = math.sqrt(1.0 - self._decay**2)
        self._rng = np.random.default_rng([0x0DA27, 0 if seed is None else int(seed)])
        self._state = 0.0  # differential part (unit variance), right wheel +, left −

    def applied(self, command: np.ndarray, limit: float) -> np.ndarray:
        """``command`` plus the disturbance's next value, within the motor limit."""
        self._state = self._decay * self._state + self._innovation * self._rng.normal()
        differential = self._sigma * self._state
        return np.clip(command + np.array([-differential, differential]), -limit, limit)
