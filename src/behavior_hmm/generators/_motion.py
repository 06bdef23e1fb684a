"""Motion generators: one small tanh network per motion primitive (thesis §4.2, §6.2)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any, Final, NoReturn

import numpy as np
from numpy.typing import ArrayLike, NDArray

from behavior_hmm._estimator import Estimator
from behavior_hmm.errors import ConfigError, ModelFileError, NotFittedError
from behavior_hmm.generators._mlp import (
    FloatArray,
    layer_views,
    n_params,
    train_stack,
)

#: Default minibatch size: 16 samples per primitive per update (batch_size=1 is the
#: thesis's incremental rule; see docs/algorithms.md for the measured trade-off).
DEFAULT_BATCH_SIZE = 16

#: Default training epochs of an SBLM's generators (and of the behavior-cloning baseline,
#: which reads the same features): at 200, 78 % of the generators of the five simple rows
#: kept a weight set from their last 20 epochs (the held-out error was still falling), and
#: the approach generators underfit the short starts (0.10-0.20 m). Measured in
#: docs/algorithms.md; the thesis preset keeps 200.
DEFAULT_GENERATOR_EPOCHS = 400

#: Hidden units per ``window`` inputs when ``hidden=None`` (thesis table 6.2: 5/10/15).
HIDDEN_PER_CHANNEL = 5


class MotionGenerators(Estimator):
    """One tanh network per motion primitive, mapping a sensor window to commands.

    All primitives' networks have the same layer sizes and are trained together
    (their weights stacked in ``(n_primitives, ...)`` arrays), each on its own
    samples, with backpropagation and momentum (thesis §3.4.2.1, table 6.2).

    Parameters
    ----------
    window
        Readings per input channel in a window (thesis: 10). Used only for the
        default hidden size; the inputs ``X`` may have any width (e.g. windows
        plus goal inputs for a behavior-cloning baseline).
    hidden
        Hidden layer sizes: an int (one layer), a tuple (several layers, ``()``
        for none), or ``None`` for the thesis default of 5 units per
        ``window`` inputs, ``5 * max(1, n_features // window)`` (5/10/15 for
        10/20/30 inputs).
    learning_rate
        Step size per sample (thesis: 0.01). A minibatch applies the sum of its
        samples' gradients, so ``batch_size=1`` is the thesis's incremental rule
        and a batch of B approximates B incremental steps.
    momentum
        Momentum constant in [0, 1) (thesis: 0.4).
    epochs
        Passes over each primitive's training samples.
    batch_size
        Samples per primitive per update (1 = thesis incremental training).
    init_range
        Weights and biases start uniform in ``[-init_range, init_range]`` (thesis: 1).
    test_fraction
        Share of each primitive's samples held out as its test split (thesis: 0.2).
    early_stopping
        Keep, per primitive, the weights of the epoch with the lowest test error.
    patience
        If set, stop a primitive after this many epochs without a new lowest test
        error (saves time; ``None`` trains every epoch).
    min_split_samples
        Primitives with fewer samples train on all of them (no test split).
    random_state
        Seed; primitive ``p`` draws from ``SeedSequence(random_state, spawn_key=(p,))``,
        so its network does not depend on the other primitives.
    init
        Where each primitive's network starts. ``"random"`` (thesis): its own uniform
        draw. ``"shared"``: the weights of one network first trained, the same way, on
        every primitive's rows together (its draws from ``SeedSequence(random_state,
        spawn_key=(SHARED_KEY,))``); each primitive's network then fine-tunes them on its
        own rows, with its own split and early stopping. With few rows per primitive
        (few demonstrations) the networks keep what all the rows teach; with many they
        specialize. A network that :meth:`partial_fit` adds for a new primitive starts
        from its own draw.

    Attributes
    ----------
    coefs_, intercepts_ : list of ndarray
        Layer weights ``(n_primitives, n_in, n_out)`` and biases ``(n_primitives, n_out)``.
    trained_ : ndarray of bool, shape (n_primitives,)
        Which primitives had samples (others cannot predict).
    n_train_, n_test_ : ndarray of int, shape (n_primitives,)
        Sizes of each primitive's training and test splits.
    train_error_, test_error_ : ndarray, shape (n_primitives, epochs)
        RMS error (normalized command units) after each epoch; NaN where a
        primitive did not train that epoch or has no test split.
    best_epoch_ : ndarray of int, shape (n_primitives,)
        0-based epoch whose weights were kept (-1: not trained).
    hidden_sizes_ : tuple of int
        Hidden layer sizes used.
    n_features_in_, n_outputs_, n_primitives_ : int
    """

    def __init__(
        self,
        window: int = 10,
        hidden: int | tuple[int, ...] | None = None,
        learning_rate: float = 0.01,
        momentum: float = 0.4,
        epochs: int = 200,
        batch_size: int = DEFAULT_BATCH_SIZE,
        init_range: float = 1.0,
        test_fraction: float = 0.2,
        early_stopping: bool = True,
        patience: int | None = None,
        min_split_samples: int = 5,
        random_state: int = 0,
        init: str = "random",
    ) -> None:
        self.window = window
        self.hidden = hidden
        self.learning_rate = learning_rate
        self.momentum = momentum
        self.epochs = epochs
        self.batch_size = batch_size
        self.init_range = init_range
        self.test_fraction = test_fraction
        self.early_stopping = early_stopping
        self.patience = patience
        self.min_split_samples = min_split_samples
        self.random_state = random_state
        self.init = init

    # ------------------------------------------------------------------ params
    def _validated_params(self) -> None:
        _check_int("window", self.window, 1)
        _check_int("epochs", self.epochs, 1)
        _check_int("batch_size", self.batch_size, 1)
        _check_int("min_split_samples", self.min_split_samples, 1)
        _check_int("random_state", self.random_state, 0)
        if self.patience is not None:
            _check_int("patience", self.patience, 1)
        _check_float("learning_rate", self.learning_rate, 0.0, None, low_open=True)
        self._optimizer_options()
        _check_float("init_range", self.init_range, 0.0, None, low_open=True)
        _check_float("test_fraction", self.test_fraction, 0.0, 1.0, high_open=True)
        if not isinstance(self.early_stopping, bool | np.bool_):
            raise ConfigError(f"early_stopping must be True or False, got {self.early_stopping!r}")
        _hidden_tuple(self.hidden, 1, self.window)
        if getattr(self, "init", "random") not in GENERATOR_INITS:
            raise ConfigError(
                f"init must be one of {', '.join(GENERATOR_INITS)}, got {self.init!r}"
            )

    def _optimizer_options(self) -> dict[str, Any]:
        """Checked keyword arguments of :func:`train_stack` choosing the update rule.

        Here the thesis's gradient descent with momentum; :class:`AdamGenerators`
        overrides it.
        """
        _check_float("momentum", self.momentum, 0.0, 1.0, high_open=True)
        return {"optimizer": "sgd", "momentum": float(self.momentum)}

    # --------------------------------------------------------------------- fit
    def fit(
        self,
        X: ArrayLike,
        Y: ArrayLike,
        primitives: ArrayLike | None = None,
        n_primitives: int | None = None,
        groups: ArrayLike | None = None,
    ) -> MotionGenerators:
        """Train one network per primitive.

        Parameters
        ----------
        X
            Inputs, shape (n, n_features): windows from :func:`make_windows`
            (normalized to [-1, 1]), optionally with extra columns appended.
        Y
            Normalized commands in [-1, 1], shape (n, n_outputs) (left, right).
        primitives
            Primitive id of each row, shape (n,), integers in ``[0, n_primitives)``;
            ``None``: every row belongs to primitive 0 (a single network).
        n_primitives
            Number of primitives (default ``max(primitives) + 1``); primitives
            without samples are allowed and flagged in ``trained_``.
        groups
            Optional group label per row (e.g. the episode). When given, a
            primitive's test split takes whole groups (no near-duplicate
            neighbouring windows on both sides of the split), where it has at
            least two groups; otherwise single rows are drawn at random.

        Returns
        -------
        MotionGenerators
            ``self``.
        """
        self._validated_params()
        x, y, prim, n_prim, group = _check_fit_inputs(X, Y, primitives, n_primitives, groups)
        n_features, n_outputs = x.shape[1], y.shape[1]
        hidden = _hidden_tuple(self.hidden, n_features, self.window)
        sizes = (n_features, *hidden, n_outputs)
        size = n_params(sizes)

        shared = None
        if getattr(self, "init", "random") == "shared" and len(x):
            shared = self._shared_start(sizes, x, y, group, int(np.bincount(prim).max()))
        rngs = [primitive_rng(int(self.random_state), p) for p in range(n_prim)]
        theta0 = np.zeros((n_prim, size))
        splits: list[tuple[NDArray[np.intp], NDArray[np.intp]]] = []
        for p in range(n_prim):
            rows = np.flatnonzero(prim == p)
            # Draw order per primitive: split, initial weights, then each epoch's order
            # (the split does not depend on the network's size).
            splits.append(
                split_rows(
                    rows, group, rngs[p], float(self.test_fraction), int(self.min_split_samples)
                )
            )
            if rows.size:
                # drawn either way, so each epoch's order is the same draw for both inits
                theta0[p] = init_weights(rngs[p], sizes, float(self.init_range))
                if shared is not None:
                    theta0[p] = shared

        n_train, n_test, result = self._train(theta0, sizes, splits, x, y, rngs)
        theta = result.theta
        theta[n_train == 0] = 0.0
        weights = layer_views(theta, sizes)
        self.coefs_ = [np.ascontiguousarray(w[:, :-1, :]) for w in weights]
        self.intercepts_ = [np.ascontiguousarray(w[:, -1, :]) for w in weights]
        self.trained_ = n_train > 0
        self.n_train_ = n_train
        self.n_test_ = n_test
        self.train_error_ = result.train_error
        self.test_error_ = result.test_error
        self.best_epoch_ = result.best_epoch
        self._set_shapes()
        return self

    def _shared_start(
        self,
        sizes: Any,
        x: NDArray[np.float64],
        y: NDArray[np.float64],
        group: NDArray[Any] | None,
        largest: int,
    ) -> NDArray[np.float64]:
        """``init="shared"``: the weights of one network trained on every row, as a
        primitive's is (split, early stopping), from its own draws, for as many updates
        as the primitive of most rows (``largest``) gets: :func:`shared_epochs`."""
        rng = np.random.default_rng(
            np.random.SeedSequence(int(self.random_state), spawn_key=(SHARED_KEY,))
        )
        split = split_rows(
            np.arange(len(x)), group, rng, float(self.test_fraction), int(self.min_split_samples)
        )
        theta = init_weights(rng, sizes, float(self.init_range))[None, :]
        epochs = shared_epochs(
            int(self.epochs),
            int(self.batch_size),
            len(split[0]),
            largest,
            float(self.test_fraction),
        )
        _, _, result = self._train(theta, sizes, [split], x, y, [rng], epochs=epochs)
        return np.array(result.theta[0], dtype=np.float64)

    def _train(
        self,
        theta0: NDArray[np.float64],
        sizes: Any,
        splits: list[tuple[NDArray[np.intp], NDArray[np.intp]]],
        x: NDArray[np.float64],
        y: NDArray[np.float64],
        rngs: Any,
        epochs: int | None = None,
    ) -> tuple[NDArray[np.int64], NDArray[np.int64], Any]:
        """Train one network per row of ``theta0`` on its (train, test) rows of ``x``, ``y``
        (for ``epochs``, default the generators' own): the train and test counts and
        :func:`train_stack`'s result."""
        n_train = np.array([len(tr) for tr, _ in splits], dtype=np.int64)
        n_test = np.array([len(te) for _, te in splits], dtype=np.int64)
        x_tr, y_tr = _pad([tr for tr, _ in splits], x, y)
        x_te, y_te = _pad([te for _, te in splits], x, y)
        options = self._optimizer_options()
        momentum = float(options.pop("momentum", 0.0))
        n = len(splits)
        result = train_stack(
            theta0,
            sizes,
            x_tr,
            y_tr,
            n_train,
            x_te,
            y_te,
            n_test,
            learning_rate=np.full(n, float(self.learning_rate)),
            momentum=np.full(n, momentum),
            epochs=int(self.epochs) if epochs is None else epochs,
            batch_size=int(self.batch_size),
            rngs=rngs,
            early_stopping=bool(self.early_stopping),
            patience=None if self.patience is None else int(self.patience),
            **options,
        )
        return n_train, n_test, result

    def partial_fit(
        self,
        X: ArrayLike,
        Y: ArrayLike,
        primitives: ArrayLike,
        n_primitives: int | None = None,
        groups: ArrayLike | None = None,
        *,
        update: int = 1,
    ) -> MotionGenerators:
        """Train the networks of the primitives that have rows in ``X``; keep the others.

        A primitive that is new (an index ``>= n_primitives_``) or had no samples so far
        gets a fresh network, trained exactly as :meth:`fit` trains one (its own seed
        ``primitive_rng(random_state, p)``, split, ``epochs``). A primitive that already
        has a network is *fine-tuned*: training starts from its current weights and runs
        ``epochs`` passes over the new rows only (the rows it was trained on before are
        not kept), with the split and the order drawn from
        ``SeedSequence(random_state, spawn_key=(p, update))``. Its ``n_train_``,
        ``n_test_``, error curves and ``best_epoch_`` then describe this training. The
        networks, counts and curves of every primitive without rows in ``X`` stay bit
        for bit as they were; the stacks grow to ``n_primitives`` (default: the larger
        of ``n_primitives_`` and the highest index + 1), new primitives without rows
        untrained.

        Parameters
        ----------
        X, Y, groups
            As for :meth:`fit`, with the fitted number of features and outputs.
        primitives
            Primitive id of each row.
        n_primitives
            Number of primitives after the update; at least ``n_primitives_``.
        update
            Which update this is (1, 2, ...): the seed of the fine-tuned primitives' draws.

        Returns
        -------
        MotionGenerators
            ``self``.
        """
        self._check_fitted()
        self._validated_params()
        x, y, prim, n_prim, group = check_update_inputs(
            self, X, Y, primitives, n_primitives, groups, update
        )
        old_n = self.n_primitives_
        sizes = (self.n_features_in_, *self.hidden_sizes_, self.n_outputs_)
        size = n_params(sizes)
        which = np.unique(prim)
        theta0 = np.zeros((which.size, size))
        rngs: list[np.random.Generator] = []
        splits: list[tuple[NDArray[np.intp], NDArray[np.intp]]] = []
        for i, p in enumerate(which.tolist()):
            rows = np.flatnonzero(prim == p)
            warm = p < old_n and bool(self.trained_[p])
            rng = update_rng(int(self.random_state), p, update, warm)
            rngs.append(rng)
            # the draws in fit's order: split, initial weights, each epoch's order
            splits.append(
                split_rows(rows, group, rng, float(self.test_fraction), int(self.min_split_samples))
            )
            if warm:
                views = layer_views(theta0[i : i + 1], sizes)
                for w, c, b in zip(views, self.coefs_, self.intercepts_, strict=True):
                    w[0, :-1, :] = c[p]
                    w[0, -1, :] = b[p]
            else:
                theta0[i] = init_weights(rng, sizes, float(self.init_range))
        n_train, n_test, result = self._train(theta0, sizes, splits, x, y, rngs)
        weights = layer_views(result.theta, sizes)

        def grown(arr: NDArray[Any], fill: Any) -> NDArray[Any]:
            return grow(arr, n_prim, fill)

        coefs = [grown(c, 0.0) for c in self.coefs_]
        intercepts = [grown(b, 0.0) for b in self.intercepts_]
        trained = grown(self.trained_, False)
        counts = (grown(self.n_train_, 0), grown(self.n_test_, 0))
        best_epoch = grown(self.best_epoch_, -1)
        curves = (grown(self.train_error_, np.nan), grown(self.test_error_, np.nan))
        for i, p in enumerate(which.tolist()):
            for c, b, w in zip(coefs, intercepts, weights, strict=True):
                c[p] = w[i, :-1, :]
                b[p] = w[i, -1, :]
            trained[p] = True
            counts[0][p], counts[1][p] = n_train[i], n_test[i]
            best_epoch[p] = result.best_epoch[i]
            curves[0][p], curves[1][p] = result.train_error[i], result.test_error[i]
        self.coefs_ = [np.ascontiguousarray(c) for c in coefs]
        self.intercepts_ = [np.ascontiguousarray(b) for b in intercepts]
        self.trained_ = trained
        self.n_train_, self.n_test_ = counts
        self.best_epoch_ = best_epoch
        self.train_error_, self.test_error_ = curves
        self._set_shapes()
        return self

    def _set_shapes(self) -> None:
        self.n_primitives_ = int(self.coefs_[0].shape[0])
        self.n_features_in_ = int(self.coefs_[0].shape[1])
        self.n_outputs_ = int(self.coefs_[-1].shape[2])
        self.hidden_sizes_ = tuple(int(w.shape[2]) for w in self.coefs_[:-1])
        # Per-primitive contiguous (W, b) views for the single-window fast path.
        self._fast_layers: list[tuple[tuple[FloatArray, FloatArray], ...] | None] = [
            tuple((w[p], b[p]) for w, b in zip(self.coefs_, self.intercepts_, strict=True))
            if self.trained_[p]
            else None
            for p in range(self.n_primitives_)
        ]

    # ----------------------------------------------------------------- predict
    def _not_fitted_message(self) -> str:
        return f"{type(self).__name__} is not fitted yet; call fit() first"

    def _check_fitted(self) -> None:
        if not hasattr(self, "_fast_layers"):
            raise NotFittedError(self._not_fitted_message())

    def _layers(self, primitive: int) -> tuple[tuple[FloatArray, FloatArray], ...]:
        """The (W, b) pairs of one trained primitive, or our error."""
        try:
            layers = self._fast_layers[primitive]
        except AttributeError:
            raise NotFittedError(self._not_fitted_message()) from None
        except (IndexError, TypeError):
            layers = None
        if layers is None or primitive < 0:
            self._bad_primitive(primitive)
        return layers

    def _bad_primitive(self, primitive: Any) -> NoReturn:
        n = self.n_primitives_
        if not isinstance(primitive, int | np.integer) or not 0 <= primitive < n:
            raise ConfigError(f"primitive must be an integer in [0, {n}), got {primitive!r}")
        raise ConfigError(f"primitive {primitive} had no training samples; it cannot predict")

    def predict_one(self, x: NDArray[np.float64], primitive: int) -> NDArray[np.float64]:
        """Commands for one window: the control loop's fast path (a few microseconds).

        Parameters
        ----------
        x
            One input row, shape (n_features,), float64 (not checked for NaN).
        primitive
            Primitive id.

        Returns
        -------
        ndarray, shape (n_outputs,)
            Normalized commands in (-1, 1), a new array.
        """
        layers = self._layers(primitive)
        a = x
        try:
            for w, b in layers:
                a = np.dot(a, w)
                a += b
                np.tanh(a, out=a)
        except ValueError:
            raise ConfigError(
                f"x must have shape ({self.n_features_in_},), got {np.shape(x)}"
            ) from None
        return a

    def stepper(self) -> FeedforwardStepper:
        """A closed-loop runner with the recurrent generators' interface (no state here)."""
        self._check_fitted()
        return FeedforwardStepper(self)

    def predict(self, X: ArrayLike, primitive: int | ArrayLike = 0) -> NDArray[np.float64]:
        """Commands for a batch of windows.

        Parameters
        ----------
        X
            Inputs, shape (n, n_features).
        primitive
            One primitive id for every row, or one per row (shape (n,)).

        Returns
        -------
        ndarray, shape (n, n_outputs)
            Normalized commands in (-1, 1).
        """
        self._check_fitted()
        x = _as_float_matrix(X, "X")
        if x.shape[1] != self.n_features_in_:
            raise ConfigError(f"X has {x.shape[1]} features, expected {self.n_features_in_}")
        prim = np.asarray(primitive)
        if prim.ndim == 0:
            ids = np.full(x.shape[0], _as_index(prim), dtype=np.int64)
        else:
            if prim.shape != (x.shape[0],) or (prim.size and prim.dtype.kind not in "iu"):
                raise ConfigError("primitive must be an integer or one integer per row of X")
            ids = prim.astype(np.int64)
        out = np.empty((x.shape[0], self.n_outputs_))
        for p in np.unique(ids):
            layers = self._layers(int(p))
            rows = ids == p
            a = x[rows]
            for w, b in layers:
                a = np.tanh(a @ w + b)
            out[rows] = a
        return out

    # ------------------------------------------------------------- persistence
    def to_arrays(self) -> dict[str, NDArray[Any]]:
        """Learned state as plain arrays (for ``.npz``/safetensors; no pickle).

        Keys: ``coef_{l}``, ``intercept_{l}`` per layer, ``trained``, ``n_train``,
        ``n_test``, ``best_epoch``, ``train_error``, ``test_error``. Constructor
        parameters are not included: store :meth:`get_params` beside them.
        """
        self._check_fitted()
        arrays: dict[str, NDArray[Any]] = {}
        for layer, (w, b) in enumerate(zip(self.coefs_, self.intercepts_, strict=True)):
            arrays[f"coef_{layer}"] = w.copy()
            arrays[f"intercept_{layer}"] = b.copy()
        arrays["trained"] = self.trained_.copy()
        arrays["n_train"] = self.n_train_.copy()
        arrays["n_test"] = self.n_test_.copy()
        arrays["best_epoch"] = self.best_epoch_.copy()
        arrays["train_error"] = self.train_error_.copy()
        arrays["test_error"] = self.test_error_.copy()
        return arrays

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, Any], **params: Any) -> MotionGenerators:
        """Rebuild fitted generators from :meth:`to_arrays` output and the parameters.

        Raises
        ------
        ModelFileError
            Missing or unexpected keys, wrong dtypes or shapes, non-finite
            weights, or arrays that disagree with ``params``.
        """
        try:
            model = cls(**params)
            model._validated_params()
        except (TypeError, ConfigError) as exc:
            raise ModelFileError(f"invalid motion generator parameters: {exc}") from None
        _load_arrays(model, arrays)
        return model


