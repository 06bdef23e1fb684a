"""Behavior-HMM: counted A, B, C, π in log space, most likely observation path, Viterbi.

``BehaviorHMM`` is estimated by counting labelled control cycles (thesis table 4.3);
``plan(o_current, o_goal)`` returns the most likely observation path to a goal and
the states decoded along it (thesis Algorithm 1), as a :class:`Plan` of
:class:`Segment` s, each with its exit observation.
"""

from behavior_hmm.hmm._behavior_hmm import BehaviorHMM
from behavior_hmm.hmm._plan import Plan, Segment

__all__ = ["BehaviorHMM", "Plan", "Segment"]
