"""The record of one closed-loop generation."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from behavior_hmm.data._channels import COMMAND_CHANNELS, SENSOR_CHANNELS, ChannelSpec, channel


@dataclass
class Trace:
    """Every control step of a generation, plus its outcome.

    Attributes
    ----------
    t : (n,) seconds since the start
    channels : the sensor channels of ``readings``, in column order (the env's channels,
        the data contract's first; default ``SENSOR_CHANNELS``)
    readings : (n, C) sensor readings as received (physical units, ``channels`` order;
        a non-finite reading stays as it came, see ``held``)
    true_readings : (n, C) noise-free readings (the readings themselves when the env
        gives no ``info["true_observation"]``)
    pose : (n, 3) robot pose ``x`` (m), ``y`` (m), ``yaw`` (rad) at each step, when the
        env reports ``info["pose"]``; empty otherwise
    observation : (n,) observation category at each step
    novel : (n,) whether the observation was below vigilance
    state : (n,) active motion primitive (SBLM) or component index (CBLM)
    component : (n,) name of the active component ("" for an SBLM's own steps)
    commands : (n, k) commands sent, in ``command_channels`` order (wheels: rad/s)
    command_channels : the command channels (default ``left``, ``right``)
    plan_changed : (n,) True where the plan's first state changed
    held : (n,) channels whose non-finite reading was replaced by their last good
        value at each step (the sensor-fault policy; 0 almost always)
    goal : the goal (physical units)
    goal_reached : whether the final true state lies within tolerance of the goal
        (never after a sensor fault)
    reason : ``"goal"``, ``"step_limit"`` or ``"sensor_fault"`` (a read channel stayed
        non-finite longer than the hold; the last step then records the stop)
    fault_channels : the channels whose fault ended the run (empty otherwise)
    final_observation : (C,) noise-free readings after the final stop command
    final_pose : pose after the final stop command (or None)
    wheel_gains : (left, right) wheel gains estimated by the end of a run with
        ``wheel_calibration`` (measured wheel speed per unit of command); None without
    channel_specs : declarations of the channels the registry does not know
    """

    channels: list[str] = field(default_factory=lambda: list(SENSOR_CHANNELS))
    command_channels: list[str] = field(default_factory=lambda: list(COMMAND_CHANNELS))
    pose: list[NDArray[np.float64]] = field(default_factory=list)
    final_pose: NDArray[np.float64] | None = None
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
    wheel_gains: list[float] | None = None
    final_observation: NDArray[np.float64] | None = None
    #: declarations of the channels the registry does not know (the robot's sensors and
    #: commands, the model's own), for the goal's tolerance, an angle's wrap, plot units
    channel_specs: dict[str, ChannelSpec] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.t)

    @property
    def command_array(self) -> NDArray[np.float64]:
        """Commands as an (n, 2) array (rad/s)."""
        k = len(self.command_channels)
        return np.asarray(self.commands, dtype=np.float64).reshape(-1, k)

    @property
    def reading_array(self) -> NDArray[np.float64]:
        """Readings as an (n, C) array, columns in ``channels`` order."""
        return np.asarray(self.readings, dtype=np.float64).reshape(-1, len(self.channels))

    @property
    def pose_array(self) -> NDArray[np.float64]:
        """Poses as an (n, 3) array (x m, y m, yaw rad); (0, 3) without poses."""
        return np.asarray(self.pose, dtype=np.float64).reshape(-1, 3)

    def channel(self, name: str, *, true: bool = False) -> NDArray[np.float64]:
        """One channel's readings (or noise-free readings) as an (n,) array."""
        if name not in self.channels:
            raise KeyError(f"the trace has no channel {name!r} (channels: {self.channels})")
        rows = self.true_readings if true else self.readings
        data = np.asarray(rows, dtype=np.float64).reshape(-1, len(self.channels))
        return data[:, self.channels.index(name)]

    def final_value(self, name: str) -> float:
        """A channel's noise-free value after the final stop."""
        if self.final_observation is None:
            raise ValueError("the trace has no final observation")
        return float(self.final_observation[self.channels.index(name)])

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
            value = float(final[self.channels.index(name)])
            spec = self.channel_specs.get(name) or channel(name)
            out[name] = abs(spec.error(value, target))
        return out

    def to_columns(self) -> dict[str, Any]:
        """Column arrays (for Parquet or pandas)."""
        readings = self.reading_array
        true = np.asarray(self.true_readings, dtype=np.float64).reshape(-1, len(self.channels))
        cmds = self.command_array
        cols: dict[str, Any] = {"t": np.asarray(self.t, dtype=np.float64)}
        for j, name in enumerate(self.channels):
            cols[name] = readings[:, j]
        for j, name in enumerate(self.channels):
            cols[f"true_{name}"] = true[:, j]
        if len(self.pose) == len(self.t) and self.pose:
            poses = self.pose_array
            for j, name in enumerate(("x", "y", "yaw")):
                cols[name] = poses[:, j]
        for j, name in enumerate(self.command_channels):
            cols[name] = cmds[:, j]
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
            "command_channels": list(self.command_channels),
            **({} if self.wheel_gains is None else {"wheel_gains": list(self.wheel_gains)}),
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
