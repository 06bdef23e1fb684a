"""The in-memory Dataset container."""

from __future__ import annotations

import doctest

import numpy as np
import pytest

import behavior_hmm.data._dataset
import behavior_hmm.data._filter
import behavior_hmm.data._normalize
from behavior_hmm.data import (
    COMMAND_CHANNELS,
    SCHEMA_VERSION,
    SENSOR_CHANNELS,
    Dataset,
    Episode,
    validate,
)
from behavior_hmm.errors import ConfigError, DatasetError


def test_sizes_ids_and_offsets(small_ds: Dataset) -> None:
    assert len(small_ds) == 4
    assert small_ds.lengths.tolist() == [60, 70, 80, 90]
    assert small_ds.n_samples == 300
    assert small_ds.offsets.tolist() == [0, 60, 130, 210, 300]
    assert small_ds.episode_ids.tolist() == [0, 1, 2, 3]
    assert small_ds.sensors.shape == (300, 4)
    assert small_ds.commands.shape == (300, 2)
    assert small_ds.metadata["schema_version"] == SCHEMA_VERSION
    assert not small_ds.has_behavior and small_ds.behavior is None


def test_episode_views_match_columns(small_ds: Dataset, episode_factory) -> None:
    ep = small_ds.episode(2)
    src = episode_factory(150, 0.8, n=80)
    assert isinstance(ep, Episode) and ep.id == 2 and len(ep) == 80
    np.testing.assert_array_equal(ep.t, src["t"])
    for j, name in enumerate(SENSOR_CHANNELS):
        np.testing.assert_array_equal(ep.sensors[:, j], src[name])
        np.testing.assert_array_equal(ep.channel(name), src[name])
    for j, name in enumerate(COMMAND_CHANNELS):
        np.testing.assert_array_equal(ep.commands[:, j], src[name])
    assert ep.columns(["angle", "left"]).shape == (80, 2)
    assert [e.id for e in small_ds.episodes()] == [0, 1, 2, 3]
    assert small_ds.episode(-1).id == 3
    with pytest.raises(IndexError):
        small_ds.episode(4)


def test_arrays_are_read_only(small_ds: Dataset) -> None:
    with pytest.raises(ValueError):
        small_ds.t[0] = 5.0
    with pytest.raises(ValueError):
        small_ds.episode(0).sensors[0, 0] = 5.0
    md = small_ds.metadata
    md["behavior"] = "changed"
    assert small_ds.metadata["behavior"] == "turn_approach"


def test_columns_in_requested_order(small_ds: Dataset) -> None:
    x = small_ds.columns(["angle", "distance", "t"])
    assert x.shape == (300, 3)
    np.testing.assert_array_equal(x[:, 0], small_ds.column("angle"))
    np.testing.assert_array_equal(x[:, 1], small_ds.sensors[:, 0])
    np.testing.assert_array_equal(x[:, 2], small_ds.t)
    assert small_ds.columns("right").shape == (300, 1)


def test_unknown_channel_suggests_closest(small_ds: Dataset) -> None:
    with pytest.raises(ConfigError, match="did you mean 'angle'"):
        small_ds.columns(["angel"])


def test_from_episodes_accepts_episode_views_and_ids(small_ds: Dataset) -> None:
    again = Dataset.from_episodes(list(small_ds.episodes()), small_ds.metadata)
    assert again == small_ds
    d = small_ds.episode(0).to_dict()
    d["episode"] = 42
    ds = Dataset.from_episodes([d])
    assert ds.episode_ids.tolist() == [42]


def test_scalar_behavior_is_broadcast(episode_factory) -> None:
    a, b = episode_factory(n=10), episode_factory(n=12)
    a["behavior"], b["behavior"] = "turn", "approach"
    ds = Dataset.from_episodes([a, b])
    assert ds.has_behavior and ds.behaviors == ["approach", "turn"]
    assert ds.episode(1).behavior.tolist() == ["approach"] * 12


def test_behavior_on_some_episodes_only_is_refused(episode_factory) -> None:
    a, b = episode_factory(n=10), episode_factory(n=12)
    a["behavior"] = "turn"
    with pytest.raises(DatasetError, match="some episodes") as info:
        Dataset.from_episodes([a, b])
    assert info.value.episode == 1


