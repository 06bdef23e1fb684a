"""Model parameters from a preset, a TOML config and --set assignments."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from behavior_hmm.errors import ConfigError
from behavior_hmm.models import preset_params, read_config, resolve_params
from behavior_hmm.models._config import did_you_mean, parse_sets, parse_value


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("1", 1),
        ("0.5", 0.5),
        ("true", True),
        ("plan", "plan"),
        ('"plan"', "plan"),
        ("[10, 5]", [10, 5]),
        ("none", None),
        ("{ rho = 0.9 }", {"rho": 0.9}),
    ],
)
def test_parse_value(text: str, value: object) -> None:
    assert parse_value(text) == value


def test_parse_sets_refuses_bad_and_repeated_items() -> None:
    assert parse_sets(["batch_size=1", "cblm.repair=false"]) == {
        "batch_size": 1,
        "cblm.repair": False,
    }
    with pytest.raises(ConfigError, match="NAME=VALUE"):
        parse_sets(["batch_size"])
    with pytest.raises(ConfigError, match="twice"):
        parse_sets(["batch_size=1", "batch_size=2"])


def test_precedence_preset_then_config_then_set() -> None:
    name, params = resolve_params(
        ("SBLM", "CBLM"),
        None,
        {"preset": "thesis", "onset_clock": 32, "cblm.switch_cycles": 4},
        {"onset_clock": 16, "counting": "steps"},
    )
    assert name == "thesis"
    assert params["SBLM"] == {
        **preset_params("thesis", "SBLM"),
        "onset_clock": 16,
        "counting": "steps",
    }
    assert params["CBLM"]["switch_cycles"] == 4
    assert params["CBLM"]["counting"] == "steps"  # a shared name applies to both kinds
    # the command line's preset wins over the config's
    assert resolve_params(("SBLM",), "default", {"preset": "thesis"})[0] == "default"


def test_config_file_tables(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text('preset = "thesis"\n[sblm]\nhidden = [10, 5]\n[CBLM]\nrepair = true\n')
    table = read_config(path)
    assert table == {"preset": "thesis", "sblm.hidden": [10, 5], "cblm.repair": True}
    _, params = resolve_params(("SBLM",), None, table)
    assert params["SBLM"]["hidden"] == (10, 5)
    assert params["SBLM"]["batch_size"] == 1


@pytest.mark.parametrize(
    ("config", "sets", "message"),
    [
        ({"batch_sise": 3}, {}, "unknown parameter 'batch_sise'; did you mean 'batch_size'"),
        ({"sblm.onset_clok": 3}, {}, "did you mean 'onset_clock'"),
        ({}, {"batch_size": "many"}, "must be an integer"),
        ({}, {"stop_at_rest": 1}, "true or false"),
        ({}, {"window_noise": float("nan")}, "finite number"),
        ({}, {"hidden": [0]}, "positive integer"),
        ({}, {"onset_clock": None}, "cannot be none"),
        ({}, {"inputs": "angle"}, "--inputs"),
        ({}, {"random_state": 3}, "--seed"),
        ({}, {"repair": False}, "CBLM parameter"),
        ({"preset": 3}, {}, "'preset' must be a string"),
        ({}, {"primitive_params": 3}, "table of CobART parameters"),
    ],
)
def test_bad_assignments_are_refused(
    config: dict[str, object], sets: dict[str, object], message: str
) -> None:
    with pytest.raises(ConfigError, match=message):
        resolve_params(("SBLM",), None, config, sets)


def test_a_config_section_for_another_kind_is_checked_but_not_applied() -> None:
    _, params = resolve_params(("SBLM",), None, {"cblm.repair": False})
    assert params == {"SBLM": preset_params("default", "SBLM")}
    with pytest.raises(ConfigError, match="repair"):
        resolve_params(("SBLM",), None, {"cblm.repair": "no"})


@pytest.mark.parametrize(
    ("content", "message"),
    [("x = [", "not valid TOML"), ("\xff\xfe", "not UTF-8 text \\(byte 0\\)")],
)
def test_bad_config_files(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_bytes(content.encode("latin-1"))
    with pytest.raises(ConfigError, match=message):
        read_config(path)
    with pytest.raises(ConfigError, match="a folder, not a regular file"):
        read_config(tmp_path)


def test_did_you_mean_lists_choices_when_nothing_is_close() -> None:
    assert did_you_mean("zzz", ["b", "a"]) == "; known: a, b"


@given(st.text(max_size=40))
def test_parse_value_never_raises(text: str) -> None:
    parse_value(text)


@given(st.dictionaries(st.text(max_size=12), st.integers() | st.text(max_size=5), max_size=4))
def test_resolve_params_returns_or_raises_config_error(config: dict[str, object]) -> None:
    try:
        resolve_params(("SBLM", "CBLM"), None, config)
    except ConfigError:
        pass
