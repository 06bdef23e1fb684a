"""Training grids (DESIGN §6), the shipped test starts, and reading starts files."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from behavior_hmm.data import ARENA_MAX_DISTANCE
from behavior_hmm.errors import ConfigError, DatasetError
from behavior_hmm.teach import check_start, default_starts, read_starts, test_starts

# pytest would collect ``test_starts`` as a test function; it is the function under test.
test_starts.__test__ = False  # type: ignore[attr-defined]


def _key(start: dict[str, float]) -> tuple[float, ...]:
    return tuple(round(start.get(k, float("nan")), 6) for k in ("angle", "distance"))


def test_turn_grid() -> None:
    grid = default_starts("turn")
    angles = [s["angle"] for s in grid]
    assert angles == [float(a) for a in range(-180, 181, 10) if a != 0]
    assert len(grid) == 36
    assert {s["distance"] for s in grid} == {0.5}


def test_approach_grid() -> None:
    grid = default_starts("approach")
    distances = [s["distance"] for s in grid]
    assert distances == pytest.approx([0.10 + 0.05 * i for i in range(19)])
    assert distances[-1] == 1.0  # exactly, no float drift
    assert {s["angle"] for s in grid} == {0.0}


def test_turn_approach_grid_has_edges() -> None:
    grid = default_starts("turn-approach")
    keys = {_key(s) for s in grid}
    assert len(keys) == len(grid) == 18 * 10 + 10 + 18
    assert (-180.0, 0.1) in keys and (180.0, 1.0) in keys
    assert all((0.0, d) in keys for d in (0.1, 0.5, 1.0))  # angle-0 edge
    assert all((a, 0.0) in keys for a in (-180.0, -20.0, 20.0, 180.0))  # distance-0 edge


def test_retreat_and_position_grids_are_inside_the_arena() -> None:
    retreat = default_starts("retreat")
    assert all(s["goal_distance"] > s["distance"] for s in retreat)
    position = default_starts("position")
    assert {s["goal_distance"] for s in position} == {0.0, 0.25, 0.5, 0.75, 1.0}
    assert all(abs(s["distance"] - s["goal_distance"]) >= 0.05 for s in position)
    for start in retreat + position:
        check_start(start)


def test_unknown_behavior_has_no_grid() -> None:
    with pytest.raises(ConfigError, match="spin"):
        default_starts("spin")
    with pytest.raises(ConfigError, match="spin"):
        test_starts("spin")


@pytest.mark.parametrize("behavior", ["turn", "approach", "turn-approach"])
def test_shipped_test_starts_are_15_off_grid_and_in_the_arena(behavior: str) -> None:
    starts = test_starts(behavior)
    assert len(starts) == 15
    assert len({_key(s) for s in starts}) == 15
    grid = {_key(s) for s in default_starts(behavior)}
    for start in starts:
        check_start(start)
        full = {"angle": 0.0, "distance": 0.5, **start}
        assert _key(full) not in grid, start
        if behavior != "turn":
            assert 0.0 <= start["distance"] <= ARENA_MAX_DISTANCE


def _starts_file(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "starts.csv"
    path.write_text(text, encoding="utf-8")
    return path


def test_read_starts(tmp_path: Path) -> None:
    path = _starts_file(tmp_path, "angle, distance,goal_distance\n10,0.3,0.8\n-170.5 , 0,1.2\n")
    assert read_starts(path) == [
        {"angle": 10.0, "distance": 0.3, "goal_distance": 0.8},
        {"angle": -170.5, "distance": 0.0, "goal_distance": 1.2},
    ]
    assert read_starts(_starts_file(tmp_path, "distance\n0.25\n")) == [{"distance": 0.25}]


@pytest.mark.parametrize(
    ("text", "needles"),
    [
        ("", ["empty starts file"]),
        ("angle\n", ["no starts"]),
        ("speed\n1\n", ["field 'speed'", "unknown column"]),
        ("goal_distance\n0.5\n", ["needs a column angle and/or distance"]),
        ("angle\n10\nabc\n", ["row 3", "field 'angle'", "not a number"]),
        ("angle\ninf\n", ["row 2", "field 'angle'", "finite"]),
        ("angle,distance\n10\n", ["row 2", "field 'distance'"]),
        ("angle\n10,20\n", ["row 2", "more values than columns"]),
        ("angle\n180.5\n", ["row 2", "outside the arena", "angle 180.5"]),
        ("distance\n1.5\n", ["row 2", "outside the arena", "distance 1.5"]),
        ("distance\n-0.01\n", ["row 2", "outside the arena"]),
        ("distance,goal_distance\n0.2,1.3\n", ["row 2", "goal_distance"]),
        ("angle,goal_angle\n0,-200\n", ["row 2", "goal_angle"]),
    ],
)
def test_read_starts_names_file_row_and_field(
    tmp_path: Path, text: str, needles: list[str]
) -> None:
    path = _starts_file(tmp_path, text)
    with pytest.raises(DatasetError) as info:
        read_starts(path)
    message = str(info.value)
    assert "starts.csv" in message
    assert "\n" not in message
    for needle in needles:
        assert needle in message, (needle, message)


def test_read_starts_missing_or_binary_file(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match=r"nope\.csv"):
        read_starts(tmp_path / "nope.csv")
    binary = tmp_path / "bin.csv"
    binary.write_bytes(b"\xff\xfe\xfa\x00angle\n")
    with pytest.raises(DatasetError, match="UTF-8"):
        read_starts(binary)


def test_read_starts_accepts_a_byte_order_mark(tmp_path: Path) -> None:
    path = tmp_path / "excel.csv"
    path.write_bytes(b"\xef\xbb\xbfangle\n10\n")
    assert read_starts(path) == [{"angle": 10.0}]


def test_read_starts_row_is_the_line_number_after_blank_lines(tmp_path: Path) -> None:
    path = _starts_file(tmp_path, "angle\n10\n\n999\n")
    with pytest.raises(DatasetError, match="row 4"):
        read_starts(path)


def test_read_starts_suggests_the_closest_column(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match="did you mean 'angle'"):
        read_starts(_starts_file(tmp_path, "angel\n10\n"))


@settings(max_examples=50, deadline=None)
@given(st.text(alphabet=st.sampled_from("angledistc_,.-0123456789e\n \t\"'xX"), max_size=80))
def test_read_starts_fuzz(tmp_path_factory: pytest.TempPathFactory, text: str) -> None:
    """Any text gives validated starts or a DatasetError, nothing else."""
    path = tmp_path_factory.mktemp("fuzz") / "starts.csv"
    path.write_text(text, encoding="utf-8")
    try:
        starts = read_starts(path)
    except DatasetError:
        return
    assert starts
    for start in starts:
        check_start(start)
