"""Fixtures of the Behavior-HMM tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from behavior_hmm.hmm._viterbi import set_kernel, viterbi_kernel


@pytest.fixture(scope="module", params=["numpy", "numba"])
def kernel(request: pytest.FixtureRequest) -> Iterator[str]:
    """Run a test once per Viterbi kernel: numpy, and numba where it is installed.

    Module-scoped (Hypothesis refuses function-scoped fixtures), so a module's tests run
    with one kernel, then with the other. Use it with
    ``pytestmark = pytest.mark.usefixtures("kernel")``.
    """
    name = str(request.param)
    if name == "numba":
        pytest.importorskip("numba", reason="numba is not installed (the 'fast' extra)")
    previous = set_kernel("numba" if name == "numba" else "numpy")
    assert viterbi_kernel() == name  # never the same kernel twice under two names
    yield name
    set_kernel(previous)