class FeedforwardStepper:
    """Runs :class:`MotionGenerators` in closed loop: ``step(row, primitive)`` is
    :meth:`MotionGenerators.predict_one` (a feed-forward network keeps no state), and
    ``reset`` does nothing; the interface of
    :class:`~behavior_hmm.generators._recurrent.ElmanStepper`."""

    def __init__(self, generators: MotionGenerators) -> None:
        self.step = generators.predict_one

    def reset(self) -> None:
        """Nothing to forget."""


class AdamGenerators(MotionGenerators):
    """:class:`MotionGenerators` trained with Adam instead of gradient descent with momentum.

    The same stacked tanh networks, split, early stopping, prediction and arrays; only
    the update rule differs: each minibatch's *mean* gradient drives bias-corrected
    Adam (Kingma & Ba 2015), ``w -= learning_rate * m_hat / (sqrt(v_hat) + epsilon)``.
    Adam's step does not grow with the batch or the gradient's scale, so a wider or
    deeper network (e.g. ``hidden=(64, 64)``) trains without retuning the step size
    to its width, as the thesis's per-sample rule needs.

    Parameters
    ----------
    window, hidden, epochs, batch_size, init_range, test_fraction, early_stopping,
    patience, min_split_samples, random_state
        As for :class:`MotionGenerators`.
    learning_rate
        Adam's step size (default 1e-3).
    beta1, beta2
        Decay rates of the running mean of the gradient and of its square, in [0, 1).
    epsilon
        Added to the denominator, > 0.
    """

    def __init__(
        self,
        window: int = 10,
        hidden: int | tuple[int, ...] | None = None,
        learning_rate: float = 1e-3,
        beta1: float = 0.9,
        beta2: float = 0.999,
        epsilon: float = 1e-8,
        epochs: int = 200,
        batch_size: int = 64,
        init_range: float = 1.0,
        test_fraction: float = 0.2,
        early_stopping: bool = True,
        patience: int | None = None,
        min_split_samples: int = 5,
        random_state: int = 0,
    ) -> None:
        self.window = window
        self.hidden = hidden
        self.learning_rate = learning_rate
        self.beta1 = beta1
        self.beta2 = beta2
        self.epsilon = epsilon
        self.epochs = epochs
        self.batch_size = batch_size
        self.init_range = init_range
        self.test_fraction = test_fraction
        self.early_stopping = early_stopping
        self.patience = patience
        self.min_split_samples = min_split_samples
        self.random_state = random_state

    def _optimizer_options(self) -> dict[str, Any]:
        _check_float("beta1", self.beta1, 0.0, 1.0, high_open=True)
        _check_float("beta2", self.beta2, 0.0, 1.0, high_open=True)
        _check_float("epsilon", self.epsilon, 0.0, None, low_open=True)
        return {
            "optimizer": "adam",
            "beta1": float(self.beta1),
            "beta2": float(self.beta2),
            "epsilon": float(self.epsilon),
        }


