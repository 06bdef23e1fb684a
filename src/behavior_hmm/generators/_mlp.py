"""Stacked tanh networks: many small multilayer perceptrons trained in lock-step.

Every network ("slot") in a stack has the same layer sizes. All parameters of
slot ``p`` live in one row ``theta[p]`` of a ``(P, n_params)`` array, laid out
layer by layer as bias-augmented matrices ``(n_in + 1, n_out)`` (row-major, the
last row is the bias). :func:`layer_views` returns ``(P, n_in + 1, n_out)``
views into it, so the momentum update is a few numpy calls on one array
whatever the depth, and a bias costs no separate add or reduction: inputs and
hidden activations carry a trailing column of ones.

The error of a batch is the thesis's ``E = 1/2 * sum (t - o)^2`` summed over
the batch's samples (thesis §3.4.2.1); the update is the generalized delta
rule with momentum, ``dw(n) = -lr * dE/dw + momentum * dw(n-1)``. With one
sample per step this is exactly the thesis's incremental training.

``optimizer="adam"`` trains with Adam instead (Kingma & Ba 2015): the gradient
of a batch is the *mean* over its samples, ``m`` and ``v`` are exponential
averages of it and of its square (``beta1``, ``beta2``), and each step moves
the weights by ``-lr * m_hat / (sqrt(v_hat) + epsilon)`` with the bias-corrected
``m_hat = m / (1 - beta1^t)``, ``v_hat = v / (1 - beta2^t)``, ``t`` counting the
slot's own steps. Stochastic gradient descent with momentum stays the default.

Slots never interact: the arithmetic of a slot only reads that slot's rows, and
a slot with no sample in a step (``active`` false) keeps its weights and its
momentum (or its Adam moments and step count) unchanged, so training a slot
inside a stack gives the same weights as training it alone (tested).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def n_params(sizes: Sequence[int]) -> int:
    """Number of weights and biases of a network with layer ``sizes`` (inputs first)."""
    return sum((sizes[i] + 1) * sizes[i + 1] for i in range(len(sizes) - 1))


def layer_views(theta: FloatArray, sizes: Sequence[int]) -> list[FloatArray]:
    """Views ``W_l (P, n_l + 1, n_{l+1})`` into ``theta (P, n_params)``; row ``n_l`` is the bias."""
    weights: list[FloatArray] = []
    start = 0
    n_slots = theta.shape[0]
    for n_in, n_out in itertools.pairwise(sizes):
        stop = start + (n_in + 1) * n_out
        weights.append(theta[:, start:stop].reshape(n_slots, n_in + 1, n_out))
        start = stop
    return weights


def with_ones(x: FloatArray) -> FloatArray:
    """``x (..., n)`` with a column of ones appended (the bias input)."""
    out = np.ones((*x.shape[:-1], x.shape[-1] + 1))
    out[..., :-1] = x
    return out


def activation_buffers(weights: list[FloatArray], n_slots: int, batch: int) -> list[FloatArray]:
    """Arrays for :func:`forward`'s hidden activations (ones column set) and output."""
    last = len(weights) - 1
    return [
        np.ones((n_slots, batch, w.shape[2] + 1))
        if layer < last
        else np.empty((n_slots, batch, w.shape[2]))
        for layer, w in enumerate(weights)
    ]


def forward(
    weights: list[FloatArray], x1: FloatArray, buffers: list[FloatArray] | None = None
) -> list[FloatArray]:
    """Activations ``[x1, h_1, ..., out]`` for bias-augmented inputs ``x1 (P, B, n_in + 1)``.

    Hidden activations carry the trailing ones column too; the output does not.
    ``buffers`` (from :func:`activation_buffers` for the same shapes) receive the
    activations instead of new arrays: the trainer reuses them every step.
    """
    if buffers is None:
        buffers = activation_buffers(weights, x1.shape[0], x1.shape[1])
    a = x1
    last = len(weights) - 1
    for layer, (w, a_next) in enumerate(zip(weights, buffers, strict=True)):
        z = a_next[:, :, :-1] if layer < last else a_next
        np.matmul(a, w, out=z)
        np.tanh(z, out=z)
        a = a_next
    return [x1, *buffers]


