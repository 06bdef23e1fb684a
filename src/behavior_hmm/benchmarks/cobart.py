"""CobART speed: offline categorization throughput and live latency per reading.

Usage::

    behavior-hmm bench cobart --json OUT.json
    python -m behavior_hmm.benchmarks.cobart [--quick]          # prints the JSON

Figures (medians over repeats, one thread):

- ``windows_per_s``: ``CobART.fit`` (learning) on the turn dataset, motion-primitive
  preset (thesis table 4.2), angle channel; target >= 50,000. ``windows_per_s_best``:
  the fastest repeat (less sensitive to other processes on a shared machine).
- ``predict_windows_per_s``: ``CobART.categorize`` on the same data (no learning).
- ``windows_per_s_2ch`` / ``obs_windows_per_s``: fit with angle + angular velocity, and
  with the observation preset.
- ``predict_us_median`` / ``predict_us_p99``: one ``LiveCategorizer.update`` with 200
  categories (motion preset, angle), microseconds; target median <= 20.
  ``predict_us_median_2ch``: the same with two channels.

Until the simulator's default turn dataset exists, :func:`synthetic_turn_episodes`
builds a turn-like one (jerk-limited turns to 0 deg from -180..180 every 10 deg,
filtered, normalized by 180 deg); pass ``data=(X, lengths)`` to :func:`run` to use
real data instead.
"""

from __future__ import annotations

import json
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, sosfilt, sosfilt_zi

from behavior_hmm.cobart import CobART
from behavior_hmm.data._channels import CONTROL_PERIOD

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def _turn_profile(
    start_deg: float, peak_deg_s: float, accel_deg_s2: float, still_s: float, dt: float
) -> tuple[FloatArray, FloatArray]:
    """Angle (deg) and angular velocity (deg/s) of a smooth turn from ``start_deg`` to 0."""
    dist = abs(start_deg)
    ramp = 1.5 * peak_deg_s / accel_deg_s2  # raised-cosine ramp: peak acceleration = accel
    vmax = peak_deg_s
    if dist < vmax * ramp:  # too short to reach the peak: lower it
        vmax = dist / ramp
    cruise = (dist - vmax * ramp) / vmax
    total = 2 * ramp + cruise
    t = np.arange(0.0, total + still_s, dt)
    up = vmax * 0.5 * (1 - np.cos(np.pi * t / ramp))
    down = vmax * 0.5 * (1 + np.cos(np.pi * (t - ramp - cruise) / ramp))
    vel = np.where(t < ramp, up, np.where(t < ramp + cruise, vmax, np.where(t < total, down, 0.0)))
    turned = np.cumsum(vel) * dt
    turned *= dist / turned[-1]
    sign = np.sign(start_deg)
    return sign * (dist - turned), -sign * vel


def synthetic_turn_episodes(
    starts_deg: Sequence[float] | None = None,
    *,
    channels: Sequence[str] = ("angle",),
    peak_deg_s: float = 60.0,
    accel_deg_s2: float = 150.0,
    still_s: float = 0.3,
    cutoff_hz: float = 5.0,
    dt: float = CONTROL_PERIOD,
) -> tuple[FloatArray, IntArray]:
    """A turn-like dataset: filtered, normalized ``(X, lengths)``.

    Parameters
    ----------
    starts_deg
        Start angles (deg); default -180..180 every 10 deg without 0 (36 episodes).
    channels
        ``"angle"`` (normalized by 180 deg) and/or ``"angular_velocity"`` (by 90 deg/s).
    peak_deg_s, accel_deg_s2
        Peak angular velocity (deg/s) and acceleration (deg/s^2) of the turn.
    still_s
        Seconds at rest after the turn.
    cutoff_hz
        Cut-off of the causal second-order Butterworth low-pass filter.
    """
    if starts_deg is None:
        starts_deg = [a for a in range(-180, 181, 10) if a != 0]
    scale = {"angle": 180.0, "angular_velocity": 90.0}
    sos = butter(2, cutoff_hz, fs=1.0 / dt, output="sos")
    zi = sosfilt_zi(sos)
    episodes = []
    for start in starts_deg:
        angle, vel = _turn_profile(float(start), peak_deg_s, accel_deg_s2, still_s, dt)
        cols = []
        for name in channels:
            x = (angle if name == "angle" else vel) / scale[name]
            cols.append(sosfilt(sos, x, zi=zi * x[0])[0])
        episodes.append(np.stack(cols, axis=1))
    lengths = np.array([len(e) for e in episodes], dtype=np.int64)
    return np.concatenate(episodes), lengths


