"""Bad input found late or not at all (issue 11, items 4 and 5): each is refused up front
with one line and exit code 2, or handled; no output is half-written."""

from __future__ import annotations

import errno
import json
import shutil
from pathlib import Path
from typing import Any

import pytest
from cli_testing import Invoke, assert_user_error, files_in, png_size, write_starts

from behavior_hmm.errors import BehaviorHMMError, DatasetError, UnreachableGoalError


def _kinematic(*args: object) -> list[object]:
    return [*args, "--sim", "kinematic"]


@pytest.fixture
def work(tmp_path: Path, turn_parquet: Path, turn_bhmm: Path) -> dict[str, Path]:
    """Copies of a dataset and a model, a one-row starts file, in ``tmp_path``."""
    return {
        "data": Path(shutil.copy(turn_parquet, tmp_path / "turn.parquet")),
        "model": Path(shutil.copy(turn_bhmm, tmp_path / "turn.bhmm")),
        "starts": write_starts(tmp_path / "starts.csv", "angle", "60"),
    }


# ---------------------------------------------------------------- seeds, noise, epochs

SEEDED = {
    "collect": lambda w: _kinematic("collect", "turn", "--starts", w["starts"], "-o", "x.parquet"),
    "train simple": lambda w: ["train", "simple", w["data"], "--inputs", "angle", "-o", "x.bhmm"],
    "generate": lambda w: _kinematic("generate", w["model"], "--start", "angle=60"),
    "evaluate": lambda w: _kinematic("evaluate", w["model"], "--starts", w["starts"]),
    "experiment simple": lambda w: _kinematic("experiment", "simple", "-o", "res"),
    "experiment complex": lambda w: _kinematic("experiment", "complex", "-o", "res"),
    "experiment ablation": lambda w: _kinematic("experiment", "ablation", "-o", "res"),
    "experiment categorization": lambda w: _kinematic("experiment", "categorization", "-o", "res"),
    "experiment generators": lambda w: _kinematic("experiment", "generators", "-o", "res"),
    "demo": lambda w: _kinematic("demo", "-o", "res"),
}


@pytest.mark.parametrize("command", list(SEEDED))
def test_a_negative_seed_is_refused_up_front(
    invoke: Invoke, work: dict[str, Path], command: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`--seed -1` gave a gymnasium/numpy traceback after loading and training."""
    monkeypatch.chdir(work["data"].parent)
    before = files_in(work["data"].parent)
    result = invoke([*SEEDED[command](work), "--seed", "-1"])
    assert_user_error(result, "--seed", ">= 0")
    assert result.stdout == ""
    assert files_in(work["data"].parent) == before


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["--noise", "1"], ["--noise", "too large", "0.0833"]),
        (["--noise", "0.09"], ["--noise", "too large"]),
        (["--noise", "-0.1"], ["--noise", ">= 0"]),
    ],
)
def test_collect_refuses_noise_the_dataset_check_would_refuse(
    invoke: Invoke, work: dict[str, Path], args: list[str], needles: list[str]
) -> None:
    """`collect --noise 1` simulated everything, then failed on an "absurd value"."""
    out = work["data"].parent / "noisy.parquet"
    result = invoke(_kinematic("collect", "turn-approach", "-o", out, *args))
    assert_user_error(result, *needles)
    assert result.stdout == "" and not out.exists()


def test_the_largest_noise_allowed_records_a_valid_dataset(
    invoke: Invoke, work: dict[str, Path]
) -> None:
    from behavior_hmm.cli.data import max_noise

    starts = write_starts(work["data"].parent / "near.csv", "angle,distance", "30,0.05")
    out = work["data"].parent / "noisy.parquet"
    args = ["collect", "turn-approach", "--starts", starts, "--noise", f"{max_noise():.4f}"]
    result = invoke(_kinematic(*args, "-o", out))
    assert result.exit_code == 0, result.output


def test_recorded_data_that_fails_its_check_is_named(
    invoke: Invoke, work: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Should a noisy reading still fall outside the plausible range, the error says it
    is the recorded data (not a file) and that nothing was written."""

    def collect(*args: Any, **kwargs: Any) -> Any:
        raise DatasetError("absurd value -0.6 m", episode=0, row=71, field="distance")

    monkeypatch.setattr("behavior_hmm.teach.collect", collect)
    out = work["data"].parent / "noisy.parquet"
    args = ["collect", "turn", "--starts", work["starts"], "--noise", "0.05", "-o", out]
    line = assert_user_error(invoke(_kinematic(*args)), "recorded demonstrations, episode 0")
    assert "nothing written to" in line and "--noise" in line
    assert not out.exists()


@pytest.mark.parametrize(
    ("command", "args"),
    [
        ("generate", ["--noise", "nan"]),
        ("generate", ["--noise", "-1"]),
        ("evaluate", ["--noise", "inf"]),
    ],
)
def test_generate_and_evaluate_refuse_bad_noise(
    invoke: Invoke, work: dict[str, Path], command: str, args: list[str]
) -> None:
    assert_user_error(invoke([*SEEDED[command](work), *args]), "--noise")


def test_generators_refuse_zero_epochs(invoke: Invoke, tmp_path: Path) -> None:
    result = invoke(_kinematic("experiment", "generators", "--epochs", "0", "-o", tmp_path / "g"))
    assert_user_error(result, "--epochs")
    assert files_in(tmp_path) == set()


# ------------------------------------------------------------ --start, --goal, starts CSV


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["--start", "angle=120,angle=-120"], ["--start", "'angle' twice"]),
        (["--start", "angle=120,noise=0.5"], ["--start", "unknown channel 'noise'"]),
        (["--start", "=3"], ["--start", "CHANNEL=VALUE"]),
        (["--start", "angle=60", "--goal", "angle=0,angle=10"], ["--goal", "'angle' twice"]),
        (["--start", "angle=60", "--goal", "speed=1"], ["unknown goal channel 'speed'"]),
        (["--start", "angle=60", "--goal", "distance=0.2"], ["not an input"]),
    ],
)
def test_bad_start_and_goal_are_refused(
    invoke: Invoke, work: dict[str, Path], args: list[str], needles: list[str]
) -> None:
    """A repeated key used to keep its last value silently; unknown start keys reached
    the simulator's reset options (``noise``, ``random``)."""
    plot = work["data"].parent / "run.png"
    result = invoke(_kinematic("generate", work["model"], *args, "--plot", plot))
    assert_user_error(result, *needles)
    assert result.stdout == "" and not plot.exists()


