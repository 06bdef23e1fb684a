"""Rehearsal rows: a bounded sample of each primitive's generator training rows, kept in
the model file so that an update fine-tunes a network on old rows beside the new ones.

:meth:`SBLM.partial_fit <behavior_hmm.models.SBLM.partial_fit>` fine-tunes the network of
every primitive the new demonstrations visit. Trained on the new rows alone, a network
forgets what the old ones taught it (a turn fitted on half of its grid and grown by the
other half fell from 96.7 to 85.5 % on the first half's starts; 98.2 % with 512 rows kept,
docs/results.md). Continual learning's answer is
rehearsal (experience replay): keep some of the old rows and train on them too. The
model file keeps at most ``rehearsal`` rows a primitive (the SBLM parameter), drawn at
random, so it grows by a bounded amount however many demonstrations it learned from.

The sample stands for every row a primitive was trained on (``seen``): a stored row of a
primitive that saw ``N`` rows and keeps ``k`` stands for ``N / k`` of them when an update
draws the next sample from the stored rows and the new ones (weighted sampling without
replacement, Efraimidis and Spirakis 2006: each unit's key ``log(u) / w``, the largest
keys kept). A unit is a row for feed-forward generators, and a run of consecutive rows of
one primitive for recurrent ones, which train on sequences (a run longer than the cap is
passed over).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.errors import ModelFileError
from behavior_hmm.models import _modelfile

#: Rows of each primitive an SBLM keeps for its updates (its ``rehearsal`` default).
DEFAULT_REHEARSAL: Final[int] = 512
#: Most rows a model file's ``seen`` may count for one primitive (so updates never carry
#: it past the file format's integer bound, 2**53).
MAX_SEEN: Final[int] = 2**40
#: Largest magnitude of a kept input row's value (normalized units: a reading far outside
#: the demonstrations' range maps beyond ±1 linearly) that a model file may hold.
MAX_FEATURE: Final[float] = 1e4
#: Spawn key of the rehearsal draws (apart from the generators' ``(primitive, update)``).
_SEED_KEY: Final[int] = 0x7265_6865  # "rehe"
#: Array names in a model file, after the ``rehearsal.`` prefix.
ARRAYS: Final[tuple[str, ...]] = ("features", "targets", "index", "seen")


@dataclass(frozen=True)
class RehearsalRows:
    """Generator training rows kept for updates.

    Attributes
    ----------
    features : ndarray of shape (n_rows, n_features), float32
        The generators' input rows (normalized units, as trained).
    targets : ndarray of shape (n_rows, n_outputs), float32
        Their training targets.
    primitives, groups, segments : ndarray of shape (n_rows,), int64
        Each row's primitive, its demonstration (numbered from 0 within the sample; the
        generators' held-out split draws whole demonstrations) and its run of
        consecutive rows (numbered from 0; a recurrent generator's sequence).
    seen : ndarray of shape (n_primitives,), int64
        Rows each primitive was trained on in all, over the fit and every update (the
        window-noise copies not counted).
    """

    features: NDArray[np.float32]
    targets: NDArray[np.float32]
    primitives: NDArray[np.int64]
    groups: NDArray[np.int64]
    segments: NDArray[np.int64]
    seen: NDArray[np.int64]

    @property
    def n_rows(self) -> int:
        """Rows kept."""
        return int(self.primitives.size)

    def of(self, primitives: NDArray[np.int64]) -> RehearsalRows:
        """The rows of ``primitives`` (``seen`` unchanged)."""
        return self._rows(np.isin(self.primitives, primitives))

    def without(self, primitives: NDArray[np.int64]) -> RehearsalRows:
        """The rows of every other primitive (``seen`` unchanged)."""
        return self._rows(~np.isin(self.primitives, primitives))

    def _rows(self, keep: NDArray[np.bool_]) -> RehearsalRows:
        return RehearsalRows(
            self.features[keep],
            self.targets[keep],
            self.primitives[keep],
            self.groups[keep],
            self.segments[keep],
            self.seen,
        )

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Arrays for a model file (see :func:`from_arrays`)."""
        index = np.stack([self.primitives, self.groups, self.segments], axis=1)
        return {
            "features": self.features,
            "targets": self.targets,
            "index": index.astype(np.int32),
            "seen": self.seen,
        }


def sample(
    features: NDArray[np.floating[Any]],
    targets: NDArray[np.floating[Any]],
    primitives: NDArray[np.integer[Any]],
    groups: NDArray[np.integer[Any]],
    segments: NDArray[np.integer[Any]],
    weights: NDArray[np.floating[Any]],
    seen: NDArray[np.int64],
    *,
    cap: int,
    by_segment: bool,
    rng: np.random.Generator,
) -> RehearsalRows:
    """At most ``cap`` rows of each primitive, drawn with probability by ``weights``.

    Parameters
    ----------
    features, targets, primitives, groups, segments
        Candidate rows (the old sample's and the new training rows), in order; groups
        and segments must already be distinct between the old and the new rows.
    weights
        How many training rows each candidate stands for (1 for a new row).
    seen
        The ``seen`` of the sample (every primitive's rows in all).
    cap
        Rows a primitive keeps at most.
    by_segment
        Draw whole runs (recurrent generators) instead of single rows.
    rng
        Source of the draws.
    """
    prim = np.asarray(primitives, dtype=np.int64)
    unit = np.asarray(segments, dtype=np.int64) if by_segment else np.arange(prim.size)
    # units in order of first row; each unit's primitive, rows and weight
    first, unit_of_row = np.unique(unit, return_index=True, return_inverse=True)[1:]
    unit_prim = prim[first]
    unit_rows = np.bincount(unit_of_row, minlength=first.size)
    unit_weight = np.bincount(unit_of_row, weights=weights, minlength=first.size)
    u = rng.random(first.size)
    # Efraimidis-Spirakis: the largest keys log(u) / w are a weighted sample
    key = np.log(np.maximum(u, np.finfo(np.float64).tiny)) / np.maximum(unit_weight, 1e-12)
    order = np.lexsort((-key, unit_prim))
    keep_units = np.zeros(first.size, dtype=bool)
    if by_segment:
        # runs by key, each kept where it still fits (a longer run is passed over)
        taken: dict[int, int] = {}
        for i in order.tolist():
            p, n = int(unit_prim[i]), int(unit_rows[i])
            if taken.get(p, 0) + n <= cap:
                taken[p] = taken.get(p, 0) + n
                keep_units[i] = True
    else:  # single rows: each primitive's first ``cap`` keys
        prim_sorted = unit_prim[order]
        start = np.searchsorted(prim_sorted, prim_sorted, side="left")
        keep_units[order[np.arange(order.size) - start < cap]] = True
    keep = keep_units[unit_of_row]
    return RehearsalRows(
        np.asarray(features[keep], dtype=np.float32),
        np.asarray(targets[keep], dtype=np.float32),
        prim[keep],
        _compact(np.asarray(groups)[keep]),
        _compact(np.asarray(segments)[keep]),
        np.asarray(seen, dtype=np.int64),
    )


def merged(kept: RehearsalRows, drawn: RehearsalRows) -> RehearsalRows:
    """The rows of both (``kept``'s first, their demonstrations and runs numbered apart),
    with ``drawn``'s ``seen``."""
    return RehearsalRows(
        np.vstack([kept.features, drawn.features]),
        np.vstack([kept.targets, drawn.targets]),
        np.concatenate([kept.primitives, drawn.primitives]),
        _compact(np.concatenate([kept.groups, drawn.groups + kept.n_rows])),
        _compact(np.concatenate([kept.segments, drawn.segments + kept.n_rows])),
        drawn.seen,
    )


def rehearsal_rng(random_state: int, update: int) -> np.random.Generator:
    """The draws of the sample kept after update ``update`` (0: the fit)."""
    seq = np.random.SeedSequence(int(random_state), spawn_key=(_SEED_KEY, int(update)))
    return np.random.default_rng(seq)


def _compact(labels: NDArray[Any]) -> NDArray[np.int64]:
    """Labels renumbered 0, 1, ... in order of first appearance."""
    if labels.size == 0:
        return np.zeros(0, dtype=np.int64)
    _, first, inverse = np.unique(labels, return_index=True, return_inverse=True)
    rank = np.empty(first.size, dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size)
    return rank[inverse.ravel()]


def from_arrays(
    arrays: Mapping[str, np.ndarray],
    *,
    cap: int,
    n_primitives: int,
    n_features: int,
    n_outputs: int,
) -> RehearsalRows:
    """The rows of a model file's ``rehearsal.*`` arrays, checked.

    Refused (:class:`ModelFileError`): a shape that disagrees with the generators, more
    than ``cap`` rows of a primitive, a primitive, demonstration or run number out of
    range, runs of rows that are not consecutive or mix primitives or demonstrations,
    ``seen`` below the rows kept or above ``MAX_SEEN``, targets outside [-1, 1], inputs
    beyond ``MAX_FEATURE``.
    """
    feats = _modelfile.check_array(arrays, "rehearsal.features", ndim=2)
    targs = _modelfile.check_array(arrays, "rehearsal.targets", ndim=2)
    index = _modelfile.check_array(arrays, "rehearsal.index", ndim=2, kind="iu")
    seen = _modelfile.check_array(arrays, "rehearsal.seen", ndim=1, kind="iu")
    n = feats.shape[0]
    if feats.shape[1] != n_features or targs.shape != (n, n_outputs) or index.shape != (n, 3):
        raise ModelFileError(
            "arrays 'rehearsal.*' must hold rows of the generators' inputs and outputs"
        )
    if seen.shape != (n_primitives,):
        raise ModelFileError("array 'rehearsal.seen' must hold one count per primitive")
    index = index.astype(np.int64)
    prim, groups, segments = index[:, 0], index[:, 1], index[:, 2]
    if n and (prim.min() < 0 or prim.max() >= n_primitives):
        raise ModelFileError("array 'rehearsal.index' names a primitive the model lacks")
    if n and (min(groups.min(), segments.min()) < 0 or max(groups.max(), segments.max()) >= n):
        raise ModelFileError("array 'rehearsal.index' numbers demonstrations or runs past its rows")
    # a run is consecutive rows (numbered in order) of one primitive and one demonstration
    steps = np.diff(segments)
    same = steps == 0
    if (steps < 0).any() or (same & (np.diff(prim) != 0)).any():
        raise ModelFileError("array 'rehearsal.index' splits or mixes a run of rows")
    if (same & (np.diff(groups) != 0)).any():
        raise ModelFileError("array 'rehearsal.index' mixes demonstrations in a run of rows")
    kept = np.bincount(prim, minlength=n_primitives)
    if kept.max(initial=0) > cap:
        raise ModelFileError(
            f"arrays 'rehearsal.*' keep more than rehearsal={cap} rows a primitive"
        )
    seen64 = seen.astype(np.int64)
    if (seen64 < kept).any() or (seen64 > MAX_SEEN).any():
        raise ModelFileError(
            f"array 'rehearsal.seen' counts fewer rows than it keeps, or more than {MAX_SEEN:g}"
        )
    # as trained: targets clipped to [-1, 1], inputs in normalized units
    if n and np.abs(targs).max() > 1.0:
        raise ModelFileError("array 'rehearsal.targets' holds values outside [-1, 1]")
    if n and np.abs(feats).max() > MAX_FEATURE:
        raise ModelFileError(f"array 'rehearsal.features' holds values beyond ±{MAX_FEATURE:g}")
    return RehearsalRows(
        np.array(feats, dtype=np.float32),
        np.array(targs, dtype=np.float32),
        prim,
        groups,
        segments,
        seen64,
    )
