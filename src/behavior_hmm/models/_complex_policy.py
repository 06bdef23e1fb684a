"""The policy of a complex behavior: delegation to component behaviors."""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence
from enum import Enum
from typing import Any

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data._channels import ChannelSpec, within_tolerance
from behavior_hmm.errors import UnreachableGoalError
from behavior_hmm.models._confirm import GoalConfirmation
from behavior_hmm.models._policy import (
    REST_CHANNELS,
    GoalTracking,
    RateLimited,
    make_policy,
    read_channels,
    readings_at_rest,
    retarget,
)
from behavior_hmm.runtime import ordered_channels
from behavior_hmm.runtime._policy import StepOutput

FloatArray = NDArray[np.float64]


class Phase(Enum):
    """The run state of a complex behavior's policy (:attr:`ComplexPolicy.phase`)."""

    #: no component runs: the plan chooses the next one (or the run ends, or a repair)
    CHOOSING = "choosing"
    #: a component runs toward its intermediate goal
    RUNNING = "running"
    #: inside the complex goal, the running component finishes braking into its own
    #: goal instead of the robot stopping at speed (``settle_cycles``)
    SETTLING = "settling"
    #: a component ended at rest: the robot rests as long as the teacher at a switch
    #: (``handover_pause``)
    PAUSED = "paused"
    #: at the goal, ramping the command to rest (``command_rate_limit``); a run that
    #: stops at once ends with its done step instead
    STOPPING = "stopping"


# -- rules: each decides one thing from what it is given, and can be tested alone -------


class Debounce:
    """Debounce rule: a running component is replaced only when the plan insists.

    Near a category border the plan's first component can flip every few cycles; the
    running one goes on until the plan has wanted the same other component for
    ``cycles`` cycles in a row (thesis: 0, a switch at once).

    Parameters
    ----------
    cycles
        Cycles in a row the plan must want another component (``switch_cycles``).
    """

    def __init__(self, cycles: int) -> None:
        self.cycles = int(cycles)
        self.clear()

    def clear(self) -> None:
        """Forget what the plan wanted (a switch happened, or none was asked for)."""
        self._wanted = -1
        self._insist = 0

    def holds(self, wanted: int) -> bool:
        """Count one cycle the plan wants ``wanted``: True while the running one goes on."""
        self._insist = self._insist + 1 if self._wanted == wanted else 1
        self._wanted = wanted
        return self._insist < self.cycles


def _needed_change(
    values: Mapping[str, float], goal: float, channel: str, spec: ChannelSpec
) -> float:
    """The sign of the change that closes a gap: |angle| must shrink; others move to the goal."""
    return -1.0 if spec.wraps else -float(np.sign(values[channel] - goal))


def preempting_component(
    goal: Mapping[str, float],
    values: Mapping[str, float],
    specs: Mapping[str, ChannelSpec],
    channels: Sequence[str],
    effects: FloatArray,
    goal_channels: Sequence[Collection[str]],
    planned: Sequence[int],
    follows: Callable[[int, int], bool],
    unable: Collection[int] = (),
    tolerance: float = 1.0,
) -> int | None:
    """Pre-emption rule: a component to run first because the plan cannot close a gap.

    At a decision point (nothing running), a goal channel outside its tolerance must be
    closed by some planned component, judged by the components' learned effects (a
    substantial share of the best effect); e.g. a start 9 deg off the object whose still
    window looks aligned gets "approach" planned, but approach does not turn, and in
    the demonstrations nothing turns after it. Then the component that closes that gap
    best runs first, unless the demonstrations run it after the plan's first component
    (a start 3 cm short of the goal and 109 deg off gets "turn" planned; the approach
    then comes after the turn, as the plan's repair, not before it).

    Parameters
    ----------
    goal, values
        The complex goal and the current (filtered) readings, physical units.
    specs
        Each channel's declaration (tolerance, wrap).
    channels
        The complex behavior's input channels: the columns of ``effects``.
    effects
        ``(components, channels)``: each component's learned effect per cycle.
    goal_channels
        Per component, the channels its own goal states.
    planned
        The components the plan has still to run, first first.
    follows
        ``follows(k, other)``: whether the demonstrations run ``k`` after ``other``.
    unable
        Components that cannot start from here.
    tolerance
        Scale of the goal's tolerance.

    Returns
    -------
    int or None
        The component to run first; ``None``: the plan covers every gap, or goes first.
    """
    for channel in goal:
        if within_tolerance(values, {channel: goal[channel]}, tolerance, specs):
            continue
        j = list(channels).index(channel)
        gain = _needed_change(values, goal[channel], channel, specs[channel]) * effects[:, j]
        able = [
            k
            for k in np.argsort(-gain, kind="stable").tolist()
            if gain[k] > 0
            and gain[k] >= 0.1 * gain.max()
            and channel in goal_channels[k]
            and k not in unable
        ]
        if able and not any(k in able for k in planned):
            fix = int(able[0])
            if planned and follows(fix, planned[0]):
                # in the demonstrations it comes after the plan's first component
                # (e.g. approach after turn): the plan runs first, a repair after it
                continue
            return fix
    return None


def stops_at_rest(model: Any) -> bool:
    """Whether a model's runs stop at rest: an SBLM's ``stop_at_rest``, a CBLM's when
    any of its components' runs do."""
    components = getattr(model, "components_", None)
    if components is not None:
        return any(stops_at_rest(component) for component in components)
    return bool(getattr(model, "stop_at_rest", False))


