"""Incremental learning measured as continual learning measures it (thesis 7.1, issue 29).

A *sequence* of tasks (default :data:`DEFAULT_SEQUENCE`: turn → approach → turn &
approach → retreat → position; ``grasp`` can be appended: it is collected and scored on
the gripper robot it needs, in MuJoCo, whatever ``sim`` the others use) is learned one
*stage* at a time: stage ``k`` learns task ``k`` from that task's demonstrations only.
After every stage each task learned so far is scored on its fixed shipped test starts
(:func:`behavior_hmm.teach.test_starts`) with the project's success rate
(:func:`behavior_hmm.evaluate.evaluate_model`, mean over the starts, %), giving the
matrix ``R[k, i]`` (row: after stage ``k``; column: task ``i``; ``NaN`` for ``i > k``).

The model after stage k
-----------------------
What task ``i <= k`` is evaluated with after stage ``k``, for the incremental learner:

* A **simple** task (no components: turn, approach, retreat) is one SBLM, fitted at its
  own stage on its own demonstrations and never changed afterwards. Once the growing
  CBLM (below) holds it as a component, the task is evaluated with that component, i.e.
  the object the CBLM runs (byte-identical to the SBLM fitted at its stage, which
  ``model_sha256`` records for every cell); before, with the SBLM itself.
* A **complex** task (turn & approach, position) is evaluated with the CBLM it was
  learned into, *as that CBLM is after stage k*. The first complex task creates the
  *growing CBLM*: ``CBLM(its components).fit(its demonstrations)``. A later complex task
  that needs exactly one component the growing CBLM lacks is learned into it with
  :meth:`CBLM.add_component` (new state, observation categories continued, counts
  added; no component retrained, earlier demonstrations not used). A complex task that
  needs no new component or several, or whose demonstrations the growing CBLM refuses
  (``ConfigError``), gets a CBLM of its own fitted on its demonstrations alone; nothing
  that exists changes then. ``how`` records which happened at every stage.

So forgetting can appear only where a later stage changes what an earlier task is
evaluated with: a complex task learned into the growing CBLM, after another complex task
joined it (default sequence: turn & approach after position joins). Simple tasks cannot
forget by construction, which every cell checks rather than assumes: each records the
SHA-256 of the model file it is evaluated with (``model_sha256``; for BC, of its weights
and step limit). A cell whose model is byte-identical to one already scored on that task
(in any scheme) takes that score, since an evaluation is deterministic given the model,
the starts and the seed; any other cell is evaluated (``evaluations``: runs and reuses).

Metrics (R in %, K stages; :func:`transfer_metrics`)
----------------------------------------------------
* ``ACC`` = mean over i of ``R[K, i]`` (the last row).
* ``BWT`` = mean over i < K of ``R[K, i] − R[i, i]`` (points; negative: forgetting).
* ``forgetting`` = mean over i < K of ``max_{i <= l < K} R[l, i] − R[K, i]`` (points;
  negative when tasks end above their best earlier score).
* ``FWT`` = mean over i = 2..K of ``R[i, i] − b_i``, where ``b_i`` is the score of a
  *reference trained alone*: the same learner fitted on task ``i``'s demonstrations only
  (a simple task's SBLM; a complex task's CBLM over its components, fitted on its
  demonstrations only; for the BC baseline, the same network trained from scratch on
  task ``i`` alone). Positive: learning earlier tasks helped task ``i``; negative: the
  model grown for them hurt it. Task 1 is left out (it is always learned alone). For
  the incremental learner a simple task, and a complex task that created its CBLM, *is*
  its reference (``b_i = R[i, i]``); only a complex task learned with ``add_component``
  has a reference trained and evaluated separately.

Baselines in the same run
-------------------------
* **Full refit** (the thesis's off-line scheme): at every stage every model is retrained
  from scratch on all demonstrations so far: one SBLM per simple task learned so far (on
  its own demonstrations) and, once a complex task is learned, one CBLM over every
  component the complex tasks so far need, fitted on all their demonstrations together
  (their nominal episodes, renumbered). Every complex task is evaluated with that CBLM.
  Its wall time per stage is all of that training.
* **BC-strong fine-tuned stage by stage** (:class:`StrongBehaviorCloning`, what a user
  of a monolithic network would do): one network for every task, reading
  ``BC_INPUTS`` (distance, angle) and the goal (angle and distance where each
  demonstration ends; BC's goal input, there is no task input: the goal is the only
  thing that tells tasks apart). Stage 1 trains it as BC-strong trains (architecture,
  Adam, epochs, patience, window noise), except that the command scale is fixed to the
  robot's top wheel speed (``metadata["robot"]["max_wheel_speed"]``, 10 rad/s) instead
  of the first task's largest command, so that later tasks' faster commands are not
  clipped. Stage ``k > 1`` fine-tunes the same weights on task ``k``'s demonstrations
  only (:meth:`MotionGenerators.partial_fit`: BC-strong's epochs and early stopping on a
  held-out 20 % of the new episodes, the best epoch's weights kept). Task ``i`` is run
  toward its behavior's goal (:class:`BehaviorSpec` ``goal``, the channels it leaves out
  from its ``start_defaults``: turn holds 0.5 m, approach and retreat face the object;
  position's per-start goal distance as given).

Times (``timings``, wall seconds of training only, no collection or evaluation): the
incremental learner's stage ``k`` is the one fit / ``add_component`` of task ``k``; the
full refit's, everything it retrains; BC's, the stage's (fine-)tuning. CobART's compiled
kernels (the ``fast`` extra) are loaded, or compiled, before any stage is timed
(``kernels_s``), so neither scheme's first fit pays for it.
"""

