"""One feature layout for training and the policy: the online rows equal the offline ones."""

from __future__ import annotations

import numpy as np
import pytest

from behavior_hmm.generators._features import (
    DEFAULT_ONSET_CLOCK,
    FeatureLayout,
    OnlineFeatures,
    grown_ranges,
    input_ranges,
    onset_floors,
    start_ranges,
)
from behavior_hmm.teach import collect


@pytest.mark.parametrize(
    "layout",
    [
        FeatureLayout(n_channels=2, window=4),
        FeatureLayout(n_channels=1, window=10, history=3, clock=8),
        FeatureLayout(n_channels=2, window=3, history=2, delta=True, clock=5, delta_scale=0.3),
        FeatureLayout(n_channels=3, window=5, goal=2, history=1, clock=4),
    ],
)
def test_online_rows_equal_offline_rows(layout: FeatureLayout) -> None:
    rng = np.random.default_rng(0)
    lengths = [7, 12]
    x = rng.uniform(-1, 1, size=(sum(lengths), layout.n_channels))
    goals = np.repeat(rng.uniform(-1, 1, size=(2, layout.goal)), lengths, axis=0)
    online = layout.online()
    y = np.zeros((sum(lengths), 2))
    rows = []
    start = 0
    for n in lengths:
        online.reset()
        if layout.goal:
            online.set_goal(goals[start])
        for k in range(start, start + n):
            online.push(x[k])
            rows.append(online.row().copy())
            out = rng.uniform(-1, 1, size=2)  # what a generator answered
            y[k] = online.commit(out)
        start += n
    offline = layout.offline(x, y, lengths, goals if layout.goal else None)
    assert offline.shape == (sum(lengths), layout.width)
    np.testing.assert_allclose(np.asarray(rows), offline, atol=1e-12)


def test_delta_commands_accumulate_within_bounds() -> None:
    online = FeatureLayout(n_channels=1, window=2, history=1, delta=True, delta_scale=0.5).online()
    online.push(np.zeros(1))
    commands = []
    for _ in range(5):
        online.row()
        commands.append(online.commit(np.array([1.0, -1.0])).copy())
    assert commands[0].tolist() == [0.5, -0.5]
    assert commands[-1].tolist() == [1.5, -1.5]  # clipped at DELTA_COMMAND_BOUND


@pytest.mark.parametrize(
    ("behavior", "starts"),
    [
        ("turn", [{"angle": a, "distance": 0.5} for a in (-170.0, -60.0, 40.0, 180.0)]),
        ("approach", [{"distance": d} for d in (0.2, 0.5, 1.0)]),
    ],
)
def test_default_onset_clock_covers_the_start_up_ramps(
    behavior: str, starts: list[dict[str, float]]
) -> None:
    """The clock must still be running while a demonstration accelerates: a clock that
    saturates mid-ramp leaves the rest of the ramp to the flat-looking window."""
    data = collect(behavior, starts, sim="kinematic", seed=0)
    ramps = []
    for episode in range(len(data.lengths)):
        speed = np.abs(data.episode(episode).commands).max(axis=1)
        ramps.append(int(np.argmax(speed >= 0.9 * speed.max())))  # cycles to 90 % of peak
    assert max(ramps) > 64  # turn 73, approach 95: a 64-cycle clock saturated mid-ramp
    assert max(ramps) <= DEFAULT_ONSET_CLOCK


def test_a_resumed_clock_goes_on_from_where_it_stopped() -> None:
    layout = FeatureLayout(n_channels=1, window=2, clock=8)
    features = OnlineFeatures(layout)
    features.push(np.array([0.3]))
    for _ in range(5):
        features.row()
    assert features.cycles == 5
    features.reset()
    assert features.cycles == 0 and features.row()[-1] == 0.0  # a new start
    features.reset()
    features.resume(5)
    assert features.row()[-1] == pytest.approx(5 / 8)  # the run goes on
    features.resume(30)
    assert features.row()[-1] == 1.0  # saturated


def test_onset_floors_are_each_primitives_earliest_clock() -> None:
    clock = np.array([0.0, 0.1, 0.2, 0.9, 1.0, 0.5, 0.6])
    states = np.array([0, 0, 2, 2, 2, 3, 0])
    # primitive 1 has no rows: nothing to hold it to
    assert onset_floors(clock, states, 4).tolist() == [0.0, 0.0, 0.2, 0.5]
    assert onset_floors(np.array([]), np.array([], dtype=np.int64), 2).tolist() == [0.0, 0.0]


