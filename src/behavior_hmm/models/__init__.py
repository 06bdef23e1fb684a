"""Learned behaviors: SBLM (simple) and CBLM (complex), fit / generate / save / load.

Both are selectable in two presets (DESIGN §10): ``SBLM.from_preset("thesis", ...)`` is the
method as published; the constructor defaults are the ``default`` preset. Every departure
is listed in :data:`DEPARTURES`; the measured options the default leaves off (recurrent
generators, inputs chosen from the data) in :data:`OPTIONS`.
"""

from behavior_hmm.models._cblm import CBLM
from behavior_hmm.models._config import read_config, resolve_params
from behavior_hmm.models._goals import AUTO_INPUTS
from behavior_hmm.models._inputs import InputChoice, select_inputs
from behavior_hmm.models._load import MODEL_KINDS, load
from behavior_hmm.models._policy import perform
from behavior_hmm.models._presets import (
    DEPARTURES,
    OPTIONS,
    PRESETS,
    Departure,
    Option,
    describe_params,
    preset_params,
)
from behavior_hmm.models._sblm import SBLM

__all__ = [
    "AUTO_INPUTS",
    "CBLM",
    "DEPARTURES",
    "MODEL_KINDS",
    "OPTIONS",
    "PRESETS",
    "SBLM",
    "Departure",
    "InputChoice",
    "Option",
    "describe_params",
    "load",
    "perform",
    "preset_params",
    "read_config",
    "resolve_params",
    "select_inputs",
]
