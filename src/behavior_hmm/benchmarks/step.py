"""Time of one control step: sense -> categorize -> re-plan -> command, and how it grows.

Three parts, all on the kinematic simulator from the behavior's listed test starts, timing
only the controller's ``step`` (the simulator's own step is timed beside it as a
reference, the 16 ms control period is the budget):

* the turn SBLM trained on the default turn dataset (``step_us_*``);
* without ``--quick``, the turn & approach CBLM (``complex_step_us_*``);
* ``scaling``: SBLMs of the same turn data with more observation categories (100 …
  5,000) or more primitives (100 … 1,000), made by raising the CobART vigilance of that
  layer (found by bisection; the real counts are reported), run through the same
  policy (``SBLM.policy()``, ``CBLM.policy()``).

Each figure has a median, a 99th percentile and a maximum of wall-clock time. The first
step of a run is left out of them (it plans before the robot moves and refuses an
unreachable goal; ``first_step_us_median``). Garbage collection stays on, as in a real
loop; every object made during set-up is moved out of its reach (``gc.freeze()``), and
the collections that still ran inside timed steps are counted (``gc_in_steps``). The
machine may be shared: a step that lost the CPU to another process counts in full in the
wall-clock maximum, so the thread's CPU time is reported beside it
(``*_cpu_us_p99``/``*_cpu_us_max``): where the two maxima differ, the difference was
spent waiting, not computing.

``live_kernel`` says how live streams of ``LIVE_COMPILED_MIN`` categories or more (the
CBLM's observations, the scaling curve's larger models) searched: ``"numba"`` (the
compiled kernels' tree, used here because this process trained its models with them
loaded) or ``"numpy"`` (every category screened; without the ``fast`` extra).
"""

from __future__ import annotations

import gc
import math
import time
from typing import Any

import numpy as np

from behavior_hmm.benchmarks._common import default_dataset

#: Observation categories and primitives of the scaling curve (without ``--quick``).
OBSERVATION_TARGETS = (100, 500, 1000, 2000, 5000)
PRIMITIVE_TARGETS = (100, 300, 1000)
#: Add-k smoothing of the models with more primitives (see ``_sized_model``).
PRIMITIVE_SMOOTHING = 0.001


class _GcCounter:
    """Counts garbage collections by generation while ``active``."""

    def __init__(self) -> None:
        self.active = False
        self.counts = [0, 0, 0]

    def __call__(self, phase: str, info: dict[str, Any]) -> None:
        if self.active and phase == "start":
            self.counts[int(info["generation"])] += 1


def _stats(prefix: str, wall: list[float], cpu: list[float]) -> dict[str, Any]:
    w = np.asarray(wall)
    c = np.asarray(cpu)
    return {
        f"{prefix}_us_median": float(np.median(w)),
        f"{prefix}_us_p99": float(np.percentile(w, 99)),
        f"{prefix}_us_max": float(w.max()),
        f"{prefix}_cpu_us_p99": float(np.percentile(c, 99)),
        f"{prefix}_cpu_us_max": float(c.max()),
    }


def time_steps(
    model: Any, behavior: str, env: Any, starts: list[dict[str, float]] | None = None
) -> dict[str, Any]:
    """Run ``model`` from each start and time its control steps (see the module doc)."""
    from behavior_hmm.errors import UnreachableGoalError
    from behavior_hmm.runtime import Robot, start_options
    from behavior_hmm.teach import complete_start, test_starts

    chosen = test_starts(behavior) if starts is None else starts
    robot = Robot(env)
    wall: list[float] = []
    cpu: list[float] = []
    first: list[float] = []
    env_us: list[float] = []
    refused = 0
    counter = _GcCounter()
    gc.callbacks.append(counter)
    clock, cpu_clock = time.perf_counter_ns, time.thread_time_ns
    try:
        for i, start in enumerate(chosen):
            controller = model.policy()
            options = start_options(complete_start(behavior, start), None, None)
            reading, _, _ = robot.reset(seed=i, options=options)
            obs = robot.as_dict(reading)
            controller.reset()
            gc.collect()
            gc.freeze()  # what set-up made is out of the collector's reach
            counter.active = True
            for k in range(model.max_steps_):
                t0, c0 = clock(), cpu_clock()
                try:
                    out = controller.step(obs)
                except UnreachableGoalError:
                    if k:
                        raise
                    refused += 1
                    break
                c1, t1 = cpu_clock(), clock()
                if k:
                    wall.append((t1 - t0) / 1e3)
                    cpu.append((c1 - c0) / 1e3)
                else:
                    first.append((t1 - t0) / 1e3)
                if out.done:
                    break
                counter.active = False
                t2 = clock()
                reading, _, _ = robot.step(out.command)
                obs = robot.as_dict(reading)
                env_us.append((clock() - t2) / 1e3)
                counter.active = True
            counter.active = False
    finally:
        gc.callbacks.remove(counter)
    result = {
        "steps_timed": len(wall),
        "starts_refused": refused,
        "first_step_us_median": float(np.median(first)) if first else None,
        "gc_in_steps": dict(zip(("gen0", "gen1", "gen2"), counter.counts, strict=True)),
        "env_step_us_median": float(np.median(env_us)) if env_us else None,
    }
    if wall:
        result.update(_stats("step", wall, cpu))
    return result


