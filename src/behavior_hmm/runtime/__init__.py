"""Closed-loop behavior execution (thesis Algorithm 1) and hierarchical delegation."""

from behavior_hmm.runtime._loop import (
    DEFAULT_FAULT_HOLD_S,
    SensorHold,
    channels_read,
    run_behavior,
    run_controller,
    start_options,
)
from behavior_hmm.runtime._simple import SimpleController, StepOutput, make_controller
from behavior_hmm.runtime._trace import Trace

__all__ = [
    "DEFAULT_FAULT_HOLD_S",
    "SensorHold",
    "SimpleController",
    "StepOutput",
    "Trace",
    "channels_read",
    "make_controller",
    "run_behavior",
    "run_controller",
    "start_options",
]
