"""Fuzzing ``--start`` / ``--goal`` parsing: validated values or our error, nothing else."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from behavior_hmm.cli._common import START_KEYS, parse_assignments, parse_start
from behavior_hmm.errors import BehaviorHMMError
from behavior_hmm.models._goals import check_goal

FUZZ = settings(max_examples=150, deadline=None)

KEYS = [*START_KEYS, "linear_velocity", "angular_velocity", "noise", "random", "", " angle", "x"]
VALUES = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**30), 10**30).map(str),
    st.sampled_from(["", "nan", "inf", "-inf", "1e999", "1_0", " 5 ", "0x10", "abc", "=", "١٢"]),
    st.text(max_size=8),
)
PAIR = st.tuples(st.sampled_from(KEYS), st.sampled_from(["=", "", "==", " = "]), VALUES)
TEXT = st.one_of(
    st.text(max_size=40),
    st.lists(PAIR, max_size=4).map(lambda ps: ",".join(f"{k}{s}{v}" for k, s, v in ps)),
)


def _check_start(start: dict[str, float]) -> None:
    assert start and set(start) <= set(START_KEYS)
    assert all(isinstance(v, float) and math.isfinite(v) for v in start.values())
    assert -180.0 <= start.get("angle", 0.0) <= 180.0
    assert 0.0 <= start.get("distance", 0.0) <= 1.2


@FUZZ
@given(TEXT)
def test_a_start_is_valid_or_our_error(text: str) -> None:
    try:
        start = parse_start(text)
    except BehaviorHMMError:
        return
    _check_start(start)


@FUZZ
@given(TEXT, st.sampled_from([("angle",), ("distance", "angle"), ("angular_velocity",)]))
def test_a_goal_is_valid_or_our_error(text: str, inputs: tuple[str, ...]) -> None:
    """What ``generate`` does with --goal: parse, then the model's own goal check."""
    try:
        goal = check_goal(parse_assignments(text, "--goal"), inputs)
    except BehaviorHMMError:
        return
    assert goal and set(goal) <= set(inputs)
    assert all(math.isfinite(v) for v in goal.values())


@FUZZ
@given(st.lists(st.tuples(st.sampled_from(START_KEYS), st.floats(-1, 1)), min_size=1, max_size=4))
def test_a_repeated_channel_is_refused(pairs: list[tuple[str, float]]) -> None:
    text = ",".join(f"{key}={value!r}" for key, value in pairs)
    keys = [key for key, _ in pairs]
    if len(set(keys)) < len(keys):
        with pytest.raises(BehaviorHMMError, match="twice"):
            parse_assignments(text, "--start")
    else:
        assert parse_assignments(text, "--start") == dict(pairs)
