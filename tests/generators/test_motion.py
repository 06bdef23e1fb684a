"""MotionGenerators: learning, lock-step equivalence, edge cases, persistence."""

from __future__ import annotations

import io

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from behavior_hmm.errors import ConfigError, ModelFileError, NotFittedError
from behavior_hmm.generators import DEFAULT_BATCH_SIZE, MotionGenerators
from behavior_hmm.generators._mlp import n_params, train_stack
from behavior_hmm.generators._motion import init_weights, primitive_rng, split_rows


def _data(rng: np.random.Generator, counts: list[int], n_features: int = 10):
    """Per primitive p: Y = tanh(X @ A_p) / 2, a learnable smooth map into (-1, 1)."""
    xs, ys, prims = [], [], []
    for p, count in enumerate(counts):
        a = rng.normal(0, 0.4, (n_features, 2))
        x = rng.uniform(-1, 1, (count, n_features))
        xs.append(x)
        ys.append(0.5 * np.tanh(x @ a))
        prims.append(np.full(count, p))
    return np.concatenate(xs), np.concatenate(ys), np.concatenate(prims)


def test_learns_a_smooth_map_to_low_error(rng: np.random.Generator) -> None:
    x, y, prim = _data(rng, [300, 200])
    model = MotionGenerators(epochs=150, random_state=1).fit(x, y, prim)
    assert model.trained_.all()
    assert model.hidden_sizes_ == (5,)
    rms_before = np.sqrt(np.mean(y**2))
    # Errors fall over training and end far below the signal's own RMS.
    assert (model.test_error_[:, -1] < 0.25 * rms_before).all()
    assert (model.test_error_[:, -1] < model.test_error_[:, 0]).all()
    pred = model.predict(x, prim)
    assert np.sqrt(np.mean((pred - y) ** 2)) < 0.25 * rms_before


def test_defaults_follow_thesis_table_6_2() -> None:
    model = MotionGenerators()
    assert (model.learning_rate, model.momentum, model.init_range, model.test_fraction) == (
        0.01,
        0.4,
        1.0,
        0.2,
    )
    assert model.batch_size == DEFAULT_BATCH_SIZE
    rng = np.random.default_rng(0)
    for n_features, units in [(10, 5), (20, 10), (30, 15), (21, 10)]:
        x = rng.uniform(-1, 1, (8, n_features))
        fitted = MotionGenerators(epochs=1).fit(x, np.zeros((8, 2)))
        assert fitted.hidden_sizes_ == (units,)
        assert fitted.coefs_[0].shape == (1, n_features, units)


def test_same_seed_gives_byte_identical_weights(rng: np.random.Generator) -> None:
    x, y, prim = _data(rng, [40, 25, 3])
    model = MotionGenerators(epochs=5, random_state=7)
    a = model.fit(x, y, prim).to_arrays()
    b = model.fit(x, y, prim).to_arrays()  # refitting the same object
    fresh = MotionGenerators(epochs=5, random_state=7).fit(x, y, prim).to_arrays()
    c = MotionGenerators(epochs=5, random_state=8).fit(x, y, prim).to_arrays()
    for key in a:
        assert a[key].tobytes() == b[key].tobytes() == fresh[key].tobytes(), key
    assert a["coef_0"].tobytes() != c["coef_0"].tobytes()


@pytest.mark.parametrize("batch_size", [1, 7])
def test_primitive_trains_the_same_with_or_without_the_others(
    rng: np.random.Generator, batch_size: int
) -> None:
    x, y, prim = _data(rng, [50, 12, 31])
    params = dict(epochs=3, batch_size=batch_size, random_state=3)
    together = MotionGenerators(**params).fit(x, y, prim)
    for p in range(3):
        rows = prim == p
        alone = MotionGenerators(**params).fit(x[rows], y[rows], prim[rows], n_primitives=3)
        assert alone.trained_.tolist() == [q == p for q in range(3)]
        for w_all, w_one in zip(together.coefs_, alone.coefs_, strict=True):
            np.testing.assert_array_equal(w_all[p], w_one[p])
        np.testing.assert_array_equal(together.test_error_[p], alone.test_error_[p])
        np.testing.assert_array_equal(together.train_error_[p], alone.train_error_[p])


