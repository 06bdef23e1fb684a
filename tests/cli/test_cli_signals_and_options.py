"""Interrupts in one line (issue 31, item 3) and usage errors in one line.

Ctrl-C or SIGTERM while the command modules import is one line (or none) with exit
130/143, never a traceback; a signal once the outputs are complete exits 0. A wrong
option is one ``error: ...`` line and exit 2, no usage box.

The signals are real ones a process sends itself at a chosen moment: the command runs
under a small script that patches the moment's function (an import, ``typer.echo``,
``os.replace``) to call ``os.kill(os.getpid(), SIG)`` first.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from cli_testing import Invoke, assert_user_error, files_in, write_starts

from behavior_hmm import _atomic, data

pytestmark = pytest.mark.skipif(os.name != "posix", reason="POSIX signals")

SIGNALS = [pytest.param(signal.SIGINT, 130, "interrupted\n", id="SIGINT")]
SIGNALS += [pytest.param(signal.SIGTERM, 143, "", id="SIGTERM")]

#: Run like the console script (``behavior_hmm.cli:main``) after the test's patch.
RUN = "from behavior_hmm.cli import main\nsys.argv[0] = 'behavior-hmm'\nsys.exit(main())\n"


def _run(patch: str, *args: object, cwd: Path, signum: int) -> subprocess.CompletedProcess[str]:
    script = "import os, signal, sys\n" + f"SIG = {int(signum)}\n"
    script += textwrap.dedent(patch) + RUN
    return subprocess.run(
        [sys.executable, "-c", script, *[str(a) for a in args]],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        env={**os.environ, "COLUMNS": "100"},
    )


def _collect_args(tmp_path: Path) -> list[object]:
    starts = write_starts(tmp_path / "starts.csv", "angle", "120")
    return ["collect", "turn", "--starts", starts, "--sim", "kinematic", "-o", "out.parquet"]


# --------------------------------------------------------------- while importing

#: The signal arrives while the command modules import (the first second of a run).
DURING_IMPORT = """
class Hook:
    def find_spec(self, name, path=None, target=None):
        if name == "behavior_hmm.cli.data":
            sys.meta_path.remove(self)
            os.kill(os.getpid(), SIG)
        return None

sys.meta_path.insert(0, Hook())
"""


@pytest.mark.parametrize(("signum", "code", "stderr"), SIGNALS)
def test_a_signal_while_the_modules_import_is_one_line(
    tmp_path: Path, signum: int, code: int, stderr: str
) -> None:
    done = _run(DURING_IMPORT, *_collect_args(tmp_path), cwd=tmp_path, signum=signum)
    assert done.returncode == code, done.stderr
    assert done.stderr == stderr
    assert done.stdout == ""
    assert not (tmp_path / "out.parquet").exists()


# ------------------------------------------------------- once the outputs are complete

#: The signal arrives right after the command prints "wrote ...".
AFTER_WROTE = """
import typer

real_echo = typer.echo

def echo(message=None, *args, **kwargs):
    real_echo(message, *args, **kwargs)
    if str(message).startswith("wrote "):
        os.kill(os.getpid(), SIG)

typer.echo = echo
"""

#: The signal arrives right after the output is moved into place, before "wrote ...".
AFTER_REPLACE = """
import behavior_hmm._atomic as atomic

real_replace = os.replace

def replace(src, dst):
    real_replace(src, dst)
    if str(dst).endswith("out.parquet"):
        os.kill(os.getpid(), SIG)

atomic.os = type(sys)("os_patched")
atomic.os.__dict__.update(os.__dict__)
atomic.os.replace = replace
"""

#: The signal arrives after the command returned, while the process tidies up.
AFTER_RETURN = """
import behavior_hmm._atomic as atomic

real_remove = atomic.remove_leftovers

def remove_leftovers():
    os.kill(os.getpid(), SIG)
    real_remove()

atomic.remove_leftovers = remove_leftovers
"""


@pytest.mark.parametrize("moment", ["after_replace", "after_wrote", "after_return"])
@pytest.mark.parametrize(("signum", "code", "stderr"), SIGNALS)
def test_a_signal_once_the_output_is_complete_exits_0(
    tmp_path: Path, signum: int, code: int, stderr: str, moment: str
) -> None:
    patch = {"after_replace": AFTER_REPLACE, "after_wrote": AFTER_WROTE}.get(moment, AFTER_RETURN)
    done = _run(patch, *_collect_args(tmp_path), cwd=tmp_path, signum=signum)
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    assert len(data.read(tmp_path / "out.parquet")) == 1
    assert files_in(tmp_path) == {"starts.csv", "out.parquet"}  # no temporary file
    if moment != "after_replace":
        assert "wrote out.parquet: 1 episodes" in done.stdout


#: The signal arrives just before the output is written: the result is not complete.
BEFORE_WRITE = """
import behavior_hmm.data as bdata

real_write = bdata.write

def write(*args, **kwargs):
    os.kill(os.getpid(), SIG)
    return real_write(*args, **kwargs)

