"""make_windows: causal, padded per episode, channel-major."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from behavior_hmm.errors import ConfigError
from behavior_hmm.generators import make_windows


def test_feature_order_and_padding() -> None:
    signals = np.array([[1.0, 10.0], [2.0, 20.0], [3.0, 30.0], [4.0, 40.0]])
    windows = make_windows(signals, [3, 1], window=3)
    assert windows.shape == (4, 6)
    np.testing.assert_array_equal(windows[0], [1, 1, 1, 10, 10, 10])  # flat first window
    np.testing.assert_array_equal(windows[1], [1, 1, 2, 10, 10, 20])
    np.testing.assert_array_equal(windows[2], [1, 2, 3, 10, 20, 30])
    np.testing.assert_array_equal(windows[3], [4, 4, 4, 40, 40, 40])  # new episode restarts


def test_one_channel_and_one_episode_defaults() -> None:
    windows = make_windows(np.arange(5.0), window=2)
    np.testing.assert_array_equal(windows, [[0, 0], [0, 1], [1, 2], [2, 3], [3, 4]])


@settings(max_examples=50, deadline=None)
@given(
    lengths=st.lists(st.integers(1, 12), min_size=1, max_size=5),
    window=st.integers(1, 6),
    channels=st.integers(1, 3),
    seed=st.integers(0, 2**16),
)
def test_windows_are_causal_and_stay_in_their_episode(lengths, window, channels, seed) -> None:
    rng = np.random.default_rng(seed)
    n = sum(lengths)
    signals = rng.uniform(-1, 1, (n, channels))
    windows = make_windows(signals, lengths, window)
    assert windows.shape == (n, window * channels)
    starts = np.cumsum([0, *lengths[:-1]])
    for start, length in zip(starts, lengths, strict=True):
        for t in range(start, start + length):
            # Changing anything after row t, or in another episode, leaves row t alone.
            changed = signals.copy()
            changed[t + 1 :] += 5.0
            changed[:start] -= 5.0
            np.testing.assert_array_equal(make_windows(changed, lengths, window)[t], windows[t])
            # Newest reading of each channel is row t itself.
            np.testing.assert_array_equal(windows[t, window - 1 :: window], signals[t])
            # Oldest reading is row max(start, t - window + 1).
            np.testing.assert_array_equal(windows[t, ::window], signals[max(start, t - window + 1)])


@pytest.mark.parametrize(
    ("signals", "lengths", "window"),
    [
        (np.zeros((4, 1)), [2, 1], 3),  # lengths do not sum to n
        (np.zeros((4, 1)), [4, 0], 3),
        (np.zeros((4, 1)), [4.0], 3),
        (np.zeros((4, 1)), None, 0),
        (np.zeros((4, 1)), None, True),
        (np.full((4, 1), np.nan), None, 3),
        (np.zeros((4, 1, 1)), None, 3),
        ([["a"]], None, 3),
    ],
)
def test_bad_arguments_raise_config_error(signals, lengths, window) -> None:
    with pytest.raises(ConfigError):
        make_windows(signals, lengths, window)


def test_no_rows_gives_no_windows() -> None:
    assert make_windows(np.zeros((0, 2)), [], window=3).shape == (0, 6)