from __future__ import annotations

import copy
import hashlib
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.cobart._compiled import warm as warm_cobart_kernels
from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate._grasp import STAGES as GRASP_STAGES

Progress = Callable[[int, int], None]
FloatArray = NDArray[np.float64]
Start = dict[str, float]

#: Our robot's behaviors in the order issue 29 learns them (then grasp, with ``--task``).
DEFAULT_SEQUENCE: Final[tuple[str, ...]] = (
    "turn",
    "approach",
    "turn-approach",
    "retreat",
    "position",
)

#: Inputs of each simple task's SBLM: the thesis's best (as ``experiment complex``).
SIMPLE_INPUTS: Final[dict[str, tuple[str, ...]]] = {
    "turn": ("angle",),
    "approach": ("distance", "angle"),
    "retreat": ("distance", "angle"),
    "grasp": dict(GRASP_STAGES)["grasp"],  # on the gripper robot, as experiment grasp
}

#: Inputs of the CBLMs' own observation categories (as ``experiment complex``).
CBLM_INPUTS: Final[tuple[str, ...]] = ("distance", "angle")

#: Inputs of the one fine-tuned BC-strong network (every task's channels).
BC_INPUTS: Final[tuple[str, ...]] = ("distance", "angle")

#: The schemes compared, in table order.
SCHEMES: Final[tuple[str, ...]] = ("incremental", "full_refit", "bc_strong_finetuned")


# ----------------------------------------------------------------------- metrics
def _checked_matrix(r: Any) -> FloatArray:
    """``R`` as a square float array with every cell on or below the diagonal finite."""
    m = np.asarray(r, dtype=np.float64)
    if m.ndim != 2 or m.shape[0] != m.shape[1] or m.shape[0] == 0:
        raise ConfigError(f"R must be a non-empty square matrix, got shape {m.shape}")
    if not np.all(np.isfinite(m[np.tril_indices(m.shape[0])])):
        raise ConfigError("R must be finite on and below its diagonal")
    return m


def accuracy(r: Any) -> float:
    """ACC: mean of the last row of ``R`` (%), every task after the last stage.

    Parameters
    ----------
    r
        Success matrix ``R[k, i]`` (%), shape (K, K); cells above the diagonal ignored.
    """
    m = _checked_matrix(r)
    return float(np.mean(m[-1]))


def backward_transfer(r: Any) -> float:
    """BWT: mean over i < K of ``R[K, i] − R[i, i]`` (points; 0 for a single task).

    Parameters
    ----------
    r
        Success matrix ``R[k, i]`` (%), shape (K, K).
    """
    m = _checked_matrix(r)
    k = m.shape[0]
    if k == 1:
        return 0.0
    return float(np.mean([m[-1, i] - m[i, i] for i in range(k - 1)]))


def forgetting(r: Any) -> float:
    """Mean over i < K of ``max_{i <= l < K} R[l, i] − R[K, i]`` (points; 0 for one task).

    Parameters
    ----------
    r
        Success matrix ``R[k, i]`` (%), shape (K, K).
    """
    m = _checked_matrix(r)
    k = m.shape[0]
    if k == 1:
        return 0.0
    return float(np.mean([np.max(m[i : k - 1, i]) - m[-1, i] for i in range(k - 1)]))


def forward_transfer(r: Any, reference: Sequence[float]) -> float:
    """FWT: mean over i = 2..K of ``R[i, i] − b_i`` (points; 0 for a single task).

    Parameters
    ----------
    r
        Success matrix ``R[k, i]`` (%), shape (K, K).
    reference
        ``b_i``: task i's score (%) with the same learner trained on task i alone.
    """
    m = _checked_matrix(r)
    b = np.asarray(reference, dtype=np.float64)
    if b.shape != (m.shape[0],):
        raise ConfigError(f"reference must hold one score per task ({m.shape[0]})")
    if m.shape[0] == 1:
        return 0.0
    return float(np.mean(np.diag(m)[1:] - b[1:]))


