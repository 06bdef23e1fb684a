"""Primitive sequences and transition counts (thesis §6.1)."""

from __future__ import annotations

import numpy as np
import pytest
from cobart_testing import split, turn_dataset

from behavior_hmm.cobart import CobART, primitive_sequence, transition_counts
from behavior_hmm.errors import ConfigError


def test_primitive_sequence_collapses_runs() -> None:
    assert primitive_sequence([3, 3, 4, 4, 4, 1, 2, 2]) == [3, 4, 1, 2]
    assert primitive_sequence(np.array([7])) == [7]
    assert primitive_sequence([]) == []
    assert primitive_sequence([0, 1, 0]) == [0, 1, 0]


def test_transition_counts_with_self_transitions() -> None:
    counts = transition_counts([0, 0, 1, 1, 2], None)
    expected = np.zeros((3, 3), dtype=int)
    expected[0, 0] = expected[0, 1] = expected[1, 1] = expected[1, 2] = 1
    np.testing.assert_array_equal(counts, expected)


def test_transition_counts_respect_episodes_and_collapse() -> None:
    labels = [0, 0, 1, 2, 2, 0]
    counts = transition_counts(labels, [3, 3], n_categories=4, collapse=True)
    assert counts.shape == (4, 4)
    assert counts[1, 2] == 0  # 1 -> 2 crosses the episode boundary
    assert counts[0, 1] == 1 and counts[2, 0] == 1
    assert np.trace(counts) == 0
    full = transition_counts(labels, [3, 3])
    assert full.sum() == len(labels) - 2


def test_turns_share_their_final_primitives() -> None:
    """Thesis table 6.1: turns from the same side end with the same primitives."""
    x, lengths = turn_dataset()  # starts -1 .. -0.25, then 0.25 .. 1
    m = CobART.motion_primitives().fit(x, lengths)
    seqs = [primitive_sequence(lab) for lab in split(m.labels_, lengths)]
    negative = {tuple(s[-2:]) for s in seqs[:4]}
    positive = {tuple(s[-2:]) for s in seqs[4:]}
    assert len(negative) == 1 and len(positive) == 1
    assert negative != positive
    assert len({s[0] for s in seqs}) == len(seqs)  # different starts, different first primitive
    counts = transition_counts(m.labels_, lengths)
    assert counts.sum() == len(x) - len(lengths)


@pytest.mark.parametrize(
    ("labels", "kw"),
    [
        ([[0, 1]], {}),
        ([-1, 0], {}),
        ([0.5, 1.0], {}),
        ([0, 3], {"n_categories": 2}),
        ([0, 1, 2], {"lengths": [1, 1]}),
    ],
)
def test_bad_labels(labels: list, kw: dict) -> None:
    with pytest.raises(ConfigError):
        transition_counts(labels, **kw)
