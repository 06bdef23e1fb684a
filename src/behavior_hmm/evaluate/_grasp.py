"""Grasp and turn → approach → grasp, measured like the chains in the literature (issue 28).

The thesis's chapter-5 example on our Khepera with a gripper (``behavior_hmm/
KheperaGripper-v0``): turn {angle}, approach {distance, angle} and grasp {arm, fingers,
object_present} are learned as SBLMs on the gripper robot and composed, without
retraining them, into the CBLM turn → approach → grasp on (distance, angle, arm, fingers,
object_present). Every seed is scored

1. per stage: each component on its own shipped test starts (grasp given a finished
   approach: its starts lie inside the approach's goal region);
2. at the hand-off: where the composed run hands over from approach to grasp (distance
   and bearing at the first grasp step, inside the approach's goal region or not) and
   whether the grasp then lifts;
3. end to end: the CBLM from the 15 turn → approach → grasp test starts, lifted count
   (``goal_reached`` and the env's own ``info["lifted"]``) and success rate beside the
   all-zero floor, and BC / BC-strong trained on the whole composed behavior;
4. nudged: the same starts with the object moved 1-2 cm after the approach (the env's
   ``nudge`` reset option, added by :class:`NudgeWrapper`), for the CBLM and the teacher.

Demonstrations are collected once, noise-free, from the default grids (the same for
every seed); each seed trains its own models.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Final, SupportsFloat

import gymnasium
import numpy as np

from behavior_hmm._envs import GRIPPER_ENV_ID
from behavior_hmm.data import ANGLE_TOLERANCE_DEG, DISTANCE_TOLERANCE_M
from behavior_hmm.errors import ConfigError, SimulationError
from behavior_hmm.evaluate._baselines import BASELINES
from behavior_hmm.evaluate._executor import Executor, SerialExecutor, map_largest_first
from behavior_hmm.evaluate._experiments import check_seeds, over_seeds
from behavior_hmm.evaluate._protocol import evaluate_model

Progress = Callable[[int, int], None]
Start = dict[str, float]

#: The components: (behavior, inputs), learned as SBLMs on the gripper robot.
STAGES: Final[tuple[tuple[str, tuple[str, ...]], ...]] = (
    ("turn", ("angle",)),
    ("approach", ("distance", "angle")),
    ("grasp", ("arm", "fingers", "object_present")),
)
#: The composed behavior and the CBLM's inputs.
COMPOSED: Final[str] = "turn-approach-grasp"
COMPOSED_INPUTS: Final[tuple[str, ...]] = ("distance", "angle", "arm", "fingers", "object_present")
#: Every behavior demonstrated (all on the gripper robot).
BEHAVIORS: Final[tuple[str, ...]] = (*(b for b, _ in STAGES), COMPOSED)
#: The nudge after the approach: distance (m) and turn of its direction (deg), uniform.
NUDGE_DISTANCE_M: Final[tuple[float, float]] = (0.01, 0.02)
NUDGE_ANGLE_DEG: Final[tuple[float, float]] = (-20.0, 20.0)
#: The approach's goal region, where a grasp can begin: distance (m) and |bearing| (deg).
HANDOFF_DISTANCE_M: Final[float] = DISTANCE_TOLERANCE_M
HANDOFF_ANGLE_DEG: Final[float] = ANGLE_TOLERANCE_DEG
#: The issue's targets (of 15 starts, MuJoCo, default preset, seed 0, 5 seeds).
TARGETS: Final[dict[str, int]] = {"grasp": 14, "composed": 14, "nudged": 12}


def draw_nudges(seed: int, n: int) -> list[dict[str, float]]:
    """``n`` nudges drawn from a generator seeded by ``seed``.

    Returns
    -------
    list of dict
        ``{"distance": m, "angle": deg}`` per start: distance uniform in
        :data:`NUDGE_DISTANCE_M`, angle uniform in :data:`NUDGE_ANGLE_DEG`.
    """
    rng = np.random.default_rng(seed)
    return [
        {
            "distance": float(rng.uniform(*NUDGE_DISTANCE_M)),
            "angle": float(rng.uniform(*NUDGE_ANGLE_DEG)),
        }
        for _ in range(n)
    ]


class NudgeWrapper(gymnasium.Wrapper[Any, Any, Any, Any]):
    """Adds the ``nudge`` reset option of the gripper env and records every episode.

    Parameters
    ----------
    env
        A :class:`~behavior_hmm.sim._gripper.KheperaGripperEnv` (or a wrapper of one).
    nudge
        ``{"distance": m, "angle": deg}`` added to every reset not armed otherwise
        (:meth:`arm`); ``None``: no nudge.

    Notes
    -----
    ``episodes`` holds one record per reset: ``case`` and ``runner`` (set by
    :meth:`arm`, else ``None``), the ``nudge`` applied, ``lifted`` and ``nudged`` from the
    env's last ``info``, and the object's position (m) at the reset and at the end.
    """

    def __init__(self, env: Any, nudge: Mapping[str, float] | None = None) -> None:
        super().__init__(env)
        self.nudge = None if nudge is None else dict(nudge)
        self.episodes: list[dict[str, Any]] = []
        self._queue: list[tuple[int, int, dict[str, float] | None]] = []

    def arm(self, runs: int, *, case: int, nudge: Mapping[str, float] | None = None) -> None:
        """Tag the next ``runs`` resets as runners 0..runs-1 of ``case``, nudged by ``nudge``."""
        given = None if nudge is None else dict(nudge)
        self._queue = [(case, k, given) for k in range(runs)]

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset, adding ``options["nudge"]`` when armed with one (or given one at init)."""
        chosen = dict(options or {})
        case: int | None
        runner: int | None
        if self._queue:
            case, runner, nudge = self._queue.pop(0)
        else:
            case, runner, nudge = None, None, self.nudge
        if nudge is not None:
            chosen["nudge"] = dict(nudge)
        obs, info = self.env.reset(seed=seed, options=chosen)
        self.episodes.append(
            {
                "case": case,
                "runner": runner,
                "nudge": nudge,
                "lifted": bool(info.get("lifted", False)),
                "nudged": bool(info.get("nudged", False)),
                "object_start": [float(c) for c in info.get("object", (math.nan,) * 3)],
                "object_end": [float(c) for c in info.get("object", (math.nan,) * 3)],
            }
        )
        return obs, info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step, recording the episode's latest ``lifted``, ``nudged`` and object position."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        if self.episodes:
            episode = self.episodes[-1]
            episode["lifted"] = bool(info.get("lifted", False))
            episode["nudged"] = bool(info.get("nudged", False))
            if "object" in info:
                episode["object_end"] = [float(c) for c in info["object"]]
        return obs, reward, terminated, truncated, info


