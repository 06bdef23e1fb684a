"""``train simple NEW --update MODEL -o OUT`` (issue 29): continue an SBLM on new data."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from cli_testing import Invoke, assert_user_error, digest, files_in, write_starts
from typer.testing import CliRunner

from behavior_hmm.cli import app
from behavior_hmm.models import SBLM


@pytest.fixture(scope="module")
def new_parquet(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """New turn demonstrations from other starts (kinematic, seed 11, noise 0.01)."""
    folder = tmp_path_factory.mktemp("new")
    starts = write_starts(folder / "starts.csv", "angle", "80", "-150", "20")
    out = folder / "new.parquet"
    args = ["collect", "turn", "--starts", starts, "--sim", "kinematic"]
    args += ["--seed", "11", "--noise", "0.01", "-o", out]
    result = CliRunner().invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    return out


@pytest.fixture
def work(tmp_path: Path, new_parquet: Path, turn_bhmm: Path) -> dict[str, Path]:
    return {
        "data": Path(shutil.copy(new_parquet, tmp_path / "new.parquet")),
        "model": Path(shutil.copy(turn_bhmm, tmp_path / "turn.bhmm")),
    }


def test_update_writes_a_new_model_and_leaves_the_old_one_untouched(
    invoke: Invoke, work: dict[str, Path], tmp_path: Path
) -> None:
    before = digest(work["model"])
    out = tmp_path / "updated.bhmm"
    args = ["train", "simple", work["data"], "--update", work["model"], "-o", out]
    result = invoke([*args, "--inputs", "angle"])  # the model's own inputs may be repeated
    assert result.exit_code == 0, result.output
    assert f"wrote {out}" in result.stdout and "unchanged" in result.stdout
    assert digest(work["model"]) == before
    old, new = SBLM.load(work["model"]), SBLM.load(out)
    assert old.updates_ == []
    (record,) = new.updates_
    assert record["source"] == str(work["data"]) and record["episodes"] == 3
    assert f"(with {record['rehearsed']:,} kept rows)" in result.stdout
    assert record["rehearsed"] > 0  # the fine-tuned networks also trained on old rows
    assert new.primitives_.n_categories_ >= old.primitives_.n_categories_
    assert new.get_params() == old.get_params()
    assert new.train_data_ == old.train_data_
    # the updated model can be updated again
    again = tmp_path / "again.bhmm"
    result = invoke(["train", "simple", work["data"], "--update", out, "-o", again])
    assert result.exit_code == 0, result.output
    assert len(SBLM.load(again).updates_) == 2
    # inspect tells how many updates a model had and how many rows it keeps for the next
    rows = SBLM.load(again).rehearsal_
    assert rows is not None
    shown = invoke(["inspect", again])
    assert shown.exit_code == 0, shown.output
    assert f"updates: 2; training rows kept for the next: {rows.n_rows:,}" in shown.stdout


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--preset", "thesis"], "--preset cannot be used with --update"),
        (["--set", "epochs=5"], "--set cannot be used with --update"),
        (["--config", "CONFIG"], "--config cannot be used with --update"),
        (["--inputs", "distance,angle"], "--inputs distance,angle: the model reads angle"),
        (["--seed", "3"], "--seed 3: an update draws from the model's seed (0)"),
    ],
)
def test_options_that_make_no_sense_with_update_are_refused(
    invoke: Invoke, work: dict[str, Path], tmp_path: Path, extra: list[str], needle: str
) -> None:
    config = write_starts(tmp_path / "c.toml", "epochs = 5")
    extra = [str(config) if e == "CONFIG" else e for e in extra]
    before, listing = digest(work["model"]), files_in(tmp_path)
    out = tmp_path / "out.bhmm"
    result = invoke(["train", "simple", work["data"], "--update", work["model"], "-o", out, *extra])
    assert_user_error(result, needle)
    assert digest(work["model"]) == before
    assert files_in(tmp_path) == listing


def test_the_output_may_not_name_the_model(invoke: Invoke, work: dict[str, Path]) -> None:
    before = digest(work["model"])
    args = ["train", "simple", work["data"], "--update", work["model"], "-o", work["model"]]
    assert_user_error(invoke(args), "-o", "--update")
    assert digest(work["model"]) == before


def test_a_missing_or_foreign_model_is_refused(
    invoke: Invoke, work: dict[str, Path], tmp_path: Path
) -> None:
    out = tmp_path / "out.bhmm"
    missing = tmp_path / "none.bhmm"
    assert_user_error(
        invoke(["train", "simple", work["data"], "--update", missing, "-o", out]), "none.bhmm"
    )
    assert_user_error(
        invoke(["train", "simple", work["data"], "--update", work["data"], "-o", out]),
        "new.parquet",
    )
    assert not out.exists()


def test_without_update_inputs_are_required(
    invoke: Invoke, work: dict[str, Path], tmp_path: Path
) -> None:
    result = invoke(["train", "simple", work["data"], "-o", tmp_path / "x.bhmm"])
    assert_user_error(result, "--inputs is required")
