"""``experiment data-efficiency``: nested subsets, a tiny end-to-end run, the aggregation
over seeds and the report."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate import _data_efficiency as de
from behavior_hmm.evaluate._baselines import BASELINES
from behavior_hmm.evaluate._data_efficiency import (
    check_fractions,
    check_tasks,
    grid_subset,
    nested_subsets,
    parse_fractions,
    run_data_efficiency_experiment,
    subset_size,
    summarize,
)
from behavior_hmm.evaluate._executor import ProcessExecutor, SerialExecutor
from behavior_hmm.teach import collect
from behavior_hmm.viz._data_efficiency import (
    FIGURE_NAME,
    fraction_text,
    plot_data_efficiency,
    write_data_efficiency_report,
)

PNG = b"\x89PNG\r\n\x1a\n"
FRACTIONS = (0.125, 0.25, 0.5, 1.0)


# ------------------------------------------------------------------------ subsets
def test_subset_sizes() -> None:
    # the default grids: turn 36, approach 19, turn & approach 208 starts
    assert [subset_size(f, 36) for f in FRACTIONS] == [5, 9, 18, 36]
    assert [subset_size(f, 19) for f in FRACTIONS] == [3, 5, 10, 19]
    assert [subset_size(f, 208) for f in FRACTIONS] == [26, 52, 104, 208]
    assert subset_size(0.01, 19) == 2  # never fewer than two demonstrations
    assert subset_size(0.5, 38) == 19 and subset_size(0.5, 1) == 1
    assert subset_size(0.3, 10) == 3  # 0.3 * 10 is 3.0000000000000004 in floating point


@pytest.mark.parametrize("n", [36, 19, 208, 3])
def test_nested_subsets_are_nested_and_deterministic(n: int) -> None:
    for seed in range(5):
        subsets = nested_subsets(n, seed, FRACTIONS)
        assert list(subsets) == list(FRACTIONS)
        order = np.random.default_rng(seed).permutation(n)
        previous: set[int] = set()
        for f, chosen in subsets.items():
            assert chosen == sorted(chosen) and len(set(chosen)) == len(chosen)
            assert len(chosen) == subset_size(f, n)
            # the first entries of the seed's one permutation, so each lies in the next
            assert set(chosen) == {int(i) for i in order[: len(chosen)]}
            assert previous <= set(chosen)
            previous = set(chosen)
        assert subsets[1.0] == list(range(n))
        assert nested_subsets(n, seed, FRACTIONS) == subsets  # the same draw again
    if n > 3:  # another seed draws other subsets
        assert nested_subsets(n, 0, FRACTIONS)[0.25] != nested_subsets(n, 1, FRACTIONS)[0.25]


def test_fractions_are_checked() -> None:
    assert check_fractions([1, 0.25, 0.5]) == (0.25, 0.5, 1.0)
    assert parse_fractions(" 0.125, 1 ,0.5") == (0.125, 0.5, 1.0)
    for bad, match in (
        ([0.0], r"\(0, 1\]"),
        ([-0.5], r"\(0, 1\]"),
        ([1.5], r"\(0, 1\]"),
        ([math.nan], r"\(0, 1\]"),
        ([0.5, 0.5], "repeats 0.5"),
        ([], "at least one"),
        ([True], "numbers"),
    ):
        with pytest.raises(ConfigError, match=match):
            check_fractions(bad)
    with pytest.raises(ConfigError, match="comma-separated"):
        parse_fractions("0.5,half")
    with pytest.raises(ConfigError, match="comma-separated"):
        parse_fractions("")


def test_tasks_are_checked() -> None:
    assert [t.name for t in check_tasks(["approach", "turn"])] == ["turn", "approach"]
    with pytest.raises(ConfigError, match="needs its components: approach"):
        check_tasks(["turn", "turn-approach"])
    with pytest.raises(ConfigError, match="unknown task 'grab'"):
        check_tasks(["grab"])


def test_a_subset_keeps_the_corrective_copies_of_its_starts() -> None:
    starts = [{"distance": d} for d in (0.3, 0.5, 0.7)]
    data = collect("approach", starts, sim="kinematic", seed=0, corrections=1)
    assert len(data) == 6 and data.metadata["corrective_episodes"] == [3, 4, 5]
    part = grid_subset(data, [2, 0], 3)
    assert list(part.episode_ids) == [0, 2, 3, 5]
    assert part.metadata["corrective_episodes"] == [3, 5]
    assert [s["distance"] for s in part.metadata["starts"]] == [0.3, 0.7]
    assert np.array_equal(part.commands[: part.lengths[0]], data.commands[: data.lengths[0]])
    assert grid_subset(data, [0, 1, 2], 3) is data  # the whole grid is the dataset itself
    with pytest.raises(ConfigError, match="whole copies"):
        grid_subset(data, [0], 4)


# ------------------------------------------------------------------- a tiny run
# A few seconds of demonstrations per task, one test start each.
STARTS: dict[str, list[dict[str, float]]] = {
    "turn": [{"angle": float(a)} for a in range(-160, 181, 40)],
    "approach": [{"distance": d} for d in (0.2, 0.35, 0.5, 0.8)],
    "turn-approach": [
        {"angle": a, "distance": d} for a in (-120.0, 0.0, 120.0) for d in (0.3, 0.7)
    ],
}
TESTS: dict[str, list[dict[str, float]]] = {
    "turn": [{"angle": -100.0}],
    "approach": [{"distance": 0.6}],
    "turn-approach": [{"angle": 60.0, "distance": 0.5}],
}


@pytest.fixture(scope="module")
def tiny() -> dict[str, Any]:
    return run_data_efficiency_experiment(
        sim="kinematic",
        seed=3,
        seeds=2,
        fractions=(1.0, 0.25),
        bc=False,
        starts=STARTS,
        test_starts=TESTS,
        sblm_params={"epochs": 15},
        executor=SerialExecutor(),
    )


def test_every_cell_is_trained_on_its_nested_subset(tiny: dict[str, Any]) -> None:
    assert tiny["seeds"] == [3, 4] and tiny["fractions"] == [0.25, 1.0]
    assert list(tiny["tasks"]) == ["turn", "approach", "turn-approach"]
    assert tiny["tasks"]["turn-approach"]["components"] == ["turn", "approach"]
    assert [tiny["tasks"][t]["grid_size"] for t in tiny["tasks"]] == [9, 4, 6]
    cells = tiny["cells"]
    assert len(cells) == 3 * 2 * 2
    by_key = {(c["behavior"], c["fraction"], c["seed"]): c for c in cells}
    for task, grid in STARTS.items():
        for seed in (3, 4):
            small, whole = by_key[(task, 0.25, seed)], by_key[(task, 1.0, seed)]
            assert small["grid_indices"] == nested_subsets(len(grid), seed, (0.25,))[0.25]
            assert small["starts"] == [grid[i] for i in small["grid_indices"]]
            assert small["n_demonstrations"] == subset_size(0.25, len(grid)) == small["n_episodes"]
            assert set(small["grid_indices"]) < set(whole["grid_indices"])
            assert whole["grid_indices"] == list(range(len(grid)))
            assert small["n_rows"] < whole["n_rows"]
        # the whole grid is the same data for every seed
        assert by_key[(task, 1.0, 3)]["n_rows"] == by_key[(task, 1.0, 4)]["n_rows"]
    for cell in cells:
        ours = cell["ours"]
        assert set(cell) >= {"ours"} and "bc" not in cell
        assert ours["n"] == 1 and ours["goal_reached"] in (0, 1)
        assert 0.0 < ours["zero_floor"] < 100.0 and 0.0 <= ours["success_rate_mean"] <= 100.0
        assert ours["observations"] > 0 and ours["primitives"] > 0
    # turn & approach is composed of the SBLMs of the same fraction and seed
    for f in (0.25, 1.0):
        for seed in (3, 4):
            parts = by_key[("turn", f, seed)]["ours"]["primitives"]
            parts += by_key[("approach", f, seed)]["ours"]["primitives"]
            assert by_key[("turn-approach", f, seed)]["ours"]["primitives"] == parts


def test_the_summary_aggregates_the_cells(tiny: dict[str, Any]) -> None:
    rows = tiny["summary"]
    assert [(r["behavior"], r["fraction"]) for r in rows] == [
        (t, f) for t in ("turn", "approach", "turn-approach") for f in (0.25, 1.0)
    ]
    for row in rows:
        mine = [
            c
            for c in tiny["cells"]
            if (c["behavior"], c["fraction"]) == (row["behavior"], row["fraction"])
        ]
        values = [c["ours"]["success_rate_mean"] for c in mine]
        assert row["ours"]["success"]["values"] == values
        assert row["ours"]["success"]["mean"] == pytest.approx(np.mean(values))
        assert row["ours"]["success"]["sd"] == pytest.approx(np.std(values, ddof=1))
        assert row["ours"]["goals"]["mean"] == pytest.approx(
            np.mean([c["ours"]["goal_reached"] for c in mine])
        )
        assert row["n_demonstrations"] == mine[0]["n_demonstrations"]
        assert row["seeds"] == [3, 4] and "bc" not in row
    timings = tiny["timings"]
    assert timings["collect_s"] > 0 and len(timings["cells"]) == len(tiny["cells"])
    assert all(set(t) == {"behavior", "fraction", "seed", "ours"} for t in timings["cells"])


def test_the_results_do_not_depend_on_the_executor(tiny: dict[str, Any]) -> None:
    # turn alone, in two worker processes: the same cells as in the full run
    again = run_data_efficiency_experiment(
        executor=ProcessExecutor(2),
        sim="kinematic",
        seed=3,
        seeds=2,
        fractions=(0.25, 1.0),
        bc=False,
        tasks=["turn"],
        starts=STARTS,
        test_starts=TESTS,
        sblm_params={"epochs": 15},
    )
    turn = [c for c in tiny["cells"] if c["behavior"] == "turn"]
    assert again["cells"] == turn


def test_baselines_train_on_the_same_subset_with_the_same_seed(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    seen: list[tuple[tuple[str, ...], list[int], int, tuple[str, ...]]] = []

    def quick(inputs: Any, dataset: Any, seed: int, names: Any = tuple(BASELINES)) -> Any:
        seen.append((tuple(inputs), [int(i) for i in dataset.episode_ids], seed, tuple(names)))
        return {
            n: BASELINES[n](inputs=tuple(inputs), random_state=seed, epochs=2).fit(dataset)
            for n in names
        }

    monkeypatch.setattr(de, "fit_baselines", quick)
    results = run_data_efficiency_experiment(
        sim="kinematic",
        seed=1,
        seeds=1,
        fractions=(0.5,),
        tasks=["turn"],
        starts=STARTS,
        test_starts=TESTS,
        sblm_params={"epochs": 15},
    )
    (cell,) = results["cells"]
    chosen = cell["grid_indices"]
    assert seen == [(("angle",), chosen, 1, ("bc",)), (("angle",), chosen, 1, ("bc-strong",))]
    for learner in ("bc", "bc_strong"):
        assert cell[learner]["n"] == 1 and 0.0 <= cell[learner]["success_rate_mean"] <= 100.0
        assert results["summary"][0][learner]["success"]["values"] == [
            cell[learner]["success_rate_mean"]
        ]
    assert set(results["timings"]["cells"][0]) >= {"ours", "bc", "bc_strong"}


# ------------------------------------------------------------ aggregation by hand
def _cell(
    task: str, f: float, seed: int, n: int, ours: float, goals: int, bc: float
) -> dict[str, Any]:
    return {
        "behavior": task,
        "fraction": f,
        "seed": seed,
        "n_demonstrations": n,
        "n_episodes": n,
        "n_rows": 100 * n,
        "grid_indices": list(range(n)),
        "starts": [{"angle": float(i)} for i in range(n)],
        "ours": {
            "success_rate_mean": ours,
            "goal_reached": goals,
            "n": 15,
            "zero_floor": 40.0 + seed,
            "command_scale": 1.0 if f == 1.0 or seed == 0 else 0.5,
            "primitives": 3,
            "observations": 9,
        },
        "bc": {"success_rate_mean": bc, "goal_reached": 10, "n": 15},
        "bc_strong": {"success_rate_mean": bc + 1.0, "goal_reached": 12, "n": 15},
    }


def _hand_made() -> dict[str, Any]:
    cells = [
        _cell("turn", 0.125, 0, 5, 90.0, 15, 70.0),
        _cell("turn", 0.125, 1, 5, 80.0, 13, 60.0),
        _cell("turn", 1.0, 0, 36, 97.0, 15, 95.0),
        _cell("turn", 1.0, 1, 36, 99.0, 15, 95.0),
    ]
    return {
        "sim": "kinematic",
        "seeds": [0, 1],
        "fractions": [0.125, 1.0],
        "bc": True,
        "tasks": {
            "turn": {
                "behavior": "turn",
                "inputs": ["angle"],
                "components": [],
                "thesis": 90.9,
                "grid_size": 36,
                "episodes_per_start": 1,
                "command_scale": 1.0,
            }
        },
        "cells": cells,
        "summary": summarize(cells),
        "timings": {
            "collect_s": 1.0,
            "cells": [
                {
                    "behavior": "turn",
                    "fraction": c["fraction"],
                    "seed": c["seed"],
                    "ours": t,
                    "bc": 2.0,
                    "bc_strong": 3.0,
                }
                for c, t in zip(cells, (1.0, 3.0, 10.0, 20.0), strict=True)
            ],
        },
        "preset": "default",
    }


def test_aggregation_by_hand() -> None:
    rows = _hand_made()["summary"]
    assert [(r["behavior"], r["fraction"], r["n_demonstrations"]) for r in rows] == [
        ("turn", 0.125, 5),
        ("turn", 1.0, 36),
    ]
    small = rows[0]
    assert small["ours"]["success"]["mean"] == pytest.approx(85.0)
    assert small["ours"]["success"]["sd"] == pytest.approx(math.sqrt(50.0))  # (90, 80)
    # Student's t, one degree of freedom: 12.706 · sd / sqrt(2)
    assert small["ours"]["success"]["ci95"] == pytest.approx(12.7062 * 5.0, rel=1e-4)
    assert small["ours"]["goals"]["mean"] == pytest.approx(14.0)
    assert small["bc"]["success"]["mean"] == pytest.approx(65.0)
    assert small["bc_strong"]["success"]["mean"] == pytest.approx(66.0)
    assert small["bc_strong"]["goals"]["sd"] == 0.0
    assert small["zero_floor"] == pytest.approx(40.5) and small["seeds"] == [0, 1]
    one = summarize([_cell("turn", 0.5, 7, 18, 88.0, 14, 50.0)])[0]
    assert one["ours"]["success"]["sd"] == 0.0 and one["ours"]["success"]["ci95"] == 0.0
    with pytest.raises(ConfigError, match="different sizes"):
        summarize(
            [_cell("turn", 0.5, 0, 18, 88.0, 14, 50.0), _cell("turn", 0.5, 1, 17, 88.0, 14, 50.0)]
        )


def test_the_report(tmp_path: Path) -> None:
    results = _hand_made()
    table = write_data_efficiency_report(results, tmp_path)
    assert (tmp_path / FIGURE_NAME).read_bytes().startswith(PNG)
    assert (tmp_path / "table.md").read_text() == table
    saved = json.loads((tmp_path / "results.json").read_text())
    assert "timings" not in saved and saved["summary"][0]["ours"]["success"]["mean"] == 85.0
    assert json.loads((tmp_path / "timings.json").read_text())["collect_s"] == 1.0
    assert "| turn | 1/8 | 5 of 36 | 85.0 ± 7.1 (14.0/15) | 65.0 ± 7.1 (10.0/15) " in table
    assert "| 66.0 ± 7.1 (12.0/15) | 40.5 | 2.0 / 2.0 / 3.0 |" in table
    assert "| turn | all | 36 of 36 | 98.0 ± 1.4 (15.0/15) |" in table
    assert "turn {angle} 90.9 %" in table
    # the one cell scored on half the grid's command scale is named
    note = table.strip().splitlines()[-1]
    assert note.endswith(": turn 1/8 seed 1 (0.50 of 1.00)."), note


def test_one_fraction_still_draws_its_floor() -> None:
    """A run of one fraction (``--fractions 0.25``) draws the all-zero floor as a visible
    line across its one point, not a zero-length one."""
    results = _hand_made()
    results["cells"] = [c for c in results["cells"] if c["fraction"] == 0.125]
    results["summary"] = summarize(results["cells"])
    results["fractions"] = [0.125]
    fig = plot_data_efficiency(results)
    (line,) = [ln for ln in fig.axes[0].get_lines() if ln.get_label() == "all-zero floor"]
    xs = np.asarray(line.get_xdata(), dtype=float)
    assert xs.max() > xs.min()  # a segment, not a point
    assert np.allclose(np.asarray(line.get_ydata(), dtype=float), 40.5)


def test_a_long_preset_title_stays_inside_the_figure() -> None:
    results = _hand_made()
    results["preset"] = (
        "default + hidden=10, generator_init='shared', mirror=True, start_envelope=True; "
        "default + mirror=True"
    )
    fig = plot_data_efficiency(results)
    title = fig._suptitle
    assert title is not None and "\n" in title.get_text()
    fig.canvas.draw()
    box = title.get_window_extent()
    width = fig.get_figwidth() * fig.dpi
    assert box.x0 >= 0.0 and box.x1 <= width


def test_fraction_text() -> None:
    assert [fraction_text(f) for f in (0.125, 0.25, 0.5, 1.0, 0.3)] == [
        "1/8",
        "1/4",
        "1/2",
        "all",
        "0.3",
    ]
