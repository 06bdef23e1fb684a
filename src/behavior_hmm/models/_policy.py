"""The policy of a simple behavior: one control cycle of thesis Algorithm 1."""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data._channels import TOLERANCES, ChannelSpec, within_tolerance
from behavior_hmm.data._filter import LowPassFilter, OnlinePipeline
from behavior_hmm.errors import ConfigError, UnreachableGoalError
from behavior_hmm.models._confirm import NOISE_MIN, GoalConfirmation
from behavior_hmm.runtime import DEFAULT_FAULT_HOLD_S, Trace, ordered_channels, run_policy
from behavior_hmm.runtime._policy import StepOutput

if TYPE_CHECKING:
    from behavior_hmm.models._sblm import SBLM

FloatArray = NDArray[np.float64]


#: The channels the stop-at-rest rule of an SBLM reads (``stop_at_rest``).
REST_CHANNELS: tuple[str, ...] = ("linear_velocity", "angular_velocity")
#: ``recover``: a run is steered back once its reading is farther than this multiple of
#: ``reach_radius_`` from every prototype (LASA, 8 x 8 grids and the held-out starts of
#: 6 shapes: with 1, Zshape reached 56 of 64 grid starts against 16 without, but held-out
#: starts a few units off the training demonstrations were steered too, Angle's DTW 375
#: -> 755; with 2 the held-out runs were unchanged on 4 of 6 shapes, Zshape 32 of 64) ...
RECOVER_ENTER = 2.0
#: ... and until it is within
#: this share of ``reach_radius_`` of a prototype (hysteresis: with 1 it hovers at the
#: edge, a generator carrying it out and the guard pulling it back; LASA Zshape, 6 x 6
#: grid of starts, steering at RECOVER_SPEED: 19 of 36 reached with 1, 23 with 0.5, 18
#: with 0.25).
RECOVER_EXIT = 0.5
#: ``recover``, on a robot without velocity readings: a run in its goal category, outside
#: the goal's tolerance, that has not come closer to the goal (by ``CLOSE_PROGRESS`` of
#: the tolerance) for this many cycles is steered onto the goal itself, at RECOVER_SPEED,
#: closing in RECOVER_CYCLES, until its run ends or it leaves the goal category. The
#: generators learned to rest at the goal, not to find it from a unit or two off: LASA
#: runs came to rest there (LShape, Line) or circled it (CShape's held-out starts, 1-2.5
#: units off for hundreds of cycles). A run that slows down into its goal comes closer
#: every cycle and is left alone.
CLOSE_CYCLES = 8
#: ... closer meaning: its largest goal error, in tolerances, below the least so far by
#: this much.
CLOSE_PROGRESS = 0.01
#: ``recover``: the steering command's largest channel, at most this share of its
#: command scale ...
RECOVER_SPEED = 0.5
#: ... and no faster than closing the gap to the prototype in this many cycles, so a
#: run steered onto its goal slows down there instead of overshooting the stop (6 x 6
#: grids, starts reached of 36: Zshape 18 with 25 cycles, 30 with 10, 24 with 1; Sshape
#: 29 with 10, 34 with 1).
RECOVER_CYCLES = 10


def read_channels(model: Any) -> tuple[str, ...]:
    """The sensor channels a model's policy reads: the data contract's first, in order.

    A model reads its ``inputs_``; an SBLM with ``stop_at_rest`` also reads
    ``linear_velocity`` and ``angular_velocity`` (its stop rule waits for rest); a CBLM
    also reads whatever its components read (recursively).
    """
    names: list[str] = list(getattr(model, "inputs_", ()))
    if bool(getattr(model, "stop_at_rest", False)):
        names += [c for c in REST_CHANNELS if c not in names]
    for component in getattr(model, "components_", None) or ():
        names += [c for c in read_channels(component) if c not in names]
    return ordered_channels(names)


class GoalTracking:
    """The goal part of a controller: goal, goal categories, stop set (see retarget)."""

    model: Any
    goal: dict[str, float]
    channel_specs: dict[str, ChannelSpec]
    command_channels: tuple[str, ...]
    goal_category: int
    _tolerance: float
    _goal_candidates: NDArray[np.int64]
    _goal_set: frozenset[int]
    _stop_set: frozenset[int]
    _reachable_from: int
    #: the live categorizer of the observation windows (CobART ``stream()``)
    _live: Any
    #: the goal confirmed on the raw readings at rest when they are noisy
    _confirmation: GoalConfirmation
    #: off for a component of a complex behavior (that one confirms its own goal)
    confirm_goal: bool
    #: whether the readings are noisy, asked of the complex behavior that runs this
    #: policy (None: judged from this policy's own goal confirmation)
    noisy_readings: Callable[[], bool] | None
    #: the readings' filter and normalization, and the channels it reads, in order
    _pipe: OnlinePipeline
    _channels: tuple[str, ...]

    def start_at(self, values: Mapping[str, float]) -> None:
        """Start the readings' filters at ``values`` (physical units; a channel missing
        or not finite leaves them to start at the next reading, as after ``reset``).

        A complex behavior hands a component its own filtered readings (or, after a
        refuted goal, their mean at rest) when it starts it at rest on noisy readings:
        started at one raw reading instead, the component's filter carries that reading's
        noise into its first cycles (σ 3.6° on the bearing at noise 0.01, against about
        1° filtered), and an approach started on a bearing it reads 5° off turns to
        correct it.
        """
        x0 = [values.get(c, math.nan) for c in self._channels]
        if all(math.isfinite(v) for v in x0):
            self._pipe.reset(x0)

    def _keeps_noise(self) -> bool:
        """Whether this policy records the readings' noise: it may confirm its goal."""
        raise NotImplementedError

    def _noisy(self) -> bool:
        """Whether the readings are noisy: told by the complex behavior that runs this
        policy (``noisy_readings``), else judged by this policy's own goal confirmation
        (kept only by a policy that may confirm its goal)."""
        if self.noisy_readings is not None:
            return self.noisy_readings()
        return self._keeps_noise() and self._confirmation.needed(self.goal, self._tolerance)

    def _set_goal(self, model: Any, goal: Mapping[str, float] | None) -> None:
        """Resolve the goal and its categories; build their planning trees before motion.

        The candidates of each goal are kept (a renewed component controller gets the
        same intermediate goals again and again; they depend on the model alone).
        """
        self.goal = model.resolve_goal(goal)
        # the declaration of each channel the model reads (tolerance, wrap): the control
        # loop judges the goal with them too
        self.channel_specs = {c: model.channel_spec(c) for c in model.inputs_}
        #: the command channels its commands are for, in action order
        self.command_channels = tuple(model.command_channels)
        memo: dict[tuple[tuple[str, float], ...], NDArray[np.int64]]
        memo = self.__dict__.setdefault("_goal_memo", {})
        key = tuple(self.goal.items())
        candidates = memo.get(key)
        if candidates is None:
            candidates = memo[key] = model.goal_categories(self.goal)
        self._goal_candidates = candidates
        self.goal_category = int(self._goal_candidates[0])
        self._goal_set = frozenset(int(k) for k in self._goal_candidates)
        model.hmm_.prepare_goals(self._goal_candidates)
        # the thesis's stop test (o_c == o_g) until the goal had to be retargeted
        self._stop_set = frozenset({self.goal_category})
        self._reachable_from = -1

    @property
    def goal_candidates(self) -> NDArray[np.int64]:
        """The categories matching the goal, best match first (see ``model.goal_categories``)."""
        return self._goal_candidates

    def planned_from(self, category: int) -> None:
        """Record that the goal category has been checked against ``category`` (retarget)."""
        self._reachable_from = category

    def aim_at(self, candidate: int) -> None:
        """Aim at the goal candidate ``candidate`` (retarget).

        From then on the run stops in any category describing the goal place (within
        the physical tolerance), not only in the best-matching one.
        """
        self.goal_category = int(candidate)
        self._stop_set = self._goal_set

    def goal_fallbacks(self, category: int) -> NDArray[np.int64]:
        """The categories near the goal, nearer to it than ``category``, planned to when
        no goal candidate is reachable from ``category`` (``model.goal_fallback_categories``)."""
        fallbacks: NDArray[np.int64] = self.model.goal_fallback_categories(self.goal, category)
        return fallbacks

    def aim_near(self, fallback: int) -> None:
        """Aim at ``fallback``, a category near the goal (retarget): the run stops in it
        or in any goal candidate, within the physical tolerance."""
        self.goal_category = int(fallback)
        self._stop_set = self._goal_set | {int(fallback)}

    def plannable_starts(self, hmm: Any, category: int, count: int) -> list[int]:
        """The ``count`` best matches of the live window other than ``category`` from which
        a plan to a goal candidate exists, best first (``BehaviorHMM.plannable_from``; the
        mask depends on the model and the goal alone, ~17 ms at 2,400 categories, and is
        kept per goal)."""
        memo = self.__dict__.setdefault("_plannable_memo", {})
        key = self.goal_candidates.tobytes()
        if key not in memo:
            memo[key] = hmm.plannable_from(self.goal_candidates)
        ranked = np.argsort(self._live.mismatch, kind="stable")
        ranked = ranked[memo[key][ranked] & (ranked != category)]
        return [int(k) for k in ranked[:count]]

    def alternative_start(self, hmm: Any, category: int, count: int, **retargeting: Any) -> int:
        """The first of :meth:`plannable_starts` that ``retarget`` (``retargeting``: its
        keywords) plans from, now aimed at; -1 if none. Later cycles in ``category`` do not
        retarget again."""
        if count < 1:  # none to try: not even the plannable mask is computed
            return -1
        for alternative in self.plannable_starts(hmm, category, count):
            try:
                retarget(self, hmm, alternative, may_raise=True, **retargeting)
            except UnreachableGoalError:
                continue
            self._reachable_from = category
            return alternative
        return -1

    def renew(self, goal: Mapping[str, float] | None, tolerance: float) -> None:
        """Aim at a new goal with the state a new controller would have after ``reset()``.

        A complex controller keeps one controller per component and renews it instead of
        building a new one (CobART streams, filters, buffers) inside a control cycle;
        the caller calls :meth:`reset` next, as it would on a new controller.
        """
        self._tolerance = float(tolerance)
        self._set_goal(self.model, goal)