def repair_candidates(
    goal: Mapping[str, float],
    values: Mapping[str, float],
    specs: Mapping[str, ChannelSpec],
    channels: Sequence[str],
    effects: FloatArray,
    goal_channels: Sequence[Collection[str]],
    unable: Collection[int] = (),
) -> list[int]:
    """Repair rule: the components to try, in order, when the plan ends short of the goal.

    For each goal channel outside its tolerance (in the goal's order), the components
    whose own goal states that channel and whose learned effect closes the gap, the
    largest effect first; those in ``unable`` are left out. A component can appear once
    per missed channel (the caller skips one that has failed meanwhile).

    Parameters
    ----------
    goal, values, specs, channels, effects, goal_channels, unable
        As for :func:`preempting_component`.
    """
    order: list[int] = []
    for channel in goal:
        if within_tolerance(values, {channel: goal[channel]}, specs=specs):
            continue
        j = list(channels).index(channel)
        needed = _needed_change(values, goal[channel], channel, specs[channel])
        for comp in (int(k) for k in np.argsort(-needed * effects[:, j], kind="stable")):
            if (
                channel not in goal_channels[comp]
                or comp in unable
                or needed * effects[comp, j] <= 0
            ):
                continue
            order.append(comp)
    return order


#: A component *needs* an input its demonstrations start it within this many tolerances of
#: (the width of its reach); it is within its reach up to this many tolerances outside.
REACH_WIDTH_TOLERANCES = 2.0
REACH_MARGIN_TOLERANCES = 0.5


class _Reach:
    """Where a component starts on one input, beside the current reading (reach rule).

    ``value`` is the reading (its magnitude for an angle, as ``reach`` is); ``None`` from
    :meth:`of` when the input has no tolerance or the component never starts.
    """

    def __init__(self, lo: float, hi: float, tolerance: float, value: float) -> None:
        self.lo, self.hi, self.tolerance, self.value = lo, hi, tolerance, value

    @classmethod
    def of(
        cls, bounds: FloatArray, channel: str, values: Mapping[str, float], spec: ChannelSpec
    ) -> _Reach | None:
        lo, hi = (float(v) for v in bounds)
        if spec.tolerance is None or not (np.isfinite(lo) and np.isfinite(hi)):
            return None
        value = abs(values[channel]) if spec.wraps else values[channel]
        return cls(lo, hi, float(spec.tolerance), value)

    @property
    def narrow(self) -> bool:
        """The component starts at one place on this input: it needs it."""
        return self.hi - self.lo <= REACH_WIDTH_TOLERANCES * self.tolerance

    @property
    def inside(self) -> bool:
        """The reading lies within the reach's margin."""
        margin = REACH_MARGIN_TOLERANCES * self.tolerance
        return self.lo - margin <= self.value <= self.hi + margin


def reach_fix(
    comp: int,
    values: Mapping[str, float],
    specs: Mapping[str, ChannelSpec],
    channels: Sequence[str],
    effects: FloatArray,
    reach: FloatArray,
    goal_channels: Sequence[Collection[str]],
    goals: Sequence[Mapping[str, float]],
    unable: Collection[int] = (),
) -> int | None:
    """Reach rule: the component to run before ``comp``, which is out of its reach here.

    A component *needs* an input when its demonstrations start it within about that
    channel's tolerance (``reach`` no wider than two tolerances) and it does not move
    the channel itself (its effect under a tenth of the largest). Grasp, for one,
    starts with the object 4 mm ahead and never moves the wheels. Where such a channel
    lies more than half a tolerance outside the reach, the component whose own goal
    states the channel, whose effect brings it back and whose goal does not already hold
    runs first (the largest such effect).

    Parameters
    ----------
    comp
        The component about to run, or running.
    values
        The current (filtered) readings, physical units.
    specs, channels, effects, goal_channels, unable
        As for :func:`preempting_component`.
    reach
        ``(components, channels, 2)``: where each component starts (``CBLM.reach_``;
        of the magnitude for an angle).
    goals
        Per component, its own goal (physical units).

    Returns
    -------
    int or None
        The component to run first; ``None``: ``comp`` is within its reach, or no
        component can bring it there.
    """
    for j, channel in enumerate(channels):
        where = _Reach.of(reach[comp, j], channel, values, specs[channel])
        if where is None or not where.narrow:
            continue  # it starts anywhere on this channel: it does not need it
        scale = float(np.max(np.abs(effects[:, j])))
        if abs(effects[comp, j]) > 0.1 * scale:
            continue  # it moves this channel itself
        if where.inside:
            continue
        gain = (1.0 if where.value < where.lo else -1.0) * effects[:, j]
        for k in np.argsort(-gain, kind="stable").tolist():
            if (
                k != comp
                and gain[k] > 0
                and channel in goal_channels[k]
                and k not in unable
                and not within_tolerance(values, {channel: goals[k][channel]}, specs=specs)
            ):
                return int(k)
    return None


def not_begun(
    comp: int,
    values: Mapping[str, float],
    specs: Mapping[str, ChannelSpec],
    channels: Sequence[str],
    reach: FloatArray,
    goal_channels: Sequence[Collection[str]],
) -> bool:
    """Reach rule: whether a running component has not yet begun its own work.

    True while every input its goal states still lies where its demonstrations start it
    (within half a tolerance of ``reach``), and they start it at one place on at least
    one of them (a reach no wider than two tolerances): a grasp that has opened its
    fingers but not yet lowered its arm. Only until then is a running component held to
    its reach (:func:`reach_fix`): once begun, it moves what it needs (the object rides
    in its fingers). An approach, started anywhere on its goal's distance, has always
    begun.
    """
    placed = False
    for j, channel in enumerate(channels):
        if channel not in goal_channels[comp]:
            continue
        where = _Reach.of(reach[comp, j], channel, values, specs[channel])
        if where is None:
            continue
        if not where.inside:
            return False
        placed = placed or where.narrow
    return placed


def undone(
    finished: Mapping[int, Mapping[str, float]],
    values: Mapping[str, float],
    specs: Mapping[str, ChannelSpec],
) -> list[int]:
    """Repair rule: the finished components whose goal no longer holds (e.g. after a push)."""
    return [
        comp
        for comp, sub_goal in finished.items()
        if not within_tolerance(values, sub_goal, specs=specs)
    ]


