"""Training times: the turn SBLM, the approach SBLM, the turn & approach CBLM, and a curve.

The datasets are collected once (not timed); each repeat fits a fresh model with the same
seed, so every repeat does identical work. ``demonstrations_curve`` times the turn SBLM
trained on ×1, ×2, ×4 and ×8 the default grid of demonstrations (the same angle range
sampled k times as densely, collected on the kinematic simulator), one fit per point.

``options`` times the turn and approach SBLMs with the options that learn from few
demonstrations (``mirror``, ``generator_init="shared"``, both) beside the default preset's
fit in the same run: medians of the same repeats and each one's ratio over the default's.

``cobart_kernel`` names CobART's episode loops: ``"numba"`` with the ``fast`` extra, else
``"numpy"``. With numba the turn & approach CBLM is also timed on the numpy loops in the
same run (``train_complex_numpy_s_median``, ``complex_numpy_over_numba``): the same model
to the bit, so the ratio is the compiled kernels' speed-up of that fit.
"""

from __future__ import annotations

import time
from functools import lru_cache
from typing import Any

import numpy as np

from behavior_hmm.benchmarks._common import default_dataset
from behavior_hmm.cobart._compiled import cobart_kernel, set_kernel

#: Multiples of the default turn grid in the curve.
CURVE_FACTORS = (1, 2, 4, 8)
#: The SBLM options ``options`` times, by name: parameters over the default preset.
OPTIONS: dict[str, dict[str, Any]] = {
    "default": {},
    "mirror": {"mirror": True},
    "shared": {"generator_init": "shared"},
    "mirror+shared": {"mirror": True, "generator_init": "shared"},
}


def _median_time(fit: Any, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fit()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


@lru_cache(maxsize=8)
def dense_turn_dataset(factor: int) -> Any:
    """Turn demonstrations from ``factor`` × the default grid's starts (kinematic)."""
    from behavior_hmm.teach import collect, default_starts

    grid = default_starts("turn")  # every 10 deg at one distance, 0 excluded
    distance = grid[0]["distance"]
    step = 10.0 / factor
    angles = [-180.0 + step * i for i in range(round(360.0 / step) + 1)]
    starts = [{"angle": a, "distance": distance} for a in angles if abs(a) > 1e-9]
    return collect("turn", starts, sim="kinematic", seed=0)


def demonstrations_curve(factors: tuple[int, ...] = CURVE_FACTORS) -> list[dict[str, Any]]:
    """Training time of the turn SBLM against the number of demonstrations."""
    from behavior_hmm.models import SBLM

    rows = []
    for factor in factors:
        data = dense_turn_dataset(factor)
        t0 = time.perf_counter()
        model = SBLM(inputs=("angle",)).fit(data)
        rows.append(
            {
                "grid_factor": factor,
                "demonstrations": len(data.lengths),
                "samples": int(data.n_samples),
                "train_s": time.perf_counter() - t0,
                "primitives": int(model.hmm_.n_states_),
                "observation_categories": int(model.hmm_.n_observations_),
            }
        )
    return rows


def option_times(
    tasks: dict[str, tuple[Any, tuple[str, ...]]], repeats: int
) -> dict[str, dict[str, float]]:
    """SBLM training time with each of :data:`OPTIONS`, per task.

    Parameters
    ----------
    tasks
        Task name → (demonstrations, input channels).
    repeats
        Fits per option; the median is reported.

    Returns
    -------
    dict
        Per task: ``"<option>_s"`` (median s) for every option and ``"<option>_over_default"``
        (that median over the default preset's, measured in the same run) for the others.
    """
    from behavior_hmm.models import SBLM

    out: dict[str, dict[str, float]] = {}
    for task, (data, inputs) in tasks.items():
        row: dict[str, float] = {}
        for name, extra in OPTIONS.items():
            row[f"{name}_s"] = _median_time(
                lambda e=extra, i=inputs, d=data: SBLM(inputs=i, **e).fit(d), repeats
            )
        for name in OPTIONS:
            if name != "default":
                row[f"{name}_over_default"] = row[f"{name}_s"] / row["default_s"]
        out[task] = row
    return out


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

    def fit_complex() -> None:
        CBLM(components, inputs=("distance", "angle")).fit(complex_data)

    results["train_complex_s_median"] = _median_time(fit_complex, repeats)
    results["cobart_kernel"] = cobart_kernel()
    if results["cobart_kernel"] == "numba":
        previous = set_kernel("numpy")
        try:
            numpy_s = _median_time(fit_complex, repeats)
        finally:
            set_kernel(previous)
        results["train_complex_numpy_s_median"] = numpy_s
        results["complex_numpy_over_numba"] = numpy_s / results["train_complex_s_median"]
    results["complex_samples"] = int(complex_data.n_samples)
    results["options"] = option_times(
        {"turn": (turn, ("angle",)), "approach": (approach, ("distance", "angle"))}, repeats
    )
    results["demonstrations_curve"] = demonstrations_curve(
        CURVE_FACTORS[:2] if quick else CURVE_FACTORS
    )
    return results


if __name__ == "__main__":
    import json

    print(json.dumps(run(), indent=2))
