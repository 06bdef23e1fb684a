"""One executor for batch work: the same results whatever runs the tasks."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from behavior_hmm.errors import ConfigError, DatasetError
from behavior_hmm.evaluate._executor import (
    ProcessExecutor,
    SerialExecutor,
    check_workers,
    default_workers,
    make_executor,
    map_largest_first,
)
from behavior_hmm.evaluate._experiments import SIMPLE_CONFIGS, over_seeds, run_simple_experiment
from behavior_hmm.viz._reports import write_results_files


def square(x: int) -> int:
    return x * x


def bad_row(x: int) -> int:
    raise DatasetError("NaN value", file="f.csv", episode=x, row=7, field="angle")


def test_executors_keep_task_order_and_report_progress() -> None:
    seen: list[tuple[int, int]] = []
    tasks = list(range(7))
    for executor in (SerialExecutor(), ProcessExecutor(2)):
        seen.clear()
        out = executor.map(square, tasks, lambda d, t: seen.append((d, t)))
        assert out == [x * x for x in tasks]
        assert [d for d, _ in seen] == list(range(1, 8)) and {t for _, t in seen} == {7}


def test_largest_tasks_go_first_and_results_keep_task_order() -> None:
    ran: list[int] = []

    def record(x: int) -> int:
        ran.append(x)
        return x * x

    tasks = [5, 1, 9, 3, 7]
    sizes = [2.0, 1.0, 5.0, 1.0, 3.0]  # the two of size 1 keep their order
    out = map_largest_first(SerialExecutor(), record, tasks, sizes)
    assert ran == [9, 7, 5, 1, 3]
    assert out == [x * x for x in tasks]
    # in processes too: the results do not depend on the order the tasks ran in
    assert map_largest_first(ProcessExecutor(2), square, tasks, sizes) == out
    assert map_largest_first(SerialExecutor(), square, [], []) == []


def test_bad_executor_options_are_refused() -> None:
    with pytest.raises(ConfigError, match="unknown executor 'dask'"):
        make_executor("dask")
    with pytest.raises(ConfigError, match="--workers"):
        check_workers(0)
    with pytest.raises(ConfigError, match="--address is for --executor ray"):
        make_executor("local", address="10.0.0.1:6379")


def test_an_error_in_a_worker_comes_back_whole() -> None:
    # user errors carry where they happened (file, episode, row, field) across processes
    with pytest.raises(DatasetError) as caught:
        ProcessExecutor(2).map(bad_row, [3, 4])
    err = caught.value
    assert str(err).endswith("row 7, field 'angle': NaN value") and err.file == "f.csv"
    assert (err.row, err.field, err.reason) == (7, "angle", "NaN value")


def test_workers_default_comes_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BEHAVIOR_HMM_WORKERS", "3")
    assert default_workers() == 3 and ProcessExecutor().workers == 3
    monkeypatch.delenv("BEHAVIOR_HMM_WORKERS")
    assert default_workers() >= 1
    for bad in ("0", "two", "2000"):
        monkeypatch.setenv("BEHAVIOR_HMM_WORKERS", bad)
        with pytest.raises(ConfigError, match="BEHAVIOR_HMM_WORKERS must be an integer"):
            default_workers()


def test_over_seeds_mean_and_interval() -> None:
    rows = [[{"a": 90.0}], [{"a": 92.0}], [{"a": 94.0}]]
    (summary,) = over_seeds(rows, ("a",))
    assert summary["a"]["mean"] == pytest.approx(92.0)
    # t(0.975, 2) = 4.303; sd = 2; interval = 4.303 * 2 / sqrt(3)
    assert summary["a"]["ci95"] == pytest.approx(4.3027 * 2 / 3**0.5, rel=1e-3)
    assert summary["a"]["values"] == [90.0, 92.0, 94.0]


def _results_json(results: dict, folder: Path) -> bytes:
    results = dict(results)
    results.pop("figures", None)  # arrays: drawn, compared through the rows and cases
    write_results_files(folder, results, "")
    return (folder / "results.json").read_bytes()


@pytest.mark.slow
def test_process_workers_give_byte_identical_results(tmp_path: Path) -> None:
    configs = SIMPLE_CONFIGS[:1]
    serial = run_simple_experiment(sim="kinematic", configs=configs, executor=SerialExecutor())
    parallel = run_simple_experiment(sim="kinematic", configs=configs, executor=ProcessExecutor(2))
    assert _results_json(serial, tmp_path / "a") == _results_json(parallel, tmp_path / "b")
    assert (tmp_path / "a" / "timings.json").exists()


@pytest.mark.slow
def test_seeds_report_each_seed_and_the_interval() -> None:
    result = run_simple_experiment(
        sim="kinematic", configs=SIMPLE_CONFIGS[:1], seeds=2, executor=ProcessExecutor(2)
    )
    assert result["seeds"] == [0, 1]
    (row,) = result["over_seeds"]
    values = [rows[0]["sblm"] for rows in result["per_seed_rows"]]
    assert row["sblm"]["values"] == values and values[0] == result["rows"][0]["sblm"]


@pytest.mark.slow
def test_ray_gives_byte_identical_results(tmp_path: Path) -> None:
    ray = pytest.importorskip("ray")
    configs = SIMPLE_CONFIGS[:1]
    local = run_simple_experiment(sim="kinematic", configs=configs, executor=SerialExecutor())
    try:
        on_ray = run_simple_experiment(
            sim="kinematic", configs=configs, executor=make_executor("ray", workers=2)
        )
    finally:
        ray.shutdown()
    assert json.loads(_results_json(local, tmp_path / "a")) == json.loads(
        _results_json(on_ray, tmp_path / "b")
    )
    assert _results_json(local, tmp_path / "a") == _results_json(on_ray, tmp_path / "b")
