"""Adam in the stacked trainer: bias correction, speed, early stopping, determinism."""

from __future__ import annotations

import io

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from behavior_hmm.errors import ConfigError, NotFittedError
from behavior_hmm.generators import MotionGenerators
from behavior_hmm.generators._mlp import (
    backward,
    forward,
    layer_views,
    n_params,
    train_stack,
    with_ones,
)
from behavior_hmm.generators._motion import AdamGenerators


def _ill_conditioned(seed: int, n: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """A smooth map whose inputs differ 20-fold in scale: slow for plain gradient descent."""
    rng = np.random.default_rng(seed)
    scale = np.array([1, 1, 0.1, 0.1, 0.05, 0.05])
    x = rng.uniform(-1, 1, (n, 6)) * scale
    a = rng.normal(0, 1, (6, 2)) / scale[:, None]
    return x, 0.8 * np.tanh(x @ a)


def _stack_args(rng: np.random.Generator, sizes: tuple[int, ...], n: list[int], n_test: list[int]):
    width, test_width = max(n), max(max(n_test), 1)
    x = rng.uniform(-1, 1, (len(n), width, sizes[0]))
    xt = rng.uniform(-1, 1, (len(n), test_width, sizes[0]))
    y = np.tanh(x[:, :, : sizes[-1]] * 0.7)
    yt = np.tanh(xt[:, :, : sizes[-1]] * 0.7)
    theta0 = rng.uniform(-1, 1, (len(n), n_params(sizes)))
    return theta0, x, y, np.array(n), xt, yt, np.array(n_test)


def test_first_adam_step_is_the_bias_corrected_sign_step(rng: np.random.Generator) -> None:
    # After one step m_hat = g and v_hat = g^2 exactly, so every weight moves by
    # -lr * g / (|g| + eps): about lr, whatever the gradient's size.
    sizes = (3, 4, 2)
    theta0, x, y, n, xt, yt, n_test = _stack_args(rng, sizes, [8], [0])
    lr, eps = 0.01, 1e-8
    result = train_stack(
        theta0, sizes, x, y, n, xt, yt, n_test,
        learning_rate=np.array([lr]), momentum=np.zeros(1), epochs=1, batch_size=8,
        rngs=[np.random.default_rng(0)], early_stopping=False, patience=None,
        optimizer="adam", epsilon=eps,
    )  # fmt: skip
    # The mean gradient of the whole (single) batch: the order does not matter.
    grad = np.zeros_like(theta0)
    weights = layer_views(theta0.copy(), sizes)
    x1 = with_ones(x)
    backward(weights, forward(weights, x1), y, np.full((1, 8, 1), 1 / 8), layer_views(grad, sizes))
    np.testing.assert_allclose(result.theta - theta0, -lr * grad / (np.abs(grad) + eps), atol=1e-15)


def test_adam_beats_plain_gradient_descent_at_equal_epochs() -> None:
    for seed in range(2):
        x, y = _ill_conditioned(seed)
        common = dict(hidden=16, epochs=30, batch_size=16, init_range=0.5, random_state=seed)
        adam = AdamGenerators(learning_rate=0.01, **common).fit(x, y)
        # plain SGD (no momentum) at its best of four learning rates
        sgd = min(
            MotionGenerators(momentum=0.0, learning_rate=lr, **common).fit(x, y).train_error_[0, -1]
            for lr in (0.003, 0.01, 0.03, 0.1)
        )
        assert adam.train_error_[0, -1] < 0.5 * sgd
        assert adam.train_error_[0, -1] < 0.2 * adam.train_error_[0, 0]


def test_early_stopping_restores_the_best_held_out_weights() -> None:
    # Few noisy samples and a big network: the held-out error turns up as it overfits.
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, (50, 4))
    y = np.clip(0.5 * np.tanh(x[:, :2]) + rng.normal(0, 0.3, (50, 2)), -1, 1)
    params = dict(
        hidden=(64, 64), learning_rate=0.01, epochs=80, batch_size=8, init_range=0.3, random_state=3
    )
    stopped = AdamGenerators(**params).fit(x, y)
    curve = stopped.test_error_[0]
    best = int(stopped.best_epoch_[0])
    assert best == int(np.nanargmin(curve))
    assert curve[-1] > 1.2 * curve[best]  # validation loss really rose
    # The kept weights are those after epoch `best`: a replay that stops there.
    replay = AdamGenerators(**{**params, "epochs": best + 1, "early_stopping": False}).fit(x, y)
    for kept, again in zip(stopped.coefs_, replay.coefs_, strict=True):
        np.testing.assert_array_equal(kept, again)
    last = AdamGenerators(**{**params, "early_stopping": False}).fit(x, y)
    assert not np.array_equal(last.coefs_[0], stopped.coefs_[0])
    np.testing.assert_array_equal(last.test_error_, stopped.test_error_)
    # Patience stops 5 epochs after the best one so far, and keeps that epoch's weights.
    patient = AdamGenerators(**{**params, "patience": 5}).fit(x, y)
    ran = int(np.isfinite(patient.test_error_[0]).sum())
    np.testing.assert_array_equal(patient.test_error_[0, :ran], curve[:ran])
    kept = int(patient.best_epoch_[0])
    assert kept == int(np.argmin(curve[:ran])) and ran == kept + 6 < 80
    replay = AdamGenerators(**{**params, "epochs": kept + 1, "early_stopping": False}).fit(x, y)
    np.testing.assert_array_equal(patient.coefs_[0], replay.coefs_[0])


