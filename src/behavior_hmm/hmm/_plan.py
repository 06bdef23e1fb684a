"""The result of one behavior-generation plan: observation path, states, segments."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Literal, NamedTuple


class Segment(NamedTuple):
    """One run of a state on the planned path (an immutable named tuple).

    Attributes
    ----------
    state
        State index (a motion primitive in SBLM, a learned behavior in CBLM).
    exit_observation
        Observation category whose appearance ends this segment: the first
        observation after its run on the path, or the goal for the last segment.
        This is the exit condition of thesis Algorithm 1 and the intermediate goal
        handed to a sub-behavior in CBLM (thesis ch. 5: turn → o1, approach → o2,
        grasp → o_g).
    last_observation
        Last observation of the segment's own run on the path (the state was decoded
        as active while this category is seen).
    start, stop
        The segment covers ``Plan.observations[start:stop]``.
    """

    state: int
    exit_observation: int
    last_observation: int
    start: int
    stop: int


@dataclass(frozen=True)
class Plan:
    """Most likely observation path to a goal and the decoded states along it.

    Immutable (tuples only) so cached plans can be shared safely.

    Attributes
    ----------
    observations
        Observation categories from the current one to the goal, both included.
    states
        Decoded state for each element of ``observations``.
    path_log_prob
        Log probability of the observation path under C (with the model's
        ``path_self_loops`` rule); 0.0 when current == goal.
    log_prob
        Viterbi ``log P(states, observations)`` with π, A, B; ``-inf`` when
        ``decoding == "emissions"`` (no sequence was possible under A).
    decoding
        ``"viterbi"``, or ``"emissions"`` when the fallback was used.
    """

    observations: tuple[int, ...]
    states: tuple[int, ...]
    path_log_prob: float
    log_prob: float
    decoding: Literal["viterbi", "emissions"]

    @functools.cached_property
    def segments(self) -> tuple[Segment, ...]:
        """``states`` collapsed into runs, each with its exit observation.

        Made on first use: a controller that needs only the first state reads
        ``states[0]``, and the many cached plans of a large model then hold no segment
        objects for the garbage collector to walk through.
        """
        return make_segments(self.observations, self.states)

    @property
    def goal(self) -> int:
        """The goal observation category (last element of the path)."""
        return self.observations[-1]

    @property
    def state_sequence(self) -> tuple[int, ...]:
        """The collapsed state sequence (one entry per segment)."""
        return tuple(s.state for s in self.segments)

    @property
    def exit_observations(self) -> tuple[int, ...]:
        """The exit observation of each segment, in order; the last is the goal."""
        return tuple(s.exit_observation for s in self.segments)


def make_segments(observations: tuple[int, ...], states: tuple[int, ...]) -> tuple[Segment, ...]:
    """Collapse consecutive equal states into segments with their exit observation."""
    segments: list[Segment] = []
    n = len(states)
    start = 0
    for stop in range(1, n + 1):
        if stop == n or states[stop] != states[start]:
            exit_obs = observations[stop] if stop < n else observations[-1]
            segments.append(Segment(states[start], exit_obs, observations[stop - 1], start, stop))
            start = stop
    return tuple(segments)