@pytest.mark.parametrize("command", ["collect", "evaluate"])
def test_a_starts_file_with_a_repeated_column_is_refused(
    invoke: Invoke, work: dict[str, Path], command: str
) -> None:
    starts = write_starts(work["data"].parent / "dup.csv", "angle,distance,angle", "10,0.5,20")
    args = (
        ["collect", "turn", "-o", "x.parquet"]
        if command == "collect"
        else ["evaluate", work["model"], "--json", work["data"].parent / "x.json"]
    )
    result = invoke(_kinematic(*args, "--starts", starts))
    assert_user_error(result, "dup.csv", "field 'angle'", "twice")
    assert result.stdout == ""


@pytest.mark.parametrize(
    ("rows", "needles"),
    [
        (["10,0.5", "20,0.5"], ["start 1", "goal channel 'distance'", "not an input"]),
        (["10,0", "20,1.5"], ["row 3", "goal_distance 1.5"]),
    ],
)
def test_every_start_and_goal_is_checked_before_the_first_case(
    invoke: Invoke, work: dict[str, Path], rows: list[str], needles: list[str]
) -> None:
    """A turn model (input: angle) cannot take a distance goal: refused before case 1."""
    starts = write_starts(work["data"].parent / "goals.csv", "angle,goal_distance", *rows)
    out = work["data"].parent / "eval.json"
    result = invoke(_kinematic("evaluate", work["model"], "--starts", starts, "--json", out))
    assert_user_error(result, "goals.csv", *needles)
    assert result.stdout == "" and not out.exists()  # no progress bar: nothing ran


# ------------------------------------------------- refused runs in the report; all or none


