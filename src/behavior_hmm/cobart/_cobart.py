"""The CobART estimator (thesis §3.2, DESIGN §5): windows of normalized readings → categories."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Final, NamedTuple, Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from behavior_hmm.cobart import _compiled as compiled
from behavior_hmm.cobart._engine import (
    Engine,
    Layout,
    Predictor,
    episode_windows,
    features,
    fit_episode,
    make_layout,
)
from behavior_hmm.cobart._params import ParamsMixin
from behavior_hmm.cobart._similarity import DEFAULT_EDM_SCALE, suggest_dcm_scale
from behavior_hmm.cobart._validation import (
    check_alpha,
    check_data,
    check_dcm_scale,
    check_positive,
    check_ranges,
    check_unit_interval,
    check_window,
)
from behavior_hmm.errors import ConfigError, NotFittedError

if TYPE_CHECKING:
    from behavior_hmm.cobart._live import LiveCategorizer

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

#: Thesis table 4.2, motion primitives: windows of 10 readings.
MOTION_PRIMITIVE_PARAMS: Final[Mapping[str, float | int]] = MappingProxyType(
    {"a": 0.8, "b": 0.4, "d": 0.2, "alpha": -1.0, "rho": 0.85, "window": 10}
)

#: Thesis table 4.2, observation categories: windows of 3 readings.
OBSERVATION_PARAMS: Final[Mapping[str, float | int]] = MappingProxyType(
    {"a": 0.95, "b": 0.1, "d": 0.2, "alpha": -1.0, "rho": 0.95, "window": 3}
)


class Categorization(NamedTuple):
    """Result of categorizing data without learning (one entry per time step)."""

    labels: IntArray
    """Best-matching category."""
    scores: FloatArray
    """Its matching score in [0, 1]."""
    novel: BoolArray
    """True where the score is below the vigilance ρ (learning would have made a new category)."""


@dataclass(frozen=True)
class _Params:
    a: float
    b: float
    d: float
    alpha: float
    rho: float
    window: int
    edm_scale: float


class CobART(ParamsMixin):
    """Correlation-based ART network: unsupervised categories of windows of readings.

    Each time step ``t`` of an episode is categorized from the window of readings
    ``t-I+1 .. t`` of that episode (the first ``I-1`` steps repeat the episode's first
    reading; no window spans two episodes). The processed input is
    ``p = a·w + (1-a)·z_last`` with ``z_last`` the prototype of the previous step's
    category (none at an episode start, where ``p = w``). Each category ``k`` scores
    ``r_k = mean over channels of (b·DCM + (1-b)·EDM)`` (see :func:`cobart_score`).
    The best category (ties: lowest index) learns if ``r_k >= rho``:
    ``z_k += d · n_k^alpha · (p - z_k)`` with ``n_k`` its win count including this
    step; otherwise a new category starts at ``p`` with ``n = 1``.

    Parameters
    ----------
    a
        Weight of the new window against the last category, in [0, 1].
    b
        Weight of DCM (shape) against EDM (distance), in [0, 1].
    d
        Initial learning rate, in [0, 1].
    alpha
        Learning-rate decrease, <= 0 (-1: running mean scaled by ``d``).
    rho
        Vigilance, in [0, 1]: higher gives more, finer categories.
    window
        Window length ``I`` (readings), >= 1.
    edm_scale
        RMS difference (normalized units) at which EDM similarity reaches 0.
    dcm_scale
        Per-step difference (normalized units per step) at which DCM reaches 0: a
        number, one number per channel, or ``"auto"`` (from the first ``fit`` data, see
        :func:`suggest_dcm_scale`).

    Attributes
    ----------
    prototypes_ : ndarray, shape (n_categories, I, C)
        Category prototypes in normalized units.
    counts_ : ndarray, shape (n_categories,)
        Wins per category during learning (the creating step counts as one).
    n_categories_ : int
    labels_ : ndarray, shape (n_samples,)
        Categories assigned while learning the last ``fit`` / ``partial_fit`` data.
    dcm_scale_ : ndarray, shape (C,)
        DCM scale in use, per channel.
    n_features_in_ : int
        Number of channels ``C``.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.r_[np.zeros(20), np.linspace(0, 0.5, 40), np.full(20, 0.5)][:, None]
    >>> model = CobART.motion_primitives().fit(x)
    >>> model.predict(x).shape
    (80,)
    """

    _engine: Engine
    _fit: _Params
    dcm_scale_: FloatArray
    n_features_in_: int
    labels_: IntArray
    kept_: IntArray

    def __init__(
        self,
        a: float = 0.8,
        b: float = 0.4,
        d: float = 0.2,
        alpha: float = -1.0,
        rho: float = 0.85,
        window: int = 10,
        *,
        edm_scale: float = DEFAULT_EDM_SCALE,
        dcm_scale: float | Sequence[float] | str = "auto",
    ) -> None:
        self.a = a
        self.b = b
        self.d = d
        self.alpha = alpha
        self.rho = rho
        self.window = window
        self.edm_scale = edm_scale
        self.dcm_scale = dcm_scale

    # ------------------------------------------------------------------ presets
    @classmethod
    def motion_primitives(cls, **overrides: Any) -> CobART:
        """Thesis table 4.2 preset for motion primitives (a .8, b .4, d .2, α -1, ρ .85, I 10)."""
        return cls(**{**MOTION_PRIMITIVE_PARAMS, **overrides})

    @classmethod
    def observations(cls, **overrides: Any) -> CobART:
        """Thesis table 4.2 preset for observations (a .95, b .1, d .2, α -1, ρ .95, I 3)."""
        return cls(**{**OBSERVATION_PARAMS, **overrides})

    # ------------------------------------------------------------------ learning
    def _checked_params(self) -> _Params:
        return _Params(
            a=check_unit_interval("a", self.a),
            b=check_unit_interval("b", self.b),
            d=check_unit_interval("d", self.d),
            alpha=check_alpha(self.alpha),
            rho=check_unit_interval("rho", self.rho),
            window=check_window(self.window),
            edm_scale=check_positive("edm_scale", self.edm_scale),
        )

    def fit(self, X: ArrayLike, lengths: Sequence[int] | ArrayLike | None = None) -> Self:
        """Learn categories from scratch, episodes in order.

        Parameters
        ----------
        X
            Filtered readings normalized to [-1, 1], shape ``(n_samples, n_channels)``.
        lengths
            Samples per episode; ``None`` means one episode.

        Returns
        -------
        self
        """
        for name in ("_engine", "_fit", "dcm_scale_", "n_features_in_", "labels_", "kept_"):
            self.__dict__.pop(name, None)
        return self.partial_fit(X, lengths)

    def partial_fit(self, X: ArrayLike, lengths: Sequence[int] | ArrayLike | None = None) -> Self:
        """Continue learning from the current categories (``fit`` if not fitted yet).

        Every call starts its episodes afresh (no ``z_last``); an episode cannot be
        split across calls.
        """
        params = self._checked_params()
        arr, lens = check_data(X, lengths)
        n_ch = arr.shape[1]
        fitted = "_engine" in self.__dict__
        if fitted:
            if n_ch != self.n_features_in_:
                raise ConfigError(
                    f"X has {n_ch} channels but the model was fitted on {self.n_features_in_}"
                )
            if params.window != self._fit.window:
                raise ConfigError(
                    f"window changed from {self._fit.window} to {params.window}; "
                    "call fit to restart"
                )
        fixed = check_dcm_scale(self.dcm_scale, n_ch)
        if fixed is not None:
            scale = fixed
        elif fitted:
            scale = self.dcm_scale_
        else:
            scale = suggest_dcm_scale(arr, lens)
        layout = make_layout([params.window], [n_ch], [1.0], params.b, params.edm_scale, [scale])
        if fitted:
            old: Engine = self._engine
            eng = Engine(layout, capacity=max(old.capacity, 32))
            eng.load(old.prototypes(), old.counts)
        else:
            eng = Engine(layout)
        episodes = _episode_features(layout, arr, lens, params.window)
        kern = compiled.active()
        if kern is not None:  # the same categories, in one kernel call per stretch of steps
            found = compiled.learn_episodes(
                kern, eng, episodes, params.a, params.rho, params.d, params.alpha
            )
        else:
            labels: list[int] = []
            for wt in episodes:
                fit_episode(eng, wt, params.a, params.rho, params.d, params.alpha, labels)
            found = np.asarray(labels, dtype=np.int64)
        self._engine = eng
        self._fit = params
        self.dcm_scale_ = np.asarray(scale, dtype=np.float64).copy()
        self.n_features_in_ = n_ch
        self.labels_ = found
        return self

    def fit_predict(
        self, X: ArrayLike, lengths: Sequence[int] | ArrayLike | None = None
    ) -> IntArray:
        """``fit`` and return ``labels_`` (the categories assigned while learning)."""
        return self.fit(X, lengths).labels_

    # ------------------------------------------------------------------ fitted state
    def _check_fitted(self) -> Engine:
        eng = self.__dict__.get("_engine")
        if eng is None:
            raise NotFittedError(f"this {type(self).__name__} is not fitted yet; call fit first")
        return eng

    @property
    def prototypes_(self) -> FloatArray:
        """Category prototypes ``(K, I, C)`` in normalized units (a copy)."""
        eng = self._check_fitted()
        raw = eng.zaug[: eng.K, : eng.layout.n_raw]
        return raw.reshape(eng.K, self._fit.window, self.n_features_in_).copy()

    @property
    def counts_(self) -> IntArray:
        """Wins per category while learning (the creating step counts as one)."""
        return np.asarray(self._check_fitted().counts, dtype=np.int64)

    @property
    def n_categories_(self) -> int:
        """Number of categories."""
        return self._check_fitted().K

    def prototypes_physical(self, ranges: ArrayLike) -> FloatArray:
        """Prototypes ``(K, I, C)`` in physical units.

        Parameters
        ----------
        ranges
            ``(lo, hi)`` per channel in physical units: the range that was mapped onto
            [-1, 1] by normalization (``x_norm = 2 (x - lo) / (hi - lo) - 1``).
        """
        protos = self.prototypes_
        rng = check_ranges(ranges, self.n_features_in_)
        lo, hi = rng[:, 0], rng[:, 1]
        return lo + (protos + 1.0) * 0.5 * (hi - lo)

    def set_state(self, prototypes: ArrayLike, counts: ArrayLike, dcm_scale: ArrayLike) -> Self:
        """Restore a fitted state (e.g. from a model file) under the current parameters.

        Parameters
        ----------
        prototypes
            ``(K, I, C)`` normalized prototypes, ``I`` equal to ``window``.
        counts
            ``(K,)`` win counts, integers >= 1.
        dcm_scale
            ``(C,)`` DCM scale per channel.

        Raises
        ------
        ConfigError
            Shapes, values or parameters that do not fit together.
        """
        params = self._checked_params()
        protos = np.asarray(prototypes, dtype=np.float64)
        if protos.ndim != 3 or protos.shape[0] < 1 or protos.shape[1] != params.window:
            raise ConfigError(
                f"prototypes must have shape (K >= 1, {params.window}, C), got {protos.shape}"
            )
        if not np.all(np.isfinite(protos)):
            raise ConfigError("prototypes must be finite")
        k, _, n_ch = protos.shape
        cnt = np.asarray(counts)
        if cnt.shape != (k,) or cnt.dtype.kind not in "iu" or np.any(cnt < 1):
            raise ConfigError(f"counts must be {k} integers >= 1")
        scale = check_dcm_scale(np.asarray(dcm_scale, dtype=np.float64).tolist(), n_ch)
        assert scale is not None
        # The similarities divide by the squared scales and square the prototypes: refuse
        # values whose squares leave the float range (e.g. from an edited model file).
        with np.errstate(over="ignore", divide="ignore"):
            inverse = 1.0 / np.square(np.append(scale, params.edm_scale))
        if not (np.all(np.isfinite(inverse)) and np.all(inverse > 0.0)):
            raise ConfigError("dcm_scale and edm_scale must have squares within the float range")
        layout = make_layout([params.window], [n_ch], [1.0], params.b, params.edm_scale, [scale])
        eng = Engine(layout, capacity=max(32, k))
        with np.errstate(over="ignore", invalid="ignore"):
            eng.load(features(layout, protos.reshape(k, -1)), cnt.tolist())
        if not np.all(np.isfinite(eng.zaug[:k])):
            raise ConfigError("prototypes are too large: their squared norms overflow")
        for name in ("labels_", "kept_"):
            self.__dict__.pop(name, None)
        self._engine = eng
        self._fit = params
        self.dcm_scale_ = scale
        self.n_features_in_ = n_ch
        return self

    # ------------------------------------------------------------------ run time
    def _predictor(self) -> Predictor:
        eng = self._check_fitted()
        return Predictor(eng, self._fit.a, self._fit.rho)

    def categorize(
        self, X: ArrayLike, lengths: Sequence[int] | ArrayLike | None = None
    ) -> Categorization:
        """Best category, its score and the novelty flag per step, without learning.

        The best match is returned even when its score is below ``rho`` (flagged novel).
        ``z_last`` is the previous step's best match. Parameters are those of the last
        ``fit`` / ``partial_fit``.
        """
        pred = self._predictor()
        arr, lens = check_data(X, lengths)
        if arr.shape[1] != self.n_features_in_:
            raise ConfigError(
                f"X has {arr.shape[1]} channels but the model was fitted on {self.n_features_in_}"
            )
        n = arr.shape[0]
        labels = np.empty(n, dtype=np.int64)
        scores = np.empty(n, dtype=np.float64)
        offset = 0
        layout = self._engine.layout
        for wt in _episode_features(layout, arr, lens, self._fit.window):
            pred.episode(wt, labels, scores, offset)
            offset += wt.shape[0]
        return Categorization(labels, scores, scores < self._fit.rho)

    def predict(self, X: ArrayLike, lengths: Sequence[int] | ArrayLike | None = None) -> IntArray:
        """Best-matching category per time step, without learning (see :meth:`categorize`)."""
        return self.categorize(X, lengths).labels

    def stream(self) -> LiveCategorizer:
        """A live categorizer over a snapshot of the current categories (one reading at a time)."""
        from behavior_hmm.cobart._live import LiveCategorizer

        return LiveCategorizer(self)

    def score_window(self, window: ArrayLike) -> FloatArray:
        """Scores ``(K,)`` of one raw window ``(I, C)`` against every category (``a = 1``).

        Raises
        ------
        ConfigError
            Wrong window shape.
        DatasetError
            NaN or inf in the window.
        """
        eng = self._check_fitted()
        win = np.asarray(window, dtype=np.float64)
        shape = (self._fit.window, self.n_features_in_)
        if win.ndim == 1 and self.n_features_in_ == 1:
            win = win[:, None]
        if win.shape != shape:
            raise ConfigError(f"window must have shape {shape} (I, C), got {np.shape(window)}")
        check_data(win, None)
        ft = features(eng.layout, win.reshape(1, -1))[0]
        diff = eng.zaug[: eng.K, : eng.F] - ft
        sq = np.sqrt((diff * diff) @ eng.gs)
        return np.clip(1.0 - np.minimum(sq, 1.0) @ eng.wts, 0.0, 1.0)

    def compacted(self, X: ArrayLike, lengths: Sequence[int] | ArrayLike | None = None) -> CobART:
        """A copy keeping only the categories that win when ``predict`` relabels ``X``.

        Relabelling with the final prototypes can leave categories that never win
        (prototypes moved after they were assigned). The copy keeps the surviving
        categories in their original order, so ``predict`` on ``X`` gives the same
        winners, renumbered. ``kept_`` holds the original index of each kept category;
        ``labels_`` the renumbered relabelling of ``X``; ``counts_`` the learning counts.
        """
        labels = self.predict(X, lengths)
        kept = np.unique(labels)
        out = CobART(**self.get_params(deep=False))
        out.set_params(**{f.name: getattr(self._fit, f.name) for f in _PARAM_FIELDS})
        out.set_state(self.prototypes_[kept], self.counts_[kept], self.dcm_scale_)
        remap = np.full(self.n_categories_, -1, dtype=np.int64)
        remap[kept] = np.arange(kept.size)
        out.kept_ = kept
        out.labels_ = remap[labels]
        return out

    @property
    def layout_(self) -> Layout:
        """Feature layout in use (internal; for the hierarchical network and tests)."""
        return self._check_fitted().layout


_PARAM_FIELDS = fields(_Params)


def _episode_features(
    layout: Layout, arr: FloatArray, lens: IntArray, window: int
) -> list[FloatArray]:
    """Window features of every episode, in order."""
    out = []
    start = 0
    for n in lens.tolist():
        out.append(features(layout, episode_windows(arr[start : start + n], window)))
        start += n
    return out
