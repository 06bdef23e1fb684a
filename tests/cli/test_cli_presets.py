"""--preset, --config and --set on every command that trains; inspect MODEL shows them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from cli_testing import Invoke, assert_user_error

from behavior_hmm.models import SBLM, preset_params


def test_train_simple_thesis_preset_is_saved_and_inspected(
    invoke: Invoke, turn_parquet: Path, tmp_path: Path
) -> None:
    model = tmp_path / "turn.bhmm"
    result = invoke(
        ["train", "simple", turn_parquet, "--inputs", "angle", "--preset", "thesis",
         "--set", "epochs=20", "-o", model]
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "preset thesis + epochs=20" in result.output
    loaded = SBLM.load(model)
    params = loaded.get_params()
    assert {k: params[k] for k in preset_params("thesis", "SBLM")} == {
        **preset_params("thesis", "SBLM"),
        "epochs": 20,
    }
    summary = tmp_path / "summary.json"
    result = invoke(["inspect", model, "--json", summary])
    assert result.exit_code == 0, result.output
    assert "preset: thesis + epochs=20" in result.output
    assert "batch_size" in result.output
    shown = json.loads(summary.read_text())
    assert shown["kind"] == "SBLM" and shown["params"]["batch_size"] == 1
    assert shown["preset"] == "thesis + epochs=20"


def test_config_file_applies_under_set(invoke: Invoke, turn_parquet: Path, tmp_path: Path) -> None:
    config = tmp_path / "c.toml"
    config.write_text('preset = "thesis"\n[sblm]\nepochs = 20\nonset_clock = 32\n')
    model = tmp_path / "turn.bhmm"
    result = invoke(
        ["train", "simple", turn_parquet, "--inputs", "angle", "--config", config,
         "--set", "onset_clock=16", "-o", model]
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    loaded = SBLM.load(model)
    assert (loaded.epochs, loaded.onset_clock, loaded.batch_size) == (20, 16, 1)


@pytest.mark.parametrize(
    ("extra", "needles"),
    [
        (["--preset", "thesys"], ("unknown preset 'thesys'",)),
        (["--set", "batch_sise=2"], ("did you mean 'batch_size'",)),
        (["--set", "repair=false"], ("CBLM parameter",)),
        (["--set", "onset_clock=soon"], ("must be an integer",)),
        (["--set", "epochs"], ("NAME=VALUE",)),
    ],
)
def test_bad_parameters_exit_2_before_any_work(
    invoke: Invoke, turn_parquet: Path, tmp_path: Path, extra: list[str], needles: tuple[str, ...]
) -> None:
    out = tmp_path / "m.bhmm"
    result = invoke(["train", "simple", turn_parquet, "--inputs", "angle", *extra, "-o", out])
    assert_user_error(result, *needles)
    assert not out.exists()


@pytest.mark.parametrize("command", ["simple", "complex"])
def test_config_with_an_unknown_key_exits_2_with_one_line(
    invoke: Invoke, turn_parquet: Path, tmp_path: Path, command: str
) -> None:
    config = tmp_path / "c.toml"
    config.write_text("[cblm]\nswitch_cycle = 3\n")
    out = tmp_path / "m.bhmm"
    args = ["train", command, turn_parquet, "--config", config, "-o", out]
    args += ["--inputs", "angle"] if command == "simple" else ["--component", tmp_path / "x.bhmm"]
    result = invoke(args)
    assert_user_error(result, str(config), "switch_cycle", "did you mean 'switch_cycles'")
    assert not out.exists()


def test_experiment_refuses_bad_parameters_before_collecting(
    invoke: Invoke, tmp_path: Path
) -> None:
    result = invoke(
        ["experiment", "complex", "--sim", "kinematic", "--set", "cblm.switch_cycles=0",
         "-o", tmp_path / "out"]
    )  # fmt: skip
    assert_user_error(result, "switch_cycles must be an integer in [1, 1000]")
    result = invoke(
        ["experiment", "complex", "--sim", "kinematic", "--set", "cblm.switch_cycles=x",
         "-o", tmp_path / "out"]
    )  # fmt: skip
    assert_user_error(result, "switch_cycles", "integer")
    result = invoke(["experiment", "ablation", "--task", "turn-aproach", "-o", tmp_path / "o"])
    assert_user_error(result, "unknown ablation task 'turn-aproach'")
    result = invoke(["experiment", "ablation", "--departure", "repiar", "-o", tmp_path / "o"])
    assert_user_error(result, "did you mean 'repair'")
    assert not (tmp_path / "o").exists()


def test_inspect_refuses_a_plot_of_a_model(
    invoke: Invoke, turn_parquet: Path, tmp_path: Path
) -> None:
    model = tmp_path / "turn.bhmm"
    result = invoke(
        ["train", "simple", turn_parquet, "--inputs", "angle", "--set", "epochs=5", "-o", model]
    )
    assert result.exit_code == 0, result.output
    assert_user_error(invoke(["inspect", model, "--plot", tmp_path / "m.png"]), "model file")


def test_an_experiment_names_the_changes_over_its_preset() -> None:
    """A table's score is never shown under a preset's name it does not have."""
    from behavior_hmm.cli._common import model_params

    assert model_params(("SBLM",), None, None, None)[0] == "default"
    assert model_params(("SBLM",), "thesis", None, [])[0] == "thesis"
    name, params = model_params(("SBLM",), None, None, ["generator_network=elman"])
    assert name == "default + generator_network='elman'"
    assert params["SBLM"]["generator_network"] == "elman"
    # a --set that restates the preset's own value changes nothing
    assert model_params(("SBLM", "CBLM"), "default", None, ["epochs=400"])[0] == "default"
    name, _ = model_params(("SBLM", "CBLM"), "default", None, ["cblm.repair=false"])
    assert name == "default; default + repair=False"
