"""Videos rendered by MuJoCo's offscreen renderer, a camera tracking the robot.

The run's poses are replayed in the MJCF scene of our robot (``MUJOCO_GL=egl`` or
``osmesa`` for a headless machine); where no OpenGL context can be made, a one-line
:class:`~behavior_hmm.errors.ConfigError` says so. The default backend is the
matplotlib one (:func:`behavior_hmm.viz.render_trace`), which always works.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from behavior_hmm._atomic import atomic_write_with
from behavior_hmm.errors import ConfigError
from behavior_hmm.viz._video import (
    HOLD_S,
    _import_or_config_error,
    _video_format,
    _write_gif,
    _write_mp4,
    frame_times,
)

#: Video backends of ``generate --video`` and ``evaluate --videos``.
VIDEO_BACKENDS = ("matplotlib", "mujoco")


def offscreen_renderer(model: Any, size: tuple[int, int], instead: str) -> Any:
    """A ``mujoco.Renderer`` of ``model`` (``size`` = width, height in pixels).

    Where MuJoCo cannot make an offscreen OpenGL context, one line says so and what to
    set, or ``instead`` what to do (:class:`ConfigError`).
    """
    import mujoco

    try:
        with warnings.catch_warnings():  # GLFW warns about a missing display first
            warnings.simplefilter("ignore")
            return mujoco.Renderer(model, height=size[1], width=size[0])
    except Exception as err:  # no display, no EGL/OSMesa: say so in one line
        gl = os.environ.get("MUJOCO_GL", "unset")
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise ConfigError(
            f"MuJoCo cannot render offscreen here (MUJOCO_GL={gl}: {reason}); set "
            f"MUJOCO_GL=egl or osmesa, or {instead}"
        ) from None


def render_trace_mujoco(
    trace: Any,
    path: str | os.PathLike[str],
    *,
    robot: Any = None,
    fps: float = 25.0,
    size: tuple[int, int] = (480, 480),
) -> Path:
    """Replay ``trace.pose`` in our robot's MuJoCo scene, a camera following the robot.

    ``robot`` is the env the run came from; its ``unwrapped.params`` (our Khepera-like
    robot) size the scene. Raises :class:`ConfigError` when the run has no poses, the
    robot is not ours, or MuJoCo cannot make an offscreen OpenGL context.
    """
    import mujoco

    from behavior_hmm.sim import RobotParams
    from behavior_hmm.sim._mujoco import MujocoBackend

    target = Path(path)
    fmt = _video_format(target)
    pose = trace.pose_array
    if not len(pose):
        raise ConfigError("this run has no poses (the env reports no info['pose']): no video")
    params = getattr(getattr(robot, "unwrapped", robot), "params", None)
    if params is not None and not isinstance(params, RobotParams):
        raise ConfigError("--video-backend mujoco draws our Khepera-like robot only")
    scene = MujocoBackend(params or RobotParams())
    renderer = offscreen_renderer(scene.model, size, "use --video-backend matplotlib")
    # a camera that follows the robot, keeping the object (at the origin) in view
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.elevation = -60.0
    camera.azimuth = 90.0
    near = 10.0 * scene.params.body_radius
    t = np.asarray(trace.t, dtype=np.float64)[: len(pose)]
    indices = frame_times(t, fps)
    hold = max(1, round(HOLD_S * fps))

    def frames() -> Any:
        for i in indices:
            x, y, yaw = pose[int(i)]
            scene.place(float(x), float(y), float(yaw))
            camera.lookat[:] = (x / 2.0, y / 2.0, 0.0)
            camera.distance = max(near, 2.6 * float(np.hypot(x, y)))
            renderer.update_scene(scene.data, camera)
            yield np.ascontiguousarray(renderer.render())

    try:
        if fmt == "mp4":
            ffmpeg = _import_or_config_error("imageio_ffmpeg")
            atomic_write_with(
                target, lambda tmp: _write_mp4(ffmpeg, tmp, frames(), size, fps, hold)
            )
        else:
            pil_image = _import_or_config_error("PIL.Image")
            samples = [next(iter(frames()))]
            atomic_write_with(
                target,
                lambda tmp: _write_gif(pil_image, tmp, frames(), samples, len(indices), fps, hold),
            )
    finally:
        renderer.close()
    return target
