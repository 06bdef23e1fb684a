"""The installed ``behavior-hmm`` console script, run as a real process (no TTY)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from cli_testing import png_size, write_starts

from behavior_hmm import data

SCRIPT = Path(sys.executable).with_name("behavior-hmm")

pytestmark = pytest.mark.skipif(not SCRIPT.exists(), reason="console script not installed")


def _run(*args: object, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "COLUMNS": "100"}
    return subprocess.run(
        [str(SCRIPT), *[str(a) for a in args]],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def test_collect_then_inspect(tmp_path: Path) -> None:
    write_starts(tmp_path / "starts.csv", "angle,distance", "120,0.4", "-90,0.8")
    args = ["--starts", "starts.csv", "--sim", "kinematic", "--noise", "0.005", "-o", "ta.parquet"]
    done = _run("collect", "turn-approach", *args, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    assert "wrote ta.parquet: 2 episodes" in done.stdout
    done = _run("inspect", "ta.parquet", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "episodes: 2" in done.stdout
    assert "behaviors: approach, turn" in done.stdout or "behaviors: turn, approach" in done.stdout
    png_size(tmp_path / "ta.png")
    assert data.read(tmp_path / "ta.parquet").metadata["noise"] == 0.005


def test_user_error_is_one_line_with_exit_code_2(tmp_path: Path) -> None:
    write_starts(tmp_path / "starts.csv", "angle,distance", "30,0.4", "40,1.5")
    done = _run(
        "collect",
        "turn",
        "--starts",
        "starts.csv",
        "--sim",
        "kinematic",
        "-o",
        "o.parquet",
        cwd=tmp_path,
    )
    assert done.returncode == 2
    assert done.stdout == ""
    assert done.stderr.splitlines() == [
        "error: starts.csv, row 3: start outside the arena: distance 1.5 m not in [0, 1.2]"
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["starts.csv"]