#: Cycles over which a goal channel's rate of change is measured for goal braking.
BRAKE_RATE_CYCLES = 4
#: Cycles a braked robot stands still short of its goal before its generators resume.
BRAKE_HOLD_CYCLES = 8
#: Cycles after a brake's ramp ends before a robot inside its goal's tolerance is done
#: (the wheels' lag: it is at rest by then).
BRAKE_SETTLE_CYCLES = 3
#: Goal braking also stops a run that moves inside its goal's tolerance without closing
#: on the goal: its command would take more than this many cycles (16 s) to reach it ...
STALL_CYCLES = 1000
#: ... on this many cycles in a row (a passing moment of no progress is not a stall).
STALL_HOLD_CYCLES = 8

#: Readings over which a robot that has not moved yet must hold its goal before its run
#: ends there (with ``stop_at_rest``): one noisy first reading inside the tolerance
#: does not end a run whose start lies outside it; and the readings' noise can be
#: estimated by then (``NOISE_MIN`` second differences), so a noisy goal is confirmed
#: on the raw readings before the run ends (``SimplePolicy._noise_known``).
START_CONFIRM_CYCLES = NOISE_MIN + 2

#: A soft stop at the goal takes at most this many control cycles; a robot moving faster
#: than that when its goal is reached (an intermediate goal that its demonstrations
#: passed at speed) is stopped at once: reaching the goal comes before smoothness.
SOFT_STOP_CYCLES = 8


class RateLimited:
    """Limits how fast a controller's command changes, and stops it softly.

    With a rate ``r`` (rad/s per control period, > 0), each cycle's command moves from
    the last one by at most ``r`` per wheel (``_limit_motion``; a complex controller
    leaves that to its components, which continue from its running command). When the
    behavior is done and the command is small (within ``SOFT_STOP_CYCLES`` cycles of
    zero), it ramps to zero at that rate before the run reports done, as the
    demonstrations end at rest without a jolt; faster, it stops at once. ``r = 0``
    passes commands through (thesis).
    """

    _rate: float
    #: the rate limit of each command channel (its unit per cycle); ``_rate`` is the
    #: largest, and 0 switches the limit off
    _rates: FloatArray
    #: the command that holds the robot still (each command channel's ``rest``)
    _rest_command: FloatArray
    _limit_motion: bool
    _last: FloatArray
    _stopping: StepOutput | None
    _label: str
    #: ramping to rest short of the goal (goal braking): a stop then finishes the ramp
    _braking: bool = False
    _brake_hold: int = 0

    @property
    def braking(self) -> bool:
        """Whether the policy is ramping its command to rest short of its goal."""
        return self._braking

    @property
    def braked(self) -> bool:
        """Whether goal braking has brought the robot to rest (it waits for its goal)."""
        return self._braking and self._brake_hold >= BRAKE_SETTLE_CYCLES and self._still()

    def _still(self) -> bool:
        """Whether the robot counts as at rest for goal braking (always, unless overridden)."""
        return True

    def _limit_reset(self) -> None:
        self._last = self._rest_command.copy()
        self._stopping = None
        self._label = ""

    def _toward(self, start: FloatArray, target: FloatArray) -> FloatArray:
        """``target``, or as close to it as one step of the rate limit from ``start`` goes."""
        return start + np.clip(target - start, -self._rates, self._rates)

    def _ramped_down(self) -> FloatArray:
        """The command one step of the rate limit closer to rest (and now the last one)."""
        self._last = self._toward(self._last, self._rest_command)
        return self._last

    def _at_rest_command(self, command: FloatArray) -> bool:
        """Whether ``command`` is the one that holds the robot still."""
        return bool(np.array_equal(command, self._rest_command))

    def carry(self, command: FloatArray) -> None:
        """Continue from ``command`` (rad/s): a complex behavior's switch does not jolt."""
        self._last = np.array(command, dtype=np.float64)

    def _limited(self, out: StepOutput) -> StepOutput:
        if self._rate <= 0.0:
            self._last = out.command
            return out
        if out.done and self._stopping is None:
            away = np.abs(self._last - self._rest_command)
            fast = bool(np.any(away > SOFT_STOP_CYCLES * self._rates))
            if fast and not self.braking:
                self._last = self._rest_command.copy()
                return out  # moving fast at the goal: stop now
            # the ramp down still finishes the last component's motion: keep its name
            self._stopping = out._replace(component=out.component or self._label)
        elif not out.done:
            self._label = out.component
        if self._stopping is not None:
            u = self._ramped_down()
            return self._stopping._replace(command=u, done=self._at_rest_command(u))
        u = out.command
        if self._limit_motion:
            u = self._toward(self._last, u)
        self._last = u
        return out._replace(command=u)


