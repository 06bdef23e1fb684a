"""Memory and load time of model files, and how the Behavior-HMM scales to 100,000 categories.

Two parts, every figure measured in a fresh Python process (``peak RSS`` is the most
resident memory the process ever held: ``VmHWM``, or ``ru_maxrss`` of the process that
waited for it):

* ``cli``: the turn SBLM and the turn & approach CBLM trained on the default kinematic
  datasets and saved; then ``behavior-hmm --version`` (the floor: Python, numpy, scipy
  and the command line imported), ``behavior-hmm inspect MODEL`` (a load) and
  ``behavior-hmm generate MODEL`` (a load and one run on the kinematic simulator), each
  as its own process. ``*_above_version_mb`` is the peak above the floor.
* ``scaling``: synthetic Behavior-HMMs of 1,000 to 100,000 observation categories and 50
  to 2,000 states (:func:`synthetic_hmm`), written as a model file's arrays. A fresh
  process loads the file (checked as any stranger's file) and reports the load's time
  and peak RSS above the imports; then it runs what a controller asks of the
  Behavior-HMM every control cycle (``can_plan`` and ``state_scores`` toward the goal,
  a ``plan`` on every change of category) along held-out walks, each category held for
  a few cycles as a robot holds it: median, 99th percentile and maximum of that step.
  The goal's shortest-path tree is built before the first step (``prepare_goals``,
  reported as ``prepare_goal_ms``), as a controller builds it before the robot moves.

  Each size also gets as many observation prototypes, drawn from the turn model's
  (:func:`drawn_prototypes`), and every cycle first categorizes a reading of a turn
  against them (``CobART.stream().update``, searching the prototype index from
  ``INDEX_MIN_CATEGORIES`` on) and then makes the HMM calls: ``control_step_us_*`` is
  the two together, ``step_us_*`` the HMM calls alone, ``categorizer_build_s`` the time
  to make the live categorizer (its index included).

``live_match`` times the categorization alone at a few sizes. What both leave out is the
motion generator; ``bench step`` times whole control steps of trained models.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

#: (observation categories, states) of the scaling part; the quick run keeps the first two.
SIZES = ((1_000, 50), (10_000, 200), (100_000, 500), (100_000, 2_000))
#: Levels along a synthetic demonstration (its length) per size: M = levels × lanes.
LEVELS = 500
#: Demonstrations per synthetic model, as a multiple of its lanes.
EPISODES_PER_LANE = 3
#: Probability that a synthetic demonstration changes lane at a step.
LANE_CHANGE = 0.1
#: Control cycles a held-out walk holds each category (a robot's categories last a few).
HOLD_CYCLES = 3
#: Held-out walks timed per size.
WALKS = 20
#: Observation categories the live CobART match is timed with (``live_match``).
LIVE_SIZES = (2_315, 10_000, 100_000)
#: Readings of each way of the turn the live categorizer is timed on (normalized angle
#: 0.9 → 0.1, then back: a stream without jumps, as a robot's is).
TURN_READINGS = 600


def synthetic_walks(
    n_categories: int, n_walks: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Demonstration-like walks over ``n_categories`` categories toward category 0.

    The categories are a grid of ``LEVELS`` levels (how far from the goal) by ``lanes``
    lanes (``n_categories / LEVELS``, at least 1): a walk starts on the farthest level
    in a random lane, goes one level closer every step and changes lane by one with
    probability ``LANE_CHANGE``; level 0 is one goal category. So every category has a
    few successors, as trained observation categories have, and every walk ends at the
    goal. Returns the categories visited (concatenated) and the walks' lengths.
    """
    lanes = max(1, n_categories // LEVELS)
    levels = n_categories // lanes
    steps = rng.choice(
        [-1, 0, 1],
        size=(n_walks, levels - 1),
        p=[LANE_CHANGE / 2, 1 - LANE_CHANGE, LANE_CHANGE / 2],
    )
    start = rng.integers(0, lanes, n_walks)
    lane = np.clip(start[:, None] + np.cumsum(steps, axis=1), 0, lanes - 1)
    lane = np.concatenate([start[:, None], lane], axis=1)
    level = np.arange(levels - 1, -1, -1)[None, :]  # far to near
    cats = np.where(level == 0, 0, 1 + (level - 1) * lanes + lane)
    cats = np.minimum(cats, n_categories - 1)
    lengths = np.full(n_walks, levels, dtype=np.int64)
    return cats.reshape(-1).astype(np.int64), lengths


def synthetic_hmm(n_categories: int, n_states: int, seed: int = 0) -> Any:
    """A Behavior-HMM counted from :func:`synthetic_walks`, ``n_states`` states.

    A state owns a block of neighbouring levels and lanes (as a motion primitive owns
    the observations of one phase of a motion), so A has a few successors per state and
    B a block of categories per state; C is the walks' grid graph.
    """
    from behavior_hmm.hmm import BehaviorHMM

    rng = np.random.default_rng(seed)
    lanes = max(1, n_categories // LEVELS)
    cats, lengths = synthetic_walks(n_categories, EPISODES_PER_LANE * lanes, rng)
    level = np.where(cats == 0, 0, (cats - 1) // lanes + 1)
    lane = np.where(cats == 0, 0, (cats - 1) % lanes)
    block_lanes = max(1, round(float(np.sqrt(n_states * lanes / (n_categories / lanes)))))
    block_lanes = min(block_lanes, n_states)
    block_levels = max(1, n_states // block_lanes)
    per_level = -(-(n_categories // lanes) // block_levels)
    per_lane = -(-lanes // block_lanes)
    states = (level // per_level) * block_lanes + lane // per_lane
    states = np.minimum(states, n_states - 1)
    hmm = BehaviorHMM(n_states=n_states, n_observations=n_categories)
    return hmm.fit(states, cats, lengths)


def _peak_mb() -> float:
    """The most resident memory this process has held, MB.

    ``VmHWM`` of ``/proc/self/status`` where there is one: ``ru_maxrss`` would also count
    what the parent held when it started this process (Linux keeps it across ``exec``).
    """
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _rss_mb() -> float:
    """Resident memory now, MB (``/proc/self/statm``; the peak where there is none)."""
    try:
        with open("/proc/self/statm", encoding="ascii") as fh:
            pages = int(fh.read().split()[1])
    except OSError:
        return _peak_mb()
    return pages * os.sysconf("SC_PAGE_SIZE") / 1024.0 / 1024.0


def probe_load(path: str, walks: int = WALKS, prototypes: str | None = None) -> dict[str, Any]:
    """In this (fresh) process: load the arrays file, then time the controller's HMM calls.

    The first step of each walk is reported apart (``first_step_us_*``), as ``bench
    step`` reports it: it decodes the whole path from where the robot starts before
    the robot moves (a few ms for a path of 500 categories). With ``prototypes`` (a file
    written by :func:`_save_prototypes`), every cycle first categorizes the next reading
    of a turn against them (``control_step_us_*``: both parts).
    """
    import gc
    import time

    from behavior_hmm.hmm import BehaviorHMM
    from behavior_hmm.models import _modelfile

    gc.collect()
    before = _rss_mb()
    t0 = time.perf_counter()
    header, arrays = _modelfile.load(path)
    hmm = BehaviorHMM.from_arrays(
        {k.removeprefix("hmm."): v for k, v in arrays.items()}, header["state"]["hmm"]
    )
    load_s = time.perf_counter() - t0
    loaded = _peak_mb()  # the load's peak, above the memory held before it
    del arrays
    rng = np.random.default_rng(1)
    goal = 0
    t0 = time.perf_counter()
    hmm.prepare_goals([goal])
    prepare_ms = (time.perf_counter() - t0) * 1e3
    cats, lengths = synthetic_walks(hmm.n_observations_, walks, rng)
    live = None
    build_s = 0.0
    if prototypes is not None:
        t0 = time.perf_counter()
        live = _load_prototypes(prototypes).stream()
        build_s = time.perf_counter() - t0
    readings = _turn_readings()
    times: list[float] = []
    control: list[float] = []
    first: list[float] = []
    clock = time.perf_counter_ns
    gc.collect()
    gc.freeze()  # what set-up made is out of the collector's reach, as in bench step
    cycle = 0
    for walk in np.split(cats, np.cumsum(lengths)[:-1]):
        last = -1
        if live is not None:
            live.reset()
        for k, cat in enumerate(np.repeat(walk, HOLD_CYCLES).tolist()):
            t0 = clock()
            if live is not None:
                live.update(readings[cycle % len(readings)])
                cycle += 1
            t1 = clock()
            if hmm.can_plan(cat, goal):
                hmm.state_scores(cat, goal)
                if cat != last:
                    hmm.plan(cat, goal)
            t2 = clock()
            if k:
                times.append((t2 - t1) / 1e3)
                control.append((t2 - t0) / 1e3)
            else:
                first.append((t2 - t1) / 1e3)
            last = cat
    t = np.asarray(times)
    out: dict[str, Any] = {}
    if live is not None:
        c = np.asarray(control)
        out = {
            "categorizer_build_s": build_s,
            "control_step_us_median": float(np.median(c)),
            "control_step_us_p99": float(np.percentile(c, 99)),
            "control_step_us_max": float(c.max()),
        }
    return out | {
        "first_step_us_median": float(np.median(first)),
        "first_step_us_max": float(np.max(first)),
        "load_s": load_s,
        "load_peak_above_imports_mb": max(0.0, loaded - before),
        "peak_mb": _peak_mb(),
        "prepare_goal_ms": prepare_ms,
        "steps_timed": int(t.size),
        "step_us_median": float(np.median(t)),
        "step_us_p99": float(np.percentile(t, 99)),
        "step_us_max": float(t.max()),
    }


def _save_prototypes(net: Any, path: Path) -> None:
    """Write a CobART's parameters and state for :func:`_load_prototypes` (no pickle)."""
    np.savez(
        path,
        params=np.array(json.dumps(net.get_params())),
        prototypes=net.prototypes_,
        counts=net.counts_,
        dcm_scale=net.dcm_scale_,
    )


def _load_prototypes(path: str) -> Any:
    from behavior_hmm.cobart import CobART

    with np.load(path, allow_pickle=False) as f:
        net = CobART(**json.loads(str(f["params"])))
        return net.set_state(f["prototypes"], f["counts"], f["dcm_scale"])


def _scaling(quick: bool, folder: Path, obs: Any = None) -> list[dict[str, Any]]:
    """The scaling rows; with ``obs`` (a turn model's observation CobART) each size's cycles
    categorize a reading first (:func:`probe_load`)."""
    from behavior_hmm.models import _modelfile

    rows = []
    for n_obs, n_states in SIZES[:2] if quick else SIZES:
        hmm = synthetic_hmm(n_obs, n_states)
        arrays = {f"hmm.{k}": v for k, v in hmm.to_arrays().items()}
        path = folder / f"hmm_{n_obs}_{n_states}.bhmm"
        _modelfile.dump(path, "BehaviorHMM", {}, {"hmm": hmm.params}, arrays)
        extra = []
        if obs is not None:
            protos = folder / f"prototypes_{n_obs}.npz"
            _save_prototypes(drawn_prototypes(obs, n_obs), protos)
            extra = [str(protos)]
        code = (
            "import json, sys; from behavior_hmm.benchmarks.memory import probe_load; "
            "print(json.dumps(probe_load(sys.argv[1], int(sys.argv[2]), *sys.argv[3:])))"
        )
        done = subprocess.run(
            [sys.executable, "-c", code, str(path), str(WALKS), *extra],
            capture_output=True,
            text=True,
            check=True,
        )
        row = {
            "observation_categories": n_obs,
            "states": n_states,
            "observation_transitions": int(hmm.C_counts_.nnz),
            "emission_entries": int(hmm.B_counts_.nnz),
            "file_mb": path.stat().st_size / 1e6,
            "dense_c_would_be_mb": n_obs * n_obs * 8 / 1e6,
        }
        row.update(json.loads(done.stdout.strip().splitlines()[-1]))
        rows.append(row)
    return rows


def _child_peak_mb(args: list[str]) -> tuple[float, float]:
    """Peak RSS (MB) and wall time (s) of ``behavior-hmm ARGS`` run as its own process."""
    code = (
        "import json, resource, subprocess, sys, time; t = time.perf_counter(); "
        "subprocess.run(sys.argv[1:], check=True, capture_output=True); "
        "print(json.dumps([resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024, "
        "time.perf_counter() - t]))"
    )
    cli = [sys.executable, "-c", "from behavior_hmm.cli import main; main()"]
    done = subprocess.run(
        [sys.executable, "-c", code, *cli, *args], capture_output=True, text=True, check=True
    )
    peak, wall = json.loads(done.stdout.strip().splitlines()[-1])
    return float(peak), float(wall)


def _cli(folder: Path) -> tuple[dict[str, Any], Any]:
    """The ``cli`` figures, and the turn SBLM they were measured on."""
    from behavior_hmm.benchmarks._common import default_dataset
    from behavior_hmm.models import CBLM, SBLM

    turn = SBLM(inputs=("angle",)).fit(default_dataset("turn", "kinematic"))
    approach = SBLM(inputs=("distance", "angle")).fit(default_dataset("approach", "kinematic"))
    ta = CBLM(inputs=("distance", "angle"), components=[turn, approach])
    ta.fit(default_dataset("turn-approach", "kinematic"))
    models: dict[str, tuple[Any, str]] = {
        "turn": (turn, "angle=120"),
        "turn_approach": (ta, "angle=120,distance=0.5"),
    }
    floor, _ = _child_peak_mb(["--version"])
    out: dict[str, Any] = {"version_peak_mb": floor}
    for name, (model, start) in models.items():
        path = folder / f"{name}.bhmm"
        model.save(path)
        out[f"{name}_file_kb"] = path.stat().st_size / 1e3
        out[f"{name}_observation_categories"] = int(model.hmm_.n_observations_)
        for what, args in (
            ("inspect", ["inspect", str(path)]),
            ("generate", ["generate", str(path), "--start", start, "--sim", "kinematic"]),
        ):
            peak, wall = _child_peak_mb(args)
            out[f"{name}_{what}_peak_mb"] = peak
            out[f"{name}_{what}_above_version_mb"] = peak - floor
            out[f"{name}_{what}_s"] = wall
    return out, turn


def drawn_prototypes(obs: Any, k: int, seed: int = 0) -> Any:
    """A CobART of ``k`` categories drawn from ``obs``'s prototypes with a little noise.

    Noise of σ 0.01 (normalized units) on every reading of each drawn window, so the
    categories are windows the robot sees, ``k / K`` near copies of each.
    """
    from behavior_hmm.cobart import CobART

    rng = np.random.default_rng(seed)
    picks = obs.prototypes_[rng.integers(0, obs.n_categories_, k)]
    net = CobART(**obs.get_params())
    return net.set_state(
        picks + rng.normal(0.0, 0.01, picks.shape), np.ones(k, np.int64), obs.dcm_scale_
    )


def _turn_readings() -> list[np.ndarray]:
    way = np.linspace(0.9, 0.1, TURN_READINGS)
    return [np.array([v]) for v in np.r_[way, way[::-1]].tolist()]


def live_match(model: Any, sizes: tuple[int, ...] = LIVE_SIZES) -> list[dict[str, Any]]:
    """Time the live CobART match of one reading against ``K`` observation categories.

    ``K`` prototypes are drawn from ``model``'s observation prototypes
    (:func:`drawn_prototypes`), and a turn from 0.9 to 0.1 and back (normalized angle,
    1,200 readings) is categorized. ``indexed``: whether the prototype index was searched;
    ``search``: ``"index"``, ``"tree"`` (the compiled kernels' tree, where this process
    has numba loaded; ``cobart._live.live_kernels``) or ``"screen"`` (every prototype);
    ``scored_median``: prototypes scored per reading (``None`` for the tree, which does
    not count them).
    """
    import time

    rows = []
    for k in sizes:
        t0 = time.perf_counter()
        live = drawn_prototypes(model.observations_, k).stream()
        build_s = time.perf_counter() - t0
        index = live._pred.index
        search = "index" if index is not None else "screen" if live._search is None else "tree"
        times, scored = [], []
        for reading in _turn_readings():
            t0 = time.perf_counter_ns()
            live.update(reading)
            times.append((time.perf_counter_ns() - t0) / 1e3)
            scored.append(index.scored if index is not None else k)
        rows.append(
            {
                "observation_categories": k,
                "indexed": index is not None,
                "search": search,
                "build_s": build_s,
                "scored_median": None if search == "tree" else float(np.median(scored)),
                "update_us_median": float(np.median(times)),
                "update_us_p99": float(np.percentile(times, 99)),
                "update_us_max": float(np.max(times)),
            }
        )
    return rows


def run(quick: bool = False) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        result: dict[str, Any] = {"cpu_count": os.cpu_count()}
        result["cli"], turn = _cli(folder)
        result["live_match"] = live_match(turn)
        result["scaling"] = _scaling(quick, folder, turn.observations_)
    return result
