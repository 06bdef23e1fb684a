"""Write small ROS 1 / ROS 2 bags from demonstrations with rosbags' own writers."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from behavior_hmm.data import Dataset

#: Robot spec of the simulated robot (behavior_hmm.sim.RobotParams defaults).
WHEEL_RADIUS = 0.021
TRACK_WIDTH = 0.053

FLOAT_TOPICS = {
    "distance": "/object_distance",
    "linear_velocity": "/linear_velocity",
    "angle": "/object_bearing",
    "angular_velocity": "/yaw_rate",
    "left": "/wheel_left",
    "right": "/wheel_right",
}


def _writer(path: Path, ros: int) -> tuple[Any, Any, Any]:
    """A rosbags writer for ``path``, its typestore and its serializer."""
    from rosbags.typesys import Stores, get_typestore

    if ros == 1:
        from rosbags.rosbag1 import Writer as Writer1

        store = get_typestore(Stores.ROS1_NOETIC)
        return Writer1(path), store, store.serialize_ros1
    from rosbags.rosbag2 import Writer as Writer2

    store = get_typestore(Stores.ROS2_HUMBLE)
    return Writer2(path, version=8), store, store.serialize_cdr


def write_floats(path: Path, ros: int, topics: dict[str, list[tuple[int, float]]]) -> Path:
    """A bag of std_msgs/Float64 topics: ``{topic: [(stamp_ns, value), ...]}``."""
    writer, store, serialize = _writer(path, ros)
    f64 = store.types["std_msgs/msg/Float64"]
    with writer:
        conns = {
            topic: writer.add_connection(topic, "std_msgs/msg/Float64", typestore=store)
            for topic in topics
        }
        messages = sorted(
            (stamp, topic, value) for topic, items in topics.items() for stamp, value in items
        )
        for stamp, topic, value in messages:
            writer.write(conns[topic], stamp, serialize(f64(data=value), "std_msgs/msg/Float64"))
    return path


def write_bag(
    ds: Dataset,
    path: Path,
    *,
    ros: int,
    twist: bool = False,
    velocities: bool = True,
    gap_s: float = 1.0,
    counter: bool = False,
) -> Path:
    """One bag holding every episode of ``ds`` one after another, ``gap_s`` apart.

    Angles are published in radians, angular velocities in rad/s; wheel commands as two
    std_msgs/Float64 topics or (``twist``) one geometry_msgs/Twist on /cmd_vel. With
    ``counter`` an std_msgs/Int32 /episode counts the episodes.
    """
    writer, store, serialize = _writer(path, ros)
    f64 = store.types["std_msgs/msg/Float64"]
    i32 = store.types["std_msgs/msg/Int32"]
    twist_t = store.types["geometry_msgs/msg/Twist"]
    vec3 = store.types["geometry_msgs/msg/Vector3"]
    channels = [c for c in FLOAT_TOPICS if not (twist and c in ("left", "right"))]
    if not velocities:
        channels = [c for c in channels if c not in ("linear_velocity", "angular_velocity")]
    with writer:
        conns = {
            c: writer.add_connection(FLOAT_TOPICS[c], "std_msgs/msg/Float64", typestore=store)
            for c in channels
        }
        cmd = (
            writer.add_connection("/cmd_vel", "geometry_msgs/msg/Twist", typestore=store)
            if twist
            else None
        )
        count = (
            writer.add_connection("/episode", "std_msgs/msg/Int32", typestore=store)
            if counter
            else None
        )
        start = 1_700_000_000 * 10**9
        for k, ep in enumerate(ds.episodes()):
            stamps = start + np.round(ep.t * 1e9).astype(np.int64)
            if count is not None:
                writer.write(
                    count, int(stamps[0]) - 1, serialize(i32(data=k), "std_msgs/msg/Int32")
                )
            for i, stamp in enumerate(stamps.tolist()):
                for c in channels:
                    value = float(ep.channel(c)[i])
                    if c in ("angle", "angular_velocity"):
                        value = math.radians(value)
                    writer.write(
                        conns[c], stamp, serialize(f64(data=value), "std_msgs/msg/Float64")
                    )
                if cmd is not None:
                    left, right = (float(x) for x in ep.commands[i])
                    v = WHEEL_RADIUS * (left + right) / 2.0
                    w = WHEEL_RADIUS * (right - left) / TRACK_WIDTH
                    msg = twist_t(linear=vec3(x=v, y=0.0, z=0.0), angular=vec3(x=0.0, y=0.0, z=w))
                    writer.write(cmd, stamp, serialize(msg, "geometry_msgs/msg/Twist"))
            start = int(stamps[-1]) + round(gap_s * 1e9)
    return path
