"""Closed-loop behavior execution (thesis Algorithm 1) and hierarchical delegation."""

from behavior_hmm.runtime._loop import run_behavior, run_controller, start_options
from behavior_hmm.runtime._simple import SimpleController, StepOutput, make_controller
from behavior_hmm.runtime._trace import Trace

__all__ = [
    "SimpleController",
    "StepOutput",
    "Trace",
    "make_controller",
    "run_behavior",
    "run_controller",
    "start_options",
]
