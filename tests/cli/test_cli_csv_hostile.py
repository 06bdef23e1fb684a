"""Hostile inputs to ``import-csv`` (log, ``--map-file``, ``--delimiter``, ``--resample``)
and to ``--config`` and ``--starts``: one ``error:`` line, exit 2, no traceback."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
from cli_testing import CSV_HEADER, Invoke, assert_user_error, log_rows, write_csv

POSIX = pytest.mark.skipif(sys.platform == "win32" or not hasattr(os, "mkfifo"), reason="POSIX")


def _import(invoke: Invoke, log: Path, tmp_path: Path, *options: object) -> str:
    out = tmp_path / "out" / "mine.parquet"
    out.parent.mkdir(exist_ok=True)
    line = assert_user_error(invoke(["import-csv", log, *options, "-o", out]))
    assert not out.exists()
    assert len(line) < 2000
    return line


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="no /dev/zero")
def test_a_device_as_the_log(invoke: Invoke, tmp_path: Path) -> None:
    link = tmp_path / "log.csv"
    link.symlink_to("/dev/urandom")
    assert "a device, not a regular file" in _import(invoke, link, tmp_path)


@POSIX
def test_a_named_pipe_as_the_log_or_the_map_file(invoke: Invoke, tmp_path: Path) -> None:
    fifo = tmp_path / "log.csv"
    os.mkfifo(fifo)
    assert "named pipe" in _import(invoke, fifo, tmp_path)
    log = write_csv(tmp_path / "good.csv", CSV_HEADER, log_rows())
    pipe = tmp_path / "map.toml"
    os.mkfifo(pipe)
    assert "named pipe" in _import(invoke, log, tmp_path, "--map-file", pipe)


def test_a_long_line(invoke: Invoke, tmp_path: Path) -> None:
    log = tmp_path / "log.csv"
    log.write_text(",".join(CSV_HEADER) + "\n" + "7" * (2 * 1024 * 1024) + "\n")
    line = _import(invoke, log, tmp_path)
    assert "line 2 is longer than 1,048,576 characters" in line and "777" not in line


def test_a_long_cell_is_echoed_cut(invoke: Invoke, tmp_path: Path) -> None:
    rows = log_rows()
    rows[3][2] = "q" * 500_000
    line = _import(invoke, write_csv(tmp_path / "log.csv", CSV_HEADER, rows), tmp_path)
    assert "is not a number" in line and "..." in line and len(line) < 400


@pytest.mark.parametrize("delimiter", ["é", "»", "\x01"])
def test_a_non_ascii_delimiter(invoke: Invoke, tmp_path: Path, delimiter: str) -> None:
    log = write_csv(tmp_path / "log.csv", CSV_HEADER, log_rows())
    assert "delimiter" in _import(invoke, log, tmp_path, "--delimiter", delimiter)


def test_resampling_a_gap(invoke: Invoke, tmp_path: Path) -> None:
    rows = log_rows(n_episodes=1, n=2)
    rows[1][1] = "10000000"
    log = write_csv(tmp_path / "log.csv", CSV_HEADER, rows)
    line = _import(invoke, log, tmp_path, "--resample")
    assert "resampling at 16 ms would make 625,000,001 rows" in line
    assert "gap of 1e+07 s between its rows 0 and 1 (CSV lines 2 and 3)" in line


def test_deep_nesting_in_the_map_file(invoke: Invoke, tmp_path: Path) -> None:
    log = write_csv(tmp_path / "log.csv", CSV_HEADER, log_rows())
    deep = tmp_path / "map.toml"
    deep.write_text("drop = " + "[" * 10_000 + "]" * 10_000 + "\n")
    assert "nested more than 32 levels deep" in _import(invoke, log, tmp_path, "--map-file", deep)


def test_a_long_delimiter_in_the_map_file(invoke: Invoke, tmp_path: Path) -> None:
    log = write_csv(tmp_path / "log.csv", CSV_HEADER, log_rows())
    side = tmp_path / "map.toml"
    side.write_text(f'delimiter = "{";" * 200}"\n')
    line = _import(invoke, log, tmp_path, "--map-file", side)
    assert "'delimiter'" in line and ";" * 100 not in line


def test_hostile_config_files(invoke: Invoke, turn_parquet: Path, tmp_path: Path) -> None:
    deep = tmp_path / "deep.toml"
    deep.write_text("epochs = " + "[" * 10_000 + "]" * 10_000 + "\n")
    out = tmp_path / "m.bhmm"
    args = ["train", "simple", turn_parquet, "--inputs", "angle", "-o", out, "--config"]
    assert_user_error(invoke([*args, deep]), "deep.toml", "nested more than 32 levels deep")
    if hasattr(os, "mkfifo"):
        fifo = tmp_path / "pipe.toml"
        os.mkfifo(fifo)
        assert_user_error(invoke([*args, fifo]), "pipe.toml", "named pipe")
    if Path("/dev/zero").exists():
        assert_user_error(invoke([*args, "/dev/zero"]), "a device")
    assert not out.exists()


@POSIX
def test_a_named_pipe_of_starts(invoke: Invoke, tmp_path: Path) -> None:
    fifo = tmp_path / "starts.csv"
    os.mkfifo(fifo)
    out = tmp_path / "d.parquet"
    args = ["collect", "turn", "--starts", fifo, "--sim", "kinematic", "-o", out]
    assert_user_error(invoke(args), "named pipe")
