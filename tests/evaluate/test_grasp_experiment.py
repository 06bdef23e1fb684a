"""``experiment grasp`` (issue 28): stages, hand-off, composed, nudged; tiny grids."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner
from user_errors import assert_user_error

from behavior_hmm.evaluate._baselines import BehaviorCloning
from behavior_hmm.evaluate._grasp import (
    NUDGE_ANGLE_DEG,
    NUDGE_DISTANCE_M,
    NudgeWrapper,
    check_targets,
    draw_nudges,
    gripper_env,
    run_grasp_experiment,
)
from behavior_hmm.teach import Teacher

GRIDS = {
    "turn": [{"angle": a, "distance": 0.5} for a in (-120.0, -60.0, 60.0, 120.0)],
    "approach": [{"angle": 0.0, "distance": d} for d in (0.1, 0.2, 0.3)],
    "grasp": [{"angle": a, "distance": d} for a in (-2.0, 2.0) for d in (0.002, 0.008)],
    "turn-approach-grasp": [
        {"angle": a, "distance": d} for a in (-150.0, 0.0, 150.0) for d in (0.15, 0.3)
    ],
}


@pytest.fixture(scope="module")
def result() -> dict[str, Any]:
    """Two seeds on tiny grids, 2 test starts per behavior, short training."""
    return run_grasp_experiment(
        seed=3,
        seeds=2,
        grids=GRIDS,
        limit=2,
        sblm_params={"epochs": 3},
        baseline_params={"epochs": 2, "patience": None},
    )


def test_rows_and_counts(result: dict[str, Any]) -> None:
    assert result["seeds"] == [3, 4]
    assert result["env"] == "behavior_hmm/KheperaGripper-v0" and result["sim"] == "mujoco"
    names = [row["row"] for row in result["rows"][0]]
    assert names[:3] == [
        "turn {angle}",
        "approach {distance, angle}",
        "grasp {arm, fingers, object_present}",
    ]
    assert names[3].startswith("hand-off") and "CBLM" in names[4] and "nudged" in names[5]
    for rows in result["rows"]:
        assert [row["row"] for row in rows] == names  # the same rows for every seed
        for row in rows:
            assert row["n"] == 2
            for key, value in row.items():
                if key.endswith(("goal_reached", "lifted", "in_region", "handed_over")):
                    assert 0 <= value <= row["n"], (row["row"], key, value)
        composed = rows[4]
        for key in ("bc", "bc_strong"):
            assert 0.0 <= composed[key] <= 100.0
            assert 0 <= composed[f"{key}_lifted"] <= 2
        assert 0.0 < composed["zero_floor"] < 100.0
    # each row's mean and interval over the seeds
    cell = result["over_seeds"][2]["lifted"]
    assert cell["values"] == [float(r[2]["lifted"]) for r in result["rows"]]
    assert cell["ci95"] >= 0.0
    targets = check_targets(result)
    assert set(targets) == {"grasp", "composed", "nudged"}
    assert targets["grasp"]["per_seed"] == [r[2]["lifted"] for r in result["rows"]]


def test_lifted_is_the_envs_and_the_nudges_are_the_seeds(result: dict[str, Any]) -> None:
    for entry in result["per_seed"]:
        composed = entry["composed"]
        assert composed["lifted"] == sum(c["lifted"] for c in composed["cases"])
        assert entry["nudges"] == draw_nudges(entry["seed"], 2)
        for case, nudge in zip(entry["nudged"]["cases"], entry["nudges"], strict=True):
            assert case["nudge"] == nudge
        for case in entry["composed"]["cases"]:
            assert case["nudge"] is None and not case["nudged"]
        hand = entry["handoff"]
        assert hand["n"] == 2 and len(hand["cases"]) == 2
        # the teacher hands over inside the approach's goal region
        assert hand["teacher_in_region"] == 2
        teacher = entry["teacher_nudged"]
        assert teacher["nudged"] == 2  # the teacher stands ready to grasp: nudged every time
        assert 0 <= teacher["lifted"] <= 2
    assert "_figures" in result and len(result["_figures"]["composed"]) == 2


def test_nudges_lie_in_their_ranges() -> None:
    nudges = draw_nudges(0, 50)
    d = np.array([n["distance"] for n in nudges])
    a = np.array([n["angle"] for n in nudges])
    assert NUDGE_DISTANCE_M[0] <= d.min() and d.max() <= NUDGE_DISTANCE_M[1]
    assert NUDGE_ANGLE_DEG[0] <= a.min() and a.max() <= NUDGE_ANGLE_DEG[1]
    assert draw_nudges(0, 5) == nudges[:5] and draw_nudges(1, 5) != nudges[:5]


def test_wrapper_nudges_the_object_once_ready_to_grasp() -> None:
    wrapper = NudgeWrapper(gripper_env(), nudge={"distance": 0.015, "angle": 10.0})
    teacher = Teacher(wrapper)
    try:
        teacher.demonstrate("turn-approach-grasp", 30.0, 0.2, seed=0)
    except Exception:  # the teacher may miss the moved object: only the nudge is tested
        pass
    episode = wrapper.episodes[-1]
    assert episode["nudged"] and episode["nudge"] == {"distance": 0.015, "angle": 10.0}
    moved = np.hypot(*np.subtract(episode["object_end"][:2], episode["object_start"][:2]))
    assert moved > 0.005
    # armed for one run of a case, then back to its own nudge
    wrapper.arm(1, case=7, nudge=None)
    wrapper.reset(options={"angle": 0.0, "distance": 0.3})
    assert wrapper.episodes[-1]["case"] == 7 and wrapper.episodes[-1]["nudge"] is None
    _, info = wrapper.reset(options={"angle": 0.0, "distance": 0.3})
    assert wrapper.episodes[-1]["case"] is None and not info["nudged"]


def test_bc_takes_the_declared_grasp_goal() -> None:
    """BC on the composed data stops on the declared goal (arm up, object held), not where
    the approach ends, and scales each of the four command channels in its own unit."""
    from behavior_hmm.teach import collect

    data = collect(
        "turn-approach-grasp",
        [{"angle": 0.0, "distance": 0.1}, {"angle": 60.0, "distance": 0.2}],
        env=gripper_env(),
    )
    inputs = ("distance", "angle", "arm", "fingers", "object_present")
    bc = BehaviorCloning(inputs=inputs, epochs=1).fit(data)
    assert bc.goal_channels_ == ("arm", "object_present")
    assert bc.resolve_goal(None) == {"arm": 80.0, "object_present": 1.0}
    assert bc.command_channels == ("left", "right", "arm_speed", "finger_speed")
    scales = bc.command_scales_
    assert scales[0] == scales[1] and len(set(scales.tolist())) == 3
    # approach's declared goal names distance: the data contract's rule, as before
    approach = collect("approach", [{"distance": 0.2}, {"distance": 0.3}], env=gripper_env())
    assert BehaviorCloning(inputs=("distance", "angle"), epochs=1).fit(approach).goal_channels_ == (
        "angle",
        "distance",
    )


def test_cli_refuses_bad_counts(tmp_path: Path) -> None:
    from behavior_hmm.cli import app

    runner = CliRunner()
    for args, needle in (
        (["--seeds", "0"], "--seeds"),
        (["--limit", "0"], "--limit"),
    ):
        out = runner.invoke(app, ["experiment", "grasp", "-o", str(tmp_path / "g"), *args])
        assert_user_error(out, needle)
        assert not (tmp_path / "g" / "results.json").exists()


def test_report_files(result: dict[str, Any], tmp_path: Path) -> None:
    from behavior_hmm.viz._grasp import FIGURES, write_grasp_report

    table = write_grasp_report({**result, "preset": "default"}, tmp_path)
    assert "default preset" in table and "MuJoCo" in table
    saved = json.loads((tmp_path / "results.json").read_text())
    assert "_figures" not in saved and "_models" not in saved
    assert set(saved["targets_met"]) == {"grasp", "composed", "nudged"}
    for name in FIGURES.values():
        assert (tmp_path / name).stat().st_size > 10_000
    assert (tmp_path / "table.md").read_text() == table
