"""Baselines evaluated in the same run as the learned behaviors (DESIGN §6)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Self

import numpy as np
from numpy.typing import NDArray

from behavior_hmm._estimator import Estimator
from behavior_hmm.data import (
    DEFAULT_CUTOFF_HZ,
    SENSOR_CHANNELS,
    CommandScaler,
    Dataset,
    SignalPipeline,
)
from behavior_hmm.data._channels import ChannelSpec, channel
from behavior_hmm.errors import ConfigError, NotFittedError
from behavior_hmm.generators import DEFAULT_GENERATOR_EPOCHS, MotionGenerators
from behavior_hmm.generators._features import (
    DEFAULT_ONSET_CLOCK,
    FeatureLayout,
    shifted_windows,
)
from behavior_hmm.generators._motion import AdamGenerators
from behavior_hmm.models._goals import check_goal, check_input_names, within_tolerance
from behavior_hmm.models._sblm import without_unseen_corrections
from behavior_hmm.runtime import (
    DEFAULT_FAULT_HOLD_S,
    StepOutput,
    Trace,
    ordered_channels,
    run_policy,
)

FloatArray = NDArray[np.float64]

_DEFAULT_GOALS = {"angle": 0.0, "distance": 0.0}


class BehaviorCloning(Estimator):
    """Plain behavior cloning: one goal-conditioned network on all demonstrations.

    The network reads what an SBLM's generators read with the default settings (the
    filtered, normalized sensor windows, the onset clock, training on window-shifted
    copies too) plus the normalized goal, and outputs the normalized wheel commands, so
    the comparison isolates what the primitives and the Behavior-HMM add. There are no
    primitives, observation categories or plans; it stops when the filtered readings
    lie within the goal's physical tolerance. Goals in the data are where each
    demonstration ends (``goal_<channel>`` of the episode when present).

    Parameters
    ----------
    inputs
        Sensor channels read, as for the SBLM.
    hidden
        Hidden units: an int (one layer), a tuple of ints (one per layer, e.g.
        ``(64, 64)``) or ``None``, 10 per input channel (twice an SBLM generator's,
        since one network learns the whole behavior).
    window, command_history, onset_clock, window_noise, cutoff_hz, learning_rate, momentum,
    epochs, batch_size
        As for the SBLM's motion generators (same defaults).
    optimizer
        ``"sgd"``: gradient descent with ``momentum``, ``learning_rate`` per sample, as
        the SBLM's generators; ``"adam"``: Adam with step size ``learning_rate`` on
        each batch's mean gradient (``momentum`` is then unused).
    patience
        Stop after this many epochs without a new lowest error on the held-out 20 %
        of the episodes (``None``: train every epoch). Either way the weights of
        the epoch with the lowest held-out error are kept.
    init_range
        Initial weights are uniform in ``[-init_range, init_range]``.
    random_state
        Seed.
    """

    kind = "BC"
    #: The policy's component name in traces (``StepOutput.component``).
    label = "bc"

    def __init__(
        self,
        inputs: Sequence[str] = ("angle",),
        *,
        hidden: int | tuple[int, ...] | None = None,
        window: int = 10,
        command_history: int = 0,
        onset_clock: int = DEFAULT_ONSET_CLOCK,
        window_noise: float = 0.003,
        cutoff_hz: float | None = DEFAULT_CUTOFF_HZ,
        learning_rate: float = 0.01,
        momentum: float = 0.4,
        epochs: int = DEFAULT_GENERATOR_EPOCHS,
        batch_size: int = 32,
        optimizer: str = "sgd",
        patience: int | None = None,
        init_range: float = 1.0,
        random_state: int = 0,
    ) -> None:
        self.inputs = inputs
        self.hidden = hidden
        self.window = window
        self.command_history = command_history
        self.onset_clock = onset_clock
        self.window_noise = window_noise
        self.cutoff_hz = cutoff_hz
        self.learning_rate = learning_rate
        self.momentum = momentum
        self.epochs = epochs
        self.batch_size = batch_size
        self.optimizer = optimizer
        self.patience = patience
        self.init_range = init_range
        self.random_state = random_state

    def fit(self, dataset: Dataset) -> Self:
        """Train the network on every demonstration of ``dataset``; returns ``self``.

        Corrective demonstrations count as for an SBLM (``learn_corrections``): only when
        the inputs include the channels their disturbance moves.
        """
        if self.optimizer not in ("sgd", "adam"):
            raise ConfigError(f"optimizer must be 'sgd' or 'adam', got {self.optimizer!r}")
        inputs = (self.inputs,) if isinstance(self.inputs, str) else tuple(self.inputs)
        check_input_names(inputs, getattr(dataset, "sensor_channels", SENSOR_CHANNELS))
        # corrective demonstrations by the SBLM's rule: kept when the inputs see their cause
        dataset = without_unseen_corrections(dataset, inputs)
        pipeline = SignalPipeline.for_dataset(dataset, inputs, self.cutoff_hz)
        x = pipeline.transform(dataset)
        lengths = dataset.lengths
        raw = dataset.columns(inputs)
        finals = dataset.offsets[1:] - 1
        specs = {spec.name: spec for spec in getattr(dataset, "channel_specs", ())}
        self.channels_ = {c: specs[c] for c in inputs if c in specs}
        # the data contract's goal channels; else the dataset's goal on the inputs (a
        # robot's own channels, e.g. x, y); else the first input. A declared goal on
        # neither angle nor distance (grasp: arm and object_present) is the goal even
        # when angle or distance are inputs too: else the network would stop where the
        # approach ends.
        declared = [c for c in (dataset.metadata.get("goal") or {}) if c in inputs]
        if declared and not any(c in _DEFAULT_GOALS for c in declared):
            goal_channels = tuple(declared)
        else:
            goal_channels = (
                tuple(c for c in _DEFAULT_GOALS if c in inputs) or tuple(declared) or (inputs[0],)
            )
        # the goal of each episode: where it ends (its own goal, for goal-varying data)
        goal_cols = [inputs.index(c) for c in goal_channels]
        episode_goal = x[finals][:, goal_cols]
        goals = np.repeat(episode_goal, lengths, axis=0)
        command_specs = tuple(getattr(dataset, "command_specs", ()))
        scaler = CommandScaler([spec.unit for spec in command_specs] or None)
        scaler.fit(dataset.commands)
        y = scaler.transform(dataset.commands)
        self.command_specs_ = command_specs
        self.command_scales_ = np.asarray(scaler.scales_, dtype=np.float64)
        self.inputs_ = inputs
        self.goal_channels_ = goal_channels
        features = self.feature_layout().offline(x, y, lengths, goals)
        groups = np.repeat(dataset.episode_ids, lengths)
        targets = y
        if self.window_noise > 0:
            rng = np.random.default_rng(self.random_state)
            noisy = shifted_windows(features, len(inputs), self.window, self.window_noise, rng)
            features = np.vstack([features, noisy])
            targets = np.vstack([y, y])
            groups = np.concatenate([groups, groups])
        net = self._network(len(inputs)).fit(features, targets, None, groups=groups)
        self.pipeline_ = pipeline
        self.network_ = net
        self.command_scale_ = float(scaler.scale_)
        goal = dataset.metadata.get("goal") or {}
        self.default_goal_ = {
            c: 0.0
            if c in _DEFAULT_GOALS
            else float(goal[c])
            if c in goal
            else float(np.median(raw[finals, inputs.index(c)]))
            for c in goal_channels
        }
        self.max_steps_ = int(max(500, 2 * int(lengths.max())))
        self.behavior_ = str(dataset.metadata.get("behavior", "behavior"))
        return self

    def _network(self, n_inputs: int) -> MotionGenerators:
        """The unfitted network: one slot, trained with the chosen optimizer."""
        hidden = self.hidden if self.hidden is not None else 10 * n_inputs
        common: dict[str, Any] = {
            "window": self.window,
            "hidden": hidden,
            "learning_rate": self.learning_rate,
            "epochs": self.epochs,
            "batch_size": self.batch_size,
            "init_range": self.init_range,
            "patience": self.patience,
            "random_state": self.random_state,
        }
        if self.optimizer == "adam":
            return AdamGenerators(**common)
        return MotionGenerators(momentum=self.momentum, **common)

    def feature_layout(self) -> FeatureLayout:
        """The network's input row: sensor windows, goal, efference copy, onset clock."""
        return FeatureLayout(
            n_channels=len(self.inputs_),
            window=int(self.window),
            goal=len(self.goal_channels_),
            history=int(self.command_history),
            clock=int(self.onset_clock),
            n_commands=len(self.command_channels),
        )

    @property
    def command_channels(self) -> tuple[str, ...]:
        """The command channels the network outputs (default the wheels)."""
        specs = getattr(self, "command_specs_", None)
        return ("left", "right") if not specs else tuple(spec.name for spec in specs)

    @property
    def rest_command(self) -> NDArray[np.float64]:
        """The command that holds the robot still."""
        specs = getattr(self, "command_specs_", None)
        return np.zeros(2) if not specs else np.array([spec.rest for spec in specs])

    def channel_spec(self, name: str) -> ChannelSpec:
        """The declaration of the input channel ``name`` (the data's, else the registry's)."""
        own = getattr(self, "channels_", None) or {}
        return own[name] if name in own else channel(name)

    def resolve_goal(self, goal: Mapping[str, float] | None) -> dict[str, float]:
        """The goal on this model's goal channels (default: where the demos end)."""
        if not hasattr(self, "network_"):
            raise NotFittedError(f"this {type(self).__name__} is not fitted yet; call fit first")
        if goal is None:
            return dict(self.default_goal_)
        checked = check_goal(goal, self.inputs_, getattr(self, "channels_", None))
        return {c: checked.get(c, self.default_goal_[c]) for c in self.goal_channels_}

    def generate(
        self,
        env: Any,
        start: Mapping[str, float] | None = None,
        goal: Mapping[str, float] | None = None,
        *,
        seed: int | None = None,
        noise: float | None = None,
        max_steps: int | None = None,
        pushes: Sequence[Mapping[str, float]] | None = None,
        fault_hold_s: float = DEFAULT_FAULT_HOLD_S,
    ) -> Trace:
        """Drive ``env`` from ``start`` with the cloned policy until the goal tolerance.

        The keyword arguments are those of :func:`behavior_hmm.models.perform`
        (``fault_hold_s``: seconds a non-finite reading on an input is held).
        """
        return run_policy(
            self.policy(goal),
            env,
            start=start,
            seed=seed,
            noise=noise,
            max_steps=int(max_steps or self.max_steps_),
            pushes=pushes,
            fault_hold_s=fault_hold_s,
        )

    def policy(self, goal: Mapping[str, float] | None = None) -> BCPolicy:
        """The cloned policy toward ``goal`` (see :class:`behavior_hmm.runtime.Policy`)."""
        return BCPolicy(self, self.resolve_goal(goal))


