"""Thesis-style generated-vs-demonstrated figures: figs 6.8/6.9 and appendix B grids."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from behavior_hmm.errors import ConfigError
from behavior_hmm.viz import (
    plot_complex_grid,
    plot_start_grid,
    plot_thesis_starts,
    simple_panels,
    write_complex_report,
    write_simple_report,
)
from behavior_hmm.viz._grids import inputs_label, start_label

PNG = b"\x89PNG\r\n\x1a\n"


def _curve(start: float, n: int) -> np.ndarray:
    return start * 0.5 * (1 + np.cos(np.linspace(0, np.pi, n)))


def _series(behavior: str, inputs: list[str], starts: list[float], offset: float) -> dict:
    channel = "angle" if behavior == "turn" else "distance"
    runs = []
    for k, value in enumerate(starts):
        start = {"angle": value, "distance": 0.5} if channel == "angle" else {"distance": value}
        runs.append(
            {
                "start": start,
                "generated": _curve(value, 40 + k) + offset,
                "demonstrated": _curve(value, 42 + k),
                "success_rate": 90.0 + offset,
                "goal_reached": offset < 0.5,
            }
        )
    return {"behavior": behavior, "inputs": inputs, "channel": channel, "runs": runs}


TURN_STARTS = [float(a) for a in np.linspace(-170, 164, 15)]
APPROACH_STARTS = [float(d) for d in np.linspace(0.12, 0.96, 15)]


def _simple_figures() -> dict[str, list[dict[str, Any]]]:
    return {
        "test_starts": [
            _series("turn", ["angle"], TURN_STARTS, 0.0),
            _series("turn", ["angle", "angular_velocity"], TURN_STARTS, 1.0),
            _series("approach", ["distance"], APPROACH_STARTS, 0.0),
            _series("approach", ["distance", "angle"], APPROACH_STARTS, 0.01),
            _series("approach", ["distance", "angle", "linear_velocity"], APPROACH_STARTS, 0.02),
        ],
        "thesis_starts": [
            _series("turn", ["angle"], [100.0, -100.0], 0.0),
            _series("turn", ["angle", "angular_velocity"], [100.0, -100.0], 1.0),
            _series("approach", ["distance"], [0.7, 0.35], 0.0),
            _series("approach", ["distance", "angle"], [0.7, 0.35], 0.01),
            _series("approach", ["distance", "angle", "linear_velocity"], [0.7, 0.35], 0.02),
        ],
    }


def test_labels_are_plain_text() -> None:
    assert inputs_label(["angle", "angular_velocity"]) == "{angle, angular velocity}"
    assert start_label({"angle": -100.0, "distance": 0.5}, "angle") == "angle -100°"
    assert start_label({"angle": 0.0, "distance": 0.35}, "distance") == "distance 0.35 m"


def test_simple_panels_overlay_every_input_set_per_start() -> None:
    panels = simple_panels(_simple_figures()["test_starts"], "approach")
    assert len(panels) == 15
    assert [p["start"]["distance"] for p in panels] == APPROACH_STARTS
    labels = ["{distance}", "{distance, angle}", "{distance, angle, linear velocity}"]
    for panel in panels:
        assert list(panel["generated"]) == labels
        assert panel["channel"] == "distance"
        assert set(panel["success_rate"]) == set(labels)
    with pytest.raises(ConfigError, match="no figure series"):
        simple_panels(_simple_figures()["test_starts"], "retreat")
    broken = _simple_figures()["test_starts"][:2]
    broken[1]["runs"] = broken[1]["runs"][:3]
    with pytest.raises(ConfigError, match="share their starts"):
        simple_panels(broken, "turn")


def test_start_grid_has_one_panel_per_start() -> None:
    panels = simple_panels(_simple_figures()["test_starts"], "turn")
    fig = plot_start_grid(panels, title="turn grid")  # drawn, not written (see the report test)
    visible = [ax for ax in fig.axes if ax.get_visible()]
    assert len(visible) == 15
    assert [ax.get_title() for ax in visible] == [f"angle {a:g}°" for a in TURN_STARTS]
    for ax in visible:
        # the demonstration and one line per input set
        assert len(ax.lines) == 3
        texts = [t.get_text() for t in ax.texts]
        assert texts[0].startswith("90.0 %") and texts[1].endswith("*")  # goal missed
    assert fig.get_suptitle() == "turn grid"


def test_thesis_starts_overlay_input_sets_in_one_axes_per_start(tmp_path: Path) -> None:
    panels = simple_panels(_simple_figures()["thesis_starts"], "approach")
    fig = plot_thesis_starts(panels, tmp_path / "fig69.png")
    assert (tmp_path / "fig69.png").read_bytes().startswith(PNG)
    assert len(fig.axes) == 2
    assert [ax.get_title() for ax in fig.axes] == [
        "(a) from distance 0.70 m",
        "(b) from distance 0.35 m",
    ]
    assert all(len(ax.lines) == 4 for ax in fig.axes)  # demonstration + three input sets
    assert fig.axes[0].get_ylabel() == "distance (m)"
    assert fig.axes[0].get_xlabel() == "time (s)"


def _complex_runs(n: int) -> list[dict[str, Any]]:
    runs = []
    for k in range(n):
        steps = 60
        comp = ["turn"] * 25 + ["approach"] * 35 if k else ["approach"] * steps
        runs.append(
            {
                "start": {"angle": 10.0 * k, "distance": 0.5},
                "t": np.arange(steps) * 0.016,
                "angle": np.r_[np.linspace(10.0 * k, 0, 25), np.zeros(35)],
                "distance": np.r_[np.full(25, 0.5), np.linspace(0.5, 0, 35)],
                "component": comp,
                "demo_angle": np.r_[np.linspace(10.0 * k, 0, 27), np.zeros(35)],
                "demo_distance": np.r_[np.full(27, 0.5), np.linspace(0.5, 0, 35)],
                "demo_behavior": ["turn"] * 27 + ["approach"] * 35,
                "success_rate": 88.0,
                "goal_reached": k != 2,
            }
        )
    return runs


def test_complex_grid_draws_angle_and_distance_per_start() -> None:
    runs = _complex_runs(15)
    fig = plot_complex_grid(runs, title="B.3")
    assert len(fig.axes) == 30  # angle and distance for each of the 15 starts
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    assert len(titles) == 15
    assert titles[0] == "angle 0°, distance 0.50 m: success 88.0 %"
    assert titles[2].endswith("goal missed")
    angle_ax = fig.axes[2]
    # demonstration + one segment per active component, each in its component's colour
    colors = {line.get_color() for line in angle_ax.lines[1:]}
    assert len(angle_ax.lines) == 3 and len(colors) == 2
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend == [
        "demonstrated (teacher)",
        "generated, approach active",
        "generated, turn active",
    ]


@pytest.mark.slow
def test_reports_write_the_thesis_figures(tmp_path: Path) -> None:
    rows = [
        {
            "behavior": "turn",
            "inputs": ["angle"],
            "thesis": 90.9,
            "sblm": 95.0,
            "sblm_goal_reached": 15,
            "bc": 90.0,
            "bc_goal_reached": 15,
            "zero_floor": 40.0,
            "sblm_motor_max": 99.0,
            "zero_floor_motor_max": 94.0,
            "n": 15,
            "primitives": 30,
            "observations": 98,
        }
    ]
    simple = {"sim": "kinematic", "rows": rows, "figures": _simple_figures()}
    write_simple_report(simple, tmp_path / "simple")
    for name in (
        "turn_generated_vs_demonstrated",
        "approach_generated_vs_demonstrated",
        "turn_test_starts",
        "approach_test_starts",
    ):
        assert (tmp_path / "simple" / f"{name}.png").read_bytes().startswith(PNG), name
    summary = {
        "success_rate_mean": 80.0,
        "zero_floor_mean": 40.0,
        "goal_reached": 15,
        "n": 15,
        "success_rate_motor_max_mean": 95.0,
        "zero_floor_motor_max_mean": 70.0,
    }
    part = {**summary, "approach_goal_reached": 15, "approach_n": 15}
    part |= {"retreat_goal_reached": 15, "retreat_n": 15}
    complex_results = {
        "sim": "kinematic",
        "turn_approach": {**summary, "baselines": {"bc": summary}},
        "turn_approach_train_s": 1.0,
        "turn_approach_observations": 10,
        "position": part,
        "nested_position": part,
        "retreat": summary,
        "figure": _complex_runs(15),
        "figure_highlight": [13, 3],
    }
    write_complex_report(complex_results, tmp_path / "complex")
    pngs = sorted(p.name for p in (tmp_path / "complex").glob("*.png"))
    assert pngs == ["turn_approach_0.png", "turn_approach_1.png", "turn_approach_test_starts.png"]
    public = json.loads((tmp_path / "complex" / "results.json").read_text())
    assert "figure" not in public and public["figure_highlight"] == [13, 3]
