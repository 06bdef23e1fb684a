"""SBLM: the simple-behavior learning model (thesis chapter 4)."""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Mapping, Sequence
from typing import Any, Final, NamedTuple, cast

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from behavior_hmm.cobart import CobART, suggest_dcm_scale
from behavior_hmm.data import (
    COMMAND_CHANNELS,
    DEFAULT_CUTOFF_HZ,
    SENSOR_CHANNELS,
    CommandScaler,
    Dataset,
    SignalPipeline,
)
from behavior_hmm.data._channels import ChannelSpec
from behavior_hmm.errors import ConfigError, ModelFileError, UnreachableGoalError
from behavior_hmm.generators import (
    DEFAULT_GENERATOR_EPOCHS,
    GENERATOR_INITS,
    GENERATOR_NETWORKS,
    ElmanGenerators,
    MotionGenerators,
)
from behavior_hmm.generators._features import (
    DEFAULT_ONSET_CLOCK,
    FeatureLayout,
    command_features,
    grown_ranges,
    input_ranges,
    onset_floors,
    shifted_windows,
    start_ranges,
)
from behavior_hmm.hmm import BehaviorHMM
from behavior_hmm.hmm._counting import Counting
from behavior_hmm.hmm._paths import PathSelfLoops
from behavior_hmm.models import _modelfile
from behavior_hmm.models._base import (
    DEFAULT_PROGRESS_LIMIT,
    LearnedBehavior,
    dataset_hash,
)
from behavior_hmm.models._envelope import merged_envelope, startup_envelope
from behavior_hmm.models._goals import AUTO_INPUTS, check_goal, check_input_names
from behavior_hmm.models._rehearsal import ARRAYS as REHEARSAL_ARRAYS
from behavior_hmm.models._rehearsal import (
    DEFAULT_REHEARSAL,
    RehearsalRows,
    merged,
    rehearsal_rng,
    sample,
)
from behavior_hmm.models._rehearsal import from_arrays as rehearsal_from_arrays
from behavior_hmm.runtime._calibration import (
    CALIBRATION_CHANNELS,
    CALIBRATION_COMMANDS,
    wheel_response,
)

FloatArray = NDArray[np.float64]

#: Goal channels (and nominal goals) of a dataset whose metadata names none (a log
#: imported without a registered behavior): the data contract's two goal channels.
_DEFAULT_GOALS = {"angle": 0.0, "distance": 0.0}
#: Learned arrays a model file carries when the model has them (array name, attribute);
#: a file written before one was learned lacks it.
LEARNED_ARRAYS: Final[tuple[tuple[str, str], ...]] = (
    ("stops", "stops_"),
    ("command_rates", "command_rates_"),
    ("wheel_response", "wheel_response_"),
    ("start_envelope", "start_envelope_"),
    ("onset_floor", "onset_floor_"),
    ("input_range", "input_range_"),
    ("start_range", "start_range_"),
)

#: Most channels a model file's chosen inputs may list (select_inputs' max_inputs is 3).
_MAX_AUTO_INPUTS = 64


class _Rows(NamedTuple):
    """Generator training rows (:meth:`SBLM._generator_rows`): features, targets, and each
    row's primitive, demonstration, run of consecutive rows (a recurrent generator's
    sequence) and how many training rows it stands for (a kept row: more than one)."""

    features: FloatArray
    target: FloatArray
    states: NDArray[np.int64]
    groups: NDArray[Any]
    segments: NDArray[np.int64]
    weights: FloatArray

    @property
    def starts(self) -> NDArray[np.intp]:
        """The first row of each run."""
        return np.r_[0, np.flatnonzero(np.diff(self.segments)) + 1].astype(np.intp)


def margin_rows(
    states: NDArray[np.int64], lengths: Sequence[int] | NDArray[np.integer[Any]], margin: int
) -> tuple[NDArray[np.intp], NDArray[np.int64]]:
    """Training rows of every primitive: its own rows plus ``margin`` rows either side.

    Each run of one primitive inside an episode is widened by up to ``margin`` control
    cycles before and after (clipped to the episode), so a generator also sees how its
    primitive is entered and left. Returns the row indices and the primitive of each.
    """
    rows: list[NDArray[np.intp]] = []
    labels: list[NDArray[np.int64]] = []
    start = 0
    for length in lengths:
        stop = start + int(length)
        s = states[start:stop]
        cuts = np.flatnonzero(np.diff(s)) + 1
        bounds = np.r_[0, cuts, s.size]
        for a, b in itertools.pairwise(bounds):
            lo = max(0, int(a) - margin)
            hi = min(s.size, int(b) + margin)
            rows.append(np.arange(start + lo, start + hi))
            labels.append(np.full(hi - lo, s[a], dtype=np.int64))
        start = stop
    return np.concatenate(rows), np.concatenate(labels)


