"""Motion generators: one small tanh network per motion primitive (thesis §4.2, §6.2).

``MotionGenerators`` trains every primitive's feed-forward network together (stacked
numpy arrays, minibatch backpropagation with momentum); ``ElmanGenerators`` is the
recurrent option (thesis §3.4.3, §7.2: backpropagation through time); ``make_windows``
builds the causal sensor windows they read.
"""

from typing import Final

from behavior_hmm.generators._motion import (
    DEFAULT_BATCH_SIZE,
    DEFAULT_GENERATOR_EPOCHS,
    GENERATOR_INITS,
    MotionGenerators,
)
from behavior_hmm.generators._recurrent import ElmanGenerators
from behavior_hmm.generators._windows import make_windows

#: The generator networks an SBLM can use, by name (``SBLM(generator_network=...)``);
#: the first is the thesis's and the default.
GENERATOR_NETWORKS: Final[dict[str, type[MotionGenerators] | type[ElmanGenerators]]] = {
    "mlp": MotionGenerators,
    "elman": ElmanGenerators,
}

__all__ = [
    "DEFAULT_BATCH_SIZE",
    "DEFAULT_GENERATOR_EPOCHS",
    "GENERATOR_INITS",
    "GENERATOR_NETWORKS",
    "ElmanGenerators",
    "MotionGenerators",
    "make_windows",
]
