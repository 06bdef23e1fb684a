"""``behavior-hmm inspect`` on a trace (the Parquet ``generate -o`` writes): its summary,
a plot on request, and the trace read back column for column."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from cli_testing import Invoke, assert_user_error, files_in, png_size

from behavior_hmm.cli._trace_files import TRACE_KEY, read_trace


@pytest.fixture(scope="module")
def trace_file(tmp_path_factory: pytest.TempPathFactory, turn_bhmm: Path) -> tuple[Path, dict]:
    """A turn run from 60 deg (kinematic), and the summary generate printed."""
    from typer.testing import CliRunner

    from behavior_hmm.cli import app

    out = tmp_path_factory.mktemp("trace") / "run.parquet"
    args = ["generate", turn_bhmm, "--sim", "kinematic", "--start", "angle=60", "-o", out]
    result = CliRunner().invoke(app, [str(a) for a in args])
    assert result.exit_code in (0, 1), result.output
    return out, json.loads(result.stdout.splitlines()[0])


def test_inspect_prints_the_trace_summary(
    invoke: Invoke, trace_file: tuple[Path, dict], tmp_path: Path
) -> None:
    path, printed = trace_file
    before = files_in(path.parent)
    result = invoke(["inspect", path])
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert f"steps: {printed['steps']}, duration_s: {printed['duration_s']:.4g}" in out
    assert "start: angle 60 deg" in out
    assert "goal: angle 0 deg" in out
    assert f"reached: {'yes' if printed['goal_reached'] else 'no'}" in out
    assert f"reason: {printed['reason']}" in out
    assert f"final errors: angle {printed['final_errors']['angle']:.4g} deg" in out
    assert "plot:" not in out and files_in(path.parent) == before  # a trace plots on request
    assert result.stderr == ""


def test_inspect_plots_the_trace_and_writes_its_summary(
    invoke: Invoke, trace_file: tuple[Path, dict], tmp_path: Path
) -> None:
    path, printed = trace_file
    png, summary = tmp_path / "run.png", tmp_path / "run.json"
    result = invoke(["inspect", path, "--plot", png, "--json", summary])
    assert result.exit_code == 0, result.output
    assert f"plot: {png}" in result.stdout
    width, height = png_size(png)
    assert width >= 300 and height >= 300
    written = json.loads(summary.read_text())
    assert {k: written[k] for k in printed} == printed
    assert written["channels"] == ["distance", "linear_velocity", "angle", "angular_velocity"]


def test_a_trace_reads_back_column_for_column(trace_file: tuple[Path, dict]) -> None:
    path, printed = trace_file
    trace, summary = read_trace(path)
    assert summary["steps"] == len(trace) == printed["steps"]
    assert trace.goal == printed["goal"] and trace.start == printed["start"]
    assert trace.goal_reached == printed["goal_reached"] and trace.reason == printed["reason"]
    table = pq.read_table(path)
    again = trace.to_columns()
    assert sorted(again) == sorted(table.column_names)
    for name in table.column_names:
        stored = table.column(name).to_numpy(zero_copy_only=False)
        assert np.array_equal(np.asarray(again[name]), stored), name


def _rewrite(
    source: Path, target: Path, drop: str | None = None, meta: bytes | None = None
) -> None:
    table = pq.read_table(source)
    if drop is not None:
        table = table.drop_columns([drop])
    if meta is not None:
        table = table.replace_schema_metadata({TRACE_KEY: meta})
    pq.write_table(table, target)


@pytest.mark.parametrize(
    ("drop", "meta", "needle"),
    [
        ("left", None, "without column(s) left"),
        ("t", None, "without column(s) t"),
        (None, b"[1, 2]", "not a JSON object"),
        (None, b"{not json", "not a JSON object"),
        (None, b'{"goal": {"angle": "north"}}', "goal"),
    ],
    ids=["no left", "no t", "summary a list", "summary not JSON", "goal not a number"],
)
def test_a_broken_trace_is_one_line(
    invoke: Invoke,
    trace_file: tuple[Path, dict],
    tmp_path: Path,
    drop: str | None,
    meta: bytes | None,
    needle: str,
) -> None:
    broken = tmp_path / "broken.parquet"
    _rewrite(trace_file[0], broken, drop, meta)
    result = invoke(["inspect", broken, "--plot", tmp_path / "b.png"])
    assert_user_error(result, "broken.parquet", needle)
    assert not (tmp_path / "b.png").exists()


def test_a_trace_with_text_in_a_number_column_is_one_line(
    invoke: Invoke, trace_file: tuple[Path, dict], tmp_path: Path
) -> None:
    table = pq.read_table(trace_file[0])
    column = pa.array(["x"] * table.num_rows)
    table = table.set_column(table.column_names.index("angle"), "angle", column)
    pq.write_table(table, tmp_path / "text.parquet")
    assert_user_error(invoke(["inspect", tmp_path / "text.parquet"]), "angle", "not numbers")