def gripper_env() -> Any:
    """A fresh ``behavior_hmm/KheperaGripper-v0``."""
    from behavior_hmm.runtime import make_robot_env

    return make_robot_env(GRIPPER_ENV_ID)


def evaluate_on_gripper(
    model: Any,
    starts: Sequence[Mapping[str, float]],
    *,
    seed: int,
    baselines: Mapping[str, Any] | None = None,
    nudges: Sequence[Mapping[str, float]] | None = None,
    keep_traces: bool = False,
) -> dict[str, Any]:
    """:func:`evaluate_model` on a fresh gripper env, with the env's ``lifted`` per run.

    Parameters
    ----------
    model, starts, seed, baselines, keep_traces
        As for :func:`evaluate_model` (case ``i`` runs with seed ``seed + i``).
    nudges
        One ``{"distance": m, "angle": deg}`` per start: the model's and baselines' runs
        of case ``i`` are nudged by ``nudges[i]``; the teacher's reference never is.

    Returns
    -------
    dict
        The evaluation; every case (of the model and of each baseline) also holds
        ``lifted``, ``nudged``, ``nudge`` and ``object_end`` (m) from the env, and the
        summaries ``lifted`` and ``nudged`` (counts).
    """
    wrapper = NudgeWrapper(gripper_env())
    names = ["model", *(baselines or {})]

    def mark(i: int, start: Mapping[str, float], reference: Any) -> dict[str, Any]:
        wrapper.arm(len(names), case=i, nudge=None if nudges is None else nudges[i])
        return {}

    if nudges is not None and len(nudges) != len(starts):
        raise ConfigError(f"{len(nudges)} nudges for {len(starts)} starts")
    result = evaluate_model(
        model,
        list(starts),
        sim=None,
        env=wrapper,
        seed=seed,
        baselines=baselines,
        case_options=mark,
        keep_traces=keep_traces,
    )
    runs = {(e["case"], e["runner"]): e for e in wrapper.episodes if e["case"] is not None}
    for k, name in enumerate(names):
        summary = result if name == "model" else result["baselines"][name]
        for i, case in enumerate(summary["cases"]):
            episode = runs.get((i, k), {})  # none: refused before any motion
            case["lifted"] = bool(episode.get("lifted", False))
            case["nudged"] = bool(episode.get("nudged", False))
            case["nudge"] = episode.get("nudge")
            case["object_end"] = episode.get("object_end")
        summary["lifted"] = int(sum(c["lifted"] for c in summary["cases"]))
        summary["nudged"] = int(sum(c["nudged"] for c in summary["cases"]))
    return result