def transfer_metrics(r: Any, reference: Sequence[float] | None = None) -> dict[str, Any]:
    """ACC, BWT, forgetting, FWT (when ``reference`` is given) and per-task details.

    Returns
    -------
    dict
        ``acc`` (%), ``bwt``, ``forgetting``, ``fwt`` (points; ``None`` without a
        reference), ``worst_drop`` (points: the most negative ``R[K, i] − R[i, i]``
        over i < K, 0 for one task), ``drop`` (that difference per task, the last 0) and
        ``diagonal`` (``R[i, i]``, each task when learned).
    """
    m = _checked_matrix(r)
    drops = [float(m[-1, i] - m[i, i]) for i in range(m.shape[0])]
    return {
        "acc": accuracy(m),
        "bwt": backward_transfer(m),
        "forgetting": forgetting(m),
        "fwt": None if reference is None else forward_transfer(m, reference),
        "worst_drop": float(min(drops[:-1])) if len(drops) > 1 else 0.0,
        "drop": drops,
        "diagonal": np.diag(m).tolist(),
    }


# ------------------------------------------------------------------- sequences
def task_kind(task: str) -> str:
    """``"complex"`` for a behavior composed of components, else ``"simple"``."""
    from behavior_hmm.teach import behavior_spec

    return "complex" if behavior_spec(task).components else "simple"


def check_sequence(
    sequence: Sequence[str],
    inputs: Mapping[str, Sequence[str]] | None = None,
    bc: bool = False,
) -> tuple[str, ...]:
    """Refuse a sequence that cannot be learned in order (ConfigError), before any work.

    Tasks must be registered behaviors, each once; a complex task's components must be
    learned at earlier stages; a simple task needs its SBLM's inputs (``inputs`` or
    :data:`SIMPLE_INPUTS`). With ``bc``, every task must run on our Khepera: the one
    fine-tuned BC-strong network reads :data:`BC_INPUTS`, which a task on another robot
    (grasp, on the gripper robot) does not act on.
    """
    from behavior_hmm.teach import behavior_spec

    tasks = tuple(sequence)
    if not tasks:
        raise ConfigError("the sequence needs at least one task")
    seen: list[str] = []
    table = {**SIMPLE_INPUTS, **dict(inputs or {})}
    for task in tasks:
        spec = behavior_spec(task)  # ConfigError for an unknown behavior
        if task in seen:
            raise ConfigError(f"task '{task}' appears twice in the sequence")
        missing = [c for c in spec.components if c not in seen]
        if missing:
            raise ConfigError(
                f"task '{task}' is composed of {', '.join(spec.components)}; "
                f"learn {', '.join(missing)} at an earlier stage"
            )
        if not spec.components and task not in table:
            raise ConfigError(f"no SBLM inputs for simple task '{task}'; give inputs={{...}}")
        if bc and spec.env is not None:
            raise ConfigError(
                f"task '{task}' runs on {spec.env}, and the fine-tuned BC-strong network reads "
                f"only {', '.join(BC_INPUTS)}: leave BC out (--no-bc)"
            )
        seen.append(task)
    return tasks


