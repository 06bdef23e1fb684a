"""``BehaviorHMM.partial_fit``: counts of new episodes added exactly (issue 29, item 1).

Fitting on episodes A and then ``partial_fit`` on episodes B must leave the model in the
state ``fit`` on A + B leaves it: every attribute, every array byte for byte, and the
same plans and Viterbi decodings afterwards, also when B brings new states (primitives)
or observation categories.
"""

from __future__ import annotations

import copy
import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.sparse import csr_array

from behavior_hmm.errors import ConfigError, DatasetError, UnreachableGoalError
from behavior_hmm.hmm import BehaviorHMM
from behavior_hmm.hmm._tables import LogTable

Episode = tuple[list[int], list[int]]
Part = list[Episode]

RULES: list[dict[str, Any]] = [
    {"counting": counting, "self_transitions": self_transitions, "smoothing": smoothing}
    for counting, self_transitions, smoothing in itertools.product(
        ("changes", "steps"), (True, False), (0.0, 0.5)
    )
]
RULE_IDS = [f"{r['counting']}-self{int(r['self_transitions'])}-k{r['smoothing']}" for r in RULES]


# ------------------------------------------------------------------ helpers
def flatten(parts: Sequence[Part]) -> tuple[list[int], list[int], list[int]]:
    """States, observations and lengths of the episodes of ``parts``, in order."""
    states: list[int] = []
    observations: list[int] = []
    lengths: list[int] = []
    for part in parts:
        for s, o in part:
            states += s
            observations += o
            lengths.append(len(s))
    return states, observations, lengths


def fit_in_pieces(parts: Sequence[Part], **params: Any) -> BehaviorHMM:
    """``fit`` on the first part, ``partial_fit`` on each later one."""
    hmm = BehaviorHMM(**params).fit(*flatten(parts[:1]))
    for part in parts[1:]:
        hmm.partial_fit(*flatten([part]))
    return hmm


def assert_same_value(x: Any, y: Any, name: str) -> None:
    assert type(x) is type(y), name
    if isinstance(x, csr_array):  # sparse counts: the same stored arrays, byte for byte
        assert x.shape == y.shape, name
        for part in ("indptr", "indices", "data"):
            assert_same_value(getattr(x, part), getattr(y, part), f"{name}.{part}")
    elif isinstance(x, LogTable):  # sparse log probabilities: entries and fills
        assert x.shape == y.shape, name
        for part in ("indptr", "indices", "data", "fill"):
            assert_same_value(getattr(x, part), getattr(y, part), f"{name}.{part}")
        assert_same_value(x.toarray(), y.toarray(), f"{name}.toarray()")
    elif isinstance(x, np.ndarray):
        assert x.dtype == y.dtype, name
        assert x.shape == y.shape, name
        assert np.array_equal(x, y), name
        assert x.tobytes() == y.tobytes(), name
    elif isinstance(x, Mapping):
        assert list(x) == list(y), name
        for key in x:
            assert_same_value(x[key], y[key], f"{name}[{key!r}]")
    else:
        assert x == y, name


def assert_same_model(got: BehaviorHMM, want: BehaviorHMM) -> None:
    """Every attribute equal: arrays byte for byte, the count and probability tables first."""
    learned = [k for k in vars(want) if k.endswith("_") and not k.startswith("_")]
    assert {
        "A_counts_",
        "B_counts_",
        "C_counts_",
        "pi_counts_",
        "start_counts_",
        "log_A_",
        "log_B_",
        "log_C_",
        "log_pi_",
        "start_prob_first_",
        "n_states_",
        "n_observations_",
    } <= set(learned)
    assert sorted(vars(got)) == sorted(vars(want))
    for key in vars(want):
        assert_same_value(vars(got)[key], vars(want)[key], key)
    assert_same_value(got.to_arrays(), want.to_arrays(), "to_arrays()")


def outcome(call: Any) -> Any:
    """What a call returns, or the type and message of the error it raises."""
    try:
        return ("ok", call())
    except (UnreachableGoalError, DatasetError, ConfigError) as err:
        return ("error", type(err), str(err))


