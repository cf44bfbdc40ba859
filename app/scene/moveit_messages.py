"""MoveIt's messages as this planner reads and writes them: `moveit_msgs` PlanningScene, MotionPlanRequest and
MotionPlanResponse (the fields used; others in a file are ignored), loaded from either YAML form MoveIt's tools dump
(`ros2 topic echo`, or Robowflex's, which MotionBenchMaker's datasets use: `_normalised` makes them one) with Drake's
typed YAML loader, and MoveIt's error codes. What a problem's messages become is app.scene.moveit's."""

from dataclasses import dataclass, field
from pathlib import Path

from app.errors import UserError
from app.io import check_input

# moveit_msgs/MoveItErrorCodes.msg (moveit/moveit_msgs, master): the codes a response carries, by the names our
# errors carry (app.errors: `code`). Bad input of ours that MoveIt has no name for is its FAILURE.
ERROR_CODES = {
    "SUCCESS": 1,
    "FAILURE": 99999,
    "PLANNING_FAILED": -1,
    "INVALID_MOTION_PLAN": -2,
    "TIMED_OUT": -6,
    "PREEMPTED": -7,
    "START_STATE_IN_COLLISION": -10,
    "GOAL_IN_COLLISION": -12,
    "INVALID_GROUP_NAME": -15,
    "INVALID_GOAL_CONSTRAINTS": -16,
    "INVALID_ROBOT_STATE": -17,
    "INVALID_LINK_NAME": -18,
    "INVALID_OBJECT_NAME": -19,
    "FRAME_TRANSFORM_FAILURE": -21,
    "START_STATE_INVALID": -26,
    "GOAL_STATE_INVALID": -27,
    "NO_IK_SOLUTION": -31,
}
# moveit_msgs/CollisionObject's operations.
ADD, REMOVE, APPEND, MOVE = 0, 1, 2, 3
# shape_msgs/SolidPrimitive types and the dimensions each takes.
PRIMITIVES = {"BOX": (1, 3), "SPHERE": (2, 1), "CYLINDER": (3, 2), "CONE": (4, 2)}


# ---- the messages (the fields read; others in a file are ignored) --------------------------------------------------
@dataclass
class Vector3:
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0


@dataclass
class Quaternion:
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    w: float = 1.0


@dataclass
class Pose:
    position: Vector3 = field(default_factory=Vector3)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class Header:
    frame_id: str = ""


@dataclass
class SolidPrimitive:
    type: int = 0
    dimensions: list[float] = field(default_factory=list)


@dataclass
class Listed:
    """A message this planner does not read, only counts (a mesh, a plane, an attached object)."""


@dataclass
class CollisionObject:
    header: Header = field(default_factory=Header)
    pose: Pose = field(default_factory=Pose)
    id: str = ""
    primitives: list[SolidPrimitive] = field(default_factory=list)
    primitive_poses: list[Pose] = field(default_factory=list)
    meshes: list[Listed] = field(default_factory=list)
    planes: list[Listed] = field(default_factory=list)
    operation: int = 0  # ADD


@dataclass
class JointState:
    name: list[str] = field(default_factory=list)
    position: list[float] = field(default_factory=list)


@dataclass
class Transform:
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass
class MultiDOFJointState:
    joint_names: list[str] = field(default_factory=list)
    transforms: list[Transform] = field(default_factory=list)


@dataclass
class AttachedCollisionObject:
    link_name: str = ""
    object: CollisionObject = field(default_factory=CollisionObject)
    touch_links: list[str] = field(default_factory=list)


@dataclass
class RobotState:
    joint_state: JointState = field(default_factory=JointState)
    multi_dof_joint_state: MultiDOFJointState = field(default_factory=MultiDOFJointState)
    attached_collision_objects: list[AttachedCollisionObject] = field(default_factory=list)
    is_diff: bool = False


@dataclass
class AllowedCollisionEntry:
    enabled: list[bool] = field(default_factory=list)


@dataclass
class AllowedCollisionMatrix:
    entry_names: list[str] = field(default_factory=list)
    entry_values: list[AllowedCollisionEntry] = field(default_factory=list)
    default_entry_names: list[str] = field(default_factory=list)
    default_entry_values: list[bool] = field(default_factory=list)


@dataclass
class Transform:
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass
class TransformStamped:
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    transform: Transform = field(default_factory=Transform)


@dataclass
class Octomap:
    data: list[int] = field(default_factory=list)


@dataclass
class OctomapWithPose:
    octomap: Octomap = field(default_factory=Octomap)


@dataclass
class PlanningSceneWorld:
    collision_objects: list[CollisionObject] = field(default_factory=list)
    octomap: OctomapWithPose = field(default_factory=OctomapWithPose)


@dataclass
class PlanningScene:
    """moveit_msgs/PlanningScene, the fields read."""

    name: str = ""
    robot_state: RobotState = field(default_factory=RobotState)
    fixed_frame_transforms: list[TransformStamped] = field(default_factory=list)
    allowed_collision_matrix: AllowedCollisionMatrix = field(default_factory=AllowedCollisionMatrix)
    world: PlanningSceneWorld = field(default_factory=PlanningSceneWorld)
    is_diff: bool = False


@dataclass
class JointConstraint:
    joint_name: str = ""
    position: float = 0.0
    tolerance_above: float = 0.0
    tolerance_below: float = 0.0


@dataclass
class BoundingVolume:
    primitives: list[SolidPrimitive] = field(default_factory=list)
    primitive_poses: list[Pose] = field(default_factory=list)
    meshes: list[Listed] = field(default_factory=list)


