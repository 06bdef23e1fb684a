"""to_arrays / from_arrays: round trip and refusal of malformed tables."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from behavior_hmm.errors import ModelFileError
from behavior_hmm.hmm import BehaviorHMM


def fitted() -> BehaviorHMM:
    states = [0, 0, 1, 1, 2, 0, 1, 1, 2, 2]
    obs = [0, 1, 1, 2, 3, 0, 1, 2, 2, 3]
    return BehaviorHMM(smoothing=0.0).fit(states, obs, lengths=[5, 5])


def test_round_trip_reproduces_the_model() -> None:
    hmm = fitted()
    arrays = hmm.to_arrays()
    params = json.loads(json.dumps(hmm.params))  # the params must survive JSON
    back = BehaviorHMM.from_arrays(arrays, params)
    for name in ("log_A_", "log_B_", "log_C_", "log_pi_", "start_prob_first_", "A_counts_"):
        np.testing.assert_array_equal(getattr(back, name), getattr(hmm, name))
    assert back.plan(0, 3) == hmm.plan(0, 3)
    assert back.get_params() == hmm.get_params()
    assert {a.dtype.kind for a in arrays.values()} <= {"f", "i"}


def test_round_trip_with_smoothing_and_no_self_transitions() -> None:
    hmm = BehaviorHMM(smoothing=0.3, self_transitions=False, counting="steps")
    hmm.fit([0, 0, 1, 1, 0], [0, 1, 1, 2, 2])
    back = BehaviorHMM.from_arrays(hmm.to_arrays(), hmm.params)
    np.testing.assert_array_equal(back.log_C_, hmm.log_C_)


def tamper(key: str, change: Callable[[np.ndarray], Any]) -> dict[str, Any]:
    arrays: dict[str, Any] = fitted().to_arrays()
    arrays[key] = change(arrays[key].copy())
    return arrays


def set_nan(a: np.ndarray) -> np.ndarray:
    a[0, 0] = np.nan
    return a


def negative_prob(a: np.ndarray) -> np.ndarray:
    a[0, 0], a[0, 1] = -0.25, a[0, 1] + 0.25 + a[0, 0]
    return a


def swap_rows(a: np.ndarray) -> np.ndarray:
    return a[[1, 0, 2]]


def scale_row(a: np.ndarray) -> np.ndarray:
    a[0] *= 0.9
    return a


@pytest.mark.parametrize(
    ("key", "change", "match"),
    [
        ("A", lambda a: a[:2, :2], "shape"),
        ("B", lambda a: a[:, :3], "shape"),
        ("pi", lambda a: a[None, :], "shape"),
        ("A", set_nan, "NaN"),
        ("A", negative_prob, r"outside \[0, 1\]"),
        ("C", scale_row, "sum to neither"),
        ("A", lambda a: a.astype(np.int64), "floating"),
        ("B_counts", lambda a: a.astype(np.float64), "integer"),
        ("pi_counts", lambda a: -a, "negative"),
        ("A", swap_rows, "does not match"),
        ("A", lambda a: a.tolist(), "not an array"),
    ],
)
def test_from_arrays_refuses_bad_tables(key: str, change: Callable[..., Any], match: str) -> None:
    with pytest.raises(ModelFileError, match=match):
        BehaviorHMM.from_arrays(tamper(key, change), fitted().params)


def test_from_arrays_refuses_missing_and_unexpected_arrays() -> None:
    arrays: dict[str, Any] = fitted().to_arrays()
    del arrays["C_counts"]
    with pytest.raises(ModelFileError, match="missing"):
        BehaviorHMM.from_arrays(arrays, {})
    arrays = {**fitted().to_arrays(), "payload": np.zeros(1)}
    with pytest.raises(ModelFileError, match="unexpected"):
        BehaviorHMM.from_arrays(arrays, {})


@pytest.mark.parametrize(
    ("params", "match"),
    [
        ({"alpha": 1}, "unknown"),
        ({"counting": "pairs"}, "invalid"),
        ({"smoothing": -1}, "invalid"),
        ({"n_states": 7}, "n_states=7"),
    ],
)
def test_from_arrays_refuses_bad_params(params: dict[str, Any], match: str) -> None:
    with pytest.raises(ModelFileError, match=match):
        BehaviorHMM.from_arrays(fitted().to_arrays(), params)


def test_counts_must_match_the_smoothing_they_were_saved_with() -> None:
    hmm = BehaviorHMM(smoothing=1.0).fit([0, 0, 1], [0, 1, 1])
    with pytest.raises(ModelFileError, match="does not match"):
        BehaviorHMM.from_arrays(hmm.to_arrays(), {"smoothing": 0.0})


def test_to_arrays_round_trips_bit_for_bit() -> None:
    rng = np.random.default_rng(7)
    states = rng.integers(0, 5, 400)
    observations = rng.integers(0, 17, 400)
    model = BehaviorHMM(smoothing=0.3).fit(states, observations, [150, 250])
    arrays = model.to_arrays()
    again = BehaviorHMM.from_arrays(arrays, model.params).to_arrays()
    for key, value in arrays.items():
        assert value.tobytes() == again[key].tobytes(), key
