"""experiment parallel: sequential against parallel turn & approach (thesis 7.2)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from behavior_hmm.cli import app
from behavior_hmm.evaluate._parallel import ROWS, path_length, run_parallel_experiment
from behavior_hmm.models import preset_params
from behavior_hmm.viz._parallel import FIGURE_NAME, parallel_markdown, write_parallel_report


def test_path_length_sums_the_steps_in_the_plane() -> None:
    pose = np.array([[0.0, 0.0, 1.0], [3.0, 4.0, 2.0], [3.0, 5.0, 0.0]])
    assert path_length(pose) == pytest.approx(6.0)  # the heading column is not a distance
    assert path_length(pose[:1]) == 0.0


@pytest.mark.slow
def test_the_parallel_model_arrives_sooner_than_the_sequential_one(tmp_path: Path) -> None:
    sblm = {**preset_params("default", "SBLM"), "epochs": 30}
    results = run_parallel_experiment(
        sim="kinematic", sblm_params=sblm, cblm_params=preset_params("default", "CBLM")
    )
    rows = results["rows"]
    assert list(rows) == [key for key, _ in ROWS]
    for row in rows.values():
        assert row["n"] == 15 and row["zero_floor_mean"] < row["success_rate_mean"]
    # turning while approaching takes less time than one after the other, for the
    # teachers and for the learned models, and running both at once is what buys it
    assert (
        rows["parallel"]["teacher_time_total_s"] < 0.95 * rows["sequential"]["teacher_time_total_s"]
    )
    assert rows["parallel"]["time_ratio_median"] < 0.95
    assert rows["one_at_a_time"]["time_total_s"] > rows["parallel"]["time_total_s"]
    assert rows["parallel"]["success_rate_mean"] > rows["one_at_a_time"]["success_rate_mean"] + 10
    assert results["parallel_categories"] > 0
    # the bound: the sequential teacher's whole turn beside its approach; the parallel
    # teacher, which drives only once it faces the object within 80 deg, saves less
    sequential = rows["sequential"]["cases"]
    assert all(0.0 <= c["teacher_turn_s"] <= c["teacher_time_s"] for c in sequential)
    assert sum(c["teacher_turn_s"] > 0 for c in sequential) == 14  # all but the one at 0 deg
    bound = np.median(
        [max(c["teacher_turn_s"], c["teacher_time_s"] - c["teacher_turn_s"]) for c in sequential]
        / np.array([c["teacher_time_s"] for c in sequential])
    )
    teacher = np.median(
        [
            p["teacher_time_s"] / s["teacher_time_s"]
            for p, s in zip(rows["parallel"]["cases"], sequential, strict=True)
        ]
    )
    assert 0.5 < bound < teacher < 1.0
    table = write_parallel_report(results, tmp_path / "parallel")
    assert "| parallel teacher |" in table and "time ÷ sequential" in table
    assert f"| {bound:.3f} (÷ sequential teacher's) |" in table
    saved = json.loads((tmp_path / "parallel" / "results.json").read_text())
    assert "timings" not in saved and parallel_markdown(saved) == table
    assert (tmp_path / "parallel" / FIGURE_NAME).stat().st_size > 20_000


def test_bad_options_are_refused_before_any_work() -> None:
    for options, message in (
        (["--seeds", "0"], "--seeds must be an integer"),
        (["--sim", "webots"], "webots"),
        (["--set", "parallel=maybe"], "parallel"),
    ):
        result = CliRunner().invoke(app, ["experiment", "parallel", *options])
        assert result.exit_code == 2, result.output
        assert message in result.output
