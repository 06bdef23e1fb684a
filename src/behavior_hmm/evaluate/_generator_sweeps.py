"""Thesis §6.2: learning rate, momentum and hidden-layout sweeps of one motion generator.

The thesis trained one primitive's network (the turn behavior's, 80/20 split,
incremental backpropagation, tanh, weights in [-1, 1]) under different settings
and plotted test error against training iteration (figures 6.5-6.7). Here the
primitive with the most samples is used, "iteration" is an epoch, and every
setting starts from the same split and the same sample order; settings with the
same layer sizes also share their initial weights. Settings with the same
hidden layout train together as one stack.
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
from behavior_hmm.generators._mlp import train_stack
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


def _hidden_label(hidden: tuple[int, ...]) -> str:
    """Thesis notation: layers x units ("1x5", "2x5"); unequal layers as "5-10"."""
    if len(set(hidden)) == 1:
        return f"{len(hidden)}x{hidden[0]}"
    return "-".join(str(h) for h in hidden) if hidden else "none"


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
    base_learning_rate: float = 0.01,
    base_momentum: float = 0.4,
    base_hidden: tuple[int, ...] = (5,),
    batch_size: int = 1,
    init_range: float = 1.0,
    test_fraction: float = 0.2,
    primitive: int | None = None,
    random_state: int = 0,
) -> dict[str, Any]:
    """Reproduce the thesis's motion-generator experiments (§6.2) on one primitive.

    Parameters
    ----------
    X, Y, primitives
        Inputs (n, n_features), normalized commands (n, 2) in [-1, 1] and primitive
        ids (n,), as for :meth:`behavior_hmm.generators.MotionGenerators.fit`.
    out_dir
        Folder for ``generator_sweeps.json`` and the PNG figures.
    epochs
        Training epochs per setting (the x axis of the figures).
    learning_rates
        Learning-rate sweep, at ``base_momentum`` and ``base_hidden`` (figure 6.5).
    momenta
        Momentum sweep, at ``base_learning_rate`` and ``base_hidden`` (figure 6.6).
    hidden_layouts
        Hidden-layer sweep, at the base rate and momentum (figure 6.7); each is a
        tuple of layer sizes, e.g. ``(10,)`` or ``(5, 5)``.
    batch_size
        1 (default) is the thesis's incremental training.
    primitive
        Primitive to study; default: the one with the most samples.
    random_state
        Seed (the primitive's own stream, as in ``MotionGenerators``).

    Returns
    -------
    dict
        JSON-ready: ``primitive``, ``n_train``, ``n_test``, ``epochs``,
        ``batch_size``; ``sweeps[sweep][label]`` with ``learning_rate``,
        ``momentum``, ``hidden``, ``final_test_error``, ``best_test_error``,
        ``best_epoch`` (1-based), ``final_train_error`` and ``test_error`` (per
        epoch); ``titles[sweep]`` for the plots (drawn by
        ``behavior_hmm.viz.plot_generator_sweeps``) and ``summary_file``.
    """
    if isinstance(epochs, bool) or not isinstance(epochs, int) or epochs < 1:
        raise ConfigError(f"epochs must be a positive integer, got {epochs!r}")
    if isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1:
        raise ConfigError(f"batch_size must be a positive integer, got {batch_size!r}")
    x, y, prim, _, _ = _check_fit_inputs(X, Y, primitives, None, None)
    counts = np.bincount(prim)
    chosen = int(np.argmax(counts)) if primitive is None else int(primitive)
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

    # Unique settings (learning rate, momentum, hidden layout) per sweep.
    sweeps: dict[str, list[tuple[str, float, float, tuple[int, ...]]]] = {
        "learning_rate": [
            (f"lr={lr:g}", float(lr), base_momentum, tuple(base_hidden)) for lr in learning_rates
        ],
        "momentum": [
            (f"momentum={m:g}", base_learning_rate, float(m), tuple(base_hidden)) for m in momenta
        ],
        "hidden": [
            (f"hidden={_hidden_label(tuple(h))}", base_learning_rate, base_momentum, tuple(h))
            for h in hidden_layouts
        ],
    }
    settings = sorted({(lr, m, h) for runs in sweeps.values() for _, lr, m, h in runs})
    curves: dict[tuple[float, float, tuple[int, ...]], dict[str, Any]] = {}
    for hidden in sorted({h for _, _, h in settings}):
        group = [(lr, m) for lr, m, h in settings if h == hidden]
        for (lr, m), result in zip(
            group,
            _train_group(
                x, y, train_rows, test_rows, hidden, group, state, epochs, batch_size, init_range
            ),
            strict=True,
        ):
            curves[(lr, m, hidden)] = result

    out = Path(out_dir)
    report: dict[str, Any] = {
        "primitive": chosen,
        "n_train": int(train_rows.size),
        "n_test": int(test_rows.size),
        "epochs": epochs,
        "batch_size": batch_size,
        "sweeps": {},
    }
    titles = {
        "learning_rate": f"Learning rate (momentum {base_momentum:g}, hidden "
        f"{_hidden_label(tuple(base_hidden))})",
        "momentum": f"Momentum (learning rate {base_learning_rate:g}, hidden "
        f"{_hidden_label(tuple(base_hidden))})",
        "hidden": f"Hidden layers (learning rate {base_learning_rate:g}, momentum "
        f"{base_momentum:g})",
    }
    for name, runs in sweeps.items():
        report["sweeps"][name] = {label: curves[(lr, m, h)] for label, lr, m, h in runs}
    report["titles"] = {name: f"{titles[name]} - primitive {chosen}" for name in sweeps}
    summary = out / "generator_sweeps.json"
    report["summary_file"] = str(summary)
    atomic_write_bytes(summary, json.dumps(report, indent=1, allow_nan=False).encode())
    return report


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
    result = train_stack(
        theta0,
        sizes,
        np.broadcast_to(x[train_rows], (n_slots, *x[train_rows].shape)),
        np.broadcast_to(y[train_rows], (n_slots, *y[train_rows].shape)),
        n_train,
        np.broadcast_to(x[test_rows], (n_slots, *x[test_rows].shape)),
        np.broadcast_to(y[test_rows], (n_slots, *y[test_rows].shape)),
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
                "final_test_error": _json_float(test_curve[-1]),
                "best_test_error": _json_float(test_curve[best]) if best >= 0 else None,
                "best_epoch": best + 1,
                "final_train_error": _json_float(result.train_error[slot, -1]),
                "test_error": [_json_float(v) for v in test_curve],
            }
        )
    return entries


def _json_float(value: float) -> float | None:
    """A float for JSON; ``None`` for NaN/inf (e.g. a diverged setting)."""
    v = float(value)
    return v if np.isfinite(v) else None
