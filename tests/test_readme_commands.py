"""The README's Command line block runs top to bottom on a fresh clone (issue 12).

The slow test copies ``examples/`` into a temporary folder and runs every command of the
first ``bash`` block under the README's "Command line" heading there, in order, through the
installed ``behavior-hmm`` console script, and asserts that each exits with code 0 and writes
the files it names. One substitution, stated under the block in the README: each ``collect``,
``generate`` and ``evaluate`` command that names neither ``--sim`` nor ``--env`` gets
``--sim kinematic`` (the README's lines use the default MuJoCo simulator). The second block
(the experiments, minutes each, and ROS bags the repository does not ship) is not run.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# commands that take --sim, and what the test gives them instead of the default MuJoCo
SIMULATED = ("collect", "generate", "evaluate")
SUBSTITUTE = ["--sim", "kinematic"]
# options whose value is a file or folder the command must have written
WRITES = ("-o", "--out", "--plot", "--video", "--json", "--report")
# a test case must not hang CI: no command of the block takes a minute on two cores
COMMAND_TIMEOUT_S = 300


def command_line_block(text: str) -> str:
    """The first ``bash`` fence under the README's "## Command line" heading."""
    heading = re.search(r"(?m)^##\s+Command line\s*$", text)
    assert heading, "README.md has no '## Command line' heading"
    section = text[heading.end() :]
    following = re.search(r"(?m)^##\s", section)
    section = section[: following.start()] if following else section
    fence = re.search(r"(?ms)^```bash[ \t]*\n(.*?)^```", section)
    assert fence, "the README's Command line section has no ```bash block"
    return fence.group(1)


def commands(block: str) -> list[list[str]]:
    """Argument lists, one per command: continuation lines joined, comments dropped."""
    joined = re.sub(r"\\\n", " ", block)
    return [argv for line in joined.splitlines() if (argv := shlex.split(line, comments=True))]


def as_tested(argv: list[str]) -> list[str]:
    """``argv`` with the documented substitution: the kinematic simulator where none is named."""
    if len(argv) > 1 and argv[1] in SIMULATED:
        named = {arg.split("=", 1)[0] for arg in argv}
        if not named & {"--sim", "--env"}:
            return [*argv, *SUBSTITUTE]
    return argv


def written(argv: list[str]) -> list[str]:
    """The paths ``argv`` names after an output option (``-o data/x.parquet``, ``--json=x``)."""
    paths = []
    for i, arg in enumerate(argv):
        name, eq, value = arg.partition("=")
        if name in WRITES:
            if eq:
                paths.append(value)
            elif i + 1 < len(argv):
                paths.append(argv[i + 1])
    return paths


def console_script() -> str:
    """The installed ``behavior-hmm`` entry point, this interpreter's own first."""
    beside = Path(sys.executable).with_name("behavior-hmm")
    found = str(beside) if beside.is_file() else shutil.which("behavior-hmm")
    assert found, "the behavior-hmm console script is not installed (pip install -e .)"
    return found


def run_commands(argvs: list[list[str]], folder: Path) -> list[tuple[str, float]]:
    """Run each command in ``folder``, in order; fail at the first that breaks.

    Returns each command line and its wall time in seconds.
    """
    script = console_script()
    env = {**os.environ, "MPLBACKEND": "Agg", "NO_COLOR": "1"}
    timings = []
    for argv in argvs:
        assert argv[0] == "behavior-hmm", f"not a behavior-hmm command: {shlex.join(argv)}"
        line = shlex.join(argv)
        began = time.perf_counter()
        done = subprocess.run(
            [script, *argv[1:]],
            cwd=folder,
            env=env,
            capture_output=True,
            text=True,
            timeout=COMMAND_TIMEOUT_S,
            check=False,
        )
        timings.append((line, time.perf_counter() - began))
        output = (done.stdout + done.stderr)[-3000:]
        assert done.returncode == 0, f"`{line}` exited with {done.returncode}:\n{output}"
        missing = [p for p in written(argv) if not (folder / p).exists()]
        assert not missing, f"`{line}` exited 0 but did not write {missing}:\n{output}"
    return timings


def readme_commands() -> list[list[str]]:
    return commands(command_line_block((ROOT / "README.md").read_text(encoding="utf-8")))


def test_block_is_a_tour_of_the_main_commands() -> None:
    argvs = readme_commands()
    assert all(argv[0] == "behavior-hmm" for argv in argvs)
    tour = {" ".join(argv[1:3]) if argv[1] == "train" else argv[1] for argv in argvs}
    for command in ("collect", "inspect", "import-csv", "train simple", "train complex"):
        assert command in tour
    assert {"generate", "evaluate"} <= tour
    # minutes-long runs live in the README's second block, which CI does not run
    assert "experiment" not in tour


def test_block_reads_only_shipped_examples() -> None:
    named = [arg for argv in readme_commands() for arg in argv if arg.startswith("examples/")]
    assert named, "the block reads nothing from examples/"
    for path in named:
        assert (ROOT / path).is_file(), f"README names {path}, which examples/ does not ship"


def test_substitution_rule() -> None:
    assert as_tested(["behavior-hmm", "collect", "turn", "-o", "a.parquet"])[-2:] == SUBSTITUTE
    assert as_tested(["behavior-hmm", "evaluate", "m.bhmm", "--sim", "mujoco"])[-1] == "mujoco"
    assert as_tested(["behavior-hmm", "generate", "m.bhmm", "--env=x.py:make"])[-1] != "kinematic"
    assert as_tested(["behavior-hmm", "train", "simple", "d.parquet"])[-1] == "d.parquet"


def test_continuation_lines_and_comments() -> None:
    block = "behavior-hmm a b \\\n        --c d  # note\n\n# only a comment\nbehavior-hmm e\n"
    assert commands(block) == [["behavior-hmm", "a", "b", "--c", "d"], ["behavior-hmm", "e"]]
    assert written(["behavior-hmm", "x", "-o", "m.bhmm", "--json=r.json"]) == ["m.bhmm", "r.json"]


def test_a_breaking_line_fails_the_run(tmp_path: Path) -> None:
    broken = [["behavior-hmm", "inspect", "data/never-written.parquet"]]
    with pytest.raises(AssertionError, match="never-written"):
        run_commands(broken, tmp_path)


@pytest.mark.slow
def test_command_line_block_runs_top_to_bottom(tmp_path: Path) -> None:
    shutil.copytree(
        ROOT / "examples", tmp_path / "examples", ignore=shutil.ignore_patterns("__pycache__")
    )
    timings = run_commands([as_tested(argv) for argv in readme_commands()], tmp_path)
    for line, seconds in timings:
        print(f"{seconds:6.1f} s  {line}")