def already_reached(
    sub_goal: Mapping[str, float],
    values: Mapping[str, float],
    specs: Mapping[str, ChannelSpec],
) -> bool:
    """Skip rule: whether the goal a planned component would run toward already holds.

    Such a component would hand back the cycle it starts; replacing the running one
    with it only stops the robot (``skip_reached``). Under sensor noise the plan can ask
    for it where the filtered readings cross the border of the categories the
    demonstrations switched at: an approach on its bearing, replaced by a turn to that
    bearing. An empty goal never counts as reached.
    """
    return bool(sub_goal) and within_tolerance(values, sub_goal, specs=specs)


def settles_in_goal(
    child: Any,
    goal: Mapping[str, float],
    tolerance: float,
    specs: Mapping[str, ChannelSpec],
) -> bool:
    """Settle rule: whether a running component may finish inside the complex goal.

    ``child`` (a component's controller: ``braked``, ``braking``, ``goal`` and its
    model's ``default_goal_``) heads for a goal inside the complex goal's tolerance
    and is braking into it, or heads for the goal its demonstrations stop at (a goal
    they only pass at speed, e.g. an approach to 0.5 m, is not one to settle in). One
    braked to rest inside the goal is done.
    """
    if child.braked:
        return False  # a component braked to rest inside the goal is done
    shared = {c: g for c, g in goal.items() if c in child.goal}
    if not shared or not within_tolerance(child.goal, shared, tolerance, specs):
        return False
    own = child.model.default_goal_
    return bool(child.braking) or within_tolerance(child.goal, own, specs=specs)


def on_the_way(
    sub_goal: dict[str, float],
    values: Mapping[str, float],
    goal: Mapping[str, float],
    specs: Mapping[str, ChannelSpec],
) -> dict[str, float]:
    """Forward-goals rule: ``sub_goal`` with no channel sent back, away from ``goal``.

    An intermediate goal is its exit category's prototype, which is coarse: from
    0.49 m toward 0.63 m the turn & approach before a retreat is handed 0.39 m, and
    would approach 10 cm only for the retreat to undo it. A channel the complex goal
    states (other than a wrapping one, an angle, whose sign is no direction) whose
    sub-goal lies behind the robot, away from the goal, keeps its current value
    instead (``sub_goal`` is changed in place and returned).
    """
    for channel, target in sub_goal.items():
        if channel not in goal or specs[channel].wraps:
            continue
        now = values[channel]
        if (target - now) * (goal[channel] - now) < 0.0:
            sub_goal[channel] = now
    return sub_goal