class SBLM(LearnedBehavior):
    """Simple-behavior learning model: CobART + Behavior-HMM + motion generators.

    Parameters
    ----------
    inputs
        Sensor channels the model reads, e.g. ``("angle",)`` or ``("distance", "angle")``,
        or ``"auto"``: :func:`~behavior_hmm.models.select_inputs` picks them from the
        demonstrations at ``fit`` (thesis 7.2's feature selection; the choice in
        ``inputs_``, its reason in ``provenance_["inputs_selection"]``).
    primitive_params, observation_params
        Overrides of CobART's motion-primitive / observation presets (thesis table 4.2).
    cutoff_hz
        Low-pass cut-off (Hz) applied to the inputs in training and at run time.
    hidden, learning_rate, momentum, epochs, batch_size
        Motion-generator training (lr 0.01, momentum 0.4 as thesis table 6.2). ``epochs``
        400 (``DEFAULT_GENERATOR_EPOCHS``; the thesis preset 200): at 200 most generators
        kept a weight set from their last 20 epochs, and the approach generators underfit
        the short starts (approach {distance, angle} 93.6 → 95.7 % over 8 seeds). ``hidden``
        ``None`` gives the thesis's 5/10/15 units for 1/2/3 channels; the default 5 for
        any number of channels generalizes better off the demonstrated states (approach
        {distance, angle}: 10 units 50 %, 5 units 81 % success on the kinematic robot).
    generator_test_fraction
        Share of each primitive's rows, drawn as whole demonstrations, held out of its
        generator's training to keep the epoch with the lowest error on them (early
        stopping), as the thesis's §6.2 holds out 20 % (default). 0: every demonstration
        trains every generator for all ``epochs`` and the last epoch is kept; a held-out
        demonstration can be the only example of a start (an approach from 0.10–0.20 m
        begins in a primitive that otherwise only ends approaches). Measured over 5
        training seeds (MuJoCo, 64-cycle onset clock): 0 raises the mean success (turn
        95.9 → 97.0 %, turn & approach 89.9 → 90.9 %) but misses more goals (8 against 3
        over the simple rows, turn & approach and position), so it is an option, not the
        default.
    command_history
        Previous commands fed to each generator beside its sensor window (an efference
        copy); 0 (default) gives the thesis's sensor-only networks. With a copy, a
        generator learns ``u[t] ≈ g(u[t-1])`` with gain above 1 on the demonstrations'
        accelerating ramps, so in closed loop small errors grow (wrong-sign starts).
    generator_network
        ``"mlp"`` (default, thesis): each primitive's generator is a feed-forward tanh
        network reading the current feature row. ``"elman"``: a recurrent Elman network
        (thesis §3.4.3, proposed in §7.2) reading the same row, whose context carries
        the rows seen since its primitive took over; trained by backpropagation through
        time on each segment (with its ``segment_margin`` rows) with Adam at
        ``learning_rate``, 8 segments per update (``batch_size`` and ``momentum`` are
        the feed-forward networks'), and run from an empty context that first replays
        the last ``segment_margin`` rows whenever its primitive takes over
        (:class:`~behavior_hmm.generators.ElmanGenerators`).
    generator_init
        Where the feed-forward generators start: ``"random"`` (default, thesis) or
        ``"shared"``, the weights of one network first trained on every primitive's
        rows (for as many updates as the largest primitive's network makes), which each
        primitive's network then fine-tunes on its own
        (:class:`~behavior_hmm.generators.MotionGenerators` ``init``). It helps where
        the demonstrations are few: over 15 kinematic seeds, turn from a quarter of its
        grid scores 95.8 % against 93.7 % (docs/results.md, "Data efficiency").
    generator_output
        ``"command"``: each network outputs the normalized wheel commands (thesis);
        ``"delta"``: it outputs the change of the commands since the last cycle, in
        units of the largest change seen in training (needs ``command_history >= 1``;
        the previous command and its last change are fed as inputs).
    state_decoding
        ``"plan"``: the active primitive is the first state of the Viterbi decoding of
        the planned path (thesis Algorithm 1, prior π); ``"history"``: the prior is the
        forward Viterbi message of the observations seen so far in this run.
    primitive_recognition
        If true (default), the primitive run each cycle is the one the primitive CobART
        recognizes in the live 10-reading window, among those the plan allows (finite
        decoding score: able to emit the current observation on a path to the goal);
        its generator then sees the kind of window it was trained on. ``False``: the
        best-scoring state of the decoding (thesis).
    onset_clock
        If > 0, each generator also reads the time since the behavior started,
        ``min(t, onset_clock) / onset_clock`` (t in control cycles). At rest the window
        is flat, so without it a network cannot tell how far its start-up ramp has
        gone (the stall / wrong-sign start of DESIGN §8). The default, 96 cycles (~1.5 s),
        covers the demonstrations' start-up ramps (90 % of their peak command after up to
        73 cycles on turn, 95 on approach). 0 disables it.
    window_noise
        If > 0, the generators also train on a copy of every row whose windows are
        shifted by a Gaussian offset per channel with this standard deviation
        (normalized units; input-noise regularization, so a generator reacts smoothly
        to windows slightly off the demonstrations).
    stop_at_rest
        If true (default), the stop rule also waits until the robot is at rest (yaw rate
        within 5 deg/s, forward speed within 0.01 m/s), as the demonstrations end: the
        last small settling commands are generated too, and a component of a complex
        behavior hands over where its demonstrations did (turn & approach 83.8 -> 86.4 %).
        A run that has not moved yet ends at its goal only once 8 readings in a row
        confirm it (``START_CONFIRM_CYCLES``), so one noisy first reading inside the
        tolerance does not end it (turn from 7 deg under sensor noise 0.01). On noisy
        readings a goal found at rest is confirmed on the mean of the raw readings while
        the robot holds still (``models._confirm.GoalConfirmation``: turn & approach under
        noise 0.02, 12 -> 15 of 15 goals); a complex behavior whose components stop at
        rest confirms its own goal so, not theirs. Noise-free readings change nothing.
    segment_margin
        Each generator is trained on its primitive's rows plus up to this many rows
        before and after each of its segments, so it has seen how its primitive is
        entered and left and switches are smooth.
    dcm_floor
        The automatic CobART DCM scale of each channel is raised to at least this
        fraction of the largest channel's scale (for both networks, when their params
        do not set ``dcm_scale``). A channel that barely moves in the demonstrations
        (the angle while approaching: 3e-5 per step) otherwise gets a DCM so sensitive
        that noise splits the categories.
    command_rate_limit
        If > 0, the command may change per control cycle by at most this multiple of
        the largest change per cycle in the demonstrations (``delta_scale_``), and at
        the goal it ramps to zero at that rate before the run ends (a soft stop). The
        teacher is jerk-limited; without it the robot jolts at every primitive switch
        (turn: 6.7× the teacher's largest change; approach 24×). 0 disables it (thesis).
    progress_limit
        A run that at its step limit (``max_steps_``) still closes in on its goal goes
        on, up to this many times ``max_steps_`` cycles in all, as long as every quarter
        of ``max_steps_`` lowers its goal error by 10 % (``runtime.Progress``): a robot
        slower than its demonstrations (a lower speed limit, a lagging motor) is not
        stopped short while it is getting there (thesis: 1, a fixed limit).
    goal_fallback
        If true (default), a run whose goal no candidate goal category is reachable from
        where it starts plans to the nearest reachable category within 12 cm / 36 deg of
        the goal and nearer to it than the start (``goal_fallbacks``: never away from
        the goal), and stops at the goal by its tolerance on the way
        (a retreat learned with mirror images could not plan to goals between its coarse
        categories: 10 of 86 start-goal pairs). ``False`` (thesis): the goal is
        unreachable.
    wheel_calibration
        If true, each run estimates each wheel's gain from the robot's measured body
        speed and yaw rate and divides the commands by them
        (:class:`~behavior_hmm.runtime.WheelCalibration`; the wheels' difference only):
        a robot whose wheels answer differently from the demonstrated one's (a motor
        gain mismatch) drives as the behavior asks; a difference within the readings'
        noise is left alone. Needs demonstrations with left/right wheel commands and
        measured ``linear_velocity`` and ``angular_velocity`` (``wheel_response_``;
        without them it is off, silently: an arm, a pen), and a robot that measures
        those and declares its wheel geometry (elsewhere it is off, with a warning).
        Thesis: off (docs/reliability.md).
    recover
        If true, a run whose filtered readings leave the demonstrations (farther from
        every observation category's prototype than twice ``reach_radius_``, the
        farthest any demonstrated reading was) is steered back toward the nearest
        prototype, with the command ``command_rates_`` says moves the readings that
        way, until it is within half ``reach_radius_``; then the generators drive as
        before. Without it a start far from every demonstration is left to a generator
        extrapolating (LASA Zshape: 25 % of a 16 x 16 grid of starts reach the goal, 47
        % with it). ``False`` (thesis, and the default): the generators alone.
    mirror
        If true, learn from every demonstration and its left–right mirror image
        (:func:`behavior_hmm.data.mirrored`: bearing and yaw rate negated, the wheels'
        commands traded; every channel must declare its ``mirror``), as if each had
        been shown from the other side too. For a robot whose sides are alike, with few
        demonstrations (turn from a quarter of its grid: 85.3 → 92.6 %, docs/results.md,
        "Mirror images of the demonstrations"). ``False`` (thesis, and the default): the
        demonstrations as given.
    start_envelope
        If true, a run that starts from rest moves each command away from rest no faster
        than the demonstrations did: at the generators' onset clock cycle ``t`` the
        command is clipped to ``rest ± start_envelope_[t]`` (the largest distance from
        rest any demonstration had reached by its cycle ``t``; module
        ``models._envelope``), until the envelope reaches its top. The teacher's
        start-up is an s-curve; a generator decoded at rest between demonstrated starts,
        one of mid-motion never shown a start, otherwise reaches cruising speed at the
        rate limit (turn from a quarter of its grid, kinematic, 5 seeds: 85.3 → 93.8 %;
        docs/results.md, "Data efficiency"). Only the cycles whose primitive's network
        was never trained on so early a clock (``onset_floor_``) are bounded, a command
        beyond the envelope brought back at the rate limit: a network shown the
        demonstrations' starts runs its own start-up (bounding it too slowed a
        short turn the network ends too slowly, and the approach after it: turn &
        approach 95.8 → 94.7 % on MuJoCo, data seed 4). A run that starts while the robot
        moves (a component carried on by a complex behavior) or a resumed clock is not
        bounded. ``True`` (the default); ``False`` (thesis): the generators alone.
    onset_floor
        If true (needs ``onset_clock`` > 0), each primitive's network reads the onset
        clock no earlier than the earliest its own training rows held
        (``onset_floor_``): a primitive met only mid-motion, decoded at a start from
        rest between the demonstrated starts, reads the clock it was trained on instead
        of one near 0 it never saw, and does not extrapolate (the approach from a
        quarter of its grid, decoded mid-approach at rest, first turned the robot 8°
        and handed turn & approach back to its turn 13 times). ``True`` (the default;
        without a clock it does nothing); ``False`` (thesis): the clock as it runs.
    input_range
        If true, a run that starts beyond the demonstrations has each input's windows
        clipped to the range its primitive's training rows held (``input_range_``) until
        that input's readings have been inside the range of all the rows: an approach
        from 0.96 m learned from starts up to 0.8 m reads as the farthest its primitive
        was shown, instead of a value its network extrapolates from (a heading-correction
        primitive decoded there turned the robot to 88° off the object). Once inside, a
        deviation the rows never held (a bearing drifting off) stays visible to the
        network. In the first ``onset_clock`` cycles of a run from rest (not one carried
        on at speed by a complex behavior, nor a resumed onset clock), an input whose
        first reading lies more than its channel's goal tolerance outside what any
        primitive's rows held by that onset clock (``start_range_``: a start closer to
        the goal than every demonstrated start) has its windows clipped to what the
        running primitive's rows held by then, until its reading comes within the
        tolerance of what they held: the approach from 4 cm, whose nearest demonstrated
        start began 0.1 m off, reads as that start instead of backing the robot away
        first. ``True`` (the default); ``False`` (thesis): the readings as
        they are.
    rehearsal
        Most training rows of each primitive's generator the model keeps
        (``rehearsal_``, drawn at random; the window-noise copies are not kept) so that
        :meth:`partial_fit` fine-tunes a network on them beside the new rows; a network
        fine-tuned on new rows alone forgets the old ones (a turn fitted on half of its
        grid and grown by the other half: 96.7 → 85.5 % on the first half's starts; 98.2 %
        with the default 512 rows, docs/results.md, "An SBLM grown by new demonstrations of
        its own behavior"). The rows are stored as float32, deflated (the default turn
        model keeps 9,623 rows, 222 → 311 KB; approach 4,096, 72 → 234 KB). 0 keeps none
        (thesis; it has no updates), and set after a fit drops the rows; a value below the
        rows a fitted model keeps of a primitive is refused by :meth:`partial_fit` and
        ``save``. Fitting is unchanged by it.
    goal_braking
        If true (default; needs ``command_rate_limit`` > 0), when a ramp to rest at the
        rate limit started any later would overshoot the goal (predicted from
        ``command_rates_``), the command ramps to zero: a generator that arrives too
        fast comes to rest at its goal instead of being stopped at speed (approach's
        largest change per cycle 27.5× the teacher's without it, 1.6× with it).
        ``False``: the thesis's stop.
    learn_corrections
        If true (default), the generators also learn from the dataset's corrective
        demonstrations (``collect --corrections``; the approach's default grid has one per
        start), provided the inputs include every channel their disturbance moves (the
        metadata's ``corrections.disturbs``: the bearing). A model that cannot see the
        disturbance cannot tell a correction from noise (approach on {distance}: 88.1 %,
        13/15 with them, 97.6 % without) and, like ``False`` (the thesis, which had
        none), learns from the nominal demonstrations only.
    counting, smoothing, path_self_loops
        Behavior-HMM estimation options (see :class:`~behavior_hmm.hmm.BehaviorHMM`).
    random_state
        Seed of every random choice (generator initialisation and splits).

    Attributes
    ----------
    pipeline_ : SignalPipeline
    primitives_ : CobART
        Motion-primitive network (compacted to the categories that win on the data).
    observations_ : CobART
        Observation-category network (compacted likewise).
    hmm_ : BehaviorHMM
    generators_ : MotionGenerators or ElmanGenerators
    command_scale_ : float
        Largest absolute wheel command (rad/s) in the (nominal) training demonstrations.
    reach_radius_ : float
        The farthest any nominal demonstrated reading lies from its nearest observation
        category's prototype (the newest reading of its window), in normalized units:
        where the demonstrations end, for ``recover``.
    command_rates_ : ndarray of shape (n_commands, n_inputs)
        Change of each filtered input per control cycle (its unit) per unit of each
        command (rad/s of the left and the right wheel), fitted on the demonstrations
        (goal braking).
    onset_floor_ : ndarray of shape (n_primitives,) or None
        The earliest onset clock (normalized, ``min(t, onset_clock) / onset_clock``)
        among each primitive's generator training rows (0 for one without rows), the
        floor ``onset_floor`` holds its network's clock to; None without a clock, or in
        a model file written before it was learned.
    input_range_ : ndarray of shape (n_primitives, 2, n_inputs * window) or None
        Per primitive, the lowest (``[:, 0]``) and highest (``[:, 1]``) normalized value
        of each sensor-window input among its generator training rows (a primitive
        without rows: all rows'), the range ``input_range`` clips its network's windows
        to; None in a model file written before it was learned.
    start_range_ : ndarray of shape (n_primitives, n_inputs, onset_clock + 1, 2) or None
        Per primitive, input and onset clock cycle ``k``, the lowest (``0``) and highest
        (``1``) normalized reading in that input's windows among the primitive's
        generator training rows whose clock had counted at most ``k`` cycles (NaN where
        it has none; ``generators._features.start_ranges``), what ``input_range`` clips
        a start-up's windows to; None without a clock, or in a model file written before
        it was learned.
    rehearsal_ : RehearsalRows or None
        The rows kept for updates (``rehearsal``): features, targets, primitive,
        demonstration and run of each, and how many rows each primitive was trained on
        in all (module ``models._rehearsal``). None with ``rehearsal=0``, or in a model
        file written before rows were kept (its updates fine-tune on the new rows alone).
    start_envelope_ : ndarray of shape (T, n_commands)
        The demonstrations' start-up envelope (``start_envelope``): row ``t`` is the
        largest ``|command - rest|`` of each command channel any demonstration reached
        within its first ``t + 1`` cycles, up to the cycle where every channel has
        reached its largest. None in a model file written before it was learned.
    wheel_response_ : ndarray of shape (2, 3) or None
        How the demonstrated robot's wheels answered their commands
        (:func:`behavior_hmm.runtime.wheel_response` sums over the demonstrations), the
        reference ``wheel_calibration`` restores; None where the demonstrations have no
        left/right wheel commands or no measured ``linear_velocity`` and
        ``angular_velocity``.
    command_specs_ : tuple of ChannelSpec
        The command channels the generators output, in action order (the dataset's).
    command_scales_ : ndarray of shape (n_commands,)
        Each command's normalization scale (channels of one unit share one).
    rest_values_ : dict
        Median final reading of each input channel over the demonstrations.
    default_goal_ : dict
        Goal used when none is given: where the demonstrations end.
    stops_ : ndarray of shape (n_episodes, n_inputs)
        Final reading of every demonstration (physical units): where the behavior was
        shown to stop (see :meth:`check_stoppable`).
    max_steps_ : int
        Step limit of a generation (twice the longest demonstration, at least 500).
    updates_ : list of dict
        One record per :meth:`partial_fit` since the last :meth:`fit` (saved with the
        model): the new data's ``dataset_sha256``, ``episodes``, ``rows``, ``env``,
        ``package_version``, ``new_primitives``, ``new_observations``, the
        ``fine_tuned`` generators, the ``rehearsed`` rows they also trained on and the
        ``source`` file, if given.
    """

    kind = "SBLM"

    def __init__(
        self,
        inputs: Sequence[str] = ("angle",),
        *,
        primitive_params: Mapping[str, Any] | None = None,
        observation_params: Mapping[str, Any] | None = None,
        cutoff_hz: float | None = DEFAULT_CUTOFF_HZ,
        hidden: int | tuple[int, ...] | None = 5,
        learning_rate: float = 0.01,
        momentum: float = 0.4,
        epochs: int = DEFAULT_GENERATOR_EPOCHS,
        batch_size: int = 32,
        generator_test_fraction: float = 0.2,
        command_history: int = 0,
        generator_network: str = "mlp",
        generator_init: str = "random",
        generator_output: str = "command",
        state_decoding: str = "history",
        primitive_recognition: bool = True,
        onset_clock: int = DEFAULT_ONSET_CLOCK,
        window_noise: float = 0.003,
        segment_margin: int = 10,
        stop_at_rest: bool = True,
        dcm_floor: float = 0.3,
        command_rate_limit: float = 1.5,
        goal_braking: bool = True,
        learn_corrections: bool = True,
        progress_limit: float = DEFAULT_PROGRESS_LIMIT,
        goal_fallback: bool = True,
        wheel_calibration: bool = True,
        recover: bool = False,
        mirror: bool = False,
        start_envelope: bool = True,
        onset_floor: bool = True,
        input_range: bool = True,
        rehearsal: int = DEFAULT_REHEARSAL,
        counting: str = "changes",
        smoothing: float = 0.0,
        path_self_loops: str = "drop",
        random_state: int = 0,
    ) -> None:
        self.inputs = inputs
        self.primitive_params = primitive_params
        self.observation_params = observation_params
        self.cutoff_hz = cutoff_hz
        self.hidden = hidden
        self.learning_rate = learning_rate
        self.momentum = momentum
        self.epochs = epochs
        self.batch_size = batch_size
        self.generator_test_fraction = generator_test_fraction
        self.command_history = command_history
        self.generator_network = generator_network
        self.generator_init = generator_init
        self.generator_output = generator_output
        self.state_decoding = state_decoding
        self.primitive_recognition = primitive_recognition
        self.onset_clock = onset_clock
        self.window_noise = window_noise
        self.segment_margin = segment_margin
        self.stop_at_rest = stop_at_rest
        self.dcm_floor = dcm_floor
        self.command_rate_limit = command_rate_limit
        self.goal_braking = goal_braking
        self.learn_corrections = learn_corrections
        self.progress_limit = progress_limit
        self.goal_fallback = goal_fallback
        self.wheel_calibration = wheel_calibration
        self.recover = recover
        self.mirror = mirror
        self.start_envelope = start_envelope
        self.onset_floor = onset_floor
        self.input_range = input_range
        self.rehearsal = rehearsal
        self.counting = counting
        self.smoothing = smoothing
        self.path_self_loops = path_self_loops
        self.random_state = random_state

    # ------------------------------------------------------------------ params
    def check_params(self) -> None:
        """Refuse parameters out of range (ConfigError) before any data is read."""
        super().check_params()
        self._checked_inputs()
        flags = ("primitive_recognition", "stop_at_rest", "goal_braking", "learn_corrections")
        options = ("recover", "goal_fallback", "start_envelope", "onset_floor", "input_range")
        for name in (*flags, *options):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{name} must be true or false, got {getattr(self, name)!r}")
        size = self.batch_size
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            raise ConfigError(f"batch_size must be an integer >= 1, got {size!r}")
        held = self.generator_test_fraction
        if isinstance(held, bool) or not isinstance(held, int | float) or not 0 <= held < 1:
            raise ConfigError(f"generator_test_fraction must lie in [0, 1), got {held!r}")

    @property
    def auto_inputs(self) -> bool:
        """Whether ``fit`` chooses the inputs (``inputs="auto"``)."""
        return isinstance(self.inputs, str) and self.inputs == AUTO_INPUTS

    def _checked_inputs(self, available: Sequence[str] | None = None) -> tuple[str, ...]:
        """The inputs, each one of ``available`` (a dataset's channels; default: all known);
        ``()`` for ``inputs="auto"`` (chosen at ``fit``)."""
        inputs = (self.inputs,) if isinstance(self.inputs, str) else tuple(self.inputs)
        if self.auto_inputs:
            inputs = ()
        elif not inputs:
            raise ConfigError("inputs must name at least one sensor channel (or 'auto')")
        else:
            check_input_names(inputs, available)
        if len(set(inputs)) != len(inputs):
            raise ConfigError(f"inputs repeat a channel: {inputs}")
        if self.generator_network not in GENERATOR_NETWORKS:
            raise ConfigError(
                f"generator_network must be one of {', '.join(GENERATOR_NETWORKS)}, "
                f"got {self.generator_network!r}"
            )
        if self.generator_init not in GENERATOR_INITS:
            raise ConfigError(
                f"generator_init must be one of {', '.join(GENERATOR_INITS)}, "
                f"got {self.generator_init!r}"
            )
        if self.generator_network == "elman" and self.generator_init != "random":
            raise ConfigError("generator_init='shared' is for the feed-forward generators")
        if self.generator_network == "elman" and not isinstance(self.hidden, int):
            raise ConfigError(
                f"generator_network='elman' has one hidden layer: hidden must be an "
                f"integer, got {self.hidden!r}"
            )
        if self.generator_output not in ("command", "delta"):
            raise ConfigError(
                f"generator_output must be 'command' or 'delta', got {self.generator_output!r}"
            )
        if self.state_decoding not in ("plan", "history"):
            raise ConfigError(
                f"state_decoding must be 'plan' or 'history', got {self.state_decoding!r}"
            )
        for name in ("onset_clock", "segment_margin", "rehearsal"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ConfigError(f"{name} must be an integer >= 0, got {value!r}")
        for name in ("window_noise", "dcm_floor"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not value >= 0:
                raise ConfigError(f"{name} must be a number >= 0, got {value!r}")
        if self.dcm_floor > 1:
            raise ConfigError(f"dcm_floor must lie in [0, 1], got {self.dcm_floor!r}")
        if self.generator_output == "delta" and self.command_history < 1:
            raise ConfigError("generator_output='delta' needs command_history >= 1")
        if not isinstance(self.command_history, int) or self.command_history < 0:
            raise ConfigError(
                f"command_history must be an integer >= 0, got {self.command_history}"
            )
        return inputs

    # --------------------------------------------------------------------- fit
    #: ``behavior_`` of demonstrations that do not name theirs
    _unnamed = "behavior"

    def _fit_setup(self, dataset: Any) -> tuple[tuple[str, ...], Any]:
        """Fit step 1: the parameters, and the inputs among the dataset's channels."""
        self.check_params()
        inputs = self._checked_inputs(getattr(dataset, "sensor_channels", SENSOR_CHANNELS))
        if inputs or not isinstance(dataset, Dataset):
            return inputs, None
        from behavior_hmm.models._inputs import select_inputs

        params = self.get_params()
        seed = params.pop("random_state")
        del params["inputs"]
        choice = select_inputs(dataset, random_state=seed, **params)
        return choice.inputs, choice

    def _fit_rows(self, dataset: Dataset, inputs: tuple[str, ...], context: Any) -> tuple[Any, Any]:
        """Fit step 2: the nominal demonstrations, and the corrective ones it learns from."""
        dataset = (
            without_unseen_corrections(dataset, inputs)
            if self.learn_corrections
            else dataset.subset(np.flatnonzero(nominal_episodes(dataset)))
        )
        return dataset, context

    def _fit_learn(
        self,
        dataset: Dataset,
        x: np.ndarray,
        inputs: tuple[str, ...],
        pipeline: SignalPipeline,
        context: Any,
    ) -> None:
        """Fit step 4: primitives, observations, the Behavior-HMM and the generators."""
        lengths = dataset.lengths
        # Corrective demonstrations (collect --corrections) teach the generators how to
        # recover; the categories, the Behavior-HMM and the command scales come from the
        # nominal demonstrations alone, so the plan and the success rate's normalization
        # are those of the behavior as demonstrated.
        nominal = nominal_rows(dataset)
        x_nom = x[nominal]
        lengths_nom = lengths[nominal_episodes(dataset)]
        prim_params = self._cobart_overrides(self.primitive_params, x_nom, lengths_nom)
        obs_params = self._cobart_overrides(self.observation_params, x_nom, lengths_nom)
        prim = CobART.motion_primitives(**prim_params).fit(x_nom, lengths_nom)
        prim = prim.compacted(x_nom, lengths_nom)
        obs = CobART.observations(**obs_params).fit(x_nom, lengths_nom)
        obs = obs.compacted(x_nom, lengths_nom)
        self.reach_radius_ = reach_radius(x_nom, obs)
        nominal_states = prim.labels_
        observations = obs.labels_
        # every row's primitive: the nominal rows' own, the corrective rows' best match
        states = nominal_states if nominal.all() else prim.predict(x, lengths)
        self.inputs_ = inputs
        self.primitives_ = prim
        hmm = BehaviorHMM(
            n_states=prim.n_categories_,
            n_observations=obs.n_categories_,
            counting=cast(Counting, self.counting),
            smoothing=self.smoothing,
            path_self_loops=cast(PathSelfLoops, self.path_self_loops),
        ).fit(nominal_states, observations, lengths_nom)
        units = [spec.unit for spec in dataset.command_specs]
        scaler = CommandScaler(units).fit(dataset.commands[nominal])
        self._learn_commands(dataset, scaler.scales_)
        y = np.clip(scaler.transform(dataset.commands), -1.0, 1.0)
        prev = command_features(y, lengths, 1)
        step = y - prev
        delta_scale = float(np.max(np.abs(step[nominal]))) or 1.0
        layout = self.feature_layout(len(inputs), int(prim.window), delta_scale)
        features = layout.offline(x, y, lengths)
        target = y if self.generator_output == "command" else np.clip(step / delta_scale, -1, 1)
        rows, originals = self._generator_rows(
            features, target, states, lengths, dataset.episode_ids
        )
        features, target, gen_states, groups, _, _ = rows
        starts = rows.starts
        # the clock is a row's last feature (FeatureLayout)
        self.onset_floor_: np.ndarray | None = (
            onset_floors(features[:, -1], gen_states, prim.n_categories_)
            if self.onset_clock > 0
            else None
        )
        # the sensor windows are a row's first n_inputs * window features (FeatureLayout)
        self.input_range_: np.ndarray | None = input_ranges(
            features[:, : len(inputs) * int(prim.window)], gen_states, prim.n_categories_
        )
        self.start_range_: np.ndarray | None = self._start_ranges(
            features, gen_states, prim.n_categories_, layout
        )
        common: dict[str, Any] = {
            "window": int(prim.window),
            "learning_rate": self.learning_rate,
            "epochs": self.epochs,
            "test_fraction": float(self.generator_test_fraction),
            "early_stopping": self.generator_test_fraction > 0,
            "random_state": self.random_state,
        }
        gens: MotionGenerators | ElmanGenerators
        if self.generator_network == "elman":
            hidden = cast(int, self._hidden(len(inputs)))
            gens = ElmanGenerators(hidden=hidden, warmup=int(self.segment_margin), **common)
        else:
            gens = MotionGenerators(
                hidden=self._hidden(len(inputs)),
                momentum=self.momentum,
                batch_size=self.batch_size,
                init=self.generator_init,
                **common,
            )
        gens.fit(
            features,
            target,
            gen_states,
            n_primitives=prim.n_categories_,
            groups=groups,
            **_sequences(gens, starts),
        )
        self.rehearsal_ = self._kept_rows(originals, prim.n_categories_, None, 0, 0)
        self.observations_ = obs
        self.hmm_ = hmm
        self.generators_ = gens
        self.command_scale_ = float(scaler.scale_)
        self.delta_scale_ = delta_scale
        self.train_states_ = nominal_states
        self.train_observations_ = observations

    def _fit_finish(
        self,
        dataset: Dataset,
        x: np.ndarray,
        inputs: tuple[str, ...],
        raw: np.ndarray,
        finals: np.ndarray,
        context: Any,
    ) -> None:
        """Fit step 6: the robot's response to a command, where demonstrations stop, the
        default goal and the step limit."""
        self.command_rates_ = command_rates(
            x,
            dataset.commands,
            dataset.lengths,
            self.pipeline_,
            [self.channel_spec(c) for c in inputs],
            wheels=self.command_channels == COMMAND_CHANNELS,
        )
        self.wheel_response_ = demonstrated_wheel_response(dataset)
        rest = self.rest_command
        self.start_envelope_: np.ndarray | None = startup_envelope(
            dataset.commands, dataset.lengths, rest
        )
        self.stops_ = np.array(raw[finals], dtype=np.float64)
        self.default_goal_ = self._default_goal(inputs, dataset.metadata.get("goal"))
        self.max_steps_ = int(max(500, 2 * int(dataset.lengths.max())))
        if context is not None:  # inputs="auto": say what select_inputs chose and why
            self.provenance_["inputs_selection"] = f"{context.summary()}: {context.reason}"

    # ------------------------------------------------------------- partial_fit
    def partial_fit(
        self, dataset: Dataset, *, source: str | os.PathLike[str] | None = None
    ) -> SBLM:
        """Grow the fitted model with new demonstrations of the same behavior.

        The model continues from what it learned; nothing is refitted from scratch, and
        the demonstrations it was fitted on are not needed (the model file keeps none).
        Corrective demonstrations are handled as :meth:`fit` handles them.

        What stays, bit for bit:

        * ``pipeline_``: the filter and the normalization ranges. The new readings go
          through the fitted pipeline's ``transform``, as in training and at run time
          (no clipping: a reading outside a range maps beyond [-1, 1] linearly).
        * ``command_scale_``, ``command_scales_``, ``delta_scale_``: the generators'
          output units (a new command beyond the fitted scale is clipped to ±1, as
          :meth:`fit` clips the corrective demonstrations' commands), and
          ``command_rates_``, the robot's response to a command (a property of the robot,
          not of the demonstrations; it is not re-estimated, since the least squares
          of :func:`command_rates` cannot be updated without the old rows).
        * Every existing category index of both CobARTs, and every motion generator
          whose primitive gets no row of the new demonstrations (margins included).

        What moves:

        * ``primitives_`` and ``observations_`` learn on the new nominal demonstrations
          with :meth:`CobART.partial_fit`: a window that resonates with an existing
          category (score >= ρ) moves that prototype by ``d · n^α · (p - z)``, ``n`` its
          win count including this win (presets d 0.2, α -1: at most ``0.2 / (n + 1)`` of
          the way, for a prototype that already won ``n`` times), and raises its count
          by one; prototypes no new window resonates with stay bit for bit, and so do
          ``dcm_scale_``. A window that resonates with none starts a new category at the
          end. As in :meth:`fit` the new demonstrations are then relabelled with the
          final prototypes; new categories that win nowhere are dropped, old ones are
          never dropped nor renumbered (``kept_`` indexes the grown network). The old
          demonstrations keep the labels they were counted with.
        * ``hmm_``: the new labels are counted in with :meth:`BehaviorHMM.partial_fit`
          (tables grown by the new primitives and categories): the counts equal those of
          ``BehaviorHMM.fit`` on the old labels followed by the new.
        * ``generators_``: a new primitive gets a new network trained on its rows as in
          :meth:`fit`; an existing primitive with new rows is fine-tuned from its
          current weights (``MotionGenerators.partial_fit``) on its new rows and the
          rows ``rehearsal_`` kept of it (at most ``rehearsal``; in a model without
          them, on its new rows only).
        * ``rehearsal_``: the rows kept of a primitive with new rows are drawn again from
          its kept rows and its new ones, each kept row standing for as many as the
          primitive's rows seen so far over the rows kept; the rows of every other
          primitive stay bit for bit.
        * ``wheel_response_``: the new demonstrations' sums are added (a sum over all
          the demonstrations, exactly as :meth:`fit` on all of them gives it).
        * ``start_envelope_``: the larger of the fitted envelope and the new
          demonstrations' at every cycle (exactly what :meth:`fit` on all of them gives).
        * ``stops_`` gains the new demonstrations' final readings; ``rest_values_`` (their
          median), ``default_goal_`` (from ``rest_values_`` and the new dataset's goal
          channels) and ``max_steps_`` (twice the longest demonstration, at least 500)
          are then what :meth:`fit` on all the demonstrations gives.
        * ``provenance_`` stays that of the fit; ``updates_`` gets one record per update
          (the new data's hash, episodes, rows, env, package version, the new primitives
          and categories, the fine-tuned generators, the kept rows they rehearsed and
          ``source``), saved in the file.

        Parameters
        ----------
        dataset
            New demonstrations of the model's behavior: the same input channels (same
            declarations), command channels, control period and normalization ranges.
        source
            The file the demonstrations came from, recorded in the update's record.

        Returns
        -------
        SBLM
            ``self``. Nothing is changed when an error is raised.

        Raises
        ------
        NotFittedError
            The model is not fitted.
        ConfigError
            Demonstrations of another behavior, robot, channels or rates, or parameters
            changed since the fit in a way the fitted parts cannot follow.
        """
        self._check_fitted()
        self.check_params()
        if not isinstance(dataset, Dataset):
            raise ConfigError(
                f"partial_fit expects a behavior_hmm.data.Dataset, got {type(dataset)}"
            )
        inputs = self._checked_inputs(getattr(dataset, "sensor_channels", SENSOR_CHANNELS))
        inputs = inputs or self.inputs_  # inputs="auto": the channels chosen at the fit
        self._check_update(dataset, inputs)
        stored = self._stored_rows()  # refused here, before any work, if lowered
        dataset = self._as_learned(dataset)
        dataset = (
            without_unseen_corrections(dataset, inputs)
            if self.learn_corrections
            else dataset.subset(np.flatnonzero(nominal_episodes(dataset)))
        )
        x = self.pipeline_.transform(dataset)
        lengths = dataset.lengths
        nominal = nominal_rows(dataset)
        x_nom = x[nominal]
        lengths_nom = lengths[nominal_episodes(dataset)]
        prim = continued_cobart(self.primitives_, x_nom, lengths_nom)
        obs = continued_cobart(self.observations_, x_nom, lengths_nom)
        nominal_states = prim.labels_
        observations = obs.labels_
        states = nominal_states if nominal.all() else prim.predict(x, lengths)
        hmm = BehaviorHMM.from_arrays(self.hmm_.to_arrays(), self.hmm_.params)
        hmm.set_params(n_states=prim.n_categories_, n_observations=obs.n_categories_)
        hmm.partial_fit(nominal_states, observations, lengths_nom)
        # the generators' units stay those of the fit
        y = np.clip(np.asarray(dataset.commands, dtype=np.float64) / self.command_scales_, -1, 1)
        step = y - command_features(y, lengths, 1)
        layout = self.feature_layout(len(inputs), int(prim.window), self.delta_scale_)
        features = layout.offline(x, y, lengths)
        if self.generator_output == "command":
            target = y
        else:
            target = np.clip(step / self.delta_scale_, -1, 1)
        # the rows kept of every primitive the new demonstrations visit join its training
        visited = np.unique(np.asarray(states, dtype=np.int64))
        kept = None if stored is None else stored.of(visited)
        rows, originals = self._generator_rows(
            features, target, states, lengths, dataset.episode_ids, kept=kept
        )
        features, target, gen_states, groups, _, _ = rows
        starts = rows.starts
        floors = self._grown_floors(features, gen_states, prim.n_categories_)
        # a model file written before input_range_ was learned stays without it: the old
        # primitives' rows are not kept, so their ranges cannot be known
        old_ranges = getattr(self, "input_range_", None)
        ranges = None
        if old_ranges is not None:
            fresh = input_ranges(
                features[:, : len(inputs) * int(prim.window)], gen_states, prim.n_categories_
            )
            ranges = grown_ranges(old_ranges, fresh, gen_states)
        # the same for the start-ups' ranges (none in a file written before them)
        old_starts = getattr(self, "start_range_", None)
        starts_grown = None
        if old_starts is not None:
            fresh_starts = self._start_ranges(features, gen_states, prim.n_categories_, layout)
            if fresh_starts is not None:
                starts_grown = grown_ranges(old_starts, fresh_starts, gen_states, side=-1)
        old = self.generators_
        gens = type(old).from_arrays(old.to_arrays(), **old.get_params())
        updates = list(getattr(self, "updates_", []))
        gens.partial_fit(
            features,
            target,
            gen_states,
            n_primitives=prim.n_categories_,
            groups=groups,
            update=len(updates) + 1,
            **_sequences(gens, starts),
        )
        finals = dataset.offsets[1:] - 1
        raw = dataset.columns(inputs)
        stops = np.vstack([self.stops_, raw[finals]])
        reach = reach_radius(x_nom, obs)
        wheels = added_wheel_response(
            getattr(self, "wheel_response_", None), demonstrated_wheel_response(dataset)
        )
        envelope = startup_envelope(dataset.commands, lengths, self.rest_command)
        old_envelope = getattr(self, "start_envelope_", None)
        if old_envelope is not None:
            envelope = merged_envelope(old_envelope, envelope)
        rehearsal = None
        if stored is not None and kept is not None:
            update = len(updates) + 1
            drawn = self._kept_rows(originals, prim.n_categories_, stored, kept.n_rows, update)
            rehearsal = None if drawn is None else merged(stored.without(visited), drawn)
        retrained = [
            int(p) for p in np.unique(gen_states) if p < old.n_primitives_ and old.trained_[p]
        ]
        record: dict[str, Any] = {
            "dataset_sha256": dataset_hash(dataset),
            "episodes": len(dataset),
            "rows": int(dataset.n_samples),
            "env": str(
                dataset.metadata.get("env") or dataset.metadata.get("simulator") or "unknown"
            ),
            "package_version": _package_version(),
            "new_primitives": prim.n_categories_ - self.primitives_.n_categories_,
            "new_observations": obs.n_categories_ - self.observations_.n_categories_,
            "fine_tuned": retrained,
            "rehearsed": 0 if kept is None else kept.n_rows,
        }
        if source is not None:
            record["source"] = str(source)
        # everything is computed: only now does the model change
        self.primitives_ = prim
        self.observations_ = obs
        self.hmm_ = hmm
        self.generators_ = gens
        self.stops_ = stops
        self.wheel_response_ = wheels
        self.start_envelope_ = envelope
        self.onset_floor_ = floors
        self.input_range_ = ranges
        self.start_range_ = starts_grown
        self.rehearsal_ = rehearsal
        # the old rows are not kept: the old radius, or the new rows' from the moved prototypes
        self.reach_radius_ = max(float(getattr(self, "reach_radius_", 0.0)), reach)
        self.rest_values_ = {c: float(np.median(stops[:, j])) for j, c in enumerate(inputs)}
        self.default_goal_ = self._default_goal(inputs, dataset.metadata.get("goal"))
        self.max_steps_ = int(max(self.max_steps_, 2 * int(lengths.max())))
        self.updates_ = [*updates, record]
        if getattr(self, "train_states_", None) is not None:
            self.train_states_ = np.concatenate([self.train_states_, nominal_states])
            self.train_observations_ = np.concatenate([self.train_observations_, observations])
        return self

    def _kept_rows(
        self,
        originals: _Rows,
        n_primitives: int,
        stored: RehearsalRows | None,
        n_kept: int,
        update: int,
    ) -> RehearsalRows | None:
        """The rows kept for the next update: at most ``rehearsal`` of each primitive among
        ``originals`` (the last training's rows, the first ``n_kept`` of them ``stored``'s),
        drawn as they stand for the rows seen (module ``models._rehearsal``); None where
        ``rehearsal`` is 0."""
        if self.rehearsal <= 0:
            return None
        seen = np.bincount(originals.states[n_kept:], minlength=n_primitives).astype(np.int64)
        if stored is not None:
            seen[: stored.seen.size] += stored.seen
        return sample(
            *originals[:5],
            originals.weights,
            seen,
            cap=int(self.rehearsal),
            by_segment=self.generator_network == "elman",
            rng=rehearsal_rng(self.random_state, update),
        )

    def _start_ranges(
        self, features: FloatArray, states: Any, n_primitives: int, layout: FeatureLayout
    ) -> np.ndarray | None:
        """``start_range_`` of generator rows ``features`` of primitives ``states`` (None
        without an onset clock: the rows do not say how far into a run they lie)."""
        if layout.clock <= 0:
            return None
        n_inputs = layout.n_channels
        return start_ranges(
            features[:, : n_inputs * layout.window],
            features[:, -1],
            states,
            n_primitives,
            n_inputs,
            layout.clock,
        )

    def _grown_floors(
        self, features: FloatArray, states: Any, n_primitives: int
    ) -> np.ndarray | None:
        """``onset_floor_`` after an update whose generator rows are ``features`` of
        primitives ``states``: a primitive with new rows takes the lower of its floor and
        theirs (its network is fine-tuned on them), a new one theirs, the rest keep theirs."""
        old = getattr(self, "onset_floor_", None)
        if self.onset_clock <= 0 or old is None:
            return None
        fresh = onset_floors(features[:, -1], states, n_primitives)
        seen = np.zeros(n_primitives, dtype=bool)
        seen[np.unique(np.asarray(states, dtype=np.int64))] = True
        kept = old.shape[0]
        fresh[:kept] = np.where(seen[:kept], np.minimum(old, fresh[:kept]), old)
        return fresh

    def _stored_rows(self) -> RehearsalRows | None:
        """The kept rows an update rehearses and a model file holds: none where
        ``rehearsal`` is 0 (also when set so since the fit); a ``rehearsal`` lowered below
        the rows kept of a primitive is refused (ConfigError)."""
        rows: RehearsalRows | None = getattr(self, "rehearsal_", None)
        if rows is None or self.rehearsal == 0:
            return None
        most = int(np.bincount(rows.primitives).max(initial=0)) if rows.n_rows else 0
        if self.rehearsal < most:
            raise ConfigError(
                f"rehearsal={self.rehearsal} is below the {most} rows this model keeps of a "
                "primitive; keep it, raise it, or set 0 to keep none"
            )
        return rows

    def _check_update(self, dataset: Dataset, inputs: tuple[str, ...]) -> None:
        """Refuse (ConfigError) demonstrations that this fitted model cannot learn from."""
        if inputs != self.inputs_:
            raise ConfigError(
                f"inputs changed since the fit ({','.join(self.inputs_)} -> {','.join(inputs)}); "
                "an update keeps the model's inputs"
            )
        if getattr(self, "stops_", None) is None:
            raise ConfigError("this model file predates stops_; fit it again to update it")
        behavior = str(dataset.metadata.get("behavior", "behavior"))
        if behavior != self.behavior_:
            raise ConfigError(
                f"the new demonstrations show {behavior!r}, the model {self.behavior_!r}"
            )
        self._check_same_robot(dataset, inputs, "model's")
        layout = self.feature_layout(len(inputs), int(self.primitives_.window))
        if self.generators_.n_features_in_ != layout.width:
            raise ConfigError(
                "the generator parameters (command_history, generator_output, onset_clock) "
                "changed since the fit; an update keeps them"
            )

    def _hidden(self, n_channels: int) -> int | tuple[int, ...]:
        if self.hidden is not None:
            return self.hidden
        return 5 * n_channels  # thesis table 6.2: 5 / 10 / 15 units for 1 / 2 / 3 channels

    def feature_layout(
        self, n_channels: int, window: int, delta_scale: float = 1.0
    ) -> FeatureLayout:
        """The generators' input row: sensor windows, efference copy, onset clock."""
        return FeatureLayout(
            n_channels=n_channels,
            window=window,
            history=int(self.command_history),
            delta=self.generator_output == "delta",
            clock=int(self.onset_clock),
            delta_scale=delta_scale,
            n_commands=len(self.command_channels),
        )

    def _cobart_overrides(
        self, params: Mapping[str, Any] | None, x: FloatArray, lengths: Any
    ) -> dict[str, Any]:
        """CobART overrides, with the ``dcm_floor`` applied to an automatic DCM scale."""
        out = dict(params or {})
        if self.dcm_floor > 0 and out.get("dcm_scale", "auto") == "auto":
            scale = suggest_dcm_scale(x, lengths)
            out["dcm_scale"] = np.maximum(scale, float(self.dcm_floor) * scale.max()).tolist()
        return out

    def _generator_rows(
        self,
        features: FloatArray,
        target: FloatArray,
        states: Any,
        lengths: Any,
        episode_ids: Any,
        kept: RehearsalRows | None = None,
    ) -> tuple[_Rows, _Rows]:
        """The generators' training rows (``segment_margin`` rows around each primitive,
        ``window_noise`` copies), and the same before the copies (what rehearsal keeps).
        ``kept`` rows (an update's rehearsal) come first, their demonstrations and runs
        numbered apart from the new rows'."""
        gen_states = np.asarray(states, dtype=np.int64)
        groups = np.repeat(episode_ids, lengths)
        source = np.arange(features.shape[0])
        if self.segment_margin > 0:
            rows, gen_states = margin_rows(gen_states, lengths, int(self.segment_margin))
            features, target, groups = features[rows], target[rows], groups[rows]
            source = rows
        breaks = (np.diff(source) != 1) | (gen_states[1:] != gen_states[:-1])
        breaks |= groups[1:] != groups[:-1]
        segments = np.r_[0, np.cumsum(breaks)].astype(np.int64)
        weights = np.ones(gen_states.size)
        if kept is not None and kept.n_rows:
            # a kept row stands for seen / kept rows of its primitive
            stored = np.bincount(kept.primitives, minlength=kept.seen.size)
            share = kept.seen[kept.primitives] / stored[kept.primitives]
            groups = np.unique(groups, return_inverse=True)[1].ravel() + kept.groups.max() + 1
            segments = segments + kept.segments.max() + 1
            features = np.vstack([kept.features.astype(np.float64), features])
            target = np.vstack([kept.targets.astype(np.float64), target])
            gen_states = np.concatenate([kept.primitives, gen_states])
            groups = np.concatenate([kept.groups, groups])
            segments = np.concatenate([kept.segments, segments])
            weights = np.concatenate([share, weights])
        originals = _Rows(features, target, gen_states, groups, segments, weights)
        if self.window_noise <= 0:
            return originals, originals
        features, target, gen_states, groups = self._noisy_copies(
            features, target, gen_states, groups
        )
        segments = np.concatenate([segments, segments + segments.max() + 1])
        weights = np.concatenate([weights, weights])
        return _Rows(features, target, gen_states, groups, segments, weights), originals

    def _noisy_copies(
        self, features: FloatArray, target: FloatArray, states: Any, groups: Any
    ) -> tuple[FloatArray, FloatArray, Any, Any]:
        """Append a copy of every row with a Gaussian offset on each channel's window."""
        rng = np.random.default_rng(self.random_state)
        n_ch, window = len(self.inputs_), int(self.primitives_.window)
        noisy = shifted_windows(features, n_ch, window, float(self.window_noise), rng)
        return (
            np.vstack([features, noisy]),
            np.vstack([target, target]),
            np.concatenate([states, states]),
            np.concatenate([groups, groups]),
        )

    def _default_goal(
        self, inputs: tuple[str, ...], declared: Mapping[str, float] | None
    ) -> dict[str, float]:
        """Where the demonstrations end on the behavior's goal channels.

        The goal channels and their nominal goals travel in the dataset's metadata
        (``goal``, written by ``collect`` from the behavior's spec); a dataset without
        them, or none of whose goal channels is an input, aims at the data contract's
        angle and distance among the inputs.
        """
        nominal_goals = {str(c): float(v) for c, v in (declared or {}).items()}
        if not any(c in inputs for c in nominal_goals):
            nominal_goals = dict(_DEFAULT_GOALS)
        goal = {}
        for c, nominal in nominal_goals.items():
            tolerance = self.channel_spec(c).tolerance if c in inputs else None
            if tolerance is None:  # not an input, or a channel that cannot be a goal
                continue
            # where the demonstrations end; the nominal goal when they end there
            end = self.rest_values_[c]
            goal[c] = nominal if abs(end - nominal) <= tolerance else round(end, 3)
        if not goal:
            goals = [c for c in inputs if self.channel_spec(c).tolerance is not None]
            if not goals:
                raise ConfigError(
                    f"none of the inputs {', '.join(inputs)} can be a goal: declare a "
                    "tolerance for at least one of them (docs/robots.md)"
                )
            goal = {goals[0]: self.rest_values_[goals[0]]}
        return goal

    # ----------------------------------------------------------------- queries
    def resolve_goal(self, goal: Mapping[str, float] | None) -> dict[str, float]:
        """The goal in physical units on this model's input channels (default: demos' end)."""
        self._check_fitted()
        if goal is None:
            return dict(self.default_goal_)
        return check_goal(goal, self.inputs_, self.channels_)

    def check_stoppable(self, goal: Mapping[str, float] | None) -> None:
        """Refuse, before any motion, a goal where no demonstration stopped.

        A simple behavior's networks learned to stop only where its demonstrations
        stopped; a goal the demonstrations merely passed through at speed (a turn to
        90 deg, an approach to 0.5 m) would be overshot and crept after until the step
        limit. A goal is stoppable on each goal channel when it lies within twice the
        channel's tolerance of a demonstrated stop, or inside the span of stops no
        further from one than the widest gap between neighbouring stops. (A complex
        behavior hands its components intermediate goals itself; this check is for the
        goal a user asks for.)

        Raises
        ------
        UnreachableGoalError
            Naming the goals this model can stop at.
        """
        stops = getattr(self, "stops_", None)
        if stops is None:
            return
        wanted = self.resolve_goal(goal)
        for channel, value in wanted.items():
            spec = self.channel_spec(channel)
            tolerance = float(spec.tolerance or 0.0)
            ends = np.sort(stops[:, self.inputs_.index(channel)])
            slack = 2.0 * tolerance
            if ends.size > 1:
                slack = max(slack, float(np.max(np.diff(ends))))
            gaps = np.abs([spec.error(end, value) for end in ends])
            if float(gaps.min()) > slack:
                # as many decimals as the tolerance shows: 3 deg -> 0, 0.01 m -> 2
                digits = max(0, -math.floor(math.log10(tolerance))) if tolerance > 0 else 2
                low, high = (round(float(e), digits) + 0.0 for e in (ends[0], ends[-1]))
                where = f"{low:.{digits}f}"
                if high - low > slack:
                    where += f" to {high:.{digits}f}"
                raise UnreachableGoalError(
                    f"goal {channel} {value:g} {spec.unit}: this {self.behavior_} model stops "
                    f"only where its demonstrations stopped, {channel} {where} {spec.unit} "
                    f"(±{slack:.{digits + 1}f}); "
                    f"compose it in a complex behavior to stop elsewhere"
                )

    # -------------------------------------------------------------- generation
    # --------------------------------------------------------------- save/load
    def _state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        self._check_fitted()
        arrays: dict[str, np.ndarray] = {}
        for prefix, part in (("hmm", self.hmm_), ("gen", self.generators_)):
            for name, arr in part.to_arrays().items():
                arrays[f"{prefix}.{name}"] = arr
        for name, attribute in LEARNED_ARRAYS:
            value = getattr(self, attribute, None)
            if value is not None:
                arrays[name] = value
        rehearsal = self._stored_rows()
        if rehearsal is not None:
            for name, arr in rehearsal.to_arrays().items():
                arrays[f"rehearsal.{name}"] = arr
        for prefix, net in (("prim", self.primitives_), ("obs", self.observations_)):
            arrays[f"{prefix}.prototypes"] = net.prototypes_
            arrays[f"{prefix}.counts"] = net.counts_
            arrays[f"{prefix}.dcm_scale"] = net.dcm_scale_
        state = {
            "inputs": list(self.inputs_),
            "pipeline": self.pipeline_.to_dict(),
            "primitives": _cobart_params(self.primitives_),
            "observations": _cobart_params(self.observations_),
            "hmm": self.hmm_.params,
            "generators": self.generators_.get_params(),
            "command_scale": self.command_scale_,
            "delta_scale": self.delta_scale_,
            "rest_values": self.rest_values_,
            "default_goal": self.default_goal_,
            "max_steps": self.max_steps_,
            "behavior": self.behavior_,
            "channels": self._channels_state(),
            **self._commands_state(),
            "train_data": self.train_data_,
            "provenance": dict(self.provenance_),
        }
        if getattr(self, "reach_radius_", None) is not None:
            state["reach_radius"] = self.reach_radius_
        if getattr(self, "updates_", None):  # a model never updated: the file as before
            state["updates"] = [dict(record) for record in self.updates_]
        return state, arrays

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the model to ``path`` (zip of JSON + arrays, no pickle; atomic)."""
        state, arrays = self._state()
        _modelfile.dump(path, self.kind, _jsonable_params(self.get_params()), state, arrays)

    @classmethod
    def _from_state(
        cls,
        params: Mapping[str, Any],
        state: Mapping[str, Any],
        arrays: Mapping[str, np.ndarray],
        budget: _modelfile.Budget | None = None,
    ) -> SBLM:
        model = cls(**params)
        model.check_params()
        inputs = model._checked_inputs()
        if not inputs:  # inputs="auto": the channels the fit chose
            names = state["inputs"]
            if not isinstance(names, list) or not 0 < len(names) <= _MAX_AUTO_INPUTS:
                raise ModelFileError("state inputs must be a list of sensor channels")
            inputs = tuple(str(_modelfile.check_text(n, "input channel")) for n in names)
            try:
                check_input_names(inputs)
            except ConfigError as err:
                raise ModelFileError(str(err)) from None
            if len(set(inputs)) != len(inputs):
                raise ModelFileError("state inputs repeat a channel")
        if list(inputs) != list(state["inputs"]):
            raise ModelFileError("inputs in params and state disagree")
        pipeline = SignalPipeline.from_dict(_modelfile.check_mapping(state["pipeline"], "pipeline"))
        if pipeline.channels != inputs:
            raise ModelFileError("pipeline channels do not match the inputs")
        _modelfile.check_pipeline(pipeline)
        names = {f"{p}.{n}" for p in ("prim", "obs") for n in ("prototypes", "counts", "dcm_scale")}
        names.update(name for name, _ in LEARNED_ARRAYS)
        names.update(f"rehearsal.{name}" for name in REHEARSAL_ARRAYS)
        extra = sorted(k for k in arrays if k not in names and not k.startswith(("hmm.", "gen.")))
        if extra:
            raise ModelFileError(f"unexpected arrays: {', '.join(extra[:5])}")
        for key in ("primitives", "observations", "generators"):
            window = _modelfile.check_mapping(state[key], key).get("window")
            _modelfile.check_int(window, f"{key} window", 1, _modelfile.MAX_WINDOW)
        # The HMM first: its tables bound the numbers of primitives and categories
        # that the networks below restore one by one.
        hmm = BehaviorHMM.from_arrays(
            _prefixed(arrays, "hmm"), _modelfile.check_mapping(state["hmm"], "hmm")
        )
        rows = {
            "prim.prototypes": hmm.n_states_,
            "obs.prototypes": hmm.n_observations_,
            "gen.w_x" if model.generator_network == "elman" else "gen.coef_0": hmm.n_states_,
        }
        for name, n in rows.items():
            arr = _modelfile.check_array(arrays, name, kind="biuf", finite=False)
            if arr.ndim < 1 or arr.shape[0] != n:
                raise ModelFileError(f"array '{name}' does not have the HMM's {n} rows")
        prim = _cobart_from(state["primitives"], arrays, "prim", len(inputs))
        obs = _cobart_from(state["observations"], arrays, "obs", len(inputs))
        gens = GENERATOR_NETWORKS[model.generator_network].from_arrays(
            _prefixed(arrays, "gen"), **state["generators"]
        )
        model._restore_commands(state)
        if hmm.n_states_ != prim.n_categories_ or hmm.n_observations_ != obs.n_categories_:
            raise ModelFileError("HMM sizes do not match the CobART categories")
        if gens.n_primitives_ != prim.n_categories_:
            raise ModelFileError("generator count does not match the primitives")
        if gens.window != prim.window:
            raise ModelFileError("generator window differs from the primitives' window")
        if gens.n_features_in_ != model.feature_layout(len(inputs), int(prim.window)).width:
            raise ModelFileError("generator inputs do not match the model's parameters")
        if gens.n_outputs_ != len(model.command_channels):
            raise ModelFileError("generator outputs do not match the command channels")
        model.rehearsal_ = None  # files written before it was kept, or rehearsal=0
        if any(name.startswith("rehearsal.") for name in arrays):
            model.rehearsal_ = rehearsal_from_arrays(
                arrays,
                cap=model.rehearsal,
                n_primitives=gens.n_primitives_,
                n_features=gens.n_features_in_,
                n_outputs=gens.n_outputs_,
            )
        model.inputs_ = inputs
        model.pipeline_ = pipeline
        model.primitives_ = prim
        model.observations_ = obs
        model.hmm_ = hmm
        model.generators_ = gens
        model.delta_scale_ = _modelfile.check_number(
            state["delta_scale"], "delta_scale", positive=True
        )
        model._restore_common(state, inputs)
        model.updates_ = _check_updates(state.get("updates"))
        if "reach_radius" in state:  # files written before it was learned have none
            reach = _modelfile.check_number(state["reach_radius"], "reach_radius")
            if reach < 0:
                raise ModelFileError(f"reach_radius must be >= 0, got {reach:g}")
            model.reach_radius_ = reach
        if "stops" in arrays:  # files written before it was kept have no stops
            stops = _modelfile.check_array(arrays, "stops", ndim=2)
            if stops.shape[1] != len(inputs) or not 0 < stops.shape[0] <= _modelfile.MAX_STEPS:
                raise ModelFileError("array 'stops' must have one column per input")
            if np.abs(stops).max() > _modelfile.MAX_ABS_VALUE:
                raise ModelFileError("array 'stops' holds absurd values")
            model.stops_ = np.array(stops, dtype=np.float64)
        if "command_rates" in arrays:  # files written before it was learned have none
            rates = _modelfile.check_array(arrays, "command_rates", ndim=2)
            if rates.shape != (len(model.command_channels), len(inputs)):
                raise ModelFileError(
                    "array 'command_rates' must be commands x the number of inputs"
                )
            if np.abs(rates).max() > _modelfile.MAX_ABS_VALUE:
                raise ModelFileError("array 'command_rates' holds absurd values")
            model.command_rates_ = np.array(rates, dtype=np.float64)
        model.wheel_response_ = None  # files written before it was learned have none
        if "wheel_response" in arrays:
            sums = _modelfile.check_array(arrays, "wheel_response", ndim=2)
            if sums.shape != (2, 3):
                raise ModelFileError("array 'wheel_response' must be 2 wheels x 3 sums")
            if np.abs(sums).max() > _modelfile.MAX_ABS_VALUE:
                raise ModelFileError("array 'wheel_response' holds absurd values")
            model.wheel_response_ = np.array(sums, dtype=np.float64)
        model.start_envelope_ = None  # files written before it was learned have none
        if "start_envelope" in arrays:
            envelope = _modelfile.check_array(arrays, "start_envelope", ndim=2)
            rows, cols = envelope.shape
            if cols != len(model.command_channels) or not 0 < rows <= _modelfile.MAX_STEPS:
                raise ModelFileError(
                    "array 'start_envelope' must be cycles x the number of commands"
                )
            if not np.all(envelope >= 0.0) or envelope.max() > _modelfile.MAX_ABS_VALUE:
                raise ModelFileError("array 'start_envelope' holds negative or absurd values")
            model.start_envelope_ = np.array(envelope, dtype=np.float64)
        model.onset_floor_ = None  # files written before it was learned have none
        if "onset_floor" in arrays:
            floors = _modelfile.check_array(arrays, "onset_floor", ndim=1)
            if floors.shape != (model.generators_.n_primitives_,):
                raise ModelFileError("array 'onset_floor' must hold one value per primitive")
            if not np.all((floors >= 0.0) & (floors <= 1.0)):
                raise ModelFileError("array 'onset_floor' must lie in [0, 1]")
            model.onset_floor_ = np.array(floors, dtype=np.float64)
        model.input_range_ = None  # files written before it was learned have none
        if "input_range" in arrays:
            ranges = _modelfile.check_array(arrays, "input_range", ndim=3)
            columns = len(inputs) * int(model.generators_.window)
            if ranges.shape != (model.generators_.n_primitives_, 2, columns):
                raise ModelFileError(
                    "array 'input_range' must be primitives x 2 x the windows' inputs"
                )
            if np.abs(ranges).max(initial=0.0) > _modelfile.MAX_ABS_VALUE:
                raise ModelFileError("array 'input_range' holds absurd values")
            if not np.all(ranges[:, 0] <= ranges[:, 1]):
                raise ModelFileError("array 'input_range' has a low above its high")
            model.input_range_ = np.array(ranges, dtype=np.float64)
        model.start_range_ = None  # files written before it was learned have none
        if "start_range" in arrays:
            model.start_range_ = _checked_start_range(arrays, model, len(inputs))
        return model


def _checked_start_range(
    arrays: Mapping[str, np.ndarray], model: SBLM, n_inputs: int
) -> np.ndarray:
    """A model file's ``start_range`` array, checked against the model it belongs to."""
    starts = _modelfile.check_array(arrays, "start_range", ndim=4, finite=False)
    clock = model.feature_layout(n_inputs, int(model.generators_.window)).clock
    if clock <= 0 or starts.shape != (model.generators_.n_primitives_, n_inputs, clock + 1, 2):
        raise ModelFileError(
            "array 'start_range' must be primitives x inputs x the onset clock's cycles + 1 x 2"
        )
    unseen = np.isnan(starts)
    if np.any(unseen[..., 0] != unseen[..., 1]) or np.isinf(starts).any():
        raise ModelFileError("array 'start_range' has a low without its high, or an infinity")
    if np.abs(np.where(unseen, 0.0, starts)).max(initial=0.0) > _modelfile.MAX_ABS_VALUE:
        raise ModelFileError("array 'start_range' holds absurd values")
    if np.any(starts[..., 0] > starts[..., 1]):  # NaN compares False
        raise ModelFileError("array 'start_range' has a low above its high")
    return np.array(starts, dtype=np.float64)


def demonstrated_wheel_response(dataset: Dataset) -> np.ndarray | None:
    """How the demonstrated wheels answered (:func:`behavior_hmm.runtime.wheel_response`),
    or None without left/right wheel commands or measured velocities."""
    if tuple(dataset.command_channels) != CALIBRATION_COMMANDS or any(
        c not in dataset.sensor_channels for c in CALIBRATION_CHANNELS
    ):
        return None
    speed, yaw_rate = (dataset.column(c) for c in CALIBRATION_CHANNELS)
    return wheel_response(
        dataset.commands,
        speed,
        yaw_rate,
        dataset.lengths,
        rest=np.array([spec.rest for spec in dataset.command_specs], dtype=np.float64),
    )


def added_wheel_response(old: np.ndarray | None, new: np.ndarray | None) -> np.ndarray | None:
    """The sums of both (either alone where the other is None)."""
    if old is None or new is None:
        return new if old is None else old
    return np.asarray(old + new, dtype=np.float64)


def _sequences(gens: Any, starts: NDArray[np.intp]) -> dict[str, Any]:
    """The training sequences' starts, for generators that train on sequences (recurrent)."""
    return {"sequences": starts} if isinstance(gens, ElmanGenerators) else {}


def nominal_episodes(dataset: Dataset) -> NDArray[np.bool_]:
    """Which episodes are nominal demonstrations (not listed in ``corrective_episodes``)."""
    corrective = dataset.metadata.get("corrective_episodes") or []
    keep = ~np.isin(np.asarray(dataset.episode_ids), np.asarray(corrective, dtype=np.int64))
    if not keep.any():
        raise ConfigError("the dataset holds corrective demonstrations only; no nominal ones")
    return np.asarray(keep, dtype=bool)


def without_unseen_corrections(dataset: Dataset, inputs: Sequence[str]) -> Dataset:
    """``dataset`` without its corrective demonstrations if ``inputs`` cannot see them.

    A corrective run's disturbance moves the channels its metadata lists
    (``corrections.disturbs``: the bearing); a learner whose inputs miss one of them sees
    the teacher's corrections without their cause, as noise, and keeps the nominal
    demonstrations only. Datasets that do not say what their disturbance moves are kept
    whole.
    """
    nominal = nominal_episodes(dataset)
    disturbs = (dataset.metadata.get("corrections") or {}).get("disturbs")
    if nominal.all() or disturbs is None or set(disturbs) <= set(inputs):
        return dataset
    return dataset.subset(np.flatnonzero(nominal))


def nominal_rows(dataset: Dataset) -> NDArray[np.bool_]:
    """Rows of the nominal demonstrations."""
    return np.repeat(nominal_episodes(dataset), dataset.lengths)


def reach_radius(x: np.ndarray, observations: CobART) -> float:
    """How far the demonstrations reach: the largest distance from a row of ``x``
    (normalized readings) to its nearest observation prototype's newest reading."""
    anchors = observations.prototypes_[:, -1, :]
    if not len(x) or not len(anchors):
        return 0.0
    distance, _ = cKDTree(anchors).query(np.asarray(x, dtype=np.float64))
    return float(np.max(distance))


def command_rates(
    x: np.ndarray,
    commands: np.ndarray,
    lengths: np.ndarray,
    pipeline: SignalPipeline,
    inputs: Sequence[ChannelSpec],
    wheels: bool = True,
) -> np.ndarray:
    """How each wheel command moves each input: least squares over the demonstrations.

    Row ``w`` (a command channel: left, right for our wheels), column ``c``: the change
    of filtered input ``c`` per control cycle (its physical unit, an angle wrapped) per
    unit of command ``w`` (rad/s of a wheel), fitted on every
    pair of consecutive rows of an episode (the command of a row against the change to
    the next). Goal braking predicts from it where a ramp to rest would end, from the
    command alone rather than from a noisy measured rate.
    """
    norm = pipeline.normalizer
    phys = (x + 1.0) / np.asarray(norm.gain, dtype=np.float64) + np.asarray(norm.lo)
    keep = np.ones(len(x), dtype=bool)
    keep[np.cumsum(lengths) - 1] = False  # no pair across an episode's end
    change = np.diff(phys, axis=0, append=phys[-1:])
    for j, spec in enumerate(inputs):
        if spec.wraps:
            change[:, j] = (change[:, j] + 180.0) % 360.0 - 180.0
    u = np.asarray(commands, dtype=np.float64)[keep]
    # in the wheels' common and differential parts, which a behavior rarely mixes (an
    # approach barely yaws): a small ridge keeps the unexcited part's gain near zero
    # instead of letting two nearly equal columns cancel each other with huge gains;
    # other commands (joints, a gripper) in their own axes, with the same ridge
    if wheels:
        basis = np.array([[0.5, -0.5], [0.5, 0.5]])  # (left, right) -> (common, differential)
    else:
        basis = np.eye(u.shape[1])
    z = u @ basis
    gram = z.T @ z
    ridge = 1e-3 * max(float(np.trace(gram)), 1e-12)
    coef = np.linalg.solve(gram + ridge * np.eye(len(gram)), z.T @ change[keep])
    return np.asarray(basis @ coef, dtype=np.float64)


def continued_cobart(net: CobART, x: FloatArray, lengths: Any) -> CobART:
    """A copy of ``net`` that went on learning on ``x``, compacted as :meth:`SBLM.fit` does.

    The copy learns with :meth:`CobART.partial_fit` (``net`` is left as it was), then
    relabels ``x`` with its final prototypes (``labels_``). Every category of ``net``
    keeps its index, whether it wins on ``x`` or not; of the categories ``x`` created,
    those that win are kept, in order, after them (``kept_``: their indices in the grown
    network), the others dropped.
    """
    grown = CobART(**net.get_params(deep=False))
    grown.set_state(net.prototypes_, net.counts_, net.dcm_scale_)
    grown.partial_fit(x, lengths)
    labels = grown.predict(x, lengths)
    k_old = net.n_categories_
    kept = np.r_[np.arange(k_old), np.unique(labels[labels >= k_old])].astype(np.int64)
    out = CobART(**grown.get_params(deep=False))
    out.set_state(grown.prototypes_[kept], grown.counts_[kept], grown.dcm_scale_)
    remap = np.full(grown.n_categories_, -1, dtype=np.int64)
    remap[kept] = np.arange(kept.size)
    out.kept_ = kept
    out.labels_ = remap[labels]
    return out


#: The keys of an update record (``SBLM.updates_``): text, whole numbers, a list of them.
_UPDATE_TEXT = ("dataset_sha256", "env", "package_version", "source")
_UPDATE_INTS = ("episodes", "rows", "new_primitives", "new_observations", "rehearsed")
_MAX_UPDATES = 10_000


def _check_updates(value: Any) -> list[dict[str, Any]]:
    """The update records of a model file (none in files of models never updated)."""
    if value is None:
        return []
    if not isinstance(value, list) or len(value) > _MAX_UPDATES:
        raise ModelFileError(f"updates must be a list of at most {_MAX_UPDATES} records")
    out = []
    for entry in value:
        record = _modelfile.check_mapping(entry, "updates")
        checked: dict[str, Any] = {}
        for key, item in record.items():
            if key in _UPDATE_TEXT:
                checked[key] = _modelfile.check_text(item, f"updates {key}")
            elif key in _UPDATE_INTS:
                checked[key] = _modelfile.check_int(item, f"updates {key}", 0, 2**53)
            elif key == "fine_tuned":
                if not isinstance(item, list) or len(item) > _modelfile.MAX_STEPS:
                    raise ModelFileError("updates fine_tuned must be a list of primitives")
                checked[key] = [
                    _modelfile.check_int(p, "updates fine_tuned", 0, 2**31) for p in item
                ]
            else:
                raise ModelFileError(f"unknown key {key!r} in an update record")
        out.append(checked)
    return out


def _package_version() -> str:
    from behavior_hmm import __version__

    return str(__version__)


def _cobart_params(net: CobART) -> dict[str, Any]:
    params = net.get_params()
    params["dcm_scale"] = "auto"  # the fitted scale is stored as an array
    return params


def _cobart_from(
    params: Mapping[str, Any], arrays: Mapping[str, np.ndarray], prefix: str, n_channels: int
) -> CobART:
    protos = _modelfile.check_array(arrays, f"{prefix}.prototypes", ndim=3)
    counts = _modelfile.check_array(arrays, f"{prefix}.counts", ndim=1, kind="iu")
    scale = _modelfile.check_array(arrays, f"{prefix}.dcm_scale", ndim=1)
    if protos.shape[2] != n_channels or scale.shape[0] != n_channels:
        raise ModelFileError(f"{prefix} CobART has the wrong number of channels")
    if protos.shape[0] == 0 or counts.shape[0] != protos.shape[0]:
        raise ModelFileError(f"{prefix} CobART prototypes and counts disagree")
    net = CobART(**params)
    net.set_state(protos, counts, scale)
    return net


def _prefixed(arrays: Mapping[str, np.ndarray], prefix: str) -> dict[str, np.ndarray]:
    head = prefix + "."
    return {k[len(head) :]: v for k, v in arrays.items() if k.startswith(head)}


def _jsonable_params(params: Mapping[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in params.items():
        if isinstance(value, tuple):
            value = list(value)
        if isinstance(value, Mapping):
            value = dict(value)
        out[key] = value
    return out
