"""Sparse tables of the Behavior-HMM: counts and log probabilities of B and C.

A trained model's emission table B (states × observation categories) and observation
transition table C (categories × categories) are almost all zero: the turn & approach
CBLM's C holds 4,630 counts among 2,315² cells (0.09 %). So they are counted, stored and
used as compressed sparse rows (``scipy.sparse.csr_array``): memory and load time grow
with the counted entries, not with the categories squared.

Their log probabilities are a :class:`LogTable`: the entries that were counted, plus one
value per row for every entry that was not: ``-inf`` without smoothing, the smoothed
probability of a zero count with it. Every dense answer (a column of B for Viterbi, the
whole table for a small model's tests) is derived from that, so a model that smooths
stays exact without ever holding a dense table.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_array, csr_array

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


def count_pairs(rows: IntArray, cols: IntArray, shape: tuple[int, int]) -> csr_array:
    """How often each ``(rows[k], cols[k])`` pair occurs, as canonical int64 CSR counts.

    Canonical: within a row the column indices increase strictly, and no stored count is
    zero (what :func:`check_counts` requires of a model file).
    """
    ones = np.ones(rows.shape[0], dtype=np.int64)
    counts = coo_array((ones, (rows, cols)), shape=shape).tocsr()
    counts.sum_duplicates()
    return _int64(counts)


def _int64(counts: csr_array) -> csr_array:
    """``counts`` with int64 data and index arrays (scipy picks int32 where it fits)."""
    return csr_array(
        (
            np.asarray(counts.data, dtype=np.int64),
            np.asarray(counts.indices, dtype=np.int64),
            np.asarray(counts.indptr, dtype=np.int64),
        ),
        shape=counts.shape,
    )


def grown_sparse(counts: csr_array, shape: tuple[int, int]) -> csr_array:
    """``counts`` enlarged to ``shape`` with empty trailing rows and columns."""
    rows, cols = counts.shape
    if rows > shape[0] or cols > shape[1]:
        raise ValueError(f"cannot grow a table of shape {counts.shape} to {shape}")
    indptr = np.concatenate(
        [counts.indptr, np.full(shape[0] - rows, counts.indptr[-1], dtype=counts.indptr.dtype)]
    )
    return csr_array((counts.data, counts.indices, indptr), shape=shape)


def canonical(counts: csr_array) -> csr_array:
    """``counts`` with sorted indices, duplicates summed and stored zeros dropped (int64)."""
    out = csr_array(counts, copy=True)
    out.sum_duplicates()
    out.eliminate_zeros()
    return _int64(out)


def entry_rows(indptr: IntArray) -> IntArray:
    """The row of every stored entry of a CSR table with this ``indptr``."""
    return np.repeat(np.arange(indptr.shape[0] - 1, dtype=np.int64), np.diff(indptr))


#: The arrays a count table is stored as, ``{name}_{part}``: compressed sparse rows.
CSR_PARTS: tuple[str, ...] = ("indptr", "indices", "counts")


def csr_arrays(name: str, table: csr_array) -> dict[str, NDArray[np.int64]]:
    """The int64 arrays ``{name}_indptr``, ``{name}_indices``, ``{name}_counts`` of ``table``."""
    parts = (table.indptr, table.indices, table.data)
    return {
        f"{name}_{part}": np.array(values, dtype=np.int64)
        for part, values in zip(CSR_PARTS, parts, strict=True)
    }


def check_counts(
    indptr: NDArray[Any], indices: NDArray[Any], counts: NDArray[Any], n_cols: int
) -> str | None:
    """What is wrong with the CSR arrays of a count table, or ``None``.

    ``indptr`` must start at 0, never decrease and end at the number of entries;
    ``indices`` must lie in ``[0, n_cols)`` and increase strictly within each row;
    ``counts`` must be positive (a zero count is not stored). Every check is one pass over
    the arrays as they are: nothing is allocated from a claimed size.
    """
    if indptr.ndim != 1 or indices.ndim != 1 or counts.ndim != 1:
        return "must be 1-D"
    if indices.shape[0] != counts.shape[0]:
        return f"has {indices.shape[0]} column indices but {counts.shape[0]} counts"
    if indptr.shape[0] < 2 or indptr[0] != 0 or indptr[-1] != indices.shape[0]:
        return "row pointers must run from 0 to the number of stored counts"
    if np.any(np.diff(indptr) < 0):
        return "row pointers decrease"
    if indices.shape[0]:
        if indices.min() < 0 or indices.max() >= n_cols:
            return f"has column indices outside 0 to {n_cols - 1}"
        if counts.min() < 1:
            return "stores counts below 1"
        steps = np.diff(indices)
        first = np.zeros(indices.shape[0], dtype=bool)
        first[indptr[:-1][np.diff(indptr) > 0]] = True
        if np.any(steps[~first[1:]] <= 0):
            return "has column indices that do not increase within a row"
    return None


def normalize_sparse(
    counts: csr_array, smoothing: float, *, zero_diagonal: bool
) -> tuple[csr_array, FloatArray]:
    """Probabilities of a sparse count table along its rows, and each row's fill.

    Returns the probabilities of the counted entries (the same structure; with smoothing
    and ``zero_diagonal`` also an explicit 0 on every diagonal cell) and, per row, the
    probability of every entry not stored: ``smoothing / total`` (0 without smoothing,
    and for a row whose total is zero). Without smoothing the probabilities are those of
    :func:`~behavior_hmm.hmm._counting.normalize` on the dense table, to the bit (the row
    totals are exact integers); with it the row total is ``sum + k · cells``, computed
    once instead of summed cell by cell.
    """
    n_rows, n_cols = counts.shape
    data = np.asarray(counts.data, dtype=np.float64)
    indptr = np.asarray(counts.indptr, dtype=np.int64)
    indices = np.asarray(counts.indices, dtype=np.int64)
    rows = entry_rows(indptr)
    total = np.zeros(n_rows)
    np.add.at(total, rows, data)  # exact: integer counts below 2**53
    fill = np.zeros(n_rows)
    if smoothing > 0.0:
        cells = n_cols - 1 if zero_diagonal else n_cols
        total = total + smoothing * cells
        data = data + smoothing
        np.divide(smoothing, total, out=fill, where=total > 0.0)
    probs = np.zeros_like(data)
    np.divide(data, total[rows], out=probs, where=total[rows] > 0.0)
    if smoothing > 0.0 and zero_diagonal:  # the structural zeros must be stored
        diag = np.arange(min(n_rows, n_cols), dtype=np.int64)
        rows = np.concatenate([rows, diag])
        indices = np.concatenate([indices, diag])
        probs = np.concatenate([probs, np.zeros(diag.shape[0])])
        order = np.lexsort((indices, rows))
        rows, indices, probs = rows[order], indices[order], probs[order]
        indptr = np.searchsorted(rows, np.arange(n_rows + 1)).astype(np.int64)
    return csr_array((probs, indices, indptr), shape=counts.shape), fill


class LogTable:
    """Log probabilities of a (rows, cols) table: stored entries, and one fill per row.

    Parameters
    ----------
    probs
        The probabilities of the stored entries (CSR, sorted indices); explicit zeros
        are kept (they become ``-inf``: a structural zero under smoothing).
    fill
        Shape (rows,): the probability of every entry of the row that is not stored.

    Notes
    -----
    ``log`` of a stored probability is ``numpy.log`` of it, so every value equals the
    dense table's ``log(p)`` bit for bit. Columns are read through a column-major copy
    of the index arrays, made on the first :meth:`column` call.
    """

    def __init__(self, probs: csr_array, fill: FloatArray) -> None:
        self.shape: tuple[int, int] = (int(probs.shape[0]), int(probs.shape[1]))
        self.indptr = np.asarray(probs.indptr, dtype=np.int64)
        self.indices = np.asarray(probs.indices, dtype=np.int64)
        with np.errstate(divide="ignore"):
            self.data = np.log(np.asarray(probs.data, dtype=np.float64))
            self.fill = np.log(np.asarray(fill, dtype=np.float64))
        self._columns: tuple[IntArray, IntArray, FloatArray] | None = None

    @property
    def nnz(self) -> int:
        """Stored entries."""
        return int(self.indices.shape[0])

    @property
    def dense_fill(self) -> bool:
        """Whether any entry not stored is possible (the table was smoothed)."""
        return bool(np.isfinite(self.fill).any())

    def rows(self) -> IntArray:
        """The row of every stored entry."""
        return entry_rows(self.indptr)

    def row(self, i: int) -> FloatArray:
        """Row ``i`` as a dense vector, shape (cols,)."""
        out = np.full(self.shape[1], self.fill[i])
        lo, hi = self.indptr[i], self.indptr[i + 1]
        out[self.indices[lo:hi]] = self.data[lo:hi]
        return out

    def _by_column(self) -> tuple[IntArray, IntArray, FloatArray]:
        if self._columns is None:
            order = np.argsort(self.indices, kind="stable")  # rows stay increasing
            col_ptr = np.searchsorted(self.indices[order], np.arange(self.shape[1] + 1))
            self._columns = (col_ptr.astype(np.int64), self.rows()[order], self.data[order])
        return self._columns

    def column(self, j: int) -> FloatArray:
        """Column ``j`` as a dense vector, shape (rows,)."""
        col_ptr, col_rows, col_data = self._by_column()
        out = self.fill.copy()
        lo, hi = col_ptr[j], col_ptr[j + 1]
        out[col_rows[lo:hi]] = col_data[lo:hi]
        return out

    def columns(self, cols: IntArray) -> FloatArray:
        """Columns ``cols`` as the rows of a C-contiguous (len(cols), rows) array."""
        col_ptr, col_rows, col_data = self._by_column()
        out = np.repeat(self.fill[None, :], cols.shape[0], axis=0)
        lo = col_ptr[cols]
        sizes = col_ptr[cols + 1] - lo
        # the stored entries of every wanted column, one after another
        first = np.cumsum(sizes) - sizes
        at = np.repeat(lo - first, sizes) + np.arange(int(sizes.sum()), dtype=np.int64)
        out[np.repeat(np.arange(cols.shape[0]), sizes), col_rows[at]] = col_data[at]
        return out

    def values(self, rows: IntArray, cols: IntArray) -> FloatArray:
        """Entries ``(rows[k], cols[k])``."""
        out = self.fill[rows].copy()
        for k, (i, j) in enumerate(zip(rows.tolist(), cols.tolist(), strict=True)):
            lo, hi = self.indptr[i], self.indptr[i + 1]
            at = lo + int(np.searchsorted(self.indices[lo:hi], j))
            if at < hi and self.indices[at] == j:
                out[k] = self.data[at]
        return out

    def diagonal(self) -> FloatArray:
        """The diagonal, shape (min(rows, cols),)."""
        rows = self.rows()
        on = rows == self.indices
        out = self.fill[: min(self.shape)].copy()
        out[rows[on]] = self.data[on]
        return out

    def toarray(self) -> FloatArray:
        """The whole table, dense (for small models and tests)."""
        out = np.repeat(self.fill[:, None], self.shape[1], axis=1)
        out[self.rows(), self.indices] = self.data
        return out
