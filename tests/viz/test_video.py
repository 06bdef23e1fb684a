"""Top-down rollout videos: MP4/GIF written, readable, timed, atomic; the missing extra."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from behavior_hmm.errors import ConfigError
from behavior_hmm.viz import _video
from behavior_hmm.viz._video import (
    VIDEO_EXTRA_MESSAGE,
    frame_grid,
    frame_times,
    goal_text,
    render_frame,
    render_rollout,
)

iio = pytest.importorskip("imageio.v3")
pytest.importorskip("imageio_ffmpeg")
PIL_Image = pytest.importorskip("PIL.Image")

SMALL: dict[str, Any] = {"dpi": 60, "size_in": 3.0}  # 180 px wide: fast


def _run(duration: float = 2.0, dt: float = 0.016, scale: float = 1.0) -> dict[str, Any]:
    """A robot driving in +x towards the object at the origin, then stopping."""
    t = np.arange(0.0, duration + 1e-9, dt)
    x = -0.4 * scale + np.minimum(t, 0.75 * duration) * 0.3 * scale / duration
    pose = np.column_stack([x, np.full_like(t, 0.05 * scale), np.zeros_like(t)])
    labels = ["approach" if tk < 0.75 * duration else "stop" for tk in t]
    return {
        "t": t,
        "pose": pose,
        "labels": labels,
        "goal": {"angle": 0.0, "distance": 0.01},
        "body_radius": 0.035 * scale,
        "object_radius": 0.02 * scale,
    }


def _frame_size(run: dict[str, Any], **kw: Any) -> tuple[int, int]:
    h, w = render_frame(0.0, **run, **kw).shape[:2]
    return w, h


def _count(path: Path) -> int:
    return sum(1 for _ in iio.imiter(path))


# ---------------------------------------------------------------- frame timing


def test_frame_times_subsample_to_the_frame_rate_and_keep_the_last_state() -> None:
    t = np.arange(0.0, 2.0 + 1e-9, 0.016)  # 126 samples, last at 2.0 s
    idx = frame_times(t, fps=25.0)
    assert idx[0] == 0 and idx[-1] == len(t) - 1
    assert len(idx) == 51  # frames at 0, 0.04, ..., 2.0 s
    np.testing.assert_allclose(t[idx[:-1]], np.arange(50) * 0.04, atol=0.016)
    assert np.all(np.diff(idx) >= 0)
    assert len(frame_times(t, fps=25.0, speed=2.0)) == 26  # twice as fast: half the frames
    # a grid that misses the last sample still ends on it
    idx = frame_times(np.array([0.0, 0.03, 0.05]), fps=25.0)
    assert idx.tolist() == [0, 1, 2]
    assert frame_times(np.array([3.0]), fps=25.0).tolist() == [0]


def test_goal_text_names_units() -> None:
    assert goal_text({"angle": 0.0, "distance": 0.01}) == "goal: angle 0°, distance 0.01 m"
    assert goal_text(None) == ""


# ---------------------------------------------------------------- writing videos


def test_mp4_is_written_and_reads_back(tmp_path: Path) -> None:
    run = _run()
    out = render_rollout(tmp_path / "run.mp4", **run, fps=20.0, **SMALL)
    assert out == tmp_path / "run.mp4" and out.stat().st_size > 0
    frames = list(iio.imiter(out))
    expected = len(frame_times(run["t"], 20.0)) + round(0.5 * 20.0)  # motion + held end
    assert abs(len(frames) - expected) <= 1
    w, h = _frame_size(run, **SMALL)
    assert w % 2 == 0 and h % 2 == 0 and w == 180
    assert frames[0].shape == (h, w, 3)
    assert [p.name for p in tmp_path.iterdir()] == ["run.mp4"]  # no temporary left


def test_gif_is_written_loops_and_holds_the_end(tmp_path: Path) -> None:
    run = _run()
    out = render_rollout(tmp_path / "run.gif", **run, fps=10.0, **SMALL)
    expected = len(frame_times(run["t"], 10.0))  # the hold lengthens the last frame
    assert abs(_count(out) - expected) <= 1
    w, h = _frame_size(run, **SMALL)
    assert next(iter(iio.imiter(out))).shape[:2] == (h, w)
    with PIL_Image.open(out) as im:
        assert im.info["loop"] == 0  # forever
        assert im.info["duration"] == 100
        im.seek(im.n_frames - 1)
        assert im.info["duration"] == 600  # 0.1 s + 0.5 s hold


def test_suffix_is_case_insensitive_and_others_are_refused(tmp_path: Path) -> None:
    render_rollout(tmp_path / "a.GIF", **_run(0.2), **SMALL)
    for name in ("a.avi", "a.png", "a"):
        with pytest.raises(ConfigError, match=r"\.mp4 or \.gif") as err:
            render_rollout(tmp_path / name, **_run(0.2), **SMALL)
        assert "\n" not in str(err.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.GIF"]


@pytest.mark.parametrize(
    ("suffix", "module"),
    [(".mp4", "imageio_ffmpeg"), (".gif", "PIL.Image")],
)
def test_missing_video_extra_is_a_config_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, suffix: str, module: str
) -> None:
    monkeypatch.setitem(sys.modules, module, None)  # makes `import module` fail
    with pytest.raises(ConfigError) as err:
        render_rollout(tmp_path / f"run{suffix}", **_run(0.2), **SMALL)
    assert str(err.value) == VIDEO_EXTRA_MESSAGE
    assert "pip install 'behavior-hmm[video]'" in str(err.value)
    assert list(tmp_path.iterdir()) == []


def test_frame_grid_needs_imageio(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    video = render_rollout(tmp_path / "run.gif", **_run(0.2), **SMALL)
    monkeypatch.setitem(sys.modules, "imageio.v3", None)
    with pytest.raises(ConfigError, match=r"video extra"):
        frame_grid(video, tmp_path / "grid.png")


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_a_failed_render_leaves_no_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, suffix: str
) -> None:
    calls = {"n": 0}
    frame = _video._Scene.frame

    def failing(self: Any, i: int) -> np.ndarray:
        calls["n"] += 1
        if calls["n"] > 12:
            raise RuntimeError("boom")
        return frame(self, i)

    monkeypatch.setattr(_video._Scene, "frame", failing)
    with pytest.raises(RuntimeError, match="boom"):
        render_rollout(tmp_path / f"new{suffix}", **_run(), **SMALL)
    assert list(tmp_path.iterdir()) == []  # neither the video nor a temporary

    old = tmp_path / f"old{suffix}"
    old.write_bytes(b"previous video")
    calls["n"] = 0
    with pytest.raises(RuntimeError, match="boom"):
        render_rollout(old, **_run(), **SMALL)
    assert old.read_bytes() == b"previous video"
    assert [p.name for p in tmp_path.iterdir()] == [old.name]


def test_bad_inputs_are_config_errors(tmp_path: Path) -> None:
    run = _run(0.2)
    with pytest.raises(ConfigError, match="pose"):
        render_rollout(tmp_path / "a.mp4", **{**run, "pose": run["pose"][:, :2]}, **SMALL)
    with pytest.raises(ConfigError, match="labels"):
        render_rollout(tmp_path / "a.mp4", **{**run, "labels": ["x"]}, **SMALL)
    with pytest.raises(ConfigError, match="rows"):
        render_rollout(tmp_path / "a.mp4", **{**run, "t": run["t"][:-1]}, **SMALL)
    with pytest.raises(ConfigError, match="fps"):
        render_rollout(tmp_path / "a.mp4", **run, fps=0.0, **SMALL)
    with pytest.raises(ConfigError, match="non-decreasing"):
        render_rollout(tmp_path / "a.mp4", **{**run, "t": run["t"][::-1]}, **SMALL)
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------- what the frames show

ROBOT_FILL = np.array([130.0, 178.0, 211.0])  # C0 at alpha 0.55 over the axes' background


def _robot_centre(frame: np.ndarray, tol: float) -> np.ndarray:
    """Mean (row, column) of the robot's fill colour below the header."""
    top = frame.shape[0] // 3  # the legend's robot marker is in the header
    body = np.abs(frame[top:, :, :3].astype(float) - ROBOT_FILL).max(axis=2) < tol
    rows, cols = np.nonzero(body)
    assert len(rows) > 20, "robot not found"
    return np.array([rows.mean() + top, cols.mean()])


