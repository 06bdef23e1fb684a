"""``behavior-hmm inspect``: a readable summary and a PNG; broken Parquet files refused."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from cli_testing import Invoke, assert_user_error, files_in, png_size

from behavior_hmm import data


def test_inspect_prints_summary_and_writes_png(
    invoke: Invoke, tmp_path: Path, turn_parquet: Path
) -> None:
    dataset = shutil.copy(turn_parquet, tmp_path / "turn.parquet")
    result = invoke(["inspect", dataset])
    assert result.exit_code == 0, result.output
    out = result.stdout
    ds = data.read(turn_parquet)
    assert "episodes: 3" in out
    assert f"samples: {ds.n_samples}" in out
    assert "duration_s: min" in out
    assert "behavior: turn" in out and "simulator: kinematic" in out
    for channel in (*data.SENSOR_CHANNELS, *data.COMMAND_CHANNELS):
        assert channel in out
    assert "deg/s" in out and "rad/s" in out
    png = tmp_path / "turn.png"  # default: next to the dataset
    assert f"plot: {png}" in out
    width, height = png_size(png)
    assert width >= 300 and height >= 300
    assert png.stat().st_size > 10_000
    assert "\x1b[" not in result.output


def test_inspect_plot_and_json_options(invoke: Invoke, tmp_path: Path, turn_parquet: Path) -> None:
    png, summary = tmp_path / "plots" / "t.png", tmp_path / "t.json"
    result = invoke(["inspect", turn_parquet, "--plot", png, "--json", summary])
    assert result.exit_code == 0, result.output
    png_size(png)
    info = json.loads(summary.read_text())
    assert info["episodes"] == 3
    assert info["metadata"]["seed"] == 5
    low, high = info["channels"]["angle"]["min"], info["channels"]["angle"]["max"]
    assert low < -40.0 and high > 160.0
    durations = info["duration_s"]
    assert 0.5 < durations["min"] <= durations["median"] <= durations["max"] < 30.0


def _table(ds: data.Dataset) -> dict[str, Any]:
    return dict(ds.to_columns())


def _write(path: Path, columns: dict[str, Any], metadata: bytes | None) -> None:
    table = pa.table(columns)
    if metadata is not None:
        table = table.replace_schema_metadata({data.METADATA_KEY: metadata})
    pq.write_table(table, path)


Edit = Callable[[dict[str, Any]], None]


def _set(name: str, index: int, value: float) -> Edit:
    def edit(cols: dict[str, Any]) -> None:
        cols[name] = cols[name].copy()
        cols[name][index] = value

    return edit


def _rename(old: str, new: str) -> Edit:
    def edit(cols: dict[str, Any]) -> None:
        cols[new] = cols.pop(old)

    return edit


def _pop(name: str) -> Edit:
    return lambda cols: cols.pop(name)


def _add(name: str) -> Edit:
    def edit(cols: dict[str, Any]) -> None:
        cols[name] = np.zeros(len(cols["t"]))

    return edit


def _as_text(name: str) -> Edit:
    def edit(cols: dict[str, Any]) -> None:
        cols[name] = pa.array([f"{v:g}" for v in cols[name]])

    return edit


def _as_float(name: str) -> Edit:
    def edit(cols: dict[str, Any]) -> None:
        cols[name] = cols[name].astype(np.float64) + 0.5

    return edit


def _null(name: str, index: int) -> Edit:
    def edit(cols: dict[str, Any]) -> None:
        values = cols[name].tolist()
        values[index] = None
        cols[name] = pa.array(values, type=pa.float64())

    return edit


def _repeat_time(cols: dict[str, Any]) -> None:
    cols["t"] = cols["t"].copy()
    cols["t"][6] = cols["t"][5]


def _empty(cols: dict[str, Any]) -> None:
    for name in list(cols):
        cols[name] = pa.array(cols[name][:0], type=pa.string() if name == "behavior" else None)


# Defects in episode 0 (the first rows) so that the error's row is the file row.
BAD_TABLES: list[tuple[str, Edit, list[str]]] = [
    ("missing column", _pop("right"), ["field 'right'", "missing column"]),
    ("extra column", _add("battery"), ["field 'battery'", "unexpected column"]),
    ("misnamed column", _rename("angle", "angel"), ["field 'angel'", "did you mean 'angle'"]),
    ("wrong type", _as_text("angle"), ["field 'angle'", "wrong type"]),
    ("wrong type episode", _as_float("episode"), ["field 'episode'", "wrong type"]),
    ("NaN", _set("angle", 10, np.nan), ["episode 0, row 10, field 'angle'", "NaN"]),
    ("inf", _set("left", 3, np.inf), ["episode 0, row 3, field 'left'", "infinite"]),
    ("null", _null("distance", 4), ["episode 0, row 4, field 'distance'", "missing value"]),
    ("non-increasing time", _repeat_time, ["episode 0, row 6, field 't'", "does not increase"]),
    ("empty", _empty, ["empty"]),
    ("absurd value", _set("distance", 7, 50.0), ["row 7, field 'distance'", "absurd value 50"]),
    ("absurd angle", _set("angle", 2, 400.0), ["row 2, field 'angle'", "absurd value 400"]),
]


@pytest.mark.parametrize(("kind", "edit", "needles"), BAD_TABLES, ids=[k for k, *_ in BAD_TABLES])
def test_bad_parquet_is_refused_and_no_plot_is_written(
    invoke: Invoke,
    tmp_path: Path,
    turn_parquet: Path,
    kind: str,
    edit: Edit,
    needles: list[str],
) -> None:
    ds = data.read(turn_parquet)
    cols = _table(ds)
    edit(cols)
    bad = tmp_path / "bad.parquet"
    _write(bad, cols, json.dumps(ds.metadata).encode())
    result = invoke(["inspect", bad, "--json", tmp_path / "s.json"])
    assert_user_error(result, "bad.parquet", *needles)
    assert files_in(tmp_path) == {"bad.parquet"}  # neither bad.png nor s.json


@pytest.mark.parametrize(
    ("kind", "needles"),
    [
        ("random bytes", ["not a readable Parquet file"]),
        ("truncated", ["not a readable Parquet file"]),
        ("bad metadata", ["field 'metadata'", "JSON"]),
        ("future schema", ["field 'schema_version'", "unsupported"]),
        ("directory", ["directory"]),
        ("missing", ["no such file"]),
        ("csv", ["import-csv"]),
    ],
)
def test_unreadable_files_are_refused(
    invoke: Invoke,
    tmp_path: Path,
    turn_parquet: Path,
    rng: np.random.Generator,
    kind: str,
    needles: list[str],
) -> None:
    target = tmp_path / ("bad.csv" if kind == "csv" else "bad.parquet")
    good = turn_parquet.read_bytes()
    ds = data.read(turn_parquet)
    if kind == "random bytes":
        target.write_bytes(rng.bytes(4096))
    elif kind == "truncated":
        target.write_bytes(good[: len(good) // 2])
    elif kind == "bad metadata":
        _write(target, _table(ds), b"{not json")
    elif kind == "future schema":
        _write(target, _table(ds), json.dumps({**ds.metadata, "schema_version": 99}).encode())
    elif kind == "directory":
        target.mkdir()
    elif kind == "csv":
        target.write_text("angle\n1\n")
    existing = files_in(tmp_path)
    result = invoke(["inspect", target])
    assert_user_error(result, "bad.", *needles)
    assert files_in(tmp_path) == existing


def test_flipped_bytes_never_crash(invoke: Invoke, tmp_path: Path, turn_parquet: Path) -> None:
    """Corruption anywhere in the file: refused with one line, or (metadata) read fine."""
    good = bytearray(turn_parquet.read_bytes())
    for k, position in enumerate(np.linspace(0, len(good) - 1, 6).astype(int)):
        broken = bytearray(good)
        broken[position] ^= 0xFF
        path = tmp_path / f"flip{k}.parquet"
        path.write_bytes(bytes(broken))
        result = invoke(["inspect", path, "--plot", tmp_path / f"flip{k}.png"])
        if result.exit_code != 0:
            assert_user_error(result, f"flip{k}.parquet")


def test_inspect_never_overwrites_its_input(
    invoke: Invoke, tmp_path: Path, turn_parquet: Path
) -> None:
    dataset = Path(shutil.copy(turn_parquet, tmp_path / "turn.parquet"))
    before = dataset.read_bytes()
    assert_user_error(invoke(["inspect", dataset, "--plot", dataset]), "overwrite")
    assert_user_error(invoke(["inspect", dataset, "--json", dataset]), "overwrite")
    assert dataset.read_bytes() == before


def test_unwritable_json_is_one_line(invoke: Invoke, tmp_path: Path, turn_parquet: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    result = invoke(
        ["inspect", turn_parquet, "--plot", tmp_path / "p.png", "--json", blocker / "s.json"]
    )
    assert_user_error(result, "s.json")