def _rates(fn: Callable[[], object], n_items: int, repeats: int) -> tuple[float, float]:
    """Median and best items per second over ``repeats`` calls of ``fn``."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return n_items / statistics.median(times), n_items / min(times)


def _live_latency(
    X: FloatArray, lengths: IntArray, n_categories: int, n_readings: int, seed: int
) -> tuple[float, float]:
    """Median and p99 (microseconds) of one live update with ``n_categories`` categories."""
    model = CobART.motion_primitives().fit(X, lengths)
    rng = np.random.default_rng(seed)
    i = model.window
    padded = np.concatenate([np.repeat(X[:1], i - 1, axis=0), X])
    windows = np.lib.stride_tricks.sliding_window_view(padded, i, axis=0).transpose(0, 2, 1)
    pick = rng.choice(windows.shape[0], size=n_categories, replace=False)
    model.set_state(windows[pick], np.ones(n_categories, dtype=np.int64), model.dcm_scale_)
    live = model.stream()
    update = live.update
    clock = time.perf_counter_ns
    rows = list(X)
    ends = set(np.cumsum(lengths).tolist())
    lat = np.empty(n_readings)
    j = 0
    for _ in range(n_readings):
        if j in ends or j == len(rows):
            live.reset()
            j = j % len(rows)
        t0 = clock()
        update(rows[j])
        lat[_] = clock() - t0
        j += 1
    return float(np.median(lat) / 1e3), float(np.percentile(lat, 99) / 1e3)


def default_turn_data() -> tuple[FloatArray, IntArray]:
    """The default turn dataset, filtered and normalized like the SBLM does (angle, ang. vel.)."""
    from behavior_hmm.benchmarks._common import default_dataset
    from behavior_hmm.data import SignalPipeline

    ds = default_dataset("turn")
    x = SignalPipeline(("angle", "angular_velocity")).transform(ds)
    return x, np.asarray(ds.lengths, dtype=np.int64)


def run(
    quick: bool = False, data: tuple[FloatArray, IntArray] | None = None, seed: int = 0
) -> dict[str, Any]:
    """Measure CobART speed; see the module docstring for the figures.

    Parameters
    ----------
    quick
        Fewer repeats and readings (a smoke run, figures less stable).
    data
        ``(X, lengths)`` to use instead of the synthetic turn dataset (angle channel
        first; its first channel is used for the one-channel figures).
    seed
        Seed for choosing the 200 live prototypes.
    """
    repeats = 3 if quick else 7
    n_live = 3000 if quick else 30000
    if data is None:
        data = default_turn_data()
        out_source = "default turn dataset (MuJoCo, DESIGN §6 grid), angle + angular_velocity"
    else:
        out_source = "caller's data"
    if data is None:
        X2, lengths = synthetic_turn_episodes(channels=("angle", "angular_velocity"))
    else:
        X2 = np.asarray(data[0], dtype=np.float64)
        X2 = X2[:, None] if X2.ndim == 1 else X2
        lengths = np.asarray(data[1], dtype=np.int64)
    X1 = np.ascontiguousarray(X2[:, :1])
    n = X1.shape[0]
    motion = CobART.motion_primitives()
    observation = CobART.observations()
    out: dict[str, Any] = {
        "n_windows": float(n),
        "n_episodes": float(len(lengths)),
        "data": out_source,
    }
    out["windows_per_s"], out["windows_per_s_best"] = _rates(
        lambda: motion.fit(X1, lengths), n, repeats
    )
    out["n_categories"] = float(motion.n_categories_)
    out["predict_windows_per_s"] = _rates(lambda: motion.categorize(X1, lengths), n, repeats)[0]
    out["obs_windows_per_s"] = _rates(lambda: observation.fit(X1, lengths), n, repeats)[0]
    out["obs_n_categories"] = float(observation.n_categories_)
    if X2.shape[1] > 1:
        two = np.ascontiguousarray(X2[:, :2])
        motion2 = CobART.motion_primitives()
        out["windows_per_s_2ch"] = _rates(lambda: motion2.fit(two, lengths), n, repeats)[0]
        out["n_categories_2ch"] = float(motion2.n_categories_)
    med, p99 = _live_latency(X1, lengths, 200, n_live, seed)
    out["predict_us_median"], out["predict_us_p99"] = med, p99
    if X2.shape[1] > 1:
        med2, _ = _live_latency(np.ascontiguousarray(X2[:, :2]), lengths, 200, n_live, seed)
        out["predict_us_median_2ch"] = med2
    return out


if __name__ == "__main__":
    print(json.dumps(run(quick="--quick" in sys.argv[1:]), indent=2))