def _refuse_goal_90(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make the model refuse (unreachable) any run whose goal is angle 90."""
    from behavior_hmm.models import SBLM

    real = SBLM.generate

    def generate(self: Any, env: Any, start: Any = None, goal: Any = None, **kw: Any) -> Any:
        if goal == {"angle": 90.0}:
            raise UnreachableGoalError("no observation path leads to the goal")
        return real(self, env, start=start, goal=goal, **kw)

    monkeypatch.setattr(SBLM, "generate", generate)


def test_a_report_shows_a_refused_case(
    invoke: Invoke, work: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The run plot of a refused case (one step, no reading) died in matplotlib after
    --json was written."""
    _refuse_goal_90(monkeypatch)
    folder = work["data"].parent
    starts = write_starts(folder / "goals.csv", "angle,goal_angle", "120,90", "-45,0")
    out, page = folder / "eval.json", folder / "eval.html"
    args = ["evaluate", work["model"], "--starts", starts, "--json", out, "--report", page]
    result = invoke(_kinematic(*args))
    assert result.exit_code == 0, result.output
    cases = json.loads(out.read_text())["cases"]
    assert cases[0]["reason"].startswith("unreachable") and cases[0]["steps"] == 1
    text = page.read_text(encoding="utf-8")
    assert text.count("<img") == 2


def test_a_refused_run_plots(tmp_path: Path, turn_bhmm: Path) -> None:
    from behavior_hmm.cli._common import load_model
    from behavior_hmm.evaluate._protocol import _refused
    from behavior_hmm.viz import plot_trace

    trace = _refused(load_model(turn_bhmm), {"angle": 120.0, "distance": 0.5}, None, "no path")
    assert len(trace.t) == 1 and len(trace.readings) == 0
    plot_trace(trace, png := tmp_path / "refused.png")
    assert png_size(png)[0] > 0


def _fail_after_writing(path_kw: str) -> Any:
    """A stand-in writer: writes its output (staged), then fails like a late bug would."""
    from behavior_hmm._atomic import atomic_write_bytes

    def writer(*args: Any, **kwargs: Any) -> None:
        target = kwargs.get(path_kw, args[-1])
        atomic_write_bytes(target, b"half")
        raise DatasetError("late failure", file=str(target))

    return writer


def test_evaluate_writes_json_and_report_or_neither(
    invoke: Invoke, work: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = work["data"].parent
    out, page = folder / "eval.json", folder / "eval.html"
    out.write_text("old json")
    monkeypatch.setattr("behavior_hmm.viz.write_evaluation_report", _fail_after_writing("path"))
    args = ["evaluate", work["model"], "--starts", work["starts"], "--json", out, "--report", page]
    assert_user_error(invoke(_kinematic(*args)), "late failure")
    assert out.read_text() == "old json" and not page.exists()
    assert not [name for name in files_in(folder) if name.startswith(".")]


def test_generate_writes_trace_and_plot_or_neither(
    invoke: Invoke, work: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = work["data"].parent
    trace, plot = folder / "run.parquet", folder / "run.png"
    trace.write_text("old trace")
    monkeypatch.setattr("behavior_hmm.viz.plot_trace", _fail_after_writing("path"))
    args = ["generate", work["model"], "--start", "angle=60", "-o", trace, "--plot", plot]
    assert_user_error(invoke(_kinematic(*args)), "late failure")
    assert trace.read_text() == "old trace" and not plot.exists()
    assert not [name for name in files_in(folder) if name.startswith(".")]


def test_inspect_writes_plot_and_json_or_neither(
    invoke: Invoke, work: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = work["data"].parent
    plot, summary = folder / "a.png", folder / "a.json"
    plot.write_text("old plot")
    from behavior_hmm import _atomic

    real = _atomic.atomic_write_bytes

    def failing_write(path: Any, data: bytes) -> None:  # the JSON, after the plot
        real(path, b"half")
        raise BehaviorHMMError("cannot encode the summary")

    monkeypatch.setattr(_atomic, "atomic_write_bytes", failing_write)
    result = invoke(["inspect", work["data"], "--plot", plot, "--json", summary])
    assert_user_error(result, "cannot encode")
    assert plot.read_text() == "old plot" and not summary.exists()
    assert not [name for name in files_in(folder) if name.startswith(".")]


def test_a_failed_write_names_the_output_not_its_temporary_file(
    invoke: Invoke, work: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    from matplotlib.figure import Figure

    def full_disk(self: Any, fname: Any, *args: Any, **kwargs: Any) -> None:
        raise OSError(errno.ENOSPC, "No space left on device", str(fname))

    monkeypatch.setattr(Figure, "savefig", full_disk)
    plot = work["data"].parent / "run.png"
    result = invoke(_kinematic("generate", work["model"], "--start", "angle=60", "--plot", plot))
    line = assert_user_error(result, str(plot), "No space left on device")
    assert ".tmp" not in line
    assert files_in(plot.parent) == {"turn.parquet", "turn.bhmm", "starts.csv"}
