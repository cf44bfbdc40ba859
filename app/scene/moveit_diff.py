"""A MoveIt planning-scene diff as a change of the cell, and the one reader of change files.

A change file is our CellChange YAML (app.scene.changes) or a `moveit_msgs/PlanningScene` with `is_diff: true`, in
either YAML form app.scene.moveit_messages reads; `read_change_file` tells them apart by their keys. A diff becomes
one CellChange (`diff_change`), its objects named by their ids, as the cell's objects are named (`python -m app show
SCENE`):

- world.collision_objects: ADD -> add (each primitive a Solid at header frame * object pose * primitive pose, MoveIt's
  order; an object of several primitives is the parts `ID_0`, `ID_1`, ... of object ID, Solid.part_of); REMOVE ->
  remove; MOVE -> move, to the object's new `pose` (its parts keep their poses relative to it: the object's own pose
  is kept for an object a diff added, and is its geometry's for one of the cell's own).
- robot_state.attached_collision_objects: ADD -> attach to `link_name` (the object's primitives posed in that link's
  frame), `touch_links` the links it may touch; REMOVE -> detach.

A header frame is the world ("" or "world") or an object of the cell (Placement.relative_to). What MoveIt would do
with the robot's current state (attach a world object by id alone, pose an attached object in another frame, leave a
detached object in the world where the robot holds it), meshes, planes, octomaps and changes of the allowed-collision
matrix are refused, each in one line; the robot's joint state is no change of the cell (a query gives its start) and
is passed over with a warning.
"""

import dataclasses
import math
import warnings
from pathlib import Path

import numpy as np

from app.errors import PlannerWarning, UserError
from app.io import check_input
from app.scene.changes import Attachment, CellChange, Move, Placement, Solid, read_change
from app.scene.moveit import rigid_transform
from app.scene.moveit_messages import (
    ADD,
    MOVE,
    PRIMITIVES,
    REMOVE,
    CollisionObject,
    PlanningScene,
    read_message,
)

WORLD_FRAMES = ("", "world")
# The keys that make a file a PlanningScene (those of the message, read or not), not a CellChange.
_SCENE_KEYS = {f.name for f in dataclasses.fields(PlanningScene)} | {
    "robot_model_name",
    "link_padding",
    "link_scale",
    "object_colors",
}


def read_change_file(path) -> CellChange:
    """The change in file `path`: a CellChange YAML, or a MoveIt PlanningScene diff (told apart by its keys)."""
    from pydrake.common.yaml import yaml_load_data

    path = check_input(Path(path), "change file")
    try:
        raw = yaml_load_data(path.read_text(errors="replace"))
    except Exception:  # yaml's errors: the CellChange reader says what is wrong
        raw = None
    is_scene = isinstance(raw, dict) and raw.keys() & _SCENE_KEYS and not raw.keys() & _change_keys()
    if not is_scene:
        return read_change(path)
    return diff_change(read_message(path, PlanningScene, "MoveIt planning-scene diff"), path.name)


def _change_keys() -> set[str]:
    return {f.name for f in dataclasses.fields(CellChange)}


def diff_change(diff: PlanningScene, source: str) -> CellChange:
    """The CellChange a MoveIt PlanningScene diff makes (the module's docstring); one UserError for what cannot."""
    _refuse_unsupported(diff, source)
    world = {}
    for obj in diff.world.collision_objects:
        what = f"{source}: collision object '{obj.id}'"
        if not obj.id:
            raise UserError(f"{source}: a collision object needs an id (clearing the whole world is not supported)")
        if obj.id in world:
            raise UserError(f"{what} is named twice: give one operation per object")
        world[obj.id] = obj
    change = CellChange()
    detached = set()
    for attached in diff.robot_state.attached_collision_objects:
        obj = attached.object
        what = f"{source}: attached object '{obj.id}'"
        if not obj.id or not attached.link_name:
            raise UserError(f"{what} needs an id and a link_name (detaching everything is not supported)")
        if obj.operation == ADD:
            if obj.id in world and world[obj.id].operation != REMOVE:
                raise UserError(f"{what} is also in the world's objects: give one operation per object")
            if not obj.primitives:
                raise UserError(
                    f"{what} has no primitives: attaching a world object by id takes it where the robot's state holds "
                    f"it, which is not supported; give its primitives, posed in the frame of '{attached.link_name}'"
                )
            if obj.header.frame_id not in ("", attached.link_name):
                raise UserError(
                    f"{what} is posed in frame '{obj.header.frame_id}': give its pose in the frame of its link "
                    f"'{attached.link_name}'"
                )
            extra = {"link": attached.link_name, "touch": list(attached.touch_links)}
            change.attach += _solids(obj, Attachment, "", what, **extra)
        elif obj.operation == REMOVE:
            if obj.id not in world or world[obj.id].operation not in (ADD, REMOVE):
                raise UserError(
                    f"{what}: MoveIt leaves a detached object in the world where the robot holds it, which is not "
                    "supported; give it a world ADD at a pose too, or a world REMOVE"
                )
            change.detach.append(obj.id)
            detached.add(obj.id)
        else:
            raise UserError(f"{what}: operation {obj.operation} is not supported (ADD attaches, REMOVE detaches)")
    for obj in world.values():
        what = f"{source}: collision object '{obj.id}'"
        frame = _frame(obj.header.frame_id)
        if obj.operation == ADD:
            change.add += _solids(obj, Solid, frame, what)
        elif obj.operation == REMOVE:
            if obj.id not in detached:  # (put down and taken away: the detach takes it out of the cell)
                change.remove.append(obj.id)
        elif obj.operation == MOVE:
            if obj.primitives or obj.primitive_poses or obj.meshes or obj.planes:
                raise UserError(f"{what}: a MOVE gives the object's new pose only (its shapes stay as they are)")
            pose = rigid_transform(obj.pose.position, obj.pose.orientation)
            change.move.append(Move(name=obj.id, pose=_placement(pose, frame)))
        else:
            raise UserError(f"{what}: operation {obj.operation} (APPEND) is not supported; give ADD, REMOVE or MOVE")
    return change


