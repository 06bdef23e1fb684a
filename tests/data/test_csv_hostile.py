"""Hostile CSV logs and starts files: each is refused in one line, bounded, quickly.

Every hostile file is built here (tmp_path); named pipes need POSIX.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from behavior_hmm.data import Dataset, import_csv
from behavior_hmm.data._csv import (
    MAX_COLUMNS,
    MAX_CSV_LINES,
    MAX_RESAMPLE_FACTOR,
    SHOWN_CHARS,
    check_resampling,
)
from behavior_hmm.errors import ConfigError, DatasetError
from behavior_hmm.teach import read_starts

HEADER = "episode,t,distance,linear_velocity,angle,angular_velocity,left,right"
ROW = "0,{t},0.5,0.0,10,0.0,0.1,0.1"
POSIX = pytest.mark.skipif(sys.platform == "win32" or not hasattr(os, "mkfifo"), reason="POSIX")

#: The longest message any refusal here may have (a few quoted values of SHOWN_CHARS).
MAX_MESSAGE = 2000


def _log(path: Path, *rows: str, header: str = HEADER) -> Path:
    path.write_text("\n".join([header, *rows]) + "\n", encoding="utf-8")
    return path


def _refused(path: Path, *needles: str, error: type[Exception] = DatasetError, **kw: object) -> str:
    """Import ``path``; it must raise ``error`` with one short line holding ``needles``."""
    start = time.perf_counter()
    with pytest.raises(error) as caught:
        import_csv(path, **kw)  # type: ignore[arg-type]
    assert time.perf_counter() - start < 10.0
    message = str(caught.value)
    assert "\n" not in message
    assert len(message) < MAX_MESSAGE, len(message)
    for needle in needles:
        assert needle in message, (needle, message)
    return message


# ------------------------------------------------------------ not a regular file


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="no /dev/zero")
def test_a_device_is_refused_before_it_is_read(tmp_path: Path) -> None:
    _refused(Path("/dev/zero"), "/dev/zero", "a device, not a regular file")
    link = tmp_path / "log.csv"
    link.symlink_to("/dev/urandom")
    _refused(link, "log.csv", "a device, not a regular file")


@POSIX
def test_a_named_pipe_is_refused_without_waiting(tmp_path: Path) -> None:
    fifo = tmp_path / "log.csv"
    os.mkfifo(fifo)
    done: list[str] = []
    worker = threading.Thread(target=lambda: done.append(_refused(fifo, "named pipe")))
    worker.start()
    worker.join(timeout=10)
    if worker.is_alive():  # unblock it, then fail
        with open(fifo, "wb"):
            pass
        worker.join()
        pytest.fail("the importer waited on a named pipe")
    assert done and "not a regular file" in done[0]


@POSIX
def test_a_named_pipe_of_starts_is_refused(tmp_path: Path) -> None:
    fifo = tmp_path / "starts.csv"
    os.mkfifo(fifo)
    with pytest.raises(DatasetError, match="named pipe"):
        read_starts(fifo)


def test_a_folder_is_refused(tmp_path: Path) -> None:
    _refused(tmp_path, "directory")


# ------------------------------------------------------------------ sizes and lines


def test_a_long_line_is_refused_before_parsing(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    path.write_text(HEADER + "\n" + "9" * (3 * 1024 * 1024) + "\n", encoding="utf-8")
    message = _refused(path, "line 2 is longer than")
    assert "999" not in message


def test_a_file_past_the_size_limit_is_refused_unread(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    with open(path, "wb") as fh:
        fh.truncate(65 * 1024 * 1024)  # sparse: no disk used
    _refused(path, "larger than 64 MiB")


def test_too_many_lines_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    path.write_text(HEADER + "\n" * (MAX_CSV_LINES + 1), encoding="utf-8")
    _refused(path, f"(limit {MAX_CSV_LINES:,}")


def test_too_many_columns_are_refused(tmp_path: Path) -> None:
    header = ",".join(f"c{i}" for i in range(MAX_COLUMNS + 1))
    _refused(_log(tmp_path / "log.csv", "0", header=header), f"(limit {MAX_COLUMNS:,})")


def test_many_unknown_long_columns_are_named_briefly(tmp_path: Path) -> None:
    names = [f"{'x' * 1000}{i}" for i in range(500)]
    header = HEADER + "," + ",".join(names)
    row = ROW.format(t=0) + "," + ",".join("0" for _ in names)
    message = _refused(_log(tmp_path / "log.csv", row, header=header), "and 488 more")
    assert "x" * (SHOWN_CHARS + 1) not in message


@pytest.mark.parametrize(
    ("cell", "needle"),
    [
        ("y" * 500_000, "is not a number"),
        ("1" * 400_000 + "x", "is not a number"),
    ],
)
def test_a_long_cell_is_echoed_cut(tmp_path: Path, cell: str, needle: str) -> None:
    path = _log(tmp_path / "log.csv", ROW.format(t=0), f"0,0.016,{cell},0,10,0,0.1,0.1")
    message = _refused(path, needle, "...", "CSV line 3")
    assert len(message) < 400


def test_a_long_episode_name_is_refused(tmp_path: Path) -> None:
    name = "run-" + "a" * 100_000
    path = _log(tmp_path / "log.csv", "x" + ROW.format(t=0)[1:], name + ROW.format(t=1)[1:])
    _refused(path, "longer than 128 characters")


def test_a_long_behavior_name_is_echoed_cut(tmp_path: Path) -> None:
    header = HEADER + ",behavior"
    path = _log(tmp_path / "log.csv", ROW.format(t=0) + ",T" * 1 + "x" * 200_000, header=header)
    _refused(path, "invalid behavior name", "...")


def test_a_long_quoted_cell_is_refused(tmp_path: Path) -> None:
    path = _log(
        tmp_path / "log.csv", ROW.format(t=0), '0,0.016,"' + "1\n" * 200_000 + '",0,1,0,0,0'
    )
    _refused(path, "not a valid CSV file")


def test_a_long_mapped_name_is_echoed_cut(tmp_path: Path) -> None:
    path = _log(tmp_path / "log.csv", ROW.format(t=0))
    message = _refused(path, "is not in the file", mapping={"angle": "b" * 100_000})
    assert "b" * (SHOWN_CHARS + 1) not in message


# ------------------------------------------------------------------ options


@pytest.mark.parametrize("delimiter", ["é", "\u2028", "\x00", '"', "ab", "", "1", "."])
def test_a_bad_delimiter_is_a_config_error(tmp_path: Path, delimiter: str) -> None:
    _refused(
        _log(tmp_path / "log.csv", ROW.format(t=0)),
        "delimiter",
        error=ConfigError,
        delimiter=delimiter,
    )


@pytest.mark.parametrize("period", [0.0, -1.0, float("nan"), float("inf"), "16ms", True])
def test_a_bad_period_is_a_config_error(tmp_path: Path, period: object) -> None:
    path = _log(tmp_path / "log.csv", ROW.format(t=0), ROW.format(t=1))
    _refused(path, "period", error=ConfigError, resample=True, period=period)


def test_typed_arguments(tmp_path: Path) -> None:
    path = _log(tmp_path / "log.csv", ROW.format(t=0))
    _refused(path, "mapping", error=ConfigError, mapping={"angle": 3})
    _refused(path, "drop", error=ConfigError, drop=[None])


# ------------------------------------------------------------------ resampling


def test_resampling_a_gap_is_refused_before_the_grid_is_made(tmp_path: Path) -> None:
    path = _log(tmp_path / "log.csv", ROW.format(t=0), ROW.format(t=1e7))
    message = _refused(
        path,
        "episode 0",
        "field 't'",
        "resampling at 16 ms would make 625,000,001 rows",
        f"{MAX_RESAMPLE_FACTOR:,} per row",
        "gap of 1e+07 s between its rows 0 and 1 (CSV lines 2 and 3)",
        resample=True,
    )
    assert "Memory" not in message


def test_resampling_in_all_is_bounded() -> None:
    n = 1000
    episode = np.repeat(np.arange(n), 2).astype(np.int64)
    t = np.tile([0.0, 15.0], n)  # 938 rows each: within the factor, 938,000 in all
    assert check_resampling(episode, t, 0.016, file="f") == 938 * n
    with pytest.raises(DatasetError, match="rows in all"):
        check_resampling(episode, t, 0.008, file="f")
    huge = np.array([0.0, 1e300])
    with pytest.raises(DatasetError, match=r"would make 6\.25e\+301 rows"):
        check_resampling(np.zeros(2, dtype=np.int64), huge, 0.016, file="f")


def test_resampling_a_plain_log_still_works(tmp_path: Path) -> None:
    path = _log(tmp_path / "log.csv", *(ROW.format(t=i * 0.1) for i in range(5)))
    ds = import_csv(path, resample=True)
    assert isinstance(ds, Dataset) and ds.n_samples == 26


# ------------------------------------------------------------------ any input


@settings(
    max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(body=st.binary(max_size=300))
def test_arbitrary_bytes_after_our_header(tmp_path: Path, body: bytes) -> None:
    path = tmp_path / "log.csv"
    path.write_bytes(HEADER.encode() + b"\n" + body)
    try:
        import_csv(path)
    except (DatasetError, ConfigError) as err:
        assert "\n" not in str(err) and len(str(err)) < MAX_MESSAGE


_CELL = st.one_of(
    st.sampled_from(["0", "1.5", "-3", "nan", "inf", "1e999", "", " ", "x", '"1"', "run-a"]),
    st.text(max_size=8),
)


@settings(
    max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    rows=st.lists(st.lists(_CELL, min_size=7, max_size=9), min_size=1, max_size=6),
    delimiter=st.sampled_from([",", ";", "\t"]),
    resample=st.booleans(),
)
def test_arbitrary_cells_give_a_dataset_or_our_error(
    tmp_path: Path, rows: list[list[str]], delimiter: str, resample: bool
) -> None:
    path = tmp_path / "log.csv"
    lines = [HEADER.replace(",", delimiter), *(delimiter.join(r) for r in rows)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    try:
        ds = import_csv(path, delimiter=delimiter, resample=resample)
    except (DatasetError, ConfigError) as err:
        assert "\n" not in str(err) and len(str(err)) < MAX_MESSAGE
    else:
        assert isinstance(ds, Dataset)


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(body=st.text(max_size=200))
def test_arbitrary_starts_text(tmp_path: Path, body: str) -> None:
    path = tmp_path / "starts.csv"
    path.write_text("angle,distance\n" + body, encoding="utf-8", errors="surrogatepass")
    try:
        read_starts(path)
    except DatasetError as err:
        assert "\n" not in str(err) and len(str(err)) < MAX_MESSAGE


def test_a_long_starts_cell_is_echoed_cut(tmp_path: Path) -> None:
    path = tmp_path / "starts.csv"
    path.write_text("angle\n" + "z" * 100_000 + "\n", encoding="utf-8")
    with pytest.raises(DatasetError, match="not a number") as caught:
        read_starts(path)
    assert len(str(caught.value)) < 400


def test_a_line_break_quoted_in_a_starts_cell_stays_on_the_messages_line(tmp_path: Path) -> None:
    path = tmp_path / "starts.csv"
    path.write_text('angle,distance\n"0\n0', encoding="utf-8")  # found by hypothesis above
    with pytest.raises(DatasetError, match=r"not a number: '0\\n0'") as caught:
        read_starts(path)
    assert "\n" not in str(caught.value)
