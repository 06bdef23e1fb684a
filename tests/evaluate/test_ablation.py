"""experiment ablation: thesis, thesis + each departure, default, default − each."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from behavior_hmm import teach
from behavior_hmm.cli import app
from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate._ablation import (
    ABLATION_TASKS,
    AblationRow,
    ablation_rows,
    run_ablation,
    task,
)
from behavior_hmm.evaluate._executor import ProcessExecutor, SerialExecutor
from behavior_hmm.evaluate._protocol import evaluate_model
from behavior_hmm.models import DEPARTURES, SBLM, preset_params
from behavior_hmm.viz._ablation import ablation_markdown, write_ablation_report

#: A quick ablation: turn only, the thesis and default rows (no departure rows), short
#: training; the rows' other parameters are the presets', whatever departures exist.
QUICK: dict[str, Any] = {
    "sim": "kinematic",
    "tasks": ["turn"],
    "departures": [],
    "overrides": {"SBLM": {"epochs": 10}},
}


def _public(result: dict[str, Any]) -> str:
    """What results.json holds: everything but the wall-clock timings, as sorted JSON."""
    return json.dumps({k: v for k, v in result.items() if k != "timings"}, sort_keys=True)


@pytest.fixture(scope="module")
def two_seeds() -> dict[str, Any]:
    """The quick ablation with two model seeds, run in this process."""
    return run_ablation(**QUICK, seeds=2, executor=SerialExecutor())


def test_rows_of_a_simple_task_leave_out_cblm_departures() -> None:
    rows = ablation_rows(task("turn"))
    sblm = [d.name for d in DEPARTURES if "SBLM" in d.kinds]
    assert [r.label for r in rows] == (
        ["thesis"]
        + [f"thesis + {n}" for n in sblm]
        + ["default"]
        + [f"default − {n}" for n in sblm]
        + ["default + elman", "default − onset_clock + elman"]
        + [
            "default + shared_init",
            "default + recover",
            "default + auto_inputs",
        ]
    )
    assert "repair" not in {n for r in rows for n in r.switched}


def test_rows_of_the_complex_task_cover_every_departure() -> None:
    rows = ablation_rows(task("turn-approach"))
    # + elman, − onset_clock + elman, + shared_init, + recover, + auto_inputs
    assert len(rows) == 2 + 2 * len(DEPARTURES) + 5
    assert {n for r in rows for n in r.switched} == {d.name for d in DEPARTURES}
    assert [t.name for t in ABLATION_TASKS] == ["turn", "approach", "turn-approach"]


def test_row_parameters() -> None:
    row = AblationRow("thesis", ("repair",))
    assert row.params("CBLM") == {**preset_params("thesis", "CBLM"), "repair": True}
    assert row.params("SBLM") == preset_params("thesis", "SBLM")
    assert AblationRow("default", ("repair",)).params("CBLM")["repair"] is False


def test_option_rows_set_the_option_over_the_default() -> None:
    row = AblationRow("default", ("onset_clock",), ("elman",))
    assert row.label == "default − onset_clock + elman"
    params = row.params("SBLM")
    assert params["generator_network"] == "elman" and params["onset_clock"] == 0
    assert preset_params("default", "SBLM")["generator_network"] == "mlp"
    assert preset_params("thesis", "SBLM")["generator_network"] == "mlp"  # the thesis's MLP
    assert row.params("CBLM") == preset_params("default", "CBLM")
    only = ablation_rows(task("turn"), ["elman"])
    assert [r.label for r in only] == [
        "thesis",
        "default",
        "default + elman",
        "default − onset_clock + elman",
    ]
    assert [r.label for r in ablation_rows(task("turn"), ["onset_clock"])][-1] == (
        "default − onset_clock"
    )
    with pytest.raises(ConfigError, match=r"unknown departure or option .elmann.*elman"):
        ablation_rows(task("turn"), ["elmann"])


def test_an_auto_inputs_row_fits_on_the_channels_its_demonstrations_choose() -> None:
    """The approach's hand-picked inputs are {distance, angle}; ``default + auto_inputs``
    fits an SBLM that chooses its own (``select_inputs``), says which in its row and in
    the table, and leaves the default row's model on the task's inputs."""
    result = run_ablation(**{**QUICK, "tasks": ["approach"], "departures": ["auto_inputs"]})
    (entry,) = result["tasks"]
    rows = {r["label"]: r for r in entry["rows"]}
    assert list(rows) == ["thesis", "default", "default + auto_inputs"]
    assert "chosen_inputs" not in rows["default"]
    chosen = rows["default + auto_inputs"]["chosen_inputs"]
    assert chosen and chosen != "distance, angle"
    assert set(chosen.split(", ")) <= set(
        teach.collect("approach", sim="kinematic").sensor_channels
    )
    assert f"default + auto_inputs (chose {chosen})" in ablation_markdown(result)


@pytest.mark.slow
def test_ablation_command_measures_the_onset_clock(tmp_path: Path) -> None:
    out = tmp_path / "ablation"
    result = CliRunner().invoke(
        app,
        ["experiment", "ablation", "--sim", "kinematic", "--task", "turn",
         "--departure", "onset_clock", "-o", str(out)],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    results = json.loads((out / "results.json").read_text())
    rows = {r["label"]: r for r in results["tasks"][0]["rows"]}
    assert list(rows) == ["thesis", "thesis + onset_clock", "default", "default − onset_clock"]
    # the onset clock is what lets a sensor-only network start from rest (docs/algorithms.md)
    assert (
        rows["thesis + onset_clock"]["success_rate_mean"] > rows["thesis"]["success_rate_mean"] + 10
    )
    assert (
        rows["default"]["success_rate_mean"]
        > rows["default − onset_clock"]["success_rate_mean"] + 10
    )
    assert rows["default"]["goal_reached"] == 15
    for row in rows.values():  # every score beside its floor
        assert row["zero_floor_mean"] < row["success_rate_mean"]
    table = (out / "table.md").read_text()
    assert "| **thesis preset** |" in table and "| default − onset_clock |" in table
    assert (out / "ablation.png").stat().st_size > 10_000


def test_processes_give_the_same_results_as_one_process(two_seeds: dict[str, Any]) -> None:
    parallel = run_ablation(**QUICK, seeds=2, executor=ProcessExecutor(2))
    assert _public(parallel) == _public(two_seeds)
    # the timings have the same shape: per task, per row, per seed
    assert {k: [len(s) for s in v] for k, v in parallel["timings"]["train_s"].items()} == {
        "turn": [2, 2]
    }


def test_seeds_give_each_row_a_mean_and_interval(two_seeds: dict[str, Any]) -> None:
    assert two_seeds["seeds"] == [0, 1]
    (entry,) = two_seeds["tasks"]
    assert [r["label"] for r in entry["rows"]] == ["thesis", "default"]
    first, second = entry["per_seed_rows"]
    assert first != second  # each seed trains its own models
    for j, row in enumerate(entry["rows"]):
        over = row["over_seeds"]
        assert set(over) == {"success_rate_mean", "goal_reached"}
        for key, summary in over.items():
            values = [first[j][key], second[j][key]]
            assert summary["values"] == values
            assert summary["mean"] == pytest.approx(sum(values) / 2)
            assert summary["ci95"] >= 0
        # the row's own values are the first seed's: the same as a one-seed run
        assert {k: v for k, v in row.items() if k != "over_seeds"} == first[j]
    one = run_ablation(**QUICK)
    assert "seeds" not in one and "over_seeds" not in one["tasks"][0]["rows"][0]
    assert one["tasks"][0]["rows"] == first


def test_rows_report_the_evaluations_jolts_and_switches(two_seeds: dict[str, Any]) -> None:
    rows = two_seeds["tasks"][0]["rows"]
    for row in rows:
        assert 0 < row["command_jump_ratio_median"] <= row["command_jump_ratio_max"]
        assert isinstance(row["switches_max"], int) and row["switches_max"] >= 0
        assert "train_s" not in row
    # the default row's figures are its model's evaluation summary, not recomputed
    data = teach.collect("turn", sim="kinematic", seed=0)
    params = {**preset_params("default", "SBLM"), "epochs": 10}
    model = SBLM(**params, inputs=("angle",), random_state=0).fit(data)
    result = evaluate_model(model, teach.test_starts("turn"), sim="kinematic", seed=0)
    default = rows[1]
    for key in ("command_jump_ratio_median", "command_jump_ratio_max", "switches_max"):
        assert default[key] == result[key], key
    assert default["success_rate_mean"] == result["success_rate_mean"]


def test_the_report_keeps_timings_out_of_results_json(
    two_seeds: dict[str, Any], tmp_path: Path
) -> None:
    table = write_ablation_report(two_seeds, tmp_path)
    saved = (tmp_path / "results.json").read_text()
    assert "train_s" not in saved and "timings" not in json.loads(saved)
    timings = json.loads((tmp_path / "timings.json").read_text())
    assert timings == two_seeds["timings"]
    assert "jump × teacher's (median / max)" in table
    lines = [line for line in table.splitlines() if line.startswith("|")]
    assert len(lines) == 4  # header, rule, thesis, default
    thesis = lines[2]
    # mean ± interval over the seeds, then the first seed's jump ratio (median / max)
    row = two_seeds["tasks"][0]["rows"][0]
    over = row["over_seeds"]["success_rate_mean"]
    assert thesis.startswith(f"| **thesis preset** | {over['mean']:.1f} ± {over['ci95']:.1f} |")
    jump = f"{row['command_jump_ratio_median']:.1f} / {row['command_jump_ratio_max']:.1f}"
    assert f"| {jump} | {row['switches_max']} |" in thesis
    # re-rendered from results.json alone (no timings): "—" for the training time
    assert ablation_markdown(json.loads(saved)).splitlines()[-2].endswith("| — |")


def test_bad_ablation_options_are_refused_before_any_work() -> None:
    with pytest.raises(ConfigError, match="unknown model kind 'GBLM'"):
        run_ablation(**{**QUICK, "overrides": {"GBLM": {"epochs": 1}}})
    with pytest.raises(ConfigError, match="unknown SBLM parameter"):
        run_ablation(**{**QUICK, "overrides": {"SBLM": {"epoch": 1}}})
    with pytest.raises(ConfigError, match="--seeds"):
        run_ablation(**QUICK, seeds=0)
    for options, message in (
        (["--seeds", "0"], "--seeds must be an integer"),
        (["--address", "10.0.0.1:6379"], "--address is for --executor ray"),
        (["--workers", "0"], "--workers must be an integer"),
    ):
        result = CliRunner().invoke(
            app, ["experiment", "ablation", "--sim", "kinematic", "--task", "turn", *options]
        )
        assert result.exit_code == 2, result.output
        assert message in result.output


@pytest.mark.slow
def test_a_complex_task_gives_the_same_results_in_processes() -> None:
    """Turn & approach: the rows' CBLMs share fitted components in one process only."""
    quick = {**QUICK, "tasks": ["turn-approach"]}
    serial = run_ablation(**quick, executor=SerialExecutor())
    parallel = run_ablation(**quick, executor=ProcessExecutor(2))
    assert _public(parallel) == _public(serial)
    rows = serial["tasks"][0]["rows"]
    assert [r["label"] for r in rows] == ["thesis", "default"]
    assert all("primitives" not in r and r["command_jump_ratio_max"] > 0 for r in rows)
