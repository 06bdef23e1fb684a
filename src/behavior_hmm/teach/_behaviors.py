"""Every behavior the teacher can demonstrate, declared once (issue: any behavior).

A :class:`BehaviorSpec` says what a behavior is: its goal channels and their nominal
goal, the teacher's phases from a start, its default training grid, its shipped test
starts and the start values it fills in. ``turn``, ``approach``, ``retreat``,
``turn-approach``, ``position`` and, on the Khepera with a gripper, ``grasp`` and
``turn-approach-grasp`` are entries of :data:`BEHAVIORS`; a user adds their
own with :func:`register_behavior` without editing the package. Collected datasets carry
the goal channels in their metadata (``goal``), so the learners never need a name.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Final

from behavior_hmm._envs import GRIPPER_ENV_ID
from behavior_hmm.data import ANGLE_TOLERANCE_DEG, DISTANCE_TOLERANCE_M
from behavior_hmm.data._channels import (
    ARM_DOWN_DEG,
    ARM_UP_DEG,
    CHANNELS,
    FINGERS_CLOSED_M,
    FINGERS_OPEN_M,
)
from behavior_hmm.errors import ConfigError

Start = dict[str, float]

#: Distance (m) at which turn demonstrations are recorded.
TURN_DISTANCE: Final[float] = 0.5
#: Distance (m) retreat demonstrations back away to.
RETREAT_DISTANCE: Final[float] = 1.0

#: Phases that move the gripper: ``open`` and ``close`` the fingers (target: the
#: opening in m), ``lower`` and ``lift`` the arm (target: the arm angle in deg).
GRIPPER_PHASES: Final[tuple[str, ...]] = ("open", "lower", "close", "lift")
#: The kinds of phase the teacher can track: a turn steers the bearing (deg), an
#: approach or a retreat the distance (m), the gripper phases the arm or the fingers.
PHASE_KINDS: Final[tuple[str, ...]] = ("turn", "approach", "retreat", *GRIPPER_PHASES)

_NAME = re.compile(r"[a-z][a-z0-9_-]{0,63}\Z")


@dataclass(frozen=True)
class Phase:
    """One sub-behavior of a demonstration: its kind and goal (deg for turn, lower and
    lift; m otherwise), and the tag its rows carry in the ``behavior`` column (default:
    its kind; a grasp's four phases are tagged ``grasp`` in a composite behavior)."""

    name: str
    target: float
    tag: str = ""

    def __post_init__(self) -> None:
        if self.name not in PHASE_KINDS:
            raise ConfigError(
                f"unknown phase '{self.name}'; the teacher tracks {', '.join(PHASE_KINDS)}"
            )

    @property
    def label(self) -> str:
        """What the phase's rows are tagged with in the ``behavior`` column."""
        return self.tag or self.name


#: ``phases(angle_deg, distance_m, goal_distance_m_or_None) -> [Phase, ...]``
PhasePlanner = Callable[[float, float, "float | None"], list[Phase]]


@dataclass(frozen=True)
class BehaviorSpec:
    """One behavior: everything the package needs to know about it, in one place.

    Parameters
    ----------
    name
        The name used on the command line and in datasets (lowercase, ``-`` or ``_``).
    goal
        Goal channels and their nominal goal in physical units, e.g. ``{"angle": 0.0}``;
        a learned model's default goal is where its demonstrations end on these channels.
    phases
        The teacher's phases from a start: ``phases(angle, distance, goal_distance)``.
    train_starts
        The default training grid: a function returning starts (``angle`` deg,
        ``distance`` m, optionally ``goal_distance``).
    test_starts
        File name of the shipped test starts in ``behavior_hmm/teach/starts/``, or a
        function returning them; ``None``: none shipped.
    start_defaults
        Values a start may omit (e.g. turn: ``{"distance": 0.5}``); other channels must
        be given.
    replan
        Re-plan the remaining phases from where the robot really is after each phase
        (composite behaviors: a turn touching the object can push it off).
    components
        For a composite behavior, the behaviors it is composed of (tags of the
        ``behavior`` column).
    parallel
        The teacher runs a composite's turn and its drive at once where it can (thesis
        §7.2): it turns from the start and drives from where the bearing is within
        ``TeacherConfig.parallel_angle`` of ahead; rows where both run are tagged with both
        components, joined by ``+`` (``turn+approach``).
    corrections
        Corrective demonstrations per start in its default training set (its
        ``train_starts``): runs in which the teacher corrects a disturbance of its heading
        (see :meth:`Teacher.demonstrate`). Simple behaviors only.
    description
        One line for ``--help`` and docs.
    env
        The robot the behavior needs (a gymnasium id) when it is not our Khepera, e.g.
        ``grasp`` needs the gripper: ``collect`` uses it when no ``--env`` is given.
    """

    name: str
    goal: Mapping[str, float]
    phases: PhasePlanner
    train_starts: Callable[[], list[Start]]
    test_starts: str | Callable[[], list[Start]] | None = None
    start_defaults: Mapping[str, float] = field(default_factory=lambda: {"angle": 0.0})
    replan: bool = False
    components: tuple[str, ...] = ()
    parallel: bool = False
    corrections: int = 0
    description: str = ""
    env: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not _NAME.match(self.name):
            raise ConfigError(f"behavior name {self.name!r} must be a lowercase identifier")
        if not self.goal:
            raise ConfigError(f"behavior '{self.name}' needs at least one goal channel")
        for channel, value in self.goal.items():
            spec = CHANNELS.get(channel)
            if spec is None or spec.tolerance is None:
                raise ConfigError(
                    f"behavior '{self.name}': goal channel '{channel}' is not a channel with a "
                    "goal tolerance"
                )
            float(value)
        if isinstance(self.corrections, bool) or not isinstance(self.corrections, int):
            raise ConfigError(f"behavior '{self.name}': corrections must be an integer")
        if self.parallel and len(self.components) != 2:
            raise ConfigError(
                f"behavior '{self.name}': a parallel behavior has two components (a turn and "
                "a drive)"
            )
        if self.corrections < 0 or (self.corrections and self.components):
            raise ConfigError(
                f"behavior '{self.name}': corrections must be >= 0, and 0 for a composite"
            )

    @property
    def goal_channels(self) -> tuple[str, ...]:
        return tuple(self.goal)

    def complete_start(self, start: Mapping[str, float]) -> Start:
        """``start`` with this behavior's defaults filled in; a missing channel is an error."""
        full = {k: float(v) for k, v in start.items()}
        for key in ("angle", "distance"):
            if key not in full:
                if key not in self.start_defaults:
                    raise ConfigError(f"a start for '{self.name}' needs a {key}")
                full[key] = float(self.start_defaults[key])
        return full


BEHAVIORS: dict[str, BehaviorSpec] = {}


def register_behavior(spec: BehaviorSpec, *, replace: bool = False) -> BehaviorSpec:
    """Declare a behavior once; ``collect``, ``train`` and ``experiment`` then know it.

    Registering a different spec under a known name needs ``replace=True``.
    """
    if not isinstance(spec, BehaviorSpec):
        raise ConfigError(f"register_behavior needs a BehaviorSpec, got {type(spec).__name__}")
    known = BEHAVIORS.get(spec.name)
    if known is not None and known != spec and not replace:
        raise ConfigError(
            f"behavior '{spec.name}' is already registered (replace=True to redefine)"
        )
    BEHAVIORS[spec.name] = spec
    return spec


def behavior_spec(name: str) -> BehaviorSpec:
    """The spec of a registered behavior; an unknown name is a clear error."""
    spec = BEHAVIORS.get(name)
    if spec is None:
        import difflib

        close = difflib.get_close_matches(name, list(BEHAVIORS), n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise ConfigError(
            f"unknown behavior '{name}'; choose one of {', '.join(BEHAVIORS)}{hint} "
            "(or register your own with behavior_hmm.teach.register_behavior)"
        )
    return spec


# -- the teacher's own behaviors ---------------------------------------------------------


def grid(lo: float, hi: float, step: float) -> list[float]:
    """``lo, lo + step, ..., hi`` rounded to 6 decimals."""
    n = round((hi - lo) / step)
    return [round(lo + i * step, 6) for i in range(n + 1)]


def _turn_phases(angle: float, distance: float, goal_distance: float | None) -> list[Phase]:
    return [Phase("turn", 0.0)]


def _approach_phases(angle: float, distance: float, goal_distance: float | None) -> list[Phase]:
    return [Phase("approach", 0.0)]


def _retreat_phases(angle: float, distance: float, goal_distance: float | None) -> list[Phase]:
    target = RETREAT_DISTANCE if goal_distance is None else goal_distance
    if target <= distance:
        raise ConfigError(
            f"retreat needs a goal distance beyond the start ({target} m <= {distance} m)"
        )
    return [Phase("retreat", target)]


def _turn_approach_phases(
    angle: float, distance: float, goal_distance: float | None
) -> list[Phase]:
    phases = [Phase("turn", 0.0)] if abs(angle) > ANGLE_TOLERANCE_DEG else []
    if distance > DISTANCE_TOLERANCE_M:
        phases.append(Phase("approach", 0.0))
    return phases


def _position_phases(angle: float, distance: float, goal_distance: float | None) -> list[Phase]:
    if goal_distance is None:
        raise ConfigError("position needs a goal distance (a goal_distance column)")
    phases = [Phase("turn", 0.0)] if abs(angle) > ANGLE_TOLERANCE_DEG else []
    if distance > goal_distance + DISTANCE_TOLERANCE_M:
        phases.append(Phase("approach", goal_distance))
    elif distance < goal_distance - DISTANCE_TOLERANCE_M:
        phases.append(Phase("retreat", goal_distance))
    return phases


def grasp_phases(tag: str = "") -> list[Phase]:
    """The gripper's part of a grasp: open, lower the arm, close on the object, lift."""
    return [
        Phase("open", FINGERS_OPEN_M, tag),
        Phase("lower", ARM_DOWN_DEG, tag),
        Phase("close", FINGERS_CLOSED_M, tag),
        Phase("lift", ARM_UP_DEG, tag),
    ]


def _grasp_phases(angle: float, distance: float, goal_distance: float | None) -> list[Phase]:
    return grasp_phases()


def _turn_approach_grasp_phases(
    angle: float, distance: float, goal_distance: float | None
) -> list[Phase]:
    # approach ends where a grasp can begin: anywhere inside the distance tolerance the
    # object lies between the lowered fingers (assets/khepera_gripper.xml)
    return _turn_approach_phases(angle, distance, goal_distance) + grasp_phases("grasp")


def _turn_grid() -> list[Start]:
    return [{"angle": float(a), "distance": TURN_DISTANCE} for a in range(-180, 181, 10) if a]


def _approach_grid() -> list[Start]:
    return [{"angle": 0.0, "distance": d} for d in grid(0.10, 1.00, 0.05)]


def _retreat_grid() -> list[Start]:
    return [
        {"angle": 0.0, "distance": d, "goal_distance": RETREAT_DISTANCE}
        for d in grid(0.0, 0.90, 0.05)
    ]


def _turn_approach_grid() -> list[Start]:
    angles = [float(a) for a in range(-180, 181, 20) if a]
    distances = grid(0.1, 1.0, 0.1)
    starts = [{"angle": a, "distance": d} for a in angles for d in distances]
    starts += [{"angle": 0.0, "distance": d} for d in distances]
    starts += [{"angle": a, "distance": 0.0} for a in angles]
    return starts


def _grasp_grid() -> list[Start]:
    # where an approach ends: inside the distance and angle tolerances
    return [
        {"angle": a, "distance": d}
        for a in (-3.0, -1.5, 0.0, 1.5, 3.0)
        for d in grid(0.0, DISTANCE_TOLERANCE_M, 0.0025)
    ]


def _turn_approach_grasp_grid() -> list[Start]:
    # all around the object, 0.1-0.5 m away; not touching it (a turn in place touching
    # a 5 g object shoves it away)
    angles = [float(a) for a in range(-180, 181, 30) if a]
    distances = grid(0.1, 0.5, 0.1)
    starts = [{"angle": a, "distance": d} for a in angles for d in distances]
    starts += [{"angle": 0.0, "distance": d} for d in distances]
    return starts


def _position_grid() -> list[Start]:
    angles = [float(a) for a in range(-180, 181, 40) if a] + [0.0]
    starts = []
    for goal in (0.0, 0.25, 0.5, 0.75, 1.0):
        for d in grid(0.0, 1.0, 0.2):
            if abs(d - goal) < 0.05:
                continue
            starts += [{"angle": a, "distance": d, "goal_distance": goal} for a in angles]
    return starts


for _spec in (
    BehaviorSpec(
        "turn",
        {"angle": 0.0},
        _turn_phases,
        _turn_grid,
        "turn_test.csv",
        start_defaults={"distance": TURN_DISTANCE},
        description="turn in place to face the object (-180..180 deg every 10 deg, at 0.5 m)",
    ),
    BehaviorSpec(
        "approach",
        {"distance": 0.0},
        _approach_phases,
        _approach_grid,
        "approach_test.csv",
        # a push off its bearing is undone only by a model that saw the teacher correct one
        # (docs/results.md, "Pushes"): its nominal runs never leave |angle| <= 0.6 deg
        corrections=1,
        description="drive straight to the object (0.10..1.00 m every 0.05 m)",
    ),
    BehaviorSpec(
        "retreat",
        {"distance": RETREAT_DISTANCE},
        _retreat_phases,
        _retreat_grid,
        "retreat_test.csv",
        description="back away from the object to 1.0 m (0.00..0.90 m every 0.05 m)",
    ),
    BehaviorSpec(
        "turn-approach",
        {"angle": 0.0, "distance": 0.0},
        _turn_approach_phases,
        _turn_approach_grid,
        "turn_approach_test.csv",
        replan=True,
        components=("turn", "approach"),
        description="turn to face the object, then approach it (every 20 deg x every 0.1 m)",
    ),
    BehaviorSpec(
        "position",
        {"angle": 0.0, "distance": 0.5},
        _position_phases,
        _position_grid,
        "position_test.csv",
        replan=True,
        components=("turn", "approach", "retreat"),
        description="face the object at a goal distance: turn, then approach or retreat",
    ),
    BehaviorSpec(
        "grasp",
        {"arm": ARM_UP_DEG, "object_present": 1.0},
        _grasp_phases,
        _grasp_grid,
        "grasp_test.csv",
        start_defaults={"angle": 0.0, "distance": 0.004},
        description="open, lower the arm, close on the object and lift it (gripper robot)",
        env=GRIPPER_ENV_ID,
    ),
    BehaviorSpec(
        "turn-approach-grasp",
        {"arm": ARM_UP_DEG, "object_present": 1.0},
        _turn_approach_grasp_phases,
        _turn_approach_grasp_grid,
        "turn_approach_grasp_test.csv",
        replan=True,
        components=("turn", "approach", "grasp"),
        description="turn, approach and grasp the object from all around (gripper robot)",
        env=GRIPPER_ENV_ID,
    ),
    BehaviorSpec(
        "turn-approach-parallel",
        {"angle": 0.0, "distance": 0.0},
        _turn_approach_phases,
        _turn_approach_grid,
        "turn_approach_test.csv",
        components=("turn", "approach"),
        parallel=True,
        description="turn to face the object while driving to it (thesis 7.2: in parallel)",
    ),
):
    register_behavior(_spec)