# ------------------------------------------------------------------- experiment
def run_incremental_experiment(
    *,
    sim: str = "mujoco",
    seed: int = 0,
    sequence: Sequence[str] = DEFAULT_SEQUENCE,
    sblm_params: Mapping[str, Any] | None = None,
    cblm_params: Mapping[str, Any] | None = None,
    inputs: Mapping[str, Sequence[str]] | None = None,
    starts: Mapping[str, Sequence[Mapping[str, float]]] | None = None,
    test_starts: Mapping[str, Sequence[Mapping[str, float]]] | None = None,
    bc: bool = True,
    bc_params: Mapping[str, Any] | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """Learn ``sequence`` stage by stage three ways and score every task after every stage.

    Parameters
    ----------
    sim
        Simulator of the demonstrations and the evaluations (``mujoco``, ``kinematic``).
    seed
        Seed of every random draw: the demonstrations (``collect``), every model's
        ``random_state``, BC's window noise and the evaluations (case ``i``: seed + i).
    sequence
        Task names in learning order (registered behaviors; see :func:`check_sequence`).
    sblm_params, cblm_params
        SBLM and CBLM constructor parameters (a preset's), for every model of every scheme.
    inputs
        SBLM inputs per simple task, over :data:`SIMPLE_INPUTS`.
    starts
        Training starts per task (default: the behavior's default grid).
    test_starts
        Test starts per task (default: the shipped ones).
    bc
        Also run BC-strong fine-tuned stage by stage.
    bc_params
        Overrides of :class:`StrongBehaviorCloning`'s parameters (e.g. ``epochs``).
    progress
        Called as ``progress(done, total)`` after each collection, training and evaluation.

    Returns
    -------
    dict
        ``sim``, ``seed``, ``sequence``, ``kinds``; ``schemes``: per scheme (``SCHEMES``)
        ``R`` (list of rows, ``None`` above the diagonal), ``goals`` (goals reached, same
        layout), ``n`` (test starts per task), ``how`` (what each stage did),
        ``model_sha256`` (per cell: SHA-256 of the model file the cell was evaluated
        with; BC: of its weights), ``reference`` (``b_i``, %) and ``metrics``
        (:func:`transfer_metrics`); ``growing_components`` (the incremental CBLM's
        components after each stage); ``timings`` (wall seconds: ``collect_s``, and per
        scheme ``<scheme>_s`` per stage). Everything but the timings is the same for the
        same arguments.
    """
    from behavior_hmm.teach import collect

    tasks = check_sequence(sequence, inputs, bc)
    table = {**SIMPLE_INPUTS, **{k: tuple(v) for k, v in dict(inputs or {}).items()}}
    kinds = {t: task_kind(t) for t in tasks}
    n = len(tasks)
    schemes = [s for s in SCHEMES if bc or s != "bc_strong_finetuned"]
    cells = n * (n + 1) // 2
    complex_at = [k for k, t in enumerate(tasks) if kinds[t] == "complex"]
    later = max(0, len(complex_at) - 1)  # complex tasks that may need a reference each
    total = n + len(schemes) * (n + cells) + 2 * later + (n - 1 if bc else 0)
    done = 0

    def tick() -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total)

    t0 = time.perf_counter()
    data = {}
    for task in tasks:
        given = (starts or {}).get(task)
        data[task] = collect(
            task, None if given is None else [dict(s) for s in given], sim=sim, seed=seed
        )
        tick()
    collect_s = time.perf_counter() - t0
    tests = {t: [dict(s) for s in (test_starts or {}).get(t) or _shipped_starts(t)] for t in tasks}
    context = _Context(
        tasks=tasks,
        kinds=kinds,
        inputs=table,
        data=data,
        tests=tests,
        sim=sim,
        seed=seed,
        sblm_params=dict(sblm_params or {}),
        cblm_params=dict(cblm_params or {}),
        bc_params=dict(bc_params or {}),
        tick=tick,
    )
    results: dict[str, Any] = {
        "sim": sim,
        "seed": seed,
        "sequence": list(tasks),
        "kinds": kinds,
        "n_demonstrations": {t: len(data[t]) for t in tasks},
        "n_rows": {t: int(data[t].n_samples) for t in tasks},
        "schemes": {},
    }
    t0 = time.perf_counter()
    warm_cobart_kernels()  # compiled once per machine: not the first scheme's training time
    timings: dict[str, Any] = {"collect_s": collect_s, "kernels_s": time.perf_counter() - t0}
    incremental = _Incremental(context)
    runs: dict[str, _Scheme] = {"incremental": incremental, "full_refit": _FullRefit(context)}
    if bc:
        runs["bc_strong_finetuned"] = _FineTunedBC(context)
    seconds: dict[str, list[float]] = {s: [] for s in schemes}
    # stage by stage, each scheme in turn: their times are taken under the same load
    for k in range(n):
        for scheme, run in runs.items():
            t1 = time.perf_counter()
            run.learn(k)
            seconds[scheme].append(time.perf_counter() - t1)
            tick()
            run.evaluate_row(k)
    for scheme, run in runs.items():
        outcome = run.outcome()
        outcome["metrics"] = transfer_metrics(outcome["R"], outcome["reference"])
        outcome["R"] = _jsonable(outcome["R"])
        outcome["goals"] = _jsonable(outcome["goals"])
        results["schemes"][scheme] = outcome
        timings[f"{scheme}_s"] = seconds[scheme]
    results["growing_components"] = incremental.components_after
    results["evaluations"] = {"run": context.evaluations, "reused": context.reused}
    results["timings"] = timings
    if progress is not None:
        progress(total, total)
    return results


def _shipped_starts(task: str) -> list[Start]:
    from behavior_hmm.teach import test_starts

    return test_starts(task)


