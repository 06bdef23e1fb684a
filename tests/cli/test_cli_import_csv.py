"""``behavior-hmm import-csv``: users' logs in, validated datasets out, bad logs refused."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from cli_testing import (
    CSV_HEADER,
    Invoke,
    assert_user_error,
    digest,
    files_in,
    log_rows,
    write_csv,
)

from behavior_hmm import data

COL = {name: j for j, name in enumerate(CSV_HEADER)}


def test_good_log_is_imported(invoke: Invoke, tmp_path: Path) -> None:
    log = write_csv(tmp_path / "log.csv", CSV_HEADER, log_rows())
    out = tmp_path / "mine.parquet"
    result = invoke(["import-csv", log, "--behavior", "turn", "-o", out])
    assert result.exit_code == 0, result.output
    assert f"wrote {out}: 2 episodes, 12 rows" in result.stdout
    ds = data.read(out)
    assert len(ds) == 2
    assert ds.metadata["behavior"] == "turn"
    assert ds.metadata["source"]["file"] == "log.csv"
    assert ds.column("angle")[0] == 60.0


def test_mapping_units_drop_and_delimiter(invoke: Invoke, tmp_path: Path) -> None:
    header = list(CSV_HEADER)
    header[COL["angle"]] = "bearing"
    header[COL["t"]] = "time_ms"
    rows = []
    for cells in log_rows(n_episodes=1):
        cells = list(cells)
        cells[COL["angle"]] = f"{math.radians(float(cells[COL['angle']])):.12f}"
        cells[COL["t"]] = f"{float(cells[COL['t']]) * 1000:g}"
        rows.append([*cells, "junk"])
    log = tmp_path / "log.csv"
    log.write_text(
        "\n".join(";".join(r) for r in [[*header, "note"], *rows]) + "\n", encoding="utf-8"
    )
    out = tmp_path / "mine.parquet"
    args = ["import-csv", log, "--map", "angle=bearing", "--map", "t=time_ms"]
    args += ["--unit", "angle=rad", "--unit", "t=ms", "--drop", "note", "--delimiter", ";"]
    result = invoke([*args, "-o", out])
    assert result.exit_code == 0, result.output
    ds = data.read(out)
    assert np.allclose(ds.column("angle")[:3], [60.0, 50.0, 40.0])
    assert np.allclose(ds.column("t")[:2], [0.0, 0.016])
    source = ds.metadata["source"]
    assert source["mapping"] == {"angle": "bearing", "t": "time_ms"}
    assert source["units"] == {"angle": "rad", "t": "ms"}


def test_split_on_time_reset(invoke: Invoke, tmp_path: Path) -> None:
    header = [c for c in CSV_HEADER if c != "episode"]
    rows = [cells[1:] for cells in log_rows(n_episodes=3)]
    log = write_csv(tmp_path / "log.csv", header, rows)
    out = tmp_path / "mine.parquet"
    result = invoke(["import-csv", log, "-o", out])
    assert_user_error(result, "log.csv", "field 't'", "time does not increase")
    result = invoke(["import-csv", log, "--split-on-time-reset", "-o", out])
    assert result.exit_code == 0, result.output
    assert len(data.read(out)) == 3


def _bad_log(kind: str, path: Path) -> Path:
    """Write a log with one defect of ``kind`` (in episode 1 where rows are involved)."""
    header = list(CSV_HEADER)
    rows = [list(r) for r in log_rows()]  # episode 0 = rows 0-5, episode 1 = rows 6-11
    if kind == "missing column":
        j = COL["right"]
        header.pop(j)
        rows = [r[:j] + r[j + 1 :] for r in rows]
    elif kind == "extra column":
        header.append("battery")
        rows = [[*r, "12.1"] for r in rows]
    elif kind == "misnamed column":
        header[COL["angle"]] = "angel"
    elif kind == "wrong type":
        rows[8][COL["angle"]] = "north"
    elif kind == "wrong type episode":
        rows[8][COL["episode"]] = "one"
    elif kind == "NaN":
        rows[8][COL["distance"]] = "nan"
    elif kind == "inf":
        rows[8][COL["left"]] = "-inf"
    elif kind == "missing value":
        rows[8][COL["right"]] = ""
    elif kind == "non-increasing time":
        rows[8][COL["t"]] = rows[7][COL["t"]]
    elif kind == "empty episode":
        rows = []
    elif kind == "absurd value":
        rows[8][COL["distance"]] = "250"
    elif kind == "absurd angle":
        rows[8][COL["angle"]] = "1e9"
    elif kind == "ragged row":
        rows[8] = rows[8][:-1]
    elif kind == "episode not contiguous":
        rows[8][COL["episode"]] = "0"
    else:
        raise AssertionError(kind)
    return write_csv(path, header, rows)


BAD_LOGS = [
    ("missing column", ["field 'right'", "missing column"]),
    ("extra column", ["field 'battery'", "unexpected column"]),
    ("misnamed column", ["field 'angel'", "did you mean 'angle'"]),
    ("wrong type", ["episode 1, row 2, field 'angle'", "not a number", "line 10"]),
    ("wrong type episode", ["field 'episode'", "not an integer", "line 10"]),
    ("NaN", ["episode 1, row 2, field 'distance'", "NaN"]),
    ("inf", ["episode 1, row 2, field 'left'", "infinite"]),
    ("missing value", ["episode 1, row 2, field 'right'", "missing value"]),
    ("non-increasing time", ["episode 1, row 2, field 't'", "time does not increase"]),
    ("empty episode", ["no data rows"]),
    ("absurd value", ["episode 1, row 2, field 'distance'", "absurd value 250"]),
    ("absurd angle", ["episode 1, row 2, field 'angle'", "absurd angle"]),
    ("ragged row", ["line 10", "cells"]),
    ("episode not contiguous", ["episode 0", "not contiguous"]),
]


@pytest.mark.parametrize(("kind", "needles"), BAD_LOGS, ids=[k for k, _ in BAD_LOGS])
def test_bad_log_is_refused_and_nothing_is_written(
    invoke: Invoke, tmp_path: Path, kind: str, needles: list[str]
) -> None:
    log = _bad_log(kind, tmp_path / "log.csv")
    out = tmp_path / "out.parquet"
    result = invoke(["import-csv", log, "-o", out])
    assert_user_error(result, "log.csv", *needles)
    assert files_in(tmp_path) == {"log.csv"}


def test_failed_import_keeps_the_old_output(invoke: Invoke, tmp_path: Path) -> None:
    out = tmp_path / "out.parquet"
    good = write_csv(tmp_path / "good.csv", CSV_HEADER, log_rows())
    assert invoke(["import-csv", good, "-o", out]).exit_code == 0
    before = digest(out)
    bad = _bad_log("NaN", tmp_path / "bad.csv")
    assert_user_error(invoke(["import-csv", bad, "-o", out]), "bad.csv")
    assert digest(out) == before
    assert files_in(tmp_path) == {"good.csv", "bad.csv", "out.parquet"}


@pytest.mark.parametrize(
    ("content", "needles"),
    [
        (b"", ["empty file"]),
        (b"\n\n", ["empty file"]),
        (b"\xff\xfe\x00a\x00n\x00g", ["UTF-8"]),
    ],
    ids=["zero bytes", "blank lines", "not utf-8"],
)
def test_unreadable_logs(
    invoke: Invoke, tmp_path: Path, content: bytes, needles: list[str]
) -> None:
    log = tmp_path / "log.csv"
    log.write_bytes(content)
    out = tmp_path / "out.parquet"
    assert_user_error(invoke(["import-csv", log, "-o", out]), "log.csv", *needles)
    assert not out.exists()


@pytest.mark.parametrize(
    ("options", "needles"),
    [
        (["--map", "angle"], ["--map expects KEY=VALUE"]),
        (["--map", "angle=a", "--map", "angle=b"], ["--map", "twice"]),
        (["--map", "angel=bearing"], ["unknown column 'angel'", "did you mean 'angle'"]),
        (["--map", "angle=bearing"], ["'bearing'", "not in the file"]),
        (["--unit", "angle=furlong"], ["unknown unit 'furlong'", "deg, rad"]),
        (["--unit", "episode=s"], ["takes no unit"]),
        (["--drop", "nothere"], ["field 'nothere'", "not in the file"]),
        (["--delimiter", ";;"], ["--delimiter"]),
        (["--behavior", "Turn Left"], ["invalid behavior name"]),
    ],
)
def test_bad_options_are_refused(
    invoke: Invoke, tmp_path: Path, options: list[str], needles: list[str]
) -> None:
    log = write_csv(tmp_path / "log.csv", CSV_HEADER, log_rows())
    out = tmp_path / "out.parquet"
    assert_user_error(invoke(["import-csv", log, *options, "-o", out]), *needles)
    assert not out.exists()


def test_missing_log_and_overwriting_the_log(invoke: Invoke, tmp_path: Path) -> None:
    out = tmp_path / "out.parquet"
    assert_user_error(invoke(["import-csv", tmp_path / "nope.csv", "-o", out]), "nope.csv")
    folder = tmp_path / "logs"
    folder.mkdir()
    assert_user_error(invoke(["import-csv", folder, "-o", out]), "is a directory")
    log = write_csv(tmp_path / "log.csv", CSV_HEADER, log_rows())
    before = digest(log)
    assert_user_error(invoke(["import-csv", log, "-o", log]), "overwrite")
    assert digest(log) == before
