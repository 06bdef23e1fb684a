"""The prototype index finds the full scan's winners while scoring few categories."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from cobart_testing import episodes, params, split, turn_dataset
from hypothesis import given, settings

from behavior_hmm.cobart import CobART, _index
from behavior_hmm.cobart._index import PrototypeIndex


def _noisy_copies(base: CobART, k: int, noise: float, seed: int = 0) -> CobART:
    """``k`` categories drawn from ``base``'s prototypes with Gaussian noise."""
    rng = np.random.default_rng(seed)
    protos = base.prototypes_[rng.integers(0, base.n_categories_, k)]
    net = CobART(**base.get_params())
    net.set_state(
        protos + rng.normal(0.0, noise, protos.shape), np.ones(k, np.int64), base.dcm_scale_
    )
    return net


def _both(
    net: CobART, x: np.ndarray, lengths: list[int], monkeypatch: pytest.MonkeyPatch
) -> tuple[Any, Any]:
    """``categorize`` by the full scan and through the index."""
    monkeypatch.setattr(_index, "INDEX_MIN_CATEGORIES", 10**9)
    full = net.categorize(x, lengths)
    assert net._predictor().index is None
    monkeypatch.setattr(_index, "INDEX_MIN_CATEGORIES", 1)
    assert net._predictor().index is not None
    return full, net.categorize(x, lengths)


def test_index_finds_the_full_scans_winners_on_turns(monkeypatch: pytest.MonkeyPatch) -> None:
    x, lengths = turn_dataset(two_channels=True)
    base = CobART.observations(rho=0.99).fit(x, lengths)
    net = _noisy_copies(base, 5_000, noise=0.01)
    full, fast = _both(net, x, lengths, monkeypatch)
    np.testing.assert_array_equal(fast.labels, full.labels)
    np.testing.assert_allclose(fast.scores, full.scores, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(fast.novel, full.novel)


def test_index_scores_a_small_share_and_live_equals_offline(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    x, lengths = turn_dataset()
    base = CobART.observations().fit(x, lengths)
    net = _noisy_copies(base, 20_000, noise=0.01, seed=3)
    monkeypatch.setattr(_index, "INDEX_MIN_CATEGORIES", 1)
    offline = net.categorize(x, lengths)
    live = net.stream()
    index = live._pred.index
    assert index is not None
    scored = []
    labels, scores = [], []
    for ep in split(x, lengths):
        live.reset()
        for reading in ep:
            k, _, s = live.update(reading)
            labels.append(k)
            scores.append(s)
            scored.append(index.scored)
    np.testing.assert_array_equal(labels, offline.labels)
    np.testing.assert_array_equal(scores, offline.scores)  # bit for bit
    assert np.median(scored) < 0.05 * 20_000


def test_mismatch_of_an_indexed_categorizer_is_every_categorys(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    x, lengths = turn_dataset(two_channels=True)
    base = CobART.observations(rho=0.99).fit(x, lengths)
    net = _noisy_copies(base, 3_000, noise=0.02)
    monkeypatch.setattr(_index, "INDEX_MIN_CATEGORIES", 10**9)
    full = net.stream()
    monkeypatch.setattr(_index, "INDEX_MIN_CATEGORIES", 1)
    fast = net.stream()
    for reading in x[:40]:
        k_full, _, _ = full.update(reading)
        k_fast, _, _ = fast.update(reading)
        assert k_fast == k_full
        np.testing.assert_allclose(fast.mismatch, full.mismatch, rtol=0, atol=1e-12)
        assert int(np.argmin(fast.mismatch)) == k_fast


def test_ties_go_to_the_lowest_category(monkeypatch: pytest.MonkeyPatch) -> None:
    x, lengths = turn_dataset()
    base = CobART.observations().fit(x, lengths)
    protos = np.repeat(base.prototypes_, 40, axis=0)[::-1]  # every prototype 40 times
    net = CobART(**base.get_params())
    net.set_state(protos, np.ones(len(protos), np.int64), base.dcm_scale_)
    full, fast = _both(net, x, lengths, monkeypatch)
    np.testing.assert_array_equal(fast.labels, full.labels)


def test_large_unnormalized_features_keep_the_winner(monkeypatch: pytest.MonkeyPatch) -> None:
    """Readings of magnitude 1e3 on a fine scale (the expansion cancels most): same winners."""
    rng = np.random.default_rng(5)
    x = 1e3 + np.cumsum(rng.normal(0.0, 0.05, size=(400, 3)), axis=0)
    lengths = [100, 100, 200]
    net = CobART(rho=0.9, window=3, edm_scale=0.5, dcm_scale=[0.01, 0.01, 0.01])
    net.set_state(
        x[rng.integers(0, 400, 4_000)][:, None, :].repeat(3, axis=1)
        + rng.normal(0.0, 0.02, (4_000, 3, 3)),
        np.ones(4_000, np.int64),
        np.full(3, 0.01),
    )
    full, fast = _both(net, x, lengths, monkeypatch)
    np.testing.assert_array_equal(fast.labels, full.labels)


@settings(max_examples=40, deadline=None)
@given(episodes(max_channels=3, max_len=40), params)
def test_index_equals_the_full_scan_on_random_models(
    data: tuple[np.ndarray, list[int]], kw: dict[str, Any]
) -> None:
    x, lengths = data
    m = CobART(**kw).fit(x, lengths)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(_index, "LEAF_SIZE", 2)  # many leaves even for a few categories
        full, fast = _both(m, x, lengths, mp)
    np.testing.assert_array_equal(fast.labels, full.labels)
    np.testing.assert_allclose(fast.scores, full.scores, rtol=0, atol=1e-9)


def test_leaves_cover_every_prototype_once() -> None:
    rng = np.random.default_rng(0)
    f, g = 5, 2
    gs = np.zeros((f, g))
    gs[:3, 0] = 1.0
    gs[3:, 1] = 4.0
    z = rng.normal(size=(1_000, f))
    norms = (z * z) @ gs
    zaug = np.c_[z, norms, np.full(1_000, -0.5)]
    index = PrototypeIndex(zaug, gs, np.array([0.7, 0.3]))
    np.testing.assert_array_equal(np.sort(index.order), np.arange(1_000))
    sizes = np.diff(index.bounds)
    assert sizes.max() <= _index.LEAF_SIZE
    for leaf in range(sizes.size):
        rows = z[index.order[index.bounds[leaf] : index.bounds[leaf + 1]]]
        assert np.all(rows >= index.lo[leaf]) and np.all(rows <= index.hi[leaf])
