"""LeRobot export and import keep every declared channel (issue 26).

A dataset with a robot's own sensor channels (``metadata["channels"]``), its own
command channels (``metadata["commands"]``, e.g. the wheels and a gripper), or its own
channels only (a point mass: x, y commanded by vx, vy) is exported with every sensor
channel in ``observation.state`` and every command in ``action``, and imported back the
same. A LeRobot dataset not made by us takes the declarations from the caller
(``channels=``, ``commands=``; ``import-lerobot --channel/--command``).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner, Result
from user_errors import assert_user_error

from behavior_hmm.cli import app
from behavior_hmm.data import SENSOR_CHANNELS, Dataset, export_lerobot, import_lerobot, read, write
from behavior_hmm.errors import ConfigError, DatasetError

IR = [
    {"name": "ir0", "unit": "m", "range": [0.0, 0.1], "tolerance": 0.001},
    {"name": "ir1", "unit": "m", "range": [0.0, 0.1], "label": "rear proximity"},
]
GRIP = {"name": "grip", "unit": "m/s", "range": [-0.02, 0.02], "rest": 0.001, "label": "fingers"}
OPENING = {"name": "opening", "unit": "m", "range": [0.0, 0.035], "tolerance": 0.001}
POINT = [
    {"name": "x", "unit": "m", "range": [-1.0, 1.0], "tolerance": 0.01},
    {"name": "y", "unit": "m", "range": [-1.0, 1.0], "tolerance": 0.01},
]
VELOCITY = [
    {"name": "vx", "unit": "m/s", "range": [-0.5, 0.5]},
    {"name": "vy", "unit": "m/s", "range": [-0.5, 0.5]},
]
CONTRACT = {
    "distance": (0.1, 1.0),
    "linear_velocity": (-0.1, 0.1),
    "angle": (-170.0, 170.0),
    "angular_velocity": (-60.0, 60.0),
}
WHEELS = {"left": (-5.0, 5.0), "right": (-5.0, 5.0)}


def _episodes(ranges: dict[str, tuple[float, float]], n: int = 25, k: int = 3) -> list[Any]:
    rng = np.random.default_rng(7)
    out = []
    for _ in range(k):
        ep: dict[str, Any] = {"t": np.arange(n) * 0.016}
        for name, (lo, hi) in ranges.items():
            ep[name] = rng.uniform(lo, hi, n)
        out.append(ep)
    return out


@pytest.fixture(scope="module")
def ir_ds() -> Dataset:
    ranges = {**CONTRACT, "ir0": (0.0, 0.1), "ir1": (0.0, 0.1), **WHEELS}
    return Dataset.from_episodes(_episodes(ranges), {"behavior": "turn", "channels": IR})


@pytest.fixture(scope="module")
def gripper_ds() -> Dataset:
    ranges = {**CONTRACT, "opening": (0.0, 0.035), **WHEELS, "grip": (-0.02, 0.02)}
    md = {"behavior": "turn", "channels": [OPENING], "commands": ["left", "right", GRIP]}
    return Dataset.from_episodes(_episodes(ranges), md)


@pytest.fixture(scope="module")
def point_ds() -> Dataset:
    ranges = {"x": (-1.0, 1.0), "y": (-1.0, 1.0), "vx": (-0.5, 0.5), "vy": (-0.5, 0.5)}
    md = {"behavior": "reach", "channels": POINT, "commands": VELOCITY, "goal": {"x": 0.0}}
    return Dataset.from_episodes(_episodes(ranges), md)


def _same(got: Dataset, want: Dataset) -> None:
    assert got.sensor_channels == want.sensor_channels
    assert got.command_channels == want.command_channels
    assert got.lengths.tolist() == want.lengths.tolist()
    assert got.episode_ids.tolist() == want.episode_ids.tolist()
    np.testing.assert_allclose(got.t, want.t, atol=1e-9)
    # float32 in the LeRobot files
    np.testing.assert_allclose(got.sensors, want.sensors, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(got.commands, want.commands, rtol=1e-6, atol=1e-6)
    for key in ("channels", "commands", "behavior", "goal"):
        assert got.metadata.get(key) == want.metadata.get(key), key


def _invoke(*args: object) -> Result:
    return CliRunner().invoke(app, [str(a) for a in args])


def _foreign(ds: Dataset, folder: Path) -> Path:
    """A LeRobot folder of ``ds`` without our own file: as if another tool wrote it."""
    export_lerobot(ds, folder)
    (folder / "meta" / "behavior_hmm.json").unlink()
    return folder


# -- round trips through the folder ------------------------------------------------------


@pytest.mark.parametrize("name", ["ir_ds", "gripper_ds", "point_ds"])
def test_export_then_import_gives_the_same_dataset(
    name: str, request: pytest.FixtureRequest, tmp_path: Path
) -> None:
    ds: Dataset = request.getfixturevalue(name)
    back = import_lerobot(export_lerobot(ds, tmp_path / name))
    _same(back, ds)
    assert back.metadata["source"]["format"] == "lerobot"


def test_every_channel_is_named_in_info_json(gripper_ds: Dataset, tmp_path: Path) -> None:
    root = export_lerobot(gripper_ds, tmp_path / "grip")
    info = json.loads((root / "meta" / "info.json").read_text())
    state, action = info["features"]["observation.state"], info["features"]["action"]
    assert state["names"] == [*SENSOR_CHANNELS, "opening"] and state["shape"] == [5]
    assert action["names"] == ["left", "right", "grip"] and action["shape"] == [3]
    stats = json.loads((root / "meta" / "stats.json").read_text())
    assert len(stats["action"]["mean"]) == 3 and len(stats["observation.state"]["max"]) == 5
    ours = json.loads((root / "meta" / "behavior_hmm.json").read_text())
    assert ours["units"]["grip"] == "m/s" and ours["units"]["opening"] == "m"
    assert [c if isinstance(c, str) else c["name"] for c in ours["metadata"]["commands"]] == [
        "left",
        "right",
        "grip",
    ]


def test_a_robot_of_its_own_exports_its_channels_only(point_ds: Dataset, tmp_path: Path) -> None:
    root = export_lerobot(point_ds, tmp_path / "point")
    features = json.loads((root / "meta" / "info.json").read_text())["features"]
    assert features["observation.state"]["names"] == ["x", "y"]
    assert features["action"]["names"] == ["vx", "vy"]


def test_complex_demonstrations_with_a_gripper(gripper_ds: Dataset, tmp_path: Path) -> None:
    cols = gripper_ds.to_columns()
    cols["behavior"] = np.where(np.arange(len(cols["t"])) % 25 < 12, "turn", "close")
    ds = Dataset(cols, {**gripper_ds.metadata, "behavior": None})
    back = import_lerobot(export_lerobot(ds, tmp_path / "complex"))
    _same(back, ds)
    assert back.behavior is not None and back.behavior.tolist() == cols["behavior"].tolist()


def test_a_wrapping_channel_is_resampled_like_an_angle(tmp_path: Path) -> None:
    heading = {"name": "heading", "unit": "deg", "range": [-180.0, 180.0], "wraps": True}
    n = 6
    ep = {
        **{c: np.full(n, (lo + hi) / 2) for c, (lo, hi) in {**CONTRACT, **WHEELS}.items()},
        "t": np.arange(n) * 0.032,  # twice the control period
        "heading": np.array([170.0, 174.0, 178.0, -178.0, -174.0, -170.0]),
    }
    ds = Dataset.from_episodes([ep], {"channels": [heading]})
    back = import_lerobot(export_lerobot(ds, tmp_path / "slow"), resample=True)
    assert back.n_samples == 2 * n - 1
    # halfway between 178 and -178 lies 180, not 0
    np.testing.assert_allclose(back.column("heading")[5], 180.0, atol=1e-4)
    np.testing.assert_allclose(back.column("heading")[1], 172.0, atol=1e-4)


# -- meta/behavior_hmm.json checks the declarations -----------------------------------------


def test_units_of_declared_channels_are_checked(gripper_ds: Dataset, tmp_path: Path) -> None:
    root = export_lerobot(gripper_ds, tmp_path / "grip")
    ours = root / "meta" / "behavior_hmm.json"
    doc = json.loads(ours.read_text())
    doc["units"]["grip"] = "rad/s"
    ours.write_text(json.dumps(doc))
    with pytest.raises(DatasetError, match="unit of 'grip' is \"rad/s\"; this reader takes 'm/s'"):
        import_lerobot(root)


def test_a_malformed_command_declaration_names_our_file(
    gripper_ds: Dataset, tmp_path: Path
) -> None:
    root = export_lerobot(gripper_ds, tmp_path / "grip")
    ours = root / "meta" / "behavior_hmm.json"
    doc = json.loads(ours.read_text())
    doc["metadata"]["commands"] = ["left", "right", {"name": "grip", "unit": "m/s"}]
    ours.write_text(json.dumps(doc))
    with pytest.raises(DatasetError, match="bad command declaration") as info:
        import_lerobot(root)
    assert info.value.file == str(ours) and info.value.field == "commands"


# -- a LeRobot dataset not made by us ----------------------------------------------------


def test_foreign_folder_takes_declarations_found_by_name(
    gripper_ds: Dataset, tmp_path: Path
) -> None:
    folder = _foreign(gripper_ds, tmp_path / "theirs")
    back = import_lerobot(folder, channels=[OPENING], commands=["left", "right", GRIP])
    assert back.sensor_channels == (*SENSOR_CHANNELS, "opening")
    assert back.command_channels == ("left", "right", "grip")
    np.testing.assert_allclose(back.commands, gripper_ds.commands, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(back.sensors, gripper_ds.sensors, rtol=1e-6, atol=1e-6)
    assert back.metadata["channels"] == gripper_ds.metadata["channels"]
    assert back.metadata["commands"] == gripper_ds.metadata["commands"]
    assert back.metadata["source"]["mapping"]["grip"] == "action:grip"


def test_foreign_folder_of_a_robots_own_channels_with_a_mapping(
    point_ds: Dataset, tmp_path: Path
) -> None:
    folder = _foreign(point_ds, tmp_path / "theirs")
    info_path = folder / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    info["features"]["observation.state"]["names"] = ["pos_x", "pos_y"]
    info["features"]["action"]["names"] = None
    info_path.write_text(json.dumps(info))
    mapping = {"x": "observation.state:pos_x", "y": "observation.state:1"}
    mapping |= {"vx": "action:0", "vy": "action:1"}
    back = import_lerobot(folder, mapping=mapping, channels=POINT, commands=VELOCITY)
    assert back.sensor_channels == ("x", "y") and back.command_channels == ("vx", "vy")
    np.testing.assert_allclose(back.sensors, point_ds.sensors, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(back.commands, point_ds.commands, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize(
    ("kw", "error", "match"),
    [
        # a channel that is not declared cannot be mapped; the message says how to declare it
        ({"mapping": {"grip": "action:2"}}, ConfigError, "declare a robot's own with --channel"),
        # a declared channel the folder lacks
        (
            {"channels": [{"name": "ir9", "unit": "m", "range": [0, 1]}]},
            ConfigError,
            "no feature for channel.*ir9",
        ),
        # a declared command the folder lacks
        (
            {"commands": ["left", "right", {"name": "lift", "unit": "m/s", "range": [-1, 1]}]},
            ConfigError,
            r"no feature for channel.*lift.*--map lift=action:0",
        ),
        # a declared channel is read in its declared unit
        (
            {"channels": [OPENING], "commands": ["left", "right", GRIP], "units": {"grip": "mm/s"}},
            ConfigError,
            r"declared unit \(m/s\)",
        ),
        # a sensor channel listed among the commands
        ({"commands": ["left", "distance"]}, DatasetError, "not a command"),
    ],
)
def test_foreign_folder_refusals(
    gripper_ds: Dataset, tmp_path: Path, kw: dict[str, Any], error: type, match: str
) -> None:
    folder = _foreign(gripper_ds, tmp_path / "theirs")
    with pytest.raises(error, match=match):
        import_lerobot(folder, **kw)


# -- the command line ------------------------------------------------------------------


def test_cli_export_then_import_keeps_the_gripper(gripper_ds: Dataset, tmp_path: Path) -> None:
    source, folder, back = tmp_path / "grip.parquet", tmp_path / "lerobot", tmp_path / "b.parquet"
    write(gripper_ds, source)
    result = _invoke("export-lerobot", source, folder)
    assert result.exit_code == 0, result.output
    result = _invoke("import-lerobot", folder, "-o", back)
    assert result.exit_code == 0, result.output
    _same(read(back), gripper_ds)


def test_cli_export_then_import_a_robots_own_channels(point_ds: Dataset, tmp_path: Path) -> None:
    source, folder, back = tmp_path / "pt.parquet", tmp_path / "lerobot", tmp_path / "b.parquet"
    write(point_ds, source)
    assert _invoke("export-lerobot", source, folder, "--robot-type", "point_mass").exit_code == 0
    result = _invoke("import-lerobot", folder, "-o", back)
    assert result.exit_code == 0, result.output
    _same(read(back), point_ds)


def test_cli_import_of_a_foreign_folder_with_channel_and_command(
    gripper_ds: Dataset, tmp_path: Path
) -> None:
    folder = _foreign(gripper_ds, tmp_path / "theirs")
    info_path = folder / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    info["features"]["action"]["names"] = ["wheel_l", "wheel_r", "gripper"]
    info_path.write_text(json.dumps(info))
    back = tmp_path / "mine.parquet"
    args: list[object] = ["import-lerobot", folder, "--behavior", "turn"]
    args += ["--channel", "opening:m:0:0.035:0.001"]
    args += ["--command", "left", "--command", "right", "--command", "grip:m/s:-0.02:0.02:0.001"]
    args += ["--map", "left=action:wheel_l", "--map", "right=action:wheel_r"]
    args += ["--map", "grip=action:gripper", "-o", back]
    result = _invoke(*args)
    assert result.exit_code == 0, result.output
    ds = read(back)
    assert ds.command_channels == ("left", "right", "grip")
    assert ds.sensor_channels == (*SENSOR_CHANNELS, "opening")
    np.testing.assert_allclose(ds.commands, gripper_ds.commands, rtol=1e-6, atol=1e-6)
    spec = ds.command_specs[2]
    assert (spec.unit, spec.range, spec.rest) == ("m/s", (-0.02, 0.02), 0.001)
    assert ds.channel_specs[-1].tolerance == 0.001


def test_cli_refuses_a_foreign_gripper_without_its_declaration(
    gripper_ds: Dataset, tmp_path: Path
) -> None:
    folder = _foreign(gripper_ds, tmp_path / "theirs")
    out = tmp_path / "mine.parquet"
    result = _invoke("import-lerobot", folder, "--map", "grip=action:2", "-o", out)
    assert_user_error(result, "--map grip: unknown channel", "--command")
    assert not out.exists()
    result = _invoke("import-lerobot", folder, "--command", "grip:m/s:-1", "-o", out)
    assert_user_error(result, "--command expects NAME:UNIT:LO:HI[:REST]")
    shutil.rmtree(folder)