def test_input_ranges_are_each_primitives_lowest_and_highest_window_values() -> None:
    windows = np.array([[0.0, 1.0], [0.2, -1.0], [0.5, 0.5], [0.9, 0.4], [-0.3, 0.0]])
    states = np.array([0, 0, 2, 2, 3])
    ranges = input_ranges(windows, states, 4)
    assert ranges.shape == (4, 2, 2)
    assert ranges[0].tolist() == [[0.0, -1.0], [0.2, 1.0]]
    assert ranges[2].tolist() == [[0.5, 0.4], [0.9, 0.5]]
    assert ranges[3].tolist() == [[-0.3, 0.0], [-0.3, 0.0]]
    # primitive 1 has no rows: all rows' range
    assert ranges[1].tolist() == [[-0.3, -1.0], [0.9, 1.0]]


def test_grown_ranges_widen_only_primitives_with_new_rows() -> None:
    old = input_ranges(np.array([[0.0], [0.5], [0.2]]), np.array([0, 1, 1]), 2)
    fresh_rows, fresh_states = np.array([[-0.4], [0.9]]), np.array([1, 2])
    grown = grown_ranges(old, input_ranges(fresh_rows, fresh_states, 3), fresh_states)
    assert grown.shape == (3, 2, 1)
    assert grown[0].tolist() == old[0].tolist()  # no new rows: as it was
    assert grown[1].tolist() == [[-0.4], [0.5]]  # the union of its old and new rows
    assert grown[2].tolist() == [[0.9], [0.9]]  # a new primitive: its own rows


def test_start_ranges_widen_with_the_onset_clock() -> None:
    # two channels of windows of 2; clock of 4 cycles (a row's clock: min(k, 4) / 4)
    windows = np.array(
        [
            [0.5, 0.6, 0.0, 0.0],  # primitive 0 at cycle 0
            [0.3, 0.4, 0.1, 0.2],  # primitive 0 at cycle 2
            [-0.2, 0.0, -0.5, 0.9],  # primitive 0 from cycle 4 on (the clock's end)
            [0.8, 0.9, 0.3, 0.3],  # primitive 2 at cycle 1
        ]
    )
    clock = np.array([0.0, 0.5, 1.0, 0.25])
    states = np.array([0, 0, 0, 2])
    ranges = start_ranges(windows, clock, states, 3, 2, 4)
    assert ranges.shape == (3, 2, 5, 2)
    # primitive 0, channel 0: what its rows held by cycles 0..4
    assert ranges[0, 0].tolist() == [
        [0.5, 0.6],
        [0.5, 0.6],
        [0.3, 0.6],
        [0.3, 0.6],
        [-0.2, 0.6],
    ]
    assert ranges[0, 1, 4].tolist() == [-0.5, 0.9]  # the clock's end: every row
    # no row by cycle 0 for primitive 2, none at all for primitive 1
    assert np.isnan(ranges[2, :, 0]).all() and ranges[2, 0, 1].tolist() == [0.8, 0.9]
    assert np.isnan(ranges[1]).all()
    # the clock's end holds each primitive's whole range (input_ranges of its rows)
    whole = input_ranges(windows, states, 3)
    np.testing.assert_array_equal(ranges[0, 0, 4], [whole[0, 0, :2].min(), whole[0, 1, :2].max()])


def test_grown_start_ranges_widen_only_primitives_with_new_rows() -> None:
    old = start_ranges(np.array([[0.2], [0.5]]), np.array([0.0, 1.0]), np.array([0, 1]), 2, 1, 2)
    rows, clock, states = np.array([[-0.4], [0.9]]), np.array([0.5, 0.0]), np.array([1, 2])
    grown = grown_ranges(old, start_ranges(rows, clock, states, 3, 1, 2), states, side=-1)
    assert grown.shape == (3, 1, 3, 2)
    np.testing.assert_array_equal(grown[0], old[0])  # no new rows: as it was
    # primitive 1 had a row at the clock's end only; its new one came at cycle 1
    assert np.isnan(grown[1, 0, 0]).all()
    assert grown[1, 0, 1:].tolist() == [[-0.4, -0.4], [-0.4, 0.5]]
    assert grown[2, 0].tolist() == [[0.9, 0.9]] * 3  # a new primitive: its own rows
