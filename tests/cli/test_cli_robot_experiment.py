"""``experiment robot --env``: the headline tasks on a robot we did not build."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from cli_testing import Invoke

CONTRACT_ROBOT = Path(__file__).resolve().parents[1] / "runtime" / "test_robot_contract.py"


@pytest.mark.slow
def test_experiment_robot_on_a_robot_of_another_size(invoke: Invoke, tmp_path: Path) -> None:
    out = tmp_path / "robot"
    result = invoke(["experiment", "robot", "--env", f"{CONTRACT_ROBOT}:make", "-o", out])
    assert result.exit_code == 0, result.output
    results = json.loads((out / "results.json").read_text())
    assert results["control_period"] == 0.02 and results["start_scale"] == {"distance": 2.0}
    rows = {row["behavior"]: row for row in results["rows"]}
    assert set(rows) == {"turn", "approach", "turn-approach"}
    assert rows["turn-approach"]["model"] == "CBLM"
    for row in rows.values():
        # the goal, not only the score: every task reaches it nearly always
        assert row["goal_reached"] >= 14, row
        assert row["success_rate"] > row["zero_floor"] + 30.0, row
    assert (out / "trajectories.png").stat().st_size > 10_000
    assert "turn & approach (composed)" in (out / "table.md").read_text()
