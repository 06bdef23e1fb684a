"""behavior-hmm: learn robot behaviors from unlabeled demonstrations.

CobART categorizes sensor streams into motion primitives and observation
categories, a Behavior-HMM models how primitives follow each other, one small
network per primitive generates wheel commands, and learned behaviors compose
into complex ones (SBLM / CBLM, after the thesis in ``shared/reference``).
"""

from behavior_hmm.errors import (
    BehaviorHMMError,
    ConfigError,
    DatasetError,
    ModelFileError,
    NotFittedError,
    SimulationError,
    UnreachableGoalError,
)

__version__ = "0.1.0"

from behavior_hmm._envs import register_envs as _register_envs

_register_envs()

__all__ = [
    "BehaviorHMMError",
    "ConfigError",
    "DatasetError",
    "ModelFileError",
    "NotFittedError",
    "SimulationError",
    "UnreachableGoalError",
    "__version__",
]
