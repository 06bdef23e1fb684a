"""End-to-end: train / generate / evaluate through the command line (kinematic, small data)."""

from __future__ import annotations

import html
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from behavior_hmm.cli import app

runner = CliRunner()


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("learn")
    (d / "starts.csv").write_text("angle\n" + "\n".join(str(a) for a in range(-170, 181, 20)))
    res = runner.invoke(
        app,
        [
            "collect",
            "turn",
            "--starts",
            str(d / "starts.csv"),
            "--sim",
            "kinematic",
            "-o",
            str(d / "turn.parquet"),
        ],
    )
    assert res.exit_code == 0, res.output
    res = runner.invoke(
        app,
        [
            "train",
            "simple",
            str(d / "turn.parquet"),
            "--inputs",
            "angle",
            "-o",
            str(d / "turn.bhmm"),
        ],
    )
    assert res.exit_code == 0, res.output
    return d


def _one_error_line(output: str) -> str:
    lines = [line for line in output.strip().splitlines() if line.strip()]
    assert len(lines) == 1, output
    assert lines[0].startswith("error:"), output
    assert "Traceback" not in output
    return lines[0]


def test_generate_writes_trace_and_plot(workdir: Path) -> None:
    res = runner.invoke(
        app,
        [
            "generate",
            str(workdir / "turn.bhmm"),
            "--start",
            "angle=65,distance=0.5",
            "--goal",
            "angle=0",
            "--sim",
            "kinematic",
            "-o",
            str(workdir / "run.parquet"),
            "--plot",
            str(workdir / "run.png"),
        ],
    )
    assert res.exit_code in (0, 1), res.output  # 1 = ran but missed the goal
    summary = json.loads(res.output.splitlines()[0])
    assert summary["goal"] == {"angle": 0.0}
    assert (workdir / "run.parquet").stat().st_size > 0
    assert (workdir / "run.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_evaluate_with_bc_baseline_writes_json(workdir: Path) -> None:
    starts = workdir / "test.csv"
    starts.write_text("angle\n45\n-75\n")
    out = workdir / "eval.json"
    res = runner.invoke(
        app,
        [
            "evaluate",
            str(workdir / "turn.bhmm"),
            "--starts",
            str(starts),
            "--sim",
            "kinematic",
            "--baseline",
            "bc",
            "--data",
            str(workdir / "turn.parquet"),
            "--json",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.output
    result = json.loads(out.read_text())
    assert result["n"] == 2 and "bc" in result["baselines"]
    assert "zero_floor_mean" in result and "success_rate_motor_max_mean" in result


def test_evaluate_writes_a_self_contained_html_report(workdir: Path) -> None:
    starts = workdir / "report.csv"
    starts.write_text("angle\n35\n-95\n")
    page = workdir / "report.html"
    res = runner.invoke(
        app,
        ["evaluate", str(workdir / "turn.bhmm"), "--starts", str(starts), "--sim", "kinematic",
         "--report", str(page)],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    text = page.read_text(encoding="utf-8")
    assert "zero floor" in text and "goals reached" in text
    assert text.count("<img") == 2 and "data:image/png;base64," in text
    assert "35°, 0.50 m" in html.unescape(text)  # starts in units, not dict reprs


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--start", "angle=abc"], "not a number"),
        (["--start", "angle"], "CHANNEL=VALUE"),
        (["--start", "angle=30,distance=5"], "outside the arena"),
        (["--start", "angle=30", "--goal", "distance=0"], "not an input"),
        (["--start", "angle=30", "--goal", "heading=0"], "unknown goal channel"),
        (["--start", "angle=30", "--sim", "webots"], "unknown simulator"),
    ],
)
def test_bad_start_and_goal_are_one_line_errors(
    workdir: Path, args: list[str], needle: str
) -> None:
    res = runner.invoke(app, ["generate", str(workdir / "turn.bhmm"), *args])
    assert res.exit_code == 2
    assert needle in _one_error_line(res.output)


def test_bad_starts_csv_and_bad_model_file(workdir: Path) -> None:
    bad = workdir / "bad.csv"
    bad.write_text("angle,speed\n10,1\n")
    res = runner.invoke(app, ["evaluate", str(workdir / "turn.bhmm"), "--starts", str(bad)])
    assert res.exit_code == 2
    assert "speed" in _one_error_line(res.output)
    junk = workdir / "junk.bhmm"
    junk.write_bytes(b"\x80\x04K\x01.")  # a pickle
    res = runner.invoke(app, ["generate", str(junk), "--start", "angle=10"])
    assert res.exit_code == 2
    assert "junk.bhmm" in _one_error_line(res.output)
    res = runner.invoke(
        app,
        [
            "train",
            "simple",
            str(workdir / "missing.parquet"),
            "--inputs",
            "angle",
            "-o",
            str(workdir / "x.bhmm"),
        ],
    )
    assert res.exit_code == 2 and not (workdir / "x.bhmm").exists()
