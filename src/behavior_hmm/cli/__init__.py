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
=====================  ===================================================================

User errors print one line and exit with code 2; nothing half-written is left behind.
"""

from __future__ import annotations

from typing import Annotated, Any

import typer

from behavior_hmm.cli import bench, data, demo, experiment, learn
from behavior_hmm.cli._common import CONTEXT_SETTINGS, set_verbosity, user_errors

__all__ = ["app", "main"]

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    context_settings=CONTEXT_SETTINGS,
    help="Learn robot behaviors from unlabeled demonstrations (CobART + Behavior-HMM).\n\n"
    "Example: behavior-hmm demo --sim kinematic -o demo-output",
    pretty_exceptions_enable=False,
)


def _print_version(value: bool) -> None:
    if value:
        from behavior_hmm import __version__

        typer.echo(f"behavior-hmm {__version__}")
        raise typer.Exit()


@app.callback()
@user_errors
def _options(
    verbose: Annotated[
        bool, typer.Option("--verbose", "-v", help="Also print debug messages (on stderr)")
    ] = False,
    quiet: Annotated[
        bool,
        typer.Option("--quiet", "-q", help="Only results, warnings and errors: no progress"),
    ] = False,
    version: Annotated[
        bool,
        typer.Option(
            "--version",
            callback=_print_version,
            is_eager=True,
            help="Print the version and exit",
        ),
    ] = False,
) -> None:
    set_verbosity(verbose, quiet)


# In the order of a first session: try, make data, learn, reproduce, measure.
app.add_typer(demo.app)
app.add_typer(data.app)
app.add_typer(learn.app)
app.add_typer(experiment.app, name="experiment")
app.add_typer(bench.app)


def _terminated(signum: int, frame: Any) -> None:
    """SIGTERM: stop like Ctrl-C, so every temporary file is removed on the way out."""
    raise KeyboardInterrupt


def main() -> None:
    """Entry point of the ``behavior-hmm`` console script."""
    import signal

    from behavior_hmm._atomic import remove_leftovers

    signal.signal(signal.SIGTERM, _terminated)
    try:
        app()
    finally:
        remove_leftovers()
