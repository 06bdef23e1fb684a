"""The forgiving CSV import: names as episode ids, derived velocities, resampling,
every unexpected column in one message, mapping files."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from behavior_hmm.data import CONTROL_PERIOD, Dataset, SamplingWarning, import_csv
from behavior_hmm.data._mapfile import read_map_file
from behavior_hmm.errors import ConfigError, DatasetError
from behavior_hmm.teach import collect

HEADER = "episode,t,distance,linear_velocity,angle,angular_velocity,left,right"


def _rows(n: int = 5, episode: str = "0", angle0: float = 30.0, dt: float = 0.016) -> list[str]:
    return [f"{episode},{dt * i:.4f},0.5,0.0,{angle0 - 2.0 * i},-125.0,-0.5,0.5" for i in range(n)]


def _csv(tmp_path: Path, lines: list[str], name: str = "log.csv") -> Path:
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def turn_demos() -> Dataset:
    starts = [{"angle": a, "distance": 0.5} for a in (-120.0, -40.0, 60.0, 150.0)]
    return collect("turn", starts, sim="kinematic", seed=0)


def test_episode_names_become_ids_in_order_of_appearance(tmp_path: Path) -> None:
    lines = [HEADER, *_rows(3, "run-b"), *_rows(4, "run-a"), *_rows(2, "warm up")]
    ds = import_csv(_csv(tmp_path, lines))
    assert ds.episode_ids.tolist() == [0, 1, 2] and ds.lengths.tolist() == [3, 4, 2]
    assert ds.metadata["source"]["episode_ids"] == ["run-b", "run-a", "warm up"]


def test_errors_name_the_episode_by_its_name(tmp_path: Path) -> None:
    rows = [*_rows(3, "run-b"), *_rows(4, "run-a")]
    rows[5] = rows[5].replace(",0.5,", ",nan,", 1)
    with pytest.raises(DatasetError) as info:
        import_csv(_csv(tmp_path, [HEADER, *rows]))
    assert info.value.episode == "run-a" and info.value.row == 2
    assert "episode run-a, row 2, field 'distance'" in str(info.value)
    rows = [*_rows(3, "a"), *_rows(2, "b"), *_rows(2, "a", angle0=-10.0)]
    rows[5:] = [r.replace("a,0.0", "a,1.0", 1) for r in rows[5:]]
    with pytest.raises(DatasetError, match="not contiguous") as info:
        import_csv(_csv(tmp_path, [HEADER, *rows]))
    assert info.value.episode == "a"


def test_ids_mixing_numbers_and_names_are_refused(tmp_path: Path) -> None:
    rows = [*_rows(3, "1"), *_rows(3, "two")]
    with pytest.raises(DatasetError, match=r"'two' is not an integer.*all integers or all names"):
        import_csv(_csv(tmp_path, [HEADER, *rows]))


def test_quoted_cells_and_names(tmp_path: Path) -> None:
    rows = [r.replace("run a", '"run a"') for r in _rows(3, "run a")]
    rows += [r.replace("x,y", '"x,y"') for r in _rows(2, "x,y")]
    ds = import_csv(_csv(tmp_path, [HEADER, "", *rows]))
    assert ds.metadata["source"]["episode_ids"] == ["run a", "x,y"]
    assert ds.lengths.tolist() == [3, 2]
    bad = [*rows[:2], rows[2] + ",9"]
    with pytest.raises(DatasetError, match=r"9 cells but the header has 8 \(CSV line 4\)"):
        import_csv(_csv(tmp_path, [HEADER, *bad]))


def test_every_unexpected_column_in_one_line(tmp_path: Path) -> None:
    header = HEADER.replace("angle,", "angel,") + ",battery,note"
    rows = [r + ",12.1,x" for r in _rows(2)]
    with pytest.raises(DatasetError) as info:
        import_csv(_csv(tmp_path, [header, *rows]))
    message = str(info.value)
    assert "unexpected columns 'angel' (did you mean 'angle'?), 'battery', 'note'" in message
    assert "--drop" in message and "\n" not in message


def test_every_missing_column_in_one_line_with_a_hint_to_derive(tmp_path: Path) -> None:
    header = "t,distance,angle,left,right"
    rows = [",".join(r.split(",")[i] for i in (1, 2, 4, 6, 7)) for r in _rows(3)]
    with pytest.raises(DatasetError) as info:
        import_csv(_csv(tmp_path, [header, *rows]))
    message = str(info.value)
    assert "missing columns 'linear_velocity', 'angular_velocity'" in message
    assert "--derive linear_velocity,angular_velocity" in message


def _log_without_velocities(ds: Dataset, tmp_path: Path, dt: float | None = None) -> Path:
    """The demonstrations as a log: no velocities, angle in rad, time in ms, named runs.

    With ``dt`` each episode is first interpolated onto that period (a log at another rate).
    """
    lines = ["run,time_ms,distance,bearing,left,right"]
    for ep in ds.episodes():
        t = ep.t if dt is None else np.arange(0.0, ep.t[-1] + 1e-9, dt)
        angle = np.interp(t, ep.t, ep.channel("angle"))
        cols = [np.interp(t, ep.t, ep.channel(c)) for c in ("distance", "left", "right")]
        for i in range(len(t)):
            lines.append(
                f"demo-{ep.id},{t[i] * 1000:.6f},{cols[0][i]:.9f},{math.radians(angle[i]):.12f},"
                f"{cols[1][i]:.9f},{cols[2][i]:.9f}"
            )
    return _csv(tmp_path, lines, "robot.csv")


MAPPING = {"episode": "run", "t": "time_ms", "angle": "bearing"}
UNITS = {"t": "ms", "angle": "rad"}


def test_derived_velocities_follow_the_sign_conventions(
    turn_demos: Dataset, tmp_path: Path
) -> None:
    path = _log_without_velocities(turn_demos, tmp_path)
    ds = import_csv(path, mapping=MAPPING, units=UNITS, derive="linear_velocity,angular_velocity")
    assert ds.lengths.tolist() == turn_demos.lengths.tolist()
    assert ds.metadata["source"]["derived"] == ["linear_velocity", "angular_velocity"]
    # a turn in place: -d(angle)/dt is the recorded yaw rate (counter-clockwise positive)
    err = np.abs(ds.column("angular_velocity") - turn_demos.column("angular_velocity"))
    assert np.median(err) < 0.5 and err.max() < 5.0
    assert np.abs(ds.column("linear_velocity")).max() < 1e-3


def test_linear_velocity_is_the_closing_speed(tmp_path: Path) -> None:
    t = np.arange(20) * CONTROL_PERIOD
    lines = ["t,distance,angle,left,right"]
    for i in range(len(t)):  # drives at 0.1 m/s toward an object dead ahead
        lines.append(f"{t[i]:.3f},{0.5 - 0.1 * t[i]:.6f},0,2,2")
    ds = import_csv(_csv(tmp_path, lines), derive=["linear_velocity", "angular_velocity"])
    np.testing.assert_allclose(ds.column("linear_velocity"), 0.1, atol=1e-9)
    np.testing.assert_allclose(ds.column("angular_velocity"), 0.0, atol=1e-9)


def test_angular_velocity_is_unwrapped_across_180(tmp_path: Path) -> None:
    lines = ["t,distance,angle,left,right"]
    for i, a in enumerate([176.0, 178.0, 180.0, -178.0, -176.0]):
        lines.append(f"{0.016 * i:.3f},0.5,{a},-1,1")
    ds = import_csv(_csv(tmp_path, lines), derive="angular_velocity,linear_velocity")
    np.testing.assert_allclose(ds.column("angular_velocity"), -2.0 / 0.016)


def test_deriving_a_column_the_file_has_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="has a 'angular_velocity' column already"):
        import_csv(_csv(tmp_path, [HEADER, *_rows(3)]), derive="angular_velocity")
    with pytest.raises(ConfigError, match="cannot derive 'distance'"):
        import_csv(_csv(tmp_path, [HEADER, *_rows(3)]), derive="distance")
    no_velocities = [HEADER.replace(",linear_velocity", "")]
    no_velocities += [",".join(r.split(",")[:3] + r.split(",")[4:]) for r in _rows(3)]
    with pytest.raises(ConfigError, match="--unit linear_velocity: the channel is derived"):
        import_csv(
            _csv(tmp_path, no_velocities),
            derive="linear_velocity",
            units={"linear_velocity": "mm/s"},
        )


def test_a_log_at_another_rate_warns_unless_resampled(turn_demos: Dataset, tmp_path: Path) -> None:
    path = _log_without_velocities(turn_demos, tmp_path, dt=0.02)  # 50 Hz
    kw = {"mapping": MAPPING, "units": UNITS, "derive": "linear_velocity,angular_velocity"}
    with pytest.warns(SamplingWarning, match="20 ms, not the controller's 16 ms.*--resample"):
        slow = import_csv(path, **kw)  # type: ignore[arg-type]
    assert np.median(np.diff(slow.t[: slow.lengths[0]])) == pytest.approx(0.02)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ds = import_csv(path, resample=True, **kw)  # type: ignore[arg-type]
    for ep, demo in zip(ds.episodes(), turn_demos.episodes(), strict=True):
        np.testing.assert_allclose(np.diff(ep.t), CONTROL_PERIOD, atol=1e-9)
        assert ep.t[-1] <= demo.t[-1] + 1e-9 and len(ep) >= len(demo) - 2
        want = np.interp(ep.t, demo.t, demo.channel("angle"))
        np.testing.assert_allclose(ep.channel("angle"), want, atol=0.2)
    resampled = ds.metadata["source"]["resampled"]
    assert resampled["from_period_s"] == pytest.approx(0.02)
    assert resampled["to_period_s"] == CONTROL_PERIOD


def test_resampling_holds_the_behavior_and_wraps_angles(tmp_path: Path) -> None:
    lines = ["t,distance,linear_velocity,angle,angular_velocity,left,right,behavior"]
    for i, a in enumerate([170.0, 178.0, -174.0, -166.0]):
        mode = "turn" if i < 2 else "approach"
        lines.append(f"{0.04 * i:.2f},0.5,0,{a},200,1,-1,{mode}")
    ds = import_csv(_csv(tmp_path, lines), resample=True)
    np.testing.assert_allclose(ds.t, CONTROL_PERIOD * np.arange(8))
    angle = ds.column("angle")
    assert np.all((angle > -180) & (angle <= 180))
    np.testing.assert_allclose(np.diff(np.unwrap(angle, period=360.0)), 0.2 * 16, atol=1e-9)
    assert ds.behavior is not None
    assert ds.behavior.tolist() == ["turn"] * 5 + ["approach"] * 3  # held from t = 0.08 s


def test_no_warning_at_the_control_period(tmp_path: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        import_csv(_csv(tmp_path, [HEADER, *_rows(6)]))


def test_mapping_file(tmp_path: Path) -> None:
    path = tmp_path / "map.toml"
    path.write_text(
        'derive = ["angular_velocity"]\nresample = true\ndrop = ["note"]\n'
        '[map]\nangle = "bearing"\nt = "time_ms"\n[unit]\nangle = "rad"\nt = "ms"\n',
        encoding="utf-8",
    )
    loaded = read_map_file(path, "csv")
    assert loaded.map == {"angle": "bearing", "t": "time_ms"}
    assert loaded.unit == {"angle": "rad", "t": "ms"}
    assert loaded.options == {"derive": ["angular_velocity"], "resample": True, "drop": ["note"]}
    for text, match in [
        ("[map]\nangle = 3\n", "non-empty string"),
        ("twist = '/cmd_vel'\n", "unknown key 'twist'"),
        ("resample = 'yes'\n", "wrong type"),
        ("[map\n", "not (a )?valid TOML"),
    ]:
        path.write_text(text, encoding="utf-8")
        with pytest.raises(ConfigError, match=match):
            read_map_file(path, "csv")
    with pytest.raises(ConfigError, match="no such mapping file"):
        read_map_file(tmp_path / "nope.toml", "csv")