def test_stack_equals_a_network_trained_alone(rng: np.random.Generator) -> None:
    """Primitive 1's weights equal a one-network stack fed the same draws."""
    x, y, prim = _data(rng, [50, 40])
    model = MotionGenerators(epochs=4, batch_size=4, random_state=5).fit(x, y, prim)
    gen = primitive_rng(5, 1)
    train, test = split_rows(np.flatnonzero(prim == 1), None, gen, 0.2, 5)
    sizes = (10, 5, 2)
    theta0 = init_weights(gen, sizes, 1.0)[None]
    result = train_stack(
        theta0, sizes, x[train][None], y[train][None], np.array([train.size]),
        x[test][None], y[test][None], np.array([test.size]),
        learning_rate=np.array([0.01]), momentum=np.array([0.4]), epochs=4, batch_size=4,
        rngs=[gen], early_stopping=True, patience=None,
    )  # fmt: skip
    assert theta0.shape[1] == n_params(sizes)
    w0 = result.theta[0, : 11 * 5].reshape(11, 5)
    np.testing.assert_allclose(model.coefs_[0][1], w0[:-1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(model.intercepts_[0][1], w0[-1], rtol=0, atol=1e-12)


def test_empty_and_tiny_primitives(rng: np.random.Generator) -> None:
    x, y, prim = _data(rng, [30, 0, 3, 20])
    model = MotionGenerators(epochs=3).fit(x, y, prim, n_primitives=5)
    assert model.trained_.tolist() == [True, False, True, True, False]
    assert model.n_train_.tolist() == [24, 0, 3, 16, 0]
    assert model.n_test_.tolist() == [6, 0, 0, 4, 0]
    # The tiny primitive trains on everything and has no test curve.
    assert np.isnan(model.test_error_[2]).all() and np.isfinite(model.train_error_[2]).all()
    assert model.best_epoch_.tolist() == [model.best_epoch_[0], -1, 2, model.best_epoch_[3], -1]
    assert model.predict_one(x[0], 2).shape == (2,)
    for p in (1, 4):
        with pytest.raises(ConfigError, match="no training samples"):
            model.predict_one(x[0], p)
        with pytest.raises(ConfigError, match="no training samples"):
            model.predict(x[:3], p)
    for bad in (5, -1):
        with pytest.raises(ConfigError, match="primitive"):
            model.predict_one(x[0], bad)


def test_single_network_with_extra_inputs_for_behavior_cloning(rng: np.random.Generator) -> None:
    windows = rng.uniform(-1, 1, (200, 10))
    goal = rng.uniform(-1, 1, (200, 1))
    x = np.hstack([windows, goal])
    y = 0.5 * np.tanh(np.hstack([windows[:, -1:] - goal, goal - windows[:, -1:]]))
    model = MotionGenerators(epochs=100).fit(x, y)
    assert model.n_primitives_ == 1 and model.n_features_in_ == 11
    assert model.hidden_sizes_ == (5,)
    rms = np.sqrt(np.mean(y**2))
    assert np.sqrt(np.mean((model.predict(x) - y) ** 2)) < 0.25 * rms


def test_predict_one_matches_predict(rng: np.random.Generator) -> None:
    x, y, prim = _data(rng, [40, 40])
    model = MotionGenerators(epochs=2, hidden=(4, 3)).fit(x, y, prim)
    batch = model.predict(x[:10], 1)
    for i in range(10):
        np.testing.assert_allclose(model.predict_one(x[i], 1), batch[i], rtol=1e-12)
    per_row = model.predict(x[:10], prim[:10])
    np.testing.assert_allclose(per_row, model.predict(x[:10], 0))
    with pytest.raises(ConfigError, match="shape"):
        model.predict_one(x[0, :5], 0)
    with pytest.raises(ConfigError, match="features"):
        model.predict(x[:, :5], 0)


def test_early_stopping_keeps_the_best_epoch(rng: np.random.Generator) -> None:
    x, y, prim = _data(rng, [60])
    y = np.clip(y + rng.normal(0, 0.3, y.shape), -1, 1)  # noisy: test error turns up
    params = dict(epochs=40, learning_rate=0.05, random_state=2)
    stopped = MotionGenerators(**params).fit(x, y, prim)
    best = int(stopped.best_epoch_[0])
    assert best == int(np.nanargmin(stopped.test_error_[0]))
    assert best < 39
    replay = MotionGenerators(**{**params, "epochs": best + 1, "early_stopping": False})
    replay.fit(x, y, prim)
    np.testing.assert_array_equal(replay.coefs_[0], stopped.coefs_[0])
    last = MotionGenerators(**{**params, "early_stopping": False}).fit(x, y, prim)
    assert last.best_epoch_[0] == 39
    np.testing.assert_array_equal(last.test_error_, stopped.test_error_)
    assert not np.array_equal(last.coefs_[0], stopped.coefs_[0])


def test_patience_stops_a_primitive_early(rng: np.random.Generator) -> None:
    x, y, prim = _data(rng, [60, 60])
    y[:60] = np.clip(y[:60] + rng.normal(0, 0.3, (60, 2)), -1, 1)
    model = MotionGenerators(epochs=60, learning_rate=0.05, patience=3).fit(x, y, prim)
    ran = np.isfinite(model.test_error_[0]).sum()
    assert ran == model.best_epoch_[0] + 4 < 60
    assert np.isnan(model.test_error_[0, ran:]).all()


def test_groups_hold_out_whole_groups(rng: np.random.Generator) -> None:
    x, y, prim = _data(rng, [100])
    groups = np.repeat(np.arange(10), 10)
    model = MotionGenerators(epochs=1).fit(x, y, prim, groups=groups)
    assert model.n_test_[0] == 20 and model.n_train_[0] == 80
    gen = primitive_rng(0, 0)
    train, test = split_rows(np.arange(100), groups, gen, 0.2, 5)
    assert not set(groups[train]) & set(groups[test])
    # A single group falls back to a per-row split.
    one = MotionGenerators(epochs=1).fit(x, y, prim, groups=np.zeros(100))
    assert one.n_test_[0] == 20


def test_not_fitted_and_bad_inputs(rng: np.random.Generator) -> None:
    model = MotionGenerators()
    with pytest.raises(NotFittedError):
        model.predict_one(np.zeros(10), 0)
    with pytest.raises(NotFittedError):
        model.predict(np.zeros((1, 10)))
    with pytest.raises(NotFittedError):
        model.to_arrays()
    x, y, prim = _data(rng, [10])
    bad_calls = [
        lambda: model.fit(x, y * 3, prim),  # not normalized
        lambda: model.fit(np.where(x > 0.9, np.nan, x), y, prim),
        lambda: model.fit(x, y[:-1], prim),
        lambda: model.fit(x, y, prim.astype(float)),
        lambda: model.fit(x, y, prim - 1),
        lambda: model.fit(x, y, prim + 3, n_primitives=2),
        lambda: model.fit(x[:0], y[:0], prim[:0]),
        lambda: model.fit(x[:, 0], y, prim),
    ]
    for call in bad_calls:
        with pytest.raises(ConfigError):
            call()
    for params in [
        {"learning_rate": 0},
        {"momentum": 1.0},
        {"batch_size": 0},
        {"epochs": 2.5},
        {"hidden": (5, 0)},
        {"hidden": "5"},
        {"test_fraction": 1.0},
        {"init_range": -1},
        {"patience": 0},
        {"random_state": None},
        {"early_stopping": "yes"},
    ]:
        with pytest.raises(ConfigError):
            MotionGenerators(**params).fit(x, y, prim)


def test_params_follow_sklearn_conventions() -> None:
    model = MotionGenerators(hidden=(5, 5), batch_size=4)
    params = model.get_params()
    assert params["hidden"] == (5, 5) and params["batch_size"] == 4
    assert MotionGenerators(**params).get_params() == params
    assert model.set_params(epochs=3) is model and model.epochs == 3
    with pytest.raises(ConfigError):
        model.set_params(nonsense=1)
    assert "hidden=(5, 5)" in repr(model)
    x = np.zeros((6, 10))
    assert model.fit(x, np.zeros((6, 2))) is model


def test_arrays_round_trip_through_npz(rng: np.random.Generator) -> None:
    x, y, prim = _data(rng, [30, 0, 20])
    params = dict(epochs=3, hidden=(4, 3))
    model = MotionGenerators(**params).fit(x, y, prim)
    buffer = io.BytesIO()
    np.savez(buffer, **model.to_arrays())
    buffer.seek(0)
    with np.load(buffer, allow_pickle=False) as npz:
        loaded = MotionGenerators.from_arrays(dict(npz), **params)
    np.testing.assert_array_equal(loaded.predict(x, 2), model.predict(x, 2))
    np.testing.assert_array_equal(loaded.trained_, model.trained_)
    np.testing.assert_array_equal(loaded.test_error_, model.test_error_)
    assert loaded.predict_one(x[0], 0).tolist() == model.predict_one(x[0], 0).tolist()


def _corruptions(arrays: dict[str, np.ndarray]) -> list[dict[str, object]]:
    def with_(key: str, value: object) -> dict[str, object]:
        return {**arrays, key: value}

    nan_w = arrays["coef_0"].copy()
    nan_w[0, 0, 0] = np.nan
    no_key = dict(arrays)
    del no_key["intercept_1"]
    flipped = arrays["trained"].copy()
    flipped[0] = not flipped[0]
    return [
        with_("coef_0", nan_w),
        with_("coef_1", arrays["coef_1"][:, :-1]),  # layer chain broken
        with_("coef_1", arrays["coef_1"][:, :, :, None]),
        with_("coef_0", arrays["coef_0"].astype(object)),
        with_("coef_0", [[1.0]]),
        with_("intercept_0", arrays["intercept_0"][:1]),
        with_("trained", flipped),
        with_("trained", arrays["trained"].astype(int)),
        with_("n_train", -arrays["n_train"]),
        with_("best_epoch", arrays["best_epoch"] + 10),
        with_("train_error", arrays["train_error"][:, :2]),
        with_("test_error", np.full_like(arrays["test_error"], np.inf)),
        with_("surprise", np.zeros(1)),
        no_key,
        {},
    ]


def test_bad_arrays_are_refused(rng: np.random.Generator) -> None:
    x, y, prim = _data(rng, [30, 20])
    model = MotionGenerators(epochs=3).fit(x, y, prim)
    arrays = model.to_arrays()
    MotionGenerators.from_arrays(arrays, epochs=3)  # the intact set loads
    for bad in _corruptions(arrays):
        with pytest.raises(ModelFileError):
            MotionGenerators.from_arrays(bad, epochs=3)
    with pytest.raises(ModelFileError, match="hidden"):
        MotionGenerators.from_arrays(arrays, epochs=3, hidden=7)
    with pytest.raises(ModelFileError):
        MotionGenerators.from_arrays(arrays, epochs=4)
    with pytest.raises(ModelFileError):
        MotionGenerators.from_arrays(arrays, epochs=3, momentum=2.0)
    with pytest.raises(ModelFileError):
        MotionGenerators.from_arrays(arrays, bogus=1)
    with pytest.raises(ModelFileError):
        MotionGenerators.from_arrays([("coef_0", arrays["coef_0"])], epochs=3)  # type: ignore[arg-type]


_KEYS = [
    "coef_0", "intercept_0", "coef_1", "intercept_1", "trained", "n_train", "n_test",
    "best_epoch", "train_error", "test_error", "coef_2", "other",
]  # fmt: skip
_DTYPES = [np.float64, np.float32, np.int64, np.uint8, np.bool_, object]


@settings(max_examples=60, deadline=None)
@given(
    data=st.dictionaries(
        st.sampled_from(_KEYS),
        st.tuples(
            st.sampled_from(_DTYPES),
            st.lists(st.integers(0, 4), min_size=0, max_size=4),
            st.sampled_from([0.0, 1.0, -1.0, np.nan, np.inf]),
        ),
        max_size=len(_KEYS),
    ),
    base=st.booleans(),
)
def test_from_arrays_returns_a_model_or_model_file_error(data, base) -> None:
    arrays: dict[str, object] = dict(_VALID) if base else {}
    for key, (dtype, shape, fill) in data.items():
        if dtype is object:
            fill = None
        elif np.dtype(dtype).kind in "iub" and not np.isfinite(fill):
            fill = 1
        arrays[key] = np.full(shape, fill, dtype=dtype)
    try:
        model = MotionGenerators.from_arrays(arrays, epochs=2)
    except ModelFileError:
        return
    out = model.predict_one(np.zeros(model.n_features_in_), int(np.argmax(model.trained_)))
    assert out.shape == (model.n_outputs_,)


_VALID = (
    MotionGenerators(epochs=2)
    .fit(np.random.default_rng(0).uniform(-1, 1, (20, 10)), np.zeros((20, 2)))
    .to_arrays()
)


def test_shared_init_helps_primitives_that_have_few_rows(rng: np.random.Generator) -> None:
    """Eight primitives of one map, 12 rows each: the networks that start from the
    network trained on all 96 rows predict new inputs better than those that start from
    their own draws (on average by a fifth, and none more than 5 % worse than its own draw's); the
    fit is deterministic, and an unknown init is refused."""
    a = rng.normal(0, 0.6, (10, 2))
    x = rng.uniform(-1, 1, (96, 10))
    y = 0.5 * np.tanh(x @ a)
    prim = np.repeat(np.arange(8), 12)
    x_new = rng.uniform(-1, 1, (400, 10))
    y_new = 0.5 * np.tanh(x_new @ a)
    params = dict(epochs=60, batch_size=4, random_state=2)
    errors = {}
    for init in ("random", "shared"):
        model = MotionGenerators(**params, init=init).fit(x, y, prim)
        errors[init] = [
            float(np.sqrt(np.mean((model.predict(x_new, np.full(400, p)) - y_new) ** 2)))
            for p in range(8)
        ]
    # the shared start is trained for as many updates as one primitive's network makes
    # (shared_epochs), so a network may end level with its own draw's, never far behind
    better = sum(s < r for s, r in zip(errors["shared"], errors["random"], strict=True))
    assert better >= 6
    assert np.mean(errors["shared"]) < 0.8 * np.mean(errors["random"])
    assert all(s < 1.05 * r for s, r in zip(errors["shared"], errors["random"], strict=True))
    again = MotionGenerators(**params, init="shared").fit(x, y, prim)
    first = MotionGenerators(**params, init="shared").fit(x, y, prim)
    for w1, w2 in zip(first.coefs_, again.coefs_, strict=True):
        np.testing.assert_array_equal(w1, w2)
    assert first.get_params()["init"] == "shared"
    with pytest.raises(ConfigError, match="init must be one of random, shared"):
        MotionGenerators(init="pretrained").fit(x, y, prim)


def test_shared_start_trains_as_many_updates_as_the_largest_primitive(
    rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The shared network makes as many updates as the primitive of most rows: 40 epochs
    over 50 rows (40 train) in batches of 4 are 400 updates; 200 rows (160 train) take 40
    a pass, so it trains 10 epochs, then the primitives their 40."""
    from behavior_hmm.generators import _motion

    assert _motion.shared_epochs(40, 4, 160, 30, 0.2) == 6
    assert _motion.shared_epochs(40, 4, 24, 30, 0.2) == 40  # never more than ``epochs``
    assert _motion.shared_epochs(40, 4, 10_000, 2, 0.2) == 1  # at least one pass
    seen: list[tuple[int, int]] = []
    real = _motion.train_stack

    def spy(theta0, *args, epochs, **kwargs):  # type: ignore[no-untyped-def]
        seen.append((theta0.shape[0], epochs))
        return real(theta0, *args, epochs=epochs, **kwargs)

    monkeypatch.setattr(_motion, "train_stack", spy)
    x = rng.uniform(-1, 1, (200, 10))
    y = 0.3 * np.tanh(x[:, :2])
    prim = np.repeat(np.arange(5), [30, 20, 50, 50, 50])  # largest: 50 rows, 40 train
    MotionGenerators(epochs=40, batch_size=4, init="shared").fit(x, y, prim)
    assert seen == [(1, 40 * 10 // 40), (5, 40)]
    seen.clear()
    MotionGenerators(epochs=40, batch_size=4).fit(x, y, prim)
    assert seen == [(5, 40)]
