"""Elman generators: BPTT gradients, memory, the closed-loop stepper, arrays, partial_fit."""

from __future__ import annotations

import numpy as np
import pytest

from behavior_hmm.errors import ConfigError, ModelFileError, NotFittedError
from behavior_hmm.generators import GENERATOR_NETWORKS, ElmanGenerators, MotionGenerators
from behavior_hmm.generators._recurrent import _batch_gradient, _shapes, _views, sequence_starts


def _ramps(n_seq: int = 12, length: int = 30) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sequences whose input is constant (a flat window at rest) while the target ramps
    up with the time since the sequence began: only a network with memory can follow."""
    x = np.zeros((n_seq * length, 3))
    t = np.tile(np.arange(length), n_seq)
    y = np.column_stack([0.8 * np.minimum(t / 10.0, 1.0), -0.5 * np.minimum(t / 20.0, 1.0)])
    starts = np.arange(0, n_seq * length, length)
    return x, y, starts


def test_bptt_gradient_matches_finite_differences() -> None:
    rng = np.random.default_rng(0)
    n_slots, batch, steps, n_in, hidden, n_out = 3, 4, 7, 5, 4, 2
    shapes = _shapes(n_in, hidden, n_out)
    theta = rng.normal(0.0, 0.5, (n_slots, sum(r * c for r, c in shapes)))
    x = np.ones((n_slots, batch, steps, n_in + 1))
    x[..., :-1] = rng.normal(size=(n_slots, batch, steps, n_in))
    y = rng.uniform(-1, 1, (n_slots, batch, steps, n_out))
    mask = (rng.uniform(size=(n_slots, batch, steps)) > 0.2).astype(float)

    def loss(th: np.ndarray) -> np.ndarray:
        _, sq, rows = _batch_gradient(_views(th, shapes), x, y, mask)
        return 0.5 * sq / rows

    grads, _, _ = _batch_gradient(_views(theta, shapes), x, y, mask)
    analytic = np.concatenate([g.reshape(n_slots, -1) for g in grads], axis=1)
    numeric = np.zeros_like(theta)
    eps = 1e-6
    for i in range(theta.shape[1]):
        up, down = theta.copy(), theta.copy()
        up[:, i] += eps
        down[:, i] -= eps
        numeric[:, i] = (loss(up) - loss(down)) / (2 * eps)
    assert np.abs(analytic).max() > 1e-2
    np.testing.assert_allclose(analytic, numeric, atol=1e-8)


def test_an_elman_network_follows_a_ramp_a_feed_forward_one_cannot() -> None:
    x, y, starts = _ramps()
    elman = ElmanGenerators(hidden=6, epochs=300, test_fraction=0.0, random_state=0)
    elman.fit(x, y, sequences=starts)
    mlp = MotionGenerators(hidden=6, epochs=300, test_fraction=0.0, random_state=0).fit(x, y)
    elman_rms = np.sqrt(np.mean((elman.predict(x[:30]) - y[:30]) ** 2))
    mlp_rms = np.sqrt(np.mean((mlp.predict(x[:30]) - y[:30]) ** 2))
    assert elman_rms < 0.05 < 0.2 < mlp_rms
    assert elman.train_error_[0, -1] < elman.train_error_[0, 0]


def test_the_stepper_runs_the_network_as_predict_and_replays_on_a_switch() -> None:
    rng = np.random.default_rng(1)
    x = rng.uniform(-1, 1, (80, 4))
    y = np.tanh(np.cumsum(x[:, :2], axis=0) / 10.0)
    prim = np.repeat([0, 1, 0, 1], 20)
    gens = ElmanGenerators(hidden=3, epochs=5, warmup=4, random_state=0).fit(x, y, prim)
    stepper = gens.stepper()
    out = np.array([stepper.step(x[t], int(prim[t])) for t in range(40)])
    # the first primitive runs from an empty context, as predict does
    np.testing.assert_allclose(out[:20], gens.predict(x[:20], 0), rtol=0, atol=1e-12)
    # the second first replays the last 4 rows from an empty context
    replay = gens.predict(x[16:40], 1)[4:]
    np.testing.assert_allclose(out[20:], replay, rtol=0, atol=1e-12)
    stepper.reset()  # a new run: no rows to replay
    np.testing.assert_allclose(stepper.step(x[20], 1), gens.predict(x[20:21], 1)[0], atol=1e-12)
    with pytest.raises(ConfigError, match="row must have shape"):
        stepper.step(np.zeros(5), 1)
    with pytest.raises(ConfigError, match=r"primitive must be an integer in \[0, 2\)"):
        stepper.step(x[0], 2)


def test_sequences_default_to_runs_of_one_primitive_and_one_group() -> None:
    prim = np.array([0, 0, 1, 1, 1, 0, 0])
    groups = np.array([0, 0, 0, 0, 1, 1, 1])
    assert sequence_starts(prim, None).tolist() == [0, 2, 5]
    assert sequence_starts(prim, groups).tolist() == [0, 2, 4, 5]
    x, y = np.zeros((7, 2)), np.zeros((7, 2))
    for bad, message in (
        ([1, 3], "starting at 0"),
        ([0, 3, 3], "increasing"),
        ([0, 1], "more than one primitive"),
        ([[0]], "1-D"),
    ):
        with pytest.raises(ConfigError, match=message):
            ElmanGenerators(epochs=1).fit(x, y, prim, sequences=np.array(bad))


def test_held_out_sequences_keep_the_best_epoch_and_a_seed_gives_the_same_weights() -> None:
    x, y, _ = _ramps(n_seq=10)
    groups = np.repeat(np.arange(10), 30)
    first = ElmanGenerators(hidden=4, epochs=20, random_state=3).fit(x, y, groups=groups)
    again = ElmanGenerators(hidden=4, epochs=20, random_state=3).fit(x, y, groups=groups)
    other = ElmanGenerators(hidden=4, epochs=20, random_state=4).fit(x, y, groups=groups)
    assert first.n_test_[0] == 60 and first.n_train_[0] == 240  # 2 of 10 groups held out
    assert np.isfinite(first.test_error_[0]).all()
    assert first.best_epoch_[0] == int(np.nanargmin(first.test_error_[0]))
    for name in ("w_x_", "w_c_", "w_y_"):
        assert np.array_equal(getattr(first, name), getattr(again, name))
    assert not np.array_equal(first.w_x_, other.w_x_)


def test_arrays_round_trip_and_hostile_arrays_are_refused() -> None:
    x, y, _ = _ramps(n_seq=4, length=10)
    prim = np.repeat([0, 2, 0, 2], 10)  # primitive 1 has no rows
    gens = ElmanGenerators(hidden=3, epochs=3, random_state=0).fit(x, y, prim)
    assert gens.trained_.tolist() == [True, False, True]
    with pytest.raises(ConfigError, match="primitive 1 had no training samples"):
        gens.predict(x[:3], 1)
    arrays = gens.to_arrays()
    back = ElmanGenerators.from_arrays(arrays, **gens.get_params())
    np.testing.assert_array_equal(back.predict(x[:10], 2), gens.predict(x[:10], 2))
    for change, message in (
        ({"w_c": np.zeros((3, 2, 2))}, "'w_c' must be"),
        ({"w_x": np.full_like(arrays["w_x"], np.nan)}, "not finite"),
        ({"trained": np.array([True, True, True])}, "disagrees"),
        ({"best_epoch": np.array([0, -1, 7])}, "out of range"),
        ({"extra": np.zeros(1)}, "unexpected"),
    ):
        with pytest.raises(ModelFileError, match=message):
            ElmanGenerators.from_arrays({**arrays, **change}, **gens.get_params())
    with pytest.raises(ModelFileError, match="lack w_y"):
        ElmanGenerators.from_arrays(
            {k: v for k, v in arrays.items() if k != "w_y"}, **gens.get_params()
        )
    with pytest.raises(ModelFileError, match="'w_x' must be"):
        ElmanGenerators.from_arrays(arrays, **{**gens.get_params(), "hidden": 4})
    with pytest.raises(NotFittedError):
        ElmanGenerators().stepper()


def test_partial_fit_keeps_untouched_networks_and_trains_new_ones() -> None:
    rng = np.random.default_rng(2)
    x = rng.uniform(-1, 1, (60, 3))
    y = np.tanh(x[:, :2])
    prim = np.repeat([0, 1, 0], 20)
    gens = ElmanGenerators(hidden=3, epochs=4, random_state=0).fit(x, y, prim)
    before = {k: v.copy() for k, v in gens.to_arrays().items()}
    new_prim = np.repeat([1, 2], 15)
    gens.partial_fit(x[:30], y[:30], new_prim, update=1)
    after = gens.to_arrays()
    assert gens.n_primitives_ == 3 and gens.trained_.tolist() == [True, True, True]
    for name in ("w_x", "w_c", "w_y", "train_error", "test_error"):
        np.testing.assert_array_equal(after[name][0], before[name][0])  # untouched
    assert not np.array_equal(after["w_x"][1], before["w_x"][1])  # fine-tuned
    assert gens.n_train_[2] > 0
    with pytest.raises(ConfigError, match="features"):
        gens.partial_fit(x[:10, :2], y[:10], np.zeros(10, dtype=int))


def test_the_networks_are_named_once() -> None:
    assert list(GENERATOR_NETWORKS) == ["mlp", "elman"]
    assert GENERATOR_NETWORKS["elman"] is ElmanGenerators
    for bad in ({"hidden": 0}, {"learning_rate": 0.0}, {"warmup": -1}, {"epochs": 1.5}):
        with pytest.raises(ConfigError):
            ElmanGenerators(**bad).fit(np.zeros((4, 2)), np.zeros((4, 1)))  # type: ignore[arg-type]
