"""No output inside an input folder (issue 31, item 2): ``-o`` naming a file inside a
LeRobot folder or a ROS 2 bag is refused before anything is written, the input intact."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_testing import Invoke, assert_user_error, digest

from behavior_hmm import data
from behavior_hmm._paths import check_outputs
from behavior_hmm.errors import ConfigError


def _snapshot(folder: Path) -> dict[str, str]:
    """Every file below ``folder`` (hidden temporary files included) and its digest."""
    return {str(p.relative_to(folder)): digest(p) for p in folder.rglob("*") if p.is_file()}


@pytest.fixture
def lerobot(invoke: Invoke, tmp_path: Path, turn_parquet: Path) -> Path:
    folder = tmp_path / "ler"
    result = invoke(["export-lerobot", turn_parquet, folder])
    assert result.exit_code == 0, result.output
    assert (folder / "data" / "chunk-000" / "file-000.parquet").is_file()
    assert (folder / "meta" / "info.json").is_file()
    return folder


@pytest.fixture
def ros2_bag(tmp_path: Path, turn_parquet: Path) -> Path:
    pytest.importorskip("rosbags")
    from bag_writing import write_bag

    bag = write_bag(data.read(turn_parquet).subset([0]), tmp_path / "bag", ros=2, twist=True)
    assert (bag / "bag.db3").is_file() and (bag / "metadata.yaml").is_file()
    return bag


#: A mapping under which the bag imports (the refusals below are not about the mapping).
BAG_OPTIONS = ["--map", "angle=/object_bearing:data", "--unit", "angle=rad"]
BAG_OPTIONS += ["--map", "distance=/object_distance:data", "--twist", "/cmd_vel"]
BAG_OPTIONS += ["--derive", "linear_velocity,angular_velocity"]


@pytest.mark.parametrize("inside", ["data/chunk-000/file-000.parquet", "meta/info.json"])
def test_import_lerobot_refuses_an_output_inside_its_folder(
    invoke: Invoke, lerobot: Path, inside: str
) -> None:
    before = _snapshot(lerobot)
    out = lerobot / inside
    line = assert_user_error(invoke(["import-lerobot", lerobot, "-o", out]))
    assert line == (
        f"error: -o {out} is inside the input FOLDER {lerobot}; write outputs outside the inputs"
    )
    assert _snapshot(lerobot) == before


@pytest.mark.parametrize("inside", ["bag.db3", "metadata.yaml"])
def test_import_bag_refuses_an_output_inside_the_bag(
    invoke: Invoke, ros2_bag: Path, inside: str
) -> None:
    before = _snapshot(ros2_bag)
    out = ros2_bag / inside
    line = assert_user_error(invoke(["import-bag", ros2_bag, *BAG_OPTIONS, "-o", out]))
    assert line == (
        f"error: -o {out} is inside the input BAG {ros2_bag}; write outputs outside the inputs"
    )
    assert _snapshot(ros2_bag) == before


def test_the_same_imports_write_outside_their_inputs(
    invoke: Invoke, tmp_path: Path, lerobot: Path, ros2_bag: Path
) -> None:
    """The mappings above are good ones: beside the inputs (even a name starting like
    the folder's) the same commands succeed."""
    result = invoke(["import-lerobot", lerobot, "-o", tmp_path / "ler.parquet"])
    assert result.exit_code == 0, result.output
    result = invoke(["import-bag", ros2_bag, *BAG_OPTIONS, "-o", tmp_path / "bag2" / "b.parquet"])
    assert result.exit_code == 0, result.output


def test_a_new_file_inside_an_input_folder_is_refused_too(invoke: Invoke, lerobot: Path) -> None:
    before = _snapshot(lerobot)
    out = lerobot / "data" / "chunk-001" / "mine.parquet"
    assert_user_error(invoke(["import-lerobot", lerobot, "-o", out]), "is inside the input FOLDER")
    assert _snapshot(lerobot) == before
    assert not out.parent.exists()


def test_the_input_folder_itself_is_refused(invoke: Invoke, lerobot: Path) -> None:
    line = assert_user_error(invoke(["import-lerobot", lerobot, "-o", lerobot]))
    assert line == (
        f"error: -o {lerobot} would overwrite the input FOLDER {lerobot}; give another file name"
    )


def test_a_symlink_to_the_input_folder_is_seen_through(
    invoke: Invoke, tmp_path: Path, lerobot: Path
) -> None:
    link = tmp_path / "link"
    link.symlink_to(lerobot, target_is_directory=True)
    before = _snapshot(lerobot)
    assert_user_error(
        invoke(["import-lerobot", lerobot, "-o", link / "meta" / "info.json"]), "is inside"
    )
    assert_user_error(
        invoke(["import-lerobot", link, "-o", lerobot / "meta" / "info.json"]), "is inside"
    )
    assert _snapshot(lerobot) == before


def test_a_bag_file_makes_its_folder_an_input(invoke: Invoke, ros2_bag: Path) -> None:
    before = _snapshot(ros2_bag)
    db3, out = ros2_bag / "bag.db3", ros2_bag / "metadata.yaml"
    line = assert_user_error(invoke(["import-bag", db3, *BAG_OPTIONS, "-o", out]))
    assert line == (
        f"error: -o {out} is inside the folder {ros2_bag} of the input BAG {db3}; "
        "write outputs outside the inputs"
    )
    assert _snapshot(ros2_bag) == before


# ------------------------------------------------------------- check_outputs, directly


def test_output_folders_may_not_be_in_contain_or_equal_an_input_folder(tmp_path: Path) -> None:
    source = tmp_path / "in"
    (source / "sub").mkdir(parents=True)
    for out, relation in [
        (source, "is the input"),
        (source / "sub" / "results", "is inside the input"),
        (tmp_path, "contains the input"),
    ]:
        with pytest.raises(ConfigError) as caught:
            check_outputs({"FOLDER": source}, {}, folders={"-o": out})
        assert str(caught.value) == (
            f"-o {out} {relation} FOLDER {source}; write outputs outside the inputs"
        )


def test_an_output_folder_holding_an_input_file_is_allowed(tmp_path: Path) -> None:
    """The commands write fixed names in their folder, or need it new or empty."""
    config = tmp_path / "results" / "config.toml"
    config.parent.mkdir()
    config.write_text("")
    check_outputs({"--config": config}, {}, folders={"-o": config.parent})


def test_a_sibling_with_a_longer_name_is_outside(tmp_path: Path) -> None:
    source = tmp_path / "ler"
    source.mkdir()
    check_outputs({"FOLDER": source}, {"-o": tmp_path / "ler2" / "x.parquet"})
    check_outputs({"FOLDER": source}, {"-o": tmp_path / "ler.parquet"})
    check_outputs({"FOLDER": source}, {}, folders={"-o": tmp_path / "ler-out"})
