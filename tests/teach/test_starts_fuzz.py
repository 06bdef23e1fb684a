"""Fuzzing the starts-CSV reader: validated starts or a DatasetError, nothing else."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from behavior_hmm.errors import DatasetError
from behavior_hmm.teach import read_starts

FUZZ = settings(max_examples=150, deadline=None)

COLUMNS = ["angle", "distance", "goal_angle", "goal_distance", "Angle", "speed", "", " angle"]
CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["0", "0.5", "1.2", "1.21", "-180", "180.5", "", "nan", "1_0", '"1"', "x"]),
    st.text(max_size=6),
)
STRUCTURED = st.tuples(
    st.lists(st.sampled_from(COLUMNS), min_size=0, max_size=4),
    st.lists(st.lists(CELLS, min_size=0, max_size=5), max_size=4),
    st.sampled_from([",", ";"]),
).map(lambda t: "\n".join([t[2].join(t[0]), *(t[2].join(row) for row in t[1])]).encode())
CONTENT = st.one_of(STRUCTURED, st.binary(max_size=200), st.text(max_size=200).map(str.encode))

ALLOWED = {"angle", "distance", "goal_angle", "goal_distance"}


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("starts_fuzz")


@FUZZ
@given(content=CONTENT)
def test_read_starts_returns_valid_starts_or_a_dataset_error(folder: Path, content: bytes) -> None:
    path = folder / "starts.csv"
    path.write_bytes(content)
    try:
        starts = read_starts(path)
    except DatasetError as err:
        assert "starts.csv" in str(err)
        return
    assert starts
    for start in starts:
        assert set(start) <= ALLOWED and ({"angle", "distance"} & set(start))
        assert all(isinstance(v, float) and math.isfinite(v) for v in start.values())
        for key in ("angle", "goal_angle"):
            assert -180.0 <= start.get(key, 0.0) <= 180.0
        for key in ("distance", "goal_distance"):
            assert 0.0 <= start.get(key, 0.0) <= 1.2


@pytest.mark.parametrize(
    "header",
    ["angle,angle", "angle,distance,angle", "distance, distance", "angle,goal_angle,angle"],
)
def test_a_repeated_column_is_refused(tmp_path: Path, header: str) -> None:
    path = tmp_path / "dup.csv"
    cells = ",".join("0" for _ in header.split(","))
    path.write_text(f"{header}\n{cells}\n", encoding="utf-8")
    with pytest.raises(DatasetError, match="twice") as caught:
        read_starts(path)
    assert caught.value.file == str(path) and caught.value.field is not None


def test_a_file_the_csv_module_cannot_read_is_our_error(tmp_path: Path) -> None:
    path = tmp_path / "huge.csv"
    path.write_text('angle\n"' + "1" * 200_000 + '"\n', encoding="utf-8")  # beyond field limit
    with pytest.raises(DatasetError, match="not a readable CSV"):
        read_starts(path)