def handoff(trace: Any, demo: Mapping[str, Any]) -> dict[str, Any]:
    """Where a composed run (and the teacher's) hands over from approach to grasp.

    Returns
    -------
    dict
        ``step`` (control periods; ``None`` when the run never grasped), ``distance``
        (m) and ``angle`` (deg, noise-free) at the first grasp step, ``in_region``
        (distance ≤ :data:`HANDOFF_DISTANCE_M` and |angle| ≤ :data:`HANDOFF_ANGLE_DEG`),
        ``from`` (the component before grasp) and the teacher's ``teacher_distance``,
        ``teacher_angle``, ``teacher_in_region``.
    """
    components = list(trace.component)
    j = components.index("grasp") if "grasp" in components else None
    out: dict[str, Any] = {"step": j, "distance": None, "angle": None, "in_region": False}
    out["from"] = next((c for c in reversed(components[:j]) if c), None) if j else None
    if j is not None:
        true = np.asarray(trace.true_readings, dtype=np.float64).reshape(-1, len(trace.channels))
        distance = float(true[j, trace.channels.index("distance")])
        angle = float(true[j, trace.channels.index("angle")])
        out.update(distance=distance, angle=angle, in_region=_in_region(distance, angle))
    tags = list(demo["behavior"])
    k = tags.index("grasp") if "grasp" in tags else None
    if k is None:
        out.update(teacher_distance=None, teacher_angle=None, teacher_in_region=False)
    else:
        d, a = float(demo["distance"][k]), float(demo["angle"][k])
        out.update(teacher_distance=d, teacher_angle=a, teacher_in_region=_in_region(d, a))
    return out


def _in_region(distance: float, angle: float) -> bool:
    return bool(distance <= HANDOFF_DISTANCE_M + 1e-9 and abs(angle) <= HANDOFF_ANGLE_DEG + 1e-9)