class ComplexPolicy(GoalTracking, RateLimited):
    """A CBLM's policy: plans over its own observation categories, delegates to components.

    Each cycle it categorizes the current observation window with its own CobART,
    plans the most likely observation path to the goal category and decodes the
    component sequence (Viterbi). The first planned component that has not yet
    reached its intermediate goal runs, with the exit observation of its segment as
    its goal, in the component's own channels. Because the plan is remade every
    cycle, a push that undoes a finished component's work brings that component back.
    The run ends when the goal category is reached and the readings lie within the
    goal's physical tolerance, or when the plan has nothing left to run and the
    tolerance holds.

    The run state is :attr:`phase` (:class:`Phase`); each change of it is one method
    (``_start``, ``_carry_on``, ``_settle``, ``_hand_back``, ``_skip``, ``_wait``,
    ``_reopen``, and the stop in :meth:`step`). The CBLM's runtime additions are rules
    that can be tested alone: :class:`Debounce`, :func:`preempting_component`,
    :func:`repair_candidates`, :func:`undone`, :func:`already_reached`,
    :func:`settles_in_goal`, :func:`on_the_way`, :func:`reach_fix` and :func:`not_begun`.

    Parameters
    ----------
    model
        A fitted :class:`~behavior_hmm.models.CBLM`.
    goal
        Goal in physical units on the CBLM's inputs; ``None`` uses its default.
    name
        Name recorded in traces when this CBLM is itself a component.
    tolerance
        Scale of the goal's physical tolerance (a parent's repair asks for 0.5).
    """

    def __init__(
        self,
        model: Any,
        goal: Mapping[str, float] | None,
        name: str = "",
        tolerance: float = 1.0,
    ) -> None:
        self.model = model
        self.name = name
        self._tolerance = float(tolerance)
        self._set_goal(model, goal)
        #: the goal confirmed on the raw readings at rest when they are noisy, if the
        #: readings can show rest (``bind``)
        self._confirmation = GoalConfirmation(self.channel_specs)
        self._rest_readable = True
        #: confirming is part of stopping at rest (``SBLM.stop_at_rest``): on when the
        #: components stop at rest (the thesis preset's do not), and off for a component
        #: of a higher CBLM (``confirm_goal``: that one confirms its own goal)
        self._confirms = stops_at_rest(model)
        self.confirm_goal = True
        self._channels = tuple(model.inputs_)
        self.channels = read_channels(model)
        self._pipe = model.pipeline_.online()
        self._live = model.observations_.stream()
        norm = model.pipeline_.normalizer
        self._lo = np.array(norm.lo, dtype=np.float64)
        self._gain = np.array(norm.gain, dtype=np.float64)
        # the CBLM's runtime additions (each off in the thesis preset)
        self._may_repair = bool(model.repair)
        self._may_preempt = bool(model.preempt_uncovered)
        self._debounce = Debounce(int(model.switch_cycles))
        self._skip_reached = bool(getattr(model, "skip_reached", False))
        self._alternatives = int(model.start_alternatives)
        self._settle_cycles = int(getattr(model, "settle_cycles", 0))
        self._forward = bool(getattr(model, "forward_goals", False))
        #: where each component starts (``CBLM.reach_``); None: no reach check
        reach = getattr(model, "reach_", None)
        self._reach = reach if bool(getattr(model, "reach_check", False)) else None
        pause = bool(getattr(model, "handover_pause", False))
        self._handover = int(getattr(model, "handover_cycles_", 0)) if pause else 0
        #: per component, the channels its own goal states (the rules' ``goal_channels``)
        self._goal_channels = [tuple(c.default_goal_) for c in model.components_]
        # one controller per component, built now (before any motion) and renewed with
        # each intermediate goal: building one takes ~0.5 ms, too long inside a cycle
        self._children: dict[int, Any] = {
            k: make_policy(component, None, name=model.names_[k])
            for k, component in enumerate(model.components_)
        }
        self.noisy_readings = None
        for child in self._children.values():
            # whether the readings are noisy is this policy's to judge (its components
            # do not confirm their goals, so keep no noise estimate of their own)
            child.noisy_readings = self._noisy
            if hasattr(child, "start_confirm_cycles"):
                # the complex level checks its own goal before it runs a component
                child.start_confirm_cycles = 0
            if hasattr(child, "confirm_goal"):  # and confirms its own goal at the end
                child.confirm_goal = False
            if hasattr(child, "start_alternatives"):
                # a simple component that cannot plan from its best-matching start tries
                # the next plannable ones, as this behavior's own start does
                child.start_alternatives = self._alternatives
            if isinstance(child, ComplexPolicy):
                # a complex component with no plan to its intermediate goal from where the
                # robot is gets skipped, and this plan picks the next: a runner-up start of
                # its own describes another place (nested position from 0 m: one 0.2 m
                # away, whose plan approached and never retreated)
                child._alternatives = 0
        rate = float(getattr(model, "command_rate_limit", 0.0))
        self._rate = rate * float(getattr(model, "delta_scale_", 0.0))
        # per command channel: the step limit in each channel's own scale (wheels: equal)
        relative = np.asarray(model.command_scales_) / float(model.command_scale_)
        self._rates = self._rate * relative
        self._rest_command = model.rest_command
        self._limit_motion = False  # the components limit their own commands
        #: the component run beside the planned one, per observation category (None: the
        #: model runs one at a time); command directions and scales to fuse their commands
        partners: NDArray[np.int64] | None = getattr(model, "parallel_", None)
        self._partners = None
        if bool(getattr(model, "parallel", False)) and partners is not None:
            self._partners = partners if bool(np.any(partners >= 0)) else None
        self._directions = getattr(model, "directions_", None)
        self._scales = np.asarray(model.command_scales_, dtype=np.float64)
        #: the (component, partner) pairs the demonstrations ran at once: a partner's
        #: categories, and the component whose rows they are (emission counts)
        self._pairs: set[tuple[int, int]] = set()
        if self._partners is not None:
            counts = model.hmm_.B_counts_.tocsc()
            for k in np.flatnonzero(self._partners >= 0).tolist():
                emitting = counts.indices[counts.indptr[k] : counts.indptr[k + 1]]
                partner = int(self._partners[k])
                self._pairs.update((int(a), partner) for a in emitting if a != partner)
        self.reset()

    def reset(self) -> None:
        """Forget the previous run."""
        self._pipe.reset()
        self._live.reset()
        self._phase = Phase.CHOOSING
        # the component bookkeeping: the last one started, and those whose goal holds
        self._active = -1
        self._child: Any = None
        self._finished: dict[int, dict[str, float]] = {}
        self._unable: set[int] = set()  # cannot start from the current category
        self._reachable_from = -1
        self._handed_back = False  # a component finished, and no cycle has decided since
        self._committed = False  # the running one closes a gap the plan missed (pre-emption)
        self._redo = False  # the active component's goal was undone after it finished
        self._debounce.clear()
        self._settled = 0  # cycles spent settling (at most settle_cycles a run)
        self._pause_left = 0  # cycles of the handover pause still to rest
        self._beside = -1  # the component running beside the active one (-1: none)
        self._beside_from = 0.0  # the active one's goal error when it started
        self._wanted = -1  # the plan's component, to run beside the one pre-empting it
        self._now: Mapping[str, float] = {}  # this cycle's filtered readings
        self._reading: Mapping[str, float] = {}  # this cycle's raw readings
        self._confirmation.reset()
        self._limit_reset()

    @property
    def onset_cycles(self) -> int:
        """0: a complex behavior has no onset clock (its components keep their own)."""
        return 0

    def moved_within_tolerance(self) -> bool:
        """False: a complex behavior run as a component keeps the pause after it."""
        return False

    def resume_onset(self, cycles: int) -> None:
        """Nothing to resume: a complex behavior run again as a component of another
        starts its components anew (see :meth:`SimplePolicy.resume_onset`)."""

    @property
    def phase(self) -> Phase:
        """The run state now (see :class:`Phase`)."""
        return self._phase

    @property
    def braking(self) -> bool:
        """Whether the running component is ramping to rest short of its goal.

        A complex behavior brakes through its components; a parent that runs this one
        as a component lets it finish braking into the parent's goal (``settle_cycles``).
        """
        child = self._mid_run()
        return child is not None and bool(child.braking)

    @property
    def braked(self) -> bool:
        """Whether the running component has braked to rest (it waits for its goal)."""
        child = self._mid_run()
        return child is not None and bool(child.braked)

    def _mid_run(self) -> Any:
        """The controller of the component whose run has not finished (None: none).

        A stop at the goal does not finish it: braking still reads the component whose
        run the stop cut short.
        """
        if self._child is None or self._active in self._finished:
            return None
        return self._child

    def _running(self) -> Any:
        """The controller of the component running now (None: none runs)."""
        return self._child if self._phase in _COMPONENT_PHASES else None

    def bind(self, channels: Sequence[str]) -> None:
        """Fit every component's policy to a robot's ``channels`` (see SimplePolicy.bind)."""
        #: the readings can show rest: a goal is confirmed on noisy readings at rest
        self._rest_readable = all(c in channels for c in REST_CHANNELS)
        names = list(self._channels)
        for child in self._children.values():
            if hasattr(child, "bind"):
                child.bind(channels)
            names += [c for c in child.channels if c not in names]
        self.channels = ordered_channels(names)

    # -- one control cycle ---------------------------------------------------------------

    def step(self, reading: Mapping[str, float]) -> StepOutput:
        """Decide the command for one reading ``{channel: value}`` (physical units).

        With the model's ``command_rate_limit`` a new component continues from the
        running command (each component limits its own change per cycle), and the
        complex behavior stops softly when it is slow at its goal.
        """
        if self._phase is Phase.STOPPING:  # ramping down at the goal
            assert self._stopping is not None
            return self._limited(self._stopping)
        out = self._limited(self._decide(reading))
        if self._stopping is not None:  # done, and slow enough to ramp down
            self._phase = Phase.STOPPING
        return out

    def _decide(self, reading: Mapping[str, float]) -> StepOutput:
        x = self._pipe.step(np.array([reading[c] for c in self._channels], dtype=np.float64))
        category, novel, _ = self._live.update(x)
        if category != self._reachable_from:
            category = self._plannable(category)
            self._unable.clear()  # a component unable to reach the goal may be able now
        values = self._values(reading, x)
        self._now = values
        self._reading = reading
        if self._keeps_noise():
            self._confirmation.observe(reading, self.goal)
        if self._confirmation.pending:  # the goal being confirmed: until it is decided
            return self._done(category, novel)
        at_goal = not self._confirmation.holding and within_tolerance(
            values, self.goal, self._tolerance, self.channel_specs
        )
        if self._phase is Phase.PAUSED and not at_goal:
            return self._wait(category, novel)
        if at_goal and self._settles_in_goal():
            return self._settle(reading, category, novel)
        braked = self._child is not None and self._child.braked
        if at_goal and (category in self._stop_set or self._handed_back or braked):
            # the goal category with the goal's tolerance (thesis + DESIGN §5), or a
            # component has just finished with the complex goal's tolerance holding
            return self._done(category, novel)
        self._handed_back = False
        # a finished component whose goal no longer holds (e.g. after a push) runs again
        for comp in undone(self._finished, values, self.channel_specs):
            self._reopen(comp)
        segments = self._open_segments(category)
        if not segments:
            return self._plan_exhausted(values, reading, category, novel, at_goal)
        return self._follow_plan(segments, values, reading, category, novel)

    def _open_segments(self, category: int) -> list[Any]:
        """The plan's segments whose component has not finished (none: no plan, mid-run)."""
        try:
            plan = self.model.hmm_.plan(category, self.goal_category)
        except UnreachableGoalError:
            if self._child is None:
                raise
            return []
        return [s for s in plan.segments if s.state not in self._finished]

    def _plan_exhausted(
        self,
        values: Mapping[str, float],
        reading: Mapping[str, float],
        category: int,
        novel: bool,
        at_goal: bool,
    ) -> StepOutput:
        """Nothing left in the plan: the running component goes on, or the run ends."""
        if self._running() is not None:
            return self._carry_on(reading, category, novel)
        if at_goal:  # nothing left to run and the goal holds
            return self._done(category, novel)
        if not self._may_repair:  # thesis: stand still until the step limit
            return self._idle(category, novel)
        # The plan is exhausted short of the goal (e.g. an approach drifted off the
        # bearing): run the component whose own goal covers the channel that misses its
        # tolerance, toward the complex goal on its channels.
        return self._repair(values, reading, category, novel)

    def _follow_plan(
        self,
        segments: list[Any],
        values: Mapping[str, float],
        reading: Mapping[str, float],
        category: int,
        novel: bool,
    ) -> StepOutput:
        """Run the plan's first open segment's component (pre-emption and debounce first)."""
        segment = segments[0]
        running = self._running() is not None
        if running and self._committed:
            # a component run to close a gap the plan missed finishes its job first
            return self._carry_on(reading, category, novel)
        if not running and self._may_preempt:
            out = self._preempt(values, [s.state for s in segments], reading, category, novel)
            if out is not None:
                return out
        if self._reach is not None:
            out = self._out_of_reach(segment.state, running, values, reading, category, novel)
            if out is not None:
                return out
        replaces = running and segment.state != self._active
        if replaces and self._debounce.holds(segment.state):
            return self._carry_on(reading, category, novel)
        if replaces and self._unfinished(segment.state, values):
            return self._carry_on(reading, category, novel)
        sub_goal = None
        if replaces and self._skip_reached:
            sub_goal = self._segment_goal(segment, values)
            if already_reached(sub_goal, values, self.channel_specs):
                # it would hand back at once: the running one goes on, and the plan has
                # to insist afresh once that goal no longer holds
                self._debounce.clear()
                return self._carry_on(reading, category, novel)
        self._debounce.clear()
        self._committed = False
        if segment.state == self._active and not self._redo:  # carry on (an intermediate
            return self._carry_on(reading, category, novel)  # goal: a new one)
        renew, self._redo = self._redo, False
        if sub_goal is None:
            sub_goal = self._segment_goal(segment, values)
        return self._start(segment.state, sub_goal, reading, category, novel, renew)

    def _segment_goal(self, segment: Any, values: Mapping[str, float]) -> dict[str, float]:
        """The goal a plan segment's component runs toward: its exit observation's
        (the complex goal's at the last segment), never sent back (:meth:`_on_the_way`)."""
        sub_goal = self.model.component_goal(
            segment.state,
            segment.exit_observation,
            self.goal,
            final=segment.exit_observation in self._goal_set,
        )
        return self._on_the_way(sub_goal, values)

    def _preempt(
        self,
        values: Mapping[str, float],
        planned: list[int],
        reading: Mapping[str, float],
        category: int,
        novel: bool,
    ) -> StepOutput | None:
        """Start a component that closes a gap the plan misses (None: none, or it cannot)."""
        fix = self._uncovered(values, planned)
        if fix is None:
            return None
        sub_goal = {
            c: self.goal.get(c, v) for c, v in self.model.components_[fix].default_goal_.items()
        }
        before = self._child, self._active, self._phase, self._finished.get(fix)
        out, started = self._start_checked(fix, sub_goal, reading, category, novel, renew=True)
        if started:
            self._committed = True
            # the plan asked for another component; where the demonstrations ran the two
            # at once (parallel), it runs beside the one closing the gap
            self._wanted = planned[0] if (fix, planned[0]) in self._pairs else -1
            return out
        # it cannot start from here (e.g. a nested turn & approach asked to back away):
        # the plan goes on as if it had not been tried, or the robot would try it again
        # every cycle and never move
        self._unable.add(fix)
        self._child, self._active, self._phase, fix_goal = before
        if fix_goal is None:
            del self._finished[fix]
        else:
            self._finished[fix] = fix_goal
        return None

    def _out_of_reach(
        self,
        planned: int,
        running: bool,
        values: Mapping[str, float],
        reading: Mapping[str, float],
        category: int,
        novel: bool,
    ) -> StepOutput | None:
        """Run first what brings the running or the planned component into its reach.

        (:func:`reach_fix`; None: both are within it, or nothing can bring them.) Only
        a component that holds some commands at rest (``held_commands_``: a grasp, the
        wheels) is held to its reach: it cannot bring back what they move. The running
        one is held to it until it has begun (:func:`not_begun`), the planned one before
        it starts. The component run for it finishes its job (``_committed``) before the
        plan goes on.
        """
        reach = self._reach
        assert reach is not None
        held = []
        if running and not_begun(
            self._active, values, self.channel_specs, self._channels, reach, self._goal_channels
        ):
            held.append(self._active)
        if not running or planned != self._active:
            held.append(planned)
        goals = [c.default_goal_ for c in self.model.components_]
        for comp in held:
            if not getattr(self.model.components_[comp], "held_commands_", ()):
                # it commands everything the robot moves: it can bring back what it needs
                continue
            fix = reach_fix(
                comp,
                values,
                self.channel_specs,
                self._channels,
                self.model.effects_,
                reach,
                self._goal_channels,
                goals,
                unable=self._unable,
            )
            if fix is None:
                continue
            sub_goal = {c: self.goal.get(c, v) for c, v in goals[fix].items()}
            renew = not (running and fix == self._active)
            out, started = self._start_checked(fix, sub_goal, reading, category, novel, renew)
            if started:
                self._committed = True
                self._debounce.clear()
                return out
            self._unable.add(fix)
        return None

    # -- transitions -----------------------------------------------------------------------

    def _wait(self, category: int, novel: bool) -> StepOutput:
        """PAUSED: rest one cycle of the handover pause (then CHOOSING)."""
        self._pause_left -= 1
        if self._pause_left <= 0:
            self._phase = Phase.CHOOSING
        label = self._label or self.name
        return StepOutput(self._rest_command, category, novel, self._active, label, False, False)

    def _settle(self, reading: Mapping[str, float], category: int, novel: bool) -> StepOutput:
        """SETTLING: the running component heads for a goal inside the tolerance.

        It finishes (at rest, braking into it) rather than the robot stopping at speed.
        """
        self._settled += 1
        self._phase = Phase.SETTLING
        return self._run_child(reading, category, novel, changed=False)

    def _carry_on(self, reading: Mapping[str, float], category: int, novel: bool) -> StepOutput:
        """RUNNING: the current component goes on for one more cycle.

        One whose goal was undone after it finished (:meth:`_reopen`) starts afresh
        toward that goal: its controller has ended and would report it reached at once
        (the component handed back and was reopened every cycle, a robot at rest 3.25 deg
        off until the step limit).
        """
        if self._redo:
            self._redo = False
            goal = dict(self._child.goal)
            return self._start(self._active, goal, reading, category, novel, renew=True)
        self._phase = Phase.RUNNING
        return self._run_child(reading, category, novel, changed=False)

    def _reopen(self, comp: int) -> None:
        """A finished component's goal is undone: it may run again.

        The last one to run has stopped its controller: it runs again (RUNNING), and
        starts afresh the next cycle it runs: toward the plan's goal for it when the plan
        chooses it, toward its own goal when it is carried on (:meth:`_carry_on`).
        """
        del self._finished[comp]
        if comp == self._active:
            self._redo = True
            self._phase = Phase.RUNNING

    def _start(
        self,
        comp: int,
        sub_goal: dict[str, float],
        reading: Mapping[str, float],
        category: int,
        novel: bool,
        renew: bool = False,
        tolerance: float = 1.0,
    ) -> StepOutput:
        """RUNNING: run component ``comp`` toward ``sub_goal`` (a fresh controller if new)."""
        return self._start_checked(comp, sub_goal, reading, category, novel, renew, tolerance)[0]

    def _start_checked(
        self,
        comp: int,
        sub_goal: dict[str, float],
        reading: Mapping[str, float],
        category: int,
        novel: bool,
        renew: bool = False,
        tolerance: float = 1.0,
    ) -> tuple[StepOutput, bool]:
        """:meth:`_start`, and whether the component could start (no UnreachableGoalError)."""
        if comp == self._beside and comp != self._active:
            # the plan hands over to the component already running beside: it goes on
            self._child, self._active, self._beside = self._children[comp], comp, -1
            self._phase = Phase.RUNNING
            return self._run_child_checked(reading, category, novel, True)
        changed = comp != self._active or renew
        if changed:
            self._beside = self._wanted = -1  # another component: whatever ran beside stops
            child = self._children[comp]
            # the component that ran last, run again: it resumes (its onset clock goes on)
            elapsed = child.onset_cycles if comp == self._active else 0
            child.renew(sub_goal, tolerance)  # as a new controller, without building one
            self._child = child
            self._child.reset()
            if self._noisy() and readings_at_rest(self._reading):
                # its filters start where this one's readings are (filtered, or their
                # mean at rest), not at one noisy reading
                self._child.start_at(self._now)
            self._child.carry(self._last)
            if elapsed:
                self._child.resume_onset(elapsed)
            self._active = comp
        # a component started while its goal still counts as reached runs this cycle only
        self._phase = Phase.CHOOSING if comp in self._finished else Phase.RUNNING
        return self._run_child_checked(reading, category, novel, changed)

    def _hand_back(self, at_rest: bool) -> None:
        """The running component reached its goal: PAUSED (it ended at rest) or CHOOSING."""
        self._finished[self._active] = dict(self._child.goal)
        if at_rest and self._beside < 0 and not self._stayed():  # the teacher's pause
            self._pause_left = self._handover
        self._phase = Phase.PAUSED if self._pause_left > 0 else Phase.CHOOSING
        self._handed_back = True
        self._committed = False

    def _stayed(self) -> bool:
        """Whether the component that ends ran only on the readings' noise: they are
        noisy, and its commands moved none of its goal channels by their tolerance. The
        teacher pauses after a component it needed; after this one the next starts at once.
        Clean readings keep every pause (a turn of 0.5 deg is the teacher's too)."""
        return self._noisy() and self._child.moved_within_tolerance()

    def _skip(self) -> FloatArray:
        """The running component cannot reach its goal from here: CHOOSING, and the rest command.

        It counts as finished (the plan goes on without it) and, should it run again, goes
        on from this command.
        """
        self._finished[self._active] = dict(self._child.goal)
        self._phase = Phase.CHOOSING
        rest = self._rest()
        self._child.carry(rest)
        return rest

    # -- outputs ---------------------------------------------------------------------------

    def _done(self, category: int, novel: bool) -> StepOutput:
        """The step that ends the run at the goal: the rest command, done.

        On noisy readings the goal is first confirmed on the raw readings at rest
        (:class:`GoalConfirmation`): the robot holds still meanwhile, and a refuted goal
        is repaired from where the readings' mean puts the robot (:meth:`_repair`).
        """
        label = self._label or self.name
        confirming = self._keeps_noise() and self._rest_readable
        if confirming and not self._confirmation.noise_known(self.goal):
            # a run that starts at its goal: not before the readings' noise is known
            return self._idle(category, novel)
        if confirming and self._confirmation.needed(self.goal, self._tolerance):
            if not self._confirmation.pending:
                if not readings_at_rest(self._reading):  # come to rest first
                    return self._idle(category, novel)
                self._confirmation.begin()  # then every reading counts until it is decided
            verdict = self._confirmation.confirm(self._reading, self.goal, self._tolerance)
            if verdict is None:
                return self._idle(category, novel)
            if not verdict:
                # the mean of the readings at rest: the repair starts from it
                estimate = {**self._now, **self._confirmation.estimate}
                self._now = estimate
                return self._repair(estimate, self._reading, category, novel)
        return StepOutput(self._rest_command, category, novel, self._active, label, False, True)

    def _idle(self, category: int, novel: bool) -> StepOutput:
        """A cycle without a component: toward rest (see :meth:`_rest`)."""
        return StepOutput(self._rest(), category, novel, self._active, self.name, False, False)

    def _run_child(
        self, reading: Mapping[str, float], category: int, novel: bool, changed: bool
    ) -> StepOutput:
        return self._run_child_checked(reading, category, novel, changed)[0]

    def _run_child_checked(
        self, reading: Mapping[str, float], category: int, novel: bool, changed: bool
    ) -> tuple[StepOutput, bool]:
        """One cycle of the current component, and whether it could run (it may raise)."""
        try:
            out = self._child.step(reading)
        except UnreachableGoalError:
            # the component cannot reach its intermediate goal from here: skip it
            rest = self._skip()
            return StepOutput(rest, category, novel, self._active, self.name, changed, False), False
        if self._partners is not None and self._phase is Phase.RUNNING:
            out = self._with_beside(out, reading, category)
        if out.done:
            self._hand_back(self._at_rest_command(out.command))
        label = out.component or self.model.names_[self._active]
        return StepOutput(out.command, category, novel, self._active, label, changed, False), True

    def _with_beside(self, out: StepOutput, reading: Mapping[str, float], category: int) -> Any:
        """``out`` of the active component fused with the one the demonstrations ran
        beside it here (CBLM ``parallel``), started when the category first asks for it.

        The fused command is the active component's along its own command direction plus
        the other's along its own, the other's weighted by the share of the active
        component's goal error closed since the other started (:meth:`_goal_error`).
        """
        assert self._partners is not None and self._directions is not None
        active = self._active
        if self._beside < 0:
            partner = int(self._partners[category]) if 0 <= category < len(self._partners) else -1
            if partner < 0:
                partner = self._wanted
            if partner < 0 or partner == active or partner in self._finished:
                return out
            child = self._children[partner]
            own = self.model.components_[partner].default_goal_
            child.renew({c: self.goal.get(c, v) for c, v in own.items()}, 1.0)
            child.reset()
            child.carry(self._last)
            self._beside, self._beside_from = partner, self._goal_error(active)
        beside = self._beside
        try:
            other = self._children[beside].step(reading)
        except UnreachableGoalError:
            return out  # no plan for it from here this cycle: the active one runs alone
        if other.done:  # its goal holds: it stops, and counts as finished
            self._finished[beside] = dict(self._children[beside].goal)
            self._beside = -1
            return out
        start = self._beside_from
        weight = 1.0 if start <= 0.0 else min(1.0, max(0.0, 1.0 - self._goal_error(active) / start))
        rest = self._rest_command
        mine = self._directions[active]
        theirs = self._directions[beside]
        u = (out.command - rest) / self._scales
        v = (other.command - rest) / self._scales
        fused = mine * float(u @ mine) + weight * theirs * float(v @ theirs)
        names = self.model.names_
        label = f"{out.component or names[active]}+{other.component or names[beside]}"
        return out._replace(command=rest + fused * self._scales, component=label)

    def _goal_error(self, component: int) -> float:
        """How far the filtered readings are from ``component``'s goal: the largest error
        over its goal channels, in units of their tolerance."""
        child = self._children[component]
        errors = [
            abs(self.channel_specs[c].error(self._now[c], g))
            / (float(self.channel_specs[c].tolerance or 0.0) or 1.0)
            for c, g in child.goal.items()
            if c in self._now
        ]
        return max(errors, default=0.0)

    # -- helpers ---------------------------------------------------------------------------

    def _plannable(self, category: int) -> int:
        """``category``, or the next-best match of the current window a plan can start from.

        A window between two demonstrated starts can match best a category from which
        no demonstration led to the goal; the categories a plan to a goal candidate
        starts from are tried, best match of the window first (at most the model's
        ``start_alternatives``), before giving up (UnreachableGoalError before any
        motion). Only those: a CBLM that learned two tasks from demonstrations on
        different grids (turn & approach every 20 deg, position every 40 deg) has start
        windows that match tens of the one task's categories better than any from
        which the other's demonstrations reached its goal.
        """
        hmm = self.model.hmm_
        try:
            retarget(self, hmm, category, may_raise=True, most_likely=True)
            return category
        except UnreachableGoalError:
            if self._child is not None:
                return category  # carry on with the running component
            alternative = self.alternative_start(
                hmm, category, self._alternatives, most_likely=True
            )
            if alternative < 0:
                raise
            return alternative

    def _values(self, reading: Mapping[str, float], x: FloatArray) -> dict[str, float]:
        filtered = (x + 1.0) / self._gain + self._lo
        values = dict(reading)
        values.update(zip(self._channels, filtered.tolist(), strict=True))
        return values

    def _on_the_way(
        self, sub_goal: dict[str, float], values: Mapping[str, float]
    ) -> dict[str, float]:
        """``sub_goal``; with ``forward_goals``, no channel sent back (:func:`on_the_way`)."""
        if not self._forward:  # thesis: the prototype as it is
            return sub_goal
        return on_the_way(sub_goal, values, self.goal, self.channel_specs)

    def _rest(self) -> FloatArray:
        """The command when no component runs this cycle: toward rest at the rate limit.

        The components limit their own commands; a cycle without one (a component that
        cannot start, nothing left to run) would otherwise drop the wheels to zero at
        once, however fast the robot was moving (thesis preset: zero).
        """
        return self._ramped_down() if self._rate > 0.0 else self._rest_command

    def _settles_in_goal(self) -> bool:
        """Whether the running component may finish inside the goal (``settle_cycles``)."""
        child = self._running()
        if child is None or self._settled >= self._settle_cycles:
            return False
        return settles_in_goal(child, self.goal, self._tolerance, self.channel_specs)

    def _uncovered(self, values: Mapping[str, float], planned: list[int]) -> int | None:
        """A component to run first, for a gap the plan cannot close (see the rule).

        :func:`preempting_component` with this policy's goal, model and state.
        """
        return preempting_component(
            self.goal,
            values,
            self.channel_specs,
            self._channels,
            self.model.effects_,
            self._goal_channels,
            planned,
            self._follows,
            unable=self._unable,
            tolerance=self._tolerance,
        )

    def _unfinished(self, comp: int, values: Mapping[str, float]) -> bool:
        """Noise rule: whether the running component goes on although the plan asks for
        ``comp``, because the readings are noisy, its own goal does not hold yet, and the
        demonstrations switch from it to ``comp`` (more than back): they ended it at its
        goal before they began ``comp``.

        Sensor noise carries the observation window across the categories where the
        demonstrations switched: turn & approach from -12 deg, 0.46 m (MuJoCo, noise
        0.01) had its turn replaced by the approach 6 deg off the bearing, and the turn
        run again from rest after the approach had turned the robot. A switch the
        demonstrations never made (back from the approach to the turn, after a push) is
        left to the plan, and clean readings change nothing.
        """
        return (
            self._child is not None
            and self._noisy()
            and self._follows(comp, self._active)
            and not within_tolerance(values, self._child.goal, specs=self.channel_specs)
        )

    def _keeps_noise(self) -> bool:
        """Whether this policy records the readings' noise: it may confirm its goal (its
        components stop at rest, and it is no component of a higher one)."""
        return self.confirm_goal and self._confirms

    def _follows(self, component: int, other: int) -> bool:
        """Whether the demonstrations switch ``other`` -> ``component`` more than back."""
        counts = self.model.hmm_.A_counts_
        return bool(counts[other, component] > counts[component, other])

    def _repair(
        self, values: Mapping[str, float], reading: Mapping[str, float], category: int, novel: bool
    ) -> StepOutput:
        """Run a component whose goal channels cover one the complex goal misses.

        Components are tried in the order of :func:`repair_candidates`; one that cannot
        reach the goal from here (its own plan is unreachable, e.g. an approach asked to
        back away) is skipped.
        """
        candidates = repair_candidates(
            self.goal,
            values,
            self.channel_specs,
            self._channels,
            self.model.effects_,
            self._goal_channels,
            unable=self._unable,
        )
        for comp in candidates:
            if comp in self._unable:  # it failed for an earlier channel
                continue
            component = self.model.components_[comp]
            sub_goal = {c: self.goal.get(c, v) for c, v in component.default_goal_.items()}
            self._finished.pop(comp, None)
            # a repair aims well inside the tolerance, or the next drift undoes it
            out = self._start(comp, sub_goal, reading, category, novel, renew=True, tolerance=0.5)
            if comp not in self._finished:  # it runs (it neither failed nor finished at once)
                return out
            self._unable.add(comp)
        return self._idle(category, novel)


#: The phases in which a component's controller runs.
_COMPONENT_PHASES = frozenset({Phase.RUNNING, Phase.SETTLING})
