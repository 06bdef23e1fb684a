"""The numba-compiled Viterbi kernels: forward pass and backtracking.

numba is optional, the ``fast`` extra (``pip install 'behavior-hmm[fast]'``). Without it
:func:`~behavior_hmm.hmm._viterbi.viterbi_log` runs its numpy forward pass, whose step
costs at least four numpy calls and their per-call overhead: ~4.5 µs a step at 50
states, against ~2.7 µs for hmmlearn's compiled loop. Measured at 50 states × 200 steps:
~1,100 µs for the numpy path, ~540 µs for hmmlearn's kernel (~745 µs for its public
``decode``), ~100 µs for a numba forward pass; at 500 × 1000: 164 ms (numpy), 400 ms
(hmmlearn), ~95 ms (numba).

numba is imported on the first call of :func:`kernels`, never when ``behavior_hmm`` is
imported (importing numba takes ~0.3 s). The kernels are compiled with ``cache=True``
(the machine code is kept in ``__pycache__`` next to this file, so later processes load
it instead of compiling) and ``nogil=True``, and without ``fastmath``: every sum is the
one the numpy path forms, in the same order, so the results are identical to the bit.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from behavior_hmm._numba import compile_kernels

#: numba signatures (C-contiguous arrays), compiled eagerly when :func:`kernels` first runs.
_FORWARD_SIGNATURE = "void(float64[:, ::1], float64[:, ::1], float64[:, ::1], intp[:, ::1])"
_FOLLOW_SIGNATURE = "void(intp[:, ::1], intp, int64[::1])"
_FORWARD_SPARSE_SIGNATURE = (
    "void(intp[::1], intp[::1], float64[::1], float64[:, ::1], float64[:, ::1], intp[:, ::1])"
)


class Kernels(NamedTuple):
    """The compiled kernels (see :func:`forward` and :func:`follow` for what they do)."""

    forward: Callable[
        [NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.intp]], None
    ]
    forward_sparse: Callable[
        [
            NDArray[np.intp],
            NDArray[np.intp],
            NDArray[np.float64],
            NDArray[np.float64],
            NDArray[np.float64],
            NDArray[np.intp],
        ],
        None,
    ]
    follow: Callable[[NDArray[np.intp], int, NDArray[np.int64]], None]


@functools.cache
def kernels() -> Kernels | None:
    """The compiled kernels, or ``None`` when numba cannot be imported.

    Compiled (or loaded from numba's cache) on the first call; later calls return the
    same object.
    """
    return compile_kernels(_compiled)


def _compiled(numba: Any, cache: bool) -> Kernels:
    jit = numba.njit
    return Kernels(
        forward=jit(_FORWARD_SIGNATURE, cache=cache, nogil=True)(forward),
        forward_sparse=jit(_FORWARD_SPARSE_SIGNATURE, cache=cache, nogil=True)(forward_sparse),
        follow=jit(_FOLLOW_SIGNATURE, cache=cache, nogil=True)(follow),
    )


def forward(
    log_A: NDArray[np.float64],
    emit: NDArray[np.float64],
    lattice: NDArray[np.float64],
    psi: NDArray[np.intp],
) -> None:
    """Fill ``lattice[1:]`` with the best log scores and ``psi[1:]`` with their arguments.

    Plain Python, compiled by :func:`kernels`: far too slow to call as it is.

    Parameters
    ----------
    log_A
        Log transitions, shape (N, N), C-contiguous; row i = the transitions out of i.
    emit
        Log emissions of the observations, shape (T, N), C-contiguous; row t =
        ``log b_j(o_t)`` for every state j.
    lattice
        Best log scores, shape (T, N); row 0 (the start scores) is filled by the caller.
    psi
        Best predecessors, shape (T, N); rows 1.. are filled, row 0 is left as it is.

    Notes
    -----
    ``lattice[t, j] = max_i (lattice[t-1, i] + log a_ij) + log b_j(o_t)``, the sums formed
    in the order of the numpy path and of hmmlearn (``delta_i + log a_ij``, then
    ``+ log b_j``). The predecessors are scanned in increasing order and replace the best
    one only when strictly better, so among equal scores the lowest index wins, as with
    numpy's argmax. ``-inf`` needs no special case: no log value is ever subtracted.
    The loop over the predecessors is the outer one so that ``log_A`` is read row by row.
    """
    t_len, n = lattice.shape
    best = np.empty(n)
    for t in range(1, t_len):
        prev = lattice[t - 1]
        arg = psi[t]
        first = prev[0]
        for j in range(n):
            best[j] = first + log_A[0, j]
            arg[j] = 0
        for i in range(1, n):
            score = prev[i]
            row = log_A[i]
            for j in range(n):
                s = score + row[j]
                if s > best[j]:
                    best[j] = s
                    arg[j] = i
        cur = lattice[t]
        e = emit[t]
        for j in range(n):
            cur[j] = best[j] + e[j]


def forward_sparse(
    starts: NDArray[np.intp],
    source: NDArray[np.intp],
    weights: NDArray[np.float64],
    emit: NDArray[np.float64],
    lattice: NDArray[np.float64],
    psi: NDArray[np.intp],
) -> None:
    """:func:`forward` over the possible transitions only (most of ``log_A`` is ``-inf``).

    Plain Python, compiled by :func:`kernels`.

    Parameters
    ----------
    starts
        Shape (N + 1,): the possible transitions into state j are entries
        ``starts[j] .. starts[j + 1] - 1`` of ``source`` and ``weights``.
    source, weights
        Their predecessor states, in increasing order for each j, and ``log a_ij``.
    emit, lattice, psi
        As in :func:`forward`.

    Notes
    -----
    The same sums in the same order as :func:`forward`, the predecessors scanned in
    increasing order and replaced only when strictly better, so on every possible path
    the scores and the predecessors are those of the dense pass; a state no transition
    reaches scores ``-inf`` (predecessor 0). Work is proportional to the possible
    transitions: a trained 500-state model has about 1 % of them.
    """
    t_len, n = lattice.shape
    for t in range(1, t_len):
        prev = lattice[t - 1]
        arg = psi[t]
        cur = lattice[t]
        e = emit[t]
        for j in range(n):
            best = -np.inf
            best_i = 0
            for k in range(starts[j], starts[j + 1]):
                s = prev[source[k]] + weights[k]
                if s > best:
                    best = s
                    best_i = source[k]
            arg[j] = best_i
            cur[j] = best + e[j]


def follow(psi: NDArray[np.intp], last: int, states: NDArray[np.int64]) -> None:
    """Write into ``states`` (shape (T,)) the path through ``psi`` that ends in ``last``.

    Plain Python, compiled by :func:`kernels`.
    """
    state = last
    for t in range(psi.shape[0] - 1, 0, -1):
        states[t] = state
        state = psi[t, state]
    states[0] = state
