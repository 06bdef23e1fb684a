"""evaluate and the sweeps through the executor: the same bytes whoever runs the tasks."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from behavior_hmm.cli import app
from behavior_hmm.data import Dataset
from behavior_hmm.evaluate import BehaviorCloning, evaluate_model
from behavior_hmm.evaluate._executor import ProcessExecutor, SerialExecutor
from behavior_hmm.evaluate._faults import run_faults
from behavior_hmm.evaluate._generator_sweeps import run_generator_sweeps
from behavior_hmm.models import SBLM, load
from behavior_hmm.sim import make_env

#: Distinct starts, so a case put in the wrong place changes the bytes.
STARTS = [{"angle": 55.0}, {"angle": -35.0}, {"angle": 125.0}]
PUSH = {"at": 0.5, "angle": 20.0}


def _bytes(result: dict[str, Any]) -> str:
    """The evaluation JSON, traces left out (compared on their own)."""
    return json.dumps({k: v for k, v in result.items() if k != "_traces"}, sort_keys=True)


class _Refusing:
    """An executor that must not be asked: the work stays in this process."""

    workers = 2

    def map(self, fn: Callable[[Any], Any], tasks: Sequence[Any], progress: Any = None) -> Any:
        raise AssertionError("the executor was asked to run the cases")


@pytest.fixture(scope="module")
def bc(turn_data: Dataset) -> BehaviorCloning:
    return BehaviorCloning(inputs=("angle",), epochs=40).fit(turn_data)


def test_cases_in_processes_equal_the_serial_evaluation(
    turn_model: SBLM, bc: BehaviorCloning
) -> None:
    options: dict[str, Any] = {"sim": "kinematic", "seed": 3, "baselines": {"bc": bc}}
    options.update(push=PUSH, keep_traces=True)
    serial = evaluate_model(turn_model, STARTS, **options)
    seen: list[tuple[int, int]] = []
    parallel = evaluate_model(
        turn_model,
        STARTS,
        executor=ProcessExecutor(2),
        progress=lambda d, t: seen.append((d, t)),
        **options,
    )
    assert serial["pushed"] == 3 and len(serial["baselines"]["bc"]["cases"]) == 3
    assert _bytes(parallel) == _bytes(serial)
    # the traces came back too, each with its reference demonstration, in case order
    for name in ("model", "bc"):
        ours, theirs = parallel["_traces"][name], serial["_traces"][name]
        assert [t.start for t, _ in ours] == [t.start for t, _ in theirs]
        for (a, ref_a), (b, ref_b) in zip(ours, theirs, strict=True):
            np.testing.assert_array_equal(a.command_array, b.command_array)
            np.testing.assert_array_equal(ref_a["left"], ref_b["left"])
    # progress in steps of one case (its two runners), up to every run
    assert seen[-1] == (6, 6) and all(d % 2 == 0 for d, _ in seen)


def test_a_serial_executor_gives_the_default_result(turn_model: SBLM) -> None:
    plain = evaluate_model(turn_model, STARTS[:2], sim="kinematic", seed=1, noise=0.01)
    tasks = evaluate_model(
        turn_model, STARTS[:2], sim="kinematic", seed=1, noise=0.01, executor=SerialExecutor()
    )
    assert _bytes(tasks) == _bytes(plain)


def test_an_env_or_case_hook_keeps_the_cases_in_this_process(turn_model: SBLM) -> None:
    env = make_env("kinematic")
    with_env = evaluate_model(
        turn_model, STARTS[:1], sim="kinematic", env=env, executor=_Refusing()
    )
    hooked = evaluate_model(
        turn_model,
        STARTS[:1],
        sim="kinematic",
        case_options=lambda i, start, reference: {},
        executor=_Refusing(),
    )
    assert _bytes(with_env) == _bytes(hooked)
    with pytest.raises(AssertionError, match="asked"):
        evaluate_model(turn_model, STARTS[:1], sim="kinematic", executor=_Refusing())


def test_cli_evaluate_in_two_workers_writes_the_same_json(turn_model: SBLM, tmp_path: Path) -> None:
    model = tmp_path / "turn.bhmm"
    turn_model.save(model)
    starts = tmp_path / "starts.csv"
    starts.write_text("angle\n" + "\n".join(str(s["angle"]) for s in STARTS) + "\n")
    written = []
    for workers in (1, 2):
        out = tmp_path / f"w{workers}.json"
        args = ["evaluate", str(model), "--starts", str(starts), "--sim", "kinematic"]
        args += ["--push", "at=0.5,angle=20", "--workers", str(workers), "--json", str(out)]
        result = CliRunner().invoke(app, args)
        assert result.exit_code == 0, result.output
        written.append(out.read_bytes())
    assert json.loads(written[0])["pushed"] == 3
    assert written[0] == written[1]
    # and both are what the in-process evaluation gives
    serial = evaluate_model(load(model), STARTS, sim="kinematic", push=PUSH)
    assert json.loads(written[1]) == json.loads(json.dumps(serial, default=float))


@pytest.mark.parametrize(
    "command",
    [
        ["evaluate", "MODEL", "--sim", "kinematic"],
        ["experiment", "faults", "--sim", "kinematic"],
        ["experiment", "generators", "--sim", "kinematic"],
    ],
)
def test_commands_refuse_a_bad_worker_count(
    command: list[str], turn_model: SBLM, tmp_path: Path
) -> None:
    model = tmp_path / "turn.bhmm"
    turn_model.save(model)
    args = [str(model) if a == "MODEL" else a for a in command]
    if command[0] == "experiment":
        args += ["-o", str(tmp_path / "out")]
    result = CliRunner().invoke(app, [*args, "--workers", "0"])
    assert result.exit_code == 2, result.output
    assert result.stderr.strip() == "error: --workers must be an integer in [1, 1024], got 0"
    assert not (tmp_path / "out").exists()


def test_fault_sweep_in_processes_equals_the_serial_sweep() -> None:
    options: dict[str, Any] = {
        "sim": "kinematic",
        "tasks": ["turn"],
        "faults": ["noise", "push_bearing", "dropout"],
        "levels": {"noise": [0.02], "push_bearing": [0.5], "dropout": ["burst5"]},
        "n_starts": 2,
    }
    serial = run_faults(**options)
    seen: list[tuple[int, int]] = []
    parallel = run_faults(
        executor=ProcessExecutor(2), progress=lambda d, t: seen.append((d, t)), **options
    )
    (entry,) = serial["tasks"]
    assert [c["fault"] for c in entry["cells"]] == ["noise", "push_bearing", "dropout"]
    assert json.dumps(parallel, sort_keys=True) == json.dumps(serial, sort_keys=True)
    # one collection, one fit, the baseline and three cells
    assert seen[-1] == (6, 6)


def test_generator_sweeps_in_processes_equal_the_serial_sweeps(
    rng: np.random.Generator, tmp_path: Path
) -> None:
    x = rng.uniform(-1, 1, (150, 10))
    y = 0.5 * np.tanh(x[:, :2] - x[:, 8:])
    prim = np.where(np.arange(150) < 100, 2, 0)
    options: dict[str, Any] = {"epochs": 3, "X_two_inputs": np.hstack([x, x[:, ::-1]])}
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    serial = run_generator_sweeps(x, y, prim, tmp_path / "a", **options)
    seen: list[tuple[int, int]] = []
    parallel = run_generator_sweeps(
        x,
        y,
        prim,
        tmp_path / "b",
        executor=ProcessExecutor(2),
        progress=lambda d, t: seen.append((d, t)),
        **options,
    )
    for report in (serial, parallel):
        report.pop("summary_file")
    assert json.dumps(parallel, sort_keys=True) == json.dumps(serial, sort_keys=True)
    # stacks: 1x5 (learning rates and momenta), 1x10, 1x15, 2x5; two inputs: six layouts
    assert seen[-1] == (10, 10)
