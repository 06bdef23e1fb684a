"""``import-csv`` (forgiving), ``import-bag``, ``import-lerobot`` and ``export-lerobot``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from cli_testing import CSV_HEADER, Invoke, assert_user_error, digest, files_in, log_rows, write_csv

from behavior_hmm import data
from behavior_hmm.data import CONTROL_PERIOD, Dataset
from behavior_hmm.models import SBLM
from behavior_hmm.sim import make_env
from behavior_hmm.teach import collect


@pytest.fixture(scope="module")
def turn_demos() -> Dataset:
    starts = [{"angle": float(a), "distance": 0.5} for a in range(-170, 181, 40)]
    return collect("turn", starts, sim="kinematic", seed=0)


def _robot_log(ds: Dataset, path: Path, dt: float) -> Path:
    """A 1/dt Hz log: named runs, time in ms, bearing in rad, no velocity columns."""
    lines = ["run,time_ms,distance,bearing,left,right"]
    for ep in ds.episodes():
        t = np.arange(0.0, ep.t[-1] + 1e-9, dt)
        cols = [np.interp(t, ep.t, ep.channel(c)) for c in ("distance", "angle", "left", "right")]
        for i in range(len(t)):
            lines.append(
                f"run-{chr(97 + ep.id)},{t[i] * 1000:.3f},{cols[0][i]:.6f},"
                f"{math.radians(cols[1][i]):.9f},{cols[2][i]:.6f},{cols[3][i]:.6f}"
            )
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


CSV_OPTIONS = ["--map", "episode=run", "--map", "t=time_ms", "--map", "angle=bearing"]
CSV_OPTIONS += ["--unit", "t=ms", "--unit", "angle=rad"]
DERIVE = ["--derive", "linear_velocity,angular_velocity"]


def test_a_50_hz_log_imports_trains_and_generates(
    invoke: Invoke, tmp_path: Path, turn_demos: Dataset
) -> None:
    log = _robot_log(turn_demos, tmp_path / "robot.csv", dt=0.02)
    out = tmp_path / "turn.parquet"
    result = invoke(["import-csv", log, *CSV_OPTIONS, *DERIVE, "--resample", "-o", out])
    assert result.exit_code == 0, result.output
    assert "warning" not in result.stderr
    ds = data.read(out)
    assert len(ds) == len(turn_demos)
    assert ds.metadata["source"]["episode_ids"] == [f"run-{chr(97 + i)}" for i in range(len(ds))]
    np.testing.assert_allclose(np.diff(ds.episode(0).t), CONTROL_PERIOD, atol=1e-9)
    model = SBLM(inputs=("angle",), epochs=60, random_state=0).fit(ds)
    trace = model.generate(make_env("kinematic"), start={"angle": 100})
    assert trace.goal_reached, trace.reason


def test_a_log_at_another_rate_warns_on_one_line(
    invoke: Invoke, tmp_path: Path, turn_demos: Dataset
) -> None:
    log = _robot_log(turn_demos.subset([0]), tmp_path / "robot.csv", dt=0.02)
    out = tmp_path / "turn.parquet"
    result = invoke(["import-csv", log, *CSV_OPTIONS, *DERIVE, "-o", out])
    assert result.exit_code == 0, result.output
    (line,) = result.stderr.splitlines()
    assert line.startswith("warning: ") and "20 ms" in line and "--resample" in line
    assert out.exists()


def test_import_csv_reads_a_mapping_file(
    invoke: Invoke, tmp_path: Path, turn_demos: Dataset
) -> None:
    log = _robot_log(turn_demos.subset([0, 1]), tmp_path / "robot.csv", dt=0.016)
    mapping = tmp_path / "robot.toml"
    mapping.write_text(
        'derive = ["linear_velocity", "angular_velocity"]\n'
        '[map]\nepisode = "run"\nt = "time_ms"\nangle = "bearing"\n'
        '[unit]\nt = "ms"\nangle = "deg"\n',
        encoding="utf-8",
    )
    out = tmp_path / "turn.parquet"
    # the command line wins over the file: the bearing is in radians
    result = invoke(["import-csv", log, "--map-file", mapping, "--unit", "angle=rad", "-o", out])
    assert result.exit_code == 0, result.output
    ds = data.read(out)
    assert ds.metadata["source"]["units"] == {"t": "ms", "angle": "rad"}
    np.testing.assert_allclose(ds.episode(0).channel("angle")[0], -170.0, atol=1e-6)
    mapping.write_text("[map]\nangle = 1\n", encoding="utf-8")
    assert_user_error(invoke(["import-csv", log, "--map-file", mapping, "-o", out]), "robot.toml")


def test_import_csv_names_every_unexpected_column(invoke: Invoke, tmp_path: Path) -> None:
    log = write_csv(
        tmp_path / "log.csv", [*CSV_HEADER, "battery", "note"], [[*r, "1", "x"] for r in log_rows()]
    )
    out = tmp_path / "out.parquet"
    line = assert_user_error(
        invoke(["import-csv", log, "-o", out]), "log.csv", "'battery'", "'note'"
    )
    assert "--drop" in line
    result = invoke(["import-csv", log, "--drop", "battery", "--drop", "note", "-o", out])
    assert result.exit_code == 0, result.output


# --- ROS bags ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def bags(turn_demos: Dataset, tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    pytest.importorskip("rosbags")
    from bag_writing import write_bag

    folder = tmp_path_factory.mktemp("bags")
    return [
        write_bag(turn_demos.subset([0]), folder / "one.bag", ros=1, twist=True),
        write_bag(turn_demos.subset([1]), folder / "two", ros=2, twist=True),
    ]


BAG_MAP = """
derive = ["linear_velocity"]
twist = "/cmd_vel"

