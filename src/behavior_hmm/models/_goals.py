"""Goals in physical units: parsing, tolerances and the physical stop test."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Final

import numpy as np

from behavior_hmm.data import ANGLE_TOLERANCE_DEG, DISTANCE_TOLERANCE_M, SENSOR_CHANNELS
from behavior_hmm.errors import ConfigError

#: Physical tolerance of a goal on each channel (DESIGN §5: 3 deg, 0.01 m).
TOLERANCES: Final[dict[str, float]] = {
    "angle": ANGLE_TOLERANCE_DEG,
    "distance": DISTANCE_TOLERANCE_M,
    "linear_velocity": 0.01,
    "angular_velocity": 5.0,
}


def check_goal(goal: Mapping[str, float], allowed: tuple[str, ...]) -> dict[str, float]:
    """Validate a goal ``{channel: value}`` against the channels a model can see."""
    if not goal:
        raise ConfigError("the goal is empty; give at least one channel, e.g. angle=0")
    out: dict[str, float] = {}
    for name, value in goal.items():
        if name not in SENSOR_CHANNELS:
            raise ConfigError(
                f"unknown goal channel '{name}'; choose from {', '.join(SENSOR_CHANNELS)}"
            )
        if name not in allowed:
            raise ConfigError(
                f"goal channel '{name}' is not an input of this model "
                f"(inputs: {', '.join(allowed)})"
            )
        v = float(value)
        if v != v or v in (float("inf"), float("-inf")):
            raise ConfigError(f"goal {name} must be a finite number, got {value}")
        if name == "angle" and not -180.0 <= v <= 180.0:
            raise ConfigError(f"goal angle {v:g} deg not in [-180, 180]")
        if name == "distance" and not 0.0 <= v <= 1.2:
            raise ConfigError(f"goal distance {v:g} m not in [0, 1.2]")
        out[name] = v
    return out


def entered_categories(c_counts: np.ndarray) -> np.ndarray:
    """Observation categories that the demonstrations entered from another category."""
    counts = np.asarray(c_counts, dtype=np.int64)
    return (counts.sum(axis=0) - np.diag(counts)) > 0


def best_goal_category(scores: np.ndarray, c_counts: np.ndarray) -> int:
    """The best-matching category for a goal window among those a path can end in.

    A still window at an intermediate goal (e.g. 0.5 m for an approach) matches best the
    category of a demonstration that *started* there, which nothing ever leads into;
    such a goal would be unreachable although every approach passes 0.5 m. So the goal
    category is the best match among the categories the demonstrations entered, unless
    none was entered (a model trained on still data).
    """
    entered = entered_categories(c_counts)
    if not entered.any():
        return int(np.argmax(scores))
    masked = np.where(entered, scores, -np.inf)
    return int(np.argmax(masked))


#: Largest RMS difference (normalized units) between a goal and the latest reading of a
#: candidate goal category's prototype, over the goal's channels: about 9 deg of bearing
#: or 3 cm of distance with the default normalization.
GOAL_VALUE_MARGIN = 0.05


def goal_candidates(
    scores: np.ndarray,
    c_counts: np.ndarray,
    latest: np.ndarray,
    goal: np.ndarray,
    limit: int = 64,
) -> np.ndarray:
    """Categories that describe being at the goal, best first.

    The first candidate is :func:`best_goal_category` (the thesis's o_g). The others are
    the entered categories whose prototype ends within ``GOAL_VALUE_MARGIN`` of the goal
    on the goal's channels, nearest first, whatever the motion in their window: at an
    intermediate goal (an approach asked to stop at 0.5 m) the robot passes categories
    of moving windows, and several of them, on different branches of the observation
    graph, describe the same place.

    Parameters
    ----------
    scores
        Score of every category for a still window at the goal.
    c_counts
        Observation transition counts (which categories were entered).
    latest
        (K, G) latest reading of every prototype on the goal's channels (normalized).
    goal
        (G,) the goal on those channels (normalized).
    """
    best = best_goal_category(scores, c_counts)
    entered = entered_categories(c_counts)
    gap = np.sqrt(np.mean((np.asarray(latest) - np.asarray(goal)[None, :]) ** 2, axis=1))
    near = np.flatnonzero((gap <= GOAL_VALUE_MARGIN) & entered)
    near = near[np.argsort(gap[near], kind="stable")]
    out = [best] + [int(k) for k in near if k != best]
    return np.asarray(out[:limit], dtype=np.int64)


def within_tolerance(
    values: Mapping[str, float], goal: Mapping[str, float], scale: float = 1.0
) -> bool:
    """True when every goal channel of ``values`` lies within ``scale`` times its tolerance."""
    for name, target in goal.items():
        error = values[name] - target
        if name == "angle":
            error = (error + 180.0) % 360.0 - 180.0
        if abs(error) > scale * TOLERANCES[name]:
            return False
    return True
