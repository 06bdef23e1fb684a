"""Recurrent motion generators: one Elman network per motion primitive (thesis §3.4.3, §7.2).

The thesis's future work proposes "a different neural network architecture
specifically designed for motion generation (such as recurrent neural networks)";
its §3.4.3 describes the simple recurrent (Elman) network, whose context units
``c(t)`` hold the hidden layer of the previous step. Here each primitive's network is

    h(t) = tanh(W_x [x(t); 1] + W_c h(t-1)),     h(-1) = 0 (the context starts empty)
    y(t) = tanh(W_y [h(t); 1])

reading the same feature row as a feed-forward generator (the sensor windows, the
onset clock, ...), so the only difference is the memory ``h``. It is trained by
backpropagation through time over whole *sequences*: the contiguous runs of rows of
one primitive in one demonstration (its segment, with the ``segment_margin`` rows
either side that the SBLM adds), each from an empty context. In closed loop
(:class:`ElmanStepper`) the context likewise starts empty when a primitive takes
over, after replaying the last ``warmup`` rows the robot saw, as its training
sequences began ``segment_margin`` rows before the primitive's own.

Training is bias-corrected Adam (Kingma & Ba 2015) on each batch's mean error, per
network, with the gradient of each network clipped to norm ``CLIP_NORM``: BPTT
through a tanh recurrence can spike, and gradient descent with the thesis's
momentum needs its step size retuned to every sequence length. Networks are
stacked ``(n_primitives, ...)`` and trained in lock-step, as
:mod:`behavior_hmm.generators._mlp` does for the feed-forward ones; a network's
arithmetic reads only its own rows, so its weights do not depend on the others.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from behavior_hmm._estimator import Estimator
from behavior_hmm.errors import ConfigError, ModelFileError, NotFittedError
from behavior_hmm.generators._mlp import adam_update
from behavior_hmm.generators._motion import (
    _as_float_matrix,
    _as_index,
    _check_fit_inputs,
    _check_float,
    _check_int,
    array_getter,
    check_update_inputs,
    grow,
    primitive_rng,
    set_bookkeeping,
    split_rows,
    update_rng,
)

FloatArray = NDArray[np.float64]

#: Adam's decay rates and denominator constant (Kingma & Ba's defaults).
ADAM: Final[tuple[float, float, float]] = (0.9, 0.999, 1e-8)

#: Largest norm of one network's gradient per update (larger ones are scaled down).
CLIP_NORM: Final[float] = 1.0

#: Names of the learned weight arrays, in the order of the flat parameter vector.
WEIGHTS: Final[tuple[str, ...]] = ("w_x", "w_c", "w_y")


def _shapes(n_in: int, hidden: int, n_out: int) -> tuple[tuple[int, int], ...]:
    """Shapes of W_x (bias row last), W_c and W_y (bias row last)."""
    return ((n_in + 1, hidden), (hidden, hidden), (hidden + 1, n_out))


def _views(theta: FloatArray, shapes: tuple[tuple[int, int], ...]) -> list[FloatArray]:
    """``(P, rows, cols)`` views of each weight matrix into ``theta (P, n_params)``."""
    out: list[FloatArray] = []
    start = 0
    for rows, cols in shapes:
        stop = start + rows * cols
        out.append(theta[:, start:stop].reshape(theta.shape[0], rows, cols))
        start = stop
    return out


def sequence_starts(primitives: NDArray[np.int64], groups: NDArray[Any] | None) -> NDArray[np.intp]:
    """First row of every run of equal primitive (and group) in consecutive rows."""
    change = primitives[1:] != primitives[:-1]
    if groups is not None:
        change |= groups[1:] != groups[:-1]
    return np.r_[0, np.flatnonzero(change) + 1].astype(np.intp)


class ElmanGenerators(Estimator):
    """One Elman network per motion primitive, trained by backpropagation through time.

    Parameters
    ----------
    window
        Readings per input channel in a window (as :class:`MotionGenerators`).
    hidden
        Hidden (and context) units of every network.
    learning_rate
        Adam's step size.
    epochs
        Passes over each primitive's training sequences.
    batch_size
        Sequences per primitive per update.
    init_range
        W_x and W_y start uniform in ``[-init_range, init_range]`` (thesis: 1); the
        recurrent W_c in ``[-init_range, init_range] / hidden``, so the context starts
        as a short, fading memory rather than a chaotic one.
    test_fraction
        Share of each primitive's sequences held out (whole groups where given) to keep
        the epoch with the lowest error on them.
    early_stopping
        Keep, per primitive, the weights of the epoch with the lowest test error.
    min_split_samples
        Primitives with fewer training sequences train on all of them (no test split).
    warmup
        Rows the stepper replays from an empty context when a primitive takes over (the
        SBLM sets its ``segment_margin``: how early its training sequences begin).
    random_state
        Seed; primitive ``p`` draws from ``SeedSequence(random_state, spawn_key=(p,))``.

    Attributes
    ----------
    w_x_, w_c_, w_y_ : ndarray
        Weights ``(n_primitives, n_features + 1, hidden)`` (bias row last),
        ``(n_primitives, hidden, hidden)`` and ``(n_primitives, hidden + 1, n_outputs)``.
    trained_ : ndarray of bool, shape (n_primitives,)
    n_train_, n_test_ : ndarray of int, shape (n_primitives,)
        Rows in each primitive's training and test sequences.
    train_error_, test_error_ : ndarray, shape (n_primitives, epochs)
        RMS error (normalized command units) per epoch: of the training batches as they
        were trained, and of the test sequences after the epoch; NaN where none.
    best_epoch_ : ndarray of int, shape (n_primitives,)
    hidden_sizes_ : tuple of int
    n_features_in_, n_outputs_, n_primitives_ : int
    """

    def __init__(
        self,
        window: int = 10,
        hidden: int = 5,
        learning_rate: float = 0.01,
        epochs: int = 200,
        batch_size: int = 8,
        init_range: float = 1.0,
        test_fraction: float = 0.2,
        early_stopping: bool = True,
        min_split_samples: int = 2,
        warmup: int = 0,
        random_state: int = 0,
    ) -> None:
        self.window = window
        self.hidden = hidden
        self.learning_rate = learning_rate
        self.epochs = epochs
        self.batch_size = batch_size
        self.init_range = init_range
        self.test_fraction = test_fraction
        self.early_stopping = early_stopping
        self.min_split_samples = min_split_samples
        self.warmup = warmup
        self.random_state = random_state

    def _validated_params(self) -> None:
        for name, low in (
            ("window", 1),
            ("hidden", 1),
            ("epochs", 1),
            ("batch_size", 1),
            ("min_split_samples", 1),
            ("warmup", 0),
            ("random_state", 0),
        ):
            _check_int(name, getattr(self, name), low)
        _check_float("learning_rate", self.learning_rate, 0.0, None, low_open=True)
        _check_float("init_range", self.init_range, 0.0, None, low_open=True)
        _check_float("test_fraction", self.test_fraction, 0.0, 1.0, high_open=True)
        if not isinstance(self.early_stopping, bool | np.bool_):
            raise ConfigError(f"early_stopping must be True or False, got {self.early_stopping!r}")

    # --------------------------------------------------------------------- fit
    def fit(
        self,
        X: ArrayLike,
        Y: ArrayLike,
        primitives: ArrayLike | None = None,
        n_primitives: int | None = None,
        groups: ArrayLike | None = None,
        sequences: ArrayLike | None = None,
    ) -> ElmanGenerators:
        """Train one Elman network per primitive on its sequences.

        Parameters
        ----------
        X, Y, primitives, n_primitives, groups
            As for :meth:`MotionGenerators.fit`; rows in time order.
        sequences
            Row indices where a new sequence starts (sorted, the first 0); every
            sequence must hold one primitive. Default: wherever the primitive or the
            group changes between consecutive rows.

        Returns
        -------
        ElmanGenerators
            ``self``.
        """
        self._validated_params()
        x, y, prim, n_prim, group = _check_fit_inputs(X, Y, primitives, n_primitives, groups)
        shapes = _shapes(x.shape[1], int(self.hidden), y.shape[1])
        slots = list(range(n_prim))
        rngs = [primitive_rng(int(self.random_state), p) for p in slots]
        out = self._train_slots(x, y, prim, group, sequences, shapes, slots, rngs, {})
        theta, self.train_error_, self.test_error_, self.best_epoch_, n_train, n_test = out
        self.n_train_, self.n_test_ = n_train, n_test
        theta[self.n_train_ == 0] = 0.0
        self.w_x_, self.w_c_, self.w_y_ = (np.ascontiguousarray(w) for w in _views(theta, shapes))
        self.trained_ = self.n_train_ > 0
        self._set_shapes()
        return self

    def partial_fit(
        self,
        X: ArrayLike,
        Y: ArrayLike,
        primitives: ArrayLike,
        n_primitives: int | None = None,
        groups: ArrayLike | None = None,
        sequences: ArrayLike | None = None,
        *,
        update: int = 1,
    ) -> ElmanGenerators:
        """Train the networks of the primitives that have rows in ``X``; keep the others.

        As :meth:`MotionGenerators.partial_fit`: a new (or untrained) primitive gets a
        fresh network trained as :meth:`fit` trains one; a trained one is fine-tuned from
        its weights on the new sequences only, its split and order drawn from
        ``SeedSequence(random_state, spawn_key=(p, update))``; every other network, count
        and curve stays bit for bit as it was.
        """
        self._check_fitted()
        self._validated_params()
        x, y, prim, n_prim, group = check_update_inputs(
            self, X, Y, primitives, n_primitives, groups, update
        )
        old_n = self.n_primitives_
        shapes = _shapes(self.n_features_in_, self.hidden_sizes_[0], self.n_outputs_)
        slots = np.unique(prim).tolist()
        warm = {p: p < old_n and bool(self.trained_[p]) for p in slots}
        rngs = [update_rng(int(self.random_state), p, update, warm[p]) for p in slots]
        out = self._train_slots(x, y, prim, group, sequences, shapes, slots, rngs, warm)
        theta, train_error, test_error, best_epoch, n_train_new, n_test_new = out
        stacks = [grow(w, n_prim, 0.0) for w in self._stacks()]
        trained = grow(self.trained_, n_prim, False)
        n_train, n_test = grow(self.n_train_, n_prim, 0), grow(self.n_test_, n_prim, 0)
        kept = grow(self.best_epoch_, n_prim, -1)
        curves = (grow(self.train_error_, n_prim, np.nan), grow(self.test_error_, n_prim, np.nan))
        new = _views(theta, shapes)
        for i, p in enumerate(slots):
            for stack, w in zip(stacks, new, strict=True):
                stack[p] = w[i]
            trained[p] = True
            n_train[p], n_test[p] = n_train_new[i], n_test_new[i]
            kept[p] = best_epoch[i]
            curves[0][p], curves[1][p] = train_error[i], test_error[i]
        self.w_x_, self.w_c_, self.w_y_ = (np.ascontiguousarray(w) for w in stacks)
        self.trained_ = trained
        self.n_train_, self.n_test_ = n_train, n_test
        self.best_epoch_ = kept
        self.train_error_, self.test_error_ = curves
        self._set_shapes()
        return self

    def _train_slots(
        self,
        x: FloatArray,
        y: FloatArray,
        prim: NDArray[np.int64],
        group: NDArray[Any] | None,
        sequences: ArrayLike | None,
        shapes: tuple[tuple[int, int], ...],
        slots: list[int],
        rngs: list[np.random.Generator],
        warm: Mapping[int, bool],
    ) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.int64], Any, Any]:
        """Train one network per primitive in ``slots`` on its sequences (split, then fresh
        weights or, where ``warm``, the current ones): the weights, error curves, kept
        epochs and training and test rows of each slot."""
        starts = self._starts(sequences, prim, group)
        bounds = np.r_[starts, prim.size]
        seq_prim = prim[starts]
        seq_group = group[starts] if group is not None else None
        theta0 = np.zeros((len(slots), sum(r * c for r, c in shapes)))
        train_sets: list[NDArray[np.intp]] = []
        test_sets: list[NDArray[np.intp]] = []
        for i, (p, rng) in enumerate(zip(slots, rngs, strict=True)):
            # the draws in order: split, initial weights, each epoch's order
            mine = np.flatnonzero(seq_prim == p)
            tr, te = split_rows(
                mine, seq_group, rng, float(self.test_fraction), int(self.min_split_samples)
            )
            train_sets.append(tr)
            test_sets.append(te)
            if warm.get(p, False):
                for view, w in zip(_views(theta0[i : i + 1], shapes), self._stacks(), strict=True):
                    view[0] = w[p]
            elif mine.size:
                theta0[i] = self._init(rng, shapes)
        train = _Padded.build(train_sets, bounds, x, y)
        test = _Padded.build(test_sets, bounds, x, y)
        theta, train_error, test_error, best_epoch = _train(
            theta0,
            shapes,
            train,
            test,
            rngs,
            learning_rate=float(self.learning_rate),
            epochs=int(self.epochs),
            batch_size=int(self.batch_size),
            early_stopping=bool(self.early_stopping),
        )
        rows = (train.rows.astype(np.int64), test.rows.astype(np.int64))
        return theta, train_error, test_error, best_epoch, *rows

    def _stacks(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        return self.w_x_, self.w_c_, self.w_y_

    def _starts(
        self, sequences: ArrayLike | None, prim: NDArray[np.int64], group: NDArray[Any] | None
    ) -> NDArray[np.intp]:
        if sequences is None:
            return sequence_starts(prim, group)
        starts = np.asarray(sequences)
        if starts.ndim != 1 or starts.size == 0 or starts.dtype.kind not in "iu":
            raise ConfigError("sequences must be a non-empty 1-D array of row indices")
        starts = starts.astype(np.intp)
        if starts[0] != 0 or (np.diff(starts) <= 0).any() or starts[-1] >= prim.size:
            raise ConfigError("sequences must be increasing row indices starting at 0")
        inner = np.ones(prim.size, dtype=bool)
        inner[starts] = False
        if (prim[1:] != prim[:-1])[inner[1:]].any():
            raise ConfigError("a sequence holds rows of more than one primitive")
        return starts

    def _init(self, rng: np.random.Generator, shapes: tuple[tuple[int, int], ...]) -> FloatArray:
        r = float(self.init_range)
        parts = [rng.uniform(-r, r, rows * cols) for rows, cols in shapes]
        parts[1] /= shapes[1][0]  # W_c: a fading memory at the start
        return np.concatenate(parts)

    def _set_shapes(self) -> None:
        self.n_primitives_ = int(self.w_x_.shape[0])
        self.n_features_in_ = int(self.w_x_.shape[1] - 1)
        self.n_outputs_ = int(self.w_y_.shape[2])
        self.hidden_sizes_ = (int(self.w_x_.shape[2]),)

    # ----------------------------------------------------------------- predict
    def _check_fitted(self) -> None:
        if not hasattr(self, "trained_"):
            raise NotFittedError(f"{type(self).__name__} is not fitted yet; call fit() first")

    def _weights(self, primitive: Any) -> tuple[FloatArray, FloatArray, FloatArray]:
        self._check_fitted()
        n = self.n_primitives_
        if not isinstance(primitive, int | np.integer) or not 0 <= primitive < n:
            raise ConfigError(f"primitive must be an integer in [0, {n}), got {primitive!r}")
        if not self.trained_[primitive]:
            raise ConfigError(f"primitive {primitive} had no training samples; it cannot predict")
        p = int(primitive)
        return self.w_x_[p], self.w_c_[p], self.w_y_[p]

    def predict(self, X: ArrayLike, primitive: int | ArrayLike = 0) -> FloatArray:
        """Commands for one sequence of rows, run from an empty context.

        Parameters
        ----------
        X
            Inputs in time order, shape (n, n_features).
        primitive
            The primitive whose network runs (one id: a sequence has one primitive).

        Returns
        -------
        ndarray, shape (n, n_outputs)
        """
        self._check_fitted()
        x = _as_float_matrix(X, "X")
        if x.shape[1] != self.n_features_in_:
            raise ConfigError(f"X has {x.shape[1]} features, expected {self.n_features_in_}")
        w_x, w_c, w_y = self._weights(_as_index(np.asarray(primitive)))
        drive = x @ w_x[:-1] + w_x[-1]
        h = np.zeros(w_c.shape[0])
        out = np.empty((x.shape[0], self.n_outputs_))
        for t in range(x.shape[0]):
            h = np.tanh(drive[t] + h @ w_c)
            out[t] = np.tanh(h @ w_y[:-1] + w_y[-1])
        return out

    def stepper(self) -> ElmanStepper:
        """A closed-loop runner: one command per cycle, the context carried between cycles."""
        self._check_fitted()
        return ElmanStepper(self)

    # ------------------------------------------------------------- persistence
    def to_arrays(self) -> dict[str, NDArray[Any]]:
        """Learned state as plain arrays: ``w_x``, ``w_c``, ``w_y``, ``trained``, ``n_train``,
        ``n_test``, ``best_epoch``, ``train_error``, ``test_error`` (no pickle)."""
        self._check_fitted()
        return {
            "w_x": self.w_x_.copy(),
            "w_c": self.w_c_.copy(),
            "w_y": self.w_y_.copy(),
            "trained": self.trained_.copy(),
            "n_train": self.n_train_.copy(),
            "n_test": self.n_test_.copy(),
            "best_epoch": self.best_epoch_.copy(),
            "train_error": self.train_error_.copy(),
            "test_error": self.test_error_.copy(),
        }

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, Any], **params: Any) -> ElmanGenerators:
        """Rebuild fitted generators from :meth:`to_arrays` output and the parameters.

        Raises
        ------
        ModelFileError
            Missing or unexpected keys, wrong dtypes or shapes, non-finite weights, or
            arrays that disagree with ``params``.
        """
        try:
            model = cls(**params)
            model._validated_params()
        except (TypeError, ConfigError) as exc:
            raise ModelFileError(f"invalid recurrent generator parameters: {exc}") from None
        _load(model, arrays)
        return model


class ElmanStepper:
    """Runs :class:`ElmanGenerators` in closed loop, one row per control cycle.

    The context belongs to the running primitive: when another primitive takes over,
    its network starts from an empty context and first replays the last ``warmup``
    rows (fewer at the start of a run), as its training sequences began before its
    segment. :meth:`reset` forgets the run.
    """

    def __init__(self, generators: ElmanGenerators) -> None:
        self._gens = generators
        self._warmup = int(generators.warmup)
        self._recent = np.zeros((self._warmup, generators.n_features_in_))
        self.reset()

    def reset(self) -> None:
        """Forget the run: no primitive running, no rows seen."""
        self._primitive = -1
        self._seen = 0
        self._h = np.zeros(int(self._gens.hidden_sizes_[0]))

    def step(self, row: FloatArray, primitive: int) -> FloatArray:
        """The normalized command of ``primitive`` for this cycle's feature ``row``."""
        w_x, w_c, w_y = self._gens._weights(primitive)
        if primitive != self._primitive:
            h = np.zeros(w_c.shape[0])
            for past in self._recent[max(0, self._warmup - self._seen) :]:
                h = np.tanh(past @ w_x[:-1] + w_x[-1] + h @ w_c)
            self._primitive = primitive
        else:
            h = self._h
        try:
            h = np.tanh(row @ w_x[:-1] + w_x[-1] + h @ w_c)
        except ValueError:
            raise ConfigError(
                f"row must have shape ({self._gens.n_features_in_},), got {np.shape(row)}"
            ) from None
        self._h = h
        if self._warmup:
            self._recent[:-1] = self._recent[1:]
            self._recent[-1] = row
            self._seen += 1
        return np.tanh(h @ w_y[:-1] + w_y[-1])