def teacher_nudged(
    starts: Sequence[Mapping[str, float]], nudges: Sequence[Mapping[str, float]], seed: int
) -> dict[str, Any]:
    """Our teacher's turn → approach → grasp from each start with the object nudged.

    Returns
    -------
    dict
        ``cases`` (``start``, ``nudge``, ``nudged``, ``lifted``, ``error``: the teacher's
        own complaint when it missed, else ``None``), ``lifted`` and ``nudged`` counts.
    """
    from behavior_hmm.teach import Teacher, complete_start

    wrapper = NudgeWrapper(gripper_env())
    tutor = Teacher(wrapper)
    cases: list[dict[str, Any]] = []
    for i, (row, nudge) in enumerate(zip(starts, nudges, strict=True)):
        full = complete_start(COMPOSED, dict(row), math.inf)
        wrapper.nudge = dict(nudge)
        error = None
        try:
            tutor.demonstrate(COMPOSED, full["angle"], full["distance"], seed=seed + i)
        except SimulationError as err:  # it missed the goal, or a phase timed out
            error = str(err)
        episode = wrapper.episodes[-1]
        cases.append(
            {
                "start": full,
                "nudge": dict(nudge),
                "nudged": bool(episode["nudged"]),
                "lifted": bool(episode["lifted"]),
                "error": error,
            }
        )
    return {
        "cases": cases,
        "lifted": sum(bool(c["lifted"]) for c in cases),
        "nudged": sum(bool(c["nudged"]) for c in cases),
        "n": len(cases),
    }


def run_grasp_experiment(
    *,
    seed: int = 0,
    seeds: int = 5,
    sblm_params: Mapping[str, Any] | None = None,
    cblm_params: Mapping[str, Any] | None = None,
    baseline_params: Mapping[str, Any] | None = None,
    baselines: Sequence[str] = tuple(BASELINES),
    grids: Mapping[str, Sequence[Start]] | None = None,
    limit: int | None = None,
    progress: Progress | None = None,
    executor: Executor | None = None,
) -> dict[str, Any]:
    """Collect, train, compose and score grasp and turn → approach → grasp over seeds.

    Parameters
    ----------
    seed, seeds
        Seeds ``seed .. seed + seeds - 1`` each train their own models (``random_state``)
        and draw their own nudges; the demonstrations are collected once with ``seed``.
    sblm_params, cblm_params
        Constructor parameters of every SBLM and of the CBLM (a preset's).
    baseline_params
        Constructor parameters of every baseline (default: theirs).
    baselines
        Baselines trained on the whole composed behavior (names of :data:`BASELINES`).
    grids
        Training starts per behavior (default: each behavior's default grid).
    limit
        Score only the first ``limit`` test starts of each behavior (default: all 15).
    progress
        Called as ``progress(done, total)`` as tasks finish.
    executor
        Runs the collections, each seed's models and each seed's baselines as tasks.

    Returns
    -------
    dict
        ``env``, ``sim`` (``"mujoco"``), ``seeds``, ``rows`` (per seed: the table's rows),
        ``over_seeds`` (per row: mean, 95 % interval, min, max and values of each
        count and score), ``per_seed`` (every evaluation, hand-off and nudge of every
        seed), ``targets`` and ``timings`` (seconds). ``_figures`` (the first seed's
        runs, for the figures) and ``_models`` (the first seed's fitted SBLMs and
        CBLM, for videos) are not for results.json.
    """
    run = executor or SerialExecutor()
    seed_list = [seed + k for k in range(check_seeds(seeds))]
    unknown = [b for b in baselines if b not in BASELINES]
    if unknown:
        raise ConfigError(f"unknown baseline '{unknown[0]}'; available: {', '.join(BASELINES)}")
    if limit is not None and (isinstance(limit, bool) or not isinstance(limit, int) or limit < 1):
        raise ConfigError(f"limit must be an integer >= 1, got {limit!r}")
    data_tasks = [(b, None if grids is None else list(grids.get(b) or []), seed) for b in BEHAVIORS]
    total = len(data_tasks) + len(seed_list) * (1 + len(baselines))
    offset = 0

    def advance(done: int, _: int) -> None:
        if progress is not None:
            progress(offset + done, total)

    t0 = time.perf_counter()
    datasets = dict(zip(BEHAVIORS, run.map(_collect_task, data_tasks, advance), strict=True))
    collect_s = time.perf_counter() - t0
    offset += len(data_tasks)
    tasks: list[tuple[Any, ...]] = []
    sizes: list[float] = []
    for s in seed_list:
        tasks.append(("models", datasets, s, sblm_params, cblm_params, limit))
        sizes.append(1.0)
        for name in baselines:
            tasks.append((name, datasets, s, baseline_params, None, limit))
            sizes.append(2.0)  # a baseline on the composed data trains longest
    outcomes = map_largest_first(run, _seed_task, tasks, sizes, advance)
    per_seed: list[dict[str, Any]] = []
    for k, s in enumerate(seed_list):
        mine = outcomes[k * (1 + len(baselines)) : (k + 1) * (1 + len(baselines))]
        entry = dict(mine[0])
        entry["baselines"] = {name: o for name, o in zip(baselines, mine[1:], strict=True)}
        entry["seed"] = s
        per_seed.append(entry)
    rows = [_rows(entry, baselines) for entry in per_seed]
    first = per_seed[0]
    figures = first.pop("_figures")
    models = first.pop("_models")
    for entry in per_seed[1:]:
        entry.pop("_figures")
        entry.pop("_models")
    return {
        "env": GRIPPER_ENV_ID,
        "sim": "mujoco",
        "seed": seed,
        "seeds": seed_list,
        "baseline_names": list(baselines),
        "limit": limit,
        "handoff_region": {"distance_m": HANDOFF_DISTANCE_M, "angle_deg": HANDOFF_ANGLE_DEG},
        "nudge_range": {"distance_m": list(NUDGE_DISTANCE_M), "angle_deg": list(NUDGE_ANGLE_DEG)},
        "targets": dict(TARGETS),
        "demonstrations": {b: len(d) for b, d in datasets.items()},
        "rows": rows,
        "over_seeds": [
            over_seeds([[r[j]] for r in rows], _numeric_keys(rows[0][j]))[0]
            for j in range(len(rows[0]))
        ],
        "per_seed": [{k: v for k, v in e.items() if k != "timings"} for e in per_seed],
        "timings": {"collect_s": collect_s, "per_seed": [e["timings"] for e in per_seed]},
        "_figures": figures,
        "_models": models,
    }


