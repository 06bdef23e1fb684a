"""SBLM(generator_network="elman"): recurrent generators in a simple behavior (thesis 7.2)."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from behavior_hmm.cli import app
from behavior_hmm.data import Dataset
from behavior_hmm.data._parquet import write as write_parquet
from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate import evaluate_model
from behavior_hmm.generators import ElmanGenerators, MotionGenerators
from behavior_hmm.models import SBLM
from behavior_hmm.models import load as load_model
from behavior_hmm.sim import make_env
from behavior_hmm.teach import collect

#: Starts between those of ``turn_data`` (every 20 deg from -170), none on its grid.
STARTS = [{"angle": a, "distance": 0.5} for a in (-125.0, -40.0, 15.0, 75.0, 160.0)]


@pytest.fixture(scope="module")
def elman_model(turn_data: Dataset) -> SBLM:
    return SBLM(inputs=("angle",), epochs=60, generator_network="elman", random_state=0).fit(
        turn_data
    )


def test_elman_generators_turn_to_their_goals(elman_model: SBLM) -> None:
    gens = elman_model.generators_
    assert isinstance(gens, ElmanGenerators)
    assert gens.warmup == elman_model.segment_margin  # replays what its training saw first
    assert gens.n_primitives_ == elman_model.primitives_.n_categories_
    result = evaluate_model(elman_model, STARTS, sim="kinematic")
    assert result["goal_reached"] == len(STARTS)
    assert result["success_rate_mean"] > result["zero_floor_mean"] + 30


def test_training_sequences_are_the_segments_with_their_margins(turn_data: Dataset) -> None:
    model = SBLM(inputs=("angle",), epochs=1, window_noise=0.0, generator_network="elman")
    model.fit(turn_data)
    rows, _ = model._generator_rows(
        np.arange(turn_data.n_samples, dtype=np.float64)[:, None],
        np.zeros((turn_data.n_samples, 2)),
        model.train_states_,
        turn_data.lengths,
        turn_data.episode_ids,
    )
    features, states, groups, starts = rows.features, rows.states, rows.groups, rows.starts
    bounds = np.r_[starts, len(states)]
    for a, b in itertools.pairwise(bounds):
        rows = features[a:b, 0]
        assert np.all(np.diff(rows) == 1)  # consecutive demonstration rows
        assert len(set(states[a:b].tolist())) == 1 and len(set(groups[a:b].tolist())) == 1
    # one sequence per segment of a primitive in a demonstration
    segments = sum(
        int(np.count_nonzero(np.diff(s))) + 1
        for s in np.split(model.train_states_, np.cumsum(turn_data.lengths)[:-1])
    )
    assert len(starts) == segments


def test_a_saved_elman_model_generates_the_same_run(elman_model: SBLM, tmp_path: Path) -> None:
    path = tmp_path / "turn-elman.bhmm"
    elman_model.save(path)
    loaded = load_model(path)
    assert isinstance(loaded.generators_, ElmanGenerators)
    assert loaded.generator_network == "elman"
    start = STARTS[1]
    first = elman_model.generate(make_env("kinematic"), start)
    second = loaded.generate(make_env("kinematic"), start)
    assert len(first.commands) > 50
    np.testing.assert_array_equal(first.commands, second.commands)


def test_an_elman_model_grows_with_partial_fit(elman_model: SBLM, tmp_path: Path) -> None:
    elman_model.save(tmp_path / "m.bhmm")
    model = load_model(tmp_path / "m.bhmm")
    before = model.generators_.to_arrays()
    new = collect("turn", [{"angle": 95.0, "distance": 0.5}], sim="kinematic", seed=3)
    model.partial_fit(new)
    after = model.generators_.to_arrays()
    touched = set(model.updates_[-1]["fine_tuned"])
    k = len(before["trained"])
    for p in range(k):
        if p not in touched and before["trained"][p]:
            for name in ("w_x", "w_c", "w_y"):
                assert np.array_equal(after[name][p], before[name][p])
    assert touched and isinstance(model.generators_, ElmanGenerators)


def test_bad_generator_networks_are_refused(turn_data: Dataset) -> None:
    with pytest.raises(ConfigError, match="generator_network must be one of mlp, elman"):
        SBLM(generator_network="gru").fit(turn_data)
    with pytest.raises(ConfigError, match="one hidden layer"):
        SBLM(generator_network="elman", hidden=(5, 5)).fit(turn_data)
    assert isinstance(SBLM(epochs=1).fit(turn_data).generators_, MotionGenerators)


def test_the_command_line_trains_elman_generators(tmp_path: Path, turn_data: Dataset) -> None:
    data = tmp_path / "turn.parquet"
    write_parquet(turn_data, data)
    out = tmp_path / "turn.bhmm"
    result = CliRunner().invoke(
        app,
        ["train", "simple", str(data), "--inputs", "angle", "--set", "epochs=2",
         "--set", "generator_network=elman", "-o", str(out)],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert isinstance(load_model(out).generators_, ElmanGenerators)