def test_empty_episode_and_empty_dataset_are_refused(episode_factory) -> None:
    empty = {k: v[:0] for k, v in episode_factory(n=10).items()}
    with pytest.raises(DatasetError, match="empty episode") as info:
        Dataset.from_episodes([episode_factory(n=10), empty])
    assert info.value.episode == 1
    with pytest.raises(DatasetError, match="no episodes"):
        Dataset.from_episodes([])


def test_from_episodes_names_the_episode_with_a_bad_column(episode_factory) -> None:
    bad = episode_factory(n=10)
    bad["angel"] = bad.pop("angle")
    with pytest.raises(DatasetError, match="did you mean 'angle'") as info:
        Dataset.from_episodes([episode_factory(n=10), bad])
    assert info.value.episode == 1 and info.value.field == "angel"


def test_concat_and_renumber(small_ds: Dataset) -> None:
    with pytest.raises(DatasetError, match="renumber") as info:
        small_ds.concat(small_ds)
    assert info.value.episode == 0
    both = small_ds.concat(small_ds, renumber=True)
    assert len(both) == 8 and both.episode_ids.tolist() == list(range(8))
    assert both.n_samples == 600
    np.testing.assert_array_equal(both.episode(5).sensors, small_ds.episode(1).sensors)


def test_concat_refuses_mixing_behavior_columns(small_ds: Dataset, complex_ds: Dataset) -> None:
    with pytest.raises(DatasetError, match="behavior"):
        small_ds.concat(complex_ds, renumber=True)


def test_subset_and_with_metadata(small_ds: Dataset) -> None:
    sub = small_ds.subset([3, 1])
    assert sub.episode_ids.tolist() == [3, 1]
    assert sub.lengths.tolist() == [90, 70]
    with pytest.raises(ConfigError):
        small_ds.subset([1, 1])
    tagged = small_ds.with_metadata(seed=5, noise=(0.01, 0.02))
    assert tagged.metadata["seed"] == 5 and tagged.metadata["noise"] == [0.01, 0.02]
    assert "seed" not in small_ds.metadata
    with pytest.raises(DatasetError, match="schema version"):
        small_ds.with_metadata(schema_version=99)


def test_equality_sees_every_part(small_ds: Dataset) -> None:
    same = Dataset(small_ds.to_columns(), small_ds.metadata)
    assert same == small_ds
    cols = small_ds.to_columns()
    cols["right"][7] += 1e-9
    assert Dataset(cols, small_ds.metadata) != small_ds
    assert small_ds.with_metadata(seed=1) != small_ds


def test_metadata_must_be_json(small_ds: Dataset) -> None:
    with pytest.raises(DatasetError, match="JSON") as info:
        small_ds.with_metadata(robot=object())
    assert info.value.field == "metadata"
    with pytest.raises(DatasetError, match="JSON"):
        small_ds.with_metadata(noise=float("nan"))


def test_metadata_behavior_names_are_checked(small_ds: Dataset) -> None:
    with pytest.raises(DatasetError, match="invalid behavior name"):
        small_ds.with_metadata(behavior="Turn Left")


def test_check_behaviors_names_first_unknown_row(complex_ds: Dataset) -> None:
    complex_ds.check_behaviors(["turn", "approach"])
    with pytest.raises(DatasetError, match="unknown behavior 'approach'") as info:
        complex_ds.check_behaviors(["turn"])
    ep0 = complex_ds.episode(0).behavior.tolist()
    assert info.value.episode == 0 and info.value.row == ep0.index("approach")


def test_validate_accepts_good_and_refuses_bad_columns(small_ds: Dataset) -> None:
    cols = small_ds.to_columns()
    validate(cols)
    cols["angle"][3] = np.nan
    with pytest.raises(DatasetError, match="NaN") as info:
        validate(cols, file="x.parquet")
    assert (info.value.file, info.value.episode, info.value.row, info.value.field) == (
        "x.parquet",
        0,
        3,
        "angle",
    )


def test_repr_is_short(small_ds: Dataset, complex_ds: Dataset) -> None:
    assert repr(small_ds) == "Dataset(4 episodes, 300 samples, behavior='turn_approach')"
    assert "sub-behaviors=['approach', 'turn']" in repr(complex_ds)


@pytest.mark.parametrize(
    "module",
    [behavior_hmm.data._dataset, behavior_hmm.data._filter, behavior_hmm.data._normalize],
)
def test_docstring_examples(module) -> None:
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0