class StrongBehaviorCloning(BehaviorCloning):
    """Behavior cloning done properly: a wider, deeper network trained with Adam.

    The same inputs, features, goals, data and stopping rule as :class:`BehaviorCloning`
    (it is one, with other defaults): two hidden layers of 64 units, Adam with step
    size 2e-3 on minibatches of 128, up to 300 epochs, stopping after 20 epochs
    without a new lowest error on the held-out 20 % of the episodes and keeping the
    best epoch's weights, and initial weights in ±0.2 (near Glorot's range for these
    layer sizes, so the wider layers do not start saturated). It answers whether a
    well-trained monolithic network closes the gap to the primitives. The step size
    and batch were chosen on the held-out split's error of the default kinematic turn
    and approach data (they beat step 1e-3 with batches of 64 or 32 there).

    Parameters
    ----------
    inputs, hidden, window, command_history, onset_clock, window_noise, cutoff_hz,
    learning_rate, momentum, epochs, batch_size, optimizer, patience, init_range,
    random_state
        As for :class:`BehaviorCloning` (other defaults).
    """

    kind = "BC-strong"
    label = "bc-strong"

    def __init__(
        self,
        inputs: Sequence[str] = ("angle",),
        *,
        hidden: int | tuple[int, ...] | None = (64, 64),
        window: int = 10,
        command_history: int = 0,
        onset_clock: int = DEFAULT_ONSET_CLOCK,
        window_noise: float = 0.003,
        cutoff_hz: float | None = DEFAULT_CUTOFF_HZ,
        learning_rate: float = 2e-3,
        momentum: float = 0.4,
        epochs: int = 300,
        batch_size: int = 128,
        optimizer: str = "adam",
        patience: int | None = 20,
        init_range: float = 0.2,
        random_state: int = 0,
    ) -> None:
        super().__init__(
            inputs,
            hidden=hidden,
            window=window,
            command_history=command_history,
            onset_clock=onset_clock,
            window_noise=window_noise,
            cutoff_hz=cutoff_hz,
            learning_rate=learning_rate,
            momentum=momentum,
            epochs=epochs,
            batch_size=batch_size,
            optimizer=optimizer,
            patience=patience,
            init_range=init_range,
            random_state=random_state,
        )