# ---------------------------------------------------------------------- helpers
#: Where a generator's networks start (:class:`MotionGenerators` ``init``).
GENERATOR_INITS: Final[tuple[str, ...]] = ("random", "shared")
#: Spawn key of the shared network's draws (``init="shared"``): no primitive's, whose
#: keys are ``(p,)`` and ``(p, update)``.
SHARED_KEY = 2**31


def shared_epochs(
    epochs: int, batch_size: int, n_train: int, largest: int, test_fraction: float
) -> int:
    """Epochs of the shared network (``init="shared"``) on its ``n_train`` rows: as many
    updates as ``epochs`` passes over the primitive of most rows (``largest`` rows, of
    which about ``1 - test_fraction`` train), at least one pass and at most ``epochs``.

    Trained for every epoch on every row, the shared network alone took 2-3x a whole
    model's training (``epochs`` passes over all the rows, one update after another);
    a start needs no more updates than one primitive's network makes.
    """
    steps = epochs * math.ceil(max(1, round(largest * (1.0 - test_fraction))) / batch_size)
    per_epoch = math.ceil(max(1, n_train) / batch_size)
    return max(1, min(epochs, math.ceil(steps / per_epoch)))


def primitive_rng(random_state: int, primitive: int) -> np.random.Generator:
    """The generator of one primitive: independent of how many primitives there are."""
    return np.random.default_rng(np.random.SeedSequence(random_state, spawn_key=(primitive,)))