def test_the_robot_moves_across_the_frames(tmp_path: Path) -> None:
    run = {**_run(), "labels": None}  # one colour for the robot throughout
    first = render_frame(0.0, **run)
    last = render_frame(run["t"][-1], **run)
    a, b = _robot_centre(first, 6), _robot_centre(last, 6)
    assert b[1] - a[1] > 50  # moved right (+x) by many pixels
    assert abs(b[0] - a[0]) < 5  # at the same height

    # and in the written video
    frames = list(iio.imiter(render_rollout(tmp_path / "run.mp4", **run, fps=10.0)))
    a, b = _robot_centre(frames[0], 30), _robot_centre(frames[-1], 30)
    assert b[1] - a[1] > 50


def test_a_still_robot_draws_the_same_scene() -> None:
    run = {**_run(), "labels": None}
    run["pose"] = np.tile(run["pose"][:1], (len(run["t"]), 1))
    first, last = render_frame(0.0, **run), render_frame(run["t"][-1], **run)
    top = first.shape[0] // 3  # below the header (its time text changes)
    np.testing.assert_array_equal(first[top:], last[top:])


@pytest.mark.parametrize("scale", [1.0, 0.5 / 0.035])
def test_the_whole_run_stays_in_view(scale: float) -> None:
    run = _run(scale=scale)
    args = _video._make_run(
        run["t"],
        run["pose"],
        run["labels"],
        run["goal"],
        (0.0, 0.0),
        run["object_radius"],
        run["body_radius"],
        None,
        "",
    )
    scene = _video._Scene(args, frame_times(run["t"]), dpi=60, size_in=3.0)
    (x0, x1), (y0, y1) = scene.ax.get_xlim(), scene.ax.get_ylim()
    r = run["body_radius"]
    xy = run["pose"][:, :2]
    assert x0 < xy[:, 0].min() - r and xy[:, 0].max() + r < x1
    assert y0 < xy[:, 1].min() - r and xy[:, 1].max() + r < y1
    assert x0 < -run["object_radius"] and run["object_radius"] < x1
    assert scene.frame(len(run["t"]) - 1).shape[1] == 180


def test_teacher_title_and_a_single_step_render(tmp_path: Path) -> None:
    run = _run(1.0)
    teacher = run["pose"].copy()
    teacher[:, 1] -= 0.05
    out = render_rollout(tmp_path / "t.mp4", **run, teacher_pose=teacher, title="demo", **SMALL)
    assert _count(out) > 0
    one = {**run, "t": run["t"][:1], "pose": run["pose"][:1], "labels": run["labels"][:1]}
    out = render_rollout(tmp_path / "one.gif", **one, **SMALL)
    assert _count(out) == 1


def test_frame_grid_is_a_png_of_evenly_spaced_frames(tmp_path: Path) -> None:
    run = _run()
    video = render_rollout(tmp_path / "run.mp4", **run, fps=10.0, **SMALL)
    grid = frame_grid(video, tmp_path / "grid.png", n=6)
    image = iio.imread(grid)
    w, h = _frame_size(run, **SMALL)
    gap = max(2, w // 80)
    assert image.shape[:2] == (2 * h + gap, 3 * w + 2 * gap)  # 2 rows of 3
    with pytest.raises(ConfigError, match="png"):
        frame_grid(video, tmp_path / "grid.jpg")
