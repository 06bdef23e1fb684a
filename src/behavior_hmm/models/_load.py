"""Load any model file, whichever kind it holds."""

from __future__ import annotations

import os

from behavior_hmm.errors import ModelFileError
from behavior_hmm.models import _modelfile
from behavior_hmm.models._cblm import CBLM
from behavior_hmm.models._sblm import SBLM

#: Model classes by the ``kind`` their files carry.
MODEL_KINDS: dict[str, type[SBLM] | type[CBLM]] = {"SBLM": SBLM, "CBLM": CBLM}


def load(path: str | os.PathLike[str]) -> SBLM | CBLM:
    """Read an SBLM or CBLM file (validated as by ``SBLM.load`` / ``CBLM.load``).

    Raises
    ------
    ModelFileError
        A file that is no model, or a model of an unknown kind; the one-line message
        starts with ``path``.
    """
    header, _ = _modelfile.load(path)
    kind = header.get("kind")
    cls = MODEL_KINDS.get(str(kind))
    if cls is None:
        raise ModelFileError(f"{path}: unknown model kind {kind!r}")
    return cls.load(path)
