"""Time of one control step of the turn model: sense -> categorize -> re-plan -> command.

Runs the SBLM trained on the default turn dataset from the 15 turn test starts on the
kinematic simulator and times only the controller's ``step`` (the simulator's own step is
timed beside it as a reference, and the 16 ms control period as the budget). Without
``--quick`` it also times the turn & approach CBLM (``complex_step_us_*``).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from benchmarks._common import default_dataset


def run(quick: bool = False) -> dict[str, Any]:
    from behavior_hmm.models import SBLM
    from behavior_hmm.runtime import make_controller
    from behavior_hmm.runtime._loop import start_options
    from behavior_hmm.sim import make_env
    from behavior_hmm.teach import complete_start, test_starts

    model = SBLM(inputs=("angle",)).fit(default_dataset("turn"))
    env = make_env("kinematic")
    ctrl_us: list[float] = []
    env_us: list[float] = []
    starts = test_starts("turn")[: 5 if quick else None]
    for i, start in enumerate(starts):
        full = complete_start("turn", start)
        controller = make_controller(model, None)
        obs, _ = env.reset(seed=i, options=start_options(full, None, None))
        controller.reset()
        for _ in range(model.max_steps_):
            t0 = time.perf_counter()
            out = controller.step(obs)
            t1 = time.perf_counter()
            if out.done:
                break
            obs, *_ = env.step(out.command)
            t2 = time.perf_counter()
            ctrl_us.append((t1 - t0) * 1e6)
            env_us.append((t2 - t1) * 1e6)
    step = np.asarray(ctrl_us)
    period_us = env.unwrapped.params.control_period * 1e6
    results = {
        "step_us_median": float(np.median(step)),
        "step_us_p99": float(np.percentile(step, 99)),
        "step_us_max": float(step.max()),
        "steps_timed": int(step.size),
        "kinematic_env_step_us_median": float(np.median(env_us)),
        "control_period_us": period_us,
        "step_median_over_control_period": float(np.median(step) / period_us),
    }
    if not quick:
        results.update(_complex_step(model, env))
    return results


def _complex_step(turn: Any, env: Any) -> dict[str, float]:
    """The same for the turn & approach CBLM (its first step, which plans, is excluded)."""
    from behavior_hmm.models import CBLM, SBLM
    from behavior_hmm.runtime import make_controller
    from behavior_hmm.runtime._loop import start_options
    from behavior_hmm.teach import test_starts

    approach = SBLM(inputs=("distance", "angle")).fit(default_dataset("approach"))
    model = CBLM([turn, approach], inputs=("distance", "angle"))
    model.fit(default_dataset("turn-approach"))
    times: list[float] = []
    for i, start in enumerate(test_starts("turn-approach")):
        controller = make_controller(model, None)
        obs, _ = env.reset(seed=i, options=start_options(start, None, None))
        controller.reset()
        for k in range(model.max_steps_):
            t0 = time.perf_counter()
            out = controller.step(obs)
            if k:
                times.append((time.perf_counter() - t0) * 1e6)
            if out.done:
                break
            obs, *_ = env.step(out.command)
    arr = np.asarray(times)
    return {
        "complex_step_us_median": float(np.median(arr)),
        "complex_step_us_p99": float(np.percentile(arr, 99)),
        "complex_step_us_max": float(arr.max()),
        "complex_steps_timed": int(arr.size),
    }


if __name__ == "__main__":
    import json

    print(json.dumps(run(), indent=2))
