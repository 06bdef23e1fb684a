"""Screening a step by the last fully scanned one (module ``_reference``): the same winners,
prototypes, counts, labels and scores as scoring every category, to the bit."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from cobart_testing import assert_same_bits as _same
from cobart_testing import episodes, params
from hypothesis import HealthCheck, given, settings

from behavior_hmm.cobart import CobART, _reference
from behavior_hmm.cobart import _compiled as compiled


@pytest.fixture
def numpy_paths() -> Iterator[None]:
    previous = compiled.set_kernel("numpy")
    yield
    compiled.set_kernel(previous)


def _run(x: np.ndarray, lengths: list[int], kw: dict[str, Any]) -> tuple[np.ndarray, ...]:
    model = CobART(**kw).fit(x, lengths)
    cat = model.categorize(x, lengths)
    return model.labels_, model.prototypes_, model.counts_, cat.labels, cat.scores


def _with(monkeypatch: pytest.MonkeyPatch, min_categories: int, limit: int, *args: Any) -> Any:
    with monkeypatch.context() as m:
        m.setattr(_reference, "REFERENCE_MIN_CATEGORIES", min_categories)
        m.setattr(_reference, "SCREEN_LIMIT", limit)
        return _run(*args)


@pytest.mark.usefixtures("numpy_paths")
@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=episodes(max_channels=3, max_episodes=4, max_len=60), kw=params)
def test_screened_steps_choose_what_a_full_scan_does(
    data: tuple[np.ndarray, list[int]], kw: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Random walks (repeated readings and exact ties among them), every model screened
    from its first category on, with few or many candidates allowed a step."""
    x, lengths = data
    full = _with(monkeypatch, 10**9, 32, x, lengths, kw)
    _same(full, _with(monkeypatch, 1, 32, x, lengths, kw))
    _same(full, _with(monkeypatch, 1, 2, x, lengths, kw))


def test_many_categories_are_screened_and_match_the_full_scan(
    numpy_paths: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A vigilant network over slow 2-channel walks learns over REFERENCE_MIN_CATEGORIES
    categories; with the default settings most steps score a few of them, and the results
    are the full scan's."""
    rng = np.random.default_rng(7)
    lengths = [300] * 6
    x = np.clip(
        rng.uniform(-1, 1, (1, 2)) + np.cumsum(rng.normal(0, 0.04, (sum(lengths), 2)), axis=0),
        -1,
        1,
    )
    kw = {"window": 3, "rho": 0.985, "a": 0.6}
    full = _with(monkeypatch, 10**9, 32, x, lengths, kw)
    assert full[1].shape[0] > _reference.REFERENCE_MIN_CATEGORIES
    scans: list[int] = []
    real = _reference.ReferenceScreen.set_reference

    def counted(self: Any, *args: Any) -> None:
        scans.append(1)
        real(self, *args)

    monkeypatch.setattr(_reference.ReferenceScreen, "set_reference", counted)
    _same(full, _run(x, lengths, kw))
    assert 0 < len(scans) < 0.5 * 2 * sum(lengths)  # fit and categorize: most steps screened
