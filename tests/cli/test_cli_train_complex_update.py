"""``train complex NEW --update MODEL --component C -o OUT`` (issue 29): a behavior joins a CBLM."""

from __future__ import annotations

import io
import json
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
from cli_testing import Invoke, assert_user_error, digest, files_in, write_starts
from typer.testing import CliRunner

from behavior_hmm.cli import app
from behavior_hmm.models import CBLM, SBLM
from behavior_hmm.teach import collect

ANGLES = [int(a) for a in range(-160, 181, 40)]


def _cli(*args: object) -> str:
    result = CliRunner().invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    return result.stdout


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Turn, approach, retreat (kinematic, small); a turn-approach CBLM by the CLI; new
    "position" demonstrations (turn, then retreat to 1 m) collected by the CLI."""
    d = tmp_path_factory.mktemp("complex_update")
    grids = {
        "turn": (("angle",), [{"angle": a} for a in range(-170, 181, 20)]),
        "approach": (
            ("distance", "angle"),
            [{"distance": x} for x in np.arange(0.1, 1.01, 0.1)],
        ),
        "retreat": (
            ("distance", "angle"),
            [{"distance": x, "goal_distance": 1.0} for x in np.arange(0.0, 0.91, 0.1)],
        ),
    }
    for name, (inputs, starts) in grids.items():
        SBLM(inputs=inputs, epochs=60).fit(collect(name, starts, sim="kinematic")).save(
            d / f"{name}.bhmm"
        )
    rows = [f"{a},{x}" for a in ANGLES for x in (0.2, 0.5, 0.8)]
    rows += [f"0,{x}" for x in (0.2, 0.5, 0.8)] + [f"{a},0" for a in ANGLES]
    starts = write_starts(d / "ta.csv", "angle,distance", *rows)
    _cli(
        "collect", "turn-approach", "--starts", starts, "--sim", "kinematic", "-o", d / "ta.parquet"
    )
    # without --inputs a CBLM reads distance,angle
    _cli(
        "train", "complex", d / "ta.parquet", "--component", d / "turn.bhmm",
        "--component", d / "approach.bhmm", "-o", d / "ta.bhmm",
    )  # fmt: skip
    rows = [f"{a},{x},1.0" for a in (-120, -40, 0, 40, 120) for x in (0.1, 0.4)]
    rows += [f"{a},0.7,1.0" for a in ANGLES]
    starts = write_starts(d / "position.csv", "angle,distance,goal_distance", *rows)
    _cli(
        "collect", "position", "--starts", starts, "--sim", "kinematic",
        "-o", d / "position.parquet",
    )  # fmt: skip
    files = {name: d / f"{name}.bhmm" for name in ("turn", "approach", "retreat")}
    return {**files, "data": d / "position.parquet", "model": d / "ta.bhmm"}


@pytest.fixture
def work(tmp_path: Path, made: dict[str, Path]) -> dict[str, Path]:
    return {
        "data": Path(shutil.copy(made["data"], tmp_path / "new.parquet")),
        "model": Path(shutil.copy(made["model"], tmp_path / "ta.bhmm")),
        "retreat": Path(shutil.copy(made["retreat"], tmp_path / "retreat.bhmm")),
        "turn": made["turn"],
        "approach": made["approach"],
    }


def _embedded(path: Path, index: int) -> bytes:
    with zipfile.ZipFile(path) as archive:
        arrays = np.load(io.BytesIO(archive.read("arrays.npz")), allow_pickle=False)
        return bytes(arrays[f"component.{index}"].tobytes())


def test_update_adds_the_component_and_leaves_the_model_untouched(
    invoke: Invoke, work: dict[str, Path], tmp_path: Path
) -> None:
    before = {name: digest(work[name]) for name in ("model", "retreat", "data")}
    out = tmp_path / "position.bhmm"
    args = ["train", "complex", work["data"], "--update", work["model"]]
    args += ["--component", work["retreat"], "-o", out]
    result = invoke([*args, "--inputs", "distance,angle"])  # the model's own inputs: fine
    assert result.exit_code == 0, result.output
    assert f"wrote {out}: position over turn, approach, retreat" in result.stdout
    assert "retreat added from 19 demonstrations" in result.stdout
    assert f"{work['model']} and components unchanged" in result.stdout
    assert {name: digest(work[name]) for name in before} == before
    old, new = CBLM.load(work["model"]), CBLM.load(out)
    assert old.inputs_ == new.inputs_ == ("distance", "angle")
    assert old.names_ == ["turn", "approach"] and old.updates_ == []
    assert new.names_ == ["turn", "approach", "retreat"]
    (record,) = new.updates_
    assert record["component"] == "retreat" and record["source"] == str(work["data"])
    assert record["episodes"] == 19
    assert new.train_data_ == old.train_data_
    for i, name in enumerate(("turn", "approach", "retreat")):
        assert _embedded(out, i) == work[name].read_bytes()
    # the updated model performs the new composed behavior from the command line
    result = invoke(
        ["generate", out, "--start", "angle=40,distance=0.4", "--goal", "distance=1",
         "--sim", "kinematic"]
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout.splitlines()[0])["goal_reached"]
    # and the old one
    result = invoke(
        ["generate", out, "--start", "angle=-80,distance=0.5", "--sim", "kinematic"]
    )  # fmt: skip
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--preset", "thesis"], "--preset cannot be used with --update"),
        (["--set", "switch_cycles=4"], "--set cannot be used with --update"),
        (["--config", "CONFIG"], "--config cannot be used with --update"),
        (["--inputs", "angle"], "--inputs angle: the model reads distance,angle"),
        (["--component", "TURN"], "give one --component, not 2"),
    ],
)
def test_options_that_make_no_sense_with_update_are_refused(
    invoke: Invoke, work: dict[str, Path], tmp_path: Path, extra: list[str], needle: str
) -> None:
    config = write_starts(tmp_path / "c.toml", "switch_cycles = 4")
    names = {"CONFIG": str(config), "TURN": str(work["turn"])}
    extra = [names.get(e, e) for e in extra]
    before, listing = digest(work["model"]), files_in(tmp_path)
    out = tmp_path / "out.bhmm"
    args = ["train", "complex", work["data"], "--update", work["model"]]
    result = invoke([*args, "--component", work["retreat"], "-o", out, *extra])
    assert_user_error(result, needle)
    assert digest(work["model"]) == before
    assert files_in(tmp_path) == listing


def test_refusals_of_the_files(invoke: Invoke, work: dict[str, Path], tmp_path: Path) -> None:
    before, listing = digest(work["model"]), files_in(tmp_path)
    out = tmp_path / "out.bhmm"
    base = ["train", "complex", work["data"]]
    cases = [
        (["--update", work["turn"], "--component", work["retreat"]], "not a complex behavior"),
        (["--update", work["model"], "--component", work["turn"]], "turn is already a component"),
        (["--update", work["model"], "-o", work["model"]], ""),
    ]
    for extra, needle in cases:
        args = [*base, *extra]
        if "-o" not in extra:
            args += ["-o", out]
        else:
            args += ["--component", work["retreat"]]
        assert_user_error(invoke(args), needle)
    # demonstrations tagged with components only, none of them the new one
    tagged = invoke(
        ["train", "complex", work["data"], "--update", work["model"], "--component",
         work["approach"], "-o", out]
    )  # fmt: skip
    assert_user_error(tagged, "approach is already a component")
    assert digest(work["model"]) == before
    assert files_in(tmp_path) == listing
