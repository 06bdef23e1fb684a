"""Speed benchmarks, one module per topic.

Usage::

    behavior-hmm bench sim --json sim.json
    python -m behavior_hmm.benchmarks sim --json sim.json    # the same, without the CLI

Each module ``behavior_hmm/benchmarks/<name>.py`` defines
``run(quick: bool = False) -> dict[str, float]`` returning medians (and ratios against a
baseline measured in the same run where possible).
"""

from __future__ import annotations

import importlib
import pkgutil
from typing import Any


def available() -> list[str]:
    """Names of the benchmarks in this package."""
    return sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))


def run_benchmark(name: str, *, quick: bool = False) -> dict[str, Any]:
    """Run benchmark ``name`` and return its results dict."""
    from behavior_hmm.errors import ConfigError

    names = available()
    if name not in names:
        raise ConfigError(f"unknown benchmark '{name}'; choose one of {', '.join(names)}")
    module = importlib.import_module(f"{__name__}.{name}")
    results: dict[str, Any] = dict(module.run(quick=quick))
    results.setdefault("benchmark", name)
    return results
