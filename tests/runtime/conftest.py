"""Fixtures of the robot-contract tests."""

from __future__ import annotations

from typing import Any

import pytest
from contract_testing import Cli
from typer.testing import CliRunner, Result

from behavior_hmm.cli import app


@pytest.fixture
def cli() -> Cli:
    """Run ``behavior-hmm ARGS`` in-process and assert it succeeded (the output on failure)."""
    runner = CliRunner()

    def run(*args: Any) -> Result:
        out = runner.invoke(app, [str(a) for a in args])
        assert out.exit_code == 0, out.output
        return out

    return run
