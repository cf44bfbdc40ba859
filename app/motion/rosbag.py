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

`read_bag_for` reads one back for `view --trajectory BAG`: ours, or any bag holding a JointTrajectory (a ROS tool's).
"""

from __future__ import annotations

import contextlib
import os
import sqlite3
import warnings
from io import StringIO
from pathlib import Path

import numpy as np

from app.errors import Note, UserError
from app.io import check_input, write_folder_atomically
from app.motion.trajectory import SCHEMA, Trajectory, TrajectoryFile

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


def read_bag_for(path: str | os.PathLike, scene) -> TrajectoryFile:
    """The first JointTrajectory of the ROS 2 bag folder `path` as a trajectory of `scene` (app.scene.model.Scene),
    checked as a trajectory file is: its joints taken by name in the scene's order (a ROS tool may order them
    otherwise), velocities and accelerations estimated by finite differences where its points carry none. A bag
    carries no certificate, so the trajectory is not certified. Every fault is one UserError."""
    from rosbags.rosbag2 import Reader, ReaderError
    from rosbags.serde import SerdeError
    from rosbags.typesys import Stores, get_typestore

    folder = Path(path)
    name = folder.resolve().name
    if not (folder / "metadata.yaml").is_file():
        raise UserError(f"{name} is not a ROS 2 bag: a bag is a folder holding metadata.yaml")
    for file in folder.iterdir():
        check_input(file, "ROS 2 bag file")
    store = get_typestore(Stores.ROS2_JAZZY)
    try:
        with Reader(folder) as reader:
            found = [c for c in reader.connections if c.msgtype == MESSAGE_TYPE]
            if not found:
                raise UserError(f"bag {name} holds no {MESSAGE_TYPE} message")
            count = sum(c.msgcount for c in found)
            _, _, data = next(reader.messages(connections=found))
            message = store.deserialize_cdr(data, MESSAGE_TYPE)
    except (ReaderError, SerdeError, sqlite3.Error, StopIteration, KeyError, ValueError) as exc:
        raise UserError(f"cannot read bag {name}: {' '.join(str(exc).split())[:200]}") from None
    if count > 1:
        warnings.warn(f"bag {name} holds {count} joint trajectories: the first is read", Note, stacklevel=2)
    return TrajectoryFile.from_json(_as_file(message, scene, name), scene.dim, name, scene.position_map)


def _as_file(message, scene, source: str) -> dict:
    """The trajectory file's JSON object (docs/schemas/trajectory.json) of a JointTrajectory message."""
    names, points = list(message.joint_names), message.points
    missing = [name for name in scene.joint_names if name not in names]
    if missing or len(names) != len(set(names)):
        said = f"has no joint '{missing[0]}'" if missing else "names a joint twice"
        raise UserError(f"{source}: the trajectory {said} (scene '{scene.name}' has {', '.join(scene.joint_names)})")
    if not points:
        raise UserError(f"{source}: the trajectory is empty")
    order = [names.index(name) for name in scene.joint_names]
    times = np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in points])
    columns = {}
    for key in ("positions", "velocities", "accelerations"):
        rows = [np.asarray(getattr(p, key), float) for p in points]
        if all(len(row) == 0 for row in rows) and key != "positions":
            # d/dt of the column before (np.gradient: one-sided at the ends); a single point stands still.
            before = columns["velocities" if key == "accelerations" else "positions"]
            if len(times) > 1 and np.any(np.diff(times) <= 0):
                raise UserError(f"{source}: points without {key} need increasing times_from_start")
            rows = list(np.gradient(before, times, axis=0)) if len(times) > 1 else [np.zeros(len(order))]
        elif any(len(row) != len(names) for row in rows):
            raise UserError(f"{source}: a point's {key} do not match its {len(names)} joint names")
        else:
            rows = [row[order] for row in rows]
        columns[key] = np.asarray(rows)
    positions = columns["positions"]
    return {
        "schema": SCHEMA,
        "scene": scene.name,
        "joint_names": list(scene.joint_names),
        "time_from_start": times.tolist(),
        **{key: value.tolist() for key, value in columns.items()},
        "waypoints": positions.tolist(),
        "waypoint_times": times.tolist(),
        "certified": False,
    }
