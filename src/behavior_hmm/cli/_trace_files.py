"""Trace files (``generate -o``) read back: as a :class:`~behavior_hmm.runtime.Trace`
(``inspect``) or as a one-episode dataset of readings and commands (``export-lerobot``).

``Trace.write`` stores one row per control step and the run's summary as JSON under the
schema metadata key :data:`TRACE_KEY`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from behavior_hmm.errors import DatasetError

#: Schema metadata key of a trace file (``Trace.write``).
TRACE_KEY = b"behavior_hmm_trace"


def is_trace_file(path: Path) -> bool:
    """True if ``path`` is a Parquet file whose schema carries a trace summary."""
    import pyarrow.parquet as pq

    if not path.is_file():
        return False
    try:
        return TRACE_KEY in (pq.read_schema(path).metadata or {})
    except Exception:  # not Parquet: whoever reads it next says what is wrong
        return False


def _load(path: Path) -> tuple[Any, dict[str, Any]]:
    """The trace's table and its summary (:class:`DatasetError` if either is broken)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(path)
    except (pa.ArrowException, ValueError) as err:
        raise DatasetError(f"unreadable trace ({err})", file=str(path)) from None
    try:
        summary = json.loads((table.schema.metadata or {}).get(TRACE_KEY, b"{}"))
    except ValueError:
        summary = None
    if not isinstance(summary, dict):
        raise DatasetError("trace summary is not a JSON object", file=str(path))
    return table, summary


def _numbers(table: Any, name: str, path: Path) -> np.ndarray:
    try:
        return np.asarray(table.column(name).to_numpy(zero_copy_only=False), dtype=np.float64)
    except (TypeError, ValueError):
        raise DatasetError("not numbers", file=str(path), field=name) from None


def _values(mapping: Any, what: str, path: Path) -> dict[str, float]:
    """A summary's ``goal`` / ``start``: channel -> number."""
    if mapping is None:
        return {}
    try:
        return {str(k): float(v) for k, v in dict(mapping).items()}
    except (TypeError, ValueError):
        raise DatasetError(
            f"trace summary: '{what}' is not CHANNEL: NUMBER", file=str(path)
        ) from None


def read_trace(path: Path) -> tuple[Any, dict[str, Any]]:
    """The trace in ``path`` as a :class:`~behavior_hmm.runtime.Trace`, and its summary.

    The channels are the columns that have a ``true_<channel>`` beside them; ``x``, ``y``,
    ``yaw`` become the poses when all three are there. The final observation is not in
    the file: the summary holds the final errors.
    """
    from behavior_hmm.runtime import Trace

    table, summary = _load(path)
    names = list(table.column_names)
    channels = [n for n in names if not n.startswith("true_") and f"true_{n}" in names]
    commands = summary.get("command_channels") or ["left", "right"]
    if not isinstance(commands, list) or not all(
        isinstance(c, str) and 0 < len(c) <= 64 for c in commands
    ):
        raise DatasetError("trace summary: command_channels must be column names", file=str(path))
    missing = [c for c in ("t", *commands) if c not in names]
    if missing or not channels:
        missing += [] if channels else ["<channel> and true_<channel>"]
        raise DatasetError(f"trace without column(s) {', '.join(missing)}", file=str(path))
    trace = Trace(channels=channels, command_channels=list(commands))
    trace.t = _numbers(table, "t", path).tolist()
    readings = np.column_stack([_numbers(table, c, path) for c in channels])
    true = np.column_stack([_numbers(table, f"true_{c}", path) for c in channels])
    trace.readings, trace.true_readings = list(readings), list(true)
    trace.commands = list(np.column_stack([_numbers(table, c, path) for c in commands]))
    if all(c in names for c in ("x", "y", "yaw")):
        trace.pose = list(np.column_stack([_numbers(table, c, path) for c in ("x", "y", "yaw")]))
    for name, kind in (("observation", int), ("state", int), ("held", int)):
        if name in names:
            setattr(trace, name, [kind(v) for v in _numbers(table, name, path)])
    for name in ("novel", "plan_changed"):
        if name in names:
            setattr(trace, name, [bool(v) for v in _numbers(table, name, path)])
    if "component" in names:
        trace.component = [str(v) for v in table.column("component").to_pylist()]
    trace.goal = _values(summary.get("goal"), "goal", path)
    trace.start = _values(summary.get("start"), "start", path)
    trace.goal_reached = bool(summary.get("goal_reached", False))
    trace.reason = str(summary.get("reason", ""))
    trace.fault_channels = [str(c) for c in summary.get("fault_channels") or []]
    summary = {**summary, "steps": len(trace), "channels": channels}
    summary.setdefault("duration_s", float(trace.t[-1]) if trace.t else 0.0)
    return trace, summary


def trace_dataset(path: Path) -> Any:
    """A trace file (``generate -o``) as a one-episode dataset: readings and commands."""
    from behavior_hmm.data import COMMAND_CHANNELS, SENSOR_CHANNELS, Dataset

    table, summary = _load(path)
    needed = ["t", *SENSOR_CHANNELS, *COMMAND_CHANNELS]
    missing = [c for c in needed if c not in table.column_names]
    if missing:
        raise DatasetError(f"trace without column(s) {', '.join(missing)}", file=str(path))
    columns = {c: table.column(c).to_numpy() for c in needed}
    columns["episode"] = np.zeros(table.num_rows, dtype=np.int64)
    try:
        return Dataset(columns, {"trace": summary, "source": {"trace": path.name}})
    except DatasetError as err:
        raise DatasetError(
            err.reason, file=str(path), episode=None, row=err.row, field=err.field
        ) from None
