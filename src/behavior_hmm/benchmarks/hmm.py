"""Viterbi decoding, ours against hmmlearn's compiled one, on the same models, in one run.

For each size (states × steps) a Behavior-HMM is counted from random labels with add-one
smoothing (so every table is dense and every row is a distribution, as hmmlearn
requires), with 4 observation categories per state (our trained models have 3–4: turn
30 / 98, approach 25 / 77). hmmlearn's ``CategoricalHMM`` gets the same probabilities
(``startprob_ = π``, ``transmat_ = A``, ``emissionprob_ = B`` from ``to_arrays()``), and
both decode the same random observation sequence:

* ``ours_us_median``: ``BehaviorHMM.viterbi(observations)`` (public API, validation
  included);
* ``hmmlearn_us_median``: ``CategoricalHMM.decode(X, algorithm="viterbi")`` (public API);
* ``*_kernel_us_median``: the bare kernels, ``viterbi_log`` against hmmlearn's compiled
  ``_hmmc.viterbi`` given the frame log-likelihoods (informative; private functions).

``kernel`` (top level) names the forward pass "ours" ran: ``"numba"`` when numba is
installed (the ``fast`` extra), else ``"numpy"``. With numba, the numpy path is timed in
the same run too (``ours_numpy_us_median`` and ``ours_numpy_kernel_us_median``, forced
with ``set_kernel("numpy")``), so that ``numpy_over_numba`` is the compiled kernel's
speed-up measured under the same load, and ``kernels_agree`` says whether both gave the
same path and log probability (they must, to the bit). The compiled kernels are loaded
(or compiled, on the first run after an install) before anything is timed:
``jit_warmup_s`` is that time, which a decoding pays once per process.

All sides are timed alternately, repeat by repeat, so that load on a shared machine
hits them alike. ``paths_agree`` says whether the decoded paths are identical to
hmmlearn's (and the log probabilities are compared too). hmmlearn is an optional
dependency (``pip install 'behavior-hmm[bench]'``); without it only our side is timed.

``sparse`` repeats the comparison on models counted without smoothing, as trained
Behavior-HMMs are: each state has a few successors and emits a few categories, so most
of A and B is zero (``-inf`` in log space), and the observations are a walk of the model
(``transition_density`` is the share of possible transitions). hmmlearn's work does not
depend on it; ours scores only the possible transitions.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np

#: (states, steps) pairs timed; the quick run keeps both sizes with fewer repeats.
SIZES = ((50, 200), (500, 1000))
#: Observation categories per state.
CATEGORIES_PER_STATE = 4
#: Successors per state in the sparse models.
SPARSE_SUCCESSORS = 4


def _model(n_states: int, n_observations: int, rng: np.random.Generator) -> Any:
    """A dense Behavior-HMM counted from random labels (add-one smoothing)."""
    from behavior_hmm.hmm import BehaviorHMM

    samples = max(20_000, 4 * n_states * n_states)
    states = rng.integers(0, n_states, samples)
    observations = rng.integers(0, n_observations, samples)
    hmm = BehaviorHMM(n_states=n_states, n_observations=n_observations, smoothing=1.0)
    return hmm.fit(states, observations)


def _sparse_model(
    n_states: int, n_observations: int, steps: int, rng: np.random.Generator
) -> tuple[Any, np.ndarray]:
    """A sparse Behavior-HMM (no smoothing) and an observation sequence it can explain.

    Counted from a walk on a random graph with ``SPARSE_SUCCESSORS`` successors per state
    (one of them the next state of a cycle through all, so every state recurs), each
    state emitting one of ``CATEGORIES_PER_STATE`` categories; the decoded sequence is
    the first ``steps`` observations of that walk.
    """
    from behavior_hmm.hmm import BehaviorHMM

    successors = rng.integers(0, n_states, (n_states, SPARSE_SUCCESSORS))
    successors[:, 0] = (np.arange(n_states) + 1) % n_states
    emitted = rng.integers(0, n_observations, (n_states, CATEGORIES_PER_STATE))
    samples = max(20_000, 200 * n_states)
    picks = rng.integers(0, SPARSE_SUCCESSORS, samples).tolist()
    table = successors.tolist()
    walk = [int(rng.integers(0, n_states))]
    for pick in picks[1:]:
        walk.append(table[walk[-1]][pick])
    states = np.array(walk)
    observations = emitted[states, rng.integers(0, CATEGORIES_PER_STATE, samples)]
    hmm = BehaviorHMM(n_states=n_states, n_observations=n_observations, smoothing=0.0)
    return hmm.fit(states, observations), observations[:steps]


def _hmmlearn_model(hmm: Any) -> Any:
    from hmmlearn.hmm import CategoricalHMM

    probs = hmm.dense_probabilities()
    theirs = CategoricalHMM(n_components=hmm.n_states_, n_features=hmm.n_observations_)
    theirs.startprob_ = probs["pi"]
    theirs.transmat_ = probs["A"]
    theirs.emissionprob_ = probs["B"]
    return theirs


def _alternate(
    fns: dict[str, Callable[[], Any]], repeats: int, numpy_kernel: frozenset[str] = frozenset()
) -> dict[str, float]:
    """Median µs of each function, the functions timed in turn within every repeat.

    The functions named in ``numpy_kernel`` run with ``viterbi_log``'s numpy forward
    pass (switched outside the timed interval), the others with the default kernel.
    """
    from behavior_hmm.hmm._viterbi import set_kernel

    times: dict[str, list[float]] = {name: [] for name in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            previous = set_kernel("numpy") if name in numpy_kernel else None
            try:
                t0 = time.perf_counter()
                fn()
                times[name].append((time.perf_counter() - t0) * 1e6)
            finally:
                if previous is not None:
                    set_kernel(previous)
    return {name: float(np.median(t)) for name, t in times.items()}


def _size(
    n_states: int, steps: int, repeats: int, rng: np.random.Generator, sparse: bool = False
) -> dict[str, Any]:
    from behavior_hmm.hmm._viterbi import set_kernel, viterbi_kernel, viterbi_log

    n_obs = CATEGORIES_PER_STATE * n_states
    if sparse:
        hmm, observations = _sparse_model(n_states, n_obs, steps, rng)
    else:
        hmm = _model(n_states, n_obs, rng)
        observations = rng.integers(0, n_obs, steps)
    ours_states, ours_log_prob = hmm.viterbi(observations)
    row: dict[str, Any] = {
        "states": n_states,
        "steps": steps,
        "observation_categories": n_obs,
        "repeats": repeats,
    }
    if sparse:
        row["transition_density"] = float(np.isfinite(hmm.log_A_).mean())
    fns: dict[str, Callable[[], Any]] = {
        "ours": lambda: hmm.viterbi(observations),
        "ours_kernel": lambda: viterbi_log(hmm.log_pi_, hmm.log_A_, hmm.log_B_, observations),
    }
    numpy_kernel: frozenset[str] = frozenset()
    if viterbi_kernel() == "numba":  # the numpy path too, for the speed-up in one run
        fns["ours_numpy"], fns["ours_numpy_kernel"] = fns["ours"], fns["ours_kernel"]
        numpy_kernel = frozenset({"ours_numpy", "ours_numpy_kernel"})
        previous = set_kernel("numpy")
        try:
            numpy_states, numpy_log_prob = hmm.viterbi(observations)
        finally:
            set_kernel(previous)
        row["kernels_agree"] = bool(
            np.array_equal(ours_states, numpy_states) and ours_log_prob == numpy_log_prob
        )
    try:
        from hmmlearn import _hmmc
    except ImportError:
        _hmmc = None
    if _hmmc is not None:
        theirs = _hmmlearn_model(hmm)
        x = observations.reshape(-1, 1)
        frame_log_prob = hmm.log_B_.columns(observations)
        start, trans = theirs.startprob_, theirs.transmat_
        fns["hmmlearn"] = lambda: theirs.decode(x, algorithm="viterbi")
        fns["hmmlearn_kernel"] = lambda: _hmmc.viterbi(start, trans, frame_log_prob)
        their_log_prob, their_states = theirs.decode(x, algorithm="viterbi")
        row["paths_agree"] = bool(np.array_equal(ours_states, their_states))
        row["log_prob_abs_diff"] = abs(float(ours_log_prob) - float(their_log_prob))
    medians = _alternate(fns, repeats, numpy_kernel)
    for name, value in medians.items():
        row[f"{name}_us_median"] = value
    if _hmmc is not None:
        row["ours_over_hmmlearn"] = medians["ours"] / medians["hmmlearn"]
    else:
        row["hmmlearn_us_median"] = None
    if numpy_kernel:
        row["numpy_over_numba"] = medians["ours_numpy"] / medians["ours"]
    else:
        row["ours_numpy_us_median"] = None
    return row


def run(quick: bool = False, *, sizes: tuple[tuple[int, int], ...] = SIZES) -> dict[str, Any]:
    """Time the Viterbi decodings at ``sizes`` ((states, steps) pairs); see the module."""
    from behavior_hmm.hmm._viterbi import viterbi_kernel

    t0 = time.perf_counter()
    kernel = viterbi_kernel()  # imports numba and loads (or compiles) the kernels
    jit_warmup_s = time.perf_counter() - t0
    rng = np.random.default_rng(0)
    rows = []
    sparse_rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # hmmlearn's deprecation notices, not ours to fix
        for n_states, steps in sizes:
            small = n_states * n_states * steps < 10**6
            repeats = (21 if quick else 101) if small else (3 if quick else 21)
            rows.append(_size(n_states, steps, repeats, rng))
        for n_states, steps in sizes:
            small = n_states * n_states * steps < 10**6
            repeats = (21 if quick else 51) if small else (3 if quick else 7)
            sparse_rows.append(_size(n_states, steps, repeats, rng, sparse=True))
    results: dict[str, Any] = {"sizes": rows, "sparse": sparse_rows, "kernel": kernel}
    if kernel == "numba":
        results["jit_warmup_s"] = jit_warmup_s
        results["kernels_agree"] = all(row["kernels_agree"] for row in rows + sparse_rows)
    try:
        import hmmlearn

        results["hmmlearn_version"] = str(hmmlearn.__version__)
        results["paths_agree"] = all(row["paths_agree"] for row in rows + sparse_rows)
    except ImportError:
        results["hmmlearn_version"] = None
        results["note"] = "hmmlearn is not installed: pip install 'behavior-hmm[bench]'"
    return results


if __name__ == "__main__":
    import json

    print(json.dumps(run(), indent=2))
