"""Baselines evaluated in the same run as the learned behaviors (DESIGN §6)."""

from __future__ import annotations

import inspect
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data import (
    DEFAULT_CUTOFF_HZ,
    SENSOR_CHANNELS,
    CommandScaler,
    Dataset,
    SignalPipeline,
)
from behavior_hmm.errors import ConfigError, NotFittedError
from behavior_hmm.generators import MotionGenerators, make_windows
from behavior_hmm.models._goals import check_goal, within_tolerance
from behavior_hmm.models._sblm import command_features, onset_features, shifted_windows
from behavior_hmm.runtime import (
    DEFAULT_FAULT_HOLD_S,
    StepOutput,
    Trace,
    channels_read,
    run_controller,
)

FloatArray = NDArray[np.float64]

_DEFAULT_GOALS = {"angle": 0.0, "distance": 0.0}
_ZERO = np.zeros(2)


class BehaviorCloning:
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
        Hidden units; default 10 per input channel (twice an SBLM generator's, since
        one network learns the whole behavior).
    window, command_history, onset_clock, window_noise, cutoff_hz, learning_rate, momentum,
    epochs, batch_size
        As for the SBLM's motion generators (same defaults).
    random_state
        Seed.
    """

    kind = "BC"

    def __init__(
        self,
        inputs: Sequence[str] = ("angle",),
        *,
        hidden: int | None = None,
        window: int = 10,
        command_history: int = 0,
        onset_clock: int = 64,
        window_noise: float = 0.003,
        cutoff_hz: float | None = DEFAULT_CUTOFF_HZ,
        learning_rate: float = 0.01,
        momentum: float = 0.4,
        epochs: int = 200,
        batch_size: int = 32,
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
        self.random_state = random_state

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """Constructor parameters by name."""
        names = [n for n in inspect.signature(type(self).__init__).parameters if n != "self"]
        return {name: getattr(self, name) for name in names}

    def fit(self, dataset: Dataset) -> BehaviorCloning:
        """Train the network on every demonstration of ``dataset``; returns ``self``."""
        inputs = (self.inputs,) if isinstance(self.inputs, str) else tuple(self.inputs)
        for name in inputs:
            if name not in SENSOR_CHANNELS:
                raise ConfigError(f"unknown input '{name}'")
        pipeline = SignalPipeline(inputs, self.cutoff_hz)
        x = pipeline.transform(dataset)
        lengths = dataset.lengths
        raw = dataset.columns(inputs)
        finals = dataset.offsets[1:] - 1
        goal_channels = tuple(c for c in _DEFAULT_GOALS if c in inputs) or (inputs[0],)
        # the goal of each episode: where it ends (its own goal, for goal-varying data)
        goal_cols = [inputs.index(c) for c in goal_channels]
        episode_goal = x[finals][:, goal_cols]
        goals = np.repeat(episode_goal, lengths, axis=0)
        scaler = CommandScaler().fit(dataset.commands)
        y = scaler.transform(dataset.commands)
        parts = [make_windows(x, lengths, self.window), goals]
        if self.command_history:
            parts.append(command_features(y, lengths, self.command_history))
        if self.onset_clock > 0:
            parts.append(onset_features(lengths, self.onset_clock))
        features = np.hstack(parts)
        groups = np.repeat(dataset.episode_ids, lengths)
        targets = y
        if self.window_noise > 0:
            rng = np.random.default_rng(self.random_state)
            noisy = shifted_windows(features, len(inputs), self.window, self.window_noise, rng)
            features = np.vstack([features, noisy])
            targets = np.vstack([y, y])
            groups = np.concatenate([groups, groups])
        hidden = self.hidden if self.hidden is not None else 10 * len(inputs)
        net = MotionGenerators(
            window=self.window,
            hidden=hidden,
            learning_rate=self.learning_rate,
            momentum=self.momentum,
            epochs=self.epochs,
            batch_size=self.batch_size,
            random_state=self.random_state,
        ).fit(features, targets, None, groups=groups)
        self.inputs_ = inputs
        self.pipeline_ = pipeline
        self.network_ = net
        self.goal_channels_ = goal_channels
        self.command_scale_ = float(scaler.scale_)
        self.default_goal_ = {
            c: float(np.median(raw[finals, inputs.index(c)])) if c not in _DEFAULT_GOALS else 0.0
            for c in goal_channels
        }
        self.max_steps_ = int(max(500, 2 * int(lengths.max())))
        self.behavior_ = str(dataset.metadata.get("behavior", "behavior"))
        return self

    def resolve_goal(self, goal: Mapping[str, float] | None) -> dict[str, float]:
        """The goal on this model's goal channels (default: where the demos end)."""
        if not hasattr(self, "network_"):
            raise NotFittedError("this BehaviorCloning is not fitted yet; call fit first")
        if goal is None:
            return dict(self.default_goal_)
        checked = check_goal(goal, self.inputs_)
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

        The keyword arguments are those of :func:`behavior_hmm.runtime.run_behavior`
        (``fault_hold_s``: seconds a non-finite reading on an input is held).
        """
        controller = _BCController(self, self.resolve_goal(goal))
        return run_controller(
            controller,
            env,
            start=start,
            seed=seed,
            noise=noise,
            max_steps=int(max_steps or self.max_steps_),
            pushes=pushes,
            fault_hold_s=fault_hold_s,
            read_channels=channels_read(self),
        )


class _BCController:
    def __init__(self, model: BehaviorCloning, goal: dict[str, float]) -> None:
        self.goal = goal
        self._model = model
        self._idx = [SENSOR_CHANNELS.index(c) for c in model.inputs_]
        self._channels = model.inputs_
        self._pipe = model.pipeline_.online()
        norm = model.pipeline_.normalizer
        self._lo = np.asarray(norm._lo, dtype=np.float64)
        self._gain = np.asarray(norm._gain, dtype=np.float64)
        goal_norm = [
            (goal[c] - self._lo[model.inputs_.index(c)]) * self._gain[model.inputs_.index(c)] - 1
            for c in model.goal_channels_
        ]
        self._goal_norm = np.asarray(goal_norm, dtype=np.float64)
        self._window = int(model.window)
        self._history = int(model.command_history)
        self._clock = int(model.onset_clock)
        n_ch = len(self._idx)
        self._buf = np.zeros((n_ch, self._window))
        width = n_ch * self._window + len(goal_norm) + 2 * self._history
        self._feat = np.zeros(width + (1 if self._clock else 0))
        self._started = False
        self._k = 0

    def reset(self) -> None:
        self._pipe.reset()
        self._started = False
        self._feat[:] = 0.0
        self._k = 0

    def step(self, reading: FloatArray) -> StepOutput:
        x = self._pipe.step(reading[self._idx])
        if not self._started:
            self._buf[:] = x[:, None]
            self._started = True
        else:
            self._buf[:, :-1] = self._buf[:, 1:]
            self._buf[:, -1] = x
        filtered = (x + 1.0) / self._gain + self._lo
        values = dict(zip(self._channels, filtered.tolist(), strict=True))
        if within_tolerance(values, self.goal):
            return StepOutput(_ZERO, -1, False, 0, "bc", False, True)
        n = self._buf.size
        g = len(self._goal_norm)
        self._feat[:n] = self._buf.ravel()
        self._feat[n : n + g] = self._goal_norm
        if self._clock:
            self._feat[-1] = min(self._k, self._clock) / self._clock
        self._k += 1
        y = self._model.network_.predict_one(self._feat, 0)
        if self._history:
            hist = self._feat[n + g : n + g + 2 * self._history]
            hist[:-2] = hist[2:]
            hist[-2:] = y
        return StepOutput(y * self._model.command_scale_, -1, False, 0, "bc", False, False)