def same_outcome(a: Any, b: Any) -> bool:
    if a[0] != b[0]:
        return False
    if a[0] == "error":
        return bool(a == b)
    x, y = a[1], b[1]
    if isinstance(x, tuple) and len(x) == 2 and isinstance(x[0], np.ndarray):  # viterbi
        return bool(x[0].tobytes() == y[0].tobytes() and repr(x[1]) == repr(y[1]))
    if isinstance(x, np.ndarray):
        return bool(x.tobytes() == y.tobytes())
    return bool(x == y)


def episode(draw: Any, n_states: int, n_obs: int) -> Episode:
    length = draw(st.integers(1, 6))
    labels = st.lists(st.integers(0, n_states - 1), min_size=length, max_size=length)
    cats = st.lists(st.integers(0, n_obs - 1), min_size=length, max_size=length)
    return draw(labels), draw(cats)


@st.composite
def parts_strategy(draw: Any, grow: bool = True) -> list[Part]:
    """2 to 4 parts of 1 to 3 episodes; with ``grow`` later parts may use higher labels
    (new primitives and categories), without it all parts share the label ranges."""
    n_parts = draw(st.integers(2, 4))
    out: list[Part] = []
    for k in range(n_parts):
        extra = k if grow else 0
        n_eps = draw(st.integers(1, 3))
        out.append([episode(draw, 2 + extra, 3 + extra) for _ in range(n_eps)])
    return out


def sizes(parts: Sequence[Part]) -> tuple[int, int]:
    s, o, _ = flatten(parts)
    return max(s) + 1, max(o) + 1


# ------------------------------------------------------- pieces vs the whole
@pytest.mark.parametrize("rule", RULES, ids=RULE_IDS)
@settings(max_examples=25, deadline=None)
@given(parts=parts_strategy(grow=True))
def test_pieces_equal_the_whole_byte_for_byte(rule: dict[str, Any], parts: list[Part]) -> None:
    """Sizes from the data: new primitives and categories in later parts grow the tables."""
    whole = BehaviorHMM(**rule).fit(*flatten(parts))
    assert_same_model(fit_in_pieces(parts, **rule), whole)


@pytest.mark.parametrize("rule", RULES, ids=RULE_IDS)
@settings(max_examples=15, deadline=None)
@given(parts=parts_strategy(grow=False), pad=st.integers(0, 2))
def test_pieces_equal_the_whole_with_fixed_sizes(
    rule: dict[str, Any], parts: list[Part], pad: int
) -> None:
    """No new category or primitive: sizes declared up front, possibly beyond the data."""
    n, m = sizes(parts)
    params = {**rule, "n_states": n + pad, "n_observations": m + pad}
    whole = BehaviorHMM(**params).fit(*flatten(parts))
    assert_same_model(fit_in_pieces(parts, **params), whole)


@pytest.mark.parametrize("rule", RULES[::3], ids=RULE_IDS[::3])
@settings(max_examples=15, deadline=None)
@given(parts=parts_strategy(grow=True), pad=st.integers(0, 2))
def test_sizes_grown_through_set_params_equal_the_whole(
    rule: dict[str, Any], parts: list[Part], pad: int
) -> None:
    """Each part is fitted under declared sizes, raised with ``set_params`` before it comes."""
    hmm = BehaviorHMM(**rule)
    for k, part in enumerate(parts):
        n, m = sizes(parts[: k + 1])
        hmm.set_params(n_states=n + pad, n_observations=m + pad)
        if k == 0:
            hmm.fit(*flatten([part]))
        else:
            hmm.partial_fit(*flatten([part]))
    n, m = sizes(parts)
    whole = BehaviorHMM(**rule, n_states=n + pad, n_observations=m + pad).fit(*flatten(parts))
    assert_same_model(hmm, whole)


def test_changes_counting_keeps_one_self_transition_per_state() -> None:
    """Not a plain sum: the thesis adds one self transition to every label seen, once."""
    hmm = BehaviorHMM().fit([0, 1], [0, 1])
    hmm.partial_fit([0, 1, 2], [0, 1, 3])
    np.testing.assert_array_equal(hmm.A_counts_, [[1, 2, 0], [0, 1, 1], [0, 0, 1]])
    np.testing.assert_array_equal(
        hmm.C_counts_.toarray(), [[1, 2, 0, 0], [0, 1, 0, 1], [0, 0, 0, 0], [0, 0, 0, 1]]
    )
    assert (hmm.n_states_, hmm.n_observations_) == (3, 4)
    whole = BehaviorHMM().fit([0, 1, 0, 1, 2], [0, 1, 0, 1, 3], lengths=[2, 3])
    assert_same_model(hmm, whole)


