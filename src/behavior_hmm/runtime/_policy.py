"""What every learned behavior's policy is to the control loop: the Policy protocol."""

from __future__ import annotations

from collections.abc import Mapping
from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


class StepOutput(NamedTuple):
    """What a policy decided in one control cycle.

    Attributes
    ----------
    command
        ``(left, right)`` wheel speeds to send (rad/s).
    observation
        Observation category of this cycle (-1: none, e.g. a baseline).
    novel
        Whether the observation matched no category within vigilance.
    state
        Active motion primitive (an SBLM) or component index (a CBLM).
    component
        Name of the active component ("" for an SBLM's own steps).
    plan_changed
        True where the active state changed this cycle.
    done
        True when the behavior is finished: send the stop, not ``command``.
    """

    command: FloatArray
    observation: int
    novel: bool
    state: int
    component: str
    plan_changed: bool
    done: bool


@runtime_checkable
class Policy(Protocol):
    """A behavior performed one reading at a time, with no simulator in sight.

    ``SBLM.policy(goal)``, ``CBLM.policy(goal)`` and the baselines return one. A robot's
    own control loop (a ROS node, a microcontroller bridge) calls :meth:`step` once per
    control period with the latest readings, sends ``command`` to the wheels and stops
    when ``done`` (docs/robots.md); :func:`behavior_hmm.runtime.run_policy` does the same
    on any Gymnasium env that meets the robot contract.

    Attributes
    ----------
    goal
        The goal in physical units, e.g. ``{"angle": 0.0}``.
    channels
        The sensor channels :meth:`step` reads (it ignores others).
    """

    @property
    def goal(self) -> Mapping[str, float]:
        """The goal in physical units."""
        ...

    @property
    def channels(self) -> tuple[str, ...]:
        """The sensor channels :meth:`step` reads."""
        ...

    def reset(self) -> None:
        """Forget the previous run (filters, windows, plan)."""
        ...

    def step(self, reading: Mapping[str, float]) -> StepOutput:
        """Decide one cycle from ``{channel: value}`` in physical units (deg, m, ...)."""
        ...