class _Context:
    """What every scheme shares: the sequence, its data, starts and parameters."""

    def __init__(
        self,
        *,
        tasks: tuple[str, ...],
        kinds: dict[str, str],
        inputs: dict[str, tuple[str, ...]],
        data: dict[str, Any],
        tests: dict[str, list[Start]],
        sim: str,
        seed: int,
        sblm_params: dict[str, Any],
        cblm_params: dict[str, Any],
        bc_params: dict[str, Any],
        tick: Callable[[], None],
    ) -> None:
        self.tasks = tasks
        self.kinds = kinds
        self.inputs = inputs
        self.data = data
        self.tests = tests
        self.sim = sim
        self.seed = seed
        self.sblm_params = sblm_params
        self.cblm_params = cblm_params
        self.bc_params = bc_params
        self.tick = tick
        self.scores: dict[tuple[str, str], tuple[float, int]] = {}
        self.evaluations = 0
        self.reused = 0

    def sblm(self, task: str) -> Any:
        """A new SBLM of the simple ``task``, fitted on its demonstrations."""
        from behavior_hmm.models import SBLM

        params = {**self.sblm_params, "inputs": self.inputs[task], "random_state": self.seed}
        return SBLM(**params).fit(self.data[task])

    def cblm(self, components: Sequence[Any], dataset: Any) -> Any:
        """A new CBLM over ``components``, fitted on ``dataset``."""
        from behavior_hmm.models import CBLM

        params = {**self.cblm_params, "inputs": CBLM_INPUTS, "random_state": self.seed}
        return CBLM(list(components), **params).fit(dataset)

    def score(self, model: Any, task: str, digest: str | None = None) -> tuple[float, int]:
        """Success rate (%) and goals reached of ``model`` on ``task``'s test starts.

        With ``digest`` (the model's :func:`_model_sha256`), a model byte-identical to
        one already scored on ``task`` takes that score: the evaluation is deterministic
        given the model, the starts and the seed (``evaluations`` counts the runs).
        """
        from behavior_hmm.evaluate._protocol import evaluate_model

        key = None if digest is None else (digest, task)
        if key is not None and key in self.scores:
            self.reused += 1
        else:
            robot = self._robot(task)
            try:
                result = evaluate_model(
                    _as_task(model, task), self.tests[task], seed=self.seed, **robot
                )
            finally:
                if "env" in robot:
                    robot["env"].close()
            self.evaluations += 1
            outcome = (float(result["success_rate_mean"]), int(result["goal_reached"]))
            if key is None:
                self.tick()
                return outcome
            self.scores[key] = outcome
        self.tick()
        return self.scores[key]

    def _robot(self, task: str) -> dict[str, Any]:
        """Where ``task`` runs: the sequence's simulator, or the robot its behavior needs
        (grasp: the gripper robot, which also runs the teacher's references)."""
        from behavior_hmm.runtime import make_robot_env
        from behavior_hmm.teach import behavior_spec

        spec = behavior_spec(task)
        if spec.env is None:
            return {"sim": self.sim}
        return {"sim": None, "env": make_robot_env(spec.env)}


def _as_task(model: Any, task: str) -> Any:
    """``model`` scored as ``task``: a shallow copy whose ``behavior_`` (the teacher whose
    reference runs it is scored against) is the task's; nothing else differs, except that
    a complex task runs toward its own declared goal (``default_goal_``): a CBLM fitted on
    several tasks' demonstrations takes its default goal from the first dataset's, so
    turn & approach refitted after position would otherwise stop at position's 0.5 m."""
    from behavior_hmm.teach import behavior_spec

    view = copy.copy(model)
    view.behavior_ = task
    spec = behavior_spec(task)
    own = getattr(model, "default_goal_", None)
    if spec.components and own is not None:
        view.default_goal_ = {c: float(spec.goal.get(c, v)) for c, v in own.items()}
    return view


class _Scheme:
    """One way of learning the sequence: ``learn(k)`` learns stage ``k``; ``model(name)``
    is what task ``name`` is evaluated with now; ``digest(model)`` identifies it."""

    def __init__(self, ctx: _Context) -> None:
        self.ctx = ctx
        n = len(ctx.tasks)
        self.r = np.full((n, n), np.nan)
        self.goals = np.full((n, n), -1, dtype=np.int64)
        self.hashes: list[list[str | None]] = [[None] * n for _ in range(n)]
        self.how: list[str] = []

    def learn(self, k: int) -> None:
        raise NotImplementedError

    def _reference_alone(
        self, sblms: Mapping[str, Any], shared: Callable[[int, str], bool]
    ) -> tuple[list[float], list[str]]:
        """FWT's reference: each task's own score (the diagonal), except a complex task
        the scheme learned together with others (``shared(i, name)``): a CBLM over its
        components (``sblms``) fitted on its demonstrations alone, scored."""
        from behavior_hmm.teach import behavior_spec

        ctx = self.ctx
        reference = np.diag(self.r).copy()
        how = []
        for i, name in enumerate(ctx.tasks):
            if shared(i, name):
                parts = [sblms[c] for c in behavior_spec(name).components]
                reference[i] = ctx.score(ctx.cblm(parts, ctx.data[name]), name)[0]
                how.append("CBLM over its components fit on its demonstrations alone")
            else:
                how.append("the stage's own model (trained alone)")
        return reference.tolist(), how

    def model(self, name: str) -> Any:
        raise NotImplementedError

    def digest(self, model: Any) -> str:
        return _model_sha256(model)

    def evaluate_row(self, k: int) -> None:
        """Score every task learned so far (row ``k`` of R)."""
        for i, name in enumerate(self.ctx.tasks[: k + 1]):
            model = self.model(name)
            digest = self.digest(model)
            self.r[k, i], self.goals[k, i] = self.ctx.score(model, name, digest)
            self.hashes[k][i] = digest

    def reference(self) -> tuple[list[float], list[str]]:
        """``b_i`` (%) and how each was obtained, after the last stage."""
        raise NotImplementedError

    def outcome(self) -> dict[str, Any]:
        reference, how = self.reference()
        return {
            "R": self.r,
            "goals": self.goals,
            "n": [len(self.ctx.tests[t]) for t in self.ctx.tasks],
            "how": self.how,
            "model_sha256": self.hashes,
            "reference": reference,
            "reference_how": how,
        }


