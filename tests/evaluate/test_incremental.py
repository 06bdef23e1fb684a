"""``experiment incremental`` (issue 29, thesis 7.1): the continual-learning metrics, a
tiny end-to-end run of the sequence, its report and its command line."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner
from user_errors import assert_user_error

from behavior_hmm.cli import app
from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate import _incremental as inc
from behavior_hmm.evaluate._incremental import (
    DEFAULT_SEQUENCE,
    accuracy,
    backward_transfer,
    check_sequence,
    check_targets,
    forgetting,
    forward_transfer,
    matrix,
    run_incremental_experiment,
    transfer_metrics,
)
from behavior_hmm.viz._incremental import FIGURE_NAME, write_incremental_report

NAN = float("nan")
#: Three tasks: task 0 is learned at 90, rises to 95 after stage 2 and ends at 88; task 1
#: is learned at 80 and ends at 70; task 2 is learned at 60.
R = [
    [90.0, NAN, NAN],
    [95.0, 80.0, NAN],
    [88.0, 70.0, 60.0],
]
PNG = b"\x89PNG\r\n\x1a\n"


def test_metrics_on_a_hand_made_matrix() -> None:
    assert accuracy(R) == pytest.approx((88 + 70 + 60) / 3)
    # BWT: ((88 - 90) + (70 - 80)) / 2
    assert backward_transfer(R) == pytest.approx(-6.0)
    # forgetting: task 0 peaked at 95 (after stage 2), task 1 at 80: ((95-88) + (80-70)) / 2
    assert forgetting(R) == pytest.approx(8.5)
    # FWT: tasks 1 and 2 against references trained alone: ((80 - 75) + (60 - 70)) / 2
    assert forward_transfer(R, [90.0, 75.0, 70.0]) == pytest.approx(-2.5)
    summary = transfer_metrics(R, [90.0, 75.0, 70.0])
    assert summary["worst_drop"] == pytest.approx(-10.0)
    assert summary["drop"] == pytest.approx([-2.0, -10.0, 0.0])
    assert summary["diagonal"] == [90.0, 80.0, 60.0]
    assert transfer_metrics(R)["fwt"] is None


def test_metrics_of_a_learner_that_improves() -> None:
    r = [[70.0, NAN], [72.5, 50.0]]
    assert backward_transfer(r) == pytest.approx(2.5)
    # its best earlier score on task 0 is below the last one: negative forgetting
    assert forgetting(r) == pytest.approx(-2.5)
    one = [[42.0]]
    assert (accuracy(one), backward_transfer(one), forgetting(one)) == (42.0, 0.0, 0.0)
    assert forward_transfer(one, [10.0]) == 0.0


def test_metrics_refuse_a_broken_matrix() -> None:
    with pytest.raises(ConfigError, match="square"):
        accuracy([[1.0, 2.0]])
    with pytest.raises(ConfigError, match="finite"):
        backward_transfer([[1.0, NAN], [NAN, 2.0]])
    with pytest.raises(ConfigError, match="one score per task"):
        forward_transfer(R, [1.0])


def test_sequences_are_checked_before_any_work() -> None:
    assert check_sequence(DEFAULT_SEQUENCE) == DEFAULT_SEQUENCE
    assert check_sequence(["turn", "approach", "retreat", "position", "turn-approach"])
    with pytest.raises(ConfigError, match="learn retreat at an earlier stage"):
        check_sequence(["turn", "approach", "position"])
    with pytest.raises(ConfigError, match="appears twice"):
        check_sequence(["turn", "turn"])
    with pytest.raises(ConfigError, match="grab"):
        check_sequence(["grab"])
    with pytest.raises(ConfigError, match="at least one task"):
        check_sequence([])
    # grasp runs on the gripper robot: the BC-strong network on distance and angle cannot
    assert check_sequence([*DEFAULT_SEQUENCE, "grasp"])[-1] == "grasp"
    with pytest.raises(ConfigError, match=r"grasp.*KheperaGripper.*--no-bc"):
        check_sequence(["turn", "grasp"], bc=True)


def test_a_complex_task_runs_toward_its_own_goal_in_a_model_of_several() -> None:
    # a refit CBLM fitted on position's demonstrations before turn & approach's takes
    # position's goal (0.5 m) as its default; turn & approach must still run to 0 m
    model = SimpleNamespace(behavior_="position", default_goal_={"angle": 0.0, "distance": 0.5})
    view = inc._as_task(model, "turn-approach")
    assert view.behavior_ == "turn-approach"
    assert view.default_goal_ == {"angle": 0.0, "distance": 0.0}
    assert model.default_goal_ == {"angle": 0.0, "distance": 0.5}  # the model is untouched
    # a simple task keeps the goal its own demonstrations end at
    turn = SimpleNamespace(behavior_="turn", default_goal_={"angle": 0.012})
    assert inc._as_task(turn, "turn").default_goal_ == {"angle": 0.012}


def test_grasp_joins_the_sequence_on_the_gripper_robot() -> None:
    """A grasp stage (issue 29: "then grasp") is learned from gripper demonstrations and
    scored on the gripper robot, beside a turn learned and scored on the kinematic one."""
    grasp_starts = [
        {"angle": a, "distance": d} for a in (-3.0, 0.0, 3.0) for d in (0.0, 0.005, 0.01)
    ]
    results = run_incremental_experiment(
        sim="kinematic",
        sequence=("turn", "grasp"),
        bc=False,
        starts={"turn": ANGLES[::2], "grasp": grasp_starts},
        test_starts={"turn": TESTS["turn"], "grasp": [{"angle": 1.0, "distance": 0.0076}]},
        sblm_params={"epochs": 15},
    )
    inc = results["schemes"]["incremental"]
    assert inc["how"] == ["SBLM fit on its demonstrations"] * 2
    assert inc["goals"][1][1] == 1  # the object is lifted: arm up, object held
    assert inc["model_sha256"][0][0] == inc["model_sha256"][1][0]  # turn untouched
    assert results["schemes"]["full_refit"]["how"][-1] == "refit 2 SBLM(s)"


# A tiny grid: a few seconds of demonstrations per task, one or two test starts each.
ANGLES = [{"angle": float(a)} for a in range(-160, 181, 40)]
STARTS: dict[str, list[dict[str, float]]] = {
    "turn": ANGLES,
    "approach": [{"distance": x} for x in (0.2, 0.5, 0.8)],
    "retreat": [{"distance": x, "goal_distance": 1.0} for x in (0.1, 0.4, 0.7)],
    "turn-approach": [{"angle": a, "distance": d} for a in (-120.0, 0.0, 120.0) for d in (0.3, 0.7)]
    + [{"angle": a, "distance": 0.0} for a in (-120.0, 120.0)],
    "position": [
        {"angle": a, "distance": d, "goal_distance": g}
        for a in (-90.0, 0.0, 90.0)
        for d, g in ((0.2, 0.6), (0.8, 0.3))
    ],
}
TESTS: dict[str, list[dict[str, float]]] = {
    "turn": [{"angle": -100.0}],
    "approach": [{"distance": 0.6}],
    "retreat": [{"distance": 0.3}],
    "turn-approach": [{"angle": 60.0, "distance": 0.5}],
    "position": [{"angle": 30.0, "distance": 0.3, "goal_distance": 0.7}],
}


@pytest.fixture(scope="module")
def tiny() -> dict[str, Any]:
    return run_incremental_experiment(
        sim="kinematic",
        seed=3,
        starts=STARTS,
        test_starts=TESTS,
        sblm_params={"epochs": 15},
        bc_params={"epochs": 4},
    )


def test_every_scheme_scores_every_learned_task_after_every_stage(tiny: dict[str, Any]) -> None:
    assert tiny["sequence"] == list(DEFAULT_SEQUENCE)
    assert set(tiny["schemes"]) == {"incremental", "full_refit", "bc_strong_finetuned"}
    for entry in tiny["schemes"].values():
        rows = entry["R"]
        assert len(rows) == 5 and all(len(row) == 5 for row in rows)
        for k, row in enumerate(rows):
            assert all(v is None for v in row[k + 1 :])
            assert all(0.0 <= v <= 100.0 for v in row[: k + 1])
            goals = entry["goals"][k][: k + 1]
            assert all(0 <= g <= n for g, n in zip(goals, entry["n"][: k + 1], strict=True))
        assert entry["n"] == [1, 1, 1, 1, 1]
        metrics = entry["metrics"]
        r = matrix(rows)
        assert metrics["acc"] == pytest.approx(float(np.mean(r[-1])))
        assert metrics["bwt"] == pytest.approx(backward_transfer(r))
        assert len(entry["reference"]) == 5 and metrics["fwt"] is not None
    assert set(tiny["timings"]) == {
        "collect_s",
        "kernels_s",
        "incremental_s",
        "full_refit_s",
        "bc_strong_finetuned_s",
    }
    assert all(len(tiny["timings"][f"{s}_s"]) == 5 for s in tiny["schemes"])


def test_the_incremental_learner_never_retrains_a_stage_model(tiny: dict[str, Any]) -> None:
    entry = tiny["schemes"]["incremental"]
    hashes = entry["model_sha256"]
    turn, approach, ta, retreat, position = range(5)
    # every simple task is scored with the very same model file at every later stage,
    # also once the CBLM holds it as a component
    for task in (turn, approach, retreat):
        assert len({hashes[k][task] for k in range(task, 5)}) == 1
    # the CBLM is born at turn & approach, unchanged by retreat (a separate SBLM), and
    # grown by position: turn & approach is then scored with the grown CBLM
    assert hashes[2][ta] == hashes[3][ta] != hashes[4][ta] == hashes[4][position]
    assert tiny["growing_components"] == [
        [],
        [],
        ["turn", "approach"],
        ["turn", "approach"],
        ["turn", "approach", "retreat"],
    ]
    assert entry["how"][4] == "add_component(retreat) to the growing CBLM"
    assert entry["how"][2].startswith("growing CBLM{turn, approach} fit")
    # a task whose model did not change keeps its score (scored once, then reused)
    r = matrix(entry["R"])
    for task in (turn, approach, retreat):
        assert np.all(r[task:, task] == r[task, task])
    assert tiny["evaluations"]["reused"] >= 6
    # only position, learned with add_component, has a reference trained on its own
    assert entry["reference"][:4] == pytest.approx(np.diag(r)[:4])
    assert entry["reference_how"][4].startswith("CBLM over its components")


def test_the_baselines_retrain_or_fine_tune(tiny: dict[str, Any]) -> None:
    refit = tiny["schemes"]["full_refit"]
    assert refit["how"][4] == (
        "refit 3 SBLM(s) + CBLM{turn, approach, retreat} on turn-approach, position"
    )
    bc = tiny["schemes"]["bc_strong_finetuned"]
    # one network: every task of a row is run with the same weights, new ones each stage
    per_row = [set(row[: k + 1]) for k, row in enumerate(bc["model_sha256"])]
    assert all(len(s) == 1 for s in per_row)
    assert len(set().union(*per_row)) == 5
    assert bc["inputs"] == ["distance", "angle"]


def test_the_report(tiny: dict[str, Any], tmp_path: Path) -> None:
    results = {**tiny, "preset": "default"}
    table = write_incremental_report(results, tmp_path)
    assert (tmp_path / FIGURE_NAME).read_bytes().startswith(PNG)
    assert (tmp_path / "table.md").read_text() == table
    saved = json.loads((tmp_path / "results.json").read_text())
    assert "timings" not in saved and saved["schemes"]["incremental"]["R"][0][1] is None
    assert set(json.loads((tmp_path / "timings.json").read_text())) == set(tiny["timings"])
    assert "| 5: position |" in table and "ACC %" in table and "BWT ≥ -0.5" in table
    targets = check_targets(results)
    assert targets["time_share"] == pytest.approx(
        sum(tiny["timings"]["incremental_s"]) / sum(tiny["timings"]["full_refit_s"])
    )
    assert len(targets["new_task_gap"]) == 5


def test_the_command_line(
    tiny: dict[str, Any], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    seen: dict[str, Any] = {}

    def fake(**kwargs: Any) -> dict[str, Any]:
        seen.update(kwargs)
        return {k: v for k, v in tiny.items()}

    monkeypatch.setattr(inc, "run_incremental_experiment", fake)
    out = tmp_path / "inc"
    args = ["experiment", "incremental", "--sim", "kinematic", "--seed", "3", "-o", str(out)]
    result = CliRunner().invoke(app, [*args, "--preset", "thesis", "--no-bc"])
    assert result.exit_code == 0, result.output
    assert seen["sim"] == "kinematic" and seen["seed"] == 3 and seen["bc"] is False
    assert seen["sequence"] == DEFAULT_SEQUENCE
    assert seen["sblm_params"]["onset_clock"] == 0  # the thesis preset's SBLM
    assert (out / FIGURE_NAME).is_file() and "thesis preset" in (out / "table.md").read_text()
    bad = CliRunner().invoke(
        app, [*args, "--task", "turn", "--task", "position", "-o", str(tmp_path / "x")]
    )
    assert_user_error(bad, "learn approach, retreat at an earlier stage")
    assert not (tmp_path / "x").exists()
