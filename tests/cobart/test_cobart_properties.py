"""Property tests (hypothesis) of CobART categorization."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from cobart_testing import episodes, params, split, turn_dataset, window_at
from hypothesis import given, settings
from hypothesis import strategies as st

from behavior_hmm.cobart import CobART

FAST = settings(max_examples=50, deadline=None)


@FAST
@given(episodes(), params)
def test_identical_windows_resolve_to_the_same_category(
    data: tuple[np.ndarray, list[int]], kw: dict[str, Any]
) -> None:
    """Without feedback (a = 1) the category is a function of the window alone."""
    x, lengths = data
    kw = {**kw, "a": 1.0}
    m = CobART(**kw, dcm_scale=0.02).fit(x, lengths)
    res = m.categorize(x, lengths)
    seen: dict[bytes, tuple[int, float]] = {}
    offset = 0
    for ep in split(x, lengths):
        for t in range(len(ep)):
            key = window_at(ep, t, m.window).tobytes()
            got = (int(res.labels[offset + t]), float(res.scores[offset + t]))
            assert seen.setdefault(key, got) == got
        offset += len(ep)


@FAST
@given(episodes(max_episodes=2), params)
def test_a_repeated_episode_gets_the_same_categories(
    data: tuple[np.ndarray, list[int]], kw: dict[str, Any]
) -> None:
    """With feedback (any a) identical episodes give identical category sequences."""
    x, lengths = data
    m = CobART(**kw).fit(x, lengths)
    ep = split(x, lengths)[0]
    res = m.categorize(np.concatenate([ep, x, ep]), [len(ep), *lengths, len(ep)])
    n = len(ep)
    np.testing.assert_array_equal(res.labels[:n], res.labels[-n:])
    np.testing.assert_array_equal(res.scores[:n], res.scores[-n:])


@FAST
@given(episodes(), params)
def test_zero_vigilance_gives_one_category(
    data: tuple[np.ndarray, list[int]], kw: dict[str, Any]
) -> None:
    x, lengths = data
    m = CobART(**{**kw, "rho": 0.0}).fit(x, lengths)
    assert m.n_categories_ == 1
    assert m.counts_.tolist() == [len(x)]
    assert not m.categorize(x, lengths).novel.any()


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(-1, 1), min_size=1, max_size=25),
    st.floats(0.0, 1.0),
    st.floats(0.0, 1.0),
    st.floats(0.0, 1.0),
)
def test_raising_vigilance_never_lowers_the_count_for_scalar_readings(
    values: list[float], rho1: float, rho2: float, b: float
) -> None:
    """Proven for fixed prototypes (d = 0), no feedback (a = 1), windows of one reading.

    See docs/notes/cobart.md: on a line every category of the coarser run can be
    charged to a distinct category of the finer one. In more dimensions it does not
    hold (test below).
    """
    x = np.asarray(values)[:, None]
    lo, hi = sorted((rho1, rho2))
    kw = {"a": 1.0, "b": b, "d": 0.0, "window": 1}
    assert CobART(rho=hi, **kw).fit(x).n_categories_ >= CobART(rho=lo, **kw).fit(x).n_categories_


def test_raising_vigilance_can_lower_the_count_in_two_dimensions() -> None:
    """A documented counterexample: the finer run puts a category at the centre."""
    x = np.array([[0.1, -0.2], [-0.1, 0.2], [0.4, 0.2], [-0.4, 0.2]])
    kw = {"a": 1.0, "d": 0.0, "window": 1}
    assert CobART(rho=0.68, **kw).fit(x).n_categories_ == 3
    assert CobART(rho=0.73, **kw).fit(x).n_categories_ == 2


@pytest.mark.parametrize("preset", ["motion_primitives", "observations"])
@pytest.mark.parametrize("two_channels", [False, True])
def test_raising_vigilance_adds_categories_on_turns(preset: str, two_channels: bool) -> None:
    x, lengths = turn_dataset(two_channels=two_channels)
    counts = [
        getattr(CobART, preset)(rho=rho).fit(x, lengths).n_categories_
        for rho in (0.0, 0.5, 0.7, 0.8, 0.85, 0.9, 0.95, 0.98)
    ]
    assert counts == sorted(counts)
    assert counts[0] == 1 and counts[-1] > counts[0]


@FAST
@given(episodes(), params, st.floats(0.05, 2.0), st.floats(1e-3, 0.5))
def test_scores_stay_in_the_unit_interval(
    data: tuple[np.ndarray, list[int]], kw: dict[str, Any], edm: float, dcm: float
) -> None:
    x, lengths = data
    m = CobART(**kw, edm_scale=edm, dcm_scale=dcm).fit(x, lengths)
    res = m.categorize(x * 1.5, lengths)  # also outside [-1, 1]
    assert np.all((res.scores >= 0.0) & (res.scores <= 1.0))
    win = m.score_window(np.zeros((m.window, x.shape[1])))
    assert np.all((win >= 0.0) & (win <= 1.0))


@FAST
@given(episodes(), params)
def test_same_data_and_order_give_identical_prototypes(
    data: tuple[np.ndarray, list[int]], kw: dict[str, Any]
) -> None:
    x, lengths = data
    a = CobART(**kw).fit(x, lengths)
    b = CobART(**kw).fit(x.copy(), list(lengths))
    assert a.prototypes_.tobytes() == b.prototypes_.tobytes()
    assert a.counts_.tolist() == b.counts_.tolist()
    np.testing.assert_array_equal(a.labels_, b.labels_)