class SimplePolicy(GoalTracking, RateLimited):
    """An SBLM's policy: it runs the behavior toward a goal one reading at a time.

    Each cycle: filter and normalize the reading exactly as in training, categorize
    the current observation window (CobART, no learning), re-plan the most likely
    observation path to the goal category and decode its primitives (cached per
    observation pair), take the plan's first primitive (or, with the model's
    ``primitive_recognition``, the primitive the primitive CobART recognizes in the
    live window among those the plan allows), and command the wheels from that
    primitive's motion generator (fed the cycles since the start when the model has an
    ``onset_clock``; on noisy readings the running primitive is held through an
    observation category it was never seen in until that category has lasted the
    filter's lag, :meth:`_outlier`). It stops when the goal category is reached
    *and* the filtered readings lie within the goal's physical tolerance (with
    ``recover``, on a robot without velocity readings, which cannot show rest: where the
    robot is now, the filtered readings moved on by how far the filter makes them trail).

    Parameters
    ----------
    model
        A fitted :class:`~behavior_hmm.models.SBLM`.
    goal
        Goal in physical units on the model's inputs; ``None`` uses the model's default.
    name
        Component name recorded in traces (set by a complex model).
    tolerance
        Scale of the goal's physical tolerance in the stop rule (1: DESIGN §5's 3 deg /
        0.01 m; a complex model repairing a drifted channel asks for 0.5).
    """

    def __init__(
        self,
        model: SBLM,
        goal: Mapping[str, float] | None,
        name: str = "",
        tolerance: float = 1.0,
    ) -> None:
        self.model = model
        self.name = name
        self._set_goal(model, goal)
        self._at_rest = bool(getattr(model, "stop_at_rest", False))
        #: readings a run that has not moved must hold its goal before it ends (0: at once;
        #: a complex behavior sets 0 for its components, having checked its goal itself)
        self.start_confirm_cycles = START_CONFIRM_CYCLES if self._at_rest else 0
        self._confirmed = 0
        self._tolerance = float(tolerance)
        #: the goal confirmed on the raw readings at rest when they are noisy (off: a
        #: complex behavior confirms its own goal, not its components')
        self.confirm_goal = True
        self._confirmation = GoalConfirmation(self.channel_specs)
        self.noisy_readings = None
        self._channels = tuple(model.inputs_)
        self.channels = read_channels(model)
        self._pipe = model.pipeline_.online()
        self._live = model.observations_.stream()
        self._recognize = bool(model.primitive_recognition)
        self._prim_live = model.primitives_.stream()
        self._hmm = model.hmm_
        self._generator = model.generators_.stepper()
        self._scale = np.asarray(model.command_scales_, dtype=np.float64)
        self._held = model.held_mask if getattr(model, "held_commands_", ()) else None
        norm = model.pipeline_.normalizer
        self._lo = np.array(norm.lo, dtype=np.float64)
        self._gain = np.array(norm.gain, dtype=np.float64)
        self._use_history = model.state_decoding == "history"
        self._log_A = model.hmm_.log_A_
        self._log_B = model.hmm_.log_B_
        self._log_pi = model.hmm_.log_pi_
        layout = model.feature_layout(
            len(self._channels), int(model.generators_.window), float(model.delta_scale_)
        )
        self._features = layout.online()
        self._started = False
        self._state = -1
        self._last_obs = -1
        self._alpha = self._log_pi.copy()
        self._prior = self._log_pi
        rate = float(getattr(model, "command_rate_limit", 0.0))
        self._rate = rate * float(model.delta_scale_) * float(model.command_scale_)
        self._rates = rate * float(model.delta_scale_) * np.asarray(model.command_scales_)
        self._rest_command = model.rest_command
        self._limit_motion = True
        self._limit_reset()
        self._brakes = bool(getattr(model, "goal_braking", False)) and self._rate > 0.0
        envelope = getattr(model, "start_envelope_", None)
        #: ``start_envelope``: each cycle's bound on the command's distance from rest in a
        #: run from rest (None: off, or a model file without it)
        self._envelope = envelope if getattr(model, "start_envelope", False) else None
        #: whether this run began at rest (decided at its first command; None: not yet)
        self._from_rest: bool | None = None
        #: before any motion, the best-matching categories a plan can start from that are
        #: tried when none starts from the current one (0: the run is unreachable; a
        #: complex behavior gives its components its own ``start_alternatives``)
        self.start_alternatives = 0
        #: the earliest clock each primitive's network was trained on (None: no clock)
        self._floors = getattr(model, "onset_floor_", None)
        #: ``onset_floor``: the network is fed no earlier clock than that
        self._hold_floor = bool(getattr(model, "onset_floor", False))
        #: ``start_envelope``: whether this cycle's primitive's network was never trained
        #: on a clock this early (a primitive met only mid-motion, at a start from rest)
        self._unshown_start = True
        ranges = getattr(model, "input_range_", None)
        #: ``input_range``: the sensor-window range each primitive's network was trained on
        self._ranges = ranges if getattr(model, "input_range", False) else None
        window = int(model.generators_.window)
        #: each input channel's columns of a row's sensor windows (channel-major)
        self._window_columns = [
            slice(j * window, (j + 1) * window) for j in range(len(self._channels))
        ]
        #: ``input_range``: each input's range over all primitives' rows, and whether this
        #: run's readings have been inside it yet (until then its windows are clipped)
        self._inside = np.zeros(len(self._channels), dtype=bool)
        self._overall: FloatArray | None = None
        if self._ranges is not None:
            lo, hi = self._ranges[:, 0].min(axis=0), self._ranges[:, 1].max(axis=0)
            self._overall = np.array(
                [[lo[c].min(), hi[c].max()] for c in self._window_columns], dtype=np.float64
            )
        starts = getattr(model, "start_range_", None)
        #: ``input_range``: what each primitive's rows held by each onset clock cycle
        #: (``start_range_``, ``(P, C, K + 1, 2)``), their union over the primitives
        #: ``(C, K + 1, 2)``, and each input's goal tolerance in normalized units (NaN:
        #: never held by it: a channel without a tolerance, or one that wraps, whose
        #: demonstrated starts go round the circle rather than end somewhere)
        self._starts: FloatArray | None = None
        if self._ranges is not None and starts is not None:
            self._starts = starts
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # a clock no row had: NaN
                self._start_union = np.stack(
                    [np.nanmin(starts[..., 0], axis=0), np.nanmax(starts[..., 1], axis=0)], -1
                )
            specs = [model.channel_spec(c) for c in self._channels]
            self._start_tolerance = np.array(
                [np.nan if sp.tolerance is None or sp.wraps else sp.tolerance for sp in specs]
            ) * np.abs(self._gain)
            if np.isnan(self._start_tolerance).all():
                self._starts = None  # no input it could hold
        #: whether this run began at rest with its onset clock at 0 (None: not decided yet)
        self._rest_start: bool | None = None
        #: ``input_range``: the inputs this run's start read beyond every start-up the rows
        #: held, still held to them (None: the start not read yet)
        self._start_held: NDArray[np.bool_] | None = None
        self._x = np.zeros(len(self._channels))
        self._reading: Mapping[str, float] = {}
        learned = getattr(model, "command_rates_", None)
        self._command_rates = None if learned is None else np.asarray(learned, dtype=np.float64)
        #: how far this run's commands moved each input (``command_rates_`` units x cycles)
        self._travel = np.zeros(len(self._channels))
        self._recover = bool(getattr(model, "recover", False))
        #: a start whose goal no candidate is reachable from plans near it (goal_fallbacks)
        self._goal_fallback = bool(getattr(model, "goal_fallback", True))
        if self._recover:
            self._set_recovery(model)
        self._returning = False
        filters = model.pipeline_.filters
        #: cycles the filtered readings trail the robot while it moves steadily
        self._lag = filters[0].lag_samples if filters else 0.0
        #: noisy readings: cycles an observation the running primitive never emitted must
        #: last before it is believed (:meth:`_outlier`), and those it has lasted
        self._outlier_cycles = math.ceil(self._lag)
        self._outliers = 0
        #: cycles in a row the running primitive explained the observation
        self._support = 0
        #: ``recover``: judge the goal where the robot is now, not where the lagging
        #: filtered readings put it (set by ``bind`` on a robot whose readings cannot show
        #: rest): the inputs' change the sent commands made (``command_rates_``), less that
        #: change filtered by the readings' filter, is how far the readings trail the robot
        self._lead = False
        #: ``recover`` on a robot without velocity readings: a run that stays in its goal
        #: category without coming closer is steered onto the goal (set by ``bind``)
        self._arrive = False
        self._lead_filter = (
            LowPassFilter(filters[0].cutoff_hz, filters[0].fs).online() if filters else None
        )
        self._arrival_reset()
        self._brake_reset()

    def reset(self) -> None:
        """Forget the previous run (filters, windows, plan, efference copy)."""
        self._pipe.reset()
        self._live.reset()
        self._prim_live.reset()
        self._started = False
        self._confirmed = 0
        self._confirmation.reset()
        self._state = -1
        self._outliers = self._support = 0
        self._last_obs = -1
        self._alpha = self._log_pi.copy()
        self._prior = self._log_pi
        self._features.reset()
        self._generator.reset()
        self._inside[:] = False
        self._rest_start = None
        self._start_held = None
        self._travel = np.zeros(len(self._channels))
        self._limit_reset()
        self._brake_reset()
        self._returning = False
        self._arrival_reset()
        self._from_rest = None
        self._unshown_start = True

    def _limited(self, out: StepOutput) -> StepOutput:
        """The rate limit, then (``start_envelope``) the demonstrations' start-up envelope.

        A run whose first command left from rest (not one a complex behavior carried on
        at speed) is held, at onset clock cycle ``t``, within ``rest ± envelope[t]``
        until the envelope ends (module ``models._envelope``), in the cycles whose
        primitive's network was never trained on a clock as early as ``t``: a network
        shown the demonstrations' starts runs its own start-up. A command such a network
        took beyond the envelope is brought back into it at the rate limit, not at once."""
        if self._from_rest is None:
            self._from_rest = self._at_rest_command(self._last)
        before = self._last
        out = super()._limited(out)
        envelope = self._envelope
        if envelope is None or not self._from_rest or out.done:
            return out
        t = max(self.onset_cycles - 1, 0)  # the clock the generator read this cycle
        if t >= envelope.shape[0]:
            self._from_rest = False  # past the start-up: nothing more to bound
            return out
        if not self._unshown_start:
            return out
        rest = self._rest_command
        u = rest + np.clip(out.command - rest, -envelope[t], envelope[t])
        if self._rate > 0.0:  # from a command beyond the envelope: back at the rate limit
            u = self._toward(before, u)
        self._last = u
        return out._replace(command=u)

    @property
    def onset_cycles(self) -> int:
        """Control cycles the generators' onset clock has counted in this run."""
        return self._features.cycles

    def resume_onset(self, cycles: int) -> None:
        """After :meth:`reset`, let the generators' onset clock go on from ``cycles``.

        A complex behavior that runs the same component again right after it (a repair
        toward a tighter goal, a goal undone) resumes it: the robot is where that
        component's run left it, not at rest where its demonstrations began. Restarted
        at 0, the clock reads as a start, and a start this close to the goal lies
        outside the demonstrations (the nearest began 0.1 m off): the approach, resumed
        8.6 mm short of the object to close 4 mm, first backed away 2.6 cm.
        """
        self._features.resume(cycles)

    def _arrival_reset(self) -> None:
        """Forget the goal arrival's state: nothing moved yet, no closing in progress."""
        self._goal_cycles = 0
        self._nearest = np.inf
        self._closing = False
        self._moved = np.zeros(len(self._channels))
        if self._lead_filter is not None:
            self._lead_filter.reset(self._moved)

    def _set_recovery(self, model: SBLM) -> None:
        """``recover``: the prototypes' newest readings, how far the demonstrations
        reach, and the command per unit change of each input."""
        reach = getattr(model, "reach_radius_", None)
        if reach is None or self._command_rates is None:
            raise ConfigError(
                "recover needs reach_radius_ and command_rates_, which this model file "
                "predates; fit it again"
            )
        self._anchors = np.ascontiguousarray(model.observations_.prototypes_[:, -1, :])
        self._reach = float(reach)
        # rates = command @ command_rates_, so the command for a change v is v @ pinv
        self._steer = np.linalg.pinv(self._command_rates)
        self._wraps = np.array([bool(self.channel_specs[c].wraps) for c in self._channels])

    def _returned(self, x: FloatArray, y: FloatArray) -> FloatArray:
        """``recover``: ``y``, or where the readings ``x`` (normalized) left the
        demonstrations, the normalized command toward the nearest prototype."""
        gaps = np.linalg.norm(self._anchors - x, axis=1)
        nearest = int(np.argmin(gaps))
        edge = self._reach * (RECOVER_EXIT if self._returning else RECOVER_ENTER)
        if gaps[nearest] <= edge:
            self._returning = False
            return y
        change = (self._anchors[nearest] - x) / self._gain  # physical units
        change[self._wraps] = (change[self._wraps] + 180.0) % 360.0 - 180.0
        steer = self._steered(change)
        self._returning = steer is not None
        return y if steer is None else steer

    def _steered(self, change: FloatArray) -> FloatArray | None:
        """``recover``: the normalized command that makes the physical ``change`` of the
        inputs in ``RECOVER_CYCLES`` cycles, its largest channel at most
        ``RECOVER_SPEED``; ``None`` when no command moves the readings that way."""
        command = (change @ self._steer) / (self._scale * RECOVER_CYCLES)
        peak = float(np.max(np.abs(command)))
        if not peak > 0.0:
            return None
        out: FloatArray = command * min(1.0, RECOVER_SPEED / peak)
        return out

    def _closed(self, category: int, now: FloatArray, y: FloatArray) -> FloatArray:
        """``recover`` on a robot without velocity readings (``bind``): ``y``, or, once the
        run has been in the goal category outside its tolerance without coming closer for
        ``CLOSE_CYCLES``, the command onto the goal (``now``: where the robot is)."""
        if not self._arrive or category not in self._stop_set:
            self._goal_cycles, self._nearest, self._closing = 0, np.inf, False
            return y
        change = np.zeros(len(self._channels))
        error = 0.0
        for i, spec, goal, tol in self._brake_slots:
            change[i] = -spec.error(now[i], goal)
            if tol > 0.0:
                error = max(error, abs(change[i]) / tol)
        if not self._closing:
            if error < self._nearest - CLOSE_PROGRESS:
                self._nearest = error
                self._goal_cycles = 0
            else:
                self._goal_cycles += 1
            self._closing = self._goal_cycles >= CLOSE_CYCLES
            if not self._closing:
                return y
        steer = self._steered(change)
        return y if steer is None else steer

    def _brake_reset(self) -> None:
        """Forget the braking state; index the goal channels the model reads."""
        slots = [(self._channels.index(c), self.channel_specs[c], g) for c, g in self.goal.items()]
        self._brake_slots = [(i, spec, g, float(spec.tolerance or 0.0)) for i, spec, g in slots]
        self._brake_history: list[FloatArray] = []
        self._braking = False
        self._brake_hold = 0
        self._stall = 0

    def check_reachable(self, reading: Mapping[str, float]) -> None:
        """Raise UnreachableGoalError if no plan leads from ``reading`` to the goal."""
        probe = SimplePolicy(self.model, self.goal)
        probe.step(reading)

    def step(self, reading: Mapping[str, float]) -> StepOutput:
        """Decide the command for one reading ``{channel: value}`` (physical units).

        The model's ``command_rate_limit`` bounds the change per cycle (see RateLimited).
        """
        out = self._step(reading)
        if self._command_rates is not None:  # how far the commands moved the inputs
            self._travel = self._travel + out.command @ self._command_rates
        return out

    def _step(self, reading: Mapping[str, float]) -> StepOutput:
        if self._stopping is not None:  # ramping down at the goal
            return self._limited(self._stopping)
        out = self._decide(reading)
        if not self._brakes or out.done:
            return self._limited(out)
        return self._braked(out)

    def moved_within_tolerance(self) -> bool:
        """Whether this run's commands moved every goal channel by less than its
        tolerance, by the learned ``command_rates_`` (so the readings' noise does not
        enter); False for a model file without them.

        A complex behavior's component that ran on a noisy reading of a goal already
        held did not move the robot: turn & approach from 0.72 deg off, noise 0.01, read
        the bearing 4.9 deg off at its first cycle, turned 0.7 deg, and then paused as
        the teacher pauses after its turns (24 cycles) before it approached.
        """
        if self._command_rates is None:
            return False
        return all(abs(float(self._travel[i])) < tol for i, _, _, tol in self._brake_slots)

    def _braked(self, out: StepOutput) -> StepOutput:
        """Goal braking: ramp to rest when arriving any later would overshoot the goal.

        Each cycle the goal channels' filtered values, moved on by the filter's lag (the
        readings trail a moving robot by ``lag_samples`` cycles), and the rate of change
        the current command gives them (the model's learned ``command_rates_``; a model
        file without them: the rate measured over ``BRAKE_RATE_CYCLES``) predict where the
        robot would come to rest if its command ramped to zero now at the rate limit (a
        linear ramp covers half the distance of the current rate). When that point
        reaches the goal, the command ramps to zero, so a generator that arrives too fast
        comes to rest at its goal instead of being stopped at speed. A robot at rest
        inside the goal's tolerance ``BRAKE_SETTLE_CYCLES`` after the ramp (with
        ``stop_at_rest``: once the readings show rest) is done; one at rest short of it
        resumes its generators after ``BRAKE_HOLD_CYCLES``.
        """
        filtered = (self._x + 1.0) / self._gain + self._lo
        history = self._brake_history
        history.append(filtered)
        if len(history) > BRAKE_RATE_CYCLES + 1:
            del history[0]
        away = np.abs(self._last - self._rest_command)
        speed = float(np.max(away))
        if not self._braking and speed > 0.0 and len(history) > BRAKE_RATE_CYCLES:
            if self._command_rates is not None:  # learned: the rate the command gives
                rates = self._last @ self._command_rates
            else:  # measured (a model file from before command_rates_ was learned)
                rates = (filtered - history[0]) / BRAKE_RATE_CYCLES
            # the filtered readings trail a moving robot: where it is now
            now = filtered + rates * self._lag
            ramp = float(np.max(away / self._rates))  # cycles to rest at the rate limit
            self._braking = self._rest_at_goal(now, rates, ramp + 1.0) or self._stalled(now, rates)
            self._brake_hold = 0
            if self._braking:
                self._stall = 0
        if not self._braking:
            return self._limited(out)
        u = self._ramped_down()
        self._label = out.component
        if not self._at_rest_command(u):
            return out._replace(command=u)
        self._brake_hold += 1
        values = dict(zip(self._channels, filtered.tolist(), strict=True))
        still = self._still()
        settled = self._brake_hold >= BRAKE_SETTLE_CYCLES and still
        if settled and self._goal_holds(values):
            # braked to rest inside the goal's tolerance: done, whatever the category
            # (with stop_at_rest only once the readings show rest: slow wheels coast on);
            # on noisy readings once the next readings confirm it (``_decide``)
            self._braking = False
            if self._must_confirm():
                self._confirmation.begin()
                return out._replace(command=u)
            return out._replace(command=u, done=True, plan_changed=False)
        # resume once at rest short of the goal (slow wheels: at most 4x as long)
        self._braking = self._brake_hold < (BRAKE_HOLD_CYCLES if still else 4 * BRAKE_HOLD_CYCLES)
        return out._replace(command=u)

    def bind(self, channels: Sequence[str]) -> None:
        """Fit the policy to a robot's ``channels`` (the control loop calls it first).

        ``stop_at_rest`` reads the velocity channels (``REST_CHANNELS``); on a robot that
        neither measures them nor can derive them it is off for this policy, and a
        warning says so.
        """
        missing = [c for c in REST_CHANNELS if c not in channels]
        # ``recover`` without velocity readings: a run may reach its goal at speed, where
        # the filtered readings trail the robot; the stop rule then judges where it is, and
        # a run that stays off its goal is steered onto it (the stop cannot wait for rest)
        self._arrive = self._recover and bool(missing)
        self._lead = (
            self._arrive and self._command_rates is not None and self._lead_filter is not None
        )
        if not self._at_rest or not missing:
            return
        self._at_rest = False
        self.start_confirm_cycles = 0
        self.channels = tuple(c for c in self.channels if c not in missing)
        warnings.warn(
            f"stop_at_rest is off for {self.model.behavior_!r}: the robot has no "
            f"{', '.join(missing)} channel (the stop rule reads the goal tolerance only)",
            RuntimeWarning,
            stacklevel=2,
        )

    def _still(self) -> bool:
        """At rest by the readings when the stop rule waits for rest (``stop_at_rest``)."""
        return not self._at_rest or readings_at_rest(self._reading)

    def _goal_holds(self, values: Mapping[str, float]) -> bool:
        """Whether the stop rule's goal holds: ``values`` (the filtered readings,
        physical units) within the tolerance, and the raw readings too where
        :meth:`_held_unfiltered` asks them."""
        return (
            within_tolerance(values, self.goal, self._tolerance, self.channel_specs)
            and self._held_unfiltered()
        )

    def _held_unfiltered(self) -> bool:
        """Whether the goal also holds on this cycle's raw readings, which a policy that
        confirms its own goal at rest (``stop_at_rest``) asks when they are not noisy.

        The filtered readings trail a robot that still moves by the filter's lag (0.11 s
        at 2 Hz): slow wheels (a 0.25 s motor lag) that coast through the goal below the
        rest tolerance's yaw rate showed it inside the tolerance filtered while it was
        already past it (a turn from 23 deg stopped 3.55 deg off, raw). Noisy readings are
        judged on their mean instead (:class:`GoalConfirmation`). A component of a complex
        behavior (whose goal the complex behavior confirms) and a stop rule that does not
        wait for rest (the thesis preset) read the filtered readings only.
        """
        if not self._keeps_noise() or self._must_confirm():
            return True
        return within_tolerance(self._reading, self.goal, self._tolerance, self.channel_specs)

    def _rest_at_goal(self, now: FloatArray, rates: FloatArray, ramp: float) -> bool:
        """Whether a ramp to rest over ``ramp`` cycles, started now, ends at or past the goal.

        ``rates``: each input's change per cycle at the current command. At least one
        goal channel must be closing on its goal, and every closing channel would come
        to rest at or past its goal value; every other goal channel must hold its
        tolerance. Braking is thus a last resort: a generator that slows down into its
        goal by itself (as the teacher does) is never cut short.
        """
        closing = False
        for i, spec, goal, tol in self._brake_slots:
            rate = float(rates[i])
            error = spec.error(now[i], goal)
            rest = spec.error(now[i] + rate * ramp / 2.0, goal)
            if error * rate < 0.0:  # moving toward the goal
                closing = True
                if rest * error > 0.0:  # a ramp now would still end short of the goal
                    return False
            elif abs(rest) > tol:
                return False
        return closing

    def _stalled(self, now: FloatArray, rates: FloatArray) -> bool:
        """Whether the robot has moved inside its goal's tolerance without closing on it
        for ``STALL_HOLD_CYCLES`` cycles in a row: every goal channel holds its tolerance,
        and none is closing on its goal fast enough to reach it within ``STALL_CYCLES``.

        Such a run ends there (it brakes to rest, and the stop rule finds it inside the
        tolerance) instead of driving on: a turn whose primitive, decoded in a category
        that is no goal candidate, crept forward at 0.014 rad/s 2.3 deg from its goal
        (inside the 3 deg tolerance) until the step limit (turn & approach at 1/4 of the
        grids, seed 5, from 9 deg, 0.15 m).
        """
        stalled = True
        for i, spec, goal, tol in self._brake_slots:
            error = spec.error(now[i], goal)
            rate = float(rates[i])
            closing = error * rate < 0.0 and abs(rate) * STALL_CYCLES >= abs(error)
            if abs(error) > tol or closing:
                stalled = False
                break
        self._stall = self._stall + 1 if stalled else 0
        return self._stall >= STALL_HOLD_CYCLES

    def _now(self, x: FloatArray) -> FloatArray:
        """Where the robot is, physical units, from this cycle's filtered readings ``x``
        (normalized): the readings themselves, or, with ``recover`` on a robot without
        velocity readings (``bind``), moved on by how far the filter makes them trail
        the robot: the change the commands sent so far made to the inputs
        (``command_rates_``), less that change filtered as the readings are. Called once
        a cycle (it counts the last command)."""
        now: FloatArray = (x + 1.0) / self._gain + self._lo
        if self._lead and self._command_rates is not None and self._lead_filter is not None:
            self._moved = self._moved + self._last @ self._command_rates
            now = now + self._moved - self._lead_filter.step(self._moved)
        return now

    def _decide(self, reading: Mapping[str, float]) -> StepOutput:
        x = self._pipe.step(np.array([reading[c] for c in self._channels], dtype=np.float64))
        self._x = x
        self._reading = reading
        self._features.push(x)
        category, novel, _ = self._live.update(x)
        if self._recognize:
            self._prim_live.update(x)
        if category != self._reachable_from:
            # before any motion, a goal no candidate category is reachable for is planned
            # toward a category near it; mid-run the current primitive goes on instead
            start = not self._started
            near = start and self._goal_fallback
            try:
                retarget(self, self._hmm, category, may_raise=start, near=near)
            except UnreachableGoalError as unreachable:
                category = self._alternative_start(category, near, unreachable)
        now = self._now(x)
        if self._keeps_noise():
            self._confirmation.observe(reading, self.goal)
        rest = self._rest_command
        if self._confirmation.pending:  # a goal being confirmed: until it is decided
            held = self._confirming(category, novel)
            if held is not None:
                return held
        elif category in self._stop_set and not self._confirmation.holding:
            values = dict(zip(self._channels, now.tolist(), strict=True))
            if self._goal_holds(values) and (not self._at_rest or readings_at_rest(reading)):
                if not self._started and self._confirmed < self.start_confirm_cycles:
                    # not moved yet: hold still while the (filtered) readings confirm it
                    self._confirmed += 1
                    return StepOutput(rest, category, novel, -1, self.name, False, False)
                if self._noise_known():  # else too few readings yet to tell: it goes on
                    if not self._must_confirm():
                        self._started = True
                        return StepOutput(
                            rest, category, novel, self._state, self.name, False, True
                        )
                    self._confirmation.begin()  # noisy readings: averaged while it holds still
                    held = self._confirming(category, novel)
                    if held is not None:
                        return held
        try:
            state = self._decode(category)
        except UnreachableGoalError:
            if not self._started or self._state < 0:
                raise
            state = self._state  # keep executing the current primitive until a plan exists
        changed = state != self._state
        if changed:
            self._support = self._outliers = 0
        if self._rest_start is None:  # the run's first primitive: a start from rest, or
            # one carried on at speed or resumed where a run of it stopped (resume_onset)
            started = self._features.cycles == 0
            self._rest_start = started and self._at_rest_command(self._last)
        self._state = state
        self._started = True
        row = self._features.row()
        floors = self._floors
        # the clock is the row's last feature: was this network trained on one this early?
        if floors is None or state >= floors.shape[0]:
            self._unshown_start = True
        else:
            self._unshown_start = bool(row[-1] < floors[state])
            if self._unshown_start and self._hold_floor:
                row[-1] = floors[state]  # rewritten each cycle
        ranges, overall = self._ranges, self._overall
        if ranges is not None and overall is not None and state < ranges.shape[0]:
            # a channel is held to its primitive's range until the run's readings have
            # been inside all the rows' range: a start beyond the demonstrations reads as
            # the nearest its primitive was shown; once inside, a deviation the rows never
            # held (a bearing drifting off) stays visible to the network that corrects it
            self._inside |= (x >= overall[:, 0]) & (x <= overall[:, 1])
            for j in np.flatnonzero(~self._inside):
                cols = self._window_columns[j]  # the windows lead the row; rewritten each cycle
                np.clip(row[cols], ranges[state, 0, cols], ranges[state, 1, cols], out=row[cols])
            if self._starts is not None and self._rest_start:
                self._start_up(row, x, state)
        y = self._generator.step(row, state)
        if self._recover:
            y = self._closed(category, now, self._returned(x, y))
        if self._held is not None:  # commands its demonstrations never moved stay at rest
            y = np.where(self._held, self._rest_command / self._scale, y)
        y = self._features.commit(y)
        return StepOutput(y * self._scale, category, novel, state, self.name, changed, False)

    def _start_up(self, row: FloatArray, x: FloatArray, state: int) -> None:
        """``input_range`` at a start from rest: an input whose first reading lies more
        than its goal tolerance outside every reading the primitives' rows held by the
        onset clock the network reads (a start closer to the goal than any demonstrated
        one) has its windows clipped to what the running primitive's rows held by then
        (with none by then: all the primitives' rows), until its reading is within the
        tolerance of what they held by the clock read; from then on, and for an input
        whose start lay among the demonstrated ones, the readings are read as they are (a
        deviation from the start-ups stays visible). From the clock's end every row
        counts, and the rule of the whole range above holds alone."""
        starts, union = self._starts, self._start_union
        assert starts is not None
        cycles = starts.shape[2] - 1
        k = int(np.clip(np.rint(row[-1] * cycles), 0, cycles))
        first = self._start_held is None
        if first:
            self._start_held = np.zeros(len(self._channels), dtype=bool)
        held = self._start_held
        assert held is not None
        if k >= cycles or state >= starts.shape[0] or not (first or held.any()):
            return
        for j, tol in enumerate(self._start_tolerance.tolist()):
            lo, hi = union[j, k]
            if not (first or held[j]) or not tol >= 0.0 or not lo <= hi:
                continue  # not held, no tolerance, or no row by this clock
            held[j] = not lo - tol <= float(x[j]) <= hi + tol
            if not held[j]:
                continue
            own_lo, own_hi = starts[state, j, k]
            if own_lo <= own_hi:  # NaN: the primitive had no row by this clock
                lo, hi = own_lo, own_hi
            cols = self._window_columns[j]
            np.clip(row[cols], lo, hi, out=row[cols])

    def _alternative_start(
        self, category: int, near: bool, unreachable: UnreachableGoalError
    ) -> int:
        """Before any motion, no plan from ``category``: the best-matching category of the
        live window from which a plan to a goal candidate exists (at most
        ``start_alternatives`` tried, best match first; ``BehaviorHMM.plannable_from``),
        decoded this cycle in its place; ``unreachable`` raised if none.

        A window at rest between two demonstrated starts can match best a category from
        which no demonstration led to the goal. As a component of turn & approach from a
        quarter of each grid (seed 7, 112 deg, 0.22 m), the turn then could not start,
        the complex behavior skipped it, reopened it since its goal did not hold, and the
        robot stood until the step limit. Later cycles in the same category go on with
        the primitive decoded here (``_decode`` keeps it while no plan exists).
        """
        count = self.start_alternatives
        alternative = self.alternative_start(self._hmm, category, count, near=near)
        if alternative < 0:
            raise unreachable
        return alternative

    def _noise_known(self) -> bool:
        """Whether the readings have been read long enough to tell whether they are noisy
        (always, for a policy that does not confirm its goal): a run that moved within its
        first ``START_CONFIRM_CYCLES`` cannot end before (a turn started 7 deg off, noise
        0.02, moved on a noisy reading and ended at its 7th, 6.9 deg off)."""
        return not self._keeps_noise() or self._confirmation.noise_known(self.goal)

    def _must_confirm(self) -> bool:
        """Whether a goal the stop rule found at rest must first be confirmed on the raw
        readings (:class:`GoalConfirmation`): they are noisy, and the robot can show rest
        (one that cannot stops at speed: nothing to average)."""
        return self._keeps_noise() and self._confirmation.needed(self.goal, self._tolerance)

    def _keeps_noise(self) -> bool:
        """Whether this policy records the readings' noise: it may confirm its goal, and
        the robot can show rest (one that cannot stops at speed: nothing to average)."""
        return self.confirm_goal and self._at_rest

    def _confirming(self, category: int, novel: bool) -> StepOutput | None:
        """One reading of the goal being confirmed: hold still (not decided yet), done
        (confirmed), or None (refuted: the generators go on, the stop rule waits)."""
        verdict = self._confirmation.confirm(self._reading, self.goal, self._tolerance)
        if verdict is False:
            return None
        if verdict:
            self._started = True
        rest = self._rest_command
        return StepOutput(rest, category, novel, self._state, self.name, False, bool(verdict))

    def _decode(self, category: int) -> int:
        """Active primitive for the current observation category (see ``state_decoding``)."""
        if not self._use_history:
            if self._recognize:
                scores = self._hmm.state_scores(category, self.goal_category)
                return self._recognized(self._log_pi + scores)
            return self._hmm.plan(category, self.goal_category).states[0]
        scores = self._hmm.state_scores(category, self.goal_category)
        if category != self._last_obs:
            # Forward Viterbi message over the distinct observations seen so far.
            if self._last_obs < 0:
                prior = self._log_pi
            else:
                # only the states the history leaves possible can lead anywhere
                alive = np.flatnonzero(np.isfinite(self._alpha))
                if alive.size == self._alpha.shape[0]:  # e.g. smoothed: no copy of A
                    prior = np.max(self._alpha[:, None] + self._log_A, axis=0)
                elif alive.size:
                    prior = np.max(self._alpha[alive, None] + self._log_A[alive], axis=0)
                else:
                    prior = np.full(self._alpha.shape[0], -np.inf)
            alpha = prior + self._log_B.column(category)
            top = alpha.max()
            if not np.isfinite(top):  # the history explains nothing any more: restart
                prior = self._log_pi
                alpha = prior + self._log_B.column(category)
                top = alpha.max()
            self._alpha = alpha - top
            self._prior = prior
            self._last_obs = category
        total = self._prior + scores
        best = int(np.argmax(total))
        if not np.isfinite(total[best]):
            return self._hmm.plan(category, self.goal_category).states[0]
        if self._outlier(total):
            return self._state
        if self._recognize:
            return self._recognized(total)
        return best

    def _outlier(self, total: FloatArray) -> bool:
        """Whether the running primitive goes on through an observation it never emitted.

        On noisy readings the observation window can stray for a few cycles into a
        category the running primitive was never seen in, which rules it out (its score
        is -inf) and forces a switch and, a few cycles later, the switch back: each a dip
        in the commands (approach, MuJoCo, noise 0.01: 12-46 primitive switches a run
        against 2-5 without noise). Such a category is believed once it has lasted as
        long as the readings' filter takes to pass a change (its lag, 7 cycles at 2 Hz);
        before that the running primitive goes on, if the observations explained it for
        as long before (one chosen on a cycle or two of noise at a start is not held).
        Only a policy that decodes the history (``state_decoding="history"``) holds, and
        only on noisy readings (:meth:`_noisy`): clean readings run as before, to the bit.
        """
        cur = self._state
        if cur < 0:
            return False
        if np.isfinite(total[cur]):
            self._outliers = 0
            self._support += 1
            return False
        if self._support < self._outlier_cycles or self._outliers >= self._outlier_cycles:
            return False
        if not self._noisy():
            return False
        self._outliers += 1
        return True

    def _recognized(self, total: FloatArray) -> int:
        """Best-matching live primitive among those the plan allows (finite score)."""
        miss = np.where(np.isfinite(total), self._prim_live.mismatch, np.inf)
        return int(np.argmin(miss))


