"""The ``behavior-hmm`` command line.

Usage::

    behavior-hmm demo --sim kinematic                  # the whole pipeline, start here
    behavior-hmm collect turn -o data/turn.parquet
    behavior-hmm inspect data/turn.parquet --plot turn.png
    behavior-hmm train simple data/turn.parquet --inputs angle -o models/turn.bhmm
    behavior-hmm generate models/turn.bhmm --start angle=120 --goal angle=0 --plot run.png
    behavior-hmm evaluate models/turn.bhmm --json turn.json
    behavior-hmm experiment simple --sim kinematic
    behavior-hmm bench sim --json sim.json
    behavior-hmm COMMAND -h                            # each command's options and an example

One module per group of commands, each a ``typer.Typer`` whose commands are module-level
functions (importable and testable alone):

=====================  ===================================================================
``cli.data``           collect, inspect, import-csv, import-bag, import-lerobot,
                       export-lerobot
``cli.learn``          train simple, train complex, generate, evaluate
``cli.experiment``     experiment simple|complex|ablation|faults|categorization|
                       generators|robot
``cli.bench``          bench
``cli.demo``           demo
``cli._common``        the error wrapper, logging, progress bars, shared options and checks
``cli._app``           the root app (``behavior_hmm.cli.app``) gathering the groups
=====================  ===================================================================

User errors print one line and exit with code 2; nothing half-written is left behind.

This module is the console script's entry point (:func:`main`) and stays light: it
imports nothing heavy itself, so that Ctrl-C (exit 130, ``interrupted``) and SIGTERM
(exit 143, silent) are one line or none from the first instant :func:`main` runs, also
while the command modules import (about a second). An interrupt that lands once the
command's outputs are complete exits 0.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from behavior_hmm.cli._app import app

__all__ = ["Terminated", "app", "interrupt_exit_code", "main"]


def __getattr__(name: str) -> Any:
    """``behavior_hmm.cli.app``, imported on first use (the command modules are heavy)."""
    if name == "app":
        from behavior_hmm.cli._app import app

        return app
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so that every temporary file is removed on the way out;
    it exits 143 without a message."""


def _terminated(signum: int, frame: Any) -> None:
    raise Terminated


#: True once "interrupted" was printed in this process (main prints it at most once).
_reported = False


def interrupt_exit_code(err: BaseException) -> int:
    """The exit code for an interrupt (``err``: KeyboardInterrupt or :class:`Terminated`).

    0, silently, when the command's outputs are already complete (the interrupt changed
    nothing); 143, silently, for SIGTERM; otherwise 130 after one line ``interrupted``
    on stderr.
    """
    global _reported
    from behavior_hmm._atomic import outputs_complete

    if outputs_complete():
        return 0
    if isinstance(err, Terminated):
        return 143
    _reported = True
    try:
        print("interrupted", file=sys.stderr, flush=True)
    except (OSError, ValueError):  # stderr closed: the exit code says it
        pass
    return 130


def main() -> None:
    """Entry point of the ``behavior-hmm`` console script.

    SIGTERM is handled like Ctrl-C from the start, the command modules are imported
    inside the interrupt handling, and once the exit status is decided a further
    SIGINT or SIGTERM ends the process at once with that status (no traceback from the
    interpreter's shutdown). Meant to run once per process: it leaves those handlers.
    """
    import signal

    try:
        signal.signal(signal.SIGTERM, _terminated)
    except ValueError:  # not the main thread: no signal handling to install
        pass
    code = 1  # an unexpected error (its traceback follows)
    try:
        try:
            code = _run()
        except KeyboardInterrupt as err:  # landed between _run's own handlers
            code = interrupt_exit_code(err)
    finally:
        _exit_on_signals(code)
        from behavior_hmm._atomic import remove_leftovers

        remove_leftovers()
    sys.exit(code)


def _run() -> int:
    """Import the app and run it; the exit status."""
    from behavior_hmm._atomic import outputs_complete

    try:
        from behavior_hmm.cli._app import app

        app()
    except SystemExit as exc:
        code = _status(exc.code)
    except KeyboardInterrupt as err:
        return interrupt_exit_code(err)
    else:
        return 0
    if code in (130, 143) and outputs_complete():  # interrupted after the command returned
        return 0
    if code == 130 and not _reported:  # typer's own Ctrl-C handling exits 130 silently
        return interrupt_exit_code(KeyboardInterrupt())
    return code


def _status(code: object) -> int:
    """``sys.exit``'s argument as an exit status (a message is printed, status 1)."""
    if code is None:
        return 0
    if isinstance(code, int):
        return code
    print(code, file=sys.stderr)
    return 1


def _exit_on_signals(code: int) -> None:
    """From now on SIGINT and SIGTERM end the process with ``code`` (after removing any
    temporary file and flushing the output)."""
    import os
    import signal

    tidying: list[bool] = []

    def exit_now(signum: int, frame: Any) -> None:
        from behavior_hmm._atomic import remove_leftovers

        if not tidying:  # not again when the signal landed inside this very pass
            tidying.append(True)
            remove_leftovers()
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError, AttributeError):
                pass
        os._exit(code)

    for signum in (signal.SIGINT, signal.SIGTERM):
        try:
            signal.signal(signum, exit_now)
        except ValueError:  # not the main thread
            return
