"""The demonstration plot (time vs angle / distance, one line per episode)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.image import imread

from behavior_hmm.data import CONTROL_PERIOD, Dataset
from behavior_hmm.errors import BehaviorHMMError, ConfigError
from behavior_hmm.viz import plot_demonstrations

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _ds(vary_distance: bool = True) -> Dataset:
    eps = []
    for a0 in (-120.0, -30.0, 60.0, 150.0):
        n = 120
        s = np.linspace(0.0, 1.0, n)
        ramp = s * s * (3 - 2 * s)
        distance = 0.6 * (1 - ramp) + 0.01 if vary_distance else np.full(n, 0.5)
        eps.append(
            {
                "t": np.arange(n) * CONTROL_PERIOD,
                "distance": distance,
                "linear_velocity": np.zeros(n),
                "angle": a0 * (1 - ramp),
                "angular_velocity": np.zeros(n),
                "left": np.zeros(n),
                "right": np.zeros(n),
            }
        )
    return Dataset.from_episodes(eps, {"behavior": "turn"})


def _subplots(monkeypatch: pytest.MonkeyPatch) -> list[Figure]:
    figures: list[Figure] = []
    original = Figure.savefig

    def spy(self: Figure, *args: object, **kw: object) -> None:
        figures.append(self)
        original(self, *args, **kw)

    monkeypatch.setattr(Figure, "savefig", spy)
    return figures


def test_writes_a_png(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    figures = _subplots(monkeypatch)
    out = tmp_path / "plots" / "demo.png"
    fig = plot_demonstrations(_ds(), out)
    assert fig is figures[0]
    assert out.read_bytes()[:8] == PNG_MAGIC
    assert imread(out).shape[0] > 300
    axes = [ax for ax in figures[0].axes if ax.get_label() != "<colorbar>"]
    assert [ax.get_ylabel() for ax in axes] == ["angle (deg)", "distance (m)"]
    assert axes[-1].get_xlabel() == "time since episode start (s)"
    assert len([ln for ln in axes[0].get_lines() if len(ln.get_xdata()) > 2]) == 4
    assert [p.name for p in out.parent.iterdir()] == ["demo.png"]


def test_default_skips_constant_distance(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    figures = _subplots(monkeypatch)
    plot_demonstrations(_ds(vary_distance=False), tmp_path / "turn.png")
    labels = [ax.get_ylabel() for ax in figures[0].axes if ax.get_label() != "<colorbar>"]
    assert labels == ["angle (deg)"]


def test_explicit_channels(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    figures = _subplots(monkeypatch)
    plot_demonstrations(_ds(), tmp_path / "d.png", channels=["distance", "left"], title="x")
    labels = [ax.get_ylabel() for ax in figures[0].axes if ax.get_label() != "<colorbar>"]
    assert labels == ["distance (m)", "left wheel (rad/s)"]


def test_unknown_channel(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="cannot plot channel 'speed'"):
        plot_demonstrations(_ds(), tmp_path / "d.png", channels=["speed"])
    assert not (tmp_path / "d.png").exists()


def test_failed_write_keeps_old_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "d.png"
    path.write_bytes(b"old")

    def fail(self: Figure, fname: object, **kw: object) -> None:
        Path(str(fname)).write_bytes(PNG_MAGIC)
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Figure, "savefig", fail)
    with pytest.raises(BehaviorHMMError, match="No space left"):
        plot_demonstrations(_ds(), path)
    assert path.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["d.png"]
