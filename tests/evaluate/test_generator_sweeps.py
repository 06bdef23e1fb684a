"""Thesis §6.2 sweeps on small synthetic data, and the learning-curve plot."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate._generator_sweeps import run_generator_sweeps
from behavior_hmm.generators import MotionGenerators
from behavior_hmm.viz._learning_curves import plot_generator_sweeps, plot_learning_curves

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _data(rng: np.random.Generator):
    x = rng.uniform(-1, 1, (150, 10))
    y = 0.5 * np.tanh(x[:, :2] - x[:, 8:])
    prim = np.where(np.arange(150) < 100, 2, 0)  # primitive 2 has the most samples
    return x, y, prim


def test_sweeps_write_figures_and_summary(rng: np.random.Generator, tmp_path: Path) -> None:
    x, y, prim = _data(rng)
    report = run_generator_sweeps(
        x, y, prim, tmp_path, epochs=6, learning_rates=(0.01, 0.5), momenta=(0.0, 0.4),
        hidden_layouts=((5,), (3, 3)),
    )  # fmt: skip
    assert report["primitive"] == 2
    assert (report["n_train"], report["n_test"]) == (80, 20)
    assert set(report["sweeps"]) == {"learning_rate", "momentum", "hidden"}
    assert set(report["sweeps"]["learning_rate"]) == {"lr=0.01", "lr=0.5"}
    assert set(report["sweeps"]["hidden"]) == {"hidden=1x5", "hidden=2x3"}
    for entries in report["sweeps"].values():
        for entry in entries.values():
            assert len(entry["test_error"]) == 6
            assert entry["best_test_error"] == min(entry["test_error"])
            assert entry["final_test_error"] == entry["test_error"][-1]
    figures = plot_generator_sweeps(report, tmp_path)
    for name in ("learning_rate", "momentum", "hidden"):
        png = Path(figures[name])
        assert png.parent == tmp_path and png.read_bytes().startswith(PNG_MAGIC)
    assert json.loads(Path(report["summary_file"]).read_text()) == report
    # The shared baseline (lr 0.01, momentum 0.4, 1x5) is one run reported in every sweep.
    base = report["sweeps"]["learning_rate"]["lr=0.01"]
    assert report["sweeps"]["momentum"]["momentum=0.4"] == base
    assert report["sweeps"]["hidden"]["hidden=1x5"] == base
    assert not list(tmp_path.glob(".*.tmp"))


def test_sweep_baseline_matches_motion_generators(rng: np.random.Generator, tmp_path) -> None:
    """The sweep is MotionGenerators' incremental training of that primitive."""
    x, y, prim = _data(rng)
    report = run_generator_sweeps(
        x, y, prim, tmp_path, epochs=4, learning_rates=(0.01,), momenta=(0.4,),
        hidden_layouts=((5,),), random_state=4,
    )  # fmt: skip
    assert not list(tmp_path.glob("*.png"))
    model = MotionGenerators(epochs=4, batch_size=1, early_stopping=False, random_state=4)
    model.fit(x, y, prim)
    np.testing.assert_allclose(
        report["sweeps"]["learning_rate"]["lr=0.01"]["test_error"], model.test_error_[2], rtol=1e-12
    )


def test_sweeps_refuse_bad_input(rng: np.random.Generator, tmp_path: Path) -> None:
    x, y, prim = _data(rng)
    with pytest.raises(ConfigError):
        run_generator_sweeps(x, y, prim, tmp_path, epochs=0)
    with pytest.raises(ConfigError, match="no samples"):
        run_generator_sweeps(x, y, prim, tmp_path, primitive=1)
    with pytest.raises(ConfigError, match="test split"):
        run_generator_sweeps(x[:3], y[:3], prim[:3], tmp_path)


def test_plot_learning_curves_writes_a_png(tmp_path: Path) -> None:
    curves = {"a": np.geomspace(1.0, 0.01, 30), "b": np.r_[np.linspace(0.5, 0.2, 10), [np.nan] * 5]}
    path = plot_learning_curves(curves, tmp_path / "sub" / "curves.png", "title")
    assert path.read_bytes().startswith(PNG_MAGIC)
    with pytest.raises(ConfigError):
        plot_learning_curves({}, tmp_path / "x.png", "empty")
    with pytest.raises(ConfigError):
        plot_learning_curves({"a": np.zeros((2, 2))}, tmp_path / "x.png", "2-D")
    assert not (tmp_path / "x.png").exists()