def test_partial_fit_of_an_unfitted_model_is_fit() -> None:
    data = ([0, 0, 1, 2, 2], [1, 0, 0, 2, 3], [2, 3])
    got = BehaviorHMM(smoothing=0.25).partial_fit(*data)
    assert_same_model(got, BehaviorHMM(smoothing=0.25).fit(*data))


# ------------------------------------------------------------------ caches
@pytest.mark.parametrize(
    "params",
    [
        {},
        {"smoothing": 0.5},
        {"counting": "steps", "on_impossible": "emissions"},
        {"path_self_loops": "keep", "self_transitions": False, "on_impossible": "emissions"},
    ],
)
@settings(max_examples=10, deadline=None)
@given(parts=parts_strategy(grow=True), data=st.data())
def test_plans_and_viterbi_after_partial_fit_equal_the_whole(
    params: dict[str, Any], parts: list[Part], data: st.DataObject
) -> None:
    """Goal trees, Viterbi messages and plans cached before ``partial_fit`` are not reused."""
    hmm = BehaviorHMM(**params).fit(*flatten(parts[:1]))
    for part in parts[1:]:
        m_now = hmm.n_observations_
        hmm.prepare_goals(range(m_now))  # fill every cache of the smaller model
        for c, g in itertools.product(range(m_now), repeat=2):
            outcome(lambda c=c, g=g: hmm.plan(c, g))
            outcome(lambda c=c, g=g: hmm.state_scores(c, g))
        hmm.partial_fit(*flatten([part]))
    whole = BehaviorHMM(**params).fit(*flatten(parts))
    m = whole.n_observations_
    for c, g in itertools.product(range(m), repeat=2):
        for method in ("plan", "path_log_prob", "most_likely_path", "can_plan", "state_scores"):
            got = outcome(lambda c=c, g=g, f=method: getattr(hmm, f)(c, g))
            want = outcome(lambda c=c, g=g, f=method: getattr(whole, f)(c, g))
            assert same_outcome(got, want), (method, c, g, got, want)
    for _ in range(3):
        obs = data.draw(st.lists(st.integers(0, m - 1), min_size=1, max_size=8))
        got = outcome(lambda obs=obs: hmm.viterbi(obs))
        want = outcome(lambda obs=obs: whole.viterbi(obs))
        assert same_outcome(got, want), (obs, got, want)


def test_a_new_category_becomes_a_reachable_goal() -> None:
    hmm = BehaviorHMM().fit([0, 0, 1], [0, 1, 1])
    hmm.prepare_goals([0, 1])
    assert hmm.plan(0, 1).observations == (0, 1)
    hmm.partial_fit([1, 2, 2], [1, 2, 3])
    plan = hmm.plan(0, 3)
    assert plan.observations == (0, 1, 2, 3)
    assert plan.states == (0, 1, 2, 2)
    states, _ = hmm.viterbi([0, 1, 2, 3])
    assert states.tolist() == [0, 1, 2, 2]


# ------------------------------------------------------------- save / load
@pytest.mark.parametrize("rule", RULES[::2], ids=RULE_IDS[::2])
def test_a_partially_fitted_model_saves_and_loads_like_the_whole(rule: dict[str, Any]) -> None:
    parts: list[Part] = [
        [([0, 0, 1], [0, 1, 1]), ([1, 0], [2, 0])],
        [([2, 2, 0, 1], [3, 3, 0, 1])],
        [([1, 1, 3], [1, 4, 4])],
    ]
    whole = BehaviorHMM(**rule).fit(*flatten(parts))
    pieces = fit_in_pieces(parts, **rule)
    loaded = BehaviorHMM.from_arrays(pieces.to_arrays(), pieces.params)
    assert_same_model(loaded, BehaviorHMM.from_arrays(whole.to_arrays(), whole.params))
    assert_same_model(loaded, whole)
    # a loaded model goes on counting too
    resumed = BehaviorHMM.from_arrays(
        BehaviorHMM(**rule).fit(*flatten(parts[:1])).to_arrays(), rule
    )
    for part in parts[1:]:
        resumed.partial_fit(*flatten([part]))
    assert_same_model(resumed, whole)


