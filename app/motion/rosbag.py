"""A trajectory as a ROS 2 bag: one `trajectory_msgs/msg/JointTrajectory` message, written with the pure-Python
`rosbags` package (no ROS install needed), for `ros2 bag play` or a controller's action client to read.

The message carries the same Trajectory the JSON file does (app.motion.trajectory): one point per sample, with its
positions, velocities, accelerations and time_from_start. Continuous joints keep their unwrapped angles, as a
joint trajectory controller expects of consecutive points.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from app.io import write_folder_atomically
from app.motion.trajectory import Trajectory

TOPIC = "/joint_trajectory"
MESSAGE_TYPE = "trajectory_msgs/msg/JointTrajectory"
# Rosbag2 metadata version 8 (ROS 2 Iron, Jazzy and later); rosbags writes 8 or 9.
BAG_VERSION = 8


def write_bag(path: str | os.PathLike, trajectory: Trajectory, frame_id: str = "world") -> Path:
    """Write `trajectory` as a new ROS 2 bag folder at `path` (refused if it exists); the message is stamped 0."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    types = store.types
    Duration, Time = types["builtin_interfaces/msg/Duration"], types["builtin_interfaces/msg/Time"]
    Point = types["trajectory_msgs/msg/JointTrajectoryPoint"]
    nanoseconds = np.round(np.asarray(trajectory.times, float) * 1e9).astype(np.int64)
    names, positions, velocities, accelerations = trajectory.joints()  # mimic joints' included
    points = [
        Point(
            positions=np.asarray(positions[i], float),
            velocities=np.asarray(velocities[i], float),
            accelerations=np.asarray(accelerations[i], float),
            effort=np.zeros(0),
            time_from_start=Duration(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000)),
        )
        for i, ns in enumerate(nanoseconds)
    ]
    message = types[MESSAGE_TYPE](
        header=types["std_msgs/msg/Header"](stamp=Time(sec=0, nanosec=0), frame_id=frame_id),
        joint_names=names,
        points=points,
    )

    def fill(folder: Path) -> None:
        with Writer(folder, version=BAG_VERSION) as writer:
            connection = writer.add_connection(TOPIC, MESSAGE_TYPE, typestore=store)
            writer.write(connection, 0, store.serialize_cdr(message, MESSAGE_TYPE))

    return write_folder_atomically(path, fill)
