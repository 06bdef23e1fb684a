"""The policy of a complex behavior: delegation to component behaviors."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data._channels import within_tolerance
from behavior_hmm.errors import UnreachableGoalError
from behavior_hmm.models._policy import (
    GoalTracking,
    RateLimited,
    make_policy,
    read_channels,
    retarget,
)
from behavior_hmm.runtime import ordered_channels
from behavior_hmm.runtime._policy import StepOutput

FloatArray = NDArray[np.float64]


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
        self._switch_cycles = int(model.switch_cycles)
        self._alternatives = int(model.start_alternatives)
        self._settle_cycles = int(getattr(model, "settle_cycles", 0))
        self._forward = bool(getattr(model, "forward_goals", False))
        pause = bool(getattr(model, "handover_pause", False))
        self._handover = int(getattr(model, "handover_cycles_", 0)) if pause else 0
        # one controller per component, built now (before any motion) and renewed with
        # each intermediate goal: building one takes ~0.5 ms, too long inside a cycle
        self._children: dict[int, Any] = {
            k: make_policy(component, None, name=model.names_[k])
            for k, component in enumerate(model.components_)
        }
        for child in self._children.values():
            if hasattr(child, "start_confirm_cycles"):
                # the complex level checks its own goal before it runs a component
                child.start_confirm_cycles = 0
        rate = float(getattr(model, "command_rate_limit", 0.0))
        self._rate = rate * float(getattr(model, "delta_scale_", 0.0))
        # per command channel: the step limit in each channel's own scale (wheels: equal)
        relative = np.asarray(model.command_scales_) / float(model.command_scale_)
        self._rates = self._rate * relative
        self._rest_command = model.rest_command
        self._limit_motion = False  # the components limit their own commands
        self.reset()

    def _done(self, category: int, novel: bool) -> StepOutput:
        """The step that ends the run at the goal: the rest command, done."""
        label = self._label or self.name
        return StepOutput(self._rest_command, category, novel, self._active, label, False, True)

    def bind(self, channels: Sequence[str]) -> None:
        """Fit every component's policy to a robot's ``channels`` (see SimplePolicy.bind)."""
        names = list(self._channels)
        for child in self._children.values():
            if hasattr(child, "bind"):
                child.bind(channels)
            names += [c for c in child.channels if c not in names]
        self.channels = ordered_channels(names)

    def reset(self) -> None:
        """Forget the previous run."""
        self._pipe.reset()
        self._live.reset()
        self._active = -1
        self._child: Any = None
        self._finished: dict[int, dict[str, float]] = {}
        self._reachable_from = -1
        self._unable: set[int] = set()
        self._unreachable = False  # the last component step raised UnreachableGoalError
        self._handed_back = False
        self._insist, self._wanted = 0, -1
        self._committed = False
        self._settling = 0
        self._pause = 0
        self._redo = False  # the active component's goal was undone after it finished
        self._limit_reset()

    @property
    def braking(self) -> bool:
        """Whether the running component is ramping to rest short of its goal.

        A complex behavior brakes through its components; a parent that runs this one
        as a component lets it finish braking into the parent's goal (``settle_cycles``).
        """
        child = self._running()
        return child is not None and bool(child.braking)

    @property
    def braked(self) -> bool:
        """Whether the running component has braked to rest (it waits for its goal)."""
        child = self._running()
        return child is not None and bool(child.braked)

    def _running(self) -> Any:
        """The controller of the component running now (None: none, or it has finished)."""
        if self._child is None or self._active in self._finished:
            return None
        return self._child

    def _plannable(self, category: int) -> int:
        """``category``, or the next-best match of the current window a plan can start from.

        A window between two demonstrated starts can match best a category from which
        no demonstration led to the goal; the runner-up categories of the same window
        (at most the model's ``start_alternatives``) are tried before giving up
        (UnreachableGoalError before any motion).
        """
        hmm = self.model.hmm_
        try:
            retarget(self, hmm, category, may_raise=True, most_likely=True)
            return category
        except UnreachableGoalError:
            if self._child is not None:
                return category  # carry on with the running component
            ranked = np.argsort(self._live.mismatch, kind="stable")[: self._alternatives + 1]
            for alternative in (int(k) for k in ranked if k != category):
                try:
                    retarget(self, hmm, alternative, may_raise=True, most_likely=True)
                except UnreachableGoalError:
                    continue
                self._reachable_from = category
                return alternative
            raise

    def _values(self, reading: Mapping[str, float], x: FloatArray) -> dict[str, float]:
        filtered = (x + 1.0) / self._gain + self._lo
        values = dict(reading)
        values.update(zip(self._channels, filtered.tolist(), strict=True))
        return values

    def step(self, reading: Mapping[str, float]) -> StepOutput:
        """Decide the command for one reading ``{channel: value}`` (physical units).

        With the model's ``command_rate_limit`` a new component continues from the
        running command (each component limits its own change per cycle), and the
        complex behavior stops softly when it is slow at its goal.
        """
        if self._stopping is not None:  # ramping down at the goal
            return self._limited(self._stopping)
        return self._limited(self._decide(reading))

    def _decide(self, reading: Mapping[str, float]) -> StepOutput:
        x = self._pipe.step(np.array([reading[c] for c in self._channels], dtype=np.float64))
        category, novel, _ = self._live.update(x)
        if category != self._reachable_from:
            category = self._plannable(category)
            self._unable.clear()  # a component unable to reach the goal may be able now
        values = self._values(reading, x)
        at_goal = within_tolerance(values, self.goal, self._tolerance, self.channel_specs)
        if self._pause > 0 and not at_goal:
            # a component ended at rest: wait as long as the teacher rests at a switch
            self._pause -= 1
            label = self._label or self.name
            return StepOutput(
                self._rest_command, category, novel, self._active, label, False, False
            )
        if at_goal and self._settles_in_goal():
            # the running component heads for a goal inside the tolerance: it finishes
            # (at rest, braking into it) rather than the robot stopping at speed
            self._settling += 1
            return self._run_child(reading, category, novel, changed=False)
        braked = self._child is not None and self._child.braked
        if at_goal and (category in self._stop_set or self._handed_back or braked):
            # the goal category with the goal's tolerance (thesis + DESIGN §5), or a
            # component has just finished with the complex goal's tolerance holding
            return self._done(category, novel)
        self._handed_back = False
        # A finished component whose goal no longer holds (e.g. after a push) runs again.
        for comp, sub_goal in list(self._finished.items()):
            if not within_tolerance(values, sub_goal, specs=self.channel_specs):
                del self._finished[comp]
                # the last one to run has stopped its controller: it starts afresh
                self._redo = self._redo or comp == self._active
        plan = None
        try:
            plan = self.model.hmm_.plan(category, self.goal_category)
            segments = [s for s in plan.segments if s.state not in self._finished]
        except UnreachableGoalError:
            if self._child is None:
                raise
            segments = []
        if not segments:
            if self._running() is None:
                if at_goal:  # nothing left to run and the goal holds
                    return self._done(category, novel)
                if not self._may_repair:  # thesis: stand still until the step limit
                    return StepOutput(
                        self._rest(), category, novel, self._active, self.name, False, False
                    )
                # The plan is exhausted short of the goal (e.g. an approach drifted off
                # the bearing): run the component whose own goal covers the channel that
                # misses its tolerance, toward the complex goal on its channels.
                return self._repair(values, reading, category, novel)
            return self._run_child(reading, category, novel, changed=False)
        segment = segments[0]
        running = self._running() is not None
        if running and self._committed:
            # a component run to close a gap the plan missed finishes its job first
            return self._run_child(reading, category, novel, changed=False)
        if not running and self._may_preempt:
            fix = self._uncovered(values, [s.state for s in segments])
            if fix is not None:
                sub_goal = {
                    c: self.goal.get(c, v)
                    for c, v in self.model.components_[fix].default_goal_.items()
                }
                child, active, fix_goal = self._child, self._active, self._finished.get(fix)
                out = self._delegate(fix, sub_goal, reading, category, novel, renew=True)
                if not self._unreachable:
                    self._committed = True
                    return out
                # it cannot start from here (e.g. a nested turn & approach asked to back
                # away): the plan goes on as if it had not been tried, or the robot would
                # try it again every cycle and never move
                self._unable.add(fix)
                self._child, self._active = child, active
                if fix_goal is None:
                    del self._finished[fix]
                else:
                    self._finished[fix] = fix_goal
        if running and segment.state != self._active:
            # Debounce: near a category border the plan can flip every few cycles; a
            # running component is replaced only when the plan insists for a while.
            self._insist = self._insist + 1 if self._wanted == segment.state else 1
            self._wanted = segment.state
            if self._insist < self._switch_cycles:
                return self._run_child(reading, category, novel, changed=False)
        self._insist, self._wanted = 0, -1
        self._committed = False
        if segment.state == self._active and not self._redo:  # carry on (an intermediate
            return self._run_child(reading, category, novel, changed=False)  # goal: a new one)
        renew, self._redo = self._redo, False
        sub_goal = self.model.component_goal(
            segment.state,
            segment.exit_observation,
            self.goal,
            final=segment.exit_observation in self._goal_set,
        )
        return self._delegate(
            segment.state, self._on_the_way(sub_goal, values), reading, category, novel, renew
        )

    def _on_the_way(
        self, sub_goal: dict[str, float], values: Mapping[str, float]
    ) -> dict[str, float]:
        """``sub_goal`` with no channel sent back, away from the complex goal (``forward_goals``).

        An intermediate goal is its exit category's prototype, which is coarse: from
        0.49 m toward 0.63 m the turn & approach before a retreat is handed 0.39 m, and
        would approach 10 cm only for the retreat to undo it. A channel the complex goal
        states (other than a wrapping one, an angle, whose sign is no direction) whose
        sub-goal lies behind the robot, away from the goal, keeps its current value
        instead.
        """
        if not self._forward:  # thesis: the prototype as it is
            return sub_goal
        for channel, target in sub_goal.items():
            if channel not in self.goal or self.channel_specs[channel].wraps:
                continue
            now = values[channel]
            if (target - now) * (self.goal[channel] - now) < 0.0:
                sub_goal[channel] = now
        return sub_goal

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
        if child is None or child.braked:
            return False  # a component braked to rest inside the goal is done
        if self._settling >= self._settle_cycles:
            return False
        shared = {c: g for c, g in self.goal.items() if c in child.goal}
        if not shared or not within_tolerance(
            child.goal, shared, self._tolerance, self.channel_specs
        ):
            return False
        # braking into its goal, or heading for the goal its demonstrations stop at (a
        # goal they only pass at speed, e.g. an approach to 0.5 m, is not one to settle in)
        own = child.model.default_goal_
        return bool(child.braking) or within_tolerance(child.goal, own, specs=self.channel_specs)

    def _uncovered(self, values: Mapping[str, float], planned: list[int]) -> int | None:
        """A component to run first because the plan cannot close a gap of the goal.

        At a decision point (nothing running), a goal channel outside its tolerance
        must be closed by some planned component, judged by the components' learned
        effects (a substantial share of the best effect); e.g. a start 9 deg off the
        object whose still window looks aligned gets "approach" planned, but approach
        does not turn, and in the demonstrations nothing turns after it. Then the
        component that closes that gap best runs first, unless the demonstrations run it
        after the plan's first component (a start 3 cm short of the goal and 109 deg off
        gets "turn" planned; the approach then comes after the turn, as the plan's
        repair, not before it). ``None``: the plan covers it, or goes first.
        """
        effects = self.model.effects_
        for channel in self.goal:
            if within_tolerance(
                values, {channel: self.goal[channel]}, self._tolerance, self.channel_specs
            ):
                continue
            j = self._channels.index(channel)
            error = values[channel] - self.goal[channel]
            # the change that closes the gap: |angle| must shrink; others move to the goal
            needed = -1.0 if self.channel_specs[channel].wraps else -np.sign(error)
            gain = needed * effects[:, j]
            able = [
                k
                for k in np.argsort(-gain, kind="stable").tolist()
                if gain[k] > 0
                and gain[k] >= 0.1 * gain.max()
                and channel in self.model.components_[k].default_goal_
                and k not in self._unable
            ]
            if able and not any(k in able for k in planned):
                fix = int(able[0])
                if planned and self._follows(fix, planned[0]):
                    # in the demonstrations it comes after the plan's first component
                    # (e.g. approach after turn): the plan runs first, a repair after it
                    continue
                return fix
        return None

    def _follows(self, component: int, other: int) -> bool:
        """Whether the demonstrations switch ``other`` -> ``component`` more than back."""
        counts = self.model.hmm_.A_counts_
        return bool(counts[other, component] > counts[component, other])

    def _repair(
        self, values: Mapping[str, float], reading: Mapping[str, float], category: int, novel: bool
    ) -> StepOutput:
        """Run a component whose goal channels cover one the complex goal misses.

        Components are tried in order; one that cannot reach the goal from here (its
        own plan is unreachable, e.g. an approach asked to back away) is skipped.
        """
        missed = [
            c
            for c in self.goal
            if not within_tolerance(values, {c: self.goal[c]}, specs=self.channel_specs)
        ]
        effects = self.model.effects_
        for channel in missed:
            j = self._channels.index(channel)
            error = values[channel] - self.goal[channel]
            # the change that closes the gap: |angle| must shrink; others move to the goal
            needed = -1.0 if self.channel_specs[channel].wraps else -np.sign(error)
            order = np.argsort(-needed * effects[:, j], kind="stable")
            for comp in (int(k) for k in order):
                component = self.model.components_[comp]
                if (
                    channel not in component.default_goal_
                    or comp in self._unable
                    or needed * effects[comp, j] <= 0
                ):
                    continue
                sub_goal = {c: self.goal.get(c, v) for c, v in component.default_goal_.items()}
                self._finished.pop(comp, None)
                # a repair aims well inside the tolerance, or the next drift undoes it
                out = self._delegate(
                    comp, sub_goal, reading, category, novel, renew=True, tolerance=0.5
                )
                if comp not in self._finished:  # it runs: no UnreachableGoalError
                    return out
                self._unable.add(comp)
        return StepOutput(self._rest(), category, novel, self._active, self.name, False, False)

    def _delegate(
        self,
        comp: int,
        sub_goal: dict[str, float],
        reading: Mapping[str, float],
        category: int,
        novel: bool,
        renew: bool = False,
        tolerance: float = 1.0,
    ) -> StepOutput:
        changed = comp != self._active or renew
        if changed:
            child = self._children[comp]
            child._renew(sub_goal, tolerance)  # as a new controller, without building one
            self._child = child
            self._child.reset()
            self._child.carry(self._last)
            self._active = comp
        return self._run_child(reading, category, novel, changed)

    def _run_child(
        self, reading: Mapping[str, float], category: int, novel: bool, changed: bool
    ) -> StepOutput:
        self._unreachable = False
        try:
            out = self._child.step(reading)
        except UnreachableGoalError:
            # the component cannot reach its intermediate goal from here: skip it
            self._unreachable = True
            self._finished[self._active] = dict(self._child.goal)
            rest = self._rest()
            self._child.carry(rest)  # should it run again, it goes on from this command
            return StepOutput(rest, category, novel, self._active, self.name, changed, False)
        if out.done:
            if self._at_rest_command(out.command):  # it ended at rest: the teacher's pause
                self._pause = self._handover
            self._finished[self._active] = dict(self._child.goal)
            self._handed_back = True
            self._committed = False
        label = out.component or self.model.names_[self._active]
        return StepOutput(out.command, category, novel, self._active, label, changed, False)
