"""The ``behavior-hmm`` Typer app: the command groups under one root (imported by
``behavior_hmm.cli`` only when a command runs, or when ``behavior_hmm.cli.app`` is asked
for: importing the command modules takes about a second)."""

from __future__ import annotations

from typing import Annotated

import typer

from behavior_hmm.cli import bench, data, demo, experiment, learn
from behavior_hmm.cli._common import CONTEXT_SETTINGS, CommandLine, set_verbosity, user_errors

__all__ = ["app"]

app = typer.Typer(
    cls=CommandLine,
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
