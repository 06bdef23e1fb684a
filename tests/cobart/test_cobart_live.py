"""Live categorization, one reading at a time."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from cobart_testing import episodes, params, split, turn_dataset
from hypothesis import given, settings

from behavior_hmm.cobart import CobART, LiveCategorizer
from behavior_hmm.errors import ConfigError, DatasetError


def _stream(live: LiveCategorizer, x: np.ndarray, lengths: list[int]) -> tuple[list, list, list]:
    labels, novel, scores = [], [], []
    for ep in split(x, lengths):
        live.reset()
        for reading in ep:
            k, new, s = live.update(reading)
            labels.append(k)
            novel.append(new)
            scores.append(s)
    return labels, novel, scores


@settings(max_examples=50, deadline=None)
@given(episodes(), params)
def test_live_equals_offline(data: tuple[np.ndarray, list[int]], kw: dict[str, Any]) -> None:
    x, lengths = data
    m = CobART(**kw).fit(x, lengths)
    res = m.categorize(x, lengths)
    labels, novel, scores = _stream(m.stream(), x, lengths)
    np.testing.assert_array_equal(labels, res.labels)
    np.testing.assert_array_equal(novel, res.novel)
    np.testing.assert_array_equal(scores, res.scores)  # bit for bit


def test_live_equals_offline_on_turns_with_many_categories() -> None:
    x, lengths = turn_dataset(two_channels=True)
    m = CobART.observations(rho=0.99).fit(x, lengths)
    assert m.n_categories_ > 100
    res = m.categorize(x, lengths)
    labels, novel, scores = _stream(m.stream(), x, lengths)
    np.testing.assert_array_equal(labels, res.labels)
    np.testing.assert_array_equal(scores, res.scores)
    np.testing.assert_array_equal(novel, res.novel)


def test_novel_readings_are_flagged_with_the_best_match() -> None:
    m = CobART(window=3, rho=0.9, dcm_scale=0.01).fit(np.zeros(30))
    live = m.stream()
    assert live.update([0.0]) == (0, False, 1.0)
    k, novel, score = live.update(np.array([0.9]))
    assert (k, novel) == (0, True)
    assert 0.0 <= score < 0.9


def test_reset_starts_a_new_episode() -> None:
    x, lengths = turn_dataset()
    m = CobART().fit(x, lengths)
    ep = split(x, lengths)[1]
    live = m.stream()
    first = [live.update(r) for r in ep]
    live.reset()
    again = [live.update(r) for r in ep]
    assert first == again


def test_snapshot_is_not_affected_by_later_learning() -> None:
    x, lengths = turn_dataset()
    m = CobART().fit(x, lengths)
    live = m.stream()
    before = [live.update(r) for r in x[:50]]
    m.partial_fit(-x, lengths)
    live.reset()
    assert [live.update(r) for r in x[:50]] == before


def test_bad_readings() -> None:
    m = CobART(window=3).fit(np.zeros((20, 2)))
    live = m.stream()
    assert live.n_channels == 2 and live.window == 3
    with pytest.raises(ConfigError, match=r"\(2,\)"):
        live.update([0.0, 0.0, 0.0])
    with pytest.raises(ConfigError):
        live.update(np.zeros((1, 2)))
    with pytest.raises(DatasetError):
        live.update([np.nan, 0.0])
    # a refused reading leaves the window untouched
    assert live.update([0.0, 0.0]) == (0, False, 1.0)


def test_scalar_reading_for_one_channel() -> None:
    m = CobART(window=2).fit(np.zeros(10))
    assert m.stream().update(0.0)[0] == 0


def test_mismatch_view_tracks_the_last_reading() -> None:
    x = np.r_[np.zeros(15), np.linspace(0, 0.6, 40), np.full(15, 0.6)][:, None]
    model = CobART.motion_primitives().fit(x)
    live = model.stream()
    view = live.mismatch
    for reading in x:
        k, _, score = live.update(reading)
        assert int(np.argmin(view)) == k
        assert 1.0 - view[k] == pytest.approx(score, abs=1e-9)
    with pytest.raises(ValueError):
        view[0] = 0.0
