"""A timed motion and its one file format, written by `plan --out` and `run --out`, read by `view --trajectory`.

The file is a JSON object shaped like ROS `trajectory_msgs/JointTrajectory` (joint names; per sample the time from
start, positions, velocities, accelerations), stored by columns:

    schema            "npp-trajectory/1"
    scene             the scene's name
    joint_names       one name per joint position (the model's joint names; a floating body's as name[i])
    time_from_start   (N,) seconds, non-decreasing, from 0
    positions         (N, J) continuous angles unwrapped (no 2 pi jumps), so consecutive samples are close
    velocities        (N, J) per second
    accelerations     (N, J) per second squared
    waypoints         (K, J) the path the motion follows, unwrapped like positions
    waypoint_times    (K,) when the motion passes each waypoint
    certified         whether the whole motion, not only its samples, was proved collision-free
    clearance         optional: the distance a certified motion was proved to keep from everything (scene length
                      units), of which the straight lines between its samples and the waypoints' polyline keep
                      half; null when not certified
    narrow_samples    optional (M, J): the planner's narrow-passage samples
    narrow_on_path    optional (M,) booleans: which of them the roadmap path used

J is the scene's number of coordinates, and more when mimic joints follow them (app.scene.cspace.PositionMap):
the file carries every joint, a mimic joint's values computed from its coordinate's; in memory a Trajectory holds
the coordinates alone, and a file whose mimic joints do not follow their coordinates is refused.

Anything else in the file is an error, so a misspelt key is found rather than ignored. docs/schemas/trajectory.json
describes the file as a JSON Schema; app.motion.rosbag writes the same Trajectory as a ROS 2 bag.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.errors import UserError
from app.io import check_input, write_atomically
from app.scene.cspace import PositionMap

SCHEMA = "npp-trajectory/1"


@dataclass
class Trajectory:
    """A timed motion of the scene's coordinates, sampled every PlanSettings.dt seconds (`PlanResult.trajectory`).

    Attributes:
        joint_names: One name per coordinate.
        times: (N,) seconds from 0 to `duration`.
        positions: (N, dim), continuous angles unwrapped (no 2 pi jumps).
        velocities: (N, dim) per second.
        accelerations: (N, dim) per second squared.
        waypoints: (K, dim) the path the motion follows, unwrapped like `positions`.
        waypoint_times: (K,) when the motion passes each waypoint.
        certified: Whether the whole motion, not only its samples, was proved collision-free.
        position_map: The scene's mimic joints (None: every joint is a coordinate); `joints()` gives every joint.
        clearance: Certified: the distance the motion keeps from everything; the straight lines between its samples
            (what a controller interpolating linearly follows) and the waypoints' polyline keep half of it. None:
            not certified.
    """

    joint_names: list[str]
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    waypoints: np.ndarray
    waypoint_times: np.ndarray
    certified: bool = False
    position_map: PositionMap | None = None
    clearance: float | None = None

    @property
    def duration(self) -> float:
        """Seconds from the first sample to the last."""
        return float(self.times[-1]) if len(self.times) else 0.0

    def joints(self) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
        """Every joint's (names, positions, velocities, accelerations), mimic joints' included."""
        m = self.position_map
        if m is None:
            return list(self.joint_names), self.positions, self.velocities, self.accelerations
        return list(m.names), m.positions(self.positions), m.rates(self.velocities), m.rates(self.accelerations)

    def to_json(self) -> dict:
        """The motion's part of the trajectory file: every joint's columns (see this module's docstring)."""
        names, positions, velocities, accelerations = self.joints()
        waypoints = self.waypoints if self.position_map is None else self.position_map.positions(self.waypoints)
        return {
            "joint_names": names,
            "time_from_start": self.times.tolist(),
            "positions": positions.tolist(),
            "velocities": velocities.tolist(),
            "accelerations": accelerations.tolist(),
            "waypoints": waypoints.tolist(),
            "waypoint_times": self.waypoint_times.tolist(),
            "certified": bool(self.certified),
            "clearance": self.clearance,
        }


@dataclass
class TrajectoryFile:
    """What a trajectory file holds: the motion, the scene it is for, and optionally the narrow-passage samples
    (`PlanResult.trajectory_file()`; `write` it, `read` or `read_for` it back).

    Attributes:
        scene: The scene's name.
        trajectory: The motion.
        narrow: (M, dim) the planner's narrow-passage samples, or None.
        on_path: (M,) booleans: which of them the roadmap path used.
    """

    scene: str
    trajectory: Trajectory
    narrow: np.ndarray | None = None
    on_path: np.ndarray | None = field(default=None)

    def to_json(self) -> dict:
        """The file's JSON object (docs/schemas/trajectory.json)."""
        out = {"schema": SCHEMA, "scene": self.scene, **self.trajectory.to_json()}
        if self.narrow is not None:
            m = self.trajectory.position_map
            out["narrow_samples"] = np.asarray(self.narrow if m is None else m.positions(self.narrow)).tolist()
            out["narrow_on_path"] = [bool(x) for x in self.on_path]
        return out

    def write(self, path: str | os.PathLike) -> Path:
        """Write the file to `path`, atomically (whole or not at all); its folder must exist (UserError if not)."""
        return write_atomically(path, json.dumps(self.to_json(), separators=(",", ":")))

    @classmethod
    def read(cls, path: str | os.PathLike, dim: int, position_map: PositionMap | None = None) -> TrajectoryFile:
        """A trajectory file checked against a scene of `dim` coordinates (and its mimic joints' `position_map`);
        every fault is one UserError."""
        file = check_input(path, "trajectory file")
        try:
            obj = json.loads(file.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise UserError(f"cannot read trajectory {file.name}: {' '.join(str(exc).split())[:200]}") from None
        return cls.from_json(obj, dim, source=file.name, position_map=position_map)

    @classmethod
    def read_for(cls, path: str | os.PathLike, scene) -> TrajectoryFile:
        """A trajectory file of `scene` (app.scene.model.Scene): written for a scene of its name, with its
        joints' names in order; every fault is one UserError."""
        file = cls.read(path, scene.dim, scene.position_map)
        source = Path(path).name
        if file.scene != scene.name:
            raise UserError(f"{source} is a trajectory of scene '{file.scene}', not of '{scene.name}'")
        names = list(file.trajectory.joints()[0])
        if names != list(scene.joint_names):
            k = next(i for i, (a, b) in enumerate(zip(names, scene.joint_names)) if a != b)
            raise UserError(
                f"{source}: joint {k + 1} is '{names[k]}', but scene '{scene.name}' has '{scene.joint_names[k]}'"
            )
        return file

    @classmethod
    def from_json(
        cls, obj, dim: int, source: str = "trajectory", position_map: PositionMap | None = None
    ) -> TrajectoryFile:
        """A trajectory file's JSON object checked as `read` checks a file (`source` names it in messages)."""
        if not isinstance(obj, dict):
            raise UserError(f"{source}: expected a JSON object (schema {SCHEMA})")
        if obj.get("schema") != SCHEMA:
            raise UserError(f"{source}: schema is {obj.get('schema')!r}, expected {SCHEMA!r}")
        known = {
            "schema",
            "scene",
            "joint_names",
            "time_from_start",
            "positions",
            "velocities",
            "accelerations",
            "waypoints",
            "waypoint_times",
            "certified",
            "clearance",
            "narrow_samples",
            "narrow_on_path",
        }
        unknown = set(obj) - known
        if unknown:
            raise UserError(f"{source}: unknown key(s) {', '.join(sorted(unknown))}")
        missing = sorted(known - set(obj) - {"narrow_samples", "narrow_on_path", "clearance"})
        if missing:
            raise UserError(f"{source}: missing key(s) {', '.join(missing)}")
        names = obj["joint_names"]
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise UserError(f"{source}: 'joint_names' must be a list of names")
        joints = dim if position_map is None else len(position_map.names)
        if len(names) != joints:
            raise UserError(f"{source}: {len(names)} 'joint_names' for a scene of {joints} joints")
        times = _vector(obj["time_from_start"], "time_from_start", source)
        if len(times) == 0:
            raise UserError(f"{source}: the trajectory is empty")
        if np.any(np.diff(times) < 0):
            raise UserError(f"{source}: 'time_from_start' must be non-decreasing")
        columns = {key: _matrix(obj[key], key, joints, source) for key in ("positions", "velocities", "accelerations")}
        for key, value in columns.items():
            if len(value) != len(times):
                raise UserError(f"{source}: {len(value)} rows of '{key}' for {len(times)} times")
        columns = {
            key: _coordinates(value, position_map, key, source, rates=key != "positions")
            for key, value in columns.items()
        }
        waypoints = _coordinates(
            _matrix(obj["waypoints"], "waypoints", joints, source), position_map, "waypoints", source
        )
        waypoint_times = _vector(obj["waypoint_times"], "waypoint_times", source)
        if len(waypoint_times) != len(waypoints):
            raise UserError(f"{source}: {len(waypoint_times)} waypoint times for {len(waypoints)} waypoints")
        if not isinstance(obj["certified"], bool):
            raise UserError(f"{source}: 'certified' must be true or false")
        clearance = obj.get("clearance")
        if clearance is not None and (
            isinstance(clearance, bool) or not isinstance(clearance, (int, float)) or not 0 <= clearance < np.inf
        ):
            raise UserError(f"{source}: 'clearance' must be a distance of at least 0, or null")
        trajectory = Trajectory(
            names,
            times,
            columns["positions"],
            columns["velocities"],
            columns["accelerations"],
            waypoints,
            waypoint_times,
            obj["certified"],
            position_map,
            None if clearance is None else float(clearance),
        )
        narrow, on_path = _narrow_samples(obj, joints, position_map, source)
        return cls(scene=str(obj["scene"]), trajectory=trajectory, narrow=narrow, on_path=on_path)


def _narrow_samples(obj: dict, joints: int, position_map, source: str) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The file's narrow-passage samples and which of them the path used, or (None, None) when it has none."""
    if ("narrow_samples" in obj) != ("narrow_on_path" in obj):
        raise UserError(f"{source}: 'narrow_samples' and 'narrow_on_path' go together")
    if "narrow_samples" not in obj:
        return None, None
    matrix = _matrix(obj["narrow_samples"], "narrow_samples", joints, source)
    narrow = _coordinates(matrix, position_map, "narrow_samples", source)
    flags = obj["narrow_on_path"]
    if not isinstance(flags, list) or not all(isinstance(f, bool) for f in flags):
        raise UserError(f"{source}: 'narrow_on_path' must be a list of true/false")
    if len(flags) != len(narrow):
        raise UserError(f"{source}: {len(flags)} 'narrow_on_path' flags for {len(narrow)} narrow samples")
    return narrow, np.array(flags, bool)


def _coordinates(P: np.ndarray, position_map: PositionMap | None, key: str, source: str, rates=False) -> np.ndarray:
    """The planned coordinates of rows of every joint's values (positions, or with `rates` velocities or
    accelerations); a mimic joint that does not follow its coordinate is refused."""
    if position_map is None:
        return P
    Q = position_map.coordinates(P)
    expected = position_map.rates(Q) if rates else position_map.positions(Q)
    off = np.abs(expected - P) > 1e-9 * (1.0 + np.abs(P))
    if off.any():
        joint = position_map.names[int(np.flatnonzero(off.any(axis=0))[0])]
        raise UserError(f"{source}: '{key}' of mimic joint '{joint}' do not follow the joint it mimics")
    return Q


def _vector(value, key: str, source: str) -> np.ndarray:
    try:
        array = np.asarray(value, float)
    except (TypeError, ValueError):
        raise UserError(f"{source}: '{key}' must be a list of numbers") from None
    if array.ndim != 1 or not np.all(np.isfinite(array)):
        raise UserError(f"{source}: '{key}' must be a list of finite numbers")
    return array


def _matrix(value, key: str, dim: int, source: str) -> np.ndarray:
    try:
        array = np.asarray(value, float)
    except (TypeError, ValueError):
        raise UserError(f"{source}: '{key}' must be a list of lists of numbers") from None
    if array.ndim == 1 and array.size == 0:
        array = array.reshape(0, dim)
    if array.ndim != 2 or array.shape[1] != dim:
        got = array.shape[1] if array.ndim == 2 else f"shape {array.shape}"
        raise UserError(f"{source}: '{key}' needs rows of {dim} numbers (the scene's dimension), got {got}")
    if not np.all(np.isfinite(array)):
        raise UserError(f"{source}: '{key}' has a value that is not a finite number")
    return array
