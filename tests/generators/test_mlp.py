"""Stacked backpropagation: gradients, layout and slot independence."""

from __future__ import annotations

import numpy as np
import pytest

from behavior_hmm.generators._mlp import (
    backward,
    forward,
    layer_views,
    n_params,
    rms_error,
    train_stack,
    with_ones,
)


def _loss(theta: np.ndarray, sizes: tuple[int, ...], x1, y, weight) -> np.ndarray:
    out = forward(layer_views(theta, sizes), x1)[-1]
    return 0.5 * (weight * (out - y) ** 2).sum(axis=(1, 2))


@pytest.mark.parametrize("sizes", [(3, 4, 2), (3, 4, 3, 2), (3, 2), (6, 5, 1)])
def test_backward_matches_finite_differences(rng: np.random.Generator, sizes) -> None:
    n_slots, batch = 2, 5
    theta = rng.uniform(-1, 1, (n_slots, n_params(sizes)))
    x1 = with_ones(rng.uniform(-1, 1, (n_slots, batch, sizes[0])))
    y = rng.uniform(-0.9, 0.9, (n_slots, batch, sizes[-1]))
    weight = rng.uniform(0, 2, (n_slots, batch, 1))
    weight[1, -2:] = 0.0  # padding rows must not count
    grad = np.zeros_like(theta)
    weights = layer_views(theta, sizes)
    error = backward(weights, forward(weights, x1), y, weight, layer_views(grad, sizes))
    np.testing.assert_allclose(error, forward(weights, x1)[-1] - y)

    eps = 1e-6
    numeric = np.zeros_like(theta)
    for i in range(theta.shape[1]):
        plus, minus = theta.copy(), theta.copy()
        plus[:, i] += eps
        minus[:, i] -= eps
        numeric[:, i] = (_loss(plus, sizes, x1, y, weight) - _loss(minus, sizes, x1, y, weight)) / (
            2 * eps
        )
    np.testing.assert_allclose(grad, numeric, rtol=1e-6, atol=1e-8)


def test_layer_views_cover_theta_once() -> None:
    sizes = (4, 3, 2)
    theta = np.arange(2 * n_params(sizes), dtype=float).reshape(2, -1)
    views = layer_views(theta, sizes)
    assert [v.shape for v in views] == [(2, 5, 3), (2, 4, 2)]
    flat = np.concatenate([v.reshape(2, -1) for v in views], axis=1)
    np.testing.assert_array_equal(flat, theta)
    views[0][1, -1, 0] = -7.0  # a view, not a copy
    assert theta[1, 12] == -7.0


def test_rms_error_ignores_padding_and_empty_slots() -> None:
    sizes = (1, 1)
    theta = np.zeros((3, n_params(sizes)))  # output tanh(0) = 0
    x1 = with_ones(np.zeros((3, 4, 1)))
    y = np.array([0.5, 0.5, 9.0, 9.0])[None, :, None].repeat(3, axis=0)
    err = rms_error(layer_views(theta, sizes), x1, y, np.array([2, 1, 0]))
    np.testing.assert_allclose(err[:2], [0.5, 0.5])
    assert np.isnan(err[2])


def test_stack_slot_equals_slot_alone(rng: np.random.Generator) -> None:
    sizes = (4, 3, 2)
    n = np.array([37, 5, 0, 60])
    width = int(n.max())
    x = rng.uniform(-1, 1, (4, width, 4))
    y = np.tanh(x[:, :, :2] * 0.7)
    theta0 = rng.uniform(-1, 1, (4, n_params(sizes)))
    test_n = np.array([9, 0, 0, 15])
    xt = rng.uniform(-1, 1, (4, 15, 4))
    yt = np.tanh(xt[:, :, :2] * 0.7)
    common = dict(epochs=4, batch_size=8, early_stopping=True, patience=None)
    lr = np.array([0.01, 0.05, 0.01, 0.02])
    mom = np.array([0.4, 0.0, 0.4, 0.8])
    stacked = train_stack(
        theta0, sizes, x, y, n, xt, yt, test_n, learning_rate=lr, momentum=mom,
        rngs=[np.random.default_rng(s) for s in range(4)], **common,
    )  # fmt: skip
    for p in (0, 1, 3):
        alone = train_stack(
            theta0[p : p + 1], sizes, x[p : p + 1, : n[p]], y[p : p + 1, : n[p]], n[p : p + 1],
            xt[p : p + 1, : test_n[p]], yt[p : p + 1, : test_n[p]], test_n[p : p + 1],
            learning_rate=lr[p : p + 1], momentum=mom[p : p + 1],
            rngs=[np.random.default_rng(p)], **common,
        )  # fmt: skip
        np.testing.assert_allclose(alone.theta[0], stacked.theta[p], rtol=0, atol=1e-12)
        np.testing.assert_allclose(alone.test_error[0], stacked.test_error[p], atol=1e-12)
    # The empty slot never moves and has no curve.
    np.testing.assert_array_equal(stacked.theta[2], theta0[2])
    assert np.isnan(stacked.train_error[2]).all()
    assert stacked.best_epoch[2] == -1
