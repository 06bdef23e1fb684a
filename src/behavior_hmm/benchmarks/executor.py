"""Wall time of ``experiment simple`` on 1 worker against ``--workers N`` local processes.

Usage::

    behavior-hmm bench executor --json executor.json
    python -m behavior_hmm.benchmarks executor --quick

The experiment runs every thesis config (table 6.3 / 6.4: five SBLMs with their
baselines) on the MuJoCo robot, once in this process (``--workers 1``) and once on
``workers`` local processes (this machine's cores), alternating, so both see the same
machine. Reported: the median wall time of each and ``speedup`` (1 worker ÷ N workers),
and whether the results (results.json without timings) were byte-identical. ``--quick``
uses the kinematic robot and one repeat.
"""

from __future__ import annotations

import json
import statistics
import sys
import time
from typing import Any


def _canonical(result: dict[str, Any]) -> str:
    kept = {k: v for k, v in result.items() if k not in ("timings", "figures")}
    return json.dumps(kept, sort_keys=True, default=float)


def run(quick: bool = False) -> dict[str, Any]:
    """Median wall seconds on 1 and on N workers, their ratio, and result identity."""
    from behavior_hmm.evaluate._executor import ProcessExecutor, SerialExecutor, default_workers
    from behavior_hmm.evaluate._experiments import run_simple_experiment

    sim = "kinematic" if quick else "mujoco"
    repeats = 1
    workers = max(2, default_workers())
    serial: list[float] = []
    parallel: list[float] = []
    same = True
    for _ in range(repeats):
        t0 = time.perf_counter()
        one = run_simple_experiment(sim=sim, executor=SerialExecutor())
        serial.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        many = run_simple_experiment(sim=sim, executor=ProcessExecutor(workers))
        parallel.append(time.perf_counter() - t0)
        same = same and _canonical(one) == _canonical(many)
    one_s, many_s = statistics.median(serial), statistics.median(parallel)
    return {
        "sim": sim,
        "workers": workers,
        "repeats": repeats,
        "workers_1_s_median": one_s,
        f"workers_{workers}_s_median": many_s,
        "speedup": one_s / many_s,
        "results_identical": same,
    }


if __name__ == "__main__":
    print(json.dumps(run(quick="--quick" in sys.argv), indent=1))
