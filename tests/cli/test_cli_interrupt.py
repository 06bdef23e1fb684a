"""No leftovers (issue 11, item 7): a kill during a write, a failed write, a failure among
several outputs leave no temporary file and every old file intact."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from cli_testing import files_in, write_starts

from behavior_hmm._atomic import all_or_none, atomic_path, atomic_write_bytes, atomic_write_with


def _hidden(folder: Path) -> list[str]:
    return sorted(name for name in files_in(folder) if name.startswith("."))


@pytest.mark.skipif(not hasattr(signal, "SIGTERM") or os.name != "posix", reason="POSIX signals")
def test_sigterm_during_a_write_leaves_no_temporary_file(
    tmp_path: Path, turn_parquet: Path, turn_bhmm: Path
) -> None:
    """SIGTERM while the report renders (the JSON already staged beside its target)."""
    model = Path(shutil.copy(turn_bhmm, tmp_path / "turn.bhmm"))
    shutil.copy(turn_parquet, tmp_path / "turn.parquet")
    starts = write_starts(tmp_path / "starts.csv", "angle", "120", "-45", "170", "60", "-100")
    old = tmp_path / "eval.json"
    old.write_text("old results")
    args = ["evaluate", model, "--starts", starts, "--sim", "kinematic"]
    args += ["--json", old, "--report", tmp_path / "eval.html"]
    command = [sys.executable, "-c", "from behavior_hmm.cli import main; main()", *args]
    proc = subprocess.Popen(
        [str(a) for a in command], stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path
    )
    deadline = time.monotonic() + 60
    sent = False
    while proc.poll() is None and time.monotonic() < deadline:
        if any(name.endswith(".tmp") for name in _hidden(tmp_path)):
            proc.send_signal(signal.SIGTERM)
            sent = True
            break
        time.sleep(0.002)
    _, stderr = proc.communicate(timeout=60)
    assert sent, "the command ended before a temporary file was seen"
    assert proc.returncode in (130, 143, -signal.SIGTERM), stderr.decode()
    assert b"Traceback" not in stderr
    assert _hidden(tmp_path) == []
    assert old.read_text() == "old results"
    assert not (tmp_path / "eval.html").exists()


# ----------------------------------------------------------------- _atomic, directly


def test_an_error_names_the_target_never_the_temporary_file(tmp_path: Path) -> None:
    target = tmp_path / "out.png"

    def writer(tmp: Path) -> None:
        raise OSError(28, "No space left on device", str(tmp))

    with pytest.raises(OSError) as caught:
        atomic_write_with(target, writer)
    assert caught.value.filename == str(target)
    assert ".tmp" not in str(caught.value)
    assert files_in(tmp_path) == set()

    def library(tmp: Path) -> None:  # e.g. pyarrow: the path only in the message
        raise OSError(f"Failed to open local file '{tmp}'. Detail: [errno 13] denied")

    with pytest.raises(OSError) as caught:
        atomic_write_with(target, library)
    assert str(target) in str(caught.value) and ".tmp" not in str(caught.value)


def test_an_uncreatable_temporary_file_names_the_target(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(OSError) as caught:
        atomic_write_bytes(blocker / "out.json", b"{}")
    assert ".tmp" not in str(caught.value)


def test_interrupt_inside_a_write_removes_the_temporary_file(tmp_path: Path) -> None:
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    with pytest.raises(KeyboardInterrupt), atomic_path(target) as tmp:
        tmp.write_bytes(b"half")
        raise KeyboardInterrupt
    assert target.read_bytes() == b"old"
    assert files_in(tmp_path) == {"out.bin"}


def test_all_or_none_writes_every_output_at_the_end(tmp_path: Path) -> None:
    a, b = tmp_path / "a.json", tmp_path / "b.html"
    a.write_bytes(b"old a")
    with all_or_none():
        atomic_write_bytes(a, b"new a")
        atomic_write_bytes(b, b"new b")
        assert a.read_bytes() == b"old a" and not b.exists()  # staged, not yet moved
        atomic_write_bytes(b, b"newer b")  # a second write of one target replaces the first
    assert a.read_bytes() == b"new a" and b.read_bytes() == b"newer b"
    assert files_in(tmp_path) == {"a.json", "b.html"}


@pytest.mark.parametrize("error", [RuntimeError, KeyboardInterrupt])
def test_all_or_none_writes_nothing_when_the_block_fails(
    tmp_path: Path, error: type[BaseException]
) -> None:
    a, b = tmp_path / "a.json", tmp_path / "b.html"
    a.write_bytes(b"old a")
    with pytest.raises(error), all_or_none():
        atomic_write_bytes(a, b"new a")
        atomic_write_bytes(b, b"new b")
        raise error
    assert a.read_bytes() == b"old a" and not b.exists()
    assert files_in(tmp_path) == {"a.json"}


def test_all_or_none_undoes_the_moves_when_one_fails(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    a, b, c = tmp_path / "a.json", tmp_path / "b.html", tmp_path / "c.png"
    a.write_bytes(b"old a")
    real_replace = os.replace

    def replace(src: str | os.PathLike[str], dst: str | os.PathLike[str]) -> None:
        if Path(dst) == c:
            raise OSError(5, "Input/output error", str(src))
        real_replace(src, dst)

    monkeypatch.setattr("behavior_hmm._atomic.os.replace", replace)
    with pytest.raises(OSError) as caught, all_or_none():
        atomic_write_bytes(a, b"new a")
        atomic_write_bytes(b, b"new b")
        atomic_write_bytes(c, b"new c")
    assert caught.value.filename == str(c)
    assert a.read_bytes() == b"old a"  # put back from its backup
    assert not b.exists() and not c.exists()  # new files taken away again
    assert files_in(tmp_path) == {"a.json"}


def test_nested_all_or_none_joins_the_outer_block(tmp_path: Path) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    with pytest.raises(RuntimeError), all_or_none():
        with all_or_none():
            atomic_write_bytes(a, b"a")
        atomic_write_bytes(b, b"b")
        raise RuntimeError("late")
    assert files_in(tmp_path) == set()


def test_all_or_none_puts_back_a_symlink_it_replaced(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    real = tmp_path / "real.json"
    real.write_bytes(b"old")
    link, other = tmp_path / "link.json", tmp_path / "other.png"
    link.symlink_to(real.name)
    real_replace = os.replace

    def replace(src: str | os.PathLike[str], dst: str | os.PathLike[str]) -> None:
        if Path(dst) == other:
            raise OSError(5, "Input/output error", str(src))
        real_replace(src, dst)

    monkeypatch.setattr("behavior_hmm._atomic.os.replace", replace)
    with pytest.raises(OSError), all_or_none():
        atomic_write_bytes(link, b"new")
        atomic_write_bytes(other, b"new")
    assert link.is_symlink() and os.readlink(link) == real.name
    assert real.read_bytes() == b"old"
    assert files_in(tmp_path) == {"real.json", "link.json"}
