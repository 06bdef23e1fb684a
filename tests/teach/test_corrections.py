"""Corrective (DART-style) demonstrations: ``collect(..., corrections=K)``."""

from __future__ import annotations

import numpy as np
import pytest

from behavior_hmm.errors import ConfigError
from behavior_hmm.models import SBLM
from behavior_hmm.teach import DEFAULT_CORRECTION_NOISE, collect

STARTS = [{"distance": x} for x in (0.3, 0.6, 0.9)]


@pytest.fixture(scope="module")
def corrected():  # type: ignore[no-untyped-def]
    return collect("approach", STARTS, sim="kinematic", corrections=1, correction_noise=0.08)


def test_corrective_copies_follow_the_nominal_ones(corrected) -> None:  # type: ignore[no-untyped-def]
    nominal = collect("approach", STARTS, sim="kinematic")
    assert len(corrected) == 2 * len(nominal)
    assert corrected.metadata["corrective_episodes"] == [3, 4, 5]
    assert corrected.metadata["corrections"] == {
        "copies": 1,
        "noise": 0.08,
        "disturbs": ["angle"],
    }
    eps = list(corrected.episodes())
    for i, ep in enumerate(nominal.episodes()):
        assert np.array_equal(eps[i].commands, ep.commands)  # nominal ones unchanged
        # the corrective copy starts in the same place but drifts, and the teacher corrects
        copy = eps[i + 3]
        assert copy.to_dict()["distance"][0] == pytest.approx(ep.to_dict()["distance"][0])
        n = min(len(copy.commands), len(ep.commands))
        assert np.abs(copy.commands[:n] - ep.commands[:n]).max() > 0.05
        assert np.abs(copy.to_dict()["angle"]).max() > 5 * np.abs(ep.to_dict()["angle"]).max()
    # the same seed gives the same demonstrations
    again = collect("approach", STARTS, sim="kinematic", corrections=1, correction_noise=0.08)
    assert all(
        np.array_equal(a.commands, b.commands)
        for a, b in zip(again.episodes(), corrected.episodes(), strict=True)
    )


def test_corrections_train_the_generators_not_the_plan(corrected) -> None:  # type: ignore[no-untyped-def]
    nominal = collect("approach", STARTS, sim="kinematic")
    plain = SBLM(inputs=("distance", "angle"), epochs=5).fit(nominal)
    model = SBLM(inputs=("distance", "angle"), epochs=5).fit(corrected)
    # categories, Behavior-HMM and command scales: the nominal demonstrations'
    assert np.array_equal(model.primitives_.prototypes_, plain.primitives_.prototypes_)
    assert np.array_equal(model.hmm_.log_A_, plain.hmm_.log_A_)
    assert model.command_scale_ == plain.command_scale_
    assert model.delta_scale_ == plain.delta_scale_
    # the generators saw more rows: the corrective ones
    assert model.generators_.n_train_.sum() > plain.generators_.n_train_.sum()


def test_the_disturbance_turns_the_robot_without_changing_its_speed() -> None:
    from behavior_hmm.teach._demonstrator import _Disturbance

    disturbance = _Disturbance(sigma=0.5, period=0.016, seed=3)
    command = np.array([1.0, 1.0])
    moved = [disturbance.applied(command, limit=10.0) - command for _ in range(200)]
    assert max(abs(d[1]) for d in moved) > 0.05  # it does turn the robot
    for left, right in moved:
        assert left == pytest.approx(-right)  # wheels apart by as much: no speed change


def test_models_that_cannot_see_the_heading_learn_from_the_nominal_runs_only(  # type: ignore[no-untyped-def]
    corrected,
) -> None:
    nominal = collect("approach", STARTS, sim="kinematic")
    blind = SBLM(inputs=("distance",), epochs=5).fit(corrected)
    plain = SBLM(inputs=("distance",), epochs=5).fit(nominal)
    assert np.array_equal(blind.generators_.n_train_, plain.generators_.n_train_)
    for mine, theirs in zip(blind.generators_.coefs_, plain.generators_.coefs_, strict=True):
        assert np.array_equal(mine, theirs)  # the same networks, weight for weight
    # a model that sees the heading learns from them, unless told not to (the thesis)
    seeing = SBLM(inputs=("distance", "angle"), epochs=5)
    assert seeing.fit(corrected).generators_.n_train_.sum() > blind.generators_.n_train_.sum()
    off = SBLM(inputs=("distance", "angle"), epochs=5, learn_corrections=False).fit(corrected)
    same = SBLM(inputs=("distance", "angle"), epochs=5).fit(nominal)
    assert np.array_equal(off.generators_.n_train_, same.generators_.n_train_)