def update_rng(random_state: int, primitive: int, update: int, warm: bool) -> np.random.Generator:
    """The draws of one primitive in a ``partial_fit``: a fine-tuned (``warm``) network's
    from ``SeedSequence(random_state, spawn_key=(primitive, update))``, a new one's as
    :meth:`MotionGenerators.fit` draws them."""
    if warm:
        seq = np.random.SeedSequence(random_state, spawn_key=(primitive, int(update)))
        return np.random.default_rng(seq)
    return primitive_rng(random_state, primitive)


def grow(arr: NDArray[Any], n: int, fill: Any) -> NDArray[Any]:
    """``arr`` with rows appended up to ``n``, each ``fill`` (a grown stack of primitives)."""
    out = np.full((n, *arr.shape[1:]), fill, dtype=arr.dtype)
    out[: arr.shape[0]] = arr
    return out


def check_update_inputs(
    model: Any,
    X: ArrayLike,
    Y: ArrayLike,
    primitives: ArrayLike | None,
    n_primitives: int | None,
    groups: ArrayLike | None,
    update: Any,
) -> tuple[FloatArray, FloatArray, NDArray[np.int64], int, NDArray[Any] | None]:
    """``partial_fit``'s checked inputs for fitted generators ``model`` of either kind, with
    the number of primitives after the update (at least the fitted ``n_primitives_``)."""
    _check_int("update", update, 1)
    if primitives is None:
        raise ConfigError("partial_fit needs the primitive of every row")
    x, y, prim, n_prim, group = _check_fit_inputs(X, Y, primitives, n_primitives, groups)
    if x.shape[1] != model.n_features_in_ or y.shape[1] != model.n_outputs_:
        raise ConfigError(
            f"X and Y have {x.shape[1]} features and {y.shape[1]} outputs, the generators "
            f"{model.n_features_in_} and {model.n_outputs_}"
        )
    old_n = int(model.n_primitives_)
    if n_primitives is not None and n_prim < old_n:
        raise ConfigError(f"n_primitives={n_prim} is fewer than the fitted {old_n}")
    return x, y, prim, max(n_prim, old_n), group


