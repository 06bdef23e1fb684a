"""Videos from the command line: ``generate --video`` and ``evaluate --videos``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from cli_testing import Invoke, assert_user_error, write_starts
from typer.testing import CliRunner

from behavior_hmm.cli import app


@pytest.fixture(scope="module")
def turn_model(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A turn model from starts every 30 deg (kinematic, noise-free)."""
    folder = tmp_path_factory.mktemp("videos")
    angles = [str(a) for a in range(-165, 180, 30)]
    starts = write_starts(folder / "starts.csv", "angle", *angles)
    runner = CliRunner()
    data, model = folder / "turn.parquet", folder / "turn.bhmm"
    for args in (
        ["collect", "turn", "--starts", starts, "--sim", "kinematic", "-o", data],
        ["train", "simple", data, "--inputs", "angle", "-o", model],
    ):
        result = runner.invoke(app, [str(a) for a in args])
        assert result.exit_code == 0, result.output
    return model


def _frames(path: Path) -> list[np.ndarray]:
    from PIL import Image, ImageSequence

    with Image.open(path) as image:
        return [np.asarray(f.convert("RGB")) for f in ImageSequence.Iterator(image)]


def test_generate_writes_a_gif_of_the_run(invoke: Invoke, turn_model: Path, tmp_path: Path) -> None:
    video = tmp_path / "run.gif"
    args = ["generate", turn_model, "--sim", "kinematic", "--start", "angle=120"]
    result = invoke([*args, "--video", video])
    assert result.exit_code == 0, result.output
    assert f"video: {video}" in result.output
    frames = _frames(video)
    assert len(frames) > 10
    assert not np.array_equal(frames[0], frames[-1])  # the robot turned


def test_video_options_are_checked_before_motion(
    invoke: Invoke, turn_model: Path, tmp_path: Path
) -> None:
    args = ["generate", turn_model, "--sim", "kinematic", "--start", "angle=120"]
    assert_user_error(invoke([*args, "--video", tmp_path / "run.avi"]), ".mp4 or .gif")
    assert_user_error(
        invoke([*args, "--video", tmp_path / "r.gif", "--video-backend", "povray"]),
        "unknown --video-backend 'povray'",
    )
    assert not list(tmp_path.iterdir())


def test_mujoco_backend_renders_or_says_why_in_one_line(
    invoke: Invoke, turn_model: Path, tmp_path: Path
) -> None:
    video = tmp_path / "run.gif"
    args = ["generate", turn_model, "--sim", "kinematic", "--start", "angle=60"]
    result = invoke([*args, "--video", video, "--video-backend", "mujoco"])
    if result.exit_code == 0:  # an OpenGL context was available (MUJOCO_GL=egl or osmesa)
        assert len(_frames(video)) > 5
    else:
        assert_user_error(result, "MuJoCo cannot render offscreen here", "MUJOCO_GL")
        assert not video.exists()


@pytest.mark.slow
def test_evaluate_writes_one_video_per_run(
    invoke: Invoke, turn_model: Path, tmp_path: Path
) -> None:
    starts = write_starts(tmp_path / "starts.csv", "angle", "120", "-45")
    folder = tmp_path / "videos"
    result = invoke(
        ["evaluate", turn_model, "--sim", "kinematic", "--starts", starts, "--videos", folder]
    )
    assert result.exit_code == 0, result.output
    mp4 = sorted(p.name for p in folder.iterdir())
    assert mp4 == ["case_00.mp4", "case_01.mp4"]
    assert all((folder / name).stat().st_size > 1000 for name in mp4)
