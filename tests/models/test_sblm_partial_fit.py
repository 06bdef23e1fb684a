"""SBLM.partial_fit (issue 29): an SBLM grows with new demonstrations of its behavior."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from behavior_hmm.data import Dataset
from behavior_hmm.errors import ConfigError, NotFittedError
from behavior_hmm.hmm import BehaviorHMM
from behavior_hmm.hmm._counting import count_emissions
from behavior_hmm.models import SBLM
from behavior_hmm.models._sblm import demonstrated_wheel_response
from behavior_hmm.teach import collect

#: Starts between those of ``turn_data`` (every 20 deg from -170), farther and closer.
NEW_STARTS = [{"angle": float(a), "distance": 0.5} for a in (-155, -95, -35, 25, 85, 145)]


def _copy(model: SBLM, path: Path) -> SBLM:
    """An independent copy of a (session-shared) model, through its file."""
    model.save(path)
    return SBLM.load(path)


def _generator_bytes(model: SBLM, p: int) -> bytes:
    gens = model.generators_
    parts = [w[p].tobytes() for w in (*gens.coefs_, *gens.intercepts_)]
    for arr in (gens.trained_, gens.n_train_, gens.n_test_, gens.best_epoch_):
        parts.append(arr[p].tobytes())
    parts += [gens.train_error_[p].tobytes(), gens.test_error_[p].tobytes()]
    return b"".join(parts)


@pytest.fixture(scope="module")
def new_data() -> Dataset:
    return collect("turn", NEW_STARTS, sim="kinematic", seed=7, noise=0.01)


@pytest.fixture(scope="module")
def updated(
    turn_model: SBLM, new_data: Dataset, tmp_path_factory: pytest.TempPathFactory
) -> tuple[SBLM, SBLM, float]:
    """(the model before, the model after the update, seconds partial_fit took)."""
    folder = tmp_path_factory.mktemp("update")
    before = _copy(turn_model, folder / "before.bhmm")
    after = _copy(turn_model, folder / "after.bhmm")
    t0 = time.perf_counter()
    assert after.partial_fit(new_data, source="new.parquet") is after
    return before, after, time.perf_counter() - t0


def test_existing_categories_keep_their_indices_and_new_ones_come_last(
    updated: tuple[SBLM, SBLM, float],
) -> None:
    before, after, _ = updated
    record = after.updates_[-1]
    for old, new, grown in (
        (before.primitives_, after.primitives_, record["new_primitives"]),
        (before.observations_, after.observations_, record["new_observations"]),
    ):
        k = old.n_categories_
        assert new.n_categories_ == k + grown
        np.testing.assert_array_equal(new.kept_[:k], np.arange(k))
        assert np.all(new.counts_[:k] >= old.counts_)
        # a prototype that no new window resonated with did not move at all
        still = new.counts_[:k] == old.counts_
        assert still.any()
        assert new.prototypes_[:k][still].tobytes() == old.prototypes_[still].tobytes()
        # one that did moved by at most d / (n + 1) of the way per win: a little
        moved = np.abs(new.prototypes_[:k] - old.prototypes_).max()
        assert moved < 0.2
        assert new.dcm_scale_.tobytes() == old.dcm_scale_.tobytes()
    assert after.hmm_.n_states_ == after.primitives_.n_categories_
    assert after.hmm_.n_observations_ == after.observations_.n_categories_
    assert after.generators_.n_primitives_ == after.primitives_.n_categories_


def test_untouched_generators_are_byte_identical(updated: tuple[SBLM, SBLM, float]) -> None:
    before, after, _ = updated
    tuned = set(after.updates_[-1]["fine_tuned"])
    k = before.generators_.n_primitives_
    untouched = [p for p in range(k) if p not in tuned]
    assert untouched and tuned, (untouched, tuned)
    for p in untouched:
        assert _generator_bytes(after, p) == _generator_bytes(before, p), p
    for p in tuned:
        assert _generator_bytes(after, p) != _generator_bytes(before, p), p


def test_hmm_counts_equal_counts_over_the_union(
    turn_model: SBLM, turn_data: Dataset, new_data: Dataset, updated: tuple[SBLM, SBLM, float]
) -> None:
    """The tables after the update are those of fit on the old labels and the new."""
    _, after, _ = updated
    hmm = after.hmm_
    union = BehaviorHMM(
        n_states=hmm.n_states_,
        n_observations=hmm.n_observations_,
        counting=hmm.counting,
        smoothing=hmm.smoothing,
        path_self_loops=hmm.path_self_loops,
    ).fit(
        np.r_[turn_model.train_states_, after.primitives_.labels_],
        np.r_[turn_model.train_observations_, after.observations_.labels_],
        np.r_[turn_data.lengths, new_data.lengths],
    )
    for name in ("A_counts_", "B_counts_", "C_counts_", "pi_counts_", "start_counts_"):
        np.testing.assert_array_equal(_dense(getattr(hmm, name)), _dense(getattr(union, name)))
    for name in ("log_A_", "log_B_", "log_C_", "log_pi_"):
        assert _dense(getattr(hmm, name)).tobytes() == _dense(getattr(union, name)).tobytes()


def test_replayed_demonstrations_add_their_counts_without_new_categories(
    turn_model: SBLM, turn_data: Dataset, tmp_path: Path
) -> None:
    """Demonstrations like those fitted make no new category: the tables grow by their
    counts only (B: old + the new labels' emissions)."""
    model = _copy(turn_model, tmp_path / "m.bhmm")
    old = model.hmm_
    replay = turn_data.subset([2, 9])
    model.partial_fit(replay)
    assert model.updates_[-1]["new_primitives"] == 0
    assert model.updates_[-1]["new_observations"] == 0
    assert model.primitives_.n_categories_ == old.n_states_
    assert model.observations_.n_categories_ == old.n_observations_
    states, obs = model.primitives_.labels_, model.observations_.labels_
    np.testing.assert_array_equal(
        model.hmm_.B_counts_.toarray(),
        (
            old.B_counts_ + count_emissions(states, obs, old.n_states_, old.n_observations_)
        ).toarray(),
    )
    np.testing.assert_array_equal(
        model.hmm_.pi_counts_, old.pi_counts_ + np.bincount(states, minlength=old.n_states_)
    )
    assert model.hmm_.start_counts_.sum() == old.start_counts_.sum() + 2
    # the replay relabels as the fit labelled those episodes (the categories barely moved)
    rows = np.r_[0, np.cumsum(turn_data.lengths)]
    fitted = np.r_[
        turn_model.train_states_[rows[2] : rows[3]], turn_model.train_states_[rows[9] : rows[10]]
    ]
    assert np.mean(states == fitted) > 0.9


def test_new_primitives_get_generators_and_the_model_reaches_its_goals(
    updated: tuple[SBLM, SBLM, float], kinematic_env: Any
) -> None:
    before, after, _ = updated
    k = before.primitives_.n_categories_
    assert after.updates_[-1]["new_primitives"] > 0
    assert after.generators_.trained_[k:].all()
    assert after.generators_.n_train_[k:].min() > 0
    for angle in (120.0, -95.0, 35.0, -170.0):
        trace = after.generate(kinematic_env, start={"angle": angle, "distance": 0.5}, seed=0)
        assert trace.goal_reached, (angle, trace.summary())


def test_data_dependent_state_is_that_of_all_the_demonstrations(
    turn_model: SBLM, turn_data: Dataset, new_data: Dataset, updated: tuple[SBLM, SBLM, float]
) -> None:
    before, after, _ = updated
    finals = new_data.offsets[1:] - 1
    np.testing.assert_array_equal(
        after.stops_, np.vstack([before.stops_, new_data.columns(["angle"])[finals]])
    )
    assert after.rest_values_ == {"angle": float(np.median(after.stops_[:, 0]))}
    assert after.default_goal_ == {"angle": 0.0}
    longest = max(int(turn_data.lengths.max()), int(new_data.lengths.max()))
    assert after.max_steps_ == max(500, 2 * longest)
    # the units of the fitted parts stay: pipeline, command scales, command rates
    assert after.pipeline_.to_dict() == before.pipeline_.to_dict()
    assert after.command_scale_ == before.command_scale_
    assert after.delta_scale_ == before.delta_scale_
    assert after.command_rates_.tobytes() == before.command_rates_.tobytes()
    # how the wheels answered: the sums over all the demonstrations
    np.testing.assert_allclose(
        after.wheel_response_,
        before.wheel_response_ + demonstrated_wheel_response(new_data),
        rtol=1e-12,
    )
    assert after.provenance_ == before.provenance_
    record = after.updates_[-1]
    assert record["episodes"] == len(new_data) and record["rows"] == new_data.n_samples
    assert record["source"] == "new.parquet" and record["env"] == "kinematic"


def test_an_updated_model_saves_and_loads(
    updated: tuple[SBLM, SBLM, float], tmp_path: Path, kinematic_env: Any
) -> None:
    _, after, _ = updated
    after.save(tmp_path / "u.bhmm")
    loaded = SBLM.load(tmp_path / "u.bhmm")
    assert loaded.updates_ == after.updates_
    start = {"angle": 85.0, "distance": 0.5}
    a = after.generate(kinematic_env, start=start, seed=1)
    b = loaded.generate(kinematic_env, start=start, seed=1)
    np.testing.assert_array_equal(a.command_array, b.command_array)
    # a second update continues the first (new seeds for the fine-tuned generators)
    loaded.partial_fit(collect("turn", [{"angle": 60.0, "distance": 0.5}], sim="kinematic"))
    assert len(loaded.updates_) == 2


def test_a_model_never_updated_saves_as_before(turn_model: SBLM, tmp_path: Path) -> None:
    import json
    import zipfile

    assert turn_model.updates_ == []
    turn_model.save(tmp_path / "m.bhmm")
    with zipfile.ZipFile(tmp_path / "m.bhmm") as zf:
        state = json.loads(zf.read("model.json"))["state"]
    assert "updates" not in state


def test_refusals_leave_the_model_unchanged(
    turn_model: SBLM, new_data: Dataset, tmp_path: Path
) -> None:
    with pytest.raises(NotFittedError):
        SBLM(inputs=("angle",)).partial_fit(new_data)
    model = _copy(turn_model, tmp_path / "m.bhmm")
    with pytest.raises(ConfigError, match="Dataset"):
        model.partial_fit(new_data.commands)  # type: ignore[arg-type]
    approach = collect("approach", [{"angle": 0.0, "distance": 0.4}], sim="kinematic")
    with pytest.raises(ConfigError, match="'approach', the model 'turn'"):
        model.partial_fit(approach)
    with pytest.raises(ConfigError, match="control period"):
        model.partial_fit(new_data.with_metadata(control_period=0.032))
    with pytest.raises(ConfigError, match="range of angle"):
        model.partial_fit(new_data.with_metadata(ranges={"angle": [-90.0, 90.0]}))
    with pytest.raises(ConfigError, match="come from 'mujoco'"):
        model.partial_fit(new_data.with_metadata(env="mujoco"))
    model.set_params(inputs=("distance", "angle"))
    with pytest.raises(ConfigError, match="inputs changed since the fit"):
        model.partial_fit(new_data)
    model.set_params(inputs=("angle",), onset_clock=0)
    with pytest.raises(ConfigError, match="onset_clock"):
        model.partial_fit(new_data)
    model.set_params(onset_clock=turn_model.onset_clock)
    model.save(tmp_path / "after.bhmm")
    assert (tmp_path / "after.bhmm").read_bytes() == (tmp_path / "m.bhmm").read_bytes()


def test_timing_of_partial_fit_against_a_full_refit(
    turn_data: Dataset, new_data: Dataset, updated: tuple[SBLM, SBLM, float]
) -> None:
    """Reported, not asserted: the update against fitting everything again."""
    _, after, seconds = updated
    union = turn_data.concat(new_data, renumber=True)
    t0 = time.perf_counter()
    SBLM(inputs=("angle",), epochs=60, random_state=0).fit(union)
    refit = time.perf_counter() - t0
    print(
        f"\npartial_fit of {len(new_data)} demonstrations: {seconds:.2f} s; full refit on "
        f"{len(union)}: {refit:.2f} s (fine-tuned {after.updates_[-1]['fine_tuned']}, "
        f"+{after.updates_[-1]['new_primitives']} primitives)"
    )


def test_corrective_demonstrations_train_generators_only(turn_model: SBLM, tmp_path: Path) -> None:
    """As in fit: corrections reach the generators, not the categories nor the HMM."""
    model = _copy(turn_model, tmp_path / "m.bhmm")
    old = model.hmm_
    starts = [{"angle": 100.0, "distance": 0.5}, {"angle": -60.0, "distance": 0.5}]
    data = collect("turn", starts, sim="kinematic", seed=3, corrections=1)
    corrective = set(data.metadata["corrective_episodes"])
    assert 0 < len(corrective) < len(data)
    nominal = [i for i, e in enumerate(data.episode_ids) if int(e) not in corrective]
    model.partial_fit(data)
    assert model.hmm_.start_counts_.sum() == old.start_counts_.sum() + len(nominal)
    assert model.hmm_.pi_counts_.sum() == old.pi_counts_.sum() + data.lengths[nominal].sum()
    assert model.primitives_.labels_.size == data.lengths[nominal].sum()
    assert model.updates_[-1]["episodes"] == len(data)
    assert model.stops_.shape[0] == turn_model.stops_.shape[0] + len(data)


@pytest.mark.parametrize(
    "updates",
    [{"episodes": 1}, [{"bogus": 1}], [{"episodes": -1}], [{"fine_tuned": "all"}], [7]],
)
def test_a_tampered_update_record_is_refused(
    updated: tuple[SBLM, SBLM, float], tmp_path: Path, updates: Any
) -> None:
    import json
    import zipfile

    from behavior_hmm.errors import ModelFileError

    _, after, _ = updated
    after.save(tmp_path / "u.bhmm")
    with zipfile.ZipFile(tmp_path / "u.bhmm") as zin:
        members = {name: zin.read(name) for name in zin.namelist()}
    header = json.loads(members["model.json"])
    header["state"]["updates"] = updates
    members["model.json"] = json.dumps(header).encode()
    with zipfile.ZipFile(tmp_path / "bad.bhmm", "w") as zout:
        for name, data in members.items():
            zout.writestr(name, data)
    with pytest.raises(ModelFileError, match="update"):
        SBLM.load(tmp_path / "bad.bhmm")


def _dense(table: Any) -> np.ndarray:
    """A table as a dense array (B and C, counts and log probabilities, are sparse)."""
    return np.asarray(table.toarray() if hasattr(table, "toarray") else table)


def test_a_mirrored_model_grows_by_each_new_demonstration_and_its_image(
    turn_data: Dataset,
) -> None:
    """``mirror=True`` learns the images in ``partial_fit`` as in ``fit``: the replayed
    demonstrations add two episodes each, and the images' turns to the other side."""
    model = SBLM(inputs=("angle",), epochs=5, mirror=True, random_state=0).fit(turn_data)
    assert model.hmm_.start_counts_.sum() == 2 * len(turn_data)
    starts = model.hmm_.start_counts_.sum()
    stops = len(model.stops_)
    model.partial_fit(turn_data.subset([2, 9]))
    assert model.hmm_.start_counts_.sum() == starts + 4
    assert len(model.stops_) == stops + 4
    finals = model.stops_[-4:, 0]
    np.testing.assert_allclose(finals[1::2], -finals[0::2])  # each image ends mirrored