def _refuse_unsupported(diff: PlanningScene, source: str) -> None:
    if not diff.is_diff:
        raise UserError(
            f"{source}: a full planning scene (is_diff false) is no change; give a diff (is_diff: true), or plan "
            "on the scene with --moveit-scene"
        )
    if diff.world.octomap.octomap.data:
        raise UserError(f"{source}: octomaps are not supported; give the world's changes as collision objects")
    acm = diff.allowed_collision_matrix
    if acm.entry_names or acm.default_entry_names:
        raise UserError(
            f"{source}: changes of the allowed-collision matrix are not supported (an attached object's touch_links "
            "say what it may touch)"
        )
    if diff.fixed_frame_transforms:
        raise UserError(f"{source}: fixed frame transforms are not supported; pose objects in the world or another's")
    state = diff.robot_state
    if state.joint_state.name or state.multi_dof_joint_state.joint_names:
        warnings.warn(
            f"{source}: the robot's joint state is no change of the cell (a query gives its start): passed over",
            PlannerWarning,
            stacklevel=3,
        )
    for obj in [*diff.world.collision_objects, *(a.object for a in state.attached_collision_objects)]:
        if obj.meshes or obj.planes:
            kind = "meshes" if obj.meshes else "planes"
            raise UserError(
                f"{source}: collision object '{obj.id}': {kind} are not supported (give primitives: box, sphere, "
                "cylinder)"
            )


def _frame(frame_id: str) -> str:
    """A header frame as Placement.relative_to: "" for the world, else the cell object it names."""
    return "" if frame_id in WORLD_FRAMES else frame_id


def _solids(obj: CollisionObject, kind, frame: str, what: str, **extra) -> list:
    """An object's primitives as Solids (or Attachments) of `kind`: one named by the object's id, or several parts
    ID_0, ID_1, ..., each at object pose * primitive pose in `frame`, the object's own pose kept (Solid.part_of)."""
    if not obj.primitives:
        raise UserError(f"{what}: an ADD needs primitives (box, sphere, cylinder)")
    if len(obj.primitive_poses) != len(obj.primitives):
        raise UserError(f"{what}: {len(obj.primitives)} primitives but {len(obj.primitive_poses)} primitive poses")
    X_FO = rigid_transform(obj.pose.position, obj.pose.orientation)
    names = [obj.id] if len(obj.primitives) == 1 else [f"{obj.id}_{i}" for i in range(len(obj.primitives))]
    return [
        kind(
            name=name,
            pose=_placement(X_FO.multiply(rigid_transform(pose.position, pose.orientation)), frame),
            part_of=obj.id,
            object_pose=_placement(X_FO, frame),
            **_shape(primitive.type, primitive.dimensions, what),
            **extra,
        )
        for name, primitive, pose in zip(names, obj.primitives, obj.primitive_poses)
    ]


def _shape(kind: int, dimensions: list[float], what: str) -> dict:
    """A shape_msgs/SolidPrimitive as a Solid's shape key (a cylinder's [height, radius] as our [radius, length])."""
    names = {number: name for name, (number, _) in PRIMITIVES.items()}
    if kind not in names or names[kind] == "CONE":
        raise UserError(f"{what}: primitive type {kind} is not supported (1 BOX, 2 SPHERE, 3 CYLINDER)")
    count = PRIMITIVES[names[kind]][1]
    if len(dimensions) != count:
        raise UserError(f"{what}: a {names[kind].lower()} needs {count} dimension(s), got {list(dimensions)}")
    sizes = [float(v) for v in dimensions]
    if names[kind] == "CYLINDER":
        return {"cylinder": [sizes[1], sizes[0]]}
    return {names[kind].lower(): sizes}


def _placement(pose, frame: str) -> Placement:
    """A RigidTransform as a Placement in `frame` ("" the world, or a cell object)."""
    from pydrake.math import RollPitchYaw

    rpy = np.degrees(RollPitchYaw(pose.rotation()).vector())
    xyz = [float(v) for v in pose.translation()]
    if not all(map(math.isfinite, xyz)):
        raise UserError(f"a pose must be finite numbers, got {xyz}")
    return Placement(xyz=xyz, rpy_deg=[float(v) for v in rpy], relative_to=frame)
