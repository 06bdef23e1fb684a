"""The ``behavior-hmm`` command line."""

from __future__ import annotations

import typer

app = typer.Typer(add_completion=False, no_args_is_help=True, help=__doc__)


@app.command()
def version() -> None:
    """Print the package version."""
    from behavior_hmm import __version__

    typer.echo(__version__)


def main() -> None:
    app()