def test_the_approachs_default_grid_comes_with_one_corrective_copy_per_start() -> None:
    from behavior_hmm.teach import behavior_spec, default_starts

    grid = default_starts("approach")
    data = collect("approach", sim="kinematic")
    assert behavior_spec("approach").corrections == 1
    assert data.metadata["corrective_episodes"] == list(range(len(grid), 2 * len(grid)))
    assert data.metadata["corrections"]["noise"] == DEFAULT_CORRECTION_NOISE
    # starts of one's own, or a behavior without corrections: nominal runs only
    assert "corrective_episodes" not in collect("approach", STARTS, sim="kinematic").metadata
    assert behavior_spec("turn").corrections == 0


def test_a_composite_behavior_cannot_declare_corrections() -> None:
    from behavior_hmm.teach import BehaviorSpec, behavior_spec

    ta = behavior_spec("turn-approach")
    with pytest.raises(ConfigError, match="0 for a composite"):
        BehaviorSpec(
            "ta-corrected",
            dict(ta.goal),
            ta.phases,
            ta.train_starts,
            components=ta.components,
            corrections=1,
        )


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"corrections": -1}, "--corrections"),
        ({"corrections": 1, "correction_noise": 0.0}, "--correction-noise"),
    ],
)
def test_bad_corrections_are_refused(options, message) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ConfigError, match=message):
        collect("approach", STARTS, sim="kinematic", **options)


def test_collect_command_takes_corrections(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from typer.testing import CliRunner

    from behavior_hmm import data
    from behavior_hmm.cli import app

    out = tmp_path / "a.parquet"
    runner = CliRunner()
    res = runner.invoke(
        app, ["collect", "approach", "--sim", "kinematic", "--corrections", "-1", "-o", str(out)]
    )
    assert res.exit_code == 2 and "--corrections" in res.output and not out.exists()
    starts = tmp_path / "s.csv"
    starts.write_text("distance\n0.4\n0.8\n")
    res = runner.invoke(
        app,
        [
            "collect",
            "approach",
            "--sim",
            "kinematic",
            "--starts",
            str(starts),
            "--corrections",
            "2",
            "-o",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.output
    assert data.read(out).metadata["corrective_episodes"] == [2, 3, 4, 5]


def test_a_complex_behavior_learns_from_the_nominal_demonstrations_only() -> None:
    # a CBLM has no generators: runs a dataset lists as corrective would only distort its
    # categories, transitions and command scale, so it fits as if they were not there
    from behavior_hmm.models import CBLM

    turn = SBLM(inputs=("angle",), epochs=5).fit(
        collect("turn", [{"angle": a} for a in range(-170, 181, 40)], sim="kinematic")
    )
    approach = SBLM(inputs=("distance", "angle"), epochs=5).fit(
        collect("approach", STARTS, sim="kinematic")
    )
    nominal = collect(
        "turn-approach", [{"angle": a, "distance": 0.5} for a in (-90, 60, 150)], sim="kinematic"
    )
    other = collect(
        "turn-approach", [{"angle": a, "distance": 0.8} for a in (-30, 100)], sim="kinematic"
    )
    both = nominal.concat(other, renumber=True).with_metadata(corrective_episodes=[3, 4])
    with_copies = CBLM([turn, approach]).fit(both)
    without = CBLM([turn, approach]).fit(nominal)
    assert with_copies.command_scale_ == without.command_scale_
    assert np.array_equal(with_copies.hmm_.log_A_, without.hmm_.log_A_)
    assert np.array_equal(with_copies.observations_.prototypes_, without.observations_.prototypes_)


def test_composite_behaviors_refuse_corrections() -> None:
    with pytest.raises(ConfigError, match="collect corrective demonstrations of turn-approach's"):
        collect("turn-approach", [{"angle": 90.0, "distance": 0.5}], corrections=1)


def test_behavior_cloning_follows_the_same_rule(corrected) -> None:  # type: ignore[no-untyped-def]
    # a fair baseline: it learns from the corrective runs exactly when the SBLM would
    from behavior_hmm.evaluate._baselines import BASELINES

    nominal = collect("approach", STARTS, sim="kinematic")
    bc = BASELINES["bc"]
    blind = bc(inputs=("distance",), epochs=3).fit(corrected).network_
    plain = bc(inputs=("distance",), epochs=3).fit(nominal).network_
    assert np.array_equal(blind.n_train_, plain.n_train_)
    assert all(np.array_equal(a, b) for a, b in zip(blind.coefs_, plain.coefs_, strict=True))
    seeing = bc(inputs=("distance", "angle"), epochs=3).fit(corrected).network_
    assert (
        seeing.n_train_.sum()
        > bc(inputs=("distance", "angle"), epochs=3).fit(nominal).network_.n_train_.sum()
    )
