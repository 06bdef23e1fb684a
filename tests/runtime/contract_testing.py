"""Helpers shared by the robot-contract tests (imported as ``contract_testing``)."""

from __future__ import annotations

from collections.abc import Callable

from typer.testing import Result

#: ``cli(*args)``: run the command line in-process; it must exit 0 (the ``cli`` fixture).
Cli = Callable[..., Result]