class _Padded:
    """Each primitive's sequences, zero-padded: ``x (P, S, T, n_in + 1)`` with a ones
    column, ``y (P, S, T, n_out)``, ``mask (P, S, T)``, ``count (P,)`` sequences and
    ``rows (P,)`` real rows per primitive."""

    def __init__(
        self,
        x: FloatArray,
        y: FloatArray,
        mask: FloatArray,
        count: NDArray[np.intp],
        rows: NDArray[np.intp],
    ) -> None:
        self.x, self.y, self.mask, self.count, self.rows = x, y, mask, count, rows

    @classmethod
    def build(
        cls,
        sets: list[NDArray[np.intp]],
        bounds: NDArray[np.intp],
        x: FloatArray,
        y: FloatArray,
    ) -> _Padded:
        lengths = np.diff(bounds)
        n_seq = max((s.size for s in sets), default=0)
        longest = max((int(lengths[s].max()) for s in sets if s.size), default=0)
        n = len(sets)
        xs = np.zeros((n, n_seq, longest, x.shape[1] + 1))
        ys = np.zeros((n, n_seq, longest, y.shape[1]))
        mask = np.zeros((n, n_seq, longest))
        for p, chosen in enumerate(sets):
            for j, s in enumerate(chosen.tolist()):
                a, b = int(bounds[s]), int(bounds[s + 1])
                xs[p, j, : b - a, :-1] = x[a:b]
                xs[p, j, : b - a, -1] = 1.0
                ys[p, j, : b - a] = y[a:b]
                mask[p, j, : b - a] = 1.0
        count = np.array([s.size for s in sets], dtype=np.intp)
        rows = np.array([int(lengths[s].sum()) for s in sets], dtype=np.intp)
        return cls(xs, ys, mask, count, rows)


