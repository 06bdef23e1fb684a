"""experiment ablation: thesis, thesis + each departure, default, default − each."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from behavior_hmm.cli import app
from behavior_hmm.evaluate._ablation import ABLATION_TASKS, AblationRow, ablation_rows, task
from behavior_hmm.models import DEPARTURES, preset_params


def test_rows_of_a_simple_task_leave_out_cblm_departures() -> None:
    rows = ablation_rows(task("turn"))
    sblm = [d.name for d in DEPARTURES if "SBLM" in d.kinds]
    assert [r.label for r in rows] == (
        ["thesis"]
        + [f"thesis + {n}" for n in sblm]
        + ["default"]
        + [f"default − {n}" for n in sblm]
    )
    assert "repair" not in {n for r in rows for n in r.switched}


def test_rows_of_the_complex_task_cover_every_departure() -> None:
    rows = ablation_rows(task("turn-approach"))
    assert len(rows) == 2 + 2 * len(DEPARTURES)
    assert {n for r in rows for n in r.switched} == {d.name for d in DEPARTURES}
    assert [t.name for t in ABLATION_TASKS] == ["turn", "approach", "turn-approach"]


def test_row_parameters() -> None:
    row = AblationRow("thesis", ("repair",))
    assert row.params("CBLM") == {**preset_params("thesis", "CBLM"), "repair": True}
    assert row.params("SBLM") == preset_params("thesis", "SBLM")
    assert AblationRow("default", ("repair",)).params("CBLM")["repair"] is False


@pytest.mark.slow
def test_ablation_command_measures_the_onset_clock(tmp_path: Path) -> None:
    out = tmp_path / "ablation"
    result = CliRunner().invoke(
        app,
        ["experiment", "ablation", "--sim", "kinematic", "--task", "turn",
         "--departure", "onset_clock", "-o", str(out)],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    results = json.loads((out / "results.json").read_text())
    rows = {r["label"]: r for r in results["tasks"][0]["rows"]}
    assert list(rows) == ["thesis", "thesis + onset_clock", "default", "default − onset_clock"]
    # the onset clock is what lets a sensor-only network start from rest (docs/algorithms.md)
    assert (
        rows["thesis + onset_clock"]["success_rate_mean"] > rows["thesis"]["success_rate_mean"] + 10
    )
    assert (
        rows["default"]["success_rate_mean"]
        > rows["default − onset_clock"]["success_rate_mean"] + 10
    )
    assert rows["default"]["goal_reached"] == 15
    for row in rows.values():  # every score beside its floor
        assert row["zero_floor_mean"] < row["success_rate_mean"]
    table = (out / "table.md").read_text()
    assert "| **thesis preset** |" in table and "| default − onset_clock |" in table
    assert (out / "ablation.png").stat().st_size > 10_000
