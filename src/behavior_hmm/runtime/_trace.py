"""The record of one closed-loop generation."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data import SENSOR_CHANNELS


@dataclass
class Trace:
    """Every control step of a generation, plus its outcome.

    Attributes
    ----------
    t : (n,) seconds since the start
    readings : (n, 4) sensor readings as received (physical units, ``SENSOR_CHANNELS``
        order; a non-finite reading stays as it came, see ``held``)
    true_readings : (n, 4) noise-free readings from the simulator
    observation : (n,) observation category at each step
    novel : (n,) whether the observation was below vigilance
    state : (n,) active motion primitive (SBLM) or component index (CBLM)
    component : (n,) name of the active component ("" for an SBLM's own steps)
    commands : (n, 2) wheel commands sent (rad/s)
    plan_changed : (n,) True where the plan's first state changed
    held : (n,) channels whose non-finite reading was replaced by their last good
        value at each step (the sensor-fault policy; 0 almost always)
    goal : the goal (physical units)
    goal_reached : whether the final true state lies within tolerance of the goal
        (never after a sensor fault)
    reason : ``"goal"``, ``"step_limit"`` or ``"sensor_fault"`` (a read channel stayed
        non-finite longer than the hold; the last step then records the stop)
    fault_channels : the channels whose fault ended the run (empty otherwise)
    final_observation : (4,) noise-free readings after the final stop command
    """

    t: list[float] = field(default_factory=list)
    readings: list[NDArray[np.float64]] = field(default_factory=list)
    true_readings: list[NDArray[np.float64]] = field(default_factory=list)
    observation: list[int] = field(default_factory=list)
    novel: list[bool] = field(default_factory=list)
    state: list[int] = field(default_factory=list)
    component: list[str] = field(default_factory=list)
    commands: list[NDArray[np.float64]] = field(default_factory=list)
    plan_changed: list[bool] = field(default_factory=list)
    held: list[int] = field(default_factory=list)
    goal: dict[str, float] = field(default_factory=dict)
    start: dict[str, float] = field(default_factory=dict)
    goal_reached: bool = False
    reason: str = ""
    fault_channels: list[str] = field(default_factory=list)
    final_observation: NDArray[np.float64] | None = None

    def __len__(self) -> int:
        return len(self.t)

    @property
    def command_array(self) -> NDArray[np.float64]:
        """Commands as an (n, 2) array (rad/s)."""
        return np.asarray(self.commands, dtype=np.float64).reshape(-1, 2)

    @property
    def reading_array(self) -> NDArray[np.float64]:
        """Readings as an (n, 4) array."""
        return np.asarray(self.readings, dtype=np.float64).reshape(-1, len(SENSOR_CHANNELS))

    @property
    def n_plan_changes(self) -> int:
        """Number of steps where the active state changed."""
        return int(np.sum(self.plan_changed))

    @property
    def held_readings(self) -> int:
        """Readings (step x channel) replaced by their channel's last good value."""
        return int(sum(self.held))

    def final_errors(self) -> dict[str, float]:
        """Final angle error (deg) and distance error (m) against the goal, noise-free."""
        final = self.final_observation
        out: dict[str, float] = {}
        if final is None:
            return out
        for name, target in self.goal.items():
            value = float(final[SENSOR_CHANNELS.index(name)])
            err = value - target
            if name == "angle":
                err = (err + 180.0) % 360.0 - 180.0
            out[name] = float(abs(err))
        return out

    def to_columns(self) -> dict[str, Any]:
        """Column arrays (for Parquet or pandas)."""
        readings = self.reading_array
        true = np.asarray(self.true_readings, dtype=np.float64).reshape(-1, len(SENSOR_CHANNELS))
        cmds = self.command_array
        cols: dict[str, Any] = {"t": np.asarray(self.t, dtype=np.float64)}
        for j, name in enumerate(SENSOR_CHANNELS):
            cols[name] = readings[:, j]
        for j, name in enumerate(SENSOR_CHANNELS):
            cols[f"true_{name}"] = true[:, j]
        cols["left"] = cmds[:, 0]
        cols["right"] = cmds[:, 1]
        cols["observation"] = np.asarray(self.observation, dtype=np.int64)
        cols["novel"] = np.asarray(self.novel, dtype=bool)
        cols["state"] = np.asarray(self.state, dtype=np.int64)
        cols["component"] = np.asarray(self.component, dtype=object)
        cols["plan_changed"] = np.asarray(self.plan_changed, dtype=bool)
        # a trace recorded without the hold (built by hand) held nothing
        cols["held"] = np.asarray(self.held or [0] * len(self.t), dtype=np.int64)
        return cols

    def summary(self) -> dict[str, Any]:
        """Outcome in a JSON-ready dict."""
        return {
            "steps": len(self),
            "duration_s": float(self.t[-1]) if self.t else 0.0,
            "goal": self.goal,
            "start": self.start,
            "goal_reached": self.goal_reached,
            "reason": self.reason,
            "final_errors": self.final_errors(),
            "plan_changes": self.n_plan_changes,
            "held_readings": self.held_readings,
            "fault_channels": list(self.fault_channels),
        }

    def write(self, path: str | os.PathLike[str]) -> None:
        """Write the trace as Parquet (atomic), the summary in the schema metadata."""
        import json

        import pyarrow as pa
        import pyarrow.parquet as pq

        from behavior_hmm._atomic import atomic_write_with

        cols = self.to_columns()
        table = pa.table(
            {k: pa.array(list(v) if v.dtype == object else v) for k, v in cols.items()}
        )
        meta = {b"behavior_hmm_trace": json.dumps(self.summary(), default=float).encode()}
        table = table.replace_schema_metadata(meta)
        atomic_write_with(path, lambda tmp: pq.write_table(table, tmp))