def _sized_model(data: Any, layer: str, target: int) -> tuple[Any, float]:
    """The turn SBLM with about ``target`` categories in ``layer`` (vigilance bisection)."""
    from behavior_hmm.models import SBLM

    key = "observation_params" if layer == "observations" else "primitive_params"
    # Fine primitives make most planned observation paths unexplainable by the counted
    # primitive transitions (every start refused): those models get a small add-k.
    smoothing = 0.0 if layer == "observations" else PRIMITIVE_SMOOTHING

    def count(rho: float, epochs: int) -> tuple[int, Any]:
        params: dict[str, Any] = {key: {"rho": rho}, "smoothing": smoothing, "epochs": epochs}
        model = SBLM(inputs=("angle",), **params).fit(data)
        n = model.hmm_.n_observations_ if layer == "observations" else model.hmm_.n_states_
        return int(n), model

    # bisection on log(1 - rho): the count grows steeply as rho nears 1
    lo, hi = math.log(1 - 0.80), math.log(1 - 0.99995)
    rho = 1 - math.exp((lo + hi) / 2)
    for _ in range(14):
        rho = 1 - math.exp((lo + hi) / 2)
        n, _ = count(rho, 1)  # untrained generators: only the count matters here
        if abs(n - target) <= 0.05 * target:
            break
        if n < target:
            lo = (lo + hi) / 2
        else:
            hi = (lo + hi) / 2
    return count(rho, 200)[1], rho


def _scaling(quick: bool, env: Any) -> list[dict[str, Any]]:
    from behavior_hmm.teach import test_starts

    data = default_dataset("turn")
    starts = test_starts("turn")[: 5 if quick else None]
    plan = [("observations", t) for t in ((100, 1000) if quick else OBSERVATION_TARGETS)]
    plan += [("primitives", t) for t in ((300,) if quick else PRIMITIVE_TARGETS)]
    rows = []
    for layer, target in plan:
        model, rho = _sized_model(data, layer, target)
        timed = time_steps(model, "turn", env, starts)
        row = {
            "observation_categories": int(model.hmm_.n_observations_),
            "primitives": int(model.hmm_.n_states_),
            "varied": layer,
            "rho": rho,
            "smoothing": model.smoothing,
            "steps_timed": timed["steps_timed"],
            "starts_refused": timed["starts_refused"],
            "gc_in_steps": timed["gc_in_steps"],
        }
        for key in ("median", "p99", "max", "cpu_us_p99", "cpu_us_max"):
            name = f"step_us_{key}" if not key.startswith("cpu") else f"step_{key}"
            row[name] = timed.get(name)
        rows.append(row)
    return rows


def run(quick: bool = False) -> dict[str, Any]:
    from behavior_hmm.models import SBLM
    from behavior_hmm.runtime import Robot
    from behavior_hmm.sim import make_env
    from behavior_hmm.teach import test_starts

    model = SBLM(inputs=("angle",)).fit(default_dataset("turn"))
    env = make_env("kinematic")
    period_us = Robot(env).control_period * 1e6
    timed = time_steps(model, "turn", env, test_starts("turn")[: 5 if quick else None])
    results: dict[str, Any] = {
        **{k: v for k, v in timed.items() if k.startswith("step_")},
        "steps_timed": timed["steps_timed"],
        "first_step_us_median": timed["first_step_us_median"],
        "gc_in_steps": timed["gc_in_steps"],
        "kinematic_env_step_us_median": timed["env_step_us_median"],
        "control_period_us": period_us,
        "step_median_over_control_period": timed["step_us_median"] / period_us,
        "observation_categories": int(model.hmm_.n_observations_),
        "primitives": int(model.hmm_.n_states_),
    }
    if not quick:
        results.update(_complex_step(model, env))
    results["scaling"] = _scaling(quick, env)
    from behavior_hmm.cobart._live import live_kernels

    results["live_kernel"] = "numpy" if live_kernels() is None else "numba"
    return results


def _complex_step(turn: Any, env: Any) -> dict[str, Any]:
    """The same for the turn & approach CBLM."""
    from behavior_hmm.models import CBLM, SBLM

    approach = SBLM(inputs=("distance", "angle")).fit(default_dataset("approach"))
    model = CBLM([turn, approach], inputs=("distance", "angle"))
    model.fit(default_dataset("turn-approach"))
    timed = time_steps(model, "turn-approach", env)
    out = {f"complex_{k}": v for k, v in timed.items() if k.startswith("step_")}
    out["complex_steps_timed"] = timed["steps_timed"]
    out["complex_first_step_us_median"] = timed["first_step_us_median"]
    out["complex_gc_in_steps"] = timed["gc_in_steps"]
    out["complex_observation_categories"] = int(model.hmm_.n_observations_)
    return out


if __name__ == "__main__":
    import json

    print(json.dumps(run(), indent=2))