[map]
distance = "/object_distance:data"
angle = "/object_bearing:data"
angular_velocity = "/yaw_rate"

[unit]
angle = "rad"
angular_velocity = "rad/s"
"""


def test_import_bag_with_a_mapping_file(
    invoke: Invoke, tmp_path: Path, bags: list[Path], turn_demos: Dataset
) -> None:
    mapping = tmp_path / "bags.toml"
    mapping.write_text(BAG_MAP, encoding="utf-8")
    out = tmp_path / "bags.parquet"
    result = invoke(["import-bag", *bags, "--map-file", mapping, "--behavior", "turn", "-o", out])
    assert result.exit_code == 0, result.output
    assert f"wrote {out}: 2 episodes" in result.stdout
    ds = data.read(out)
    assert ds.lengths.tolist() == turn_demos.lengths[:2].tolist()
    np.testing.assert_allclose(ds.commands, turn_demos.subset([0, 1]).commands, atol=1e-9)
    assert ds.metadata["behavior"] == "turn"
    assert ds.metadata["source"]["bags"] == ["one.bag", "two"]


def test_import_bag_options_on_the_command_line(
    invoke: Invoke, tmp_path: Path, bags: list[Path]
) -> None:
    out = tmp_path / "bags.parquet"
    args = ["import-bag", bags[0], "--map", "angle=/object_bearing:data", "--unit", "angle=rad"]
    args += ["--map", "distance=/object_distance", "--twist", "/cmd_vel", *DERIVE]
    args += ["--wheel-radius", "0.021", "--track-width", "0.053", "--split-gap", "0.5"]
    result = invoke([*args, "-o", out])
    assert result.exit_code == 0, result.output
    assert len(data.read(out)) == 1


@pytest.mark.parametrize(
    ("options", "needles"),
    [
        (["--map", "angle=/bearing:data"], ["one.bag", "/bearing:data", "no topic /bearing"]),
        (["--map", "angle=/object_bearing:value"], ["one.bag", "no field 'value'"]),
        (["--map", "angle=/cmd_vel:linear"], ["one.bag", "/cmd_vel:linear", "not a number"]),
        (["--map", "angle=/object_bearing", "--unit", "angle=furlong"], ["unknown unit"]),
        (["--map", "angle"], ["--map expects KEY=VALUE"]),
    ],
)
def test_import_bag_errors_are_one_line_and_nothing_is_written(
    invoke: Invoke, tmp_path: Path, bags: list[Path], options: list[str], needles: list[str]
) -> None:
    out = tmp_path / "out.parquet"
    args = ["import-bag", bags[0], "--map", "distance=/object_distance", "--twist", "/cmd_vel"]
    result = invoke([*args, *DERIVE, *options, "-o", out])
    assert_user_error(result, *needles)
    assert files_in(tmp_path) == set()


def test_import_bag_keeps_the_old_output_on_failure(
    invoke: Invoke, tmp_path: Path, bags: list[Path]
) -> None:
    out = tmp_path / "out.parquet"
    out.write_bytes(b"old")
    before = digest(out)
    args = ["import-bag", bags[0], "--twist", "/cmd_vel", "--map", "distance=/nowhere", *DERIVE]
    assert_user_error(invoke([*args, "--map", "angle=/object_bearing", "-o", out]), "/nowhere")
    assert digest(out) == before
    assert files_in(tmp_path) == {"out.parquet"}


# --- LeRobot ---------------------------------------------------------------------------------


def test_export_and_import_lerobot(invoke: Invoke, tmp_path: Path, turn_demos: Dataset) -> None:
    source = data.write(turn_demos, tmp_path / "turn.parquet")
    folder = tmp_path / "lerobot" / "turn"
    result = invoke(["export-lerobot", source, folder, "--task", "turn to the object"])
    assert result.exit_code == 0, result.output
    assert "LeRobot dataset v3.0" in result.stdout
    info = json.loads((folder / "meta" / "info.json").read_text())
    assert info["total_episodes"] == len(turn_demos)
    back = tmp_path / "back.parquet"
    result = invoke(["import-lerobot", folder, "-o", back])
    assert result.exit_code == 0, result.output
    ds = data.read(back)
    assert ds.lengths.tolist() == turn_demos.lengths.tolist()
    np.testing.assert_allclose(ds.sensors, turn_demos.sensors, rtol=1e-6, atol=1e-5)
    # a second export into the now full folder is refused, the folder untouched
    before = sorted(p.name for p in folder.rglob("*"))
    assert_user_error(invoke(["export-lerobot", source, folder]), "not an empty folder")
    assert sorted(p.name for p in folder.rglob("*")) == before


def test_generated_traces_export_too(
    invoke: Invoke, tmp_path: Path, turn_demos: Dataset, turn_model: SBLM
) -> None:
    traces = []
    for k, angle in enumerate((100.0, -60.0)):
        trace = turn_model.generate(make_env("kinematic"), start={"angle": angle})
        trace.write(tmp_path / f"run{k}.parquet")
        traces.append(tmp_path / f"run{k}.parquet")
    demos = data.write(turn_demos.subset([0]), tmp_path / "demo.parquet")
    folder = tmp_path / "lr"
    result = invoke(["export-lerobot", *traces, demos, folder, "--task", "turn"])
    assert result.exit_code == 0, result.output
    assert "3 episodes" in result.stdout
    back = data.import_lerobot(folder)
    assert back.lengths[2] == turn_demos.lengths[0]
    assert back.metadata["sources"] == ["run0.parquet", "run1.parquet", "demo.parquet"]
    assert back.metadata["trace"]["goal_reached"] is True


def test_import_lerobot_errors(invoke: Invoke, tmp_path: Path, turn_demos: Dataset) -> None:
    out = tmp_path / "out.parquet"
    empty = tmp_path / "empty"
    empty.mkdir()
    assert_user_error(invoke(["import-lerobot", empty, "-o", out]), "no meta/info.json")
    folder = data.export_lerobot(turn_demos, tmp_path / "lr")
    line = assert_user_error(
        invoke(["import-lerobot", folder, "--map", "angle=observation.state:bearing", "-o", out]),
        "no element 'bearing'",
    )
    assert "distance, linear_velocity, angle, angular_velocity" in line
    assert not out.exists()


def _point_mass_log(path: Path) -> Path:
    """A 2-D point mass driven by velocity commands toward (0, 0): its own channels."""
    lines = ["episode,t,x,y,vx,vy"]
    for ep, (x0, y0) in enumerate(((0.4, 0.2), (-0.3, 0.5), (0.1, -0.6))):
        x, y = x0, y0
        for k in range(120):
            vx, vy = -2.0 * x, -2.0 * y
            lines.append(f"{ep},{k * CONTROL_PERIOD:.3f},{x:.6f},{y:.6f},{vx:.6f},{vy:.6f}")
            x, y = x + vx * CONTROL_PERIOD, y + vy * CONTROL_PERIOD
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_a_mapping_file_declares_the_robots_channels_commands_and_goal(
    invoke: Invoke, tmp_path: Path
) -> None:
    """``channel``, ``command`` and ``[goal]`` in the mapping file say what ``--channel``,
    ``--command`` and ``--goal`` say; the command line replaces them as a whole."""
    log = _point_mass_log(tmp_path / "mass.csv")
    mapping = tmp_path / "mass.toml"
    mapping.write_text(
        'channel = ["x:m:-1:1:0.01", "y:m:-1:1:0.01"]\n'
        'command = ["vx:m/s:-2:2", "vy:m/s:-2:2"]\n'
        "[goal]\nx = 0.0\ny = 0.0\n",
        encoding="utf-8",
    )
    out = tmp_path / "mass.parquet"
    result = invoke(["import-csv", log, "--map-file", mapping, "-o", out])
    assert result.exit_code == 0, result.output
    ds = data.read(out)
    assert set(ds.sensor_channels) == {"x", "y"}
    assert [spec.name for spec in ds.command_specs] == ["vx", "vy"]
    assert ds.metadata["goal"] == {"x": 0.0, "y": 0.0}
    # --goal on the command line wins over the file's [goal]
    result = invoke(["import-csv", log, "--map-file", mapping, "--goal", "x=0.05", "-o", out])
    assert result.exit_code == 0, result.output
    assert data.read(out).metadata["goal"] == {"x": 0.05}
    before = digest(out)
    # a goal that is not a number, and a goal on a channel without a tolerance: one line
    # naming the file or the field, nothing written
    mapping.write_text(mapping.read_text(encoding="utf-8") + 'z = "far"\n', encoding="utf-8")
    assert_user_error(invoke(["import-csv", log, "--map-file", mapping, "-o", out]), "[goal] z")
    mapping.write_text(
        'channel = ["x:m:-1:1", "y:m:-1:1:0.01"]\ncommand = ["vx:m/s:-2:2", "vy:m/s:-2:2"]\n'
        "[goal]\nx = 0.0\n",
        encoding="utf-8",
    )
    assert_user_error(invoke(["import-csv", log, "--map-file", mapping, "-o", out]), "goal")
    assert digest(out) == before
