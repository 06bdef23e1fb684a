"""Motion generators: one small tanh network per motion primitive (thesis §4.2, §6.2).

``MotionGenerators`` trains every primitive's network together (stacked numpy
arrays, minibatch backpropagation with momentum); ``make_windows`` builds the
causal sensor windows they read.
"""

from behavior_hmm.generators._motion import (
    DEFAULT_BATCH_SIZE,
    DEFAULT_GENERATOR_EPOCHS,
    MotionGenerators,
)
from behavior_hmm.generators._windows import make_windows

__all__ = ["DEFAULT_BATCH_SIZE", "DEFAULT_GENERATOR_EPOCHS", "MotionGenerators", "make_windows"]
