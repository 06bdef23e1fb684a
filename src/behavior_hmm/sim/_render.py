"""A small top-down raster of the arena (numpy only, no OpenGL needed)."""

from __future__ import annotations

import math

import numpy as np

from behavior_hmm.sim._params import RobotParams

_FLOOR = np.array([235, 235, 235], dtype=np.uint8)
_ARENA_EDGE = np.array([200, 200, 200], dtype=np.uint8)
_OBJECT = np.array([220, 70, 50], dtype=np.uint8)
_ROBOT = np.array([50, 100, 200], dtype=np.uint8)
_HEADING = np.array([20, 20, 20], dtype=np.uint8)


class TopDownRenderer:
    """Draws the object, the arena edge and the robot (with its heading) as RGB pixels.

    Parameters
    ----------
    params
        Robot and object geometry.
    half_width
        Half the side of the square view, centred on the object (m).
    size
        Image side (pixels).
    """

    def __init__(self, params: RobotParams, half_width: float = 1.4, size: int = 320) -> None:
        self.size = size
        self._scale = size / (2.0 * half_width)  # pixels per metre
        self._half_width = half_width
        centres = (np.arange(size) + 0.5) / self._scale - half_width
        self._gx = centres[np.newaxis, :]
        self._gy = centres[::-1, np.newaxis]  # image rows go down, y goes up
        r2 = self._gx**2 + self._gy**2
        background = np.empty((size, size, 3), dtype=np.uint8)
        background[...] = _FLOOR
        arena = params.contact_distance + 1.2
        background[np.abs(np.sqrt(r2) - arena) < 1.0 / self._scale] = _ARENA_EDGE
        background[r2 <= params.object_radius**2] = _OBJECT
        self._background = background
        # Draw the robot at least 3 pixels wide so it stays visible.
        self._robot_radius = max(params.body_radius, 3.0 / self._scale)

    def render(self, x: float, y: float, yaw: float) -> np.ndarray:
        """RGB image (size, size, 3) uint8 with the robot at ``(x, y)`` heading ``yaw`` (rad)."""
        image = self._background.copy()
        rr = self._robot_radius
        image[(self._gx - x) ** 2 + (self._gy - y) ** 2 <= rr * rr] = _ROBOT
        for k in np.linspace(0.0, 1.6 * rr, 12):
            col = int((x + k * math.cos(yaw) + self._half_width) * self._scale)
            row = int((self._half_width - (y + k * math.sin(yaw))) * self._scale)
            if 0 <= row < self.size and 0 <= col < self.size:
                image[row, col] = _HEADING
        return image