def _forward(weights: list[FloatArray], x: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Hidden states ``(P, B, T, H)`` and outputs ``(P, B, T, n_out)`` of sequences ``x``."""
    w_x, w_c, w_y = weights
    drive = np.matmul(x.reshape(x.shape[0], -1, x.shape[3]), w_x).reshape(
        (*x.shape[:3], w_x.shape[2])
    )
    hs = np.empty_like(drive)
    h = np.zeros((x.shape[0], x.shape[1], w_x.shape[2]))
    for t in range(x.shape[2]):
        h = np.tanh(drive[:, :, t] + np.matmul(h, w_c))
        hs[:, :, t] = h
    out = np.tanh(np.matmul(hs, w_y[:, None, :-1]) + w_y[:, None, None, -1])
    return hs, out


def _batch_gradient(
    weights: list[FloatArray], x: FloatArray, y: FloatArray, mask: FloatArray
) -> tuple[list[FloatArray], FloatArray, FloatArray]:
    """Gradients of each slot's mean error ``1/2 sum (y - o)^2`` over its real rows.

    Returns the gradients (as ``weights``), each slot's summed squared error and its
    number of real rows.
    """
    _, w_c, w_y = weights
    hs, out = _forward(weights, x)
    rows = mask.sum(axis=(1, 2))
    per = 1.0 / np.maximum(rows, 1.0)
    err = (out - y) * mask[..., None]
    sq = (err * err).sum(axis=(1, 2, 3))
    d_out = err * (1.0 - out * out) * per[:, None, None, None]
    n_slots, batch, steps, hidden = hs.shape
    flat_h = hs.reshape(n_slots, -1, hidden)
    flat_d = d_out.reshape(n_slots, -1, d_out.shape[3])
    g_y = np.empty_like(w_y)
    g_y[:, :-1] = np.matmul(flat_h.transpose(0, 2, 1), flat_d)
    g_y[:, -1] = flat_d.sum(axis=1)
    d_h = np.matmul(d_out, w_y[:, None, :-1].transpose(0, 1, 3, 2))  # (P, B, T, H)
    d_a = np.empty_like(hs)
    carry = np.zeros((n_slots, batch, hidden))
    w_c_t = w_c.transpose(0, 2, 1)
    for t in range(steps - 1, -1, -1):
        h = hs[:, :, t]
        d = (d_h[:, :, t] + carry) * (1.0 - h * h)
        d_a[:, :, t] = d
        carry = np.matmul(d, w_c_t)
    flat_a = d_a.reshape(n_slots, -1, hidden)
    g_x = np.matmul(x.reshape(n_slots, -1, x.shape[3]).transpose(0, 2, 1), flat_a)
    previous = np.zeros_like(hs)
    previous[:, :, 1:] = hs[:, :, :-1]
    g_c = np.matmul(previous.reshape(n_slots, -1, hidden).transpose(0, 2, 1), flat_a)
    return [g_x, g_c, g_y], sq, rows


def _train(
    theta0: FloatArray,
    shapes: tuple[tuple[int, int], ...],
    train: _Padded,
    test: _Padded,
    rngs: list[np.random.Generator],
    *,
    learning_rate: float,
    epochs: int,
    batch_size: int,
    early_stopping: bool,
) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.int64]]:
    """Train every slot; the kept weights, error curves and kept epochs."""
    from threadpoolctl import threadpool_limits

    n_slots = theta0.shape[0]
    theta = theta0.copy()
    weights = _views(theta, shapes)
    m = np.zeros_like(theta)
    s = np.zeros_like(theta)
    steps = np.zeros(n_slots)
    lr = np.full(n_slots, learning_rate)
    n_out = shapes[2][1]
    train_error = np.full((n_slots, epochs), np.nan)
    test_error = np.full((n_slots, epochs), np.nan)
    best_epoch = np.full(n_slots, -1, dtype=np.int64)
    best_theta = theta.copy()
    best_error = np.full(n_slots, np.inf)
    running = train.count > 0
    has_test = test.count > 0
    slot = np.arange(n_slots)[:, None]
    n_batches = int(-(-train.count.max() // batch_size)) if running.any() else 0
    # one BLAS thread: the same seed gives the same weights in any process (as _mlp)
    with threadpool_limits(limits=1, user_api="blas"):
        for epoch in range(epochs if running.any() else 0):
            order = np.zeros((n_slots, n_batches * batch_size), dtype=np.intp)
            real = np.zeros((n_slots, n_batches * batch_size), dtype=bool)
            for p in np.flatnonzero(running).tolist():
                count = int(train.count[p])
                order[p, :count] = rngs[p].permutation(count)
                real[p, :count] = True
            squared = np.zeros(n_slots)
            for b in range(n_batches):
                cols = slice(b * batch_size, (b + 1) * batch_size)
                pick = order[:, cols]
                mask = train.mask[slot, pick] * real[:, cols, None]
                steps_used = mask.any(axis=(0, 1))
                if not steps_used.any():
                    continue
                last = int(np.flatnonzero(steps_used)[-1]) + 1
                x = train.x[slot, pick, :last]
                grads, sq, rows = _batch_gradient(
                    weights, x, train.y[slot, pick, :last], mask[..., :last]
                )
                squared += sq
                active = rows > 0
                flat = np.concatenate([g.reshape(n_slots, -1) for g in grads], axis=1)
                norm = np.sqrt((flat * flat).sum(axis=1))
                flat *= np.minimum(1.0, CLIP_NORM / np.maximum(norm, 1e-300))[:, None]
                adam_update(theta, flat, m, s, steps, lr, active, bool(active.all()), ADAM)
            trained = running
            train_error[trained, epoch] = np.sqrt(squared[trained] / (train.rows[trained] * n_out))
            if has_test.any():
                _, out = _forward(weights, test.x)
                err = (out - test.y) * test.mask[..., None]
                sq_test = (err * err).sum(axis=(1, 2, 3))
                rms = np.sqrt(sq_test / np.maximum(test.rows * n_out, 1))
                tracked = has_test & running
                test_error[tracked, epoch] = rms[tracked]
                improved = tracked & (rms < best_error)
                best_error[improved] = rms[improved]
                best_theta[improved] = theta[improved]
                best_epoch[improved] = epoch
    ran = running & (epochs > 0)
    if early_stopping:
        keep = has_test & (best_epoch >= 0)
        theta[keep] = best_theta[keep]
        best_epoch[ran & ~keep] = epochs - 1
    else:
        best_epoch[ran] = epochs - 1
    return theta, train_error, test_error, best_epoch


def _load(model: ElmanGenerators, arrays: Mapping[str, Any]) -> None:
    """Validate ``arrays`` (from :meth:`ElmanGenerators.to_arrays`) into ``model``."""
    get = array_getter(arrays, set(WEIGHTS), "recurrent generator")
    w_x, w_c, w_y = (get(name, "f", 3).astype(np.float64) for name in WEIGHTS)
    n_prim, hidden = w_x.shape[0], int(model.hidden)
    if n_prim < 1 or w_x.shape[1] < 2 or w_x.shape[2] != hidden:
        raise ModelFileError(f"'w_x' must be (primitives, inputs + 1, {hidden}), got {w_x.shape}")
    if w_c.shape != (n_prim, hidden, hidden):
        raise ModelFileError(f"'w_c' must be ({n_prim}, {hidden}, {hidden}), got {w_c.shape}")
    if w_y.shape[:2] != (n_prim, hidden + 1) or w_y.shape[2] < 1:
        raise ModelFileError(f"'w_y' must be ({n_prim}, {hidden + 1}, outputs), got {w_y.shape}")
    if not all(np.isfinite(w).all() for w in (w_x, w_c, w_y)):
        raise ModelFileError("recurrent generator weights are not finite")
    set_bookkeeping(model, get, n_prim, model.epochs)
    model.w_x_ = np.ascontiguousarray(w_x)
    model.w_c_ = np.ascontiguousarray(w_c)
    model.w_y_ = np.ascontiguousarray(w_y)
    model._set_shapes()
