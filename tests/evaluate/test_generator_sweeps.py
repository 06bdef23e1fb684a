"""Thesis §6.2 and appendix A sweeps on small synthetic data, and the learning-curve plots."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate._generator_sweeps import (
    primitive_target_stats,
    representative_primitive,
    run_generator_sweeps,
)
from behavior_hmm.generators import MotionGenerators
from behavior_hmm.viz._learning_curves import (
    draw_learning_curves,
    plot_generator_sweeps,
    plot_learning_curves,
    sweep_curves,
)

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _data(rng: np.random.Generator):
    x = rng.uniform(-1, 1, (150, 10))
    y = 0.5 * np.tanh(x[:, :2] - x[:, 8:])
    prim = np.where(np.arange(150) < 100, 2, 0)  # primitive 2 has the most samples
    return x, y, prim


def _turn_like(rng: np.random.Generator):
    """Primitives as a turn has them: the biggest is the robot at rest (targets ~0)."""
    sizes = {0: 300, 1: 120, 2: 80, 3: 60, 4: 200}
    prim = np.concatenate([np.full(n, p) for p, n in sizes.items()])
    y = np.zeros((prim.size, 2))
    for p, level, spread in ((0, 0.0, 0.01), (1, 0.6, 0.15), (2, 0.9, 0.2), (3, 0.3, 0.12)):
        rows = prim == p
        ramp = level + spread * np.linspace(-1.7, 1.7, rows.sum())
        y[rows] = np.column_stack([ramp, -ramp])
    y[prim == 4] = [0.95, -0.95]  # cruising: large but constant
    y += rng.normal(0, 1e-3, y.shape)
    x = rng.uniform(-1, 1, (prim.size, 10))
    return x, np.clip(y, -1, 1), prim


def test_sweeps_write_figures_and_summary(rng: np.random.Generator, tmp_path: Path) -> None:
    x, y, prim = _data(rng)
    report = run_generator_sweeps(
        x, y, prim, tmp_path, epochs=6, learning_rates=(0.01, 0.5), momenta=(0.0, 0.4),
        hidden_layouts=((5,), (3, 3)),
    )  # fmt: skip
    assert report["primitive"] in (0, 2)
    assert report["selection"]["chosen"]["primitive"] == report["primitive"]
    n_train = report["n_train"]
    assert n_train + report["n_test"] == (100 if report["primitive"] == 2 else 50)
    # an iteration is one training sample presented: epoch e ends at iteration e * n_train
    assert report["iterations_per_epoch"] == n_train
    assert report["iterations"] == [n_train * e for e in range(1, 7)]
    assert "iteration" in report["iteration_label"]
    assert set(report["sweeps"]) == {"learning_rate", "momentum", "hidden"}
    assert set(report["sweeps"]["learning_rate"]) == {"lr=0.01", "lr=0.5"}
    assert set(report["sweeps"]["hidden"]) == {"hidden=1x5", "hidden=2x3"}
    for entries in report["sweeps"].values():
        for entry in entries.values():
            assert len(entry["test_error"]) == 6
            assert entry["best_test_error"] == min(entry["test_error"])
            assert entry["final_test_error"] == entry["test_error"][-1]
            assert entry["best_iteration"] == entry["best_epoch"] * n_train
            # the untrained network (iteration 0) is worse than the trained one
            assert entry["initial_test_error"] > entry["best_test_error"]
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
        hidden_layouts=((5,),), primitive=2, random_state=4,
    )  # fmt: skip
    assert not list(tmp_path.glob("*.png"))
    model = MotionGenerators(epochs=4, batch_size=1, early_stopping=False, random_state=4)
    model.fit(x, y, prim)
    np.testing.assert_allclose(
        report["sweeps"]["learning_rate"]["lr=0.01"]["test_error"], model.test_error_[2], rtol=1e-12
    )


def test_representative_primitive_picks_one_whose_targets_move(rng: np.random.Generator) -> None:
    _, y, prim = _turn_like(rng)
    stats = primitive_target_stats(y, prim)
    assert [s["n_samples"] for s in stats] == [300, 120, 80, 60, 200]
    chosen, why = representative_primitive(y, prim)
    # not the near-rest primitive with the most samples (0), nor the constant cruise (4)
    assert why["most_samples"]["primitive"] == 0
    assert chosen == 1
    assert stats[chosen]["target_std"] >= why["median_target_std"] > stats[0]["target_std"]
    assert stats[chosen]["target_rms"] >= why["median_target_rms"]
    assert stats[4]["target_std"] < why["median_target_std"]
    assert set(why["candidates"]) == {1, 2}
    # primitives below min_samples are never chosen
    chosen_big, _ = representative_primitive(y, prim, min_samples=100)
    assert chosen_big == 1 and representative_primitive(y, prim, min_samples=150)[0] in (0, 4)
    with pytest.raises(ConfigError, match="samples or more"):
        representative_primitive(y, prim, min_samples=1000)


def test_default_sweep_studies_the_representative_primitive(
    rng: np.random.Generator, tmp_path: Path
) -> None:
    x, y, prim = _turn_like(rng)
    x2 = np.column_stack([x, rng.uniform(-1, 1, x.shape)])
    report = run_generator_sweeps(
        x, y, prim, tmp_path, epochs=3, learning_rates=(0.01,), momenta=(0.4,),
        hidden_layouts=((5,),), X_two_inputs=x2, two_input_layouts=((5,), (4, 4)),
        two_inputs_label="a, b",
    )  # fmt: skip
    assert report["primitive"] == 1
    assert (report["n_train"], report["n_test"]) == (96, 24)
    two = report["sweeps"]["hidden_two_inputs"]
    assert set(two) == {"hidden=1x5", "hidden=2x4"}
    assert {entry["n_inputs"] for entry in two.values()} == {20}
    assert report["sweeps"]["hidden"]["hidden=1x5"]["n_inputs"] == 10
    assert "20 inputs (a, b)" in report["titles"]["hidden_two_inputs"]
    figures = plot_generator_sweeps(report, tmp_path)
    assert Path(figures["hidden_two_inputs"]).name == "generator_sweep_hidden_two_inputs.png"
    assert Path(figures["hidden_two_inputs"]).read_bytes().startswith(PNG_MAGIC)


def test_sweep_curves_start_at_iteration_zero() -> None:
    entries = {"a": {"initial_test_error": 1.0, "test_error": [0.5, None, 0.2]}}
    curves, x = sweep_curves(entries, [10, 20, 30])
    np.testing.assert_array_equal(x, [0, 10, 20, 30])
    np.testing.assert_array_equal(curves["a"], [1.0, 0.5, np.nan, 0.2])
    fig = draw_learning_curves(curves, x=x, xlabel="iteration")
    ax = fig.axes[0]
    assert ax.get_xlabel() == "iteration"
    np.testing.assert_array_equal(ax.lines[0].get_xdata(), x)
    with pytest.raises(ConfigError, match="x values"):
        draw_learning_curves(curves, x=[0, 1])


def test_sweeps_refuse_bad_input(rng: np.random.Generator, tmp_path: Path) -> None:
    x, y, prim = _data(rng)
    with pytest.raises(ConfigError):
        run_generator_sweeps(x, y, prim, tmp_path, epochs=0)
    with pytest.raises(ConfigError, match="no samples"):
        run_generator_sweeps(x, y, prim, tmp_path, primitive=1)
    with pytest.raises(ConfigError, match="test split"):
        run_generator_sweeps(x[:3], y[:3], prim[:3], tmp_path, min_samples=1)


def test_plot_learning_curves_writes_a_png(tmp_path: Path) -> None:
    curves = {"a": np.geomspace(1.0, 0.01, 30), "b": np.r_[np.linspace(0.5, 0.2, 10), [np.nan] * 5]}
    path = tmp_path / "sub" / "curves.png"
    plot_learning_curves(curves, path, "title")
    assert path.read_bytes().startswith(PNG_MAGIC)
    with pytest.raises(ConfigError):
        plot_learning_curves({}, tmp_path / "x.png", "empty")
    with pytest.raises(ConfigError):
        plot_learning_curves({"a": np.zeros((2, 2))}, tmp_path / "x.png", "2-D")
    assert not (tmp_path / "x.png").exists()
