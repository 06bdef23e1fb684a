"""``behavior-hmm bench NAME``: the speed benchmarks of ``behavior_hmm.benchmarks``.

Usage::

    behavior-hmm bench sim --json sim.json     # simulator real-time factors
    behavior-hmm bench step --quick            # one control step, a smoke run
    behavior-hmm bench hmm                     # our Viterbi against hmmlearn's (bench extra)
    behavior-hmm bench memory                  # memory and load; 100,000 categories

The same runs without the command line: ``python -m behavior_hmm.benchmarks NAME``.
"""

from __future__ import annotations

import json
from typing import Annotated

import typer

from behavior_hmm.benchmarks import available
from behavior_hmm.cli._common import CONTEXT_SETTINGS, JsonOut, user_errors, write_json

app = typer.Typer(context_settings=CONTEXT_SETTINGS)


@app.command()
@user_errors
def bench(
    name: Annotated[
        str,
        typer.Argument(
            help=f"Benchmark: {', '.join(available())} (hmm needs the bench extra: hmmlearn)"
        ),
    ],
    json_out: JsonOut = None,
    quick: Annotated[bool, typer.Option("--quick", help="Fewer repeats (a smoke run)")] = False,
) -> None:
    """Run a benchmark of behavior_hmm.benchmarks and print its results (medians) as JSON.

    Times are medians over repeats (s, ms or us, as each key says); real-time factors
    are simulated seconds per wall-clock second.

    Example: behavior-hmm bench sim --quick --json sim.json
    """
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.benchmarks import run_benchmark

    check_outputs({}, {"--json": json_out})
    results = run_benchmark(name, quick=quick)
    text = json.dumps(results, indent=2, sort_keys=True)
    typer.echo(text)
    if json_out is not None:
        write_json(json_out, text + "\n")
