"""The SBLM's generator and decoding options (onset clock, margins, noise, recognition)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from behavior_hmm.cobart import suggest_dcm_scale
from behavior_hmm.data import Dataset
from behavior_hmm.errors import ConfigError, ModelFileError
from behavior_hmm.models import SBLM
from behavior_hmm.models import perform as run_behavior
from behavior_hmm.models._sblm import margin_rows


def test_margin_rows_widen_each_segment_within_its_episode() -> None:
    states = np.array([0, 0, 1, 1, 1, 2, 0, 0], dtype=np.int64)
    rows, labels = margin_rows(states, [5, 3], 1)
    got = {(int(r), int(p)) for r, p in zip(rows, labels, strict=True)}
    # episode 1: segment 0 = rows 0-1 (+ row 2), segment 1 = rows 2-4 (+ row 1, no row 5)
    assert {(0, 0), (1, 0), (2, 0)} <= got
    assert {(1, 1), (2, 1), (3, 1), (4, 1)} <= got
    assert (5, 1) not in got  # never across the episode boundary
    # episode 2: segment 2 = row 5 (+ row 6), segment 0 = rows 6-7 (+ row 5)
    assert {(5, 2), (6, 2), (5, 0), (6, 0), (7, 0)} <= got
    no_margin, same = margin_rows(states, [5, 3], 0)
    np.testing.assert_array_equal(no_margin, np.arange(8))
    np.testing.assert_array_equal(same, states)


def test_onset_clock_is_an_input_that_saturates(turn_data: Dataset) -> None:
    model = SBLM(inputs=("angle",), epochs=2, onset_clock=8).fit(turn_data)
    assert model.generators_.n_features_in_ == 10 + 1
    x = model.pipeline_.transform(turn_data)
    y = turn_data.commands / model.command_scale_
    clock = model.feature_layout(1, 10).offline(x, y, turn_data.lengths)[:, -1]
    first = turn_data.lengths[0]
    np.testing.assert_allclose(
        clock[:10], [0, 1 / 8, 2 / 8, 3 / 8, 4 / 8, 5 / 8, 6 / 8, 7 / 8, 1, 1]
    )
    assert clock[first] == 0.0  # restarts with every episode
    off = SBLM(inputs=("angle",), epochs=2, onset_clock=0).fit(turn_data)
    assert off.generators_.n_features_in_ == 10


def test_dcm_floor_raises_a_still_channels_scale(turn_data: Dataset) -> None:
    inputs = ("angle", "distance")  # the distance never moves while turning
    model = SBLM(inputs=inputs, epochs=1, dcm_floor=0.5).fit(turn_data)
    auto = suggest_dcm_scale(model.pipeline_.transform(turn_data), turn_data.lengths)
    expected = np.maximum(auto, 0.5 * auto.max())
    np.testing.assert_allclose(model.primitives_.dcm_scale_, expected)
    np.testing.assert_allclose(model.observations_.dcm_scale_, expected)
    plain = SBLM(inputs=inputs, epochs=1, dcm_floor=0.0).fit(turn_data)
    np.testing.assert_allclose(plain.primitives_.dcm_scale_, auto)


def test_window_noise_changes_training_only(turn_data: Dataset) -> None:
    a = SBLM(inputs=("angle",), epochs=3, window_noise=0.0).fit(turn_data)
    b = SBLM(inputs=("angle",), epochs=3, window_noise=0.05).fit(turn_data)
    assert a.generators_.n_features_in_ == b.generators_.n_features_in_
    assert b.generators_.n_train_.sum() > a.generators_.n_train_.sum()  # noisy copies
    assert not np.allclose(a.generators_.coefs_[0], b.generators_.coefs_[0])


@pytest.mark.parametrize("recognition", [True, False])
def test_recognized_primitive_is_one_the_plan_allows(
    turn_model: SBLM, kinematic_env: Any, recognition: bool
) -> None:
    model = SBLM(**{**turn_model.get_params(), "primitive_recognition": recognition})
    for name in ("inputs_", "pipeline_", "primitives_", "observations_", "hmm_"):
        setattr(model, name, getattr(turn_model, name))
    for name in ("generators_", "command_scale_", "command_scales_", "command_specs_"):
        setattr(model, name, getattr(turn_model, name))
    for name in ("delta_scale_", "rest_values_"):
        setattr(model, name, getattr(turn_model, name))
    model.default_goal_, model.max_steps_ = turn_model.default_goal_, turn_model.max_steps_
    model.behavior_ = turn_model.behavior_
    trace = run_behavior(model, kinematic_env, start={"angle": 65.0, "distance": 0.5}, seed=0)
    goal = model.goal_category(model.default_goal_)
    b_counts = model.hmm_.B_counts_
    for obs, state in zip(trace.observation[:-1], trace.state[:-1], strict=True):
        assert b_counts[state, obs] > 0  # the state can emit what was observed
        assert np.isfinite(model.hmm_.state_scores(obs, goal)[state])


def test_default_options_turn_and_stop(turn_model: SBLM, kinematic_env: Any) -> None:
    trace = turn_model.generate(kinematic_env, start={"angle": -65.0, "distance": 0.5}, seed=0)
    assert trace.goal_reached
    # the start-up ramp turns toward the goal from the first cycles (no wrong-sign start)
    first = np.array(trace.readings[:40])[:, 2]
    assert first[-1] > first[0]


def test_approach_goal_is_the_distance_only() -> None:
    from behavior_hmm.teach import collect

    data = collect("approach", [{"distance": 0.3}, {"distance": 0.5}], sim="kinematic", seed=0)
    model = SBLM(inputs=("distance", "angle"), epochs=1).fit(data)
    assert model.default_goal_ == {"distance": 0.0}


def test_bad_option_values_are_refused(turn_data: Dataset) -> None:
    for bad in (
        {"onset_clock": -1},
        {"onset_clock": 2.5},
        {"segment_margin": -3},
        {"window_noise": -0.1},
        {"dcm_floor": 1.5},
        {"dcm_floor": float("nan")},
    ):
        with pytest.raises(ConfigError):
            SBLM(inputs=("angle",), **bad).fit(turn_data)


def test_load_refuses_generators_of_another_width(turn_model: SBLM, tmp_path: Path) -> None:
    state, arrays = turn_model._state()
    params = {**turn_model.get_params(), "onset_clock": 0}
    params["inputs"] = list(params["inputs"])
    with pytest.raises(ModelFileError, match="generator inputs"):
        SBLM._from_state(params, state, arrays)


def test_generators_hold_out_demonstrations_unless_asked(turn_data: Dataset) -> None:
    # the thesis (and default): 20 % held out as whole demonstrations, best epoch kept
    held = SBLM(inputs=("angle",), epochs=4).fit(turn_data).generators_
    assert held.n_test_.sum() > 0.1 * held.n_train_.sum()
    # 0: every demonstration trains, every epoch, the last one kept
    every = SBLM(inputs=("angle",), epochs=4, generator_test_fraction=0).fit(turn_data)
    gens = every.generators_
    assert not gens.n_test_.any() and (gens.best_epoch_[gens.trained_] == 3).all()
    assert (held.n_train_ < gens.n_train_).any()
    for bad in (-0.1, 1.0, True, "0.2"):
        with pytest.raises(ConfigError, match="generator_test_fraction"):
            SBLM(inputs=("angle",), generator_test_fraction=bad).fit(turn_data)


def test_shared_generator_init_starts_every_network_from_one(
    turn_data: Dataset, tmp_path: Path
) -> None:
    """``generator_init="shared"`` reaches the generators, changes the trained networks,
    survives save and load, and is refused for the recurrent generators."""
    from behavior_hmm.models import load

    params: dict[str, Any] = {"inputs": ("angle",), "epochs": 3}
    random = SBLM(**params).fit(turn_data)
    shared = SBLM(**params, generator_init="shared").fit(turn_data)
    assert random.generators_.init == "random" and shared.generators_.init == "shared"
    assert not np.array_equal(random.generators_.coefs_[0], shared.generators_.coefs_[0])
    path = tmp_path / "shared.bhmm"
    shared.save(path)
    again = load(path)
    assert again.generator_init == "shared" and again.generators_.init == "shared"
    np.testing.assert_array_equal(again.generators_.coefs_[0], shared.generators_.coefs_[0])
    with pytest.raises(ConfigError, match="generator_init='shared' is for the feed-forward"):
        SBLM(**params, generator_network="elman", hidden=5, generator_init="shared").fit(turn_data)
    with pytest.raises(ConfigError, match="generator_init must be one of random, shared"):
        SBLM(**params, generator_init="warm").check_params()


def test_mirror_images_teach_the_turns_never_shown(tmp_path: Path) -> None:
    """Shown only turns to the left, a model with ``mirror`` turns right as well as left:
    the images of the demonstrations are the turns from the other side."""
    from behavior_hmm.evaluate._protocol import evaluate_model
    from behavior_hmm.teach import collect

    starts = [{"angle": a, "distance": 0.5} for a in (30.0, 60.0, 90.0, 120.0, 150.0, 180.0)]
    left_only = collect("turn", starts, sim="kinematic", seed=0)
    tests = [{"angle": a} for a in (-150.0, -100.0, -45.0, -20.0)]
    scores = {}
    for mirror in (False, True):
        model = SBLM(inputs=("angle",), mirror=mirror, random_state=0).fit(left_only)
        result = evaluate_model(model, tests, sim="kinematic", seed=0)
        scores[mirror] = (float(result["success_rate_mean"]), int(result["goal_reached"]))
    assert scores[True][1] == len(tests)
    # the images' turns follow the teacher's from the other side (88 % against 69 %)
    assert scores[True][0] > scores[False][0] + 10.0
    assert len(model.stops_) == 2 * len(left_only)  # it learned from each and its image
    model.save(tmp_path / "mirror.bhmm")
    assert SBLM.load(tmp_path / "mirror.bhmm").get_params()["mirror"] is True


def test_mirror_refuses_a_channel_without_an_image(turn_data: Dataset) -> None:
    from behavior_hmm.data import ChannelSpec

    ir = ChannelSpec("ir0", "m", (0.0, 0.1))
    columns = dict(turn_data.to_columns())
    columns["ir0"] = np.full(turn_data.n_samples, 0.05)
    data = Dataset(columns, {**turn_data.metadata, "channels": [ir.to_metadata()]})
    with pytest.raises(ConfigError, match="channel 'ir0' declares no mirror"):
        SBLM(inputs=("angle",), epochs=1, mirror=True).fit(data)
    with pytest.raises(ConfigError, match="mirror must be true or false"):
        SBLM(inputs=("angle",), epochs=1, mirror="yes").fit(turn_data)  # type: ignore[arg-type]
