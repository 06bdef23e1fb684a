"""The two presets: the thesis as published, and ours (DESIGN §10).

Every departure of the ``default`` preset from the thesis is declared once, here, as a
:class:`Departure`: its name (the row label of ``experiment ablation``), the constructor
parameters it sets and their thesis values. The ``default`` value of each parameter is
the constructor default of its class (read from the signature, never repeated), so:

- ``preset_params("default", "SBLM")`` are the SBLM's constructor defaults;
- ``preset_params("thesis", "SBLM")`` are the same with every departure at its thesis value;
- ``experiment ablation`` switches departures on and off one at a time.

Where the thesis is silent, its value here is the plainest reading (docs/algorithms.md,
"The two presets", lists each such reading).
"""

from __future__ import annotations

import inspect
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Final

from behavior_hmm.data import DEFAULT_CUTOFF_HZ
from behavior_hmm.errors import ConfigError
from behavior_hmm.generators._features import DEFAULT_ONSET_CLOCK
from behavior_hmm.generators._motion import DEFAULT_GENERATOR_EPOCHS
from behavior_hmm.models._goals import AUTO_INPUTS

#: Preset names, thesis first.
PRESETS: Final[tuple[str, ...]] = ("thesis", "default")

#: Model kinds a preset configures.
KINDS: Final[tuple[str, ...]] = ("SBLM", "CBLM")

#: Constructor parameters a preset or a config file never sets (they have their own options).
NOT_PRESET: Final[frozenset[str]] = frozenset({"inputs", "components", "random_state"})


@dataclass(frozen=True)
class Departure:
    """One named departure of the default preset from the thesis.

    Parameters
    ----------
    name
        Row label in the ablation table.
    thesis
        ``{kind: {parameter: thesis value}}``; the default value is the constructor's.
    summary
        What the default does differently, in a few words.
    """

    name: str
    thesis: Mapping[str, Mapping[str, Any]]
    summary: str

    @property
    def kinds(self) -> tuple[str, ...]:
        """Model kinds this departure touches."""
        return tuple(self.thesis)

    def value(self, preset: str, kind: str, param: str) -> Any:
        """The parameter's value in ``preset`` (``"thesis"`` or ``"default"``)."""
        if preset == "thesis":
            return self.thesis[kind][param]
        return constructor_defaults(kind)[param]