def test_same_seed_same_weights_other_seed_other_weights() -> None:
    x, y = _ill_conditioned(0, 120)
    params = dict(hidden=(8, 8), epochs=5, batch_size=16)
    a = AdamGenerators(random_state=4, **params).fit(x, y)
    b = AdamGenerators(random_state=4, **params).fit(x, y)
    c = AdamGenerators(random_state=5, **params).fit(x, y)
    for wa, wb in zip(a.coefs_ + a.intercepts_, b.coefs_ + b.intercepts_, strict=True):
        assert wa.tobytes() == wb.tobytes()
    assert not np.array_equal(a.coefs_[0], c.coefs_[0])


def test_adam_stack_slot_equals_slot_alone(rng: np.random.Generator) -> None:
    # Slots of different sizes sit out steps: their Adam moments and step counts
    # must stay frozen meanwhile, as if each slot trained alone.
    sizes = (4, 3, 2)
    theta0, x, y, n, xt, yt, n_test = _stack_args(rng, sizes, [37, 5, 0, 60], [9, 0, 0, 15])
    lr = np.array([0.01, 0.05, 0.01, 0.02])
    common = dict(
        epochs=4, batch_size=8, early_stopping=True, patience=None, optimizer="adam", beta1=0.8
    )
    stacked = train_stack(
        theta0, sizes, x, y, n, xt, yt, n_test, learning_rate=lr, momentum=np.zeros(4),
        rngs=[np.random.default_rng(s) for s in range(4)], **common,
    )  # fmt: skip
    for p in (0, 1, 3):
        alone = train_stack(
            theta0[p : p + 1], sizes, x[p : p + 1, : n[p]], y[p : p + 1, : n[p]], n[p : p + 1],
            xt[p : p + 1, : n_test[p]], yt[p : p + 1, : n_test[p]], n_test[p : p + 1],
            learning_rate=lr[p : p + 1], momentum=np.zeros(1),
            rngs=[np.random.default_rng(p)], **common,
        )  # fmt: skip
        np.testing.assert_allclose(alone.theta[0], stacked.theta[p], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(stacked.theta[2], theta0[2])


def test_sgd_stays_the_default(rng: np.random.Generator) -> None:
    sizes = (4, 5, 2)
    theta0, x, y, n, xt, yt, n_test = _stack_args(rng, sizes, [30, 12], [6, 0])
    common = dict(
        learning_rate=np.array([0.01, 0.02]), momentum=np.array([0.4, 0.4]), epochs=3,
        batch_size=4, early_stopping=True, patience=None,
    )  # fmt: skip
    implicit = train_stack(
        theta0, sizes, x, y, n, xt, yt, n_test,
        rngs=[np.random.default_rng(s) for s in range(2)], **common,
    )  # fmt: skip
    explicit = train_stack(
        theta0, sizes, x, y, n, xt, yt, n_test,
        rngs=[np.random.default_rng(s) for s in range(2)], optimizer="sgd", **common,
    )  # fmt: skip
    assert implicit.theta.tobytes() == explicit.theta.tobytes()
    with pytest.raises(ValueError, match="optimizer"):
        train_stack(
            theta0, sizes, x, y, n, xt, yt, n_test,
            rngs=[np.random.default_rng(s) for s in range(2)], optimizer="rmsprop", **common,
        )  # fmt: skip
    assert "momentum" in MotionGenerators().get_params()
    assert "beta1" not in MotionGenerators().get_params()


def test_adam_generators_params_validation_and_arrays() -> None:
    model = AdamGenerators(hidden=(5, 5), beta2=0.99)
    params = model.get_params()
    assert "momentum" not in params
    assert (params["learning_rate"], params["beta1"], params["epsilon"]) == (1e-3, 0.9, 1e-8)
    assert repr(model) == "AdamGenerators(hidden=(5, 5), beta2=0.99)"
    assert AdamGenerators(**params).get_params() == params
    with pytest.raises(NotFittedError, match="AdamGenerators is not fitted"):
        model.predict_one(np.zeros(10), 0)
    x, y = _ill_conditioned(1, 60)
    for bad in ({"beta1": 1.0}, {"beta2": -0.1}, {"epsilon": 0.0}, {"learning_rate": 0.0}):
        with pytest.raises(ConfigError, match=next(iter(bad))):
            AdamGenerators(**bad).fit(x, y)
    fitted = AdamGenerators(hidden=(4, 3), epochs=3).fit(x, y)
    buffer = io.BytesIO()
    np.savez(buffer, **fitted.to_arrays())
    buffer.seek(0)
    with np.load(buffer, allow_pickle=False) as npz:
        loaded = AdamGenerators.from_arrays(dict(npz), **fitted.get_params())
    assert isinstance(loaded, AdamGenerators)
    np.testing.assert_array_equal(loaded.predict(x), fitted.predict(x))


def test_the_blas_thread_count_does_not_change_the_weights() -> None:
    # bc-strong's size: 2 x 64 hidden, batches of 128. A multi-threaded BLAS divides its
    # gradient matmul (65 x 128 @ 128 x 64) between threads, which changes the last
    # bits; a worker process or Ray task (one thread) must train what this process does.
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, (600, 24))
    y = np.tanh(x[:, :2] + 0.5 * x[:, 2:4])
    params = dict(hidden=(64, 64), epochs=3, batch_size=128, random_state=0)
    weights = []
    for threads in (1, 2):
        with threadpool_limits(limits=threads, user_api="blas"):
            net = AdamGenerators(**params).fit(x, y)
        weights.append(b"".join(w.tobytes() for w in net.coefs_ + net.intercepts_))
    assert weights[0] == weights[1]
