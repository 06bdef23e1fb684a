"""CBLM: the complex-behavior learning model (thesis chapter 5).

A CBLM's states are already learned behaviors (SBLMs or CBLMs). It learns only its
own observation categories and the counted A, B, C, π between its components from
demonstrations whose rows are tagged with the active sub-behavior. Components are
never retrained or modified; the model file embeds their saved bytes unchanged.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.cobart import CobART, suggest_dcm_scale
from behavior_hmm.cobart._similarity import DEFAULT_DCM_SCALE
from behavior_hmm.data import DEFAULT_CUTOFF_HZ, CommandScaler, Dataset, SignalPipeline
from behavior_hmm.errors import ConfigError, DatasetError, ModelFileError
from behavior_hmm.hmm import BehaviorHMM
from behavior_hmm.hmm._counting import Counting
from behavior_hmm.hmm._paths import PathSelfLoops
from behavior_hmm.models import _modelfile
from behavior_hmm.models._base import (
    DEFAULT_PROGRESS_LIMIT,
    LearnedBehavior,
    dataset_hash,
)
from behavior_hmm.models._goals import check_goal, check_input_names
from behavior_hmm.models._sblm import (
    SBLM,
    _check_updates,
    _cobart_from,
    _cobart_params,
    _jsonable_params,
    _package_version,
    _prefixed,
    added_wheel_response,
    continued_cobart,
    nominal_episodes,
)

FloatArray = NDArray[np.float64]

#: Channels a goal can be stated on, in order of preference.
GOAL_CHANNELS = ("angle", "distance")

#: add_component refuses demonstrations that move an input this many times faster (the
#: CobART's ``"auto"`` DCM scale) than the CBLM's own demonstrations moved it: the
#: observation categories, whose DCM scale stays, would split every new window apart.
DCM_SCALE_RATIO = 100.0
#: An input whose automatic DCM scale is below this share of the largest one counts as
#: never moving in a CBLM's demonstrations (it gets ``DEFAULT_DCM_SCALE``).
STILL_DCM_RATIO = 1e-3


def _component_name(model: Any) -> str:
    return str(getattr(model, "behavior_", "")) or type(model).__name__.lower()


class CBLM(LearnedBehavior):
    """Complex-behavior learning model: learned behaviors as states of a Behavior-HMM.

    Parameters
    ----------
    components
        Fitted SBLMs or CBLMs; each is a state, named by its ``behavior_`` (the tag its
        rows carry in the ``behavior`` column of the training data).
    inputs
        Sensor channels of the complex model's own observation categories.
    observation_params
        Overrides of CobART's observation preset (thesis table 4.2); a ``rho`` here
        overrides ``observation_vigilance``.
    observation_vigilance
        Vigilance ρ of the CBLM's observation categories: 0.99 (thesis: 0.95). Its
        observations span two channels, and at 0.95 a still window 9 deg off the
        object falls in the same category as an aligned one, so "turn first" and
        "approach only" could not be told apart near the 3 deg tolerance (turn &
        approach on MuJoCo, 15 test starts: 0.98 gives 83.9 %, 0.99 86.4 %).
    cutoff_hz
        Low-pass cut-off (Hz) of the inputs, as for the SBLM.
    counting, smoothing, path_self_loops
        Behavior-HMM estimation options (thesis: ``counting="changes"``).
    repair
        When the plan has nothing left to run but a goal channel misses its
        tolerance, run a component whose learned effect closes that gap (thesis:
        ``False``, the run then waits at its step limit).
    preempt_uncovered
        At a decision point, a goal channel that no planned component can close (by the
        components' learned effects) is closed first by the component that closes it
        best (thesis: ``False``).
    switch_cycles
        Control cycles the plan must ask for another component before a running one is
        replaced (8 = 128 ms; thesis: 1, switch at once).
    skip_reached
        The plan's next component does not replace the running one while the goal it
        would be run toward already holds: it would hand back at once, and the robot
        would stop for nothing. Under sensor noise the observation category flickers
        across the border where the demonstrations switched, and without this rule an
        approach already on its bearing was replaced by a turn to the same bearing and
        back, pausing at each switch (thesis: False, the plan's component runs).
    start_alternatives
        Runner-up categories of the start window tried when the best match has no
        path to the goal: the best-matching ones from which an observation path leads
        to a goal category, so the nearest demonstrated place the goal was reached
        from (thesis: 0, the goal is unreachable).
    command_rate_limit
        If > 0, the complex behavior's command may change per control cycle by at most
        this multiple of the largest change in its demonstrations (``delta_scale_``,
        rad/s), across component switches too, and it stops softly (thesis: 0).
    progress_limit
        A run that at its step limit (``max_steps_``) still closes in on its goal goes
        on, up to this many times ``max_steps_`` cycles in all, as long as every quarter
        of ``max_steps_`` lowers its goal error by 10 % (``runtime.Progress``): a robot
        slower than its demonstrations (a lower speed limit, a lagging motor) is not
        stopped short while it is getting there (thesis: 1, a fixed limit).
    wheel_calibration
        If true, the control loop corrects the wheels' gain difference while the complex
        behavior runs, across its components, as :class:`SBLM`'s ``wheel_calibration``
        does (:class:`~behavior_hmm.runtime.WheelCalibration`; thesis: off).
    settle_cycles
        When the goal's tolerance is entered while the running component still heads
        for a goal inside it, that component may finish (its own stop rule: at rest,
        braking into its goal) for up to this many control cycles before the complex
        behavior stops (64 = 1.02 s; thesis: 0, stop at once, however fast).
    forward_goals
        An intermediate goal never sends a channel back, away from the complex goal:
        a channel the goal states (not the angle) whose exit-category prototype lies
        behind the robot keeps its current value (thesis: False, the prototype).
    handover_pause
        When a component ends at rest, the next one starts after the demonstrations'
        pause at a switch (``handover_cycles_``; thesis: False, at once).
    reach_check
        A component that holds some commands at rest (``held_commands_``: grasp never
        moves the wheels) starts, and goes on until it has begun its own work, only near
        where its demonstrations start it on the inputs it needs and cannot move itself
        (``reach_``): grasp only with the object as close and as straight ahead as at
        the end of an approach. Elsewhere the component whose goal states that input and
        whose effect brings it back runs first: approach again after the object is
        nudged away (thesis: False).
    parallel
        When the demonstrations run two components at once (rows tagged ``a+b``: a
        parallel teacher, ``collect turn-approach-parallel``), run them at once where the
        teacher did (thesis §7.2; thesis: False, one component at a time). The planned
        component ``a`` runs as always; in an observation category where most of the
        demonstrations' rows ran ``b`` beside ``a`` (``parallel_``), ``b`` runs too,
        toward its goal, and the command is ``a``'s along ``a``'s own command direction
        plus ``b``'s along ``b``'s (``directions_``), ``b``'s weighted by the share of
        ``a``'s goal error closed since ``b`` started (``b`` takes over as ``a``'s goal
        comes near); when the plan hands over to ``b`` it goes on without a restart.
        Demonstrations without such rows leave the model as sequential as the thesis's.
    mirror
        If true, also learn from every demonstration's left–right mirror image, as the
        SBLM's ``mirror`` does (its components are fitted with their own). ``False``
        (thesis, and the default): the demonstrations as given.
    random_state
        Seed (kept for symmetry; nothing random is drawn when fitting a CBLM).

    Attributes
    ----------
    names_ : list of str
        Component names, in state order.
    pipeline_, observations_, hmm_
        As for the SBLM (no motion primitives or generators of its own).
    command_scale_ : float
        Largest absolute command in the complex demonstrations (for evaluation).
    handover_cycles_ : int
        Median, over the demonstrations' component switches, of the consecutive cycles
        around the switch whose commands stay under ``HANDOVER_REST`` of the command
        scale: the teacher settles each component finer than the goal's tolerance
        (MuJoCo turn & approach: 23 cycles, 0.37 s).
    effects_ : ndarray of shape (n_components, n_inputs)
        Each component's mean per-step effect on each input in the demonstrations.
    parallel_ : ndarray of int, shape (n_observations,)
        The component run beside the planned one in each observation category (-1:
        none): where the demonstrations' rows of a component ran another at once.
    directions_ : ndarray of shape (n_components, n_commands)
        Each component's command direction: the first principal direction of its
        normalized commands in the demonstrations (turn: the wheels' difference,
        approach: their sum).
    reach_ : ndarray of shape (n_components, n_inputs, 2)
        The smallest and largest value of each input (of its magnitude for an angle)
        where the demonstrations start each component (NaN: it never runs); ``None`` in
        model files written before it existed.
    updates_ : list of dict
        One record per :meth:`add_component` since the last :meth:`fit` (saved with the
        model): the ``component`` added, the new data's ``dataset_sha256``, ``episodes``,
        ``rows``, ``env``, ``package_version``, ``new_observations`` and the ``source``
        file, if given.
    """

    kind = "CBLM"
    reach_: np.ndarray | None

    def __init__(
        self,
        components: Sequence[Any] = (),
        inputs: Sequence[str] = ("distance", "angle"),
        *,
        observation_params: Mapping[str, Any] | None = None,
        observation_vigilance: float = 0.99,
        cutoff_hz: float | None = DEFAULT_CUTOFF_HZ,
        counting: str = "steps",
        smoothing: float = 0.0,
        path_self_loops: str = "drop",
        repair: bool = True,
        preempt_uncovered: bool = True,
        switch_cycles: int = 8,
        skip_reached: bool = True,
        start_alternatives: int = 5,
        command_rate_limit: float = 1.5,
        settle_cycles: int = 64,
        forward_goals: bool = True,
        handover_pause: bool = True,
        reach_check: bool = True,
        progress_limit: float = DEFAULT_PROGRESS_LIMIT,
        wheel_calibration: bool = True,
        parallel: bool = True,
        mirror: bool = False,
        random_state: int = 0,
    ) -> None:
        self.components = components
        self.inputs = inputs
        self.observation_params = observation_params
        self.observation_vigilance = observation_vigilance
        self.cutoff_hz = cutoff_hz
        self.counting = counting
        self.smoothing = smoothing
        self.path_self_loops = path_self_loops
        self.repair = repair
        self.preempt_uncovered = preempt_uncovered
        self.switch_cycles = switch_cycles
        self.skip_reached = skip_reached
        self.start_alternatives = start_alternatives
        self.command_rate_limit = command_rate_limit
        self.settle_cycles = settle_cycles
        self.forward_goals = forward_goals
        self.handover_pause = handover_pause
        self.reach_check = reach_check
        self.progress_limit = progress_limit
        self.wheel_calibration = wheel_calibration
        self.parallel = parallel
        self.mirror = mirror
        self.random_state = random_state

    def check_params(self) -> None:
        """Refuse parameters out of range (ConfigError) before any data is read."""
        super().check_params()
        rho = self.observation_vigilance
        if isinstance(rho, bool) or not isinstance(rho, int | float) or not 0 <= rho <= 1:
            raise ConfigError(f"observation_vigilance must lie in [0, 1], got {rho!r}")
        for name in (
            "repair",
            "preempt_uncovered",
            "skip_reached",
            "forward_goals",
            "handover_pause",
            "reach_check",
            "parallel",
        ):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{name} must be true or false, got {getattr(self, name)!r}")
        for name, low in (("switch_cycles", 1), ("start_alternatives", 0), ("settle_cycles", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= 1000:
                raise ConfigError(f"{name} must be an integer in [{low}, 1000], got {value!r}")

    def _checked(
        self, available: Sequence[str] | None = None
    ) -> tuple[tuple[str, ...], list[Any], list[str]]:
        self.check_params()
        inputs = (self.inputs,) if isinstance(self.inputs, str) else tuple(self.inputs)
        check_input_names(inputs, available)
        components = list(self.components)
        if not components:
            raise ConfigError("a CBLM needs at least one component behavior")
        for c in components:
            if getattr(c, "kind", None) not in ("SBLM", "CBLM") or not hasattr(c, "hmm_"):
                raise ConfigError("every component must be a fitted SBLM or CBLM")
        names = [_component_name(c) for c in components]
        if len(set(names)) != len(names):
            raise ConfigError(f"component names must be distinct, got {names}")
        return inputs, components, names

    #: ``behavior_`` of demonstrations that do not name theirs
    _unnamed = "complex"

    def _fit_setup(self, dataset: Any) -> tuple[tuple[str, ...], Any]:
        """Fit step 1: the parameters, the inputs and the components."""
        inputs, components, names = self._checked(getattr(dataset, "sensor_channels", None))
        return inputs, (components, names)

    def _fit_rows(self, dataset: Dataset, inputs: tuple[str, ...], context: Any) -> tuple[Any, Any]:
        """Fit step 2: the nominal demonstrations, each row tagged with its component."""
        components, names = context
        dataset, states, partners = _nominal_tagged(dataset, names)
        return dataset, (components, names, states, partners)

    def _fit_learn(
        self,
        dataset: Dataset,
        x: np.ndarray,
        inputs: tuple[str, ...],
        pipeline: SignalPipeline,
        context: Any,
    ) -> None:
        """Fit step 4: observation categories, the counted A, B, C, π between components,
        and the commands (scales, largest step, the pause at a switch)."""
        components, names, states, partners = context
        lengths = dataset.lengths
        overrides = {
            "rho": float(self.observation_vigilance),
            **dict(self.observation_params or {}),
        }
        if overrides.get("dcm_scale", "auto") == "auto":
            # an input the demonstrations barely move (a gripper robot's arm while it turns
            # and approaches: servo jitter, 1e-6 per step) gets the scale of one that never
            # moves, so a component added later that moves it can join (add_component)
            scale = suggest_dcm_scale(x, lengths)
            still = scale < STILL_DCM_RATIO * scale.max()
            if still.any():
                overrides["dcm_scale"] = np.where(still, DEFAULT_DCM_SCALE, scale).tolist()
        obs = CobART.observations(**overrides).fit(x, lengths)
        obs = obs.compacted(x, lengths)
        hmm = BehaviorHMM(
            n_states=len(components),
            n_observations=obs.n_categories_,
            counting=cast(Counting, self.counting),
            smoothing=self.smoothing,
            path_self_loops=cast(PathSelfLoops, self.path_self_loops),
        ).fit(states, obs.labels_, lengths)
        self.components_ = components
        self.names_ = names
        self.observations_ = obs
        self.__dict__.pop("_latest_physical", None)  # cache of category_values
        self.hmm_ = hmm
        wanted = tuple(dataset.command_channels)
        for name, component in zip(names, components, strict=True):
            if tuple(component.command_channels) != wanted:
                raise ConfigError(
                    f"component {name} commands {', '.join(component.command_channels)}; the "
                    f"demonstrations command {', '.join(wanted)}"
                )
        self.command_scale_ = float(np.max(np.abs(dataset.commands))) or 1.0
        units = [spec.unit for spec in dataset.command_specs]
        if len(set(units)) > 1:  # a scale per unit, as an SBLM's (CommandScaler)
            scales = CommandScaler(units).fit(dataset.commands).scales_
        else:
            scales = np.full(len(units), self.command_scale_)
        self._learn_commands(dataset, scales)
        self.delta_scale_ = _largest_step(dataset.commands, lengths)
        self.handover_cycles_ = _handover_cycles(
            dataset.commands,
            states,
            lengths,
            scales if len(set(units)) > 1 else self.command_scale_,
        )
        self.parallel_ = _parallel_partners(obs.labels_, states, partners, obs.n_categories_)
        self.directions_ = _command_directions(
            dataset.commands, scales, self.rest_command, states, partners, len(components)
        )

    def _fit_finish(
        self,
        dataset: Dataset,
        x: np.ndarray,
        inputs: tuple[str, ...],
        raw: np.ndarray,
        finals: np.ndarray,
        context: Any,
    ) -> None:
        """Fit step 6: the default goal, the step limit, and what each component does
        (``effects_``) and where it starts (``reach_``)."""
        components, _, states, _ = context
        # the behavior's declared goal on the inputs; without one, the data contract's
        # angle and distance 0 among them
        declared = self._declared_goal(dataset, inputs)
        self.default_goal_ = declared or {c: 0.0 for c in GOAL_CHANNELS if c in inputs}
        if not self.default_goal_:
            self.default_goal_ = {inputs[0]: self.rest_values_[inputs[0]]}
        lengths = dataset.lengths
        self.max_steps_ = int(
            max(1000, 2 * int(lengths.max()), sum(c.max_steps_ for c in components))
        )
        wraps = [self.channel_spec(c).wraps for c in inputs]
        self.effects_ = _effects(states, raw, lengths, len(components), wraps)
        self.reach_ = _reach(states, raw, lengths, len(components), wraps)

    def _declared_goal(self, dataset: Dataset, inputs: Sequence[str]) -> dict[str, float]:
        """The dataset's declared goal (``goal`` metadata, from the behavior's spec: grasp's
        arm up and object held) on the inputs that can be goals; empty without one."""
        return {
            str(c): float(v)
            for c, v in (dataset.metadata.get("goal") or {}).items()
            if c in inputs and self.channel_spec(str(c)).tolerance is not None
        }

    @property
    def wheel_response_(self) -> np.ndarray | None:
        """How the demonstrated robot's wheels answered: its components' sums added up
        (each component's ``wheel_response_``; None where none has them). The reference
        ``wheel_calibration`` restores; a component that joins adds its own."""
        total = None
        for component in self.components_:
            total = added_wheel_response(total, getattr(component, "wheel_response_", None))
        return total

    # ----------------------------------------------------------- add_component
    def add_component(
        self,
        model: Any,
        dataset: Dataset,
        *,
        source: str | os.PathLike[str] | None = None,
    ) -> CBLM:
        """Learn a new behavior incrementally: ``model`` joins the fitted CBLM as a state.

        The thesis's on-line scheme (section 7.1): the structure (a new state) and the
        parameters of the Behavior-HMM are updated from demonstrations of the new
        behavior only; no component is retrained, and the demonstrations the CBLM was
        fitted on are not needed. ``model`` becomes state ``K`` (the next index); the
        demonstrations' ``behavior`` column names, on every row, the new component or an
        existing one (episodes of the new component alone, or episodes that switch from
        existing components into it).

        What stays, bit for bit:

        * Every existing component (its embedded file is byte-identical), ``inputs_``,
          ``pipeline_`` (the new readings go through the fitted filter and ranges; the
          demonstrations must have the same ranges and control period), ``provenance_``
          and ``train_data_`` (those of the fit).
        * Every existing observation category index; prototypes no new window resonates
          with; ``dcm_scale_`` (the observations' rate scale, from the fitted
          demonstrations: demonstrations that move an input over ``DCM_SCALE_RATIO``
          times faster are refused, e.g. approach joining a CBLM of turn fitted at
          distance 0, where the distance moved by rounding only).
        * The existing rows of ``effects_``: the old demonstrations' steps are not stored,
          so a component's mean effect is kept as the fit learned it, even when the new
          demonstrations run that component too.
        * ``rest_values_`` (the median of the old demonstrations' final readings, which
          are not stored) and ``default_goal_`` (the fitted behavior's: the old task runs
          without a goal as before; give the new behavior's, e.g. grasp joining turn &
          approach: ``goal={"arm": 80, "object_present": 1}``).

        What moves:

        * ``components_`` and ``names_`` gain ``model`` at index ``K``.
        * ``observations_`` learns on the new demonstrations with
          :meth:`CobART.partial_fit`, as :meth:`SBLM.partial_fit` continues its
          CobARTs: resonating prototypes move, new categories are added at the end (those
          that win none of the new windows dropped), no index changes.
        * ``hmm_``: one more state and the new categories; the new rows' (component,
          category) labels are counted in with :meth:`BehaviorHMM.partial_fit`, so the
          tables equal the old counts plus the new episodes' counts.
        * ``effects_`` gains row ``K``: the new component's mean per-step effect on each
          input over the new demonstrations' rows it is active on.
        * ``command_scale_``, ``command_scales_`` and ``delta_scale_``: the larger of the
          fitted value and the new demonstrations' (the maxima :meth:`fit` would take on
          all demonstrations together).
        * ``max_steps_``: the larger of the fitted value, twice the longest new
          demonstration and the components' step limits summed (what :meth:`fit` takes).
        * ``handover_cycles_``: kept when it is above 0; a CBLM whose demonstrations
          never paused at a switch (0: e.g. a single component) takes the new
          demonstrations' median pause (the old switches' pauses are not stored).
        * ``behavior_``: the new demonstrations' ``behavior`` metadata (the composed
          behavior they show, e.g. ``turn-approach`` when approach joins turn), unless it
          names the new component itself (demonstrations of it alone): then kept.
        * ``updates_`` gets one record per update (the component's name, the new data's
          hash, episodes, rows, env, package version, new categories and ``source``),
          saved in the model file.

        Parameters
        ----------
        model
            A fitted SBLM or CBLM, named by its ``behavior_``, that is not yet a
            component. It must command the CBLM's command channels and read only inputs
            the CBLM or its components read.
        dataset
            Demonstrations tagged per row with the active component (``behavior``
            column), with the CBLM's input channels (same declarations and ranges),
            command channels and control period, from the same robot.
        source
            The file the demonstrations came from, recorded in the update's record.

        Returns
        -------
        CBLM
            ``self``. Nothing is changed when an error is raised.

        Raises
        ------
        NotFittedError
            The CBLM is not fitted.
        ConfigError
            A model that is not a fitted behavior, is already a component, commands other
            channels or reads inputs no component needs; demonstrations of another
            robot, rates or channels, that never run the new component, or that move an
            input far faster than the CBLM's demonstrations did (``DCM_SCALE_RATIO``).
        DatasetError
            Untagged demonstrations, or a tag that names no component.
        """
        self._check_fitted()
        self.check_params()
        if not isinstance(dataset, Dataset):
            raise ConfigError(
                f"add_component expects a behavior_hmm.data.Dataset, got {type(dataset)}"
            )
        if getattr(model, "kind", None) not in ("SBLM", "CBLM") or not hasattr(model, "hmm_"):
            raise ConfigError("the new component must be a fitted SBLM or CBLM")
        name = _component_name(model)
        if name in self.names_:
            raise ConfigError(f"{name} is already a component ({', '.join(self.names_)})")
        needed = set(self.inputs_).union(*(c.inputs_ for c in self.components_))
        extra = [c for c in model.inputs_ if c not in needed]
        if extra:
            raise ConfigError(
                f"component {name} reads {', '.join(extra)}, which neither the CBLM nor its "
                f"components read ({', '.join(sorted(needed))})"
            )
        if tuple(model.command_channels) != tuple(self.command_channels):
            raise ConfigError(
                f"component {name} commands {', '.join(model.command_channels)}; the CBLM "
                f"commands {', '.join(self.command_channels)}"
            )
        inputs = tuple(self.inputs_)
        missing = [c for c in inputs if c not in dataset.sensor_channels]
        if missing:
            raise ConfigError(
                f"the demonstrations lack the CBLM's input(s) {', '.join(missing)} "
                f"(they have {', '.join(dataset.sensor_channels)})"
            )
        self._check_new_demonstrations(dataset, inputs)
        names = [*self.names_, name]
        components = [*self.components_, model]
        k = len(self.names_)
        dataset = self._as_learned(dataset)
        dataset, states, partners = _nominal_tagged(dataset, names)
        if not (states == k).any():
            raise ConfigError(f"the demonstrations never run the new component {name}")
        x = self.pipeline_.transform(dataset)
        lengths = dataset.lengths
        fitted_scale = self.observations_.dcm_scale_
        new_scale = suggest_dcm_scale(x, lengths)
        for j, c in enumerate(inputs):
            if fitted_scale[j] * DCM_SCALE_RATIO < new_scale[j]:
                raise ConfigError(
                    f"the CBLM's demonstrations barely moved {c} (DCM scale "
                    f"{fitted_scale[j]:.2g}, the new ones' {new_scale[j]:.2g}): its "
                    f"categories cannot follow the new motion; fit a CBLM on "
                    f"demonstrations of all its components"
                )
        obs = continued_cobart(self.observations_, x, lengths)
        hmm = BehaviorHMM.from_arrays(self.hmm_.to_arrays(), self.hmm_.params)
        hmm.set_params(n_states=len(names), n_observations=obs.n_categories_)
        hmm.partial_fit(states, obs.labels_, lengths)
        raw = dataset.columns(inputs)
        wraps = [self.channel_spec(c).wraps for c in inputs]
        effect = _effects(states, raw, lengths, len(names), wraps)[k]
        direction = _command_directions(
            dataset.commands, self.command_scales_, self.rest_command, states, partners, k + 1
        )[k]
        reach = _reach(states, raw, lengths, len(names), wraps)[k]
        commands = np.asarray(dataset.commands, dtype=np.float64)
        scale = max(self.command_scale_, float(np.max(np.abs(commands))))
        units = [spec.unit for spec in self.command_specs_]
        if len(set(units)) > 1:
            scales = np.maximum(self.command_scales_, CommandScaler(units).fit(commands).scales_)
        else:
            scales = np.full(len(units), scale)
        handover = self.handover_cycles_
        if handover == 0:
            handover = _handover_cycles(
                commands, states, lengths, scales if len(set(units)) > 1 else scale
            )
        behavior = str(dataset.metadata.get("behavior") or self.behavior_)
        record: dict[str, Any] = {
            "component": name,
            "dataset_sha256": dataset_hash(dataset),
            "episodes": len(dataset),
            "rows": int(dataset.n_samples),
            "env": str(
                dataset.metadata.get("env") or dataset.metadata.get("simulator") or "unknown"
            ),
            "package_version": _package_version(),
            "new_observations": obs.n_categories_ - self.observations_.n_categories_,
        }
        if source is not None:
            record["source"] = str(source)
        # everything is computed: only now does the model change
        self.components = components
        self.components_ = components
        self.names_ = names
        self.observations_ = obs
        self.__dict__.pop("_latest_physical", None)  # cache of category_values
        self.hmm_ = hmm
        self.effects_ = np.vstack([self.effects_, effect[None, :]])
        if getattr(self, "parallel_", None) is not None:  # the new categories: none beside
            grown = np.full(obs.n_categories_, -1, dtype=np.int64)
            grown[: self.parallel_.shape[0]] = self.parallel_
            self.parallel_ = grown
            self.directions_ = np.vstack([self.directions_, direction[None, :]])
        if self.reach_ is not None:
            self.reach_ = np.concatenate([self.reach_, reach[None]], axis=0)
        self.command_scale_ = scale
        self.command_scales_ = np.asarray(scales, dtype=np.float64)
        self.delta_scale_ = max(self.delta_scale_, _largest_step(commands, lengths))
        self.handover_cycles_ = int(handover)
        self.max_steps_ = int(
            max(self.max_steps_, 2 * int(lengths.max()), sum(c.max_steps_ for c in components))
        )
        if behavior != name:
            self.behavior_ = behavior
        self.updates_ = [*getattr(self, "updates_", []), record]
        return self

    def _check_new_demonstrations(self, dataset: Dataset, inputs: tuple[str, ...]) -> None:
        """Refuse demonstrations the fitted pipeline, commands or robot cannot take."""
        self._check_same_robot(dataset, inputs, "CBLM's")

    # ----------------------------------------------------------------- queries
    def resolve_goal(self, goal: Mapping[str, float] | None) -> dict[str, float]:
        """The goal in physical units on this model's inputs (default: angle 0, distance 0).

        Channels the goal leaves out keep their default, so ``{"distance": 0.6}`` means
        facing the object at 0.6 m.
        """
        self._check_fitted()
        if goal is None:
            return dict(self.default_goal_)
        return {**self.default_goal_, **check_goal(goal, self.inputs_, self.channels_)}

    def category_values(self, category: int) -> dict[str, float]:
        """Physical value of each input at the end of an observation category's prototype."""
        self._check_fitted()
        latest = self.__dict__.get("_latest_physical")
        if latest is None:  # computed once: the runtime asks every cycle
            table = self.pipeline_.normalizer.ranges or {}
            ranges = np.array([table[c] for c in self.inputs_], dtype=np.float64)
            latest = self.observations_.prototypes_physical(ranges)[:, -1, :].copy()
            self._latest_physical = latest
        return {c: float(latest[category, j]) for j, c in enumerate(self.inputs_)}

    def component_goal(
        self,
        component: int,
        category: int,
        final_goal: Mapping[str, float],
        *,
        final: bool | None = None,
    ) -> dict[str, float]:
        """Intermediate goal handed to a component: the exit observation in its channels.

        Channels the complex goal states take the goal's value when the exit observation
        is the goal (``final``; by default, when it is the goal category); otherwise the
        exit category's prototype values. Only
        channels that are goal channels of the component (those of its default goal) are
        handed down, e.g. ``{angle 0, distance 0.8}`` -> turn gets ``angle = 0``.
        """
        model = self.components_[component]
        values = self.category_values(category)
        if final is None:
            final = category == self.goal_category(final_goal)
        if final:
            values.update(final_goal)
        goal = {}
        for channel in model.default_goal_:
            if channel in values:
                goal[channel] = values[channel]
            else:
                goal[channel] = model.default_goal_[channel]
        for channel in goal:
            spec = model.channel_spec(channel)
            if spec.wraps:
                # an aligned exit observation means "aligned": a bearing within its
                # tolerance of 0 is 0 (face the object)
                if spec.tolerance is not None and abs(goal[channel]) <= spec.tolerance:
                    goal[channel] = 0.0
            elif spec.range[0] >= 0.0:
                # a quantity that is never negative (a distance: never behind contact)
                # stays within the component's own range
                _, far = model.pipeline_.normalizer.ranges[channel]
                goal[channel] = float(np.clip(goal[channel], 0.0, far))
        return goal

    # -------------------------------------------------------------- generation
    # --------------------------------------------------------------- save/load
    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the model (own tables + the components' files embedded byte for byte)."""
        self._check_fitted()
        arrays: dict[str, np.ndarray] = {}
        for name, arr in self.hmm_.to_arrays().items():
            arrays[f"hmm.{name}"] = arr
        arrays["obs.prototypes"] = self.observations_.prototypes_
        arrays["obs.counts"] = self.observations_.counts_
        arrays["obs.dcm_scale"] = self.observations_.dcm_scale_
        arrays["effects"] = self.effects_
        if getattr(self, "parallel_", None) is not None and (self.parallel_ >= 0).any():
            # only a model that learned parallel runs stores them: the file as before
            arrays["parallel"] = self.parallel_
            arrays["directions"] = self.directions_
        if self.reach_ is not None:
            arrays["reach"] = self.reach_
        for i, component in enumerate(self.components_):
            arrays[f"component.{i}"] = np.frombuffer(_model_bytes(component), dtype=np.uint8)
        state = {
            "inputs": list(self.inputs_),
            "names": list(self.names_),
            "kinds": [c.kind for c in self.components_],
            "pipeline": self.pipeline_.to_dict(),
            "observations": _cobart_params(self.observations_),
            "hmm": self.hmm_.params,
            "command_scale": self.command_scale_,
            "delta_scale": self.delta_scale_,
            "handover_cycles": self.handover_cycles_,
            "rest_values": self.rest_values_,
            "default_goal": self.default_goal_,
            "max_steps": self.max_steps_,
            "behavior": self.behavior_,
            "channels": self._channels_state(),
            **self._commands_state(),
            "train_data": self.train_data_,
            "provenance": dict(self.provenance_),
        }
        if getattr(self, "updates_", None):  # a model never updated: the file as before
            state["updates"] = [dict(record) for record in self.updates_]
        params = _jsonable_params({k: v for k, v in self.get_params().items() if k != "components"})
        _modelfile.dump(path, self.kind, params, state, arrays)

    @classmethod
    def _from_state(
        cls,
        params: Mapping[str, Any],
        state: Mapping[str, Any],
        arrays: Mapping[str, np.ndarray],
        budget: _modelfile.Budget | None = None,
    ) -> CBLM:
        budget = _modelfile.Budget() if budget is None else budget
        kinds = state["kinds"]
        if not isinstance(kinds, list) or not 1 <= len(kinds) <= _modelfile.MAX_COMPONENTS:
            raise ModelFileError(
                f"kinds must list 1 to {_modelfile.MAX_COMPONENTS} component kinds"
            )
        own = {"obs.prototypes", "obs.counts", "obs.dcm_scale", "effects", "reach"}
        own |= {"parallel", "directions"}
        own |= {f"component.{i}" for i in range(len(kinds))}
        extra = sorted(k for k in arrays if k not in own and not k.startswith("hmm."))
        if extra:
            raise ModelFileError(f"unexpected arrays: {', '.join(extra[:5])}")
        components = []
        for i, kind in enumerate(kinds):
            raw = _modelfile.check_array(arrays, f"component.{i}", ndim=1, kind="u")
            if raw.dtype != np.uint8:
                raise ModelFileError(f"array 'component.{i}' must hold bytes (uint8)")
            loaders: dict[str, type[LearnedBehavior]] = {"SBLM": SBLM, "CBLM": CBLM}
            loader = loaders.get(kind) if isinstance(kind, str) else None
            if loader is None:
                raise ModelFileError(f"component {i} has unknown kind {kind!r}")
            with budget.component():  # refused past MAX_NESTING levels
                components.append(loader._load(raw.tobytes(), f"component {i}", budget))
        model = cls(components=components, **params)
        inputs, _, names = model._checked()
        if list(names) != list(state["names"]) or list(inputs) != list(state["inputs"]):
            raise ModelFileError("component names or inputs do not match the model's state")
        pipeline = SignalPipeline.from_dict(_modelfile.check_mapping(state["pipeline"], "pipeline"))
        if pipeline.channels != inputs:
            raise ModelFileError("pipeline channels do not match the inputs")
        _modelfile.check_pipeline(pipeline)
        window = _modelfile.check_mapping(state["observations"], "observations").get("window")
        _modelfile.check_int(window, "observations window", 1, _modelfile.MAX_WINDOW)
        # The HMM first: its tables bound the number of categories CobART restores.
        hmm = BehaviorHMM.from_arrays(
            _prefixed(arrays, "hmm"), _modelfile.check_mapping(state["hmm"], "hmm")
        )
        protos = _modelfile.check_array(arrays, "obs.prototypes", kind="biuf", finite=False)
        if protos.ndim < 1 or protos.shape[0] != hmm.n_observations_:
            raise ModelFileError("observation prototypes and HMM sizes disagree")
        obs = _cobart_from(state["observations"], arrays, "obs", len(inputs))
        if hmm.n_states_ != len(components) or hmm.n_observations_ != obs.n_categories_:
            raise ModelFileError("HMM sizes do not match the components and categories")
        model.inputs_ = inputs
        model.components_ = components
        model.names_ = names
        model.pipeline_ = pipeline
        model.observations_ = obs
        model.hmm_ = hmm
        effects = _modelfile.check_array(arrays, "effects", ndim=2)
        if effects.shape != (len(components), len(inputs)):
            raise ModelFileError("effects must have one row per component, one column per input")
        model.effects_ = effects
        # files written before the reach existed have none: no reach check then
        model.reach_ = None
        if "reach" in arrays:
            reach = _modelfile.check_array(arrays, "reach", ndim=3, finite=False)
            if reach.shape != (len(components), len(inputs), 2) or np.isinf(reach).any():
                raise ModelFileError("reach must be (components, inputs, 2), without infinities")
            model.reach_ = reach
        # files written before the rate limit existed have none: no limit then
        delta = _modelfile.check_number(state.get("delta_scale", 0.0), "delta_scale")
        if delta < 0:
            raise ModelFileError("delta_scale must be >= 0")
        model.delta_scale_ = delta
        # files written before the handover pause existed have none: no pause then
        model.handover_cycles_ = _modelfile.check_int(
            state.get("handover_cycles", 0), "handover_cycles", 0, _modelfile.MAX_STEPS
        )
        model._restore_common(state, inputs)
        model._restore_commands(state)
        model.parallel_, model.directions_ = _parallel_from(arrays, len(components), obs, model)
        model.updates_ = _check_component_updates(state.get("updates"), names)
        return model


def _nominal_tagged(dataset: Dataset, names: list[str]) -> tuple[Dataset, np.ndarray, np.ndarray]:
    """The nominal demonstrations, the component index of each of their rows and the
    component run beside it (-1: none; see :func:`_tag_states`).

    Corrective demonstrations (collect --corrections) teach generators to recover; a CBLM
    has none, and their disturbed runs would only distort its categories, its transitions
    and the command scale of its success rate.
    """
    nominal = nominal_episodes(dataset)
    if not nominal.all():
        dataset = dataset.subset(np.flatnonzero(nominal))
    tags = dataset.behavior
    if tags is None:
        raise DatasetError(
            "complex demonstrations need a 'behavior' column naming the active component",
            field="behavior",
        )
    return (dataset, *_tag_states(dataset, tags, names))


def _tag_states(dataset: Dataset, tags: Any, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """The component index of every row, from its ``behavior`` tag (DatasetError if none),
    and of the component run beside it: a row tagged ``a+b`` (two at once) is ``a``'s,
    with ``b`` beside it; -1 on other rows."""
    index = {name: i for i, name in enumerate(names)}
    states = np.empty(len(tags), dtype=np.int64)
    partners = np.full(len(tags), -1, dtype=np.int64)
    for row, tag in enumerate(tags):
        first, _, second = str(tag).partition("+")
        for name in (first, second) if second else (first,):
            if name not in index or name == second == first:
                episode = int(np.searchsorted(dataset.offsets, row, side="right") - 1)
                raise DatasetError(
                    f"behavior '{tag}' is not a component or two at once (components: "
                    f"{', '.join(names)})",
                    episode=int(dataset.episode_ids[episode]),
                    row=int(row - dataset.offsets[episode]),
                    field="behavior",
                )
        states[row] = index[first]
        if second:
            partners[row] = index[second]
    return states, partners


def _parallel_partners(
    labels: np.ndarray, states: np.ndarray, partners: np.ndarray, n_observations: int
) -> np.ndarray:
    """Per observation category, the component the demonstrations ran beside the planned
    one there: the most frequent partner where over half the category's rows had one
    (-1 elsewhere, and everywhere without parallel rows)."""
    out = np.full(n_observations, -1, dtype=np.int64)
    paired = partners >= 0
    if not paired.any():
        return out
    totals = np.bincount(labels, minlength=n_observations)
    for k in np.unique(labels[paired]).tolist():
        mine = partners[(labels == k) & paired]
        if 2 * mine.size > totals[k]:
            out[k] = int(np.bincount(mine).argmax())
    return out


def _command_directions(
    commands: np.ndarray,
    scales: Any,
    rest: np.ndarray,
    states: np.ndarray,
    partners: np.ndarray,
    n_components: int,
) -> np.ndarray:
    """Each component's command direction: the first principal direction (unit vector)
    of its commands away from rest, in units of each channel's scale, over the rows it
    ran alone (zeros for a component that never did)."""
    u = (np.asarray(commands, dtype=np.float64) - rest) / np.asarray(scales, dtype=np.float64)
    out = np.zeros((n_components, u.shape[1]))
    for k in range(n_components):
        rows = u[(states == k) & (partners < 0)]
        if rows.size and np.abs(rows).max() > 0:
            direction = np.linalg.svd(rows, full_matrices=False)[2][0]
            out[k] = direction if direction[np.argmax(np.abs(direction))] > 0 else -direction
    return out


def _parallel_from(
    arrays: Mapping[str, np.ndarray], n_components: int, obs: Any, model: Any
) -> tuple[np.ndarray, np.ndarray]:
    """``parallel_`` and ``directions_`` from a model file (none stored: no parallel runs)."""
    n_commands = len(model.command_channels)
    if "parallel" not in arrays and "directions" not in arrays:
        return np.full(obs.n_categories_, -1, dtype=np.int64), np.zeros((n_components, n_commands))
    partners = _modelfile.check_array(arrays, "parallel", ndim=1, kind="iu")
    if (
        partners.shape != (obs.n_categories_,)
        or not ((partners >= -1) & (partners < n_components)).all()
    ):
        raise ModelFileError("parallel must name a component (or -1) per observation category")
    directions = _modelfile.check_array(arrays, "directions", ndim=2)
    if directions.shape != (n_components, n_commands) or np.abs(directions).max() > 1 + 1e-9:
        raise ModelFileError("directions must be unit vectors, one per component")
    return partners.astype(np.int64), np.array(directions, dtype=np.float64)


def _check_component_updates(value: Any, names: Sequence[str]) -> list[dict[str, Any]]:
    """The add_component records of a model file: an SBLM update record plus the name of
    the component it added (one of the model's)."""
    if value is None:
        return []
    if not isinstance(value, list):
        raise ModelFileError("updates must be a list of records")
    out = []
    for entry in value:
        record = dict(_modelfile.check_mapping(entry, "updates"))
        added = _modelfile.check_text(record.pop("component", None), "updates component")
        if added not in names:
            raise ModelFileError(f"updates: {added!r} is not a component")
        out.append({"component": added, **_check_updates([record])[0]})
    return out


def _model_bytes(model: Any) -> bytes:
    """The exact bytes ``model.save`` writes (components are embedded unchanged)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "component.bhmm"
        model.save(path)
        return path.read_bytes()


def _largest_step(commands: np.ndarray, lengths: np.ndarray) -> float:
    """Largest change of either command within one cycle of an episode (rad/s)."""
    steps = np.abs(np.diff(np.asarray(commands, dtype=np.float64), axis=0))
    same_episode = np.ones(len(steps), dtype=bool)
    same_episode[np.cumsum(lengths)[:-1] - 1] = False
    inside = steps[same_episode]
    return float(inside.max()) if inside.size else 0.0


#: Share of the command scale under which a demonstrated command counts as resting,
#: for the pause at a component switch (``handover_cycles_``).
HANDOVER_REST = 0.01


def _handover_cycles(
    commands: np.ndarray, states: np.ndarray, lengths: np.ndarray, scale: float | np.ndarray
) -> int:
    """The demonstrations' typical pause at a component switch (control cycles).

    For each switch, the consecutive cycles on either side of it whose commands (both
    wheels) stay under ``HANDOVER_REST * scale``; the median over all switches (0 when
    the demonstrations never switch). ``scale``: one number, or one per command channel
    for commands in several units (a gripper's arm in deg/s beside wheels in rad/s: each
    channel against its own scale).
    """
    u = np.abs(np.asarray(commands, dtype=np.float64))
    if np.ndim(scale) == 0:
        slow = np.max(u, axis=1) < HANDOVER_REST * float(scale)
    else:
        slow = np.max(u / np.asarray(scale, dtype=np.float64), axis=1) < HANDOVER_REST
    pauses = []
    start = 0
    for length in np.asarray(lengths, dtype=np.int64).tolist():
        end = start + length
        rest, tags = slow[start:end], states[start:end]
        for k in (np.flatnonzero(tags[1:] != tags[:-1]) + 1).tolist():
            before = k - 1
            while before >= 0 and rest[before]:
                before -= 1
            after = k
            while after < length and rest[after]:
                after += 1
            pauses.append(after - before - 1)
        start = end
    return int(np.median(pauses)) if pauses else 0


def _magnitudes(raw: np.ndarray, wraps: Sequence[bool]) -> np.ndarray:
    """``raw`` as float64 with each wrapping channel (an angle) replaced by its magnitude:
    a turn shrinks the bearing from either side."""
    values = np.array(raw, dtype=np.float64)
    for j, wrapping in enumerate(wraps):
        if wrapping:
            values[:, j] = np.abs(values[:, j])
    return values


def _reach(
    states: np.ndarray,
    raw: np.ndarray,
    lengths: np.ndarray,
    n_components: int,
    wraps: Sequence[bool],
) -> np.ndarray:
    """Where each component starts: ``reach[k, j]`` = (min, max) of input ``j`` (of
    ``|x|`` for a wrapping channel, as in :func:`_effects`) over the rows on which the
    demonstrations switch to component ``k`` (an episode's first row included); NaN for a
    component that never runs."""
    values = _magnitudes(raw, wraps)
    starts = np.ones(len(states), dtype=bool)
    starts[1:] = states[1:] != states[:-1]
    starts[np.cumsum(lengths)[:-1]] = True  # every episode's first row
    reach = np.full((n_components, values.shape[1], 2), np.nan)
    for k in range(n_components):
        rows = starts & (states == k)
        if rows.any():
            reach[k, :, 0] = values[rows].min(axis=0)
            reach[k, :, 1] = values[rows].max(axis=0)
    return reach


def _effects(
    states: np.ndarray,
    raw: np.ndarray,
    lengths: np.ndarray,
    n_components: int,
    wraps: Sequence[bool],
) -> np.ndarray:
    """What each component does to each input in the demonstrations.

    ``effects[k, j]`` is the mean per-step change, while component ``k`` is active, of
    input ``j`` — of its magnitude ``|x|`` for a wrapping channel (an angle: a turn
    shrinks the bearing from either side), of the value itself otherwise (an approach
    lowers the distance, a retreat raises it). The complex runtime uses the signs to pick
    which component can still close a gap the plan has left (see
    ``models._complex_policy.ComplexPolicy``).
    """
    values = _magnitudes(raw, wraps)
    steps = np.diff(values, axis=0)
    same_episode = np.ones(len(values) - 1, dtype=bool)
    same_episode[np.cumsum(lengths)[:-1] - 1] = False
    active = states[:-1]
    effects = np.zeros((n_components, len(wraps)))
    for k in range(n_components):
        rows = same_episode & (active == k)
        if rows.any():
            effects[k] = steps[rows].mean(axis=0)
    return effects
