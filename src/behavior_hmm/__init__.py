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


def _register_for_the_command_line() -> None:
    """Register our Gymnasium ids (importing gymnasium: the longest part of start-up).

    Under the ``behavior-hmm`` console script, whose entry point (``cli.main``) is not
    running yet while this package imports, Ctrl-C here ends the command as it does
    everywhere else: one line ``interrupted`` and exit 130, no traceback. Anywhere else
    (a program or notebook importing the package) the KeyboardInterrupt propagates.
    """
    import os
    import sys

    try:
        _register_envs()
    except KeyboardInterrupt:
        if os.path.basename(sys.argv[0] if sys.argv else "") != "behavior-hmm":
            raise
        sys.stderr.write("interrupted\n")
        raise SystemExit(130) from None


_register_for_the_command_line()

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
