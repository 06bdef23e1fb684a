"""Goals in physical units: parsing, tolerances and the physical stop test."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Final

import numpy as np
from scipy.sparse import csr_array

from behavior_hmm.data._channels import (
    CHANNEL_NAME,
    CHANNELS,
    SENSOR_CHANNELS,
    TOLERANCES,
    ChannelSpec,
    within_tolerance,
)
from behavior_hmm.data._validate import suggest
from behavior_hmm.errors import ConfigError

__all__ = ["TOLERANCES", "check_goal", "goal_candidates", "within_tolerance"]


#: ``inputs`` value that lets an SBLM's ``fit`` choose the channels (``select_inputs``).
AUTO_INPUTS: Final = "auto"


def check_input_names(inputs: Sequence[str], available: Sequence[str] | None = None) -> None:
    """Refuse inputs that are not sensor channels of ``available`` (a dataset's channels).

    Without ``available`` (parameters checked before any data is read, or a model file
    loaded), a name must be a known sensor channel or a well-formed name a dataset may
    declare (docs/robots.md); command channels are never inputs.
    """
    for name in inputs:
        if available is not None:
            if name not in available:
                raise ConfigError(
                    f"unknown input '{name}'; choose from {', '.join(available)}"
                    f"{suggest(str(name), list(available))}"
                )
            continue
        spec = CHANNELS.get(name)
        if (spec is not None and spec.kind != "sensor") or not CHANNEL_NAME.match(str(name)):
            raise ConfigError(f"unknown input '{name}'; choose from {', '.join(SENSOR_CHANNELS)}")


def check_goal(
    goal: Mapping[str, float],
    allowed: tuple[str, ...],
    specs: Mapping[str, ChannelSpec] | None = None,
) -> dict[str, float]:
    """Validate a goal ``{channel: value}`` against the channels a model can see.

    ``specs`` are the model's own channel declarations (a robot's channels the registry
    does not know); any channel with a tolerance can be a goal.
    """
    if not goal:
        raise ConfigError("the goal is empty; give at least one channel, e.g. angle=0")
    known = {**CHANNELS, **(specs or {})}
    out: dict[str, float] = {}
    for name, value in goal.items():
        spec = known.get(name)
        if spec is None or spec.kind != "sensor" or spec.tolerance is None:
            goals = [c for c in allowed if c in known and known[c].tolerance is not None]
            raise ConfigError(
                f"unknown goal channel '{name}'; choose from {', '.join(goals) or '(none)'}"
                " (a goal channel needs a tolerance in its declaration)"
            )
        if name not in allowed:
            raise ConfigError(
                f"goal channel '{name}' is not an input of this model "
                f"(inputs: {', '.join(allowed)})"
            )
        v = float(value)
        if v != v or v in (float("inf"), float("-inf")):
            raise ConfigError(f"goal {name} must be a finite number, got {value}")
        lo, hi = (-180.0, 180.0) if spec.wraps else spec.bounds or spec.range
        lo = max(lo, 0.0) if spec.range[0] >= 0.0 else lo  # e.g. a distance is never < 0
        if not lo <= v <= hi:
            raise ConfigError(f"goal {name} {v:g} {spec.unit} not in [{lo:g}, {hi:g}]")
        out[name] = v
    return out


def entered_categories(c_counts: csr_array) -> np.ndarray:
    """Observation categories that the demonstrations entered from another category."""
    return (np.asarray(c_counts.sum(axis=0)) - c_counts.diagonal()) > 0


def best_goal_category(scores: np.ndarray, c_counts: csr_array) -> int:
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


#: Largest RMS difference (normalized units) between a goal and the latest reading of a
#: category a simple behavior plans to when no candidate goal category is reachable
#: from where the robot is (:func:`goal_fallbacks`): about 36 deg or 12 cm.
FALLBACK_MARGIN = 4.0 * GOAL_VALUE_MARGIN


def goal_gaps(latest: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """RMS difference of each prototype's latest reading ``(K, G)`` from ``goal`` ``(G,)``."""
    diff = np.asarray(latest) - np.asarray(goal)[None, :]
    return np.asarray(np.sqrt(np.mean(diff**2, axis=1)))


def goal_fallbacks(
    c_counts: csr_array, latest: np.ndarray, goal: np.ndarray, current: int, limit: int = 64
) -> np.ndarray:
    """Categories near the goal to plan to when no candidate goal category is reachable.

    The entered categories whose prototype ends beyond ``GOAL_VALUE_MARGIN`` but within
    ``FALLBACK_MARGIN`` of the goal on the goal's channels, and nearer to it than the
    prototype of ``current`` (where the robot is), nearest first: a plan toward one moves
    the robot toward the goal, never away. The robot is stopped at the goal by its
    physical tolerance (goal braking, the stop rule), not by the category: a plan to a
    category just past the goal carries it through the goal. Needed where the categories
    that end nearer were only ever entered from elsewhere: a retreat learned with mirror
    images has two start-at-rest categories entered from each other that best match
    goals at 0.31 and 0.70 m, while its moving categories end 3-4 cm from them.

    Parameters are those of :func:`goal_candidates`, and ``current``, the category the
    robot is in.
    """
    gap = goal_gaps(latest, goal)
    entered = entered_categories(c_counts)
    near = (gap > GOAL_VALUE_MARGIN) & (gap <= FALLBACK_MARGIN) & (gap < gap[current])
    out = np.flatnonzero(near & entered)
    return out[np.argsort(gap[out], kind="stable")][:limit].astype(np.int64)


def goal_candidates(
    scores: np.ndarray,
    c_counts: csr_array,
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
    gap = goal_gaps(latest, goal)
    near = np.flatnonzero((gap <= GOAL_VALUE_MARGIN) & entered)
    near = near[np.argsort(gap[near], kind="stable")]
    out = [best] + [int(k) for k in near if k != best]
    return np.asarray(out[:limit], dtype=np.int64)