class _Incremental(_Scheme):
    """The incremental learner (module docstring)."""

    def __init__(self, ctx: _Context) -> None:
        super().__init__(ctx)
        self.sblms: dict[str, Any] = {}
        self.home: dict[str, Any] = {}  # complex task -> the CBLM it was learned into
        self.growing: Any = None
        self.grown_by_add: list[bool] = []
        self.components_after: list[list[str]] = []

    def learn(self, k: int) -> None:
        from behavior_hmm.teach import behavior_spec

        ctx, task = self.ctx, self.ctx.tasks[k]
        via_add = False
        if ctx.kinds[task] == "simple":
            self.sblms[task] = ctx.sblm(task)
            self.how.append("SBLM fit on its demonstrations")
        else:
            needed = list(behavior_spec(task).components)
            parts = [self.sblms[c] for c in needed]
            if self.growing is None:
                self.growing = self.home[task] = ctx.cblm(parts, ctx.data[task])
                self.how.append(f"growing CBLM{{{', '.join(needed)}}} fit on its demonstrations")
            else:
                new = [c for c in needed if c not in self.growing.names_]
                reason = f"{len(new)} new components"
                if len(new) == 1:
                    try:
                        self.growing.add_component(self.sblms[new[0]], ctx.data[task])
                    except ConfigError as err:
                        reason = f"add_component refused: {err}"
                    else:
                        self.home[task] = self.growing
                        via_add = True
                        self.how.append(f"add_component({new[0]}) to the growing CBLM")
                if not via_add:
                    self.home[task] = ctx.cblm(parts, ctx.data[task])
                    self.how.append(f"own CBLM{{{', '.join(needed)}}} fit ({reason})")
        self.grown_by_add.append(via_add)
        self.components_after.append(list(self.growing.names_) if self.growing else [])

    def model(self, name: str) -> Any:
        if self.ctx.kinds[name] == "complex":
            return self.home[name]
        if self.growing is not None and name in self.growing.names_:
            return self.growing.components_[self.growing.names_.index(name)]
        return self.sblms[name]

    def reference(self) -> tuple[list[float], list[str]]:
        return self._reference_alone(self.sblms, lambda i, _: bool(self.grown_by_add[i]))


class _FullRefit(_Scheme):
    """The thesis's scheme: every model retrained from all demonstrations so far."""

    def __init__(self, ctx: _Context) -> None:
        super().__init__(ctx)
        self.sblms: dict[str, Any] = {}
        self.cblm: Any = None

    def learn(self, k: int) -> None:
        from behavior_hmm.teach import behavior_spec

        ctx = self.ctx
        so_far = ctx.tasks[: k + 1]
        self.sblms = {t: ctx.sblm(t) for t in so_far if ctx.kinds[t] == "simple"}
        complex_tasks = [t for t in so_far if ctx.kinds[t] == "complex"]
        names: list[str] = []
        self.cblm = None
        if complex_tasks:
            for t in complex_tasks:
                names += [c for c in behavior_spec(t).components if c not in names]
            dataset = _concatenated([ctx.data[t] for t in complex_tasks], ctx.tasks[k])
            self.cblm = ctx.cblm([self.sblms[c] for c in names], dataset)
        what = f"{len(self.sblms)} SBLM(s)"
        if self.cblm is not None:
            what += f" + CBLM{{{', '.join(names)}}} on {', '.join(complex_tasks)}"
        self.how.append(f"refit {what}")

    def model(self, name: str) -> Any:
        return self.cblm if self.ctx.kinds[name] == "complex" else self.sblms[name]

    def reference(self) -> tuple[list[float], list[str]]:
        kinds = self.ctx.kinds

        def shared(i: int, name: str) -> bool:  # learned with earlier complex tasks
            earlier = [t for t in self.ctx.tasks[:i] if kinds[t] == "complex"]
            return kinds[name] == "complex" and bool(earlier)

        # the refit SBLMs are those trained alone (same data, same seed)
        return self._reference_alone(self.sblms, shared)


class _FineTunedBC(_Scheme):
    """One BC-strong network fine-tuned stage by stage (module docstring)."""

    def __init__(self, ctx: _Context) -> None:
        super().__init__(ctx)
        self.net: Any = None

    def learn(self, k: int) -> None:
        ctx, task = self.ctx, self.ctx.tasks[k]
        if self.net is None:
            self.net = _bc_start(ctx.data[task], ctx.seed, ctx.bc_params)
            self.how.append("BC-strong trained on its demonstrations")
        else:
            _bc_finetune(self.net, ctx.data[task], ctx.seed, k + 1)
            self.how.append("BC-strong fine-tuned on its demonstrations")

    def model(self, name: str) -> Any:
        return _bc_for_task(self.net, name)

    def digest(self, model: Any) -> str:
        return _weights_sha256(model)

    def reference(self) -> tuple[list[float], list[str]]:
        ctx = self.ctx
        reference = np.diag(self.r).copy()
        how = ["the stage's own network (trained alone)"]
        for i, name in enumerate(ctx.tasks[1:], start=1):
            alone = _bc_start(ctx.data[name], ctx.seed, ctx.bc_params)
            reference[i] = ctx.score(_bc_for_task(alone, name), name)[0]
            how.append("BC-strong trained on its demonstrations alone")
        return reference.tolist(), how

    def outcome(self) -> dict[str, Any]:
        return {**super().outcome(), "inputs": list(BC_INPUTS)}