def _numeric_keys(row: Mapping[str, Any]) -> tuple[str, ...]:
    """The keys of a row averaged over seeds: its numbers (not its name or n)."""
    return tuple(
        k
        for k, v in row.items()
        if k not in ("row", "n") and isinstance(v, int | float) and not isinstance(v, bool)
    )


def _collect_task(task: tuple[str, list[Start] | None, int]) -> Any:
    """One behavior's demonstrations on the gripper robot (an executor task)."""
    from behavior_hmm.teach import collect

    behavior, starts, seed = task
    return collect(behavior, starts or None, env=gripper_env(), env_name=GRIPPER_ENV_ID, seed=seed)


def _test_starts(behavior: str, limit: int | None) -> list[Start]:
    from behavior_hmm.teach import test_starts

    starts = [dict(s) for s in test_starts(behavior)]
    return starts[:limit] if limit is not None else starts


def _seed_task(task: tuple[Any, ...]) -> dict[str, Any]:
    """One seed's models and their scores, or one seed's baseline (an executor task)."""
    part, datasets, seed, params, cblm_params, limit = task
    if part == "models":
        return _models_task(datasets, seed, params, cblm_params, limit)
    t0 = time.perf_counter()
    model = BASELINES[part](
        **{**dict(params or {}), "inputs": COMPOSED_INPUTS, "random_state": seed}
    ).fit(datasets[COMPOSED])
    train_s = time.perf_counter() - t0
    result = evaluate_on_gripper(model, _test_starts(COMPOSED, limit), seed=seed)
    return {"evaluation": result, "timings": {"train_s": train_s}}


