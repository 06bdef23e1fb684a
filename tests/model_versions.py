"""Model files of format version 1, written from a current model (imported as
``model_versions``): the upgrade tests convert them back and compare the bytes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.sparse import csr_array

from behavior_hmm.hmm import BehaviorHMM
from behavior_hmm.hmm._counting import normalize
from behavior_hmm.models import _modelfile

__all__ = ["as_version_1"]


def _dense_hmm(arrays: dict[str, np.ndarray], params: dict[str, object]) -> dict[str, np.ndarray]:
    """Version 1's Behavior-HMM arrays: every table dense, probabilities beside counts."""
    hmm = BehaviorHMM.from_arrays(arrays, params)
    out: dict[str, np.ndarray] = dict(hmm.dense_probabilities())
    n, m = hmm.n_states_, hmm.n_observations_
    for name, shape in (("A", (n, n)), ("B", (n, m)), ("C", (m, m))):
        table = csr_array(
            (arrays[f"{name}_counts"], arrays[f"{name}_indices"], arrays[f"{name}_indptr"]),
            shape=shape,
        )
        out[f"{name}_counts"] = table.toarray().astype(np.int64)
    out["pi_counts"] = arrays["pi_counts"]
    out["start_counts"] = arrays["start_counts"]
    out["start_prob_first"] = normalize(arrays["start_counts"], hmm.smoothing, zero_diagonal=False)
    return out


def _version_1_bytes(data: bytes, monkeypatch: pytest.MonkeyPatch) -> bytes:
    header, arrays = _modelfile.loads(data, "model")
    hmm = {k.removeprefix("hmm."): v for k, v in arrays.items() if k.startswith("hmm.")}
    out = {k: v for k, v in arrays.items() if not k.startswith("hmm.")}
    for key, value in _dense_hmm(hmm, header["state"]["hmm"]).items():
        out[f"hmm.{key}"] = value
    for key in [k for k in out if k.startswith("component.")]:
        inner = _version_1_bytes(out[key].tobytes(), monkeypatch)
        out[key] = np.frombuffer(inner, dtype=np.uint8)
    with monkeypatch.context() as patch:
        patch.setattr(_modelfile, "VERSION", 1)
        return _modelfile.dumps(header["kind"], header["params"], header["state"], out)


def as_version_1(path: Path, out: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Write ``out``: the model file ``path`` as format version 1 stored it."""
    out.write_bytes(_version_1_bytes(path.read_bytes(), monkeypatch))
    return out