def init_weights(rng: np.random.Generator, sizes: tuple[int, ...], init_range: float) -> FloatArray:
    """One network's flat weights, uniform in ``[-init_range, init_range]`` (thesis §6.2)."""
    return rng.uniform(-init_range, init_range, n_params(sizes))


def split_rows(
    rows: NDArray[np.intp],
    group: NDArray[Any] | None,
    rng: np.random.Generator,
    test_fraction: float,
    min_split_samples: int,
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Training and test rows of one primitive (no test rows for tiny primitives).

    ``round(test_fraction * n)`` rows (at least 1, at most ``n - 1``) go to the
    test split, drawn at random; with ``group`` labels and at least two groups,
    whole groups are drawn instead until that many rows are held out (one group
    always stays for training).
    """
    n = rows.size
    if n < min_split_samples or test_fraction == 0.0:
        return rows, rows[:0]
    n_test = min(n - 1, max(1, round(test_fraction * n)))
    if group is not None:
        labels = np.unique(group[rows])
        if labels.size >= 2:
            chosen: list[Any] = []
            taken = 0
            for label in rng.permutation(labels)[:-1]:  # leave one group for training
                if taken >= n_test:
                    break
                chosen.append(label)
                taken += int(np.count_nonzero(group[rows] == label))
            is_test = np.isin(group[rows], np.array(chosen))
            return rows[~is_test], rows[is_test]
    perm = rng.permutation(n)
    return np.sort(rows[perm[n_test:]]), np.sort(rows[perm[:n_test]])


def _check_int(name: str, value: Any, low: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
        raise ConfigError(f"{name} must be an integer >= {low}, got {value!r}")


def _check_float(
    name: str,
    value: Any,
    low: float,
    high: float | None,
    *,
    low_open: bool = False,
    high_open: bool = False,
) -> None:
    ok = isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)
    if ok:
        v = float(value)
        ok = np.isfinite(v) and (v > low if low_open else v >= low)
        if ok and high is not None:
            ok = v < high if high_open else v <= high
    if not ok:
        lo = "(" if low_open else "["
        hi = ")" if high_open else "]"
        rng = f"{lo}{low}, {high if high is not None else 'inf'}{hi}"
        raise ConfigError(f"{name} must be a number in {rng}, got {value!r}")


def _hidden_tuple(hidden: Any, n_features: int, window: int) -> tuple[int, ...]:
    if hidden is None:
        return (HIDDEN_PER_CHANNEL * max(1, n_features // window),)
    if isinstance(hidden, int | np.integer) and not isinstance(hidden, bool):
        layers: tuple[Any, ...] = (hidden,)
    elif isinstance(hidden, tuple | list):
        layers = tuple(hidden)
    else:
        raise ConfigError(f"hidden must be None, an int or a tuple of ints, got {hidden!r}")
    for units in layers:
        if isinstance(units, bool) or not isinstance(units, int | np.integer) or units < 1:
            raise ConfigError(f"hidden layer sizes must be positive integers, got {hidden!r}")
    return tuple(int(u) for u in layers)


def _as_float_matrix(value: ArrayLike, name: str) -> FloatArray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{name} must be numeric: {exc}") from None
    if arr.ndim != 2:
        raise ConfigError(f"{name} must be 2-D (n, features), got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ConfigError(f"{name} contains NaN or infinite values")
    return arr


def _as_index(value: Any) -> int:
    if not (isinstance(value, int | np.integer) or np.asarray(value).dtype.kind in "iu"):
        raise ConfigError(f"primitive must be an integer, got {value!r}")
    return int(value)


def _check_fit_inputs(
    X: ArrayLike,
    Y: ArrayLike,
    primitives: ArrayLike | None,
    n_primitives: int | None,
    groups: ArrayLike | None,
) -> tuple[FloatArray, FloatArray, NDArray[np.int64], int, NDArray[Any] | None]:
    x = _as_float_matrix(X, "X")
    y = _as_float_matrix(Y, "Y")
    n = x.shape[0]
    if n == 0:
        raise ConfigError("X has no rows; at least one sample is needed")
    if x.shape[1] == 0 or y.shape[1] == 0:
        raise ConfigError("X and Y need at least one column each")
    if y.shape[0] != n:
        raise ConfigError(f"X has {n} rows but Y has {y.shape[0]}")
    if np.abs(y).max() > 1.0:
        raise ConfigError("Y must be normalized commands in [-1, 1] (tanh outputs)")
    if primitives is None:
        prim = np.zeros(n, dtype=np.int64)
    else:
        raw = np.asarray(primitives)
        if raw.shape != (n,) or raw.dtype.kind not in "iu":
            raise ConfigError(f"primitives must be {n} integers, one per row of X")
        prim = raw.astype(np.int64)
        if prim.min() < 0:
            raise ConfigError("primitive ids must be non-negative")
    highest = int(prim.max()) + 1
    if n_primitives is None:
        n_prim = highest
    else:
        _check_int("n_primitives", n_primitives, 1)
        n_prim = int(n_primitives)
        if highest > n_prim:
            raise ConfigError(f"primitive id {highest - 1} >= n_primitives={n_prim}")
    group = None
    if groups is not None:
        group = np.asarray(groups)
        if group.shape != (n,):
            raise ConfigError(f"groups must have one label per row of X ({n})")
    return x, y, prim, n_prim, group


def _pad(
    index_lists: list[NDArray[np.intp]], x: FloatArray, y: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Stack per-primitive rows into zero-padded (P, max_rows, .) arrays."""
    width = max((len(rows) for rows in index_lists), default=0)
    xs = np.zeros((len(index_lists), width, x.shape[1]))
    ys = np.zeros((len(index_lists), width, y.shape[1]))
    for p, rows in enumerate(index_lists):
        xs[p, : len(rows)] = x[rows]
        ys[p, : len(rows)] = y[rows]
    return xs, ys


#: The per-primitive bookkeeping arrays both generator kinds save beside their weights.
BOOKKEEPING: tuple[str, ...] = (
    "trained",
    "n_train",
    "n_test",
    "best_epoch",
    "train_error",
    "test_error",
)


def array_getter(
    arrays: Mapping[str, Any], weights: set[str], label: str
) -> Callable[[str, str, int], NDArray[Any]]:
    """Check that ``arrays`` holds exactly ``weights`` and :data:`BOOKKEEPING`; return a
    getter ``get(name, kinds, ndim)`` that checks one array's dtype kind and rank."""
    if not isinstance(arrays, Mapping):
        raise ModelFileError(f"{label} arrays must be a mapping of name to array")
    expected = weights | set(BOOKKEEPING)
    missing = sorted(expected - set(arrays))
    extra = sorted(str(k) for k in set(arrays) - expected)
    if missing:
        raise ModelFileError(f"{label} arrays lack {', '.join(missing)}")
    if extra:
        raise ModelFileError(f"unexpected {label} arrays: {', '.join(extra)}")

    def get(name: str, kinds: str, ndim: int) -> NDArray[Any]:
        value = arrays[name]
        if not isinstance(value, np.ndarray) or value.dtype.kind not in kinds:
            raise ModelFileError(f"'{name}' must be a numeric array of kind {kinds!r}")
        if value.ndim != ndim:
            raise ModelFileError(f"'{name}' must be {ndim}-D, got shape {value.shape}")
        return value

    return get


def set_bookkeeping(
    model: Any, get: Callable[[str, str, int], NDArray[Any]], n_prim: int, epochs: int
) -> None:
    """Check the :data:`BOOKKEEPING` arrays of ``n_prim`` primitives trained ``epochs``
    epochs and set them on ``model`` (``trained_``, ``n_train_``, ...)."""
    trained = get("trained", "b", 1)
    counts = {name: get(name, "iu", 1).astype(np.int64) for name in ("n_train", "n_test")}
    best_epoch = get("best_epoch", "iu", 1).astype(np.int64)
    curves = {name: get(name, "f", 2).astype(np.float64) for name in ("train_error", "test_error")}
    for name, value in [("trained", trained), *counts.items(), ("best_epoch", best_epoch)]:
        if value.shape != (n_prim,):
            raise ModelFileError(f"'{name}' must have shape ({n_prim},), got {value.shape}")
    for name, curve in curves.items():
        if curve.shape != (n_prim, epochs):
            raise ModelFileError(
                f"'{name}' must have shape ({n_prim}, {epochs}), got {curve.shape}"
            )
        if np.isinf(curve).any() or (curve < 0).any():
            raise ModelFileError(f"'{name}' holds negative or infinite errors")
    if (counts["n_train"] < 0).any() or (counts["n_test"] < 0).any():
        raise ModelFileError("sample counts must be non-negative")
    if not np.array_equal(trained, counts["n_train"] > 0):
        raise ModelFileError("'trained' disagrees with 'n_train'")
    if ((best_epoch < -1) | (best_epoch >= epochs)).any():
        raise ModelFileError("'best_epoch' out of range")
    model.trained_ = trained.astype(bool)
    model.n_train_ = counts["n_train"]
    model.n_test_ = counts["n_test"]
    model.best_epoch_ = best_epoch
    model.train_error_ = curves["train_error"]
    model.test_error_ = curves["test_error"]


def _load_arrays(model: MotionGenerators, arrays: Mapping[str, Any]) -> None:
    """Validate ``arrays`` (from :meth:`MotionGenerators.to_arrays`) into ``model``."""
    n_layers = 0
    while isinstance(arrays, Mapping) and f"coef_{n_layers}" in arrays:
        n_layers += 1
    if isinstance(arrays, Mapping) and n_layers == 0:
        raise ModelFileError("motion generator arrays have no 'coef_0'")
    weights = {f"coef_{i}" for i in range(n_layers)} | {f"intercept_{i}" for i in range(n_layers)}
    get = array_getter(arrays, weights, "motion generator")
    coefs = [get(f"coef_{i}", "f", 3).astype(np.float64) for i in range(n_layers)]
    intercepts = [get(f"intercept_{i}", "f", 2).astype(np.float64) for i in range(n_layers)]
    n_prim = coefs[0].shape[0]
    if n_prim < 1:
        raise ModelFileError("motion generator arrays hold no primitive")
    for i, (w, b) in enumerate(zip(coefs, intercepts, strict=True)):
        if w.shape[0] != n_prim or b.shape != (n_prim, w.shape[2]) or 0 in w.shape:
            raise ModelFileError(f"layer {i} weights/biases have inconsistent shapes")
        if i > 0 and w.shape[1] != coefs[i - 1].shape[2]:
            raise ModelFileError(f"layer {i} input size does not match layer {i - 1} output")
        if not (np.isfinite(w).all() and np.isfinite(b).all()):
            raise ModelFileError(f"layer {i} weights are not finite")
    set_bookkeeping(model, get, n_prim, model.epochs)
    hidden = tuple(int(w.shape[2]) for w in coefs[:-1])
    if hidden != _hidden_tuple(model.hidden, coefs[0].shape[1], model.window):
        raise ModelFileError(f"hidden layer sizes {hidden} disagree with the parameters")

    model.coefs_ = [np.ascontiguousarray(w) for w in coefs]
    model.intercepts_ = [np.ascontiguousarray(b) for b in intercepts]
    model._set_shapes()
