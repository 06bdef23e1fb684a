"""Fuzzing the parsers: a Dataset or a DatasetError, never anything else, never a hang."""

from __future__ import annotations

from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from behavior_hmm.data import Dataset, import_csv, read, write
from behavior_hmm.errors import DatasetError

FUZZ = settings(
    max_examples=50, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)

NAMES = [
    "episode",
    "t",
    "distance",
    "linear_velocity",
    "angle",
    "angular_velocity",
    "left",
    "right",
    "behavior",
    "angel",
    "Left",
    "",
    "time",
]
CELLS = [
    "0",
    "1",
    "-1",
    "0.5",
    "0.016",
    "2",
    "179.9",
    "-180",
    "1e9",
    "nan",
    "inf",
    "",
    "abc",
    "turn",
    "Turn",
    "3.0",
    "1_0",
    " 7 ",
    '"1,2"',
    "\x00",
    "é",
]


def _parse(path: Path) -> None:
    try:
        result = read(path) if path.suffix == ".parquet" else import_csv(path)
    except DatasetError as err:
        assert "\n" not in str(err)
        return
    assert isinstance(result, Dataset)


@FUZZ
@given(st.binary(max_size=2000))
def test_random_bytes_as_parquet(tmp_path: Path, data: bytes) -> None:
    path = tmp_path / "f.parquet"
    path.write_bytes(data)
    _parse(path)


@FUZZ
@given(st.data())
def test_corrupted_parquet(tmp_path: Path, small_ds: Dataset, data: st.DataObject) -> None:
    good = tmp_path / "good.parquet"
    if not good.exists():
        write(small_ds, good)
    raw = bytearray(good.read_bytes())
    n_flips = data.draw(st.integers(1, 8))
    for _ in range(n_flips):
        i = data.draw(st.integers(0, len(raw) - 1))
        raw[i] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(0, len(raw)))
    path = tmp_path / "f.parquet"
    path.write_bytes(bytes(raw[:cut]) if data.draw(st.booleans()) else bytes(raw))
    _parse(path)


@FUZZ
@given(st.binary(max_size=2000))
def test_random_bytes_as_csv(tmp_path: Path, data: bytes) -> None:
    path = tmp_path / "f.csv"
    path.write_bytes(data)
    _parse(path)


@st.composite
def csv_text(draw: st.DrawFn) -> str:
    header = draw(st.lists(st.sampled_from(NAMES), min_size=1, max_size=10))
    if draw(st.booleans()):
        header = NAMES[:8] + draw(st.lists(st.sampled_from(NAMES), max_size=2))
    n_rows = draw(st.integers(0, 6))
    rows = []
    for _ in range(n_rows):
        width = len(header) + draw(st.sampled_from([0, 0, 0, -1, 1]))
        rows.append(",".join(draw(st.sampled_from(CELLS)) for _ in range(max(width, 0))))
    sep = draw(st.sampled_from(["\n", "\r\n"]))
    return sep.join([",".join(header), *rows])


@FUZZ
@given(csv_text())
def test_random_small_csv(tmp_path: Path, text: str) -> None:
    path = tmp_path / "f.csv"
    path.write_text(text, encoding="utf-8")
    _parse(path)


@FUZZ
@given(
    st.lists(
        st.tuples(
            st.integers(0, 2), st.floats(allow_nan=True, allow_infinity=True), st.floats(-200, 200)
        ),
        min_size=1,
        max_size=8,
    )
)
def test_valid_header_random_values(tmp_path: Path, rows: list[tuple[int, float, float]]) -> None:
    lines = ["episode,t,distance,linear_velocity,angle,angular_velocity,left,right"]
    lines += [f"{e},{t!r},0.5,0,{a!r},0,0,0" for e, t, a in rows]
    path = tmp_path / "f.csv"
    path.write_text("\n".join(lines), encoding="utf-8")
    _parse(path)