def _models_task(
    datasets: Mapping[str, Any],
    seed: int,
    sblm_params: Mapping[str, Any] | None,
    cblm_params: Mapping[str, Any] | None,
    limit: int | None,
) -> dict[str, Any]:
    """Train the three SBLMs and the CBLM of one seed; score stages, hand-off, composed
    and nudged runs, and the teacher under the same nudges."""
    from behavior_hmm.models import CBLM, SBLM

    timings: dict[str, float] = {}
    models: dict[str, Any] = {}
    for behavior, inputs in STAGES:
        t0 = time.perf_counter()
        params = {**dict(sblm_params or {}), "inputs": inputs, "random_state": seed}
        models[behavior] = SBLM(**params).fit(datasets[behavior])
        timings[f"{behavior}_train_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    components = [models[b] for b, _ in STAGES]
    cblm = CBLM(components, **{**dict(cblm_params or {}), "inputs": COMPOSED_INPUTS}).fit(
        datasets[COMPOSED]
    )
    timings["cblm_train_s"] = time.perf_counter() - t0
    stages: dict[str, Any] = {}
    traces: dict[str, Any] = {}
    for behavior, _ in STAGES:
        result = evaluate_on_gripper(
            models[behavior], _test_starts(behavior, limit), seed=seed, keep_traces=True
        )
        traces[behavior] = result.pop("_traces")["model"]
        stages[behavior] = result
    starts = _test_starts(COMPOSED, limit)
    composed = evaluate_on_gripper(cblm, starts, seed=seed, keep_traces=True)
    composed_runs = composed.pop("_traces")["model"]
    handoffs = [
        {**handoff(trace, demo), "lifted": case["lifted"], "goal_reached": case["goal_reached"]}
        for (trace, demo), case in zip(composed_runs, composed["cases"], strict=True)
    ]
    nudges = draw_nudges(seed, len(starts))
    nudged = evaluate_on_gripper(cblm, starts, seed=seed, nudges=nudges, keep_traces=True)
    nudged_runs = nudged.pop("_traces")["model"]
    teacher = teacher_nudged(starts, nudges, seed)
    figures = {
        "composed": [
            _path(trace, case)
            for (trace, _), case in zip(composed_runs, composed["cases"], strict=True)
        ],
        "nudged": [
            _path(trace, case)
            for (trace, _), case in zip(nudged_runs, nudged["cases"], strict=True)
        ],
        "grasp": _gripper_series(traces["grasp"][0], stages["grasp"]["cases"][0]),
    }
    return {
        "stages": stages,
        "composed": composed,
        "handoff": {"cases": handoffs, **_handoff_counts(handoffs)},
        "nudges": nudges,
        "nudged": nudged,
        "teacher_nudged": teacher,
        "observations": int(cblm.observations_.n_categories_),
        "timings": timings,
        "_figures": figures,
        "_models": {**models, COMPOSED: cblm},
    }


def _handoff_counts(cases: Sequence[Mapping[str, Any]]) -> dict[str, int]:
    """Counts of the hand-off row: handed over, inside the region, lifted in and out."""
    return {
        "n": len(cases),
        "handed_over": sum(c["step"] is not None for c in cases),
        "in_region": sum(bool(c["in_region"]) for c in cases),
        "lifted_in_region": sum(bool(c["in_region"] and c["lifted"]) for c in cases),
        "lifted_out_of_region": sum(
            bool(c["step"] is not None and not c["in_region"] and c["lifted"]) for c in cases
        ),
        "teacher_in_region": sum(bool(c["teacher_in_region"]) for c in cases),
    }


def _path(trace: Any, case: Mapping[str, Any]) -> dict[str, Any]:
    """A run's top-down path (robot x, y in m; component per step) and the object's end."""
    pose = np.asarray(trace.pose_array, dtype=np.float64)
    return {
        "start": dict(case["start"]),
        "xy": pose[:, :2] if len(pose) else np.zeros((0, 2)),
        "component": list(trace.component)[: len(pose)],
        "object_end": case.get("object_end"),
        "lifted": bool(case.get("lifted", False)),
        "goal_reached": bool(case["goal_reached"]),
        "nudge": case.get("nudge"),
    }


def _gripper_series(run: tuple[Any, Mapping[str, Any]], case: Mapping[str, Any]) -> dict[str, Any]:
    """Arm (deg), fingers (m) and object_present over time (s): learned and teacher."""
    trace, demo = run
    names = ("arm", "fingers", "object_present")
    return {
        "start": dict(case["start"]),
        "lifted": bool(case["lifted"]),
        "success_rate": float(case["success_rate"]),
        "t": np.asarray(trace.t, dtype=np.float64),
        "generated": {c: np.asarray(trace.channel(c), dtype=np.float64) for c in names},
        "teacher_t": np.asarray(demo["t"], dtype=np.float64),
        "teacher": {c: np.asarray(demo[c], dtype=np.float64) for c in names},
    }


def _rows(entry: Mapping[str, Any], baselines: Sequence[str]) -> list[dict[str, Any]]:
    """The table's rows of one seed (same keys for every seed)."""
    rows: list[dict[str, Any]] = []
    for behavior, inputs in STAGES:
        ev = entry["stages"][behavior]
        rows.append(
            {
                "row": f"{behavior} {{{', '.join(inputs)}}}",
                "n": ev["n"],
                "goal_reached": ev["goal_reached"],
                "lifted": ev["lifted"],
                "success": ev["success_rate_mean"],
                "zero_floor": ev["zero_floor_mean"],
            }
        )
    hand = entry["handoff"]
    rows.append(
        {
            "row": "hand-off approach → grasp",
            **{k: v for k, v in hand.items() if k != "cases"},
        }
    )
    ev = entry["composed"]
    composed: dict[str, Any] = {
        "row": "turn → approach → grasp (CBLM)",
        "n": ev["n"],
        "goal_reached": ev["goal_reached"],
        "lifted": ev["lifted"],
        "success": ev["success_rate_mean"],
        "zero_floor": ev["zero_floor_mean"],
    }
    for name in baselines:
        key = name.replace("-", "_")
        base = entry["baselines"][name]["evaluation"]
        composed[key] = base["success_rate_mean"]
        composed[f"{key}_goal_reached"] = base["goal_reached"]
        composed[f"{key}_lifted"] = base["lifted"]
    rows.append(composed)
    ev = entry["nudged"]
    rows.append(
        {
            "row": "nudged 1-2 cm after the approach (CBLM)",
            "n": ev["n"],
            "goal_reached": ev["goal_reached"],
            "lifted": ev["lifted"],
            "nudged": ev["nudged"],
            "success": ev["success_rate_mean"],
            "zero_floor": ev["zero_floor_mean"],
            "teacher_lifted": entry["teacher_nudged"]["lifted"],
            "teacher_nudged": entry["teacher_nudged"]["nudged"],
        }
    )
    return rows


def check_targets(result: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Whether the issue's targets are met, on the first seed and on every seed.

    Returns
    -------
    dict
        Per target (``grasp``, ``composed``, ``nudged``): ``target`` (lifted of n),
        ``first_seed`` (lifted), ``per_seed`` (lifted per seed), ``met_first_seed`` and
        ``met_every_seed``.
    """
    where = {"grasp": 2, "composed": 4, "nudged": 5}
    out = {}
    for name, j in where.items():
        values = [int(rows[j]["lifted"]) for rows in result["rows"]]
        target = TARGETS[name]
        out[name] = {
            "target": target,
            "n": int(result["rows"][0][j]["n"]),
            "first_seed": values[0],
            "per_seed": values,
            "met_first_seed": values[0] >= target,
            "met_every_seed": all(v >= target for v in values),
        }
    return out
