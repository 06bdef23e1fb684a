"""What every command shares (issue 12, item 4): ``--help`` with a copy-paste example,
``-h``, ``--version``, and ``--verbose`` / ``--quiet`` through the logging module."""

from __future__ import annotations

import re
import shlex
import shutil
import time
from pathlib import Path
from typing import Any

import pytest
from cli_testing import Invoke, all_commands, assert_user_error

from behavior_hmm import __version__

COMMANDS = all_commands()
IDS = [" ".join(path) or "behavior-hmm" for path, _ in COMMANDS]


def _flat(text: str) -> str:
    """Help text with rich's panel borders and line breaks folded into single spaces."""
    return " ".join(re.sub(r"[│╭╮╰╯─]", " ", text).split())


def test_the_walk_finds_every_command() -> None:
    paths = {" ".join(path) for path, _ in COMMANDS}
    expected = {"collect", "inspect", "import-csv", "import-bag", "import-lerobot"}
    expected |= {"export-lerobot", "train simple", "train complex", "generate", "evaluate"}
    expected |= {f"experiment {name}" for name in ("simple", "complex", "ablation", "faults")}
    expected |= {"experiment categorization", "experiment generators", "experiment robot"}
    expected |= {"bench", "demo"}
    assert expected <= paths


@pytest.mark.parametrize(("path", "command"), COMMANDS, ids=IDS)
def test_help_has_a_copy_paste_example(invoke: Invoke, path: tuple[str, ...], command: Any) -> None:
    result = invoke([*path, "--help"])
    assert result.exit_code == 0, result.output
    shown = _flat(result.stdout)
    assert f"Example: behavior-hmm {' '.join(path)}".strip() in shown, shown
    # the example's options are options of this command (its own help names them)
    example = re.search(r"Example: (behavior-hmm .*?)(?:\n\n|$)", command.help or "", re.S)
    assert example is not None, command.help
    words = shlex.split(example.group(1).replace("\\\n", " "))
    for word in words:
        if word.startswith("-") and len(word) > 1:
            assert re.search(rf"(^|\s){re.escape(word.split('=')[0])}(\s|,|$)", shown), word


@pytest.mark.parametrize(("path", "command"), COMMANDS, ids=IDS)
def test_dash_h_is_help(invoke: Invoke, path: tuple[str, ...], command: Any) -> None:
    short, long = invoke([*path, "-h"]), invoke([*path, "--help"])
    assert short.exit_code == 0, short.output
    assert short.stdout == long.stdout
    assert "Usage: " in short.stdout


@pytest.mark.parametrize(("path", "command"), COMMANDS, ids=IDS)
def test_sim_lists_its_choices(invoke: Invoke, path: tuple[str, ...], command: Any) -> None:
    if not any("--sim" in getattr(p, "opts", ()) for p in getattr(command, "params", [])):
        pytest.skip("no --sim")
    shown = _flat(invoke([*path, "--help"]).stdout)
    assert re.search(r"--sim .*mujoco.*kinematic", shown), shown


def test_version(invoke: Invoke) -> None:
    result = invoke(["--version"])
    assert result.exit_code == 0, result.output
    assert result.stdout == f"behavior-hmm {__version__}\n"
    assert result.stderr == ""


def test_quiet_keeps_results_and_drops_info_lines(
    invoke: Invoke, tmp_path: Path, turn_parquet: Path
) -> None:
    dataset = Path(shutil.copy(turn_parquet, tmp_path / "turn.parquet"))
    loud = invoke(["inspect", dataset, "--plot", tmp_path / "a.png"])
    quiet = invoke(["--quiet", "inspect", dataset, "--plot", tmp_path / "b.png"])
    assert loud.exit_code == quiet.exit_code == 0, quiet.output
    assert f"plot: {tmp_path / 'a.png'}" in loud.stdout
    assert "plot:" not in quiet.stdout and quiet.stderr == ""
    assert quiet.stdout == loud.stdout.replace(f"plot: {tmp_path / 'a.png'}\n", "")
    assert (tmp_path / "b.png").stat().st_size > 0  # quiet, not idle
    again = invoke(["inspect", dataset, "--plot", tmp_path / "c.png"])  # no state left over
    assert f"plot: {tmp_path / 'c.png'}" in again.stdout


def test_quiet_drops_the_progress_bar(invoke: Invoke, tmp_path: Path) -> None:
    starts = tmp_path / "s.csv"
    starts.write_text("angle\n30\n")
    args = ["collect", "turn", "--starts", starts, "--sim", "kinematic"]
    result = invoke(["-q", *args, "-o", tmp_path / "x.parquet"])
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"wrote {tmp_path / 'x.parquet'}: 1 episodes")


def test_verbose_adds_debug_lines_on_stderr_only(invoke: Invoke, turn_bhmm: Path) -> None:
    plain = invoke(["inspect", turn_bhmm])
    verbose = invoke(["--verbose", "inspect", turn_bhmm])
    assert plain.exit_code == verbose.exit_code == 0, verbose.output
    assert verbose.stdout == plain.stdout
    assert plain.stderr == ""
    assert any(line.startswith("debug: loaded ") for line in verbose.stderr.splitlines())


def test_verbose_and_quiet_together_are_refused(invoke: Invoke, turn_bhmm: Path) -> None:
    assert_user_error(invoke(["-v", "-q", "inspect", turn_bhmm]), "--verbose", "--quiet")


def test_training_prints_only_its_result_when_not_a_tty(
    invoke: Invoke, tmp_path: Path, turn_parquet: Path
) -> None:
    out = tmp_path / "t.bhmm"
    result = invoke(["train", "simple", turn_parquet, "--inputs", "angle", "-o", out])
    assert result.exit_code == 0, result.output
    assert result.stdout.splitlines() == [result.stdout.strip()]  # one line: no spinner
    assert result.stdout.startswith(f"wrote {out}: turn on angle")
    assert result.stderr == ""


def test_the_spinner_shows_on_a_terminal_only(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from behavior_hmm.cli._common import spinner

    with spinner("learning"):
        time.sleep(0.05)
    assert capsys.readouterr().out == ""  # a pipe: nothing at all
    monkeypatch.setenv("FORCE_COLOR", "1")  # rich: treat the pipe as a terminal
    with spinner("learning"):
        time.sleep(0.3)
    assert "learning" in capsys.readouterr().out
