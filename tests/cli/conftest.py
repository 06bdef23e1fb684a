"""Fixtures for end-to-end tests of the command line (kinematic sim, small data)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import pytest
from cli_testing import Invoke, write_starts
from typer.testing import CliRunner, Result

from behavior_hmm.cli import app


@pytest.fixture
def invoke() -> Invoke:
    """Run the CLI in-process (not a TTY, like a pipe) and return the result."""
    runner = CliRunner()

    def run(args: Sequence[object]) -> Result:
        return runner.invoke(app, [str(a) for a in args])

    return run


@pytest.fixture(scope="session")
def turn_parquet(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small turn dataset made by the CLI: 3 starts, kinematic, seed 5, noise 0.01."""
    folder = tmp_path_factory.mktemp("turn")
    starts = write_starts(folder / "starts.csv", "angle", "120", "-45", "170")
    out = folder / "turn.parquet"
    args = ["collect", "turn", "--starts", starts, "--sim", "kinematic"]
    args += ["--seed", "5", "--noise", "0.01", "-o", out]
    result = CliRunner().invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    return out


@pytest.fixture(scope="session")
def turn_bhmm(turn_parquet: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A turn model (.bhmm) trained by the CLI on ``turn_parquet`` (angle input)."""
    out = tmp_path_factory.mktemp("model") / "turn.bhmm"
    args = ["train", "simple", turn_parquet, "--inputs", "angle", "-o", out]
    result = CliRunner().invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    return out
