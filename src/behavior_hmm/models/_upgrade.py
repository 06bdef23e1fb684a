"""Convert a model file of an earlier format version to the current one.

``behavior-hmm upgrade MODEL`` runs :func:`upgrade`. Version 1 stored the Behavior-HMM's
tables densely, probabilities beside their counts; version 2 stores the counts only, A,
B and C as compressed sparse rows. The probabilities are the counts normalized under the
model's parameters, so the conversion loses nothing: the upgraded model plans, decodes
and generates exactly as the old file did. A CBLM's embedded components are upgraded
with it, at every depth. The old file is read with every bound of
:mod:`~behavior_hmm.models._modelfile` (it may come from a stranger), and its
probabilities must still match its counts, as the version 1 reader required.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import numpy as np
from scipy.sparse import csr_array

from behavior_hmm._atomic import atomic_write_bytes
from behavior_hmm.errors import ModelFileError
from behavior_hmm.hmm import BehaviorHMM
from behavior_hmm.hmm._counting import normalize
from behavior_hmm.hmm._tables import canonical, csr_arrays
from behavior_hmm.models import _modelfile

#: The dense Behavior-HMM arrays of a version 1 file: probability -> its counts.
_V1_TABLES = {
    "A": "A_counts",
    "B": "B_counts",
    "C": "C_counts",
    "pi": "pi_counts",
    "start_prob_first": "start_counts",
}
#: How far a version 1 probability may lie from its normalized count (its reader's rule).
_V1_MATCH_TOL = 1e-9


def upgrade(
    path: str | os.PathLike[str], out: str | os.PathLike[str] | None = None
) -> tuple[int, int]:
    """Rewrite the model file ``path`` in the current format, to ``out`` (default: in place).

    The new file is written atomically: on any error nothing is written and ``path`` is
    unchanged. A file already in the current format is rewritten as it is.

    Returns
    -------
    (old version, new version)

    Raises
    ------
    ModelFileError
        Not a model file, of a version that cannot be converted, or malformed; the
        one-line message starts with ``path``.
    """
    where = str(path)
    data = _modelfile._read_regular_file(path, where)
    new, version = upgrade_bytes(data, where, _modelfile.Budget())
    atomic_write_bytes(path if out is None else out, new)
    return version, _modelfile.VERSION


def upgrade_bytes(data: bytes, where: str, budget: _modelfile.Budget) -> tuple[bytes, int]:
    """The bytes of ``data`` (a model file) in the current format, and its old version."""
    versions = _modelfile.UPGRADABLE | {_modelfile.VERSION}
    header, arrays = _modelfile.loads(data, where, budget, versions=frozenset(versions))
    version = int(header["version"])
    if version == _modelfile.VERSION:
        return data, version
    try:
        params = _modelfile.check_mapping(header["state"].get("hmm"), "hmm")
        converted: dict[str, np.ndarray] = {}
        hmm: dict[str, np.ndarray] = {}
        for name, arr in arrays.items():
            if name.startswith("hmm."):
                hmm[name.removeprefix("hmm.")] = arr
            elif name.startswith("component."):
                with budget.component():
                    inner, _ = upgrade_bytes(arr.tobytes(), f"{where} {name}", budget)
                converted[name] = np.frombuffer(inner, dtype=np.uint8)
            else:
                converted[name] = arr
        for name, arr in _v1_hmm(hmm, params).items():
            converted[f"hmm.{name}"] = arr
        new = _modelfile.dumps(header["kind"], header["params"], header["state"], converted)
    except ModelFileError as err:
        raise _modelfile.refused(where, str(err)) from None
    except (ArithmeticError, AttributeError, LookupError, TypeError, ValueError) as err:
        raise _modelfile.refused(where, f"invalid model contents ({err})") from None
    return new, version


def _v1_hmm(arrays: Mapping[str, np.ndarray], params: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """The version 2 arrays of a version 1 Behavior-HMM (checked by ``from_arrays``)."""
    missing = sorted({*_V1_TABLES, *_V1_TABLES.values()} - set(arrays))
    if missing:
        raise ModelFileError(f"Behavior-HMM arrays missing from the version 1 file: {missing}")
    model = BehaviorHMM(**dict(params))
    smoothing = float(model.smoothing)
    counts: dict[str, np.ndarray] = {}
    for key, ckey in _V1_TABLES.items():
        c = arrays[ckey]
        p = arrays[key]
        if c.dtype.kind not in "iu" or p.dtype.kind != "f" or c.shape != p.shape:
            raise ModelFileError(f"arrays '{key}' and '{ckey}' are not probabilities and counts")
        structural = key in ("A", "C") and not model.self_transitions
        expected = normalize(c, smoothing, zero_diagonal=structural)
        if not np.all(np.abs(expected - p) <= _V1_MATCH_TOL):
            raise ModelFileError(f"array '{key}' does not match the normalized '{ckey}'")
        counts[ckey] = np.asarray(c, dtype=np.int64)
    out: dict[str, np.ndarray] = {}
    for name in ("A", "B", "C"):
        dense = counts[f"{name}_counts"]
        if dense.ndim != 2:
            raise ModelFileError(f"array '{name}_counts' must be 2-D")
        out.update(csr_arrays(name, canonical(csr_array(dense))))
    out["pi_counts"] = counts["pi_counts"]
    out["start_counts"] = counts["start_counts"]
    BehaviorHMM.from_arrays(out, params)  # the converted tables pass the current checks
    return out
