"""The two presets (DESIGN §10): declared once, documented, selectable from Python."""

from __future__ import annotations

import ast
import inspect
import re
from pathlib import Path

import pytest

from behavior_hmm.errors import ConfigError
from behavior_hmm.models import CBLM, DEPARTURES, PRESETS, SBLM, describe_params, preset_params
from behavior_hmm.models._presets import constructor_defaults

DOC = Path(__file__).resolve().parents[2] / "docs" / "algorithms.md"
ROW = re.compile(r"^\| (SBLM|CBLM) \| `(\w+)` \| `([^`]*)` \| `([^`]*)` \| (\w*) \|")


def _documented() -> dict[str, dict[str, dict[str, object]]]:
    """{preset: {kind: {param: value}}} from the presets table of docs/algorithms.md."""
    table: dict[str, dict[str, dict[str, object]]] = {p: {"SBLM": {}, "CBLM": {}} for p in PRESETS}
    for line in DOC.read_text(encoding="utf-8").splitlines():
        match = ROW.match(line)
        if match:
            kind, name, thesis, default, _ = match.groups()
            table["thesis"][kind][name] = ast.literal_eval(thesis)
            table["default"][kind][name] = ast.literal_eval(default)
    return table


@pytest.mark.parametrize("preset", PRESETS)
@pytest.mark.parametrize("kind", ["SBLM", "CBLM"])
def test_each_preset_equals_the_documented_table(preset: str, kind: str) -> None:
    assert preset_params(preset, kind) == _documented()[preset][kind]


def test_documented_departure_names_match_the_code() -> None:
    named = set()
    for line in DOC.read_text(encoding="utf-8").splitlines():
        match = ROW.match(line)
        if match and match.group(5):
            named.add(match.group(5))
    assert named == {d.name for d in DEPARTURES}


def test_default_preset_is_the_constructor_defaults() -> None:
    for cls in (SBLM, CBLM):
        signature = inspect.signature(cls.__init__)
        for name, value in preset_params("default", cls.kind).items():
            assert signature.parameters[name].default == value


def test_every_departure_departs_and_names_real_parameters() -> None:
    names = [d.name for d in DEPARTURES]
    assert len(set(names)) == len(names)
    for item in DEPARTURES:
        for kind, params in item.thesis.items():
            defaults = constructor_defaults(kind)
            for param, thesis in params.items():
                assert param in defaults, (item.name, param)
                assert thesis != defaults[param], f"{item.name}: thesis == default"


def test_the_issue_s_additions_are_all_departures() -> None:
    # the additions the thesis does not have (issue: thesis mode) are each switchable
    wanted = {
        "onset_clock", "primitive_recognition", "window_noise", "segment_margin", "dcm_floor",
        "stop_at_rest", "batch_size", "repair", "preempt_uncovered", "switch_cycles",
        "start_alternatives", "counting", "observation_vigilance",
    }  # fmt: skip
    assert wanted <= {d.name for d in DEPARTURES}


def test_switching_one_departure() -> None:
    thesis = preset_params("thesis", "SBLM")
    plus = preset_params("thesis", "SBLM", switch=["onset_clock"])
    assert plus == {**thesis, "onset_clock": 96}
    minus = preset_params("default", "CBLM", switch=["switch_cycles"])
    assert minus == {**preset_params("default", "CBLM"), "switch_cycles": 1}
    # a departure of the other kind leaves the model untouched
    assert preset_params("thesis", "CBLM", switch=["onset_clock"]) == preset_params(
        "thesis", "CBLM"
    )


def test_unknown_preset_and_departure_are_refused() -> None:
    with pytest.raises(ConfigError, match="unknown preset 'thes'"):
        preset_params("thes", "SBLM")
    with pytest.raises(ConfigError, match="did you mean 'onset_clock'"):
        preset_params("thesis", "SBLM", switch=["onset_clok"])


def test_from_preset_and_describe() -> None:
    model = SBLM.from_preset("thesis", inputs=("angle",), onset_clock=96)
    assert model.batch_size == 1 and model.onset_clock == 96 and model.inputs == ("angle",)
    assert describe_params("SBLM", model.get_params()) == "thesis + onset_clock=96"
    assert describe_params("SBLM", SBLM().get_params()) == "default"
    cblm = CBLM.from_preset("thesis")
    assert (cblm.repair, cblm.switch_cycles, cblm.observation_vigilance) == (False, 1, 0.95)
    assert describe_params("CBLM", cblm.get_params()) == "thesis"


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"switch_cycles": 0}, "switch_cycles"),
        ({"start_alternatives": -1}, "start_alternatives"),
        ({"repair": "yes"}, "repair"),
        ({"observation_vigilance": 1.5}, "observation_vigilance"),
        ({"counting": "sometimes"}, "counting"),
        ({"path_self_loops": "maybe"}, "path_self_loops"),
    ],
)
def test_cblm_parameters_are_checked(params: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        CBLM(**params).check_params()  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"batch_size": 0}, "batch_size"),
        ({"stop_at_rest": 1}, "stop_at_rest"),
        ({"state_decoding": "oracle"}, "state_decoding"),
    ],
)
def test_sblm_parameters_are_checked(params: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        SBLM(**params).check_params()  # type: ignore[arg-type]


def test_every_option_is_off_in_both_presets_and_names_real_parameters() -> None:
    from behavior_hmm.models import OPTIONS
    from behavior_hmm.models._presets import check_row_name, option

    assert [o.name for o in OPTIONS] == [
        "elman",
        "shared_init",
        "recover",
        "auto_inputs",
    ]
    for item in OPTIONS:
        assert option(item.name) is item and check_row_name(item.name) == item.name
        assert not {item.name} & {d.name for d in DEPARTURES}
        for kind, params in item.params.items():
            for preset in PRESETS:
                current = preset_params(preset, kind)
                for param, value in params.items():
                    if param == "inputs":  # a task's, never a preset's: hand-picked there
                        assert param not in current and value == "auto"
                        continue
                    assert param in current and current[param] != value
        for name in item.paired:
            assert check_row_name(name) == name
    with pytest.raises(ConfigError, match="unknown option 'gru'"):
        option("gru")