@dataclass
class _BackwardBuffers:
    """Arrays :func:`backward` writes into, reused by the trainer every step."""

    error: FloatArray  # (P, B, n_out)
    deltas: list[FloatArray]  # error signal of each layer's output, (P, B, n_{l+1})
    slopes: list[FloatArray]  # 1 - h^2 of each hidden layer, (P, B, n_l)
    transposed: list[FloatArray]  # W_l^T without its bias row, contiguous, (P, n_{l+1}, n_l)

    @classmethod
    def for_weights(cls, weights: list[FloatArray], n_slots: int, batch: int) -> _BackwardBuffers:
        sizes = [w.shape[2] for w in weights]
        return cls(
            error=np.empty((n_slots, batch, sizes[-1])),
            deltas=[np.empty((n_slots, batch, n)) for n in sizes],
            slopes=[np.empty((n_slots, batch, n)) for n in sizes[:-1]],
            transposed=[np.empty((n_slots, w.shape[2], w.shape[1] - 1)) for w in weights],
        )


def backward(
    weights: list[FloatArray],
    activations: list[FloatArray],
    y: FloatArray,
    sample_weight: FloatArray,
    grad_weights: list[FloatArray],
    buffers: _BackwardBuffers | None = None,
) -> FloatArray:
    """Write the gradient of ``E = 1/2 sum_b sample_weight[b] * |out_b - y_b|^2``.

    ``y (P, B, n_out)`` are targets and ``sample_weight (P, B, 1)`` weighs each
    sample (0 for padding; the trainer passes the learning rate there, so the
    "gradient" comes out already scaled). Results go into the ``grad_weights``
    views, bias rows included; the gradient is summed over the batch. ``buffers``
    hold the intermediate arrays (new ones when ``None``); the arithmetic is the same.

    Returns
    -------
    ndarray, shape (P, B, n_out)
        The unweighted output error ``out - y`` (in ``buffers.error`` when given).
    """
    if buffers is None:
        buffers = _BackwardBuffers.for_weights(weights, y.shape[0], y.shape[1])
    out = activations[-1]
    error = np.subtract(out, y, out=buffers.error)
    # Output error signal (thesis delta rule): (o - t) * f'(net), f' = 1 - tanh^2.
    delta = np.multiply(out, out, out=buffers.deltas[-1])
    np.subtract(1.0, delta, out=delta)
    delta *= error
    delta *= sample_weight
    for layer in range(len(weights) - 1, -1, -1):
        a_in = activations[layer]
        np.matmul(a_in.transpose(0, 2, 1), delta, out=grad_weights[layer])
        if layer > 0:
            hidden = a_in[:, :, :-1]
            # A contiguous copy of W^T makes the batched matmul take the fast path.
            w_t = buffers.transposed[layer]
            np.copyto(w_t, weights[layer][:, :-1, :].transpose(0, 2, 1))
            delta = np.matmul(delta, w_t, out=buffers.deltas[layer - 1])
            slope = np.multiply(hidden, hidden, out=buffers.slopes[layer - 1])
            np.subtract(1.0, slope, out=slope)
            delta *= slope
    return error


def rms_error(
    weights: list[FloatArray],
    x1: FloatArray,
    y: FloatArray,
    counts: NDArray[np.int64],
) -> FloatArray:
    """RMS error per slot over its first ``counts[p]`` rows; NaN where ``counts[p] == 0``."""
    n_slots, n_rows = x1.shape[0], x1.shape[1]
    result = np.full(n_slots, np.nan)
    if n_rows == 0:
        return result
    out = forward(weights, x1)[-1]
    sq = (out - y) ** 2
    # Sum each slot over its own rows only, so padding never changes the rounding.
    for p in np.flatnonzero(counts > 0).tolist():
        count = int(counts[p])
        result[p] = np.sqrt(sq[p, :count].sum() / (count * y.shape[2]))
    return result


@dataclass
class TrainResult:
    """Outcome of :func:`train_stack`.

    ``theta`` (P, n_params) are the kept weights (the best-test-error epoch's
    where early stopping applied); ``train_error``/``test_error`` (P, epochs)
    are RMS errors after each epoch (NaN where a slot did not train that epoch
    or has no test split); ``best_epoch`` (P,) is the 0-based epoch whose
    weights were kept (-1 for slots that never trained); ``epochs_run`` (P,)
    counts the epochs each slot trained.
    """

    theta: FloatArray
    train_error: FloatArray
    test_error: FloatArray
    best_epoch: NDArray[np.int64]
    epochs_run: NDArray[np.int64]


