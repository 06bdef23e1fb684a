"""evaluate --push: every run pushed at a fraction of the teacher's duration."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from cli_testing import Invoke, assert_user_error, write_starts

from behavior_hmm.models import SBLM


def test_evaluate_push_records_pushed_cases(
    invoke: Invoke, turn_model: SBLM, tmp_path: Path
) -> None:
    model = tmp_path / "turn.bhmm"
    turn_model.save(model)
    starts = write_starts(tmp_path / "s.csv", "angle", "120", "-60")
    out = tmp_path / "e.json"
    result = invoke(
        ["evaluate", model, "--starts", starts, "--sim", "kinematic",
         "--push", "at=0.5,angle=15", "--json", out]
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    assert data["pushed"] == 2 and all(c["pushed"] for c in data["cases"])
    assert {"command_jump_ratio_median", "command_jump_ratio_max", "switches_max"} <= set(data)
    assert "pushed" in result.output and "jump" in result.output


@pytest.mark.parametrize(
    ("push", "needle"),
    [
        ("at=2", "fraction"),
        ("when=0.5", "unknown key"),
        ("at=0.5,angle=400", "180"),
        ("at=0.5,at=0.6", "at"),
    ],
)
def test_bad_push_is_refused(invoke: Invoke, turn_bhmm: Path, push: str, needle: str) -> None:
    assert_user_error(invoke(["evaluate", turn_bhmm, "--sim", "kinematic", "--push", push]), needle)
