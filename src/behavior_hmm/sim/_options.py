"""Checks of what every simulated robot takes: numbers, noise, actions and pushes."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Final

import numpy as np

from behavior_hmm.errors import ConfigError

#: Keys of one scheduled push (``reset(options={"push": ...})``).
PUSH_KEYS: Final[tuple[str, ...]] = ("step", "angle", "distance")


def reset_options(options: Mapping[str, Any] | None, known: Sequence[str]) -> Mapping[str, Any]:
    """``reset``'s options (``{}`` for None), refusing a non-mapping or an unknown key."""
    options = {} if options is None else options
    if not isinstance(options, Mapping):
        raise ConfigError(f"reset options must be a dict, got {type(options).__name__}")
    refuse_unknown(options, known, "reset option(s)", f"some of {', '.join(known)}")
    return options


def refuse_unknown(mapping: Mapping[Any, Any], known: Sequence[str], what: str, hint: str) -> None:
    """ConfigError ``unknown {what}: KEYS; expected {hint}`` for keys of ``mapping`` not known."""
    unknown = sorted(str(k) for k in mapping if k not in known)
    if unknown:
        raise ConfigError(f"unknown {what}: {', '.join(unknown)}; expected {hint}")


def number(value: object, what: str) -> float:
    """``value`` as a finite float, or a ConfigError naming ``what``."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ConfigError(f"{what} must be a number, got {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise ConfigError(f"{what} must be finite, got {out}")
    return out


def check_noise(value: object, what: str) -> float:
    """A sensor-noise sigma: a finite number >= 0."""
    sigma = number(value, what)
    if sigma < 0.0:
        raise ConfigError(f"{what} must be >= 0, got {sigma}")
    return sigma


def parse_action(action: Any) -> tuple[float, float]:
    """``(left, right)`` wheel speeds (rad/s) from anything array-like of shape (2,)."""
    try:
        arr = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"action must be 2 numbers (left, right) in rad/s: {exc}") from exc
    if arr.shape != (2,):
        raise ConfigError(
            f"action must have shape (2,) = (left, right) wheel speeds, got shape {arr.shape}"
        )
    left, right = arr.tolist()
    return left, right


def parse_pushes(raw: object) -> dict[int, list[tuple[float, float]]]:
    """The ``push`` reset option: a dict or a list of dicts ``{"step", "angle", "distance"}``,
    as ``{step: [(d_angle deg, d_distance m), ...]}``."""
    if raw is None:
        return {}
    items: Sequence[object]
    if isinstance(raw, Mapping):
        items = [raw]
    elif isinstance(raw, list | tuple):
        items = raw
    else:
        raise ConfigError(f"push option must be a dict or a list of dicts, got {raw!r}")
    pushes: dict[int, list[tuple[float, float]]] = {}
    for item in items:
        if not isinstance(item, Mapping):
            raise ConfigError(f"each push must be a dict, got {item!r}")
        refuse_unknown(item, PUSH_KEYS, "push key(s)", ", ".join(PUSH_KEYS))
        step = item.get("step")
        if isinstance(step, bool) or not isinstance(step, int | np.integer) or step < 1:
            raise ConfigError(f"push step must be an integer >= 1, got {step!r}")
        d_angle = number(item.get("angle", 0.0), "push angle")
        d_distance = number(item.get("distance", 0.0), "push distance")
        pushes.setdefault(int(step), []).append((d_angle, d_distance))
    return pushes