def train_stack(
    theta0: FloatArray,
    sizes: Sequence[int],
    x_train: FloatArray,
    y_train: FloatArray,
    n_train: NDArray[np.int64],
    x_test: FloatArray,
    y_test: FloatArray,
    n_test: NDArray[np.int64],
    *,
    learning_rate: FloatArray,
    momentum: FloatArray,
    epochs: int,
    batch_size: int,
    rngs: Sequence[np.random.Generator],
    early_stopping: bool,
    patience: int | None,
    optimizer: str = "sgd",
    beta1: float = 0.9,
    beta2: float = 0.999,
    epsilon: float = 1e-8,
) -> TrainResult:
    """Train every slot of a stack with minibatch backpropagation (momentum or Adam).

    Parameters
    ----------
    theta0
        Initial weights, shape (P, n_params); not modified.
    sizes
        Layer sizes ``(n_in, hidden..., n_out)``.
    x_train, y_train
        Padded training data, shapes (P, N, n_in) and (P, N, n_out); slot ``p``
        uses its first ``n_train[p]`` rows. Slots with ``n_train[p] == 0`` never train.
    x_test, y_test, n_test
        Padded test data the same way (``n_test[p] == 0``: no test split).
    learning_rate, momentum
        Per-slot values, shape (P,). With SGD the learning rate multiplies the
        *summed* gradient of a batch (a per-sample rate, as the thesis's
        incremental rule); with Adam it is the step size and ``momentum`` is unused.
    epochs, batch_size
        Each epoch every slot visits each of its training samples once, in an
        order drawn from its own generator ``rngs[p]``, ``batch_size`` at a
        time. Slots run in lock-step; a slot that has finished its epoch sits
        out the remaining steps with its weights and momentum frozen.
    early_stopping
        Keep, per slot with a test split, the weights of its lowest-test-error epoch.
    patience
        If set, a slot with a test split stops after this many epochs without a
        new lowest test error.
    optimizer
        ``"sgd"`` (minibatch gradient descent with momentum, the thesis's rule) or
        ``"adam"`` (bias-corrected Adam on the batch's mean gradient).
    beta1, beta2, epsilon
        Adam's decay rates of the first and second moment and the constant added
        to the denominator (ignored by SGD).
    """
    if optimizer not in ("sgd", "adam"):
        raise ValueError(f"optimizer must be 'sgd' or 'adam', got {optimizer!r}")
    from threadpoolctl import threadpool_limits

    # Work on the slots sorted by training-set size, largest first (see the step loop).
    order = np.argsort(-n_train, kind="stable")
    # One BLAS thread while training: how OpenBLAS divides a large matmul between its
    # threads changes the last bits of the result (measured: the 2 x 64 bc-strong
    # network's gradient, 65 x 128 @ 128 x 64, differs between 1 and 2 threads). The
    # same seed must give the same weights in this process, in a worker process and in
    # a Ray task, whatever their thread counts. Entering the limit costs about 0.4 ms.
    with threadpool_limits(limits=1, user_api="blas"):
        result = _train_sorted(
            theta0[order],
            sizes,
            x_train[order],
            y_train[order],
            n_train[order],
            x_test[order],
            y_test[order],
            n_test[order],
            learning_rate=np.asarray(learning_rate, dtype=np.float64)[order],
            momentum=np.asarray(momentum, dtype=np.float64)[order],
            epochs=epochs,
            batch_size=batch_size,
            rngs=[rngs[p] for p in order.tolist()],
            early_stopping=early_stopping,
            patience=patience,
            adam=(float(beta1), float(beta2), float(epsilon)) if optimizer == "adam" else None,
        )
    back = np.argsort(order)
    return TrainResult(
        result.theta[back],
        result.train_error[back],
        result.test_error[back],
        result.best_epoch[back],
        result.epochs_run[back],
    )


class _PrefixViews:
    """Views of the first ``k`` slots of the training state (reused across steps)."""

    def __init__(
        self,
        theta: FloatArray,
        velocity: FloatArray,
        grad: FloatArray,
        squared: FloatArray,
        second: FloatArray,
        sizes: Sequence[int],
        k: int,
    ) -> None:
        self.theta = theta[:k]
        self.velocity = velocity[:k]
        self.grad = grad[:k]
        self.squared = squared[:k]
        self.second = second[:k]
        self.weights = layer_views(self.theta, sizes)
        self.grad_weights = layer_views(self.grad, sizes)
        batch = squared.shape[1]
        self.activations = activation_buffers(self.weights, k, batch)
        self.backward = _BackwardBuffers.for_weights(self.weights, k, batch)


