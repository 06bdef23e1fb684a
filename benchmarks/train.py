"""Training times: the turn SBLM, the approach SBLM, and the turn & approach CBLM.

The dataset is collected once (not timed); each repeat fits a fresh model with the same
seed, so every repeat does identical work.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from benchmarks._common import default_dataset


def _median_time(fit: Any, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fit()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def run(quick: bool = False) -> dict[str, Any]:
    from behavior_hmm.models import CBLM, SBLM

    repeats = 1 if quick else 3
    turn = default_dataset("turn")
    results: dict[str, Any] = {
        "train_s_median": _median_time(lambda: SBLM(inputs=("angle",)).fit(turn), repeats),
        "turn_samples": int(turn.n_samples),
        "repeats": repeats,
    }
    approach = default_dataset("approach")
    results["train_approach_s_median"] = _median_time(
        lambda: SBLM(inputs=("distance", "angle")).fit(approach), repeats
    )
    # the turn & approach CBLM, given its already learned components (not timed)
    components = [
        SBLM(inputs=("angle",)).fit(turn),
        SBLM(inputs=("distance", "angle")).fit(approach),
    ]
    complex_data = default_dataset("turn-approach")
    results["train_complex_s_median"] = _median_time(
        lambda: CBLM(components, inputs=("distance", "angle")).fit(complex_data), repeats
    )
    results["complex_samples"] = int(complex_data.n_samples)
    return results


if __name__ == "__main__":
    import json

    print(json.dumps(run(), indent=2))
