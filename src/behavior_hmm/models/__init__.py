"""Learned behaviors: SBLM (simple) and CBLM (complex), fit / generate / save / load."""

from behavior_hmm.models._cblm import CBLM
from behavior_hmm.models._sblm import SBLM

__all__ = ["CBLM", "SBLM"]
