"""Hierarchically integrated CobART networks (thesis §3.2.1, fig. 3.3).

First-layer networks categorize their own channel groups (e.g. robot motion, object
motion, distance). At every step a *relation* network categorizes the stack of the
first-layer winners' prototypes, scored with the thesis's weighted formula

    r_k = Σ_m w_m · mean over channels of part m of (b·DCM + (1-b)·EDM)

(``w_m`` normalized to sum 1, so ``r_k`` stays in [0, 1]). The feedback weight ``w_f``
lets the relation network's previous winner bias which first-layer category wins:
see :class:`HierarchicalCobART`.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from typing import Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from behavior_hmm.cobart._cobart import CobART, _Params
from behavior_hmm.cobart._engine import Engine, episode_windows, features, make_layout
from behavior_hmm.cobart._params import ParamsMixin
from behavior_hmm.cobart._similarity import suggest_dcm_scale
from behavior_hmm.cobart._validation import check_data, check_dcm_scale, check_unit_interval
from behavior_hmm.errors import ConfigError, NotFittedError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

RELATION = "relation"


class _Assoc:
    """Counts ``A[k, j]``: steps where relation category ``k`` won with layer category ``j``."""

    def __init__(self) -> None:
        self.a = np.zeros((8, 8), dtype=np.int64)

    def add(self, k: int, j: int) -> None:
        rows, cols = self.a.shape
        if k >= rows or j >= cols:
            grown = np.zeros((max(rows, 2 * (k + 1)), max(cols, 2 * (j + 1))), dtype=np.int64)
            grown[:rows, :cols] = self.a
            self.a = grown
        self.a[k, j] += 1

    def bias(self, k: int, n_layer: int) -> FloatArray:
        """Association of relation category ``k`` with each layer category, scaled to max 1."""
        out = np.zeros(n_layer)
        if k < self.a.shape[0]:
            row = self.a[k, : min(n_layer, self.a.shape[1])]
            top = row.max(initial=0)
            if top > 0:
                out[: row.size] = row / top
        return out

    def table(self, k_rel: int, k_layer: int) -> IntArray:
        out = np.zeros((k_rel, k_layer), dtype=np.int64)
        r, c = min(k_rel, self.a.shape[0]), min(k_layer, self.a.shape[1])
        out[:r, :c] = self.a[:r, :c]
        return out


def _exact_scores(eng: Engine, pt: FloatArray) -> FloatArray:
    diff = eng.zaug[: eng.K, : eng.F] - pt
    sq = np.sqrt((diff * diff) @ eng.gs)
    return np.clip(1.0 - np.minimum(sq, 1.0) @ eng.wts, 0.0, 1.0)


class HierarchicalCobART(ParamsMixin):
    """First-layer CobART networks feeding a relation CobART network (thesis §3.2.1).

    Parameters
    ----------
    layers
        Name → first-layer :class:`CobART` (its parameters are used; the instance is
        cloned, never modified).
    channels
        Name → columns of ``X`` that layer categorizes.
    weights
        Name → ``w_m >= 0``, the layer's weight in the relation score (normalized to
        sum 1); ``None`` weighs the layers equally.
    w_f
        Feedback weight in [0, 1]. At step ``t`` layer ``m`` ranks its categories ``j``
        by ``(1 - w_f)·r_j + w_f·A_m[k, j] / max_j A_m[k, j]``, where ``k`` is the
        relation winner at ``t-1`` and ``A_m[k, j]`` counts the training steps on which
        ``k`` and ``j`` won together. Only categories whose own score ``r_j`` passes
        the layer's vigilance compete (ART's search): feedback breaks near-ties toward
        the expected category but never accepts a poor match. ``0`` = independent layers.
    relation
        The relation network's parameters (``a, b, d, alpha, rho, edm_scale``; its
        ``window`` is ignored: its input is the winners' prototype windows). Its
        ``dcm_scale="auto"`` reuses each layer's DCM scale for that layer's part.
        ``None``: ``CobART()`` defaults.

    Attributes
    ----------
    layers_ : dict[str, CobART]
        Fitted first-layer networks (prototypes, counts, their ``labels_``).
    relation_prototypes_ : dict[str, ndarray]
        Per layer, the relation categories' part ``(K, I_m, C_m)`` (normalized units).
    relation_counts_ : ndarray, shape (K,)
    n_categories_ : int
        Relation categories.
    associations_ : dict[str, ndarray]
        Per layer, ``A_m`` of shape ``(K, K_m)``.
    weights_ : dict[str, float]
        Normalized ``w_m``.
    labels_ : ndarray
        Relation categories assigned while learning.
    """

    def __init__(
        self,
        layers: Mapping[str, CobART],
        channels: Mapping[str, Sequence[int]],
        weights: Mapping[str, float] | None = None,
        w_f: float = 0.0,
        relation: CobART | None = None,
    ) -> None:
        self.layers = layers
        self.channels = channels
        self.weights = weights
        self.w_f = w_f
        self.relation = relation

    # ------------------------------------------------------------------ checks
    def _check(self, n_channels: int) -> tuple[list[str], dict[str, list[int]], dict[str, float]]:
        if not isinstance(self.layers, Mapping) or not self.layers:
            raise ConfigError("layers must be a non-empty mapping of name -> CobART")
        names = list(self.layers)
        for name in names:
            if not isinstance(name, str) or name == RELATION:
                raise ConfigError(
                    f"layer names must be strings other than '{RELATION}', got {name!r}"
                )
            if not isinstance(self.layers[name], CobART):
                raise ConfigError(
                    f"layer '{name}' must be a CobART, got {type(self.layers[name]).__name__}"
                )
        if not isinstance(self.channels, Mapping) or set(self.channels) != set(names):
            raise ConfigError("channels must name the same layers as layers")
        chans: dict[str, list[int]] = {}
        for name in names:
            cols = list(self.channels[name])
            if not cols or len(set(cols)) != len(cols):
                raise ConfigError(f"channels of layer '{name}' must be distinct column indices")
            for c in cols:
                if (
                    isinstance(c, bool)
                    or not isinstance(c, numbers.Integral)
                    or not 0 <= c < n_channels
                ):
                    raise ConfigError(
                        f"channel {c!r} of layer '{name}' is not a column of X "
                        f"(0..{n_channels - 1})"
                    )
            chans[name] = [int(c) for c in cols]
        if self.weights is None:
            raw_w = {name: 1.0 for name in names}
        else:
            if not isinstance(self.weights, Mapping) or set(self.weights) != set(names):
                raise ConfigError("weights must name the same layers as layers")
            raw_w = {}
            for name in names:
                w = self.weights[name]
                if (
                    isinstance(w, bool)
                    or not isinstance(w, numbers.Real)
                    or not math.isfinite(w)
                    or w < 0
                ):
                    raise ConfigError(
                        f"weight of layer '{name}' must be a finite number >= 0, got {w!r}"
                    )
                raw_w[name] = float(w)
        total = sum(raw_w.values())
        if not total > 0:
            raise ConfigError("at least one layer weight must be > 0")
        check_unit_interval("w_f", self.w_f)
        if self.relation is not None and not isinstance(self.relation, CobART):
            raise ConfigError(
                f"relation must be a CobART or None, got {type(self.relation).__name__}"
            )
        return names, chans, {n: w / total for n, w in raw_w.items()}

    # ------------------------------------------------------------------ learning
    def fit(self, X: ArrayLike, lengths: Sequence[int] | ArrayLike | None = None) -> Self:
        """Learn first-layer, relation and association tables from scratch, episodes in order."""
        arr, lens = check_data(X, lengths)
        names, chans, weights = self._check(arr.shape[1])
        rel = self.relation if self.relation is not None else CobART()
        rel_params = rel._checked_params()
        layers: dict[str, CobART] = {}
        lparams: dict[str, _Params] = {}
        scales: dict[str, FloatArray] = {}
        for name in names:
            est = CobART(**self.layers[name].get_params(deep=False))
            p = est._checked_params()
            sub = arr[:, chans[name]]
            fixed = check_dcm_scale(est.dcm_scale, sub.shape[1])
            scales[name] = fixed if fixed is not None else suggest_dcm_scale(sub, lens)
            layout = make_layout(
                [p.window], [sub.shape[1]], [1.0], p.b, p.edm_scale, [scales[name]]
            )
            est._engine = Engine(layout)
            est._fit = p
            est.dcm_scale_ = scales[name]
            est.n_features_in_ = sub.shape[1]
            layers[name] = est
            lparams[name] = p
        total_ch = sum(len(chans[n]) for n in names)
        fixed_rel = check_dcm_scale(rel.dcm_scale, total_ch)
        if fixed_rel is None:
            rel_scales = [scales[n] for n in names]
        else:
            bounds = np.cumsum([0] + [len(chans[n]) for n in names])
            rel_scales = [fixed_rel[bounds[i] : bounds[i + 1]] for i in range(len(names))]
        rel_layout = make_layout(
            [lparams[n].window for n in names],
            [len(chans[n]) for n in names],
            [weights[n] for n in names],
            rel_params.b,
            rel_params.edm_scale,
            rel_scales,
        )
        self._names = names
        self._chans = chans
        self.weights_ = weights
        self.layers_ = layers
        self._rel_engine = Engine(rel_layout)
        self._rel_params = rel_params
        self._assoc = {n: _Assoc() for n in names}
        self._w_f = float(self.w_f)
        labels = self._run(arr, lens, learn=True)
        self.labels_ = labels[RELATION]
        for name in names:
            layers[name].labels_ = labels[name]
        return self

    def _run(self, arr: FloatArray, lens: IntArray, *, learn: bool) -> dict[str, IntArray]:
        names = self._names
        engines = {n: self.layers_[n]._engine for n in names}
        params = {n: self.layers_[n]._fit for n in names}
        rel = self._rel_engine
        rp = self._rel_params
        w_f = self._w_f
        out = {n: np.empty(arr.shape[0], dtype=np.int64) for n in [*names, RELATION]}
        start = 0
        for n_steps in lens.tolist():
            ep = arr[start : start + n_steps]
            wts = {
                n: features(
                    engines[n].layout, episode_windows(ep[:, self._chans[n]], params[n].window)
                )
                for n in names
            }
            last = {n: -1 for n in names}
            last_rel = -1
            for t in range(n_steps):
                raw_parts = []
                for n in names:
                    eng, p = engines[n], params[n]
                    j_prev = last[n]
                    if j_prev < 0:
                        pt = wts[n][t].copy()
                    else:
                        pt = p.a * wts[n][t] + (1.0 - p.a) * eng.zaug[j_prev, : eng.F]
                    j = self._choose(eng, pt, p, self._assoc[n], last_rel, w_f, learn)
                    last[n] = j
                    out[n][start + t] = j
                    raw_parts.append(eng.zaug[j, : eng.layout.n_raw])
                x = features(rel.layout, np.concatenate(raw_parts)[None, :])[0]
                if last_rel < 0:
                    pr = x
                else:
                    pr = rp.a * x + (1.0 - rp.a) * rel.zaug[last_rel, : rel.F]
                k = 0
                if rel.K:
                    r = _exact_scores(rel, pr)
                    k = int(np.argmax(r))
                    accept = r[k] >= rp.rho
                else:
                    accept = False
                if learn:
                    if accept:
                        rel.learn(k, pr, rp.d, rp.alpha)
                    else:
                        k = rel.add(pr)
                    for n in names:
                        self._assoc[n].add(k, last[n])
                last_rel = k
                out[RELATION][start + t] = k
            start += n_steps
        return out

    @staticmethod
    def _choose(
        eng: Engine, pt: FloatArray, p: _Params, assoc: _Assoc, k_rel: int, w_f: float, learn: bool
    ) -> int:
        """First-layer winner with feedback (see the class docstring); learns if ``learn``."""
        if eng.K == 0:
            return eng.add(pt)
        r = _exact_scores(eng, pt)
        ranked = r
        if w_f > 0.0 and k_rel >= 0:
            ranked = (1.0 - w_f) * r + w_f * assoc.bias(k_rel, eng.K)
        cand = r >= p.rho
        if cand.any():
            j = int(np.argmax(np.where(cand, ranked, -np.inf)))
            if learn:
                eng.learn(j, pt, p.d, p.alpha)
            return j
        if learn:
            return eng.add(pt)
        return int(np.argmax(r))

    # ------------------------------------------------------------------ run time
    def _check_fitted(self) -> None:
        if "_rel_engine" not in self.__dict__:
            raise NotFittedError("this HierarchicalCobART is not fitted yet; call fit first")

    def predict_all(
        self, X: ArrayLike, lengths: Sequence[int] | ArrayLike | None = None
    ) -> dict[str, IntArray]:
        """Categories per step of every first-layer network and of ``"relation"``, no learning.

        Each network returns its best match even below its vigilance.
        """
        self._check_fitted()
        arr, lens = check_data(X, lengths)
        n_total = sum(len(c) for c in self._chans.values())
        used = max(max(c) for c in self._chans.values()) + 1
        if arr.shape[1] < used:
            raise ConfigError(
                f"X has {arr.shape[1]} channels but the layers use {used} ({n_total} in all)"
            )
        return self._run(arr, lens, learn=False)

    def predict(self, X: ArrayLike, lengths: Sequence[int] | ArrayLike | None = None) -> IntArray:
        """Relation category per time step, without learning."""
        return self.predict_all(X, lengths)[RELATION]

    @property
    def n_categories_(self) -> int:
        """Number of relation categories."""
        self._check_fitted()
        return self._rel_engine.K

    @property
    def relation_counts_(self) -> IntArray:
        """Wins per relation category while learning."""
        self._check_fitted()
        return np.asarray(self._rel_engine.counts, dtype=np.int64)

    @property
    def relation_prototypes_(self) -> dict[str, FloatArray]:
        """Per layer, the relation prototypes' part ``(K, I_m, C_m)`` in normalized units."""
        self._check_fitted()
        rel = self._rel_engine
        lay = rel.layout
        out = {}
        for m, n in enumerate(self._names):
            i_m, c_m, ro = lay.windows[m], lay.channels[m], lay.raw_offsets[m]
            out[n] = rel.zaug[: rel.K, ro : ro + i_m * c_m].reshape(rel.K, i_m, c_m).copy()
        return out

    @property
    def associations_(self) -> dict[str, IntArray]:
        """Per layer, co-win counts ``A_m`` ``(K, K_m)`` of relation and layer categories."""
        self._check_fitted()
        return {
            n: self._assoc[n].table(self._rel_engine.K, self.layers_[n].n_categories_)
            for n in self._names
        }