# ------------------------------------------------------------------ errors
BAD_INPUTS: dict[str, tuple[Any, Any, Any]] = {
    "lengths do not sum to the samples": ([0, 1, 1], [0, 0, 1], [2]),
    "lengths sum beyond the samples": ([0, 1, 1], [0, 0, 1], [2, 2]),
    "empty episode": ([0, 1, 1], [0, 0, 1], [0, 3]),
    "negative state": ([0, -1, 1], [0, 0, 1], None),
    "negative observation": ([0, 1, 1], [0, 0, -2], None),
    "different lengths": ([0, 1, 1], [0, 0], None),
    "no samples": ([], [], None),
    "float labels": ([0.0, 1.0], [0, 1], None),
    "2-D states": ([[0, 1]], [[0, 1]], None),
    "float lengths": ([0, 1], [0, 1], [1.0, 1.0]),
}


@pytest.mark.parametrize("bad", list(BAD_INPUTS), ids=list(BAD_INPUTS))
def test_inconsistent_inputs_raise_what_fit_raises(bad: str) -> None:
    states, observations, lengths = BAD_INPUTS[bad]
    with pytest.raises(DatasetError) as fit_error:
        BehaviorHMM().fit(states, observations, lengths)
    hmm = BehaviorHMM().fit([0, 1, 1, 0], [0, 0, 1, 1], [1, 3])
    before = copy.deepcopy(hmm)
    with pytest.raises(DatasetError) as partial_error:
        hmm.partial_fit(states, observations, lengths)
    want, got = fit_error.value, partial_error.value
    assert str(got) == str(want)
    assert (got.episode, got.row, got.field) == (want.episode, want.row, want.field)
    assert_same_model(hmm, before)  # nothing changed


def test_labels_beyond_declared_sizes_raise_what_fit_raises() -> None:
    states, observations = [0, 4, 1], [0, 0, 1]
    with pytest.raises(DatasetError) as fit_error:
        BehaviorHMM(n_states=3).fit(states, observations)
    hmm = BehaviorHMM(n_states=3).fit([0, 1, 2], [0, 1, 2])
    before = copy.deepcopy(hmm)
    with pytest.raises(DatasetError) as partial_error:
        hmm.partial_fit(states, observations)
    assert str(partial_error.value) == str(fit_error.value)
    assert partial_error.value.row == fit_error.value.row == 1
    assert_same_model(hmm, before)


def test_invalid_parameters_raise_what_fit_raises() -> None:
    hmm = BehaviorHMM().fit([0, 1], [0, 1])
    hmm.set_params(smoothing=-1.0)
    with pytest.raises(ConfigError) as partial_error:
        hmm.partial_fit([0, 1], [0, 1])
    with pytest.raises(ConfigError) as fit_error:
        BehaviorHMM(smoothing=-1.0).fit([0, 1], [0, 1])
    assert str(partial_error.value) == str(fit_error.value)


@pytest.mark.parametrize(
    "change", [{"counting": "steps"}, {"self_transitions": False}], ids=["counting", "self"]
)
def test_a_changed_counting_rule_is_refused(change: dict[str, Any]) -> None:
    hmm = BehaviorHMM().fit([0, 0, 1], [0, 1, 1])
    hmm.set_params(**change)
    before = copy.deepcopy(hmm)
    with pytest.raises(ConfigError, match="call fit"):
        hmm.partial_fit([1, 0], [1, 0])
    assert_same_model(hmm, before)


def test_declared_sizes_cannot_shrink_the_tables() -> None:
    hmm = BehaviorHMM().fit([0, 1, 2], [0, 1, 3])
    before = copy.deepcopy(hmm)
    hmm.set_params(n_observations=2)
    with pytest.raises(ConfigError, match="cannot shrink"):
        hmm.partial_fit([0, 1], [0, 1])
    hmm.set_params(n_observations=None)
    assert_same_model(hmm, before)


def test_a_smoothing_change_renormalizes_all_counts() -> None:
    """Probabilities come from the total counts under the current smoothing, as in fit."""
    hmm = BehaviorHMM().fit([0, 0, 1], [0, 1, 1])
    hmm.set_params(smoothing=1.0)
    hmm.partial_fit([1, 2], [2, 2])
    whole = BehaviorHMM(smoothing=1.0).fit([0, 0, 1, 1, 2], [0, 1, 1, 2, 2], [3, 2])
    assert_same_model(hmm, whole)