def _train_sorted(
    theta0: FloatArray,
    sizes: Sequence[int],
    x_train: FloatArray,
    y_train: FloatArray,
    n_train: NDArray[np.int64],
    x_test: FloatArray,
    y_test: FloatArray,
    n_test: NDArray[np.int64],
    *,
    learning_rate: FloatArray,
    momentum: FloatArray,
    epochs: int,
    batch_size: int,
    rngs: Sequence[np.random.Generator],
    early_stopping: bool,
    patience: int | None,
    adam: tuple[float, float, float] | None,
) -> TrainResult:
    """:func:`train_stack` on slots sorted by ``n_train``, largest first.

    ``adam``: ``(beta1, beta2, epsilon)`` to train with Adam, ``None`` for SGD with momentum.
    """
    n_slots = theta0.shape[0]
    theta = theta0.copy()
    velocity = np.zeros_like(theta)  # SGD: the last step; Adam: the first moment m
    second = np.zeros_like(theta) if adam is not None else velocity[:, :0]  # Adam's v
    adam_steps = np.zeros(n_slots)  # Adam: steps each slot has taken
    grad = np.zeros_like(theta)
    weights = layer_views(theta, sizes)
    squared = np.zeros((n_slots, batch_size, sizes[-1]))  # epoch's squared errors
    views: dict[int, _PrefixViews] = {}
    x_train = with_ones(x_train)
    x_test = with_ones(x_test)
    n_out = sizes[-1]
    slot_index = np.arange(n_slots)[None, :, None]
    lr_row = np.asarray(learning_rate, dtype=np.float64).reshape(n_slots)
    momentum_row = np.asarray(momentum, dtype=np.float64).reshape(n_slots)

    train_error = np.full((n_slots, epochs), np.nan)
    test_error = np.full((n_slots, epochs), np.nan)
    best_epoch = np.full(n_slots, -1, dtype=np.int64)
    epochs_run = np.zeros(n_slots, dtype=np.int64)
    best_theta = theta.copy()
    best_error = np.full(n_slots, np.inf)
    has_test = n_test > 0
    running = n_train > 0

    for epoch in range(epochs):
        if not running.any():
            break
        # Steps this epoch: enough for the largest still-running slot.
        n_steps = int(np.where(running, -(-n_train // batch_size), 0).max())
        order = np.zeros((n_slots, n_steps * batch_size), dtype=np.int64)
        valid = np.zeros((n_slots, n_steps * batch_size), dtype=bool)
        for p in np.flatnonzero(running).tolist():
            count = int(n_train[p])
            order[p, :count] = rngs[p].permutation(count)
            valid[p, :count] = True
        # Index arrays laid out (steps, P, batch) so each step reads one contiguous block.
        order_steps = order.reshape(n_slots, n_steps, batch_size).transpose(1, 0, 2)
        xs = x_train[slot_index, order_steps]  # (steps, P, batch, n_in + 1)
        ys = y_train[slot_index, order_steps]
        valid_steps = valid.reshape(n_slots, n_steps, batch_size).transpose(1, 0, 2)
        valid_steps = valid_steps[:, :, :, None].astype(np.float64)  # (steps, P, batch, 1)
        if adam is None:
            step_weights = valid_steps * lr_row[None, :, None, None]
        else:
            # Adam reads the batch's mean gradient: weigh each real sample 1 / count.
            counts = valid_steps.sum(axis=2, keepdims=True)
            step_weights = valid_steps / np.maximum(counts, 1.0)
        # (steps, P): the slot has a sample in this step (its first batch entry is real).
        active: NDArray[np.bool_] = valid_steps[:, :, 0, 0] > 0
        # Slots are sorted by size, largest first, so a step only needs the prefix of
        # slots up to its last active one: once the small slots have finished their
        # epoch, the big ones run on alone and cheaply.
        prefix = (n_slots - np.argmax(active[:, ::-1], axis=1)).tolist()
        # whether every slot of the step's prefix is active
        all_active = np.logical_and.accumulate(active, axis=1)[
            np.arange(n_steps), np.asarray(prefix) - 1
        ].tolist()
        # Inactive slots keep their momentum (factor 1) and their weights (step factor 0).
        momentum_steps = np.where(active, momentum_row[None, :], 1.0)[:, :, None]
        apply_steps = active.astype(np.float64)[:, :, None]
        squared[:] = 0.0

        for step in range(n_steps):
            k = prefix[step]
            if k not in views:
                views[k] = _PrefixViews(theta, velocity, grad, squared, second, sizes, k)
            v = views[k]
            activations = forward(v.weights, xs[step, :k], v.activations)
            error = backward(
                v.weights,
                activations,
                ys[step, :k],
                step_weights[step, :k],
                v.grad_weights,
                v.backward,
            )
            error *= error
            error *= valid_steps[step, :k]
            v.squared += error
            if adam is not None:
                _adam_step(v, lr_row[:k], adam_steps[:k], active[step, :k], all_active[step], adam)
            else:
                # Momentum update; grad already holds learning_rate * dE/dW.
                v.velocity *= momentum_steps[step, :k]
                v.velocity -= v.grad
                if all_active[step]:
                    v.theta += v.velocity
                else:
                    v.theta += v.velocity * apply_steps[step, :k]

        epochs_run[running] += 1
        # Training error: over the epoch's samples, each just before its update.
        sums = squared.sum(axis=(1, 2))
        train_error[running, epoch] = np.sqrt(sums[running] / (n_train[running] * n_out))
        test_err = rms_error(weights, x_test, y_test, n_test)
        tracked = running & has_test
        test_error[tracked, epoch] = test_err[tracked]
        improved = tracked & (test_err < best_error)
        best_error[improved] = test_err[improved]
        best_theta[improved] = theta[improved]
        best_epoch[improved] = epoch
        if patience is not None:
            running &= ~(tracked & (epoch - best_epoch >= patience))

    if early_stopping:
        keep = has_test & (best_epoch >= 0)
        theta[keep] = best_theta[keep]
    trained = n_train > 0
    if not early_stopping:
        best_epoch[trained] = epochs_run[trained] - 1
    # Slots without a test split keep their last weights.
    no_test = trained & ~has_test
    best_epoch[no_test] = epochs_run[no_test] - 1
    return TrainResult(theta, train_error, test_error, best_epoch, epochs_run)


def _adam_step(
    v: _PrefixViews,
    learning_rate: FloatArray,
    steps: FloatArray,
    active: NDArray[np.bool_],
    all_active: bool,
    adam: tuple[float, float, float],
) -> None:
    """One Adam update of the slots in ``v`` (``v.grad``: each slot's mean gradient)."""
    adam_update(
        v.theta, v.grad, v.velocity, v.second, steps, learning_rate, active, all_active, adam
    )


def adam_update(
    theta: FloatArray,
    g: FloatArray,
    m: FloatArray,
    s: FloatArray,
    steps: FloatArray,
    learning_rate: FloatArray,
    active: NDArray[np.bool_],
    all_active: bool,
    adam: tuple[float, float, float],
) -> None:
    """One Adam update, in place, of the slots' weights ``theta (P, n)`` by gradients ``g``.

    ``m``, ``s`` are the first and second moments and ``steps`` (P,) each slot's step
    count, advanced in place for the ``active`` slots; inactive slots keep their
    weights, moments and count (``all_active``: every slot is, the fast path).
    """
    beta1, beta2, epsilon = adam
    if all_active:
        steps += 1.0
        m *= beta1
        m += (1.0 - beta1) * g
        s *= beta2
        s += (1.0 - beta2) * (g * g)
        t = steps[:, None]
        update = m / (1.0 - beta1**t)
        update /= np.sqrt(s / (1.0 - beta2**t)) + epsilon
        update *= learning_rate[:, None]
        theta -= update
        return
    on = active.astype(np.float64)[:, None]
    steps += on[:, 0]
    # Inactive slots: decay factor 1 and a zero gradient leave their moments unchanged.
    m *= np.where(on > 0, beta1, 1.0)
    m += ((1.0 - beta1) * on) * g
    s *= np.where(on > 0, beta2, 1.0)
    s += ((1.0 - beta2) * on) * (g * g)
    t = np.maximum(steps, 1.0)[:, None]  # a slot that never stepped has m = v = 0
    update = m / (1.0 - beta1**t)
    update /= np.sqrt(s / (1.0 - beta2**t)) + epsilon
    update *= (learning_rate * on[:, 0])[:, None]
    theta -= update
