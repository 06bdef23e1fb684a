"""Running any policy on any robot: the control loop, the robot contract and traces.

``runtime`` knows no model: a model's policy lives with the model
(``SBLM.policy(goal)``, ``CBLM.policy(goal)``) and meets :class:`Policy`;
:func:`run_policy` runs one on any Gymnasium env that meets the robot contract
(:class:`Robot`, docs/robots.md) and records a :class:`Trace`.
"""

from behavior_hmm.runtime._calibration import (
    WheelCalibration,
    reference_gains,
    wheel_response,
)
from behavior_hmm.runtime._loop import (
    DEFAULT_FAULT_HOLD_S,
    SensorHold,
    hold_steps,
    run_policy,
    start_options,
)
from behavior_hmm.runtime._policy import Policy, StepOutput
from behavior_hmm.runtime._robot import (
    REQUIRED_CHANNELS,
    Robot,
    RobotSpec,
    make_robot_env,
    ordered_channels,
    parse_env_kwargs,
)
from behavior_hmm.runtime._trace import Trace

__all__ = [
    "DEFAULT_FAULT_HOLD_S",
    "REQUIRED_CHANNELS",
    "Policy",
    "Robot",
    "RobotSpec",
    "SensorHold",
    "StepOutput",
    "Trace",
    "WheelCalibration",
    "hold_steps",
    "make_robot_env",
    "ordered_channels",
    "parse_env_kwargs",
    "reference_gains",
    "run_policy",
    "start_options",
    "wheel_response",
]
