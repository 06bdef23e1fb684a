"""Shared helpers for the benchmarks."""

from __future__ import annotations

from functools import lru_cache
from typing import Any


@lru_cache(maxsize=4)
def default_dataset(behavior: str, sim: str = "mujoco") -> Any:
    """The behavior's default training dataset (DESIGN §6 grid), collected once per process."""
    from behavior_hmm.teach import collect

    return collect(behavior, sim=sim, seed=0)
