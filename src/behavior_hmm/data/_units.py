"""Unit conversion for imported logs, and angle wrapping into (−180, 180]."""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from behavior_hmm.data._channels import CHANNELS
from behavior_hmm.errors import ConfigError

#: For each column, the units ``import_csv`` accepts and the factor that converts
#: a value in that unit into the column's canonical unit (``UNITS``).
UNIT_FACTORS: Final[dict[str, dict[str, float]]] = {
    "t": {"s": 1.0, "ms": 1e-3},
    **{name: dict(spec.units) for name, spec in CHANNELS.items()},
}


def unit_factor(column: str, unit: str) -> float:
    """Factor converting ``column`` values given in ``unit`` into the canonical unit.

    Raises
    ------
    ConfigError
        If the column has no units or the unit is not one it accepts.
    """
    if column not in UNIT_FACTORS:
        known = ", ".join(UNIT_FACTORS)
        raise ConfigError(f"column '{column}' takes no unit (columns with units: {known})")
    factors = UNIT_FACTORS[column]
    if unit not in factors:
        raise ConfigError(
            f"unknown unit '{unit}' for column '{column}' (choose one of: {', '.join(factors)})"
        )
    return factors[unit]


def wrap_degrees(angle: ArrayLike) -> NDArray[np.float64]:
    """Wrap angles (degrees) into (−180, 180]; 180 stays 180, −180 becomes 180."""
    a = np.asarray(angle, dtype=np.float64)
    return a - 360.0 * np.ceil((a - 180.0) / 360.0)


#: An imported angle beyond this (deg) is refused rather than wrapped: 100 turns means the
#: log is in other units (radians read as degrees are fine; milliradians or 1e5 are not).
MAX_UNWRAPPED_ANGLE = 36000.0


def wrap_imported_angles(angle: NDArray[np.float64]) -> tuple[NDArray[np.float64], int | None]:
    """Imported angles (deg) wrapped into (−180, 180], and the first absurd row, if any.

    Wrapping would hide absurd values, so the row of the first one beyond
    ``MAX_UNWRAPPED_ANGLE`` is returned for the importer to refuse (``None``: all fine).
    Non-finite values are left as they are for the validator to name.
    """
    with np.errstate(invalid="ignore"):
        huge = np.abs(angle) > MAX_UNWRAPPED_ANGLE
        wrapped = np.where(np.isfinite(angle), wrap_degrees(angle), angle)
    return wrapped, (int(np.argmax(huge)) if huge.any() else None)


def wrap_degree(angle: float) -> float:
    """Scalar twin of :func:`wrap_degrees` with bit-identical results (NaN stays NaN)."""
    turns = (angle - 180.0) / 360.0
    if not math.isfinite(turns):
        return math.nan
    return angle - 360.0 * math.ceil(turns)
