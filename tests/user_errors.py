"""The one-line user error every command gives (exit 2, ``error: ...``, no traceback),
asserted alike by the CLI tests of every package (imported as ``user_errors``)."""

from __future__ import annotations

from typer.testing import Result

__all__ = ["assert_user_error"]


def assert_user_error(result: Result, *needles: str) -> str:
    """Exit code 2, exactly one line on stderr starting ``error: ``, no traceback anywhere.

    Returns the error line; each of ``needles`` must occur in it.
    """
    assert result.exit_code == 2, (result.exit_code, result.output, result.exception)
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    line = lines[0]
    assert line.startswith("error: "), line
    assert "Traceback" not in result.output
    for needle in needles:
        assert needle in line, (needle, line)
    return line
