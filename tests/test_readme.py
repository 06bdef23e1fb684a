"""The README's quick start is what CI runs."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def quick_start_commands() -> list[str]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    pattern = r"(?im)^#+[^\n]*quick\s*-?\s*start[^\n]*\n(.*?)```[^\n]*\n(.*?)```"
    match = re.search(pattern, text, re.S)
    assert match, "README has no Quick start section with a code block"
    return [line.strip() for line in match.group(2).splitlines() if line.strip()]


def test_quick_start_has_two_commands() -> None:
    commands = quick_start_commands()
    assert len(commands) == 2
    assert "behavior-hmm demo" in commands[0]
    assert "pytest" in commands[1]


def test_ci_runs_the_readme_test_command_verbatim() -> None:
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert quick_start_commands()[1] in ci.splitlines()
