"""Thesis §6.2 and appendix A: learning rate, momentum and hidden-layout sweeps of one generator.

The thesis trained one primitive's network (the turn behavior's, 80/20 split,
incremental backpropagation, tanh, weights in [-1, 1]) under different settings
and plotted test error against training iteration (figures 6.5-6.7, and A.1 for
two-input networks). Training is incremental, one weight update per sample, so an
iteration is one training sample presented; the test error is measured after
every epoch (every ``n_train`` iterations) and once before training. The primitive
is a representative one (:func:`representative_primitive`): one where the robot
moves and its commands change, not the near-rest primitive that has the most
samples. Every setting starts from the same split and the same sample order;
settings with the same layer sizes also share their initial weights. Settings
with the same hidden layout train together as one stack; the stacks are independent
tasks of the project's executor (``experiment generators --workers N``).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from behavior_hmm._atomic import atomic_write_bytes
from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate._executor import Executor, Progress, SerialExecutor
from behavior_hmm.generators._mlp import layer_views, rms_error, train_stack, with_ones
from behavior_hmm.generators._motion import (
    _check_fit_inputs,
    init_weights,
    primitive_rng,
    split_rows,
)

#: Thesis §6.2 settings (figures 6.5, 6.6, 6.7).
THESIS_LEARNING_RATES: tuple[float, ...] = (0.001, 0.01, 0.1, 0.5)
THESIS_MOMENTA: tuple[float, ...] = (0.0, 0.2, 0.4, 0.6, 0.8)
THESIS_HIDDEN_LAYOUTS: tuple[tuple[int, ...], ...] = ((5,), (10,), (15,), (5, 5))
#: Thesis appendix A (figure A.1): two-input networks, layouts up to 2 layers x 20 units.
THESIS_TWO_INPUT_LAYOUTS: tuple[tuple[int, ...], ...] = (
    (5,),
    (10,),
    (20,),
    (5, 5),
    (10, 10),
    (20, 20),
)

#: Axis label of the learning-curve figures (what an iteration is).
ITERATION_LABEL = "iteration (training samples presented, one weight update each)"


def _hidden_label(hidden: tuple[int, ...]) -> str:
    """Thesis notation: layers x units ("1x5", "2x5"); unequal layers as "5-10"."""
    if len(set(hidden)) == 1:
        return f"{len(hidden)}x{hidden[0]}"
    return "-".join(str(h) for h in hidden) if hidden else "none"


def primitive_target_stats(Y: ArrayLike, primitives: ArrayLike) -> list[dict[str, float]]:
    """Per primitive: samples, and the spread and size of its target commands.

    ``target_std`` is the standard deviation of the targets over the primitive's
    samples, averaged over the command columns (how much the command changes inside
    the primitive); ``target_rms`` is their root mean square (how far from rest the
    robot is commanded). Primitives without samples get zeros.
    """
    y = np.asarray(Y, dtype=np.float64)
    prim = np.asarray(primitives)
    if y.ndim != 2 or prim.ndim != 1 or prim.shape[0] != y.shape[0]:
        raise ConfigError(
            f"targets (n, k) and primitive ids (n,) must have the same rows; "
            f"got {y.shape} and {prim.shape}"
        )
    n_prim = int(prim.max()) + 1 if prim.size else 0
    stats = []
    for p in range(n_prim):
        rows = y[prim == p]
        if rows.shape[0] == 0:
            stats.append({"n_samples": 0, "target_std": 0.0, "target_rms": 0.0})
            continue
        stats.append(
            {
                "n_samples": int(rows.shape[0]),
                "target_std": float(rows.std(axis=0).mean()),
                "target_rms": float(np.sqrt(np.mean(rows * rows))),
            }
        )
    return stats


def representative_primitive(
    Y: ArrayLike, primitives: ArrayLike, *, min_samples: int = 20
) -> tuple[int, dict[str, Any]]:
    """The primitive the sweeps study: the robot moves there and its commands change.

    Rule: among the primitives with at least ``min_samples`` samples, keep those whose
    target standard deviation *and* target RMS (:func:`primitive_target_stats`) are both
    at least the median over those primitives; of these, take the one with the most
    samples. If none passes both medians, the standard-deviation median alone is used.
    The primitive with the most samples overall is usually the robot standing near the
    goal, whose targets barely move: a network learns them with its biases, and the
    curves say little about the settings.

    Returns
    -------
    (int, dict)
        The primitive id and a JSON-ready account of the choice (the rule, the medians,
        the chosen primitive's statistics and the candidates' ids).
    """
    stats = primitive_target_stats(Y, primitives)
    eligible = [p for p, s in enumerate(stats) if s["n_samples"] >= max(min_samples, 1)]
    if not eligible:
        raise ConfigError(f"no primitive has {min_samples} samples or more")
    med_std = float(np.median([stats[p]["target_std"] for p in eligible]))
    med_rms = float(np.median([stats[p]["target_rms"] for p in eligible]))
    moving = [p for p in eligible if stats[p]["target_std"] >= med_std]
    candidates = [p for p in moving if stats[p]["target_rms"] >= med_rms] or moving
    chosen = max(candidates, key=lambda p: (stats[p]["n_samples"], -p))
    most = max(eligible, key=lambda p: (stats[p]["n_samples"], -p))
    return chosen, {
        "rule": "most samples among the primitives whose target std and target RMS are both "
        "at least the median over primitives with >= min_samples samples",
        "min_samples": min_samples,
        "median_target_std": med_std,
        "median_target_rms": med_rms,
        "candidates": candidates,
        "chosen": {"primitive": chosen, **stats[chosen]},
        "most_samples": {"primitive": most, **stats[most]},
    }


def run_generator_sweeps(
    X: ArrayLike,
    Y: ArrayLike,
    primitives: ArrayLike,
    out_dir: str | os.PathLike[str],
    *,
    epochs: int = 200,
    learning_rates: Sequence[float] = THESIS_LEARNING_RATES,
    momenta: Sequence[float] = THESIS_MOMENTA,
    hidden_layouts: Sequence[tuple[int, ...]] = THESIS_HIDDEN_LAYOUTS,
    X_two_inputs: ArrayLike | None = None,
    two_input_layouts: Sequence[tuple[int, ...]] = THESIS_TWO_INPUT_LAYOUTS,
    inputs_label: str | None = None,
    two_inputs_label: str | None = None,
    base_learning_rate: float = 0.01,
    base_momentum: float = 0.4,
    base_hidden: tuple[int, ...] = (5,),
    batch_size: int = 1,
    init_range: float = 1.0,
    test_fraction: float = 0.2,
    primitive: int | None = None,
    min_samples: int = 20,
    random_state: int = 0,
    executor: Executor | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """Reproduce the thesis's motion-generator experiments (§6.2, appendix A) on one primitive.

    Parameters
    ----------
    X, Y, primitives
        Inputs (n, n_features), normalized commands (n, 2) in [-1, 1] and primitive
        ids (n,), as for :meth:`behavior_hmm.generators.MotionGenerators.fit`.
    out_dir
        Folder for ``generator_sweeps.json`` (the figures are drawn by
        ``behavior_hmm.viz.plot_generator_sweeps``).
    epochs
        Training epochs per setting; each is ``n_train`` iterations.
    learning_rates
        Learning-rate sweep, at ``base_momentum`` and ``base_hidden`` (figure 6.5).
    momenta
        Momentum sweep, at ``base_learning_rate`` and ``base_hidden`` (figure 6.6).
    hidden_layouts
        Hidden-layer sweep, at the base rate and momentum (figure 6.7); each is a
        tuple of layer sizes, e.g. ``(10,)`` or ``(5, 5)``.
    X_two_inputs
        Optional second input set on the same rows (e.g. angle and angular-velocity
        windows, 20 inputs): adds the ``hidden_two_inputs`` sweep over
        ``two_input_layouts`` (figure A.1) on the same primitive, split and sample order.
    inputs_label, two_inputs_label
        Names of the input channels of ``X`` and ``X_two_inputs`` for the titles,
        e.g. ``"angle"``.
    batch_size
        1 (default) is the thesis's incremental training.
    primitive
        Primitive to study; default: :func:`representative_primitive`.
    min_samples
        Smallest primitive :func:`representative_primitive` considers.
    random_state
        Seed (the primitive's own stream, as in ``MotionGenerators``).
    executor
        Trains the stacks (one per input set and hidden layout) as independent tasks
        (default: this process, one after another); the report is the same whatever
        runs them.
    progress
        Called with (stacks trained, stacks in all).

    Returns
    -------
    dict
        JSON-ready: ``primitive``, ``selection`` (why it was chosen), ``n_train``,
        ``n_test``, ``epochs``, ``batch_size``, ``iterations_per_epoch`` and
        ``iterations`` (the iteration after each epoch, where ``test_error`` is
        measured), ``iteration_label`` (the axis label); ``sweeps[sweep][label]``
        with ``learning_rate``, ``momentum``, ``hidden``, ``n_inputs``,
        ``initial_test_error`` (iteration 0), ``final_test_error``,
        ``best_test_error``, ``best_epoch`` (1-based), ``best_iteration``,
        ``final_train_error`` and ``test_error`` (per epoch);
        ``titles[sweep]`` for the plots and ``summary_file``.
    """
    if isinstance(epochs, bool) or not isinstance(epochs, int) or epochs < 1:
        raise ConfigError(f"epochs must be a positive integer, got {epochs!r}")
    if isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1:
        raise ConfigError(f"batch_size must be a positive integer, got {batch_size!r}")
    x, y, prim, _, _ = _check_fit_inputs(X, Y, primitives, None, None)
    x2: np.ndarray | None = None
    if X_two_inputs is not None:
        x2, _, _, _, _ = _check_fit_inputs(X_two_inputs, Y, primitives, None, None)
    counts = np.bincount(prim)
    if primitive is None:
        chosen, selection = representative_primitive(y, prim, min_samples=min_samples)
    else:
        chosen = int(primitive)
        selection = {"rule": "given by the caller"}
    if not 0 <= chosen < counts.size or counts[chosen] == 0:
        raise ConfigError(f"primitive {chosen} has no samples")
    rows = np.flatnonzero(prim == chosen)
    rng = primitive_rng(random_state, chosen)
    train_rows, test_rows = split_rows(rows, None, rng, test_fraction, 5)
    # Every setting continues from this generator state: same initial weights (for
    # equal layer sizes) and same sample orders.
    state = rng.bit_generator.state
    if test_rows.size == 0:
        raise ConfigError(
            f"primitive {chosen} has {rows.size} samples; the sweeps need a test split"
        )

    # Unique settings (inputs, learning rate, momentum, hidden layout) per sweep.
    Setting = tuple[str, float, float, tuple[int, ...]]
    sweeps: dict[str, list[tuple[str, Setting]]] = {
        "learning_rate": [
            (f"lr={lr:g}", ("one", float(lr), base_momentum, tuple(base_hidden)))
            for lr in learning_rates
        ],
        "momentum": [
            (f"momentum={m:g}", ("one", base_learning_rate, float(m), tuple(base_hidden)))
            for m in momenta
        ],
        "hidden": [
            (
                f"hidden={_hidden_label(tuple(h))}",
                ("one", base_learning_rate, base_momentum, tuple(h)),
            )
            for h in hidden_layouts
        ],
    }
    inputs = {"one": x}
    if x2 is not None:
        inputs["two"] = x2
        sweeps["hidden_two_inputs"] = [
            (
                f"hidden={_hidden_label(tuple(h))}",
                ("two", base_learning_rate, base_momentum, tuple(h)),
            )
            for h in two_input_layouts
        ]
    settings = sorted({setting for runs in sweeps.values() for _, setting in runs})
    # one executor task per stack (inputs, hidden layout): independent of each other
    stacks = sorted({(k, h) for k, _, _, h in settings})
    groups = [[(lr, m) for k, lr, m, h in settings if (k, h) == stack] for stack in stacks]
    tasks = [
        (
            inputs[key],
            y,
            train_rows,
            test_rows,
            hidden,
            group,
            state,
            epochs,
            batch_size,
            init_range,
        )
        for (key, hidden), group in zip(stacks, groups, strict=True)
    ]
    run = executor or SerialExecutor()
    curves: dict[Setting, dict[str, Any]] = {}
    for (key, hidden), group, results in zip(
        stacks, groups, run.map(_group_task, tasks, progress), strict=True
    ):
        for (lr, m), result in zip(group, results, strict=True):
            curves[(key, lr, m, hidden)] = result

    out = Path(out_dir)
    n_train = int(train_rows.size)
    report: dict[str, Any] = {
        "primitive": chosen,
        "selection": selection,
        "n_train": n_train,
        "n_test": int(test_rows.size),
        "epochs": epochs,
        "batch_size": batch_size,
        "iterations_per_epoch": n_train,
        "iterations": [n_train * (e + 1) for e in range(epochs)],
        "iteration_label": ITERATION_LABEL
        if batch_size == 1
        else f"iteration (training samples presented, {batch_size} per weight update)",
        "sweeps": {},
    }
    hidden_base = _hidden_label(tuple(base_hidden))

    def described(n: int, names: str | None) -> str:
        return f"{n} inputs ({names})" if names else f"{n} inputs"

    n_two = x2.shape[1] if x2 is not None else 0
    titles = {
        "learning_rate": f"Learning rate (momentum {base_momentum:g}, hidden {hidden_base})",
        "momentum": f"Momentum (learning rate {base_learning_rate:g}, hidden {hidden_base})",
        "hidden": f"Hidden layers, {described(x.shape[1], inputs_label)}: learning rate "
        f"{base_learning_rate:g}, momentum {base_momentum:g}",
        "hidden_two_inputs": f"Hidden layers, {described(n_two, two_inputs_label)}: "
        f"learning rate {base_learning_rate:g}, momentum {base_momentum:g}",
    }
    for name, runs in sweeps.items():
        report["sweeps"][name] = {label: curves[setting] for label, setting in runs}
    report["titles"] = {name: titles[name] for name in sweeps}
    summary = out / "generator_sweeps.json"
    report["summary_file"] = str(summary)
    atomic_write_bytes(summary, json.dumps(report, indent=1, allow_nan=False).encode())
    return report


def _group_task(task: tuple[Any, ...]) -> list[dict[str, Any]]:
    """Train one stack (an executor task): the arguments of :func:`_train_group`."""
    return _train_group(*task)


def _train_group(
    x: np.ndarray,
    y: np.ndarray,
    train_rows: np.ndarray,
    test_rows: np.ndarray,
    hidden: tuple[int, ...],
    group: list[tuple[float, float]],
    state: Mapping[str, Any],
    epochs: int,
    batch_size: int,
    init_range: float,
) -> list[dict[str, Any]]:
    """Train one stack: every (learning rate, momentum) pair with this hidden layout."""
    sizes = (x.shape[1], *hidden, y.shape[1])
    n_slots = len(group)
    rngs = []
    for _ in range(n_slots):
        rng = np.random.Generator(np.random.PCG64())
        rng.bit_generator.state = state
        rngs.append(rng)
    theta0 = np.stack([init_weights(rng, sizes, init_range) for rng in rngs])
    n_train = np.full(n_slots, train_rows.size, dtype=np.int64)
    n_test = np.full(n_slots, test_rows.size, dtype=np.int64)
    x_test = np.broadcast_to(x[test_rows], (n_slots, *x[test_rows].shape))
    y_test = np.broadcast_to(y[test_rows], (n_slots, *y[test_rows].shape))
    initial = rms_error(layer_views(theta0, sizes), with_ones(x_test), y_test, n_test)
    result = train_stack(
        theta0,
        sizes,
        np.broadcast_to(x[train_rows], (n_slots, *x[train_rows].shape)),
        np.broadcast_to(y[train_rows], (n_slots, *y[train_rows].shape)),
        n_train,
        x_test,
        y_test,
        n_test,
        learning_rate=np.array([lr for lr, _ in group]),
        momentum=np.array([m for _, m in group]),
        epochs=epochs,
        batch_size=batch_size,
        rngs=rngs,
        early_stopping=False,
        patience=None,
    )
    entries = []
    for slot, (lr, m) in enumerate(group):
        test_curve = result.test_error[slot]
        finite = np.isfinite(test_curve)
        best = int(np.nanargmin(test_curve)) if finite.any() else -1
        entries.append(
            {
                "learning_rate": lr,
                "momentum": m,
                "hidden": list(hidden),
                "n_inputs": int(x.shape[1]),
                "initial_test_error": _json_float(initial[slot]),
                "final_test_error": _json_float(test_curve[-1]),
                "best_test_error": _json_float(test_curve[best]) if best >= 0 else None,
                "best_epoch": best + 1,
                "best_iteration": (best + 1) * int(train_rows.size),
                "final_train_error": _json_float(result.train_error[slot, -1]),
                "test_error": [_json_float(v) for v in test_curve],
            }
        )
    return entries


def _json_float(value: float) -> float | None:
    """A float for JSON; ``None`` for NaN/inf (e.g. a diverged setting)."""
    v = float(value)
    return v if np.isfinite(v) else None
