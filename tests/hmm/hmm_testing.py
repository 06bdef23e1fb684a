"""Helpers shared by the Behavior-HMM tests: build models straight from count tables."""

from __future__ import annotations

from typing import Any

import numpy as np

from behavior_hmm.hmm import BehaviorHMM
from behavior_hmm.hmm._counting import normalize


def model_from_counts(
    A: Any,
    B: Any,
    C: Any,
    pi: Any | None = None,
    start: Any | None = None,
    **params: Any,
) -> BehaviorHMM:
    """A fitted model whose tables are the given counts, normalized (through ``from_arrays``)."""
    A = np.asarray(A, dtype=np.int64)
    B = np.asarray(B, dtype=np.int64)
    C = np.asarray(C, dtype=np.int64)
    pi = B.sum(axis=1) if pi is None else np.asarray(pi, dtype=np.int64)
    start = pi if start is None else np.asarray(start, dtype=np.int64)
    probe = BehaviorHMM(**params)
    k = float(probe.smoothing)
    zero_diag = not probe.self_transitions
    arrays = {
        "A": normalize(A, k, zero_diagonal=zero_diag),
        "B": normalize(B, k, zero_diagonal=False),
        "C": normalize(C, k, zero_diagonal=zero_diag),
        "pi": normalize(pi, k, zero_diagonal=False),
        "start_prob_first": normalize(start, k, zero_diagonal=False),
        "A_counts": A,
        "B_counts": B,
        "C_counts": C,
        "pi_counts": pi,
        "start_counts": start,
    }
    return BehaviorHMM.from_arrays(arrays, params)


def probs(counts: Any) -> np.ndarray:
    """Row-normalize counts in plain float arithmetic (independent of the package)."""
    c = np.asarray(counts, dtype=float)
    tot = c.sum(axis=-1, keepdims=True)
    return np.where(tot > 0, c / np.where(tot > 0, tot, 1.0), 0.0)