def readings_at_rest(reading: Mapping[str, float]) -> bool:
    """Whether a reading shows the robot (nearly) still: |yaw rate|, |speed| within tolerance."""
    return all(abs(reading[c]) <= TOLERANCES[c] for c in REST_CHANNELS)


def retarget(
    controller: Any,
    hmm: Any,
    category: int,
    *,
    may_raise: bool,
    most_likely: bool = False,
    near: bool = False,
) -> None:
    """Keep ``controller.goal_category`` reachable from ``category``.

    When no observation path leads from the current category to the goal category,
    the controller switches to the best-matching goal candidate that is reachable
    (``model.goal_categories``), and from then on stops in any candidate category
    (within the physical tolerance). With ``near``, when no candidate is reachable,
    it plans to the nearest reachable category near the goal and nearer to it than
    ``category`` (``controller.goal_fallbacks``); the physical tolerance stops it at the
    goal on the way. If none is reachable, it raises before any motion (``may_raise``)
    and otherwise keeps its goal (the caller carries on with what it was doing until a
    plan exists again).
    """
    controller.planned_from(category)
    if most_likely:
        # among the goal candidates, the one the most likely observation path leads to
        # (the branch the robot is on), the best match first among equals; path
        # probabilities come from the cached goal trees, and no plan is built
        ranked = sorted(
            (-lp, order, int(candidate))
            for order, candidate in enumerate(controller.goal_candidates.tolist())
            if (lp := hmm.path_log_prob(category, candidate)) > -np.inf
        )
        best = next((c for _, _, c in ranked if hmm.can_plan(category, c)), -1)
        if best >= 0:
            if best != controller.goal_category:
                controller.aim_at(best)
            return
    if hmm.can_plan(category, controller.goal_category):
        return
    for candidate in controller.goal_candidates:
        if not hmm.can_plan(category, int(candidate)):
            continue
        # an intermediate goal: any category describing the goal place ends the run
        controller.aim_at(int(candidate))
        return
    if near:
        for fallback in controller.goal_fallbacks(category):
            if hmm.can_plan(category, int(fallback)):
                controller.aim_near(int(fallback))
                return
    if may_raise:
        raise UnreachableGoalError(
            f"no observation path leads from category {category} to any category matching "
            f"the goal {controller.goal}"
        )


