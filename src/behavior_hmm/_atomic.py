"""Crash-safe file writes: temp file in the same folder, fsync, ``os.replace``.

Inside :func:`all_or_none` the writes of a command are staged instead: each lands in its
temporary file, and only when the block ends without an error are they all moved into
place; on any error (or an interrupt) every temporary file is removed and the old files
stay as they were.

The command line also learns from here when a command's result is complete: the output
files it declared (:func:`expect_outputs`, called by ``_paths.check_outputs``) are all in
place, or the command has returned (:func:`finish_command`). From then on an interrupt
changes nothing on disk, and :func:`outputs_complete` tells the interrupt handler to exit 0.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import secrets
import tempfile
from collections.abc import Callable, Collection, Iterator
from pathlib import Path
from typing import Any

#: Writes staged by the innermost :func:`all_or_none` block: (temporary file, target).
_STAGED: contextvars.ContextVar[list[tuple[Path, Path]] | None] = contextvars.ContextVar(
    "behavior_hmm_staged_writes", default=None
)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    On any exception the temporary file is removed and ``path`` is untouched; an
    ``OSError`` names ``path``, never the temporary file. Inside :func:`all_or_none`
    the rename waits for the end of that block.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    _TARGETS.add((target.parent, target.name))
    with _signals_deferred():  # an interrupt cannot fall between creating and registering
        try:
            fd, tmp_name = tempfile.mkstemp(
                prefix=f".{target.name}.{os.getpid()}.", suffix=".tmp", dir=target.parent
            )
        except OSError as err:
            raise _renamed(err, None, target) from None
        tmp = Path(tmp_name)
        _LIVE.add(tmp)

    keep = False
    try:
        os.close(fd)
        yield tmp
        with open(tmp, "rb+") as fh:
            fh.flush()
            os.fsync(fh.fileno())
        # mkstemp creates 0600 files; give the result the mode a plain open() would.
        os.chmod(tmp, _target_mode(target))
        staged = _STAGED.get()
        if staged is None:
            with _signals_deferred():  # in place and counted as such, or neither
                os.replace(tmp, target)
                _LIVE.discard(tmp)
                _placed([target])
        else:
            _stage(staged, tmp, target)
            keep = True
    except OSError as err:
        raise _renamed(err, tmp, target) from None
    finally:
        if not keep:
            _remove(tmp)


@contextlib.contextmanager
def all_or_none() -> Iterator[None]:
    """Write every output of the block, or none of them.

    Atomic writes inside the block go to temporary files; at its end they replace their
    targets together. If the block raises (an error, Ctrl-C, SIGTERM) the temporary files
    are removed and no target changes; if moving one into place fails, those already
    moved are put back. Nested blocks join the outermost one.
    """
    if _STAGED.get() is not None:
        yield
        return
    staged: list[tuple[Path, Path]] = []
    token = _STAGED.set(staged)
    try:
        try:
            yield
        finally:
            _STAGED.reset(token)
        with _signals_deferred():  # every target moved and counted, or none moved
            targets = [target for _, target in staged]
            _commit(staged)
            _placed(targets)
    finally:
        for tmp, _ in staged:  # whatever was not moved into place
            _remove(tmp)


def _stage(staged: list[tuple[Path, Path]], tmp: Path, target: Path) -> None:
    """Add ``tmp -> target``; a second write of the same target replaces the first."""
    where = Path(os.path.abspath(target))
    for k, (old_tmp, old_target) in enumerate(staged):
        if Path(os.path.abspath(old_target)) == where:
            _remove(old_tmp)
            del staged[k]
            break
    staged.append((tmp, target))


def _commit(staged: list[tuple[Path, Path]]) -> None:
    """Move every staged file onto its target; on a failure undo the moves made."""
    done: list[tuple[Path, Path | None, bool]] = []  # (target, backup, it existed)
    try:
        while staged:
            tmp, target = staged[0]
            existed = target.exists() or target.is_symlink()
            backup = _backup(target) if existed else None
            try:
                os.replace(tmp, target)
            except OSError as err:
                if backup is not None:
                    _remove(backup)
                raise _renamed(err, tmp, target) from None
            _LIVE.discard(tmp)
            staged.pop(0)
            done.append((target, backup, existed))
    except BaseException:
        for target, backup, existed in reversed(done):
            try:
                if backup is not None:
                    os.replace(backup, target)
                elif not existed:
                    target.unlink()
                # else: an old file we could not back up; the new one stays
            except OSError:
                pass
        raise
    for _, backup, _ in done:
        if backup is not None:
            _remove(backup)


def _backup(target: Path) -> Path | None:
    """A second name for ``target``'s current file (a hard link, or a copy of a symlink)
    to put it back with; None where the file system allows neither."""
    backup = target.with_name(f".{target.name}.{secrets.token_hex(4)}.bak")
    try:
        if target.is_symlink():
            os.symlink(os.readlink(target), backup)
        else:
            os.link(target, backup)
    except OSError:
        return None
    return backup


def _remove(path: Path) -> None:
    try:
        path.unlink()
    except OSError:  # already gone, or nothing more we can do
        pass
    _LIVE.discard(path)


# --------------------------------------------------------- a command's outputs


class _Outputs:
    """What the running command declared it writes, and what is in place so far."""

    def __init__(self) -> None:
        self.missing: set[str] = set()  # declared output files not yet moved into place
        self.files = False  # it declared at least one output file
        self.folders = False  # it declared an output folder (files unknown in advance)
        self.complete = False


_OUTPUTS = _Outputs()


def begin_command() -> None:
    """Forget the outputs of an earlier command (the command line calls it per command)."""
    global _OUTPUTS
    _OUTPUTS = _Outputs()


def expect_outputs(files: Collection[str | os.PathLike[str]], *, folders: bool = False) -> None:
    """Declare the output files of the running command (``folders``: it also writes a
    folder of results, whose files are not known in advance). Declarations add up."""
    state = _OUTPUTS
    state.missing.update(os.path.abspath(f) for f in files)
    state.files = state.files or bool(files)
    state.folders = state.folders or folders


def finish_command() -> None:
    """The command has returned: whatever it wrote is complete."""
    _OUTPUTS.complete = True


def outputs_complete() -> bool:
    """True once the running command's result is complete: every declared output file is
    in place (and no output folder was declared), or the command has returned."""
    return _OUTPUTS.complete


def _placed(targets: Collection[Path]) -> None:
    state = _OUTPUTS
    state.missing.difference_update(os.path.abspath(t) for t in targets)
    if state.files and not state.folders and not state.missing:
        state.complete = True


#: Temporary files created and not yet moved into place or removed (see remove_leftovers).
_LIVE: set[Path] = set()
#: (folder, name) of every target this process began to write.
_TARGETS: set[tuple[Path, str]] = set()


def remove_leftovers() -> None:
    """Remove every temporary file this process created and has not moved into place.

    The command line calls it on its way out: an interrupt (Ctrl-C, SIGTERM) can land
    inside a cleanup handler itself, and this last pass catches what that left behind.
    """
    for tmp in list(_LIVE):
        _remove(tmp)
    # and by name: this process's temporary files beside every target it wrote
    for folder, name in list(_TARGETS):
        for tmp in folder.glob(f".{name}.{os.getpid()}.*.tmp"):
            _remove(tmp)


@contextlib.contextmanager
def _signals_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM until the block ends (main thread; else a no-op).

    The Python-level handlers are swapped for one that only records the signal, and
    the held signal is handled (``KeyboardInterrupt`` raised, ...) when the block ends.
    Blocking the signal in this thread alone would not do: the kernel hands a
    process-wide signal to any thread that does not block it (a progress bar's, a BLAS
    worker), and Python then runs the handler in this thread, inside the block.
    """
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []

    def hold(signum: int, frame: object) -> None:
        held.append(signum)

    saved: dict[int, Any] = {}
    for held_signal in (signal.SIGINT, signal.SIGTERM):
        handler = signal.getsignal(held_signal)
        if handler is not None:  # None: set outside Python, left alone
            saved[int(held_signal)] = handler
            signal.signal(held_signal, hold)
    try:
        yield
    finally:
        for signum, handler in saved.items():
            signal.signal(signum, handler)
        for signum in dict.fromkeys(held):
            handler = saved[signum]
            if callable(handler):
                handler(signum, None)  # e.g. KeyboardInterrupt, raised here
            elif handler == signal.SIG_DFL:
                signal.raise_signal(signum)


def _renamed(err: OSError, tmp: Path | None, target: Path) -> OSError:
    """``err`` with the temporary file's name replaced by the target's."""
    names = [str(err.filename or ""), str(err.filename2 or ""), str(err)]
    mentions_tmp = tmp is not None and any(str(tmp) in name for name in names)
    hidden = err.filename is not None and Path(str(err.filename)).name.startswith(
        f".{target.name}."
    )
    if not (mentions_tmp or hidden):
        return err
    if err.strerror is not None:  # OSError(errno, ...) picks the matching subclass
        return OSError(err.errno, err.strerror, str(target))
    text = str(err).replace(str(tmp), str(target)) if tmp is not None else str(err)
    return OSError(text)


def _target_mode(target: Path) -> int:
    """Mode of an existing target, else 0o666 less the process umask."""
    try:
        return target.stat().st_mode & 0o7777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def atomic_write_with(path: str | os.PathLike[str], writer: Callable[[Path], None]) -> None:
    """Call ``writer(tmp_path)`` and move the result onto ``path`` atomically."""
    with atomic_path(path) as tmp:
        writer(tmp)
