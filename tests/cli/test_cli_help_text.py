"""``--help`` re-flows each docstring paragraph (issue 26): the source's hard line breaks
never show, so no help line ends mid-sentence because of one."""

from __future__ import annotations

import inspect
from typing import Any

import pytest
from cli_testing import all_commands
from typer.testing import CliRunner

from behavior_hmm.cli import app
from behavior_hmm.cli._common import reflow_help

COMMANDS = all_commands()
IDS = [" ".join(path) or "behavior-hmm" for path, _ in COMMANDS]


def _source(command: Any) -> str:
    """The help as written: the command function's docstring, else the group's help."""
    doc = inspect.getdoc(command.callback) if command.callback is not None else None
    return doc or command.help or ""


def _paragraphs(text: str) -> list[str]:
    return [" ".join(p.split()) for p in text.split("\n\n") if p.strip()]


@pytest.mark.parametrize(("path", "command"), COMMANDS, ids=IDS)
def test_every_paragraph_is_one_line_on_a_wide_terminal(
    path: tuple[str, ...], command: Any
) -> None:
    result = CliRunner().invoke(app, [*path, "--help"], env={"COLUMNS": "1000"})
    assert result.exit_code == 0, result.output
    lines = {line.strip(" │") for line in result.stdout.splitlines()}
    for paragraph in _paragraphs(_source(command)):
        assert paragraph in lines, (paragraph, result.stdout)


def test_the_walk_reads_the_docstrings() -> None:
    """The check above compares with the source: several docstrings break lines."""
    broken = [p for p, c in COMMANDS if any("\n" in q for q in _source(c).split("\n\n"))]
    assert {("evaluate",), ("collect",), ("experiment", "faults")} <= set(broken)


def test_on_a_narrow_terminal_the_help_wraps_at_its_width() -> None:
    result = CliRunner().invoke(app, ["evaluate", "--help"], env={"COLUMNS": "60"})
    assert result.exit_code == 0, result.output
    assert all(len(line) <= 60 for line in result.stdout.splitlines())
    shown = " ".join(result.stdout.split())
    assert "records the largest command change in one period" in shown
    assert "with --env they run in this process" in shown


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            "Title.\n\nOne\nsentence.\n\nExample: a\n--b c",
            "Title.\n\nOne sentence.\n\nExample: a --b c",
        ),
        (
            "Title.\n\n    One\n    sentence.",  # indented as in a docstring
            "Title.\n\nOne sentence.",
        ),
        ("Title.\n\nUsage:\n    behavior-hmm a\n    behavior-hmm b", None),  # a layout: kept
        ("Title.\n\nChoices:\n- one\n- two", None),
        ("Title.\n\nRun:\nbehavior-hmm a\nbehavior-hmm b", None),
        ("Title.\n\n\b\nkeep\nthese lines", None),
        (
            "Title.\n\nJoin\nthis.\f\nafter the\nform feed",
            "Title.\n\nJoin this.\f\nafter the\nform feed",
        ),
        (None, None),
        ("", ""),
    ],
)
def test_reflow_help(text: str | None, expected: str | None) -> None:
    assert reflow_help(text) == (text if expected is None else expected)