bdata.write = write
"""


@pytest.mark.parametrize(("signum", "code", "stderr"), SIGNALS)
def test_a_signal_before_the_output_is_complete_still_interrupts(
    tmp_path: Path, signum: int, code: int, stderr: str
) -> None:
    done = _run(BEFORE_WRITE, *_collect_args(tmp_path), cwd=tmp_path, signum=signum)
    assert done.returncode == code, done.stderr
    assert done.stderr == stderr
    assert files_in(tmp_path) == {"starts.csv"}


def test_outputs_complete_once_every_declared_file_is_in_place(tmp_path: Path) -> None:
    a, b = tmp_path / "a.json", tmp_path / "b.png"
    _atomic.begin_command()
    _atomic.expect_outputs([a, b])
    _atomic.atomic_write_bytes(a, b"a")
    assert not _atomic.outputs_complete()
    _atomic.atomic_write_bytes(b, b"b")
    assert _atomic.outputs_complete()
    _atomic.begin_command()  # the next command starts from nothing
    assert not _atomic.outputs_complete()
    _atomic.expect_outputs([a], folders=True)  # an output folder: complete only on return
    _atomic.atomic_write_bytes(a, b"a")
    assert not _atomic.outputs_complete()
    _atomic.finish_command()
    assert _atomic.outputs_complete()
    _atomic.begin_command()


def test_staged_outputs_count_only_when_the_block_commits(tmp_path: Path) -> None:
    a, b = tmp_path / "a.json", tmp_path / "b.png"
    _atomic.begin_command()
    _atomic.expect_outputs([a, b])
    with pytest.raises(KeyboardInterrupt), _atomic.all_or_none():
        _atomic.atomic_write_bytes(a, b"a")
        _atomic.atomic_write_bytes(b, b"b")
        raise KeyboardInterrupt
    assert not _atomic.outputs_complete()
    with _atomic.all_or_none():
        _atomic.atomic_write_bytes(a, b"a")
        _atomic.atomic_write_bytes(b, b"b")
        assert not _atomic.outputs_complete()
    assert _atomic.outputs_complete()
    _atomic.begin_command()


# ------------------------------------------------------------------ usage errors

USAGE_ERRORS = [
    (
        ["collect", "turn", "--seed", "abc", "-o", "x.parquet"],
        "--seed: 'abc' is not a valid integer",
    ),
    (
        ["import-bag", "run.bag", "--split-gap", "abc", "-o", "x.parquet"],
        "--split-gap: 'abc' is not a valid number",
    ),
    (["evaluate", "m.bhmm", "--noise", "loud"], "--noise: 'loud' is not a valid number"),
    (["experiment", "simple", "--seed", "1.5"], "--seed: '1.5' is not a valid integer"),
    (["collect"], "missing argument BEHAVIOR"),
    (["collect", "turn"], "missing option -o/--out"),
    (["collect", "turn", "-o"], "option '-o' requires an argument"),
    (["collect", "turn", "--bogus", "-o", "x.parquet"], "no such option: --bogus"),
    (["--bogus"], "no such option: --bogus"),
    (["frob"], "no such command 'frob'"),
    (["colect"], "no such command 'colect'. Did you mean 'collect'?"),
    (["collect", "turn", "extra", "-o", "x.parquet"], "got unexpected extra argument(s) (extra)"),
]


@pytest.mark.parametrize(("args", "line"), USAGE_ERRORS, ids=[" ".join(a) for a, _ in USAGE_ERRORS])
def test_a_usage_error_is_one_line_with_exit_code_2(
    invoke: Invoke, args: list[str], line: str
) -> None:
    result = invoke(args)
    shown = assert_user_error(result)
    assert shown.startswith(f"error: {line}"), shown
    assert result.stdout == ""
    assert "Usage" not in result.stderr and "╭" not in result.stderr


def test_the_console_script_prints_the_same_one_line(tmp_path: Path) -> None:
    done = _run("", "collect", "turn", "--seed", "abc", "-o", "x.parquet", cwd=tmp_path, signum=0)
    assert done.returncode == 2
    assert done.stderr == "error: --seed: 'abc' is not a valid integer\n"
    assert done.stdout == ""
    assert files_in(tmp_path) == set()


def test_help_still_works(invoke: Invoke) -> None:
    result = invoke(["collect", "--help"])
    assert result.exit_code == 0, result.output
    assert "Usage: " in result.stdout and "--seed" in result.stdout
    bare = invoke([])  # no command: the help, as before
    assert "Usage: " in bare.stdout and bare.stderr == ""


@pytest.mark.skipif(os.name != "posix", reason="POSIX signals")
def test_ctrl_c_while_the_package_registers_its_envs_is_one_line() -> None:
    """Ctrl-C while ``behavior_hmm`` imports gymnasium, before the entry point runs."""
    code = (
        "import importlib.abc, os, signal, sys\n"
        "class Interrupt(importlib.abc.MetaPathFinder):\n"
        "    def find_spec(self, name, path, target=None):\n"
        "        if name == 'gymnasium':\n"
        "            os.kill(os.getpid(), signal.SIGINT)\n"
        "        return None\n"
        "sys.meta_path.insert(0, Interrupt())\n"
        "sys.argv[0] = 'behavior-hmm'\n"
        "from behavior_hmm.cli import main\n"
        "sys.exit(main())\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, "--version"], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 130, done.stderr
    assert done.stderr.strip() == "interrupted"
    assert "Traceback" not in done.stderr