@dataclass
class PositionConstraint:
    header: Header = field(default_factory=Header)
    link_name: str = ""
    target_point_offset: Vector3 = field(default_factory=Vector3)
    constraint_region: BoundingVolume = field(default_factory=BoundingVolume)


@dataclass
class OrientationConstraint:
    header: Header = field(default_factory=Header)
    orientation: Quaternion = field(default_factory=Quaternion)
    link_name: str = ""
    absolute_x_axis_tolerance: float = 0.0
    absolute_y_axis_tolerance: float = 0.0
    absolute_z_axis_tolerance: float = 0.0


@dataclass
class Constraints:
    name: str = ""
    joint_constraints: list[JointConstraint] = field(default_factory=list)
    position_constraints: list[PositionConstraint] = field(default_factory=list)
    orientation_constraints: list[OrientationConstraint] = field(default_factory=list)
    visibility_constraints: list[Listed] = field(default_factory=list)


@dataclass
class MotionPlanRequest:
    """moveit_msgs/MotionPlanRequest, the fields read."""

    start_state: RobotState = field(default_factory=RobotState)
    goal_constraints: list[Constraints] = field(default_factory=list)
    path_constraints: Constraints = field(default_factory=Constraints)
    group_name: str = ""
    allowed_planning_time: float = 0.0
    max_velocity_scaling_factor: float = 0.0
    max_acceleration_scaling_factor: float = 0.0


@dataclass
class Duration:
    sec: int = 0
    nanosec: int = 0


@dataclass
class JointTrajectoryPoint:
    positions: list[float] = field(default_factory=list)
    velocities: list[float] = field(default_factory=list)
    accelerations: list[float] = field(default_factory=list)
    time_from_start: Duration = field(default_factory=Duration)


@dataclass
class JointTrajectory:
    header: Header = field(default_factory=Header)
    joint_names: list[str] = field(default_factory=list)
    points: list[JointTrajectoryPoint] = field(default_factory=list)


@dataclass
class RobotTrajectory:
    joint_trajectory: JointTrajectory = field(default_factory=JointTrajectory)


@dataclass
class MoveItErrorCodes:
    val: int = 0


@dataclass
class MotionPlanResponse:
    """moveit_msgs/MotionPlanResponse (written by app.planning.moveit)."""

    trajectory_start: RobotState = field(default_factory=RobotState)
    group_name: str = ""
    trajectory: RobotTrajectory = field(default_factory=RobotTrajectory)
    planning_time: float = 0.0
    error_code: MoveItErrorCodes = field(default_factory=MoveItErrorCodes)


# ---- reading ------------------------------------------------------------------------------------------------------
def read_message(path: str | Path, schema, what: str):
    """A message of `schema` from its YAML file (either form: the module's docstring); one UserError if it is not
    one."""
    from pydrake.common.yaml import yaml_dump, yaml_load_data, yaml_load_typed

    path = check_input(Path(path), "scene file")
    try:
        raw = yaml_load_data(path.read_text(errors="replace"))
    except Exception as exc:  # yaml's errors, of several classes
        raise UserError(f"bad {what} {path.name}: {' '.join(str(exc).split())[:200]}") from None
    if not isinstance(raw, dict):
        raise UserError(f"bad {what} {path.name}: expected a mapping of the message's fields")
    try:
        return yaml_load_typed(schema=schema, data=yaml_dump(_normalised(raw)), allow_yaml_with_no_schema=True)
    except UserError as exc:
        raise UserError(f"bad {what} {path.name}: {exc}") from None
    except Exception as exc:  # the typed loader's: a field of the wrong kind
        raise UserError(f"bad {what} {path.name}: {' '.join(str(exc).split())[:300]}") from None


def _normalised(node, key: str = ""):
    """Robowflex's forms as ROS 2's: [x, y, z] points, [x, y, z, w] quaternions, primitive types by name and
    allowed-collision rows as bare lists."""
    if isinstance(node, list):
        if key in ("position", "translation", "target_point_offset") and len(node) == 3:
            return dict(zip("xyz", node))
        if key in ("orientation", "rotation") and len(node) == 4:
            return dict(zip("xyzw", node))
        return [_normalised(item) for item in node]
    if not isinstance(node, dict):
        return node
    out = {k: _normalised(v, k if _pose_like(node, k) else "") for k, v in node.items()}
    rows = out.get("entry_values")
    if isinstance(rows, list) and all(isinstance(row, list) for row in rows):
        # Robowflex writes an allowed-collision row as its bare list of flags.
        out["entry_values"] = [{"enabled": row} for row in rows]
    if isinstance(out.get("type"), str) and "dimensions" in out:
        name = out["type"].strip().upper()
        if name not in PRIMITIVES:
            raise UserError(f"unknown primitive type '{out['type']}' (known: {', '.join(PRIMITIVES)})")
        out["type"] = PRIMITIVES[name][0]
    return out


def _pose_like(node: dict, key: str) -> bool:
    """Whether `key` of `node` is a point or a rotation (a joint state's `position` is a list of joint positions)."""
    if key == "position":
        return "orientation" in node
    return key in ("orientation", "translation", "rotation", "target_point_offset")


def read_response(path: str | Path) -> MotionPlanResponse:
    """A MotionPlanResponse YAML file (as app.planning.moveit writes it, or MoveIt dumps it)."""
    return read_message(path, MotionPlanResponse, "MoveIt response")
