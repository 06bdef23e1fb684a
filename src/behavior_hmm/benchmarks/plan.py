"""Planning cost: a new goal, a new (current, goal) pair, a per-cycle re-plan, a path alone.

For each size (observation categories M × states N) a Behavior-HMM is counted from
synthetic turn-like demonstrations: ``EPISODES`` episodes, each starting in a random
category and drifting down a chain of categories to category 0 (each control cycle it
stays, moves one category down or skips one), the active state being the chain's band
of ``M / N`` categories (so every plan holds many segments, more than trained models'
plans, and every planned path has a state sequence). Every plan goes to category 0 from
every category the episodes visited:

* ``new_goal_ms_median``: the first plan after the caches were cleared (the goal's
  shortest-path tree, its Viterbi messages and the plan);
* ``new_pair_us_median``: a plan for a current category not planned before, the goal's
  tree and messages already made (median over the categories);
* ``repeated_pair_us_median``: the same plan again (what a control cycle that stays in
  its category pays: a cache lookup);
* ``path_us_median``: :meth:`BehaviorHMM.most_likely_path` alone, the goal's tree made;
* ``path_length_median`` / ``path_length_max``: observations on the planned paths.

Medians over ``REPEATS`` repeats (the quick run: ``QUICK_REPEATS``); ``reached`` says
whether every plan ended at the goal.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

#: (observation categories, states) timed.
SIZES = ((100, 20), (100, 50), (300, 50))
#: Demonstrations per model.
EPISODES = 36
#: Per control cycle: probability of moving one category down, of skipping one.
MOVE, SKIP = 0.4, 0.1
REPEATS = 5
QUICK_REPEATS = 2
SEED = 0


def _demonstrations(
    n_observations: int, n_states: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """States, observations and episode lengths of the synthetic drifting episodes."""
    states: list[int] = []
    observations: list[int] = []
    lengths: list[int] = []
    for _ in range(EPISODES):
        category = int(rng.integers(1, n_observations))
        steps = 0
        while True:
            states.append(category * n_states // n_observations)
            observations.append(category)
            steps += 1
            if category == 0:
                break
            u = rng.random()
            step = 2 if u < SKIP else 1 if u < SKIP + MOVE else 0
            category = max(0, category - step)
        lengths.append(steps)
    return np.array(states), np.array(observations), lengths


def _timed(call: Any) -> float:
    """Seconds one call of ``call`` takes."""
    t0 = time.perf_counter()
    call()
    return time.perf_counter() - t0


def _size(n_observations: int, n_states: int, repeats: int) -> dict[str, Any]:
    from behavior_hmm.hmm import BehaviorHMM

    rng = np.random.default_rng([SEED, n_observations, n_states])
    states, observations, lengths = _demonstrations(n_observations, n_states, rng)
    hmm = BehaviorHMM(n_states=n_states, n_observations=n_observations)
    hmm.fit(states, observations, lengths)
    goal = 0
    currents = [int(c) for c in np.unique(observations) if c != goal]
    new_goal, new_pair, repeated, path = [], [], [], []
    lengths_seen: list[int] = []
    reached = True
    for _ in range(repeats):
        hmm.set_params(on_impossible=hmm.on_impossible)  # clears every planning cache
        new_goal.append(_timed(lambda: hmm.plan(currents[0], goal)))
        for c in currents[1:]:
            new_pair.append(_timed(lambda c=c: hmm.plan(c, goal)))
        for c in currents:
            repeated.append(_timed(lambda c=c: hmm.plan(c, goal)))
            path.append(_timed(lambda c=c: hmm.most_likely_path(c, goal)))
    for c in currents:
        plan = hmm.plan(c, goal)
        lengths_seen.append(len(plan.observations))
        reached = reached and plan.observations[-1] == goal
    return {
        "n_observations": n_observations,
        "n_states": n_states,
        "episodes": EPISODES,
        "plans": len(currents),
        "path_length_median": float(np.median(lengths_seen)),
        "path_length_max": int(max(lengths_seen)),
        "new_goal_ms_median": float(np.median(new_goal)) * 1e3,
        "new_pair_us_median": float(np.median(new_pair)) * 1e6,
        "repeated_pair_us_median": float(np.median(repeated)) * 1e6,
        "path_us_median": float(np.median(path)) * 1e6,
        "reached": bool(reached),
    }


def run(quick: bool = False, *, sizes: tuple[tuple[int, int], ...] = SIZES) -> dict[str, Any]:
    """Time planning at each ``(observation categories, states)`` size; see the module."""
    repeats = QUICK_REPEATS if quick else REPEATS
    return {"repeats": repeats, "sizes": [_size(m, n, repeats) for m, n in sizes]}
