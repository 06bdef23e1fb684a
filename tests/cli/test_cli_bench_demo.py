"""``behavior-hmm bench`` and ``behavior-hmm demo``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from cli_testing import Invoke, assert_user_error, png_size

from behavior_hmm import data
from behavior_hmm.teach import behavior_spec, default_starts


def test_bench_sim_writes_real_time_factors(invoke: Invoke, tmp_path: Path) -> None:
    out = tmp_path / "sim.json"
    result = invoke(["bench", "sim", "--quick", "--json", out])
    assert result.exit_code == 0, result.output
    results = json.loads(out.read_text())
    assert json.loads(result.stdout) == results  # the same JSON is printed
    for key in ("mujoco_rtf", "kinematic_rtf"):
        assert isinstance(results[key], float) and math.isfinite(results[key])
        assert results[key] > 0
    assert results["benchmark"] == "sim"


def test_bench_refuses_unknown_names_and_folders(invoke: Invoke, tmp_path: Path) -> None:
    out = tmp_path / "x.json"
    assert_user_error(invoke(["bench", "simulator", "--json", out]), "unknown benchmark", "sim")
    assert_user_error(invoke(["bench", "sim", "--quick", "--json", tmp_path]), "folder")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_demo_collects_trains_composes_and_evaluates(invoke: Invoke, tmp_path: Path) -> None:
    out = tmp_path / "demo"
    result = invoke(["demo", "--sim", "kinematic", "-o", out])
    assert result.exit_code == 0, result.output
    for behavior in ("turn", "approach", "turn-approach"):
        ds = data.read(out / f"{behavior}.parquet")
        # each default start once, plus the behavior's corrective copies (approach: 1)
        copies = 1 + behavior_spec(behavior).corrections
        assert len(ds) == copies * len(default_starts(behavior))
        assert ds.metadata["behavior"] == behavior
        assert ds.metadata["simulator"] == "kinematic"
        png_size(out / f"{behavior}_demonstrations.png")
        png_size(out / f"{behavior}_run.png")
        assert (out / f"{behavior}.bhmm").stat().st_size > 0
        assert behavior in result.stdout
        # a video of one run (GIF: Pillow comes with matplotlib) and a report of them all
        from PIL import Image

        with Image.open(out / f"{behavior}_run.gif") as gif:
            assert gif.n_frames > 10
        report = (out / f"{behavior}_report.html").read_text()
        assert report.count("<img") >= 1
    # grasp, on the Khepera with a gripper (MuJoCo whatever --sim says)
    grasp = data.read(out / "grasp.parquet")
    assert grasp.metadata["env"] == "behavior_hmm/KheperaGripper-v0"
    assert len(grasp) == len(default_starts("grasp"))
    png_size(out / "grasp_run.png")
    assert (out / "grasp.bhmm").stat().st_size > 0
    assert (out / "grasp_report.html").read_text().count("<img") >= 1
    row = next(line for line in result.stdout.splitlines() if "grasp (gripper robot)" in line)
    assert row.split()[-1] == "15/15"  # every object lifted
    # the report table: one row per behavior with its success rate, floor and goals
    assert "success %" in result.stdout and "zero floor %" in result.stdout
    assert "/15" in result.stdout
    last = result.stdout.splitlines()[-2:]
    assert last[0].startswith("videos: ") and str(out / "turn-approach_run.gif") in last[0]
    assert last[1].startswith(f"reports: {out}/<behavior>_report.html")


def test_demo_refuses_bad_options(invoke: Invoke, tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert_user_error(invoke(["demo", "--sim", "gazebo", "-o", tmp_path / "d"]), "gazebo")
    assert_user_error(invoke(["demo", "--sim", "kinematic", "-o", blocker]), "folder")
    assert_user_error(invoke(["demo", "--seed", "-2", "-o", tmp_path / "d"]), "--seed")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]
