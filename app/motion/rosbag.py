"""A trajectory as a ROS 2 bag: one `trajectory_msgs/msg/JointTrajectory` message, written with the pure-Python
`rosbags` package (no ROS install needed), for `ros2 bag play` or a controller's action client to read.

The message carries the same Trajectory the JSON file does (app.motion.trajectory): one point per sample, with its
positions, velocities, accelerations and time_from_start. Continuous joints keep their unwrapped angles, as a
joint trajectory controller expects of consecutive points.

Its header stamp is 0, on purpose: ros2_control's joint_trajectory_controller starts a trajectory stamped 0 when it
receives it, and refuses one whose stamp plus its duration is already past ("Received trajectory with non-zero
start time ... that ends in the past"), so a bag stamped with the time it was planned could be played once, at
best, and never later.

The bag's format follows the ROS 2 distribution it is written for (`DISTROS`): storage sqlite3, and the metadata
version that distribution's rosbag2 writes itself (Humble's 5, Jazzy's 9), or 8 by default, which Iron's and every
later rosbag2 read. rosbags writes versions 8 and 9; a Humble bag is its version 8 with the metadata (metadata.yaml
and the database's copy) rewritten as Humble's rosbag2 0.15 writes and reads it: version 5, without the fields later
versions added (a topic's type_description_hash, custom_data, ros_distro).
"""

from __future__ import annotations

import contextlib
import os
import sqlite3
from io import StringIO
from pathlib import Path

import numpy as np

from app.errors import UserError
from app.io import write_folder_atomically
from app.motion.trajectory import Trajectory

TOPIC = "/joint_trajectory"
MESSAGE_TYPE = "trajectory_msgs/msg/JointTrajectory"
# The ROS 2 distribution a bag is written for -> the rosbag2 metadata version it gets: the one that distribution's
# `ros2 bag record` writes (Humble 5; Jazzy, Kilted and Rolling 9), and for Iron 8, which rosbags writes for it and
# every rosbag2 from Iron on reads (Iron itself writes 7, which rosbags cannot).
DISTROS = {"humble": 5, "iron": 8, "jazzy": 9}
DEFAULT_DISTRO = "iron"
# Metadata fields of version 8 that Humble's rosbag2 neither writes nor reads: left out of a version 5 bag.
_LATER_FIELDS = ("custom_data", "ros_distro")
_LATER_TOPIC_FIELDS = ("type_description_hash",)


def write_bag(
    path: str | os.PathLike, trajectory: Trajectory, frame_id: str = "world", distro: str = DEFAULT_DISTRO
) -> Path:
    """Write `trajectory` as a new ROS 2 bag folder at `path` (refused if it exists) that `distro`'s rosbag2 reads
    (a key of DISTROS); the message's header is stamped 0 (see the module's docstring)."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    if distro not in DISTROS:
        raise UserError(f"unknown ROS 2 distribution {distro!r} (known: {', '.join(DISTROS)})")
    version = DISTROS[distro]
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
        with Writer(folder, version=max(version, 8)) as writer:
            connection = writer.add_connection(TOPIC, MESSAGE_TYPE, typestore=store)
            writer.write(connection, 0, store.serialize_cdr(message, MESSAGE_TYPE))
        if version < 8:
            _rewrite_metadata(folder, version)

    return write_folder_atomically(path, fill)


def _rewrite_metadata(folder: Path, version: int) -> None:
    """The metadata of the version 8 bag rosbags wrote in `folder` as `version` (5) has it: metadata.yaml and the
    copy in the database's `metadata` table, with `version` and without the fields later versions added."""
    from ruamel.yaml import YAML  # rosbags' own YAML library: installed with it

    yaml = YAML(typ="safe")
    yaml.default_flow_style = False
    path = folder / "metadata.yaml"
    document = yaml.load(path.read_text("utf-8"))
    info = document["rosbag2_bagfile_information"]
    info["version"] = version
    for key in _LATER_FIELDS:
        info.pop(key, None)
    for topic in info["topics_with_message_count"]:
        for key in _LATER_TOPIC_FIELDS:
            topic["topic_metadata"].pop(key, None)
    text = StringIO()
    yaml.dump(document, text)
    path.write_text(text.getvalue(), "utf-8")
    copy = StringIO()
    yaml.dump(info, copy)
    for name in info["relative_file_paths"]:
        with contextlib.closing(sqlite3.connect(folder / name)) as database, database:  # committed, then closed
            database.execute(
                "UPDATE metadata SET metadata_version = ?, metadata = ?", (version, copy.getvalue().strip())
            )
