"""docs/usage.md only shows commands and options that exist."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest
from cli_testing import Invoke

USAGE = Path(__file__).resolve().parents[2] / "docs" / "usage.md"


def _documented_commands() -> list[list[str]]:
    text = USAGE.read_text(encoding="utf-8")
    commands = []
    for block in re.findall(r"```bash\n(.*?)```", text, re.S):
        joined = block.replace("\\\n", " ")
        for line in joined.splitlines():
            line = line.split("#")[0].strip()
            if line.startswith("behavior-hmm "):
                commands.append(shlex.split(line)[1:])
    return commands


def test_usage_has_examples_of_every_foundation_command() -> None:
    used = {args[0] for args in _documented_commands() if args}
    assert {"collect", "import-csv", "inspect", "bench", "demo"} <= used


@pytest.mark.parametrize("args", _documented_commands(), ids=lambda a: " ".join(a)[:60])
def test_documented_options_exist(invoke: Invoke, args: list[str]) -> None:
    if args == ["--help"]:
        return
    # command groups (train simple, experiment complex) document their subcommand's options
    depth = 2 if args[0] in ("train", "experiment") and len(args) > 1 else 1
    result = invoke([*args[:depth], "--help"])
    assert result.exit_code == 0, result.output
    for word in args[depth:]:
        if word.startswith("--"):
            assert word.split("=")[0] in result.stdout, word
