"""What the compiled kernels of the ``fast`` extra share: loading numba, and the switch
between a compiled kernel and its numpy path.

numba is optional (``pip install 'behavior-hmm[fast]'``) and imported on first use only,
never when ``behavior_hmm`` is imported. Every kernel forms the same floating-point
operations in the same order as its numpy path, so the switch changes speed, never
results.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any, Generic, Literal, TypeVar

K = TypeVar("K")
KernelSetting = Literal["auto", "numba", "numpy"]


def compile_kernels(build: Callable[[Any, bool], K]) -> K | None:
    """``build(numba, cache)``, or ``None`` when numba cannot be imported.

    The machine code is cached next to the source (``cache=True``); a read-only install,
    where numba finds no writable cache folder, compiles without the cache.
    """
    try:
        numba = importlib.import_module("numba")
    except ImportError:
        return None
    try:
        return build(numba, True)
    except RuntimeError:  # numba found no writable cache folder (a read-only install)
        return build(numba, False)


class KernelSwitch(Generic[K]):
    """Which path a family of kernels runs in this process.

    Parameters
    ----------
    what
        The kernels' name in messages (``"Viterbi"``, ``"CobART"``).
    kernels
        Returns the compiled kernels, or ``None`` without numba (cached by the caller).
    """

    def __init__(self, what: str, kernels: Callable[[], K | None]) -> None:
        self.what = what
        self.kernels = kernels
        self.setting: KernelSetting = "auto"

    def set(self, setting: KernelSetting) -> KernelSetting:
        """Choose the path; return the old setting.

        ``"auto"`` (the default): the compiled kernels when numba is installed, the
        numpy path otherwise; ``"numba"``: the kernels (ImportError without numba);
        ``"numpy"``: the numpy path even when numba is installed (for tests and
        benchmarks: the results are identical, only the speed differs).
        """
        if setting not in ("auto", "numba", "numpy"):
            raise ValueError(f"unknown {self.what} kernel {setting!r}: 'auto', 'numba' or 'numpy'")
        if setting == "numba" and self.kernels() is None:
            raise ImportError(
                f"the numba {self.what} kernel needs numba: pip install 'behavior-hmm[fast]'"
            )
        previous = self.setting
        self.setting = setting
        return previous

    def active(self) -> K | None:
        """The compiled kernels when the setting and the installation allow them."""
        return None if self.setting == "numpy" else self.kernels()

    def name(self) -> Literal["numba", "numpy"]:
        """The path that runs now."""
        return "numpy" if self.active() is None else "numba"
