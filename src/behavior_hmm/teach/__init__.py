"""Jerk-limited (s-curve) demonstrators for turn / approach / retreat and their compositions."""

from behavior_hmm.teach._behaviors import (
    BEHAVIORS,
    RETREAT_DISTANCE,
    TURN_DISTANCE,
    BehaviorSpec,
    Phase,
    behavior_spec,
    grid,
    register_behavior,
)
from behavior_hmm.teach._collect import DEFAULT_CORRECTION_NOISE, collect, complete_start
from behavior_hmm.teach._demonstrator import (
    Demonstration,
    Teacher,
    TeacherConfig,
    plan_phases,
    wrap_deg,
)
from behavior_hmm.teach._grids import (
    check_start,
    default_starts,
    read_starts,
    scaled_starts,
    test_starts,
)
from behavior_hmm.teach._profiles import DISTANCE_LIMITS, TURN_LIMITS, Limits, SCurve

__all__ = [
    "BEHAVIORS",
    "DEFAULT_CORRECTION_NOISE",
    "DISTANCE_LIMITS",
    "RETREAT_DISTANCE",
    "TURN_DISTANCE",
    "TURN_LIMITS",
    "BehaviorSpec",
    "Demonstration",
    "Limits",
    "Phase",
    "SCurve",
    "Teacher",
    "TeacherConfig",
    "behavior_spec",
    "check_start",
    "collect",
    "complete_start",
    "default_starts",
    "grid",
    "plan_phases",
    "read_starts",
    "register_behavior",
    "scaled_starts",
    "test_starts",
    "wrap_deg",
]
