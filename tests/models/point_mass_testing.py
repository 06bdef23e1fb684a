"""Demonstrations of the 2-D point mass for the recovery and goal-arrival tests."""

from __future__ import annotations

import numpy as np

from behavior_hmm.data import CONTROL_PERIOD
from behavior_hmm.evaluate._lasa import command_columns


def stroke(y0: float, n: int = 150, rest: int = 12) -> dict[str, np.ndarray]:
    """A smooth stroke from (-40, y0) that slows down into the goal at the origin and rests
    there ``rest`` cycles: positions and the velocity commands that made them."""
    s = np.linspace(0.0, 1.0, n)
    ease = 3 * s**2 - 2 * s**3
    x, y = -40.0 * (1 - ease), y0 * (1 - ease)
    vx = np.r_[np.diff(x) / CONTROL_PERIOD, 0.0]
    vy = np.r_[np.diff(y) / CONTROL_PERIOD, 0.0]
    a, b = command_columns()
    cols = {"x": x, "y": y, a: vx, b: vy}
    cols = {k: np.r_[v, np.zeros(rest)] for k, v in cols.items()}
    return {"t": np.arange(n + rest) * CONTROL_PERIOD, **cols}
