"""``behavior-hmm bench hmm`` reports its keys, on tiny sizes (values are not checked: no
timings), with the numba kernel and with the numpy one."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

import pytest

import behavior_hmm.hmm._viterbi as impl
from behavior_hmm.benchmarks.hmm import run

HAS_HMMLEARN = importlib.util.find_spec("hmmlearn") is not None


def _run() -> dict[str, Any]:
    return run(quick=True, sizes=((6, 20),))


def _check_rows(results: dict[str, Any]) -> None:
    for row in results["sizes"] + results["sparse"]:
        assert row["ours_us_median"] > 0 and row["ours_kernel_us_median"] > 0
        assert (row["hmmlearn_us_median"] is not None) == HAS_HMMLEARN
        if HAS_HMMLEARN:
            assert isinstance(row["paths_agree"], bool)  # False only through ties
            assert row["log_prob_abs_diff"] == 0.0  # the same sums: the same bits


def test_bench_hmm_with_numba_times_the_numpy_path_too() -> None:
    pytest.importorskip("numba", reason="numba is not installed (the 'fast' extra)")
    results = _run()
    assert results["kernel"] == "numba" and results["jit_warmup_s"] >= 0
    assert results["kernels_agree"] is True
    _check_rows(results)
    for row in results["sizes"] + results["sparse"]:
        assert row["ours_numpy_us_median"] > 0 and row["ours_numpy_kernel_us_median"] > 0
        assert row["numpy_over_numba"] == row["ours_numpy_us_median"] / row["ours_us_median"]
        assert row["kernels_agree"] is True
    assert impl.viterbi_kernel() == "numba"  # the setting is restored after the run


def test_bench_hmm_on_the_numpy_kernel_reports_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(impl._switch, "setting", "numpy")
    results = _run()
    assert results["kernel"] == "numpy" and "jit_warmup_s" not in results
    _check_rows(results)
    for row in results["sizes"] + results["sparse"]:
        assert row["ours_numpy_us_median"] is None and "numpy_over_numba" not in row


def test_plot_reads_the_bench_hmm_json(tmp_path: Path) -> None:
    from behavior_hmm.benchmarks._plot import plot_hmm

    path = plot_hmm(_run(), tmp_path)
    assert path.stat().st_size > 0
