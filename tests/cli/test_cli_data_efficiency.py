"""``experiment data-efficiency``: its options reach the experiment, and bad ones are
refused with one line and exit code 2 before any work."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from cli_testing import Invoke, assert_user_error

from behavior_hmm.evaluate import _data_efficiency as de
from behavior_hmm.evaluate._data_efficiency import summarize


def _results(seeds: list[int], fractions: list[float]) -> dict[str, Any]:
    """A hand-made result for the report: turn only, every cell the same."""
    cells = []
    for f in fractions:
        n = de.subset_size(f, 36)
        for s in seeds:
            ours = {"success_rate_mean": 90.0 + s, "goal_reached": 15, "n": 15}
            ours |= {"zero_floor": 42.0, "command_scale": 1.0, "primitives": 4, "observations": 9}
            cells.append(
                {
                    "behavior": "turn",
                    "fraction": f,
                    "seed": s,
                    "n_demonstrations": n,
                    "n_episodes": n,
                    "n_rows": 10 * n,
                    "grid_indices": list(range(n)),
                    "starts": [],
                    "ours": ours,
                }
            )
    info = {"behavior": "turn", "inputs": ["angle"], "components": [], "thesis": 90.9}
    info |= {"grid_size": 36, "episodes_per_start": 1, "command_scale": 1.0}
    return {
        "sim": "kinematic",
        "seeds": seeds,
        "fractions": fractions,
        "bc": False,
        "tasks": {"turn": info},
        "cells": cells,
        "summary": summarize(cells),
        "timings": {"collect_s": 0.5, "cells": []},
    }


def test_the_options_reach_the_experiment(
    invoke: Invoke, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    seen: dict[str, Any] = {}

    def fake(**kwargs: Any) -> dict[str, Any]:
        seen.update(kwargs)
        seeds = [kwargs["seed"] + k for k in range(kwargs["seeds"])]
        return _results(seeds, list(kwargs["fractions"]))

    monkeypatch.setattr(de, "run_data_efficiency_experiment", fake)
    out = tmp_path / "de"
    args = ["experiment", "data-efficiency", "--sim", "kinematic", "--seeds", "2"]
    args += ["--fractions", "1,0.25", "--no-bc", "--preset", "thesis", "--workers", "1"]
    result = invoke([*args, "-o", out])
    assert result.exit_code == 0, result.output
    assert seen["sim"] == "kinematic" and seen["seed"] == 0 and seen["seeds"] == 2
    assert seen["fractions"] == (0.25, 1.0) and seen["bc"] is False
    assert seen["sblm_params"]["onset_clock"] == 0  # the thesis preset's SBLM
    assert "cblm_params" in seen and seen["executor"].workers == 1
    assert "| turn | 1/4 | 9 of 36 | 90.5 ± 0.7 (15.0/15) | 42.0 |" in result.stdout
    for name in ("results.json", "timings.json", "table.md", "data_efficiency.png"):
        assert (out / name).is_file(), name
    assert "thesis preset" in (out / "table.md").read_text()


def test_the_defaults(invoke: Invoke, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    seen: dict[str, Any] = {}

    def fake(**kwargs: Any) -> dict[str, Any]:
        seen.update(kwargs)
        return _results([0, 1, 2, 3, 4], list(kwargs["fractions"]))

    monkeypatch.setattr(de, "run_data_efficiency_experiment", fake)
    result = invoke(["experiment", "data-efficiency", "-o", tmp_path / "de"])
    assert result.exit_code == 0, result.output
    assert seen["sim"] == "mujoco" and seen["seeds"] == 5 and seen["bc"] is True
    assert seen["fractions"] == (0.125, 0.25, 0.5, 1.0)


@pytest.mark.parametrize(
    ("option", "needle"),
    [
        (["--fractions", "0,0.5"], "--fractions must each lie in (0, 1], got 0"),
        (["--fractions", "0.5,1.5"], "--fractions must each lie in (0, 1], got 1.5"),
        (["--fractions", "-0.25"], "got -0.25"),
        (["--fractions", "nan"], "(0, 1]"),
        (["--fractions", "0.5,0.5"], "--fractions repeats 0.5"),
        (["--fractions", "half"], "comma-separated numbers"),
        (["--fractions", ""], "comma-separated numbers"),
        (["--seeds", "0"], "--seeds must be an integer in [1, 1000], got 0"),
        (["--seeds", "-3"], "--seeds"),
        (["--seeds", "two"], "--seeds"),
        (["--seed", "-1"], "--seed must be an integer >= 0"),
        (["--sim", "webots"], "unknown simulator 'webots'"),
        (["--workers", "0"], "--workers must be an integer in [1, 1024]"),
        (["--set", "nonsense=1"], "nonsense"),
    ],
)
def test_bad_options_are_refused_before_any_work(
    invoke: Invoke,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    option: list[str],
    needle: str,
) -> None:
    def never(**kwargs: Any) -> dict[str, Any]:
        raise AssertionError("the experiment ran")

    monkeypatch.setattr(de, "run_data_efficiency_experiment", never)
    out = tmp_path / "de"
    result = invoke(["experiment", "data-efficiency", *option, "-o", out])
    assert_user_error(result, needle)
    assert not out.exists()
