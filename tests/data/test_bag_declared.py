"""ROS bags with a robot's own channels and commands (issue 26).

``import_bags(channels=, commands=)`` and ``import-bag --channel/--command``: a bag
with a gripper topic beside the wheels imports as a dataset commanding left, right and
grip; a finger-opening topic as a declared sensor channel; a point mass's own channels
(x, y commanded by vx, vy) without any of the data contract's four.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from user_errors import assert_user_error

pytest.importorskip("rosbags")

from bag_writing import write_floats
from typer.testing import CliRunner, Result

from behavior_hmm.cli import app
from behavior_hmm.data import SENSOR_CHANNELS, Dataset, import_bags, read
from behavior_hmm.errors import ConfigError, DatasetError

GRIP = {"name": "grip", "unit": "m/s", "range": [-0.02, 0.02], "rest": 0.001}
OPENING = {"name": "opening", "unit": "m", "range": [0.0, 0.035], "tolerance": 0.001}
POINT = [
    {"name": "x", "unit": "m", "range": [-1.0, 1.0], "tolerance": 0.01},
    {"name": "y", "unit": "m", "range": [-1.0, 1.0], "tolerance": 0.01},
]
VELOCITY = [
    {"name": "vx", "unit": "m/s", "range": [-0.5, 0.5]},
    {"name": "vy", "unit": "m/s", "range": [-0.5, 0.5]},
]
START_NS = 1_700_000_000 * 10**9
N = 40


def _values(name: str) -> np.ndarray:
    """A smooth, plausible series for each channel (in its own unit)."""
    s = np.linspace(0.0, 1.0, N)
    return {
        "distance": 0.5 - 0.2 * s,
        "linear_velocity": np.full(N, 0.05),
        "angle": 90.0 * (1.0 - s),
        "angular_velocity": np.full(N, -20.0),
        "left": -2.0 + s,
        "right": 2.0 - s,
        "grip": -0.01 * (1.0 - s),
        "opening": 0.03 - 0.02 * s,
        "x": 0.8 * (1.0 - s),
        "y": -0.5 * (1.0 - s),
        "vx": np.full(N, -0.25),
        "vy": np.full(N, 0.15),
    }[name]


def _bag(path: Path, ros: int, channels: list[str]) -> Path:
    """One episode: each channel a std_msgs/Float64 topic ``/<name>``, 16 ms apart."""
    stamps = START_NS + 16_000_000 * np.arange(N)
    topics = {
        f"/{name}": list(zip(stamps.tolist(), _values(name).tolist(), strict=True))
        for name in channels
    }
    return write_floats(path, ros, topics)


def _mapping(names: list[str]) -> dict[str, str]:
    return {name: f"/{name}:data" for name in names}


WHEELED = [*SENSOR_CHANNELS, "left", "right"]


@pytest.fixture(scope="module", params=[1, 2], ids=["ros1", "ros2"])
def gripper_bag(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    ros = int(request.param)
    folder = tmp_path_factory.mktemp(f"grip{ros}")
    name = "run.bag" if ros == 1 else "run"
    return _bag(folder / name, ros, [*WHEELED, "grip", "opening"])


@pytest.fixture(scope="module")
def point_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _bag(tmp_path_factory.mktemp("point") / "point", 2, ["x", "y", "vx", "vy"])


def _invoke(*args: object) -> Result:
    return CliRunner().invoke(app, [str(a) for a in args])


def _check_values(ds: Dataset) -> None:
    for name in (*ds.sensor_channels, *ds.command_channels):
        np.testing.assert_allclose(ds.column(name), _values(name), atol=1e-12, err_msg=name)
    np.testing.assert_allclose(ds.t, 0.016 * np.arange(N), atol=1e-9)


# -- the Python API ----------------------------------------------------------------------


def test_a_gripper_topic_becomes_a_third_command(gripper_bag: Path) -> None:
    ds = import_bags(
        [gripper_bag],
        mapping=_mapping([*WHEELED, "grip"]),
        commands=["left", "right", GRIP],
        metadata={"behavior": "turn"},
    )
    assert ds.command_channels == ("left", "right", "grip")
    assert ds.sensor_channels == SENSOR_CHANNELS
    _check_values(ds)
    md = ds.metadata
    assert [c["name"] for c in md["commands"]] == ["left", "right", "grip"]
    assert md["commands"][2] == {**GRIP, "kind": "command"}
    assert md["source"]["mapping"]["grip"] == "/grip:data"
    assert ds.command_specs[2].rest == 0.001


def test_a_declared_sensor_channel_and_command_together(gripper_bag: Path) -> None:
    ds = import_bags(
        [gripper_bag],
        mapping=_mapping([*WHEELED, "grip", "opening"]),
        channels=[OPENING],
        commands=["left", "right", GRIP],
    )
    assert ds.sensor_channels == (*SENSOR_CHANNELS, "opening")
    assert ds.command_channels == ("left", "right", "grip")
    assert ds.metadata["channels"] == [OPENING]
    assert ds.channel_specs[-1].tolerance == 0.001
    _check_values(ds)


def test_a_robots_own_channels_only(point_bag: Path) -> None:
    ds = import_bags(
        [point_bag],
        mapping=_mapping(["x", "y", "vx", "vy"]),
        channels=POINT,
        commands=VELOCITY,
        metadata={"behavior": "reach"},
    )
    assert ds.sensor_channels == ("x", "y") and ds.command_channels == ("vx", "vy")
    _check_values(ds)
    assert ds.metadata["channels"] == POINT


@pytest.mark.parametrize(
    ("kw", "error", "match"),
    [
        # the gripper cannot be mapped before it is declared; the message says how
        (
            {"mapping": _mapping([*WHEELED, "grip"])},
            ConfigError,
            "declare a robot's own with --channel or --command",
        ),
        # a declared command needs a topic
        (
            {"mapping": _mapping(WHEELED), "commands": ["left", "right", GRIP]},
            ConfigError,
            r"no topic for channel\(s\) grip",
        ),
        # a declared channel needs a topic
        (
            {"mapping": _mapping(WHEELED), "channels": [OPENING]},
            ConfigError,
            r"no topic for channel\(s\) opening",
        ),
        # a declared channel is read in its declared unit
        (
            {
                "mapping": _mapping([*WHEELED, "grip"]),
                "commands": ["left", "right", GRIP],
                "units": {"grip": "mm/s"},
            },
            ConfigError,
            r"declared unit \(m/s\)",
        ),
        # a twist gives the wheels: they must be among the commands
        (
            {"mapping": _mapping(["x", "y"]), "channels": POINT, "commands": VELOCITY},
            ConfigError,
            "--twist gives the wheels left, right",
        ),
        # a sensor channel is not a command
        (
            {"mapping": _mapping(WHEELED), "commands": ["left", "angle"]},
            DatasetError,
            "not a command",
        ),
    ],
)
def test_refusals(gripper_bag: Path, kw: dict[str, Any], error: type, match: str) -> None:
    if "twist gives" in match:
        kw = {**kw, "twist": "/cmd_vel", "wheel_radius": 0.02, "track_width": 0.05}
    with pytest.raises(error, match=match):
        import_bags([gripper_bag], **kw)


def test_a_declared_channel_out_of_its_bounds_names_the_topic(tmp_path: Path) -> None:
    bag = _bag(tmp_path / "run", 2, [*WHEELED, "grip"])
    tiny = {**GRIP, "range": [-0.0001, 0.0001]}  # the bag's grip is 100 times beyond it
    with pytest.raises(DatasetError, match="absurd value") as info:
        import_bags([bag], mapping=_mapping([*WHEELED, "grip"]), commands=["left", "right", tiny])
    assert info.value.field == "grip (/grip:data)"


# -- the command line ------------------------------------------------------------------


def _map_args(names: list[str]) -> list[str]:
    return [arg for name in names for arg in ("--map", f"{name}=/{name}:data")]


def test_cli_imports_a_bag_with_a_gripper(gripper_bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "grip.parquet"
    args: list[object] = ["import-bag", gripper_bag, *_map_args([*WHEELED, "grip", "opening"])]
    args += ["--channel", "opening:m:0:0.035:0.001"]
    args += ["--command", "left", "--command", "right", "--command", "grip:m/s:-0.02:0.02:0.001"]
    args += ["--behavior", "turn", "-o", out]
    result = _invoke(*args)
    assert result.exit_code == 0, result.output
    ds = read(out)
    assert ds.command_channels == ("left", "right", "grip")
    assert ds.sensor_channels == (*SENSOR_CHANNELS, "opening")
    assert ds.metadata["behavior"] == "turn"
    assert ds.command_specs[2].rest == 0.001 and ds.channel_specs[-1].tolerance == 0.001
    _check_values(ds)


def test_cli_imports_a_robots_own_channels(point_bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "point.parquet"
    args: list[object] = ["import-bag", point_bag, *_map_args(["x", "y", "vx", "vy"])]
    args += ["--channel", "x:m:-1:1:0.01", "--channel", "y:m:-1:1:0.01"]
    args += ["--command", "vx:m/s:-0.5:0.5", "--command", "vy:m/s:-0.5:0.5", "-o", out]
    result = _invoke(*args)
    assert result.exit_code == 0, result.output
    ds = read(out)
    assert ds.sensor_channels == ("x", "y") and ds.command_channels == ("vx", "vy")
    _check_values(ds)


def test_cli_refuses_an_undeclared_gripper_in_one_line(gripper_bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "grip.parquet"
    result = _invoke("import-bag", gripper_bag, *_map_args([*WHEELED, "grip"]), "-o", out)
    assert_user_error(result, "--map grip: unknown channel", "--command")
    args = ["import-bag", gripper_bag, *_map_args(WHEELED), "--command", "grip:m/s", "-o", out]
    assert_user_error(_invoke(*args), "--command expects NAME:UNIT:LO:HI[:REST]")
    args = ["import-bag", gripper_bag, *_map_args(WHEELED), "--channel", "ir0:m:1:x", "-o", out]
    assert_user_error(_invoke(*args), "--channel ir0:m:1:x: LO, HI and TOLERANCE must be numbers")
    assert not out.exists()