class BCPolicy:
    """Behavior cloning's policy: the one network, fed the goal, until the tolerance."""

    def __init__(self, model: BehaviorCloning, goal: dict[str, float]) -> None:
        self.goal = goal
        self._model = model
        self._channels = tuple(model.inputs_)
        self.channels = ordered_channels(self._channels)
        self._pipe = model.pipeline_.online()
        norm = model.pipeline_.normalizer
        self._lo = np.array(norm.lo, dtype=np.float64)
        self._gain = np.array(norm.gain, dtype=np.float64)
        goal_norm = [
            (goal[c] - self._lo[model.inputs_.index(c)]) * self._gain[model.inputs_.index(c)] - 1
            for c in model.goal_channels_
        ]
        self._features = model.feature_layout().online()
        self._features.set_goal(np.asarray(goal_norm, dtype=np.float64))
        self._label = model.label
        self.channel_specs = {c: model.channel_spec(c) for c in model.inputs_}
        self.command_channels = tuple(model.command_channels)
        self._rest = model.rest_command
        scales = getattr(model, "command_scales_", None)
        self._scales = model.command_scale_ if scales is None else np.asarray(scales)

    def reset(self) -> None:
        self._pipe.reset()
        self._features.reset()

    def step(self, reading: Mapping[str, float]) -> StepOutput:
        x = self._pipe.step(np.array([reading[c] for c in self._channels], dtype=np.float64))
        self._features.push(x)
        filtered = (x + 1.0) / self._gain + self._lo
        values = dict(zip(self._channels, filtered.tolist(), strict=True))
        if within_tolerance(values, self.goal, 1.0, self.channel_specs):
            return StepOutput(self._rest, -1, False, 0, self._label, False, True)
        features = self._features
        y = features.commit(self._model.network_.predict_one(features.row(), 0))
        command = y * self._scales
        return StepOutput(command, -1, False, 0, self._label, False, False)


#: The baselines every table reports beside a learned behavior, by name (``--baseline``).
BASELINES: dict[str, type[BehaviorCloning]] = {
    "bc": BehaviorCloning,
    "bc-strong": StrongBehaviorCloning,
}


def fit_baselines(
    inputs: Sequence[str], dataset: Dataset, seed: int, names: Sequence[str] = tuple(BASELINES)
) -> dict[str, BehaviorCloning]:
    """Each named baseline trained on ``dataset`` with the model's inputs and seed."""
    unknown = [n for n in names if n not in BASELINES]
    if unknown:
        raise ConfigError(f"unknown baseline '{unknown[0]}'; available: {', '.join(BASELINES)}")
    return {n: BASELINES[n](inputs=tuple(inputs), random_state=seed).fit(dataset) for n in names}


def baseline_columns(result: Mapping[str, Any]) -> dict[str, Any]:
    """``bc``, ``bc_goal_reached``, ``bc_strong``, ... of an evaluation, for a table row."""
    out: dict[str, Any] = {}
    for name, base in result["baselines"].items():
        key = name.replace("-", "_")
        out[key] = base["success_rate_mean"]
        out[f"{key}_goal_reached"] = base["goal_reached"]
    return out