def calibrates(model: Any) -> bool:
    """Whether runs of ``model`` calibrate the wheels: its ``wheel_calibration``, where
    its demonstrations measured how their wheels answered (``wheel_response_``); a model
    of an arm or a pen has nothing to calibrate against and runs without, silently."""
    return bool(getattr(model, "wheel_calibration", False)) and (
        getattr(model, "wheel_response_", None) is not None
    )


def make_policy(
    model: Any, goal: Mapping[str, float] | None, name: str = "", tolerance: float = 1.0
) -> Any:
    """The policy of a fitted SBLM or CBLM (``tolerance`` scales the stop tolerance)."""
    if getattr(model, "kind", None) == "CBLM":
        from behavior_hmm.models._complex_policy import ComplexPolicy

        return ComplexPolicy(model, goal, name=name, tolerance=tolerance)
    return SimplePolicy(model, goal, name=name, tolerance=tolerance)


def perform(
    model: Any,
    env: Any,
    *,
    start: Mapping[str, float] | None = None,
    goal: Mapping[str, float] | None = None,
    seed: int | None = None,
    noise: float | None = None,
    max_steps: int | None = None,
    pushes: Sequence[Mapping[str, float]] | None = None,
    fault_hold_s: float = DEFAULT_FAULT_HOLD_S,
) -> Trace:
    """Perform a learned behavior (SBLM or CBLM) in ``env`` from ``start`` to ``goal``.

    Parameters
    ----------
    model
        A fitted SBLM or CBLM.
    env
        Any Gymnasium env that meets the robot contract (docs/robots.md).
    start
        ``{"angle": deg, "distance": m}`` for ``env.reset``; ``None`` keeps the env default.
    goal
        Goal in physical units (e.g. ``{"angle": 0}``); ``None`` uses the model's default.
    seed, noise
        Passed to ``env.reset`` (sensor noise: sigma times each channel's range).
    max_steps
        Step limit; default the model's ``max_steps_``. A run that still closes in on
        its goal there may go on up to the model's ``progress_limit`` times as long.
    pushes
        Scheduled pushes ``{"step", "angle", "distance"}`` (see the env's reset options).
    fault_hold_s
        Seconds a non-finite reading on a channel the model reads is replaced by its
        last good value (default 0.1 s); past that the robot stops and the trace's
        ``reason`` is ``"sensor_fault"`` (see :func:`behavior_hmm.runtime.run_policy`).

    Raises
    ------
    UnreachableGoalError
        Before any motion, when no observation path leads from the start to the goal,
        or when the goal is one the model was never shown to stop at (a simple
        behavior's ``check_stoppable``).
    """
    stoppable = getattr(model, "check_stoppable", None)
    if stoppable is not None:
        stoppable(goal)
    policy = make_policy(model, goal)
    limit = int(max_steps if max_steps is not None else model.max_steps_)
    if limit < 1:
        raise ConfigError(f"max_steps must be >= 1, got {limit}")
    return run_policy(
        policy,
        env,
        start=start,
        seed=seed,
        noise=noise,
        max_steps=limit,
        pushes=pushes,
        fault_hold_s=fault_hold_s,
        progress_limit=float(getattr(model, "progress_limit", 1.0)),
        wheel_calibration=calibrates(model),
        wheel_response=getattr(model, "wheel_response_", None),
    )
