"""``behavior-hmm collect``: datasets, reproducibility, noise, and refusing bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from cli_testing import Invoke, assert_user_error, digest, files_in, smooth, write_starts

from behavior_hmm import data
from behavior_hmm.teach import default_starts


def _collect(invoke: Invoke, out: Path, *extra: object) -> None:
    result = invoke(["collect", *extra, "-o", out])
    assert result.exit_code == 0, result.output
    assert result.stderr == ""
    assert f"wrote {out}" in result.stdout


def test_collect_with_starts_writes_a_readable_dataset(turn_parquet: Path) -> None:
    ds = data.read(turn_parquet)
    assert len(ds) == 3
    md = ds.metadata
    assert md["behavior"] == "turn"
    assert md["simulator"] == "kinematic"
    assert md["seed"] == 5
    assert md["noise"] == 0.01
    assert [s["angle"] for s in md["starts"]] == [120.0, -45.0, 170.0]
    assert md["robot"]["wheel_mismatch"] == pytest.approx(0.01)
    # each episode starts at its start's bearing (noise 0.01 x 360 deg = 3.6 deg std)
    first = [ep.channel("angle")[0] for ep in ds]
    assert np.allclose(first, [120.0, -45.0, 170.0], atol=20.0)


def test_progress_output_is_plain_when_not_a_tty(invoke: Invoke, tmp_path: Path) -> None:
    starts = write_starts(tmp_path / "s.csv", "angle", "30", "-30")
    out = tmp_path / "x.parquet"
    result = invoke(["collect", "turn", "--starts", starts, "--sim", "kinematic", "-o", out])
    assert result.exit_code == 0
    assert "\x1b[" not in result.output  # no cursor movement or colour codes in a pipe
    lines = result.stdout.splitlines()
    assert len(lines) <= 3, lines
    assert "2/2" in result.stdout  # the final state of the bar, printed once
    assert lines[-1].startswith(f"wrote {out}: 2 episodes")


def test_default_grid_is_collected_without_starts(invoke: Invoke, tmp_path: Path) -> None:
    out = tmp_path / "turn.parquet"
    _collect(invoke, out, "turn", "--sim", "kinematic")
    ds = data.read(out)
    assert len(ds) == len(default_starts("turn")) == 36
    assert ds.metadata["starts"] == default_starts("turn")


def test_collect_on_mujoco_by_default(invoke: Invoke, tmp_path: Path) -> None:
    starts = write_starts(tmp_path / "s.csv", "distance", "0.15")
    out = tmp_path / "a.parquet"
    _collect(invoke, out, "approach", "--starts", starts)
    ds = data.read(out)
    assert ds.metadata["simulator"] == "mujoco"
    assert ds.columns("distance")[-1] <= 0.01  # the approach reached the object


def test_same_seed_gives_identical_files(invoke: Invoke, tmp_path: Path) -> None:
    starts = write_starts(tmp_path / "s.csv", "angle,distance", "90,0.3", "-150,0.6")
    outs = [tmp_path / f"{name}.parquet" for name in ("a", "b", "c")]
    for out, seed in zip(outs, (3, 3, 4), strict=True):
        args = ["turn-approach", "--starts", starts, "--sim", "kinematic", "--noise", "0.02"]
        _collect(invoke, out, *args, "--seed", seed)
    a, b, c = (data.read(p) for p in outs)
    assert a.metadata == b.metadata
    cols_a, cols_b = a.to_columns(), b.to_columns()
    assert list(cols_a) == list(cols_b)
    for name in cols_a:
        assert np.array_equal(cols_a[name], cols_b[name]), name
    assert digest(outs[0]) == digest(outs[1])  # byte-identical files
    # another seed draws other sensor noise
    assert not np.array_equal(a.column("angle"), c.column("angle"))


def test_noise_changes_sensors_but_not_the_commands(invoke: Invoke, tmp_path: Path) -> None:
    starts = write_starts(tmp_path / "s.csv", "angle", "100", "-60")
    clean, noisy = tmp_path / "clean.parquet", tmp_path / "noisy.parquet"
    common = ["turn", "--starts", starts, "--sim", "kinematic", "--seed", "1"]
    _collect(invoke, clean, *common)
    _collect(invoke, noisy, *common, "--noise", "0.02")
    a, b = data.read(clean), data.read(noisy)
    assert np.array_equal(a.lengths, b.lengths)
    # sigma 0.02 of each channel's normalization range: angle range 360 deg -> 7.2 deg std
    for channel in a.sensor_channels:
        lo, hi = data.SENSOR_RANGES[channel]
        diff = b.column(channel) - a.column(channel)
        if channel == "angle":
            diff = data.wrap_degrees(diff)
        assert np.std(diff) == pytest.approx(0.02 * (hi - lo), rel=0.15), channel
    # the teacher steers on the noise-free state: the commands stay smooth (and identical)
    for ep in b:
        for name in data.COMMAND_CHANNELS:
            assert smooth(ep.channel(name)), (ep.id, name)
    for name in data.COMMAND_CHANNELS:
        assert np.array_equal(a.column(name), b.column(name))


BAD_STARTS = [
    # (header, rows, needles in the error line)
    ("distance", ["0.3", "1.5"], ["row 3", "outside the arena", "distance 1.5"]),
    ("angle", ["500"], ["row 2", "outside the arena", "angle 500"]),
    ("angle", ["-180.5"], ["row 2", "outside the arena"]),
    ("distance", ["-0.1"], ["row 2", "outside the arena"]),
    ("angle", ["nan"], ["row 2", "field 'angle'", "finite"]),
    ("angle", ["ninety"], ["row 2", "field 'angle'", "not a number"]),
    ("angel", ["90"], ["field 'angel'", "unknown column"]),
    ("angle,speed", ["90,1"], ["field 'speed'", "unknown column"]),
    ("angle", [], ["no starts"]),
]


@pytest.mark.parametrize(("header", "rows", "needles"), BAD_STARTS)
def test_bad_starts_file_writes_nothing(
    invoke: Invoke, tmp_path: Path, header: str, rows: list[str], needles: list[str]
) -> None:
    starts = write_starts(tmp_path / "starts.csv", header, *rows)
    out = tmp_path / "out.parquet"
    result = invoke(["collect", "turn", "--starts", starts, "--sim", "kinematic", "-o", out])
    assert_user_error(result, "starts.csv", *needles)
    assert files_in(tmp_path) == {"starts.csv"}


def test_failed_collect_leaves_the_old_output_intact(
    invoke: Invoke, tmp_path: Path, turn_parquet: Path
) -> None:
    out = tmp_path / "out.parquet"
    out.write_bytes(turn_parquet.read_bytes())
    before = digest(out)
    bad = write_starts(tmp_path / "bad.csv", "distance,angle", "0.4,10", "1.5,20")
    result = invoke(["collect", "turn", "--starts", bad, "--sim", "kinematic", "-o", out])
    assert_user_error(result, "bad.csv", "row 3", "outside the arena")
    assert digest(out) == before
    assert files_in(tmp_path) == {"out.parquet", "bad.csv"}  # no temporary file left


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["spin"], ["unknown behavior 'spin'", "turn, approach"]),
        (["trun"], ["unknown behavior 'trun'", "did you mean 'turn'"]),
        (["turn", "--sim", "webots"], ["unknown simulator 'webots'", "mujoco, kinematic"]),
        (["turn", "--noise", "-0.1"], ["--noise", ">= 0"]),
        (["turn", "--noise", "nan"], ["--noise"]),
        (["turn", "--noise", "inf"], ["--noise"]),
        (["turn", "--seed", "-1"], ["--seed", ">= 0"]),
    ],
)
def test_bad_options_write_nothing(
    invoke: Invoke, tmp_path: Path, args: list[str], needles: list[str]
) -> None:
    starts = write_starts(tmp_path / "s.csv", "angle", "30")
    out = tmp_path / "out.parquet"
    behavior, *rest = args
    result = invoke(
        ["collect", behavior, "--starts", starts, "--sim", "kinematic", *rest, "-o", out]
    )
    assert_user_error(result, *needles)
    assert not out.exists()
    assert "collect" not in result.stdout  # refused before any episode ran


def test_starts_that_do_not_fit_the_behavior_are_refused_before_running(
    invoke: Invoke, tmp_path: Path
) -> None:
    angles_only = write_starts(tmp_path / "angles.csv", "angle", "30")
    out = tmp_path / "out.parquet"
    result = invoke(
        ["collect", "approach", "--starts", angles_only, "--sim", "kinematic", "-o", out]
    )
    assert_user_error(result, "angles.csv", "field 'distance'", "start 1")
    retreat = write_starts(tmp_path / "r.csv", "distance,goal_distance", "0.2,0.8", "0.5,0.3")
    result = invoke(["collect", "retreat", "--starts", retreat, "--sim", "kinematic", "-o", out])
    assert_user_error(result, "r.csv", "start 2", "goal distance")
    assert not out.exists()


def test_missing_starts_file_and_overwriting_it(invoke: Invoke, tmp_path: Path) -> None:
    out = tmp_path / "out.parquet"
    missing = tmp_path / "nope.csv"
    result = invoke(["collect", "turn", "--starts", missing, "--sim", "kinematic", "-o", out])
    assert_user_error(result, "nope.csv")
    starts = write_starts(tmp_path / "s.csv", "angle", "30")
    before = digest(starts)
    result = invoke(["collect", "turn", "--starts", starts, "--sim", "kinematic", "-o", starts])
    assert_user_error(result, "overwrite")
    assert digest(starts) == before


def test_unwritable_output_is_one_line(invoke: Invoke, tmp_path: Path) -> None:
    starts = write_starts(tmp_path / "s.csv", "angle", "30")
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    result = invoke(
        ["collect", "turn", "--starts", starts, "--sim", "kinematic", "-o", blocker / "x.parquet"]
    )
    assert_user_error(result)
    assert blocker.read_text() == "not a folder"