def _concatenated(datasets: Sequence[Any], behavior: str) -> Any:
    """The nominal episodes of ``datasets`` as one dataset, renumbered 0..n-1 (one
    dataset: itself, whose corrective episodes the CBLM leaves out on its own)."""
    from behavior_hmm.models._sblm import nominal_episodes

    if len(datasets) == 1:
        return datasets[0]
    parts = []
    for dataset in datasets:
        keep = nominal_episodes(dataset)
        parts.append(dataset if keep.all() else dataset.subset(np.flatnonzero(keep)))
    meta = {k: v for k, v in parts[0].metadata.items() if k != "corrective_episodes"}
    meta["behavior"] = behavior
    out = parts[0]
    for part in parts[1:]:
        out = out.concat(part, renumber=True, metadata=meta)
    return out


# ---------------------------------------------------------------------- BC-strong
def _bc_start(
    dataset: Any,
    seed: int,
    params: Mapping[str, Any],
    *,
    inputs: Sequence[str] = BC_INPUTS,
    goal: Mapping[str, float] | None = None,
    top: float | None = None,
) -> Any:
    """BC-strong trained on ``dataset`` as its ``fit`` trains, the command scale fixed.

    Parameters
    ----------
    dataset, seed, params
        The first task's demonstrations, the seed and BC-strong's parameter overrides.
    inputs
        Input channels; BC's goal input is where each demonstration ends on ``goal``'s
        channels.
    goal
        The default goal (channel -> value); default angle 0, distance 0 (our robot).
    top
        Command scale for every command channel (command units): what the robot can
        command at most, so that a later task's faster commands are not clipped.
        Default: the robot's top wheel speed (rad/s), else the largest command.
    """
    from behavior_hmm.data import SignalPipeline
    from behavior_hmm.evaluate._baselines import StrongBehaviorCloning
    from behavior_hmm.models._sblm import without_unseen_corrections

    inputs = tuple(inputs)
    goal = dict(goal or {"angle": 0.0, "distance": 0.0})
    bc = StrongBehaviorCloning(**{**dict(params), "inputs": inputs, "random_state": seed})
    dataset = without_unseen_corrections(dataset, inputs)
    specs = {spec.name: spec for spec in getattr(dataset, "channel_specs", ())}
    bc.channels_ = {c: specs[c] for c in inputs if c in specs}
    bc.inputs_ = inputs
    bc.goal_channels_ = tuple(goal)
    bc.command_specs_ = tuple(dataset.command_specs)
    if top is None:
        robot = dataset.metadata.get("robot") or {}
        top = float(robot.get("max_wheel_speed") or np.max(np.abs(dataset.commands)))
    bc.command_scale_ = float(top)
    bc.command_scales_ = np.full(len(bc.command_specs_) or 2, float(top))
    bc.pipeline_ = SignalPipeline.for_dataset(dataset, inputs, bc.cutoff_hz)
    features, targets, groups = _bc_rows(bc, dataset, np.random.default_rng(seed))
    bc.network_ = bc._network(len(inputs)).fit(features, targets, None, groups=groups)
    bc.default_goal_ = {c: float(v) for c, v in goal.items()}
    bc.max_steps_ = int(max(500, 2 * int(dataset.lengths.max())))
    bc.behavior_ = str(dataset.metadata.get("behavior", "behavior"))
    return bc


def _bc_finetune(bc: Any, dataset: Any, seed: int, stage: int) -> None:
    """Fine-tune ``bc``'s network from its weights on ``dataset`` alone (stage >= 2)."""
    from behavior_hmm.models._sblm import without_unseen_corrections

    dataset = without_unseen_corrections(dataset, bc.inputs_)
    features, targets, groups = _bc_rows(bc, dataset, np.random.default_rng([seed, stage]))
    primitive = np.zeros(len(features), dtype=np.int64)
    bc.network_.partial_fit(features, targets, primitive, groups=groups, update=stage - 1)
    bc.max_steps_ = int(max(bc.max_steps_, 2 * int(dataset.lengths.max())))


def _bc_rows(bc: Any, dataset: Any, rng: np.random.Generator) -> tuple[FloatArray, ...]:
    """Training rows as :meth:`BehaviorCloning.fit` builds them (goal: where each
    demonstration ends; commands over the fixed scale, clipped to ±1), with the
    window-shifted copies when ``window_noise`` > 0."""
    from behavior_hmm.generators._features import shifted_windows

    x = bc.pipeline_.transform(dataset)
    lengths = dataset.lengths
    finals = dataset.offsets[1:] - 1
    cols = [bc.inputs_.index(c) for c in bc.goal_channels_]
    goals = np.repeat(x[finals][:, cols], lengths, axis=0)
    y = np.clip(np.asarray(dataset.commands, dtype=np.float64) / bc.command_scales_, -1.0, 1.0)
    features = bc.feature_layout().offline(x, y, lengths, goals)
    groups = np.repeat(dataset.episode_ids, lengths)
    targets = y
    if bc.window_noise > 0:
        noisy = shifted_windows(features, len(bc.inputs_), bc.window, bc.window_noise, rng)
        features = np.vstack([features, noisy])
        targets = np.vstack([y, y])
        groups = np.concatenate([groups, groups])
    return features, targets, groups


