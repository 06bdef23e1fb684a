"""Importing users' CSV logs: mapping, units, episodes, and every kind of bad file."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from behavior_hmm.data import Dataset, import_csv, read, write
from behavior_hmm.errors import ConfigError, DatasetError

HEADER = "episode,t,distance,linear_velocity,angle,angular_velocity,left,right"


def _rows(n: int = 5, episode: int = 0, angle0: float = 30.0) -> list[str]:
    return [
        f"{episode},{0.016 * i:.3f},0.5,0.0,{angle0 - 2.0 * i},-125.0,-0.5,0.5" for i in range(n)
    ]


def _csv(tmp_path: Path, lines: list[str], name: str = "log.csv") -> Path:
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _expect(path: Path, match: str, **kw: Any) -> DatasetError:
    where = {k: kw.pop(k) for k in ("episode", "row", "field", "line") if k in kw}
    with pytest.raises(DatasetError, match=match) as info:
        import_csv(path, **kw)
    err = info.value
    assert err.file == str(path)
    if "line" in where:
        assert f"(CSV line {where.pop('line')})" in str(err)
    for key, value in where.items():
        assert getattr(err, key) == value, (key, str(err))
    assert "\n" not in str(err)
    return err


def test_plain_import(tmp_path: Path) -> None:
    path = _csv(tmp_path, [HEADER, *_rows(5, 0), *_rows(3, 7)])
    ds = import_csv(path, metadata={"behavior": "turn"})
    assert isinstance(ds, Dataset)
    assert ds.episode_ids.tolist() == [0, 7] and ds.lengths.tolist() == [5, 3]
    np.testing.assert_allclose(ds.episode(0).channel("angle"), [30, 28, 26, 24, 22])
    md = ds.metadata
    assert md["behavior"] == "turn" and md["source"]["format"] == "csv"
    assert md["source"]["file"] == "log.csv"


def test_mapping_units_and_wrapping(tmp_path: Path) -> None:
    header = "run,time_ms,dist_mm,v_mm_s,bearing_rad,omega_rad_s,wl_rpm,wr_rpm,mode"
    lines = [
        header,
        f"1,0,500,100,{math.pi},1.0,60,-60,turn",
        f"1,16,480,100,{-math.pi + 0.1},1.0,30,-30,turn",
        "1,32,460,100,7.0,1.0,0,0,approach",
    ]
    mapping = {
        "episode": "run",
        "t": "time_ms",
        "distance": "dist_mm",
        "linear_velocity": "v_mm_s",
        "angle": "bearing_rad",
        "angular_velocity": "omega_rad_s",
        "left": "wl_rpm",
        "right": "wr_rpm",
        "behavior": "mode",
    }
    units = {
        "t": "ms",
        "distance": "mm",
        "linear_velocity": "mm/s",
        "angle": "rad",
        "angular_velocity": "rad/s",
        "left": "rpm",
        "right": "rpm",
    }
    ds = import_csv(_csv(tmp_path, lines), mapping=mapping, units=units)
    ep = ds.episode(0)
    np.testing.assert_allclose(ep.t, [0.0, 0.016, 0.032])
    np.testing.assert_allclose(ep.channel("distance"), [0.5, 0.48, 0.46])
    np.testing.assert_allclose(ep.channel("linear_velocity"), 0.1)
    angle = ep.channel("angle")
    assert angle[0] == pytest.approx(180.0)  # pi rad -> 180, kept (interval is (-180, 180])
    assert angle[1] == pytest.approx(-180.0 + math.degrees(0.1))
    assert angle[2] == pytest.approx(math.degrees(7.0) - 360.0)  # wrapped
    assert np.all((angle > -180.0) & (angle <= 180.0))
    np.testing.assert_allclose(ep.channel("angular_velocity"), math.degrees(1.0))
    np.testing.assert_allclose(ep.channel("left"), [2 * math.pi, math.pi, 0.0])
    np.testing.assert_allclose(ep.channel("right"), [-2 * math.pi, -math.pi, 0.0])
    assert ep.behavior.tolist() == ["turn", "turn", "approach"]
    assert ds.metadata["source"]["units"]["angle"] == "rad"


def test_centimetres_and_degrees_per_second_for_wheels(tmp_path: Path) -> None:
    lines = [HEADER, "0,0,50,10,0,0,180,-90"]
    ds = import_csv(
        _csv(tmp_path, lines),
        units={"distance": "cm", "linear_velocity": "cm/s", "left": "deg/s", "right": "deg/s"},
    )
    assert ds.column("distance")[0] == pytest.approx(0.5)
    assert ds.column("linear_velocity")[0] == pytest.approx(0.1)
    assert ds.commands[0].tolist() == pytest.approx([math.pi, -math.pi / 2])


def test_without_episode_column_the_file_is_one_episode(tmp_path: Path) -> None:
    header = HEADER.removeprefix("episode,")
    rows = [r.split(",", 1)[1] for r in _rows(4)]
    ds = import_csv(_csv(tmp_path, [header, *rows]))
    assert ds.episode_ids.tolist() == [0] and ds.lengths.tolist() == [4]


def test_split_on_time_reset(tmp_path: Path) -> None:
    header = HEADER.removeprefix("episode,")
    rows = [r.split(",", 1)[1] for r in [*_rows(4), *_rows(3), *_rows(2)]]
    path = _csv(tmp_path, [header, *rows])
    _expect(path, "time does not increase", episode=0, row=4, field="t", line=6)
    ds = import_csv(path, split_on_time_reset=True)
    assert ds.episode_ids.tolist() == [0, 1, 2] and ds.lengths.tolist() == [4, 3, 2]


def test_drop_ignores_extra_columns_and_whitespace_is_trimmed(tmp_path: Path) -> None:
    header = " " + HEADER.replace(",", " , ") + ",battery"
    rows = [r + ",12.1" for r in _rows(3)]
    ds = import_csv(_csv(tmp_path, [header, *rows]), drop=["battery"])
    assert ds.n_samples == 3


def test_blank_lines_bom_and_crlf(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    text = "\r\n".join([HEADER, *_rows(2), "", *_rows(2, 1)]) + "\r\n"
    path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    assert import_csv(path).lengths.tolist() == [2, 2]


def test_integral_float_episode_ids(tmp_path: Path) -> None:
    rows = [r.replace("0,", "3.0,", 1) for r in _rows(2)]
    assert import_csv(_csv(tmp_path, [HEADER, *rows])).episode_ids.tolist() == [3]


def test_csv_to_parquet_round_trip(tmp_path: Path) -> None:
    ds = import_csv(_csv(tmp_path, [HEADER, *_rows(6, 0), *_rows(4, 1, -170.0)]))
    assert read(write(ds, tmp_path / "d.parquet")) == ds


# --- bad files --------------------------------------------------------------------------


def test_missing_column(tmp_path: Path) -> None:
    header = HEADER.replace(",angular_velocity", "")
    rows = [",".join(r.split(",")[:5] + r.split(",")[6:]) for r in _rows(2)]
    _expect(_csv(tmp_path, [header, *rows]), "missing column", field="angular_velocity")


def test_extra_column(tmp_path: Path) -> None:
    rows = [r + ",1" for r in _rows(2)]
    err = _expect(_csv(tmp_path, [HEADER + ",battery", *rows]), "unexpected column")
    assert err.field == "battery"


def test_misnamed_column_suggests_the_right_name(tmp_path: Path) -> None:
    header = HEADER.replace("distance", "Distanse")
    err = _expect(_csv(tmp_path, [header, *_rows(2)]), "did you mean 'distance'")
    assert err.field == "Distanse"


def test_duplicate_column(tmp_path: Path) -> None:
    rows = [r + ",1" for r in _rows(2)]
    _expect(_csv(tmp_path, [HEADER + ",left", *rows]), "two columns give .left.", field="left")


def test_mapping_to_absent_column(tmp_path: Path) -> None:
    path = _csv(tmp_path, [HEADER, *_rows(2)])
    err = _expect(path, "not in the file", mapping={"angle": "bearing"})
    assert err.field == "bearing"


def test_mapping_clash(tmp_path: Path) -> None:
    header = HEADER + ",bearing"
    rows = [r + ",1" for r in _rows(2)]
    _expect(
        _csv(tmp_path, [header, *rows]), "two columns give 'angle'", mapping={"angle": "bearing"}
    )


def test_bad_mapping_and_units_are_config_errors(tmp_path: Path) -> None:
    path = _csv(tmp_path, [HEADER, *_rows(2)])
    with pytest.raises(ConfigError, match="did you mean 'angle'"):
        import_csv(path, mapping={"angel": "angle"})
    with pytest.raises(ConfigError, match="unknown unit 'furlong'"):
        import_csv(path, units={"distance": "furlong"})
    with pytest.raises(ConfigError, match="to both 'left' and 'right'"):
        import_csv(path, mapping={"left": "left", "right": "left"})
    with pytest.raises(ConfigError, match="takes no unit"):
        import_csv(path, units={"episode": "s"})


@pytest.mark.parametrize(
    ("cell", "match"),
    [("abc", "wrong type: 'abc' is not a number"), ("", "missing value"), ("1_0", "wrong type")],
)
def test_wrong_type_cell(tmp_path: Path, cell: str, match: str) -> None:
    rows = _rows(3) + _rows(4, 1)
    parts = rows[5].split(",")
    parts[4] = cell
    rows[5] = ",".join(parts)
    path = _csv(tmp_path, [HEADER, *rows])
    _expect(path, match, episode=1, row=2, field="angle", line=7)


def test_wrong_type_episode_id(tmp_path: Path) -> None:
    rows = _rows(3)
    rows[1] = "one" + rows[1][1:]
    _expect(_csv(tmp_path, [HEADER, *rows]), "not an integer", field="episode", line=3)


@pytest.mark.parametrize(
    ("cell", "match"),
    [("nan", "NaN value"), ("inf", "infinite value"), ("-1e400", "infinite value")],
)
def test_nan_and_inf(tmp_path: Path, cell: str, match: str) -> None:
    rows = _rows(4)
    parts = rows[2].split(",")
    parts[7] = cell
    rows[2] = ",".join(parts)
    _expect(_csv(tmp_path, [HEADER, *rows]), match, episode=0, row=2, field="right", line=4)


def test_nan_angle_is_not_hidden_by_wrapping(tmp_path: Path) -> None:
    rows = _rows(4)
    parts = rows[1].split(",")
    parts[4] = "inf"
    rows[1] = ",".join(parts)
    _expect(_csv(tmp_path, [HEADER, *rows]), "absurd angle inf", episode=0, row=1, field="angle")


def test_non_increasing_time(tmp_path: Path) -> None:
    rows = _rows(5)
    rows[3] = rows[3].replace("0.048", "0.016")
    path = _csv(tmp_path, [HEADER, *rows])
    _expect(path, "time does not increase", episode=0, row=3, field="t", line=5)


def test_empty_file(tmp_path: Path) -> None:
    _expect(_csv(tmp_path, []), "empty file")


def test_header_only_is_an_empty_episode(tmp_path: Path) -> None:
    _expect(_csv(tmp_path, [HEADER]), "no data rows")


@pytest.mark.parametrize(
    ("column", "value", "match"),
    [
        (2, "42", "absurd value 42 m"),
        (6, "9999", "absurd value 9999 rad/s"),
        (4, "1e9", "absurd angle 1e\\+09 deg"),
    ],
)
def test_absurd_values(tmp_path: Path, column: int, value: str, match: str) -> None:
    rows = _rows(4)
    parts = rows[3].split(",")
    parts[column] = value
    rows[3] = ",".join(parts)
    _expect(_csv(tmp_path, [HEADER, *rows]), match, episode=0, row=3, line=5)


def test_absurd_value_after_unit_conversion(tmp_path: Path) -> None:
    # 500 given as metres by mistake while units say cm: fine; given as mm -> 0.5 m: fine;
    # but 500 m with no unit is absurd.
    rows = [r.replace(",0.5,", ",500,") for r in _rows(2)]
    path = _csv(tmp_path, [HEADER, *rows])
    _expect(path, "absurd value 500 m", field="distance", row=0)
    assert import_csv(path, units={"distance": "mm"}).column("distance")[0] == 0.5


def test_bad_behavior_name(tmp_path: Path) -> None:
    rows = [r + ",turn" for r in _rows(3)]
    rows[2] = rows[2].replace(",turn", ",Turn Left")
    path = _csv(tmp_path, [HEADER + ",behavior", *rows])
    _expect(path, "invalid behavior name 'Turn Left'", episode=0, row=2, field="behavior", line=4)


def test_unknown_behavior_name(tmp_path: Path) -> None:
    rows = [r + ",turn" for r in _rows(3)]
    rows[1] = rows[1].replace(",turn", ",trun")
    path = _csv(tmp_path, [HEADER + ",behavior", *rows])
    err = _expect(
        path, "unknown behavior 'trun'", metadata={"behaviors": ["turn", "approach"]}, row=1
    )
    assert "did you mean 'turn'" in str(err)


def test_wrong_number_of_cells(tmp_path: Path) -> None:
    rows = _rows(3)
    rows[2] = rows[2] + ",7"
    _expect(_csv(tmp_path, [HEADER, *rows]), "9 cells but the header has 8", line=4)


def test_non_contiguous_episodes(tmp_path: Path) -> None:
    rows = [*_rows(3, 0), *_rows(2, 1), *_rows(2, 0, -10.0)]
    rows[5:] = [r.replace("0,0.0", "0,1.0", 1) for r in rows[5:]]
    _expect(_csv(tmp_path, [HEADER, *rows]), "not contiguous", episode=0, row=3, line=7)


def test_not_utf8(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    path.write_bytes(HEADER.encode() + b"\n\xff\xfe\x00garbage\n")
    _expect(path, "not UTF-8|not a valid CSV")


def test_nul_bytes(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    path.write_bytes(HEADER.encode() + b"\n0,0\x00,1\n")
    _expect(path, "not a text file \\(NUL byte on line 2\\)")


def test_parquet_given_as_csv(tmp_path: Path, small_ds: Dataset) -> None:
    path = write(small_ds, tmp_path / "d.parquet")
    _expect(path, "not UTF-8|not a valid CSV|column")


def test_missing_file(tmp_path: Path) -> None:
    _expect(tmp_path / "nope.csv", "no such file")