#: Every departure of ``default`` from the thesis, SBLM first (order of the ablation rows).
DEPARTURES: Final[tuple[Departure, ...]] = (
    Departure(
        "cutoff_hz",
        {"SBLM": {"cutoff_hz": 4.0}, "CBLM": {"cutoff_hz": 4.0}},
        f"low-pass cut-off {DEFAULT_CUTOFF_HZ:g} Hz (the thesis gives none; its preset: 4 Hz)",
    ),
    Departure(
        "onset_clock",
        {"SBLM": {"onset_clock": 0}},
        f"generators also read the time since the start, min(t, {DEFAULT_ONSET_CLOCK})"
        f"/{DEFAULT_ONSET_CLOCK}",
    ),
    Departure(
        "primitive_recognition",
        {"SBLM": {"primitive_recognition": False}},
        "run the primitive CobART recognizes live, among those the plan allows",
    ),
    Departure(
        "state_decoding",
        {"SBLM": {"state_decoding": "plan"}},
        "decode with the forward message of the run so far, not the prior π",
    ),
    Departure(
        "window_noise",
        {"SBLM": {"window_noise": 0.0}},
        "window-shift training: a copy of the rows with a Gaussian offset per channel",
    ),
    Departure(
        "segment_margin",
        {"SBLM": {"segment_margin": 0}},
        "each generator also trains on 10 rows either side of its segments",
    ),
    Departure(
        "dcm_floor",
        {"SBLM": {"dcm_floor": 0.0}},
        "automatic DCM scale at least 0.3 × the largest channel's",
    ),
    Departure(
        "stop_at_rest",
        {"SBLM": {"stop_at_rest": False}},
        "the stop rule also waits until the robot is at rest; noisy readings confirm a goal there",
    ),
    Departure(
        "batch_size",
        {"SBLM": {"batch_size": 1}},
        "minibatches of 32 (thesis: incremental, one update per sample)",
    ),
    Departure(
        "epochs",
        {"SBLM": {"epochs": 200}},
        f"{DEFAULT_GENERATOR_EPOCHS} training epochs per generator"
        " (the thesis gives none; its preset: 200)",
    ),
    Departure(
        "hidden",
        {"SBLM": {"hidden": None}},
        "5 hidden units for any input set (thesis: 5/10/15 for 1/2/3 channels)",
    ),
    Departure(
        "command_rate_limit",
        {"SBLM": {"command_rate_limit": 0.0}, "CBLM": {"command_rate_limit": 0.0}},
        "command change per cycle at most 1.5 × the demonstrations' largest; soft stop",
    ),
    Departure(
        "goal_braking",
        {"SBLM": {"goal_braking": False}},
        "ramp to rest at the rate limit where the ramp ends at the goal, not arrive at speed",
    ),
    Departure(
        "learn_corrections",
        {"SBLM": {"learn_corrections": False}},
        "generators also learn from runs where the teacher corrects a disturbed heading",
    ),
    Departure(
        "progress_limit",
        {"SBLM": {"progress_limit": 1.0}, "CBLM": {"progress_limit": 1.0}},
        "a run still closing in on its goal at its step limit goes on (up to 4× as long)",
    ),
    Departure(
        "path_self_loops",
        {"SBLM": {"path_self_loops": "keep"}, "CBLM": {"path_self_loops": "keep"}},
        "plan on c_ij / (1 − c_ii), the next different category (thesis: −log c_ij)",
    ),
    Departure(
        "goal_fallback",
        {"SBLM": {"goal_fallback": False}},
        "a goal no candidate category is reachable from is planned to the nearest "
        "reachable category near it (within 12 cm / 36°)",
    ),
    Departure(
        "start_envelope",
        {"SBLM": {"start_envelope": False}},
        "a run from rest leaves rest no faster than any demonstration had by the same "
        "cycle (the demonstrations' start-up envelope)",
    ),
    Departure(
        "onset_floor",
        {"SBLM": {"onset_floor": False}},
        "each primitive's network reads the onset clock no earlier than its own training "
        "rows began",
    ),
    Departure(
        "input_range",
        {"SBLM": {"input_range": False}},
        "a run that starts beyond the demonstrations reads each input clipped to the range "
        "its primitive's rows held, until the input has been inside all the rows' range; "
        "one from rest closer to the goal than every demonstrated start reads as the "
        "nearest start-up its rows held",
    ),
    Departure(
        "observation_vigilance",
        {"CBLM": {"observation_vigilance": 0.95}},
        "CBLM observation categories at ρ 0.99 (thesis: 0.95)",
    ),
    Departure(
        "counting",
        {"CBLM": {"counting": "changes"}},
        'CBLM counts every control cycle ("steps"; thesis: state changes)',
    ),
    Departure(
        "repair",
        {"CBLM": {"repair": False}},
        "when the plan is exhausted short of the goal, run a component that closes the gap",
    ),
    Departure(
        "preempt_uncovered",
        {"CBLM": {"preempt_uncovered": False}},
        "a gap no planned component can close is closed first",
    ),
    Departure(
        "switch_cycles",
        {"CBLM": {"switch_cycles": 1}},
        "a running component is replaced only after the plan insists for 8 cycles",
    ),
    Departure(
        "skip_reached",
        {"CBLM": {"skip_reached": False}},
        "a running component is not replaced by one whose goal already holds",
    ),
    Departure(
        "settle_cycles",
        {"CBLM": {"settle_cycles": 0}},
        "at the goal, a component heading for a goal inside it finishes at rest (≤ 64 cycles)",
    ),
    Departure(
        "forward_goals",
        {"CBLM": {"forward_goals": False}},
        "an intermediate goal never sends a channel back, away from the complex goal",
    ),
    Departure(
        "handover_pause",
        {"CBLM": {"handover_pause": False}},
        "after a component ends at rest, wait as long as the teacher rests at a switch",
    ),
    Departure(
        "reach_check",
        {"CBLM": {"reach_check": False}},
        "a component starts only near where its demonstrations start it (grasp: object close)",
    ),
    Departure(
        "parallel",
        {"CBLM": {"parallel": False}},
        "where the demonstrations ran two components at once, run them at once",
    ),
    Departure(
        "start_alternatives",
        {"CBLM": {"start_alternatives": 0}},
        "an unplannable start category tries up to 5 runner-up categories that lead to the goal",
    ),
    Departure(
        "wheel_calibration",
        {"SBLM": {"wheel_calibration": False}, "CBLM": {"wheel_calibration": False}},
        "each wheel's gain estimated on line from the measured speed and yaw rate; the "
        "wheels' difference beyond its noise divided out of the commands",
    ),
)


@dataclass(frozen=True)
class Option:
    """An option the default preset leaves at the thesis's value, measured beside it.

    Thesis §7.2's future work, built as parameters: ``experiment ablation`` scores each
    as a ``default + name`` row (and ``default − d + name`` for each departure ``d`` in
    ``paired``), so it becomes the default only where it measures better.

    Parameters
    ----------
    name
        Row label in the ablation table.
    params
        ``{kind: {parameter: value}}`` the option sets.
    summary
        What it does, in a few words.
    paired
        Departures also switched off beside it in a row of their own.
    """

    name: str
    params: Mapping[str, Mapping[str, Any]]
    summary: str
    paired: tuple[str, ...] = ()

    @property
    def kinds(self) -> tuple[str, ...]:
        """Model kinds this option touches."""
        return tuple(self.params)


