"""numba (the ``fast`` extra) is imported on first use of a compiled kernel, never on import."""

from __future__ import annotations

import subprocess
import sys

import pytest


@pytest.mark.parametrize(
    "modules",
    [
        "behavior_hmm, behavior_hmm.hmm, behavior_hmm.hmm._viterbi",  # the Viterbi kernels
        "behavior_hmm.cobart, behavior_hmm.cobart._compiled, behavior_hmm.models",  # CobART's
    ],
)
def test_importing_does_not_import_numba(modules: str) -> None:
    """numba costs ~0.3 s to import: only the first decoding or fit that runs a kernel
    imports it."""
    code = f"import sys, {modules}; assert 'numba' not in sys.modules, 'numba imported'"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