def _bc_for_task(bc: Any, task: str) -> Any:
    """The network run toward ``task``'s goal (module docstring) and scored as ``task``."""
    from behavior_hmm.teach import behavior_spec

    spec = behavior_spec(task)
    goal = {
        c: float(spec.goal[c]) if c in spec.goal else float(spec.start_defaults.get(c, 0.0))
        for c in bc.goal_channels_
    }
    view = _as_task(bc, task)
    view.default_goal_ = goal
    return view


# ----------------------------------------------------------------------- helpers
def _model_file(model: Any) -> bytes:
    """The bytes of the file ``model.save`` writes (a CBLM embeds its components' files)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.bhmm"
        model.save(path)
        return path.read_bytes()


def _model_sha256(model: Any) -> str:
    """SHA-256 of the file ``model.save`` writes (a CBLM embeds its components' files)."""
    return hashlib.sha256(_model_file(model)).hexdigest()


def _weights_sha256(bc: Any) -> str:
    """SHA-256 of a BC network's weights and biases and its step limit."""
    digest = hashlib.sha256(str(bc.max_steps_).encode())
    for array in (*bc.network_.coefs_, *bc.network_.intercepts_):
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()


def _jsonable(matrix: Any) -> list[list[Any]]:
    """A matrix as lists, ``None`` above the diagonal (never learned yet)."""
    m = np.asarray(matrix)
    rows: list[list[Any]] = []
    for k in range(m.shape[0]):
        row: list[Any] = []
        for i in range(m.shape[1]):
            value = m[k, i].item()
            row.append(None if i > k else value)
        rows.append(row)
    return rows


def matrix(rows: Sequence[Sequence[Any]]) -> FloatArray:
    """A results.json ``R`` (``None`` above the diagonal) as a float array with NaN."""
    return np.array([[np.nan if v is None else float(v) for v in row] for row in rows])


# ----------------------------------------------------------------------- targets
#: Issue 29's targets: BWT at least this (points), ...
TARGET_BWT: Final[float] = -0.5
#: ... each new task at most this many points below a full refit's score, ...
TARGET_NEW_TASK_GAP: Final[float] = 1.0
#: ... in at most this share of the full refit's training time.
TARGET_TIME_SHARE: Final[float] = 1.0 / 3.0


def check_targets(results: Mapping[str, Any]) -> dict[str, Any]:
    """Issue 29's targets on a run: BWT, new tasks against a full refit, time.

    Returns
    -------
    dict
        ``bwt`` (points) and ``worst_drop`` (points, the largest loss of one earlier
        task) with ``bwt_met`` (BWT >= ``TARGET_BWT``); ``new_task_gap`` per stage
        (``R_inc[k, k] − R_refit[k, k]``, points) with ``new_task_met`` (every gap >=
        −``TARGET_NEW_TASK_GAP``); with ``timings``: ``time_share`` (incremental over full
        refit training seconds, summed over the stages), ``median_s`` per scheme
        (seconds per stage), ``time_share_per_stage`` and ``time_met`` (``time_share`` <=
        ``TARGET_TIME_SHARE``); ``time_met`` is ``None`` without timings.
    """
    inc = results["schemes"]["incremental"]
    refit = results["schemes"]["full_refit"]
    r_inc, r_refit = matrix(inc["R"]), matrix(refit["R"])
    gaps = (np.diag(r_inc) - np.diag(r_refit)).tolist()
    out: dict[str, Any] = {
        "bwt": inc["metrics"]["bwt"],
        "worst_drop": inc["metrics"]["worst_drop"],
        "bwt_met": bool(inc["metrics"]["bwt"] >= TARGET_BWT),
        "new_task_gap": gaps,
        "new_task_met": bool(min(gaps) >= -TARGET_NEW_TASK_GAP),
        "time_share": None,
        "time_met": None,
    }
    timings = results.get("timings") or {}
    if "incremental_s" in timings and "full_refit_s" in timings:
        a = np.asarray(timings["incremental_s"], dtype=np.float64)
        b = np.asarray(timings["full_refit_s"], dtype=np.float64)
        share = float(a.sum() / b.sum())
        out["time_share"] = share
        out["time_share_per_stage"] = (a / b).tolist()
        out["median_s"] = {
            s: float(np.median(timings[f"{s}_s"])) for s in SCHEMES if f"{s}_s" in timings
        }
        out["time_met"] = bool(share <= TARGET_TIME_SHARE)
    return out