#: The measured options that are not the default (ablation rows ``default + name``).
OPTIONS: Final[tuple[Option, ...]] = (
    Option(
        "elman",
        {"SBLM": {"generator_network": "elman"}},
        "recurrent Elman generators trained by backpropagation through time (thesis 3.4.3)",
        paired=("onset_clock",),
    ),
    Option(
        "shared_init",
        {"SBLM": {"generator_init": "shared"}},
        "each primitive's generator starts from one network trained on all its rows",
    ),
    Option(
        "recover",
        {"SBLM": {"recover": True}},
        "a run that leaves the demonstrations is steered back to the nearest observation "
        "category's prototype",
    ),
    Option(
        "auto_inputs",
        {"SBLM": {"inputs": AUTO_INPUTS}},
        "each simple behavior's input channels chosen from its demonstrations "
        "(select_inputs; thesis 7.2's feature selection); a CBLM keeps its task's inputs",
    ),
)


def option(name: str) -> Option:
    """The option called ``name`` (a did-you-mean error otherwise)."""
    for item in OPTIONS:
        if item.name == name:
            return item
    from behavior_hmm.models._config import did_you_mean

    raise ConfigError(f"unknown option {name!r}{did_you_mean(name, [o.name for o in OPTIONS])}")


def check_row_name(name: str) -> str:
    """``name`` if it names a departure or an option (the ablation's rows), else an error."""
    if any(item.name == name for item in OPTIONS):
        return name
    known = [d.name for d in DEPARTURES] + [o.name for o in OPTIONS]
    if not any(item.name == name for item in DEPARTURES):
        from behavior_hmm.models._config import did_you_mean

        raise ConfigError(f"unknown departure or option {name!r}{did_you_mean(name, known)}")
    return name


def _model_class(kind: str) -> Any:
    if kind == "SBLM":
        from behavior_hmm.models._sblm import SBLM

        return SBLM
    if kind == "CBLM":
        from behavior_hmm.models._cblm import CBLM

        return CBLM
    raise ConfigError(f"unknown model kind {kind!r}; choose from {', '.join(KINDS)}")


def constructor_defaults(kind: str) -> dict[str, Any]:
    """The constructor defaults of ``kind`` (the ``default`` preset), bar inputs and seed."""
    signature = inspect.signature(_model_class(kind).__init__)
    return {
        name: p.default
        for name, p in signature.parameters.items()
        if name != "self" and name not in NOT_PRESET
    }


def check_preset(preset: str) -> str:
    """``preset`` if it names a preset, else a :class:`ConfigError` listing them."""
    if preset not in PRESETS:
        raise ConfigError(f"unknown preset {preset!r}; choose from {', '.join(PRESETS)}")
    return preset


def departure(name: str) -> Departure:
    """The departure called ``name`` (a did-you-mean error otherwise)."""
    for item in DEPARTURES:
        if item.name == name:
            return item
    from behavior_hmm.models._config import did_you_mean

    raise ConfigError(
        f"unknown departure {name!r}{did_you_mean(name, [d.name for d in DEPARTURES])}"
    )


def preset_params(
    preset: str, kind: str, *, switch: Iterable[str] = (), to: str | None = None
) -> dict[str, Any]:
    """Constructor parameters of ``kind`` in ``preset``.

    Parameters
    ----------
    preset
        ``"thesis"`` or ``"default"``.
    kind
        ``"SBLM"`` or ``"CBLM"``.
    switch
        Names of departures to set to the other preset's value (``to``): the thesis
        plus one addition is ``preset_params("thesis", k, switch=[name])``; the default
        minus one is ``preset_params("default", k, switch=[name])``.
    to
        The preset the switched departures take (default: the other one).
    """
    check_preset(preset)
    params = constructor_defaults(kind)
    if preset == "thesis":
        for item in DEPARTURES:
            params.update(item.thesis.get(kind, {}))
    other = to if to is not None else ("default" if preset == "thesis" else "thesis")
    check_preset(other)
    for name in switch:
        item = departure(name)
        for param in item.thesis.get(kind, {}):
            params[param] = item.value(other, kind, param)
    return params


def describe_params(kind: str, params: Mapping[str, Any]) -> str:
    """Name the preset ``params`` follow: ``"thesis"``, ``"default"``, or the closest one
    with the parameters that differ (``"thesis + batch_size=32"``)."""
    own = {k: _plain(v) for k, v in params.items() if k not in NOT_PRESET}
    best: tuple[int, str, list[str]] | None = None
    for preset in PRESETS:
        reference = {k: _plain(v) for k, v in preset_params(preset, kind).items()}
        differ = [f"{k}={own[k]!r}" for k in reference if k in own and own[k] != reference[k]]
        if best is None or len(differ) < best[0]:
            best = (len(differ), preset, differ)
    assert best is not None
    _, preset, differ = best
    return preset if not differ else f"{preset} + {', '.join(differ)}"


def _plain(value: Any) -> Any:
    """Tuples as lists and mappings as dicts, as a model file stores them."""
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    return value
