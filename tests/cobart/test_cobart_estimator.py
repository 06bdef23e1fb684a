"""CobART estimator: API conventions, learning rule, validation, fitted state."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from cobart_testing import reference_fit, s_curve, split, turn_dataset, window_at

from behavior_hmm.cobart import (
    MOTION_PRIMITIVE_PARAMS,
    OBSERVATION_PARAMS,
    CobART,
    cobart_score,
)
from behavior_hmm.errors import ConfigError, DatasetError, NotFittedError


# ---------------------------------------------------------------- conventions
def test_defaults_are_the_motion_primitive_preset() -> None:
    params = CobART().get_params()
    for key, value in MOTION_PRIMITIVE_PARAMS.items():
        assert params[key] == value
    assert params["dcm_scale"] == "auto"
    assert params["edm_scale"] == 1.0


def test_presets_follow_thesis_table_4_2() -> None:
    m = CobART.motion_primitives()
    assert (m.a, m.b, m.d, m.alpha, m.rho, m.window) == (0.8, 0.4, 0.2, -1.0, 0.85, 10)
    o = CobART.observations(rho=0.9)
    assert (o.a, o.b, o.d, o.alpha, o.rho, o.window) == (0.95, 0.1, 0.2, -1.0, 0.9, 3)
    assert OBSERVATION_PARAMS["rho"] == 0.95


def test_get_set_params_and_repr() -> None:
    m = CobART(rho=0.7)
    assert m.set_params(window=4, dcm_scale=0.01) is m
    assert m.get_params()["window"] == 4
    assert "rho=0.7" in repr(m) and "window=4" in repr(m)
    clone = CobART(**m.get_params())
    assert clone.get_params() == m.get_params()
    with pytest.raises(ConfigError, match="unknown parameter"):
        m.set_params(vigilance=0.3)


def test_fit_returns_self_and_refit_is_identical() -> None:
    x, lengths = turn_dataset()
    m = CobART()
    assert m.fit(x, lengths) is m
    protos, labels = m.prototypes_, m.labels_
    m.fit(x, lengths)
    np.testing.assert_array_equal(m.prototypes_, protos)
    np.testing.assert_array_equal(m.labels_, labels)
    np.testing.assert_array_equal(CobART().fit_predict(x, lengths), labels)


def test_not_fitted() -> None:
    m = CobART()
    for action in (
        lambda: m.predict(np.zeros((5, 1))),
        lambda: m.prototypes_,
        lambda: m.counts_,
        lambda: m.n_categories_,
        m.stream,
    ):
        with pytest.raises(NotFittedError):
            action()
    assert not hasattr(m, "prototypes_")


@pytest.mark.parametrize(
    "bad",
    [
        {"a": -0.1},
        {"a": 1.5},
        {"b": 2.0},
        {"d": -1e-9},
        {"rho": 1.01},
        {"rho": math.nan},
        {"alpha": 0.5},
        {"alpha": -math.inf},
        {"a": "high"},
        {"a": True},
        {"window": 0},
        {"window": 2.5},
        {"window": True},
        {"edm_scale": 0.0},
        {"dcm_scale": "fast"},
        {"dcm_scale": -0.01},
        {"dcm_scale": [0.01, 0.02]},  # two scales, one channel
    ],
)
def test_parameters_out_of_range(bad: dict[str, Any]) -> None:
    with pytest.raises(ConfigError):
        CobART(**bad).fit(np.zeros((20, 1)))


def test_parameter_range_edges_are_accepted() -> None:
    x = np.linspace(-1, 1, 30)[:, None]
    CobART(a=0.0, b=0.0, d=0.0, alpha=-50.0, rho=0.0, window=1).fit(x)
    CobART(a=1.0, b=1.0, d=1.0, alpha=0.0, rho=1.0, window=40).fit(x)


def test_nan_names_episode_and_row() -> None:
    x = np.zeros((30, 2))
    x[17, 1] = np.nan
    with pytest.raises(DatasetError, match=r"episode 1, row 7, field 'channel 1'"):
        CobART().fit(x, [10, 20])
    x[17, 1] = np.inf
    with pytest.raises(DatasetError):
        CobART().fit(x)
    m = CobART().fit(np.zeros((30, 2)))
    with pytest.raises(DatasetError):
        m.predict(x)


@pytest.mark.parametrize(
    ("x", "lengths", "error"),
    [
        (np.zeros((10, 1)), [5, 6], ConfigError),
        (np.zeros((10, 1)), [10, 0], ConfigError),
        (np.zeros((10, 1)), [4.5, 5.5], ConfigError),
        (np.zeros((10, 1)), [[10]], ConfigError),
        (np.zeros((0, 1)), None, DatasetError),
        (np.zeros((2, 3, 1)), None, DatasetError),
        (np.array([["a"], ["b"]]), None, DatasetError),
    ],
)
def test_bad_data(x: np.ndarray, lengths: Any, error: type[Exception]) -> None:
    with pytest.raises(error):
        CobART().fit(x, lengths)


def test_channel_count_must_match_the_fit() -> None:
    m = CobART().fit(np.zeros((20, 2)))
    with pytest.raises(ConfigError, match="2"):
        m.predict(np.zeros((20, 3)))
    with pytest.raises(ConfigError):
        m.partial_fit(np.zeros((20, 1)))


def test_one_dimensional_x_is_one_channel() -> None:
    x = s_curve(0.5)
    m = CobART().fit(x)
    assert m.prototypes_.shape[2] == 1
    np.testing.assert_array_equal(m.predict(x), m.predict(x[:, None]))


# ---------------------------------------------------------------- algorithm
@pytest.mark.parametrize("seed", range(12))
def test_matches_a_plain_reference_loop(seed: int) -> None:
    rng = np.random.default_rng(seed)
    c = int(rng.integers(1, 3))
    lengths = [int(n) for n in rng.integers(5, 40, size=3)]
    x = np.clip(np.cumsum(rng.normal(0, 0.03, size=(sum(lengths), c)), axis=0), -1, 1)
    kw = {
        "a": float(rng.uniform(0.5, 1)),
        "b": float(rng.uniform()),
        "d": float(rng.uniform()),
        "alpha": float(rng.uniform(-2, 0)),
        "rho": float(rng.uniform(0.6, 0.97)),
        "window": int(rng.integers(1, 8)),
        "edm_scale": float(rng.uniform(0.5, 2)),
        "dcm_scale": float(rng.uniform(0.01, 0.1)),
    }
    m = CobART(**kw).fit(x, lengths)
    labels, protos, counts = reference_fit(x, lengths, **kw)
    np.testing.assert_array_equal(m.labels_, labels)
    np.testing.assert_allclose(m.prototypes_, np.stack(protos), atol=1e-12)
    np.testing.assert_array_equal(m.counts_, counts)


def test_alpha_minus_one_gives_a_running_mean() -> None:
    x = np.random.default_rng(0).uniform(-1, 1, size=(50, 2))
    m = CobART(a=1.0, d=1.0, alpha=-1.0, rho=0.0, window=3).fit(x)
    windows = np.stack([window_at(x, t, 3) for t in range(50)])
    assert m.n_categories_ == 1
    assert m.counts_[0] == 50
    np.testing.assert_allclose(m.prototypes_[0], windows.mean(axis=0), atol=1e-12)


def test_alpha_zero_gives_a_constant_rate() -> None:
    x = np.array([0.0, 0.4, 0.8])[:, None]
    m = CobART(a=1.0, d=0.5, alpha=0.0, rho=0.0, window=1).fit(x)
    # 0 -> 0 + 0.5 (0.4 - 0) = 0.2 -> 0.2 + 0.5 (0.8 - 0.2) = 0.5
    assert m.prototypes_[0, 0, 0] == pytest.approx(0.5)


def test_new_category_starts_from_the_processed_input() -> None:
    x = np.array([0.0, 0.6])[:, None]
    m = CobART(a=0.5, rho=1.0, window=1).fit(x)
    # p = 0.5 * 0.6 + 0.5 * z_last(0.0)
    np.testing.assert_allclose(m.prototypes_[:, 0, 0], [0.0, 0.3])
    assert m.labels_.tolist() == [0, 1]


def test_vigilance_zero_gives_one_category_and_one_gives_many() -> None:
    x, lengths = turn_dataset()
    assert CobART(rho=0.0).fit(x, lengths).n_categories_ == 1
    assert CobART(rho=1.0, d=0.0).fit(x, lengths).n_categories_ > 100


def test_ties_go_to_the_lowest_index() -> None:
    m = CobART(window=2, dcm_scale=0.01)
    proto = np.zeros((2, 2, 1))
    m.set_state(proto, np.array([1, 1]), np.array([0.01]))
    assert set(m.predict(np.zeros(10)).tolist()) == {0}
    assert set(m.predict(np.full(10, 0.3)).tolist()) == {0}


def test_windows_never_span_episodes() -> None:
    x, lengths = turn_dataset()
    m = CobART().fit(x, lengths)
    whole = m.categorize(x, lengths)
    offset = 0
    for ep in split(x, lengths):
        alone = m.categorize(ep)
        np.testing.assert_array_equal(alone.labels, whole.labels[offset : offset + len(ep)])
        np.testing.assert_array_equal(alone.scores, whole.scores[offset : offset + len(ep)])
        offset += len(ep)


def test_first_window_repeats_the_first_reading() -> None:
    x, lengths = turn_dataset()
    m = CobART().fit(x, lengths)
    ep = split(x, lengths)[2]
    first = m.categorize(ep)
    scores = m.score_window(np.repeat(ep[:1], m.window, axis=0))
    assert first.labels[0] == int(np.argmax(scores))
    assert first.scores[0] == pytest.approx(scores.max(), abs=1e-12)


def test_categorize_scores_follow_the_definition() -> None:
    x, lengths = turn_dataset(two_channels=True)
    m = CobART(a=0.8, rho=0.9).fit(x, lengths)
    res = m.categorize(x, lengths)
    protos = m.prototypes_
    offset = 0
    for ep in split(x, lengths)[:3]:
        last = -1
        for t in range(len(ep)):
            w = window_at(ep, t, m.window)
            p = w if last < 0 else m.a * w + (1 - m.a) * protos[last]
            ref = cobart_score(p, protos, m.b, m.edm_scale, m.dcm_scale_)
            k = res.labels[offset + t]
            assert res.scores[offset + t] == pytest.approx(ref.max(), abs=1e-9)
            assert ref[k] == pytest.approx(ref.max(), abs=1e-9)
            assert res.novel[offset + t] == (res.scores[offset + t] < m.rho)
            last = k
        offset += len(ep)


def test_partial_fit_continues_learning() -> None:
    x, lengths = turn_dataset()
    half = sum(lengths[:4])
    kw = {"dcm_scale": 0.01}
    whole = CobART(**kw).fit(x, lengths)
    parts = CobART(**kw).partial_fit(x[:half], lengths[:4])
    n_first = parts.n_categories_
    parts.partial_fit(x[half:], lengths[4:])
    assert parts.n_categories_ >= n_first
    np.testing.assert_array_equal(parts.prototypes_, whole.prototypes_)
    np.testing.assert_array_equal(parts.counts_, whole.counts_)
    np.testing.assert_array_equal(parts.labels_, whole.labels_[half:])


def test_partial_fit_refuses_a_new_window_length() -> None:
    m = CobART(window=5).fit(np.zeros((20, 1)))
    m.set_params(window=6)
    with pytest.raises(ConfigError, match="window changed"):
        m.partial_fit(np.zeros((20, 1)))
    m.fit(np.zeros((20, 1)))  # fit restarts
    assert m.prototypes_.shape[1] == 6


def test_parameters_take_effect_at_the_next_fit() -> None:
    x, lengths = turn_dataset()
    m = CobART(rho=0.85).fit(x, lengths)
    before = m.categorize(x, lengths)
    m.set_params(rho=0.1)
    np.testing.assert_array_equal(m.categorize(x, lengths).novel, before.novel)


def test_auto_dcm_scale_is_stored_and_kept_by_partial_fit() -> None:
    x, lengths = turn_dataset()
    m = CobART().fit(x, lengths)
    assert m.dcm_scale_.shape == (1,)
    assert 0.005 < m.dcm_scale_[0] < 0.05
    first = m.dcm_scale_.copy()
    m.partial_fit(x[:50] * 3.0)
    np.testing.assert_array_equal(m.dcm_scale_, first)


def test_dcm_scale_decides_how_many_primitives() -> None:
    """DESIGN §8: a scale far above the per-step changes collapses the primitives."""
    x, lengths = turn_dataset()
    fine = CobART(dcm_scale=0.005).fit(x, lengths).n_categories_
    coarse = CobART(dcm_scale=0.1).fit(x, lengths).n_categories_
    assert fine > 2 * coarse


def test_observations_are_finer_than_motion_primitives() -> None:
    x, lengths = turn_dataset()
    motion = CobART.motion_primitives().fit(x, lengths)
    obs = CobART.observations().fit(x, lengths)
    assert 1 < motion.n_categories_ < obs.n_categories_ < len(x) // 2


def test_short_and_single_sample_episodes() -> None:
    x = np.linspace(0, 1, 7)[:, None]
    m = CobART(window=10).fit(x, [1, 2, 4])
    assert m.labels_.shape == (7,)
    assert m.predict(x[:1]).shape == (1,)


# ---------------------------------------------------------------- fitted state
def test_prototypes_in_physical_units() -> None:
    m = CobART(a=1.0, window=1, rho=1.0).fit(np.array([[0.5, -1.0], [-0.5, 1.0]]))
    phys = m.prototypes_physical([(-180.0, 180.0), (0.0, 1.2)])
    np.testing.assert_allclose(phys[:, 0, :], [[90.0, 0.0], [-90.0, 1.2]])
    with pytest.raises(ConfigError):
        m.prototypes_physical([(-180.0, 180.0)])
    with pytest.raises(ConfigError):
        m.prototypes_physical([(1.0, 1.0), (0.0, 1.2)])


def test_set_state_restores_an_identical_model() -> None:
    x, lengths = turn_dataset(two_channels=True)
    m = CobART(rho=0.9).fit(x, lengths)
    copy = CobART(**m.get_params()).set_state(m.prototypes_, m.counts_, m.dcm_scale_)
    a, b = m.categorize(x, lengths), copy.categorize(x, lengths)
    np.testing.assert_array_equal(a.labels, b.labels)
    np.testing.assert_array_equal(a.scores, b.scores)
    # learning continues identically too
    m.partial_fit(x, lengths)
    copy.partial_fit(x, lengths)
    np.testing.assert_array_equal(m.prototypes_, copy.prototypes_)


@pytest.mark.parametrize(
    ("protos", "counts", "scale"),
    [
        (np.zeros((2, 9, 1)), [1, 1], [0.01]),  # window 9, model 10
        (np.zeros((2, 10, 1)), [1], [0.01]),
        (np.zeros((2, 10, 1)), [0, 1], [0.01]),
        (np.full((2, 10, 1), np.nan), [1, 1], [0.01]),
        (np.zeros((2, 10, 1)), [1, 1], [0.0]),
        (np.zeros((0, 10, 1)), [], [0.01]),
    ],
)
def test_set_state_rejects_inconsistent_arrays(protos: Any, counts: Any, scale: Any) -> None:
    with pytest.raises(ConfigError):
        CobART().set_state(protos, np.asarray(counts, dtype=np.int64), scale)


def test_score_window_checks_its_input() -> None:
    m = CobART(window=4).fit(np.zeros((20, 2)))
    assert m.score_window(np.zeros((4, 2))).shape == (m.n_categories_,)
    with pytest.raises(ConfigError, match=r"\(4, 2\)"):
        m.score_window(np.zeros((3, 2)))
    with pytest.raises(DatasetError):
        m.score_window(np.full((4, 2), np.nan))


def test_compacted_drops_categories_that_never_win() -> None:
    x, lengths = turn_dataset()
    m = CobART().fit(x, lengths)
    relabel = m.predict(x, lengths)
    small = m.compacted(x, lengths)
    assert small.n_categories_ == len(np.unique(relabel)) <= m.n_categories_
    np.testing.assert_array_equal(small.kept_[small.predict(x, lengths)], relabel)
    np.testing.assert_array_equal(small.labels_, small.predict(x, lengths))
    np.testing.assert_array_equal(small.prototypes_, m.prototypes_[small.kept_])
