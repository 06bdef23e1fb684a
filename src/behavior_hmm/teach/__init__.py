"""Jerk-limited (s-curve) demonstrators for turn / approach / retreat and their compositions."""

from behavior_hmm.teach._collect import collect, complete_start
from behavior_hmm.teach._demonstrator import (
    BEHAVIORS,
    Demonstration,
    Phase,
    Teacher,
    TeacherConfig,
    plan_phases,
    wrap_deg,
)
from behavior_hmm.teach._grids import check_start, default_starts, read_starts, test_starts
from behavior_hmm.teach._profiles import DISTANCE_LIMITS, TURN_LIMITS, Limits, SCurve

__all__ = [
    "BEHAVIORS",
    "DISTANCE_LIMITS",
    "TURN_LIMITS",
    "Demonstration",
    "Limits",
    "Phase",
    "SCurve",
    "Teacher",
    "TeacherConfig",
    "check_start",
    "collect",
    "complete_start",
    "default_starts",
    "plan_phases",
    "read_starts",
    "test_starts",
    "wrap_deg",
]
