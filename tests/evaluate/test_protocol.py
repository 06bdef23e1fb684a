from __future__ import annotations

import json

import pytest

from behavior_hmm.data import Dataset
from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate import BehaviorCloning, evaluate_model, split_start
from behavior_hmm.models import SBLM

STARTS = [{"angle": 55.0}, {"angle": -35.0}, {"angle": 125.0}]


@pytest.fixture(scope="module")
def result(turn_model: SBLM, turn_data: Dataset) -> dict:
    bc = BehaviorCloning(inputs=("angle",), epochs=40).fit(turn_data)
    return evaluate_model(turn_model, STARTS, sim="kinematic", baselines={"bc": bc})


def test_evaluation_json_contract(result: dict) -> None:
    for key in (
        "behavior",
        "inputs",
        "n",
        "success_rate_mean",
        "goal_reached",
        "zero_floor_mean",
        "success_rate_motor_max_mean",
        "cases",
        "baselines",
    ):
        assert key in result
    assert result["behavior"] == "turn" and result["inputs"] == ["angle"]
    assert result["n"] == 3 and len(result["cases"]) == 3
    case = result["cases"][0]
    for key in (
        "start",
        "success_rate",
        "goal_reached",
        "final_angle_error_deg",
        "final_distance_error_m",
        "duration_ratio",
    ):
        assert key in case
    assert case["start"] == {"angle": 55.0, "distance": 0.5}
    bc = result["baselines"]["bc"]
    assert bc["n"] == 3 and "success_rate_mean" in bc and len(bc["cases"]) == 3
    json.dumps(result)  # JSON-ready


def test_scores_are_read_against_the_floor(result: dict) -> None:
    for case in result["cases"]:
        assert 0.0 <= case["success_rate"] <= 100.0
        assert 0.0 <= case["zero_floor"] < 100.0
        # motor-limit normalization is far more lenient: a stalled robot scores high
        assert case["zero_floor_motor_max"] > case["zero_floor"]


def test_split_start_and_empty_starts(turn_model: SBLM) -> None:
    assert split_start({"angle": 3.0, "goal_distance": 0.4}) == (
        {"angle": 3.0},
        {"distance": 0.4},
    )
    with pytest.raises(ConfigError):
        evaluate_model(turn_model, [], sim="kinematic")


def test_bc_reaches_goals_with_tolerance_stop(turn_data: Dataset) -> None:
    from behavior_hmm.sim import make_env

    bc = BehaviorCloning(inputs=("angle",), epochs=40).fit(turn_data)
    trace = bc.generate(make_env("kinematic"), start={"angle": 80.0, "distance": 0.5}, seed=0)
    assert abs(trace.final_observation[2]) < 80.0  # it turned toward the object


def test_command_scale_is_the_demonstrations_not_the_motor_limit(result: dict) -> None:
    assert result["command_scale_at_motor_limit"] is False
    assert result["command_scale"] < 0.5 * result["motor_max"]


def test_smoothness_and_switches_are_reported(result: dict) -> None:
    for case in result["cases"]:
        assert case["command_jump_ratio"] > 0 and case["switches"] >= 0
        assert "pushed" not in case
    ratios = [c["command_jump_ratio"] for c in result["cases"]]
    assert result["command_jump_ratio_median"] == pytest.approx(sorted(ratios)[1])
    assert result["command_jump_ratio_max"] == pytest.approx(max(ratios))
    assert result["switches_max"] == max(c["switches"] for c in result["cases"])
    assert result["kind"] == "SBLM"


def test_a_push_is_applied_in_every_case_with_a_seeded_sign(turn_model: SBLM) -> None:
    push = {"at": 0.5, "angle": 20.0}
    first = evaluate_model(turn_model, STARTS, sim="kinematic", seed=3, push=push)
    again = evaluate_model(turn_model, STARTS, sim="kinematic", seed=3, push=push)
    plain = evaluate_model(turn_model, STARTS, sim="kinematic", seed=3)
    assert first["pushed"] == 3 and all(c["pushed"] for c in first["cases"])
    assert [c["steps"] for c in first["cases"]] == [c["steps"] for c in again["cases"]]
    # a 20 deg push halfway makes the runs longer than the undisturbed ones
    assert sum(c["steps"] for c in first["cases"]) > sum(c["steps"] for c in plain["cases"])
    with pytest.raises(ConfigError, match="fraction"):
        evaluate_model(turn_model, STARTS[:1], sim="kinematic", push={"at": 1.5})
