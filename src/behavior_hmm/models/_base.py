"""What SBLM and CBLM share: parameters, the fitted check and goal observations."""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Self

import numpy as np
from numpy.typing import NDArray

from behavior_hmm._estimator import Estimator
from behavior_hmm.data import SignalPipeline
from behavior_hmm.data._channels import (
    CHANNELS,
    COMMAND_CHANNELS,
    CONTROL_PERIOD,
    SENSOR_CHANNELS,
    ChannelSpec,
    channel,
    channel_from_metadata,
    command_from_declaration,
    known_or_declared,
)
from behavior_hmm.errors import ConfigError, ModelFileError, NotFittedError
from behavior_hmm.models import _modelfile
from behavior_hmm.models._goals import (
    best_goal_category,
    check_goal,
    goal_candidates,
    goal_fallbacks,
)
from behavior_hmm.runtime import Policy, Trace


class LearnedBehavior(Estimator):
    """Base of the learned behaviors: scikit-learn parameters and goal observations.

    Subclasses set, when fitted, ``inputs_``, ``pipeline_``, ``observations_`` (a
    CobART), ``hmm_``, ``rest_values_`` and ``default_goal_``; ``channels_`` (the
    declaration of every input channel: unit, range, goal tolerance, wrap) comes from
    the training data and travels in the model file, so a model trained on a robot's
    own channels knows their tolerances wherever it is loaded.
    """

    inputs_: tuple[str, ...]
    channels_: dict[str, ChannelSpec]
    command_specs_: tuple[ChannelSpec, ...]
    command_scales_: NDArray[np.float64]
    pipeline_: Any
    observations_: Any
    hmm_: Any
    rest_values_: dict[str, float]

    train_data_: str | None
    behavior_: str
    updates_: list[dict[str, Any]]

    kind = "model"
    #: ``behavior_`` of demonstrations that do not name theirs
    _unnamed = "behavior"

    # ----------------------------------------------------------------- fit
    def fit(self, dataset: Any) -> Self:
        """Learn the behavior from demonstrations: the sequence both kinds share.

        1. Check the parameters and pick the inputs among the dataset's channels
           (:meth:`_fit_setup`; a CBLM also checks its components).
        2. Choose the rows to learn from (:meth:`_fit_rows`: an SBLM's nominal and
           corrective demonstrations, a CBLM's rows tagged with their component).
        3. Filter and normalize the inputs (``pipeline_``).
        4. Learn the kind's own tables (:meth:`_fit_learn`: an SBLM's primitives,
           observations, Behavior-HMM and generators; a CBLM's observations and
           Behavior-HMM between its components) and the commands' scales.
        5. Record what both keep: ``inputs_``, ``rest_values_`` (the median final
           reading of each input), ``behavior_``, the provenance and the inputs'
           declarations (``channels_``); no updates yet, no training data file.
        6. Finish (:meth:`_fit_finish`: the default goal, the step limit, ...).

        Parameters
        ----------
        dataset
            A :class:`~behavior_hmm.data.Dataset` of demonstrations (every episode from
            rest to the goal; a complex behavior's rows tagged with their component).

        Returns
        -------
        self
        """
        from behavior_hmm.data import Dataset

        inputs, context = self._fit_setup(dataset)
        if not isinstance(dataset, Dataset):
            raise ConfigError(f"fit expects a behavior_hmm.data.Dataset, got {type(dataset)}")
        dataset = self._as_learned(dataset)
        dataset, context = self._fit_rows(dataset, inputs, context)
        pipeline = SignalPipeline.for_dataset(dataset, inputs, getattr(self, "cutoff_hz", None))
        x = pipeline.transform(dataset)
        self._fit_learn(dataset, x, inputs, pipeline, context)
        raw = dataset.columns(inputs)
        finals = dataset.offsets[1:] - 1
        self.inputs_ = inputs
        self.pipeline_ = pipeline
        self.rest_values_ = {c: float(np.median(raw[finals, j])) for j, c in enumerate(inputs)}
        self.train_data_ = None  # set by the command line to the data file
        self.behavior_ = str(dataset.metadata.get("behavior", self._unnamed))
        self.updates_ = []  # partial_fit's or add_component's records
        self._record_provenance(dataset)  # and channels_, the inputs' declarations
        self._fit_finish(dataset, x, inputs, raw, finals, context)
        return self

    def _as_learned(self, dataset: Any) -> Any:
        """The demonstrations as the model learns from them: with each one's mirror image
        after it where ``mirror`` is set (:func:`behavior_hmm.data.mirrored`)."""
        if not getattr(self, "mirror", False):
            return dataset
        from behavior_hmm.data import mirrored

        return mirrored(dataset)

    def _fit_setup(self, dataset: Any) -> tuple[tuple[str, ...], Any]:
        """Fit step 1: check the parameters; the inputs and what later steps need."""
        raise NotImplementedError

    def _fit_rows(self, dataset: Any, inputs: tuple[str, ...], context: Any) -> tuple[Any, Any]:
        """Fit step 2: the demonstrations (rows) to learn from, and the context."""
        raise NotImplementedError

    def _fit_learn(
        self, dataset: Any, x: Any, inputs: tuple[str, ...], pipeline: Any, context: Any
    ) -> None:
        """Fit step 4: the kind's own tables from the filtered, normalized inputs ``x``."""
        raise NotImplementedError

    def _fit_finish(
        self, dataset: Any, x: Any, inputs: tuple[str, ...], raw: Any, finals: Any, context: Any
    ) -> None:
        """Fit step 6: what the kind derives once the common state is set."""
        raise NotImplementedError

    @classmethod
    def from_preset(cls, preset: str = "default", /, **params: Any) -> Any:
        """A new unfitted model with ``preset``'s parameters, ``params`` applied on top.

        ``SBLM.from_preset("thesis", inputs=("angle",))`` is the thesis's SBLM;
        see :func:`behavior_hmm.models.preset_params` and docs/algorithms.md.
        """
        from behavior_hmm.models._presets import preset_params

        return cls(**{**preset_params(preset, cls.kind), **params})

    # parameters both kinds share (set by the subclasses' constructors)
    counting: str
    smoothing: float
    path_self_loops: str
    command_rate_limit: float
    progress_limit: float
    wheel_calibration: bool

    def check_params(self) -> None:
        """Refuse parameters out of range (ConfigError) before any data is read."""
        if self.counting not in ("changes", "steps"):
            raise ConfigError(f"counting must be 'changes' or 'steps', got {self.counting!r}")
        if self.path_self_loops not in ("drop", "keep"):
            raise ConfigError(
                f"path_self_loops must be 'drop' or 'keep', got {self.path_self_loops!r}"
            )
        mirror = getattr(self, "mirror", False)
        if not isinstance(mirror, bool):
            raise ConfigError(f"mirror must be true or false, got {mirror!r}")
        smoothing = self.smoothing
        if isinstance(smoothing, bool) or not isinstance(smoothing, int | float) or smoothing < 0:
            raise ConfigError(f"smoothing must be a number >= 0, got {smoothing!r}")
        for name, (low, high) in _RANGES.items():
            value = getattr(self, name)
            number = isinstance(value, int | float) and not isinstance(value, bool)
            if not number or not low <= float(value) <= high:
                raise ConfigError(f"{name} must be a number in [{low:g}, {high:g}], got {value!r}")
        if not isinstance(self.wheel_calibration, bool):
            raise ConfigError(
                f"wheel_calibration must be true or false, got {self.wheel_calibration!r}"
            )

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Self:
        """Read a model written by ``save``; everything is validated (components included).

        The file may come from a stranger: see :mod:`behavior_hmm.models._modelfile` for
        the bounds on sizes, nesting and values that every load enforces.

        Raises
        ------
        ModelFileError
            Missing, corrupted, tampered, of another kind or version, inconsistent, or
            beyond a bound; the one-line message starts with ``path``.
        """
        return cls._load(path, str(path), _modelfile.Budget())

    @classmethod
    def _load(
        cls, source: str | os.PathLike[str] | bytes, where: str, budget: _modelfile.Budget
    ) -> Any:
        """:meth:`load` of a file, or of a file's bytes (a CBLM's component) named ``where``."""
        if isinstance(source, bytes):
            header, arrays = _modelfile.loads(source, where, budget)
        else:
            header, arrays = _modelfile.load(source, budget)
        try:
            if header["kind"] != cls.kind:
                raise ModelFileError(f"holds a {header['kind']}, not a {cls.kind}")
            return cls._from_state(header["params"], header["state"], arrays, budget)
        except ModelFileError as err:
            raise _modelfile.refused(where, str(err)) from None
        except (
            ArithmeticError,
            AttributeError,
            LookupError,
            RecursionError,
            TypeError,
            ValueError,
        ) as err:  # a value of the wrong type or range deep inside a part
            reason = f"invalid model contents ({type(err).__name__}: {err})"
            raise _modelfile.refused(where, reason) from None

    @classmethod
    def _from_state(
        cls,
        params: Mapping[str, Any],
        state: Mapping[str, Any],
        arrays: Mapping[str, Any],
        budget: _modelfile.Budget | None = None,
    ) -> Any:
        raise NotImplementedError

    def _restore_common(self, state: Mapping[str, Any], inputs: tuple[str, ...]) -> None:
        """Restore, checked, the learned state both kinds save alike (see their ``save``)."""
        self.command_scale_ = _modelfile.check_number(
            state["command_scale"], "command_scale", positive=True
        )
        self.rest_values_ = _modelfile.check_channel_values(
            state["rest_values"], "rest_values", inputs
        )
        self.channels_ = _restore_channels(state.get("channels"), inputs)
        goal = _modelfile.check_channel_values(
            state["default_goal"], "default_goal", inputs, all_channels=False
        )
        self.default_goal_ = check_goal(goal, inputs, self.channels_)
        self.max_steps_ = _modelfile.check_int(
            state["max_steps"], "max_steps", 1, _modelfile.MAX_STEPS
        )
        self.behavior_ = str(_modelfile.check_text(state["behavior"], "behavior"))
        self.train_data_ = _modelfile.check_text(
            state.get("train_data"), "train_data", optional=True
        )
        self.provenance_ = _check_provenance(state.get("provenance") or {})

    @property
    def command_channels(self) -> tuple[str, ...]:
        """The command channels the model outputs, in action order (default the wheels)."""
        specs = getattr(self, "command_specs_", None)
        return COMMAND_CHANNELS if specs is None else tuple(s.name for s in specs)

    @property
    def rest_command(self) -> NDArray[np.float64]:
        """The command that holds the robot still (each command channel's ``rest``)."""
        specs = getattr(self, "command_specs_", None) or [CHANNELS[c] for c in COMMAND_CHANNELS]
        return np.array([spec.rest for spec in specs], dtype=np.float64)

    def _learn_commands(self, dataset: Any, scales: Any) -> None:
        """The dataset's command channels and each one's normalization scale."""
        specs = getattr(dataset, "command_specs", None)
        self.command_specs_ = (
            tuple(specs) if specs else tuple(CHANNELS[c] for c in COMMAND_CHANNELS)
        )
        k = len(self.command_specs_)
        self.command_scales_ = np.broadcast_to(np.asarray(scales, dtype=np.float64), (k,)).copy()
        # a command the demonstrations never move from rest (a grasp's wheels, a turn's
        # gripper) is held at rest: the generators' small errors never move it
        u = np.asarray(dataset.commands, dtype=np.float64).reshape(-1, k)
        rest = self.rest_command
        self.held_commands_ = tuple(
            spec.name for j, spec in enumerate(self.command_specs_) if np.all(u[:, j] == rest[j])
        )

    @property
    def held_mask(self) -> NDArray[np.bool_]:
        """Per command channel, whether it is held at rest (``held_commands_``)."""
        held = set(getattr(self, "held_commands_", ()))
        return np.array([c in held for c in self.command_channels], dtype=bool)

    def _commands_state(self) -> dict[str, Any]:
        """The command channels and scales as the model file stores them."""
        state: dict[str, Any] = {
            "commands": [spec.to_metadata() for spec in self.command_specs_],
            "command_scales": [float(v) for v in self.command_scales_],
        }
        held = getattr(self, "held_commands_", ())
        if held:  # files of models that move every command stay as they were
            state["held_commands"] = list(held)
        return state

    def _restore_commands(self, state: Mapping[str, Any]) -> None:
        """The command channels and scales of a model file (older files: the wheels)."""
        entries = state.get("commands")
        if entries is None:
            self.command_specs_ = tuple(CHANNELS[c] for c in COMMAND_CHANNELS)
        else:
            if not isinstance(entries, list) or not 1 <= len(entries) <= 64:
                raise ModelFileError("commands must list 1 to 64 command channels")
            specs = []
            for entry in entries:
                if not isinstance(entry, Mapping):
                    raise ModelFileError("commands: each entry must be a declaration")
                try:
                    specs.append(command_from_declaration(entry))
                except ConfigError as err:
                    raise ModelFileError(f"commands: {err}") from None
            if len({s.name for s in specs}) != len(specs):
                raise ModelFileError("commands: a channel is listed twice")
            self.command_specs_ = tuple(specs)
        k = len(self.command_specs_)
        scale = _modelfile.check_number(state["command_scale"], "command_scale", positive=True)
        scales = state.get("command_scales", [scale] * k)
        if not isinstance(scales, list) or len(scales) != k:
            raise ModelFileError("command_scales must hold one scale per command channel")
        self.command_scales_ = np.array(
            [_modelfile.check_number(v, "command_scales", positive=True) for v in scales]
        )
        held = state.get("held_commands", [])
        names = [spec.name for spec in self.command_specs_]
        if not isinstance(held, list) or any(c not in names for c in held):
            raise ModelFileError("held_commands must list command channels of the model")
        self.held_commands_ = tuple(str(c) for c in held)

    def _check_same_robot(self, dataset: Any, inputs: tuple[str, ...], owner: str) -> None:
        """Refuse (ConfigError) new demonstrations of another robot than the fitted one:
        inputs or commands declared differently, another control period, other
        normalization ranges, or another env when both name one. ``owner`` names the
        model in the messages (``"model's"``, ``"CBLM's"``)."""
        specs = {spec.name: spec for spec in getattr(dataset, "channel_specs", ())}
        for c in inputs:
            new = (specs.get(c) or channel(c)).to_metadata()
            if new != self.channel_spec(c).to_metadata():
                raise ConfigError(
                    f"input {c!r} is declared differently in the new demonstrations "
                    f"({new}) than in the model ({self.channel_spec(c).to_metadata()})"
                )
        declared = getattr(dataset, "command_specs", None) or [
            CHANNELS[c] for c in COMMAND_CHANNELS
        ]
        theirs = [spec.to_metadata() for spec in declared]
        mine = [spec.to_metadata() for spec in self.command_specs_]
        if theirs != mine:
            names = ",".join(str(s["name"]) for s in theirs)
            raise ConfigError(
                f"the new demonstrations' commands ({names}) differ from the {owner} "
                f"({','.join(self.command_channels)}) or are declared differently"
            )
        fitted = self.pipeline_
        pipeline = SignalPipeline.for_dataset(dataset, inputs, fitted.cutoff_hz)
        if not math.isclose(pipeline.fs, fitted.fs, rel_tol=1e-9):
            raise ConfigError(
                f"the new demonstrations' control period is {1000 / pipeline.fs:g} ms, "
                f"the model's {1000 / fitted.fs:g} ms"
            )
        assert pipeline.ranges is not None and fitted.ranges is not None
        for c in inputs:
            if tuple(pipeline.ranges[c]) != tuple(fitted.ranges[c]):
                raise ConfigError(
                    f"the new demonstrations' range of {c} is {list(pipeline.ranges[c])}, the "
                    f"model's {list(fitted.ranges[c])}: another robot"
                )
        env = dataset.metadata.get("env") or dataset.metadata.get("simulator")
        mine_env = self.provenance_.get("env", "unknown")
        if env and mine_env != "unknown" and str(env) != mine_env:
            raise ConfigError(
                f"the new demonstrations come from {env!r}, the model's from {mine_env!r}"
            )

    def channel_spec(self, name: str) -> ChannelSpec:
        """The declaration of the input channel ``name`` (the model's own, else the registry's)."""
        own = getattr(self, "channels_", None) or {}
        return own[name] if name in own else channel(name)

    def _channels_state(self) -> list[dict[str, Any]]:
        """The input channels' declarations as the model file stores them."""
        return [self.channel_spec(c).to_metadata() for c in self.inputs_]

    def _record_provenance(self, dataset: Any) -> None:
        """Where the training data came from: robot, control period, package, data hash;
        and the declaration of each input channel (``channels_``, from the dataset)."""
        from behavior_hmm import __version__

        declared = {spec.name: spec for spec in getattr(dataset, "channel_specs", ())}
        self.channels_ = {c: declared.get(c) or channel(c) for c in self.inputs_}

        meta = dataset.metadata
        period = meta.get("control_period")
        self.provenance_ = {
            "env": str(meta.get("env") or meta.get("simulator") or "unknown"),
            "control_period": float(period) if period is not None else CONTROL_PERIOD,
            "package_version": __version__,
            "dataset_sha256": dataset_hash(dataset),
        }

    def set_training_data(self, path: str | os.PathLike[str]) -> None:
        """Record the training data file: as given and as an absolute path."""
        self.train_data_ = str(path)
        self.provenance_ = {
            **getattr(self, "provenance_", {}),
            "train_data": str(path),
            "train_data_absolute": str(Path(path).resolve()),
        }

    def generate(
        self,
        env: Any,
        start: Mapping[str, float] | None = None,
        goal: Mapping[str, float] | None = None,
        **kwargs: Any,
    ) -> Trace:
        """Perform the behavior in ``env`` from ``start`` to ``goal`` (closed loop).

        ``env`` is any Gymnasium env that meets the robot contract (docs/robots.md); see
        :func:`behavior_hmm.models.perform` for the keyword arguments.
        """
        from behavior_hmm.models._policy import perform

        return perform(self, env, start=start, goal=goal, **kwargs)

    def policy(
        self, goal: Mapping[str, float] | None = None, *, name: str = "", tolerance: float = 1.0
    ) -> Policy:
        """The behavior's policy toward ``goal`` (``None``: the default goal).

        Call ``reset()`` before a run and ``step({channel: value})`` once per control
        period (see :class:`behavior_hmm.runtime.Policy`); no simulator is needed, so a
        robot's own control loop can drive it (docs/robots.md). ``name`` is recorded as
        the component's name in traces; ``tolerance`` scales the goal's tolerance.
        """
        from behavior_hmm.models._policy import make_policy

        self._check_fitted()
        policy: Policy = make_policy(self, goal, name=name, tolerance=tolerance)
        return policy

    def _check_fitted(self) -> None:
        if not hasattr(self, "hmm_"):
            raise NotFittedError(f"this {type(self).__name__} is not fitted yet; call fit first")

    def goal_window(self, goal: Mapping[str, float]) -> NDArray[np.float64]:
        """A still observation window at ``goal`` (normalized), other inputs at rest."""
        self._check_fitted()
        values = [goal.get(c, self.rest_values_[c]) for c in self.inputs_]
        reading = self.pipeline_.normalizer.transform(np.asarray([values], dtype=np.float64))
        return np.repeat(reading, int(self.observations_.window), axis=0)

    def goal_category(self, goal: Mapping[str, float]) -> int:
        """Observation category of a still window at ``goal`` (thesis Algorithm 1, o_g)."""
        self._check_fitted()
        scores = self.observations_.score_window(self.goal_window(goal))
        return best_goal_category(scores, self.hmm_.C_counts_)

    def goal_categories(self, goal: Mapping[str, float], limit: int = 64) -> NDArray[np.int64]:
        """Candidate goal categories, best match first (see :func:`goal_candidates`).

        The controllers plan to the first candidate that is reachable from where the
        robot is: with fine categories, several categories describe being at the goal
        (reached from different sides), and the best match may lie on another branch.
        """
        window, latest, at_goal = self._goal_readings(goal)
        scores = self.observations_.score_window(window)
        return goal_candidates(scores, self.hmm_.C_counts_, latest, at_goal, limit)

    def goal_fallback_categories(
        self, goal: Mapping[str, float], current: int, limit: int = 64
    ) -> NDArray[np.int64]:
        """Categories near the goal, and nearer to it than category ``current``, a simple
        behavior plans to when no goal category is reachable from ``current``, nearest
        first (see :func:`goal_fallbacks`)."""
        _, latest, at_goal = self._goal_readings(goal)
        return goal_fallbacks(self.hmm_.C_counts_, latest, at_goal, current, limit)

    def _goal_readings(
        self, goal: Mapping[str, float]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The still window at ``goal``, every prototype's latest reading on the goal's
        channels and the goal on them (normalized)."""
        window = self.goal_window(goal)
        columns = [self.inputs_.index(c) for c in goal]
        latest = self.observations_.prototypes_[:, -1, :][:, columns]
        return window, latest, window[-1, columns]


#: Default ``progress_limit`` of SBLMs and CBLMs: a run that still closes in on its goal at
#: its step limit may go on up to 4 times as long (a robot 4 times slower than its
#: demonstrations: the approach's 3.9 rad/s wheels held to 1 rad/s). The thesis: 1.
DEFAULT_PROGRESS_LIMIT = 4.0


#: Parameters both kinds share that are a number in a closed range: ``command_rate_limit``
#: (multiples of the demonstrations' largest command change per cycle) and
#: ``progress_limit`` (multiples of the model's ``max_steps_``).
_RANGES: dict[str, tuple[float, float]] = {
    "command_rate_limit": (0.0, 100.0),
    "progress_limit": (1.0, 10.0),
}


#: The keys a model file's provenance may hold (text unless said otherwise).
PROVENANCE_KEYS = (
    "env",
    "control_period",
    "package_version",
    "dataset_sha256",
    "train_data",
    "train_data_absolute",
    "inputs_selection",  # train simple --inputs auto: the choice's reason (issue 30)
)


def dataset_hash(dataset: Any) -> str:
    """SHA-256 of a dataset's arrays and metadata (the same data gives the same hash)."""
    digest = hashlib.sha256()
    commands = getattr(dataset, "command_channels", COMMAND_CHANNELS)
    for name in ("t", *getattr(dataset, "sensor_channels", SENSOR_CHANNELS), *commands):
        digest.update(name.encode())
        digest.update(np.ascontiguousarray(dataset.columns([name])).tobytes())
    digest.update(np.ascontiguousarray(dataset.lengths, dtype=np.int64).tobytes())
    digest.update(json.dumps(dataset.metadata, sort_keys=True, default=str).encode())
    return digest.hexdigest()


def _restore_channels(value: Any, inputs: tuple[str, ...]) -> dict[str, ChannelSpec]:
    """The input channels' declarations of a model file (older files have none: the
    registry's). A declaration equal to a known channel's is that channel (with its
    import units and bounds)."""
    if value is None:
        return {c: CHANNELS[c] for c in inputs if c in CHANNELS}
    if not isinstance(value, list) or len(value) != len(inputs):
        raise ModelFileError("channels must list one declaration per input")
    out: dict[str, ChannelSpec] = {}
    for name, entry in zip(inputs, value, strict=True):
        try:
            spec = channel_from_metadata(entry)
        except ConfigError as err:
            raise ModelFileError(f"channels: {err}") from None
        if spec.name != name or spec.kind != "sensor":
            raise ModelFileError(f"channels: declaration {spec.name!r} does not match {name!r}")
        out[name] = known_or_declared(spec)
    return out


def _check_provenance(value: Any) -> dict[str, Any]:
    if not isinstance(value, Mapping):
        raise ModelFileError("provenance must be a mapping")
    out: dict[str, Any] = {}
    for key, item in value.items():
        if key not in PROVENANCE_KEYS:
            raise ModelFileError(f"unknown provenance key {key!r}")
        if key == "control_period":
            out[key] = _modelfile.check_number(item, "provenance control_period", positive=True)
        else:
            out[key] = _modelfile.check_text(item, f"provenance {key}")
    return out
