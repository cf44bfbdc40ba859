"""MoveIt problems as scenes: a `moveit_msgs/PlanningScene` and a `moveit_msgs/MotionPlanRequest` in their YAML forms
(and the `MotionPlanResponse` the planner answers with, read back), for a URDF robot and its SRDF.

The files are the messages as MoveIt's tools dump them: `ros2 topic echo` (a pose's position and orientation as
mappings {x, y, z, w}; a primitive's type a number, 1 BOX, 2 SPHERE, 3 CYLINDER, 4 CONE) or Robowflex, which writes
MotionBenchMaker's datasets (positions [x, y, z], orientations [x, y, z, w], types by name, "box"). Both are made one
(`_normalised`), then loaded with Drake's typed YAML loader into the message dataclasses below: keys of a message this
planner does not use (headers' stamps, link padding, object colours, ...) are ignored, and whatever it would have to
honour but cannot (attached objects, path constraints, octomaps, planes, meshes, diffs) is refused in one line.

What the messages become (`read_problem`):
- The planning frame is the URDF's root link (welded at the world's origin), also named by a fixed SRDF
  <virtual_joint>'s parent frame ("world") or ""; a frame is that, a link fixed to the root by fixed joints, or the
  child of one of the scene's `fixed_frame_transforms` (from the planning frame).
- World collision objects become one static SDF model in the cache, one <link> per object named by its id, each
  primitive a <collision> at header frame * object pose * primitive pose (MoveIt's order; a zero quaternion is the
  identity, as MoveIt takes it). Boxes, spheres and cylinders (axis along z); a cone is refused (SDF has none).
- The allowed-collision matrix: an entry allowed between two robot links, or a link and an object, is a body pair
  never checked (app.scene.spec.CustomSpec.allowed_collisions); a default entry allowed lets the name touch anything.
- The start: the scene's robot state, then the request's start state over it (a partial start keeps the scene's
  other joints; a joint neither names is at 0).
- The group: the SRDF <group> of `group_name` (its joints, chains, links' parent joints and subgroups); every other
  joint is held at the start (CustomSpec.hold), so the plan moves the group's joints only. No group name: every joint.
- Goals: each of `goal_constraints` is one goal, any of which the plan may reach: joint constraints (the group's
  joints not named stay at the start) or a position and an orientation constraint on one link (a pose, solved by IK:
  app.planning.moveit).
"""

import hashlib
import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from app.errors import PlannerWarning, UserError
from app.io import check_input
from app.scene import custom
from app.scene.emit import write_if_changed
from app.scene.meshes.cache import cache_root
from app.scene.model_files import (
    ModelFile,
    read_model_file,
    read_srdf_fixed_frames,
    read_srdf_groups,
    urdf_joints,
)
from app.scene.moveit_messages import (
    ADD,
    APPEND,
    PRIMITIVES,
    AllowedCollisionMatrix,
    Constraints,
    MotionPlanRequest,
    PlanningScene,
    Quaternion,
    SolidPrimitive,
    Transform,
    Vector3,
    read_message,
)
from app.scene.spec import CustomSpec, parse_package_paths

# The smallest tolerances a goal is solved to (a constraint of 0 has no solution a solver can certify).
MIN_POSITION_TOLERANCE, MIN_ANGLE_TOLERANCE = 1e-6, 1e-6


# ---- a problem ----------------------------------------------------------------------------------------------------
@dataclass
class PoseGoal:
    """A goal pose of a link: its origin at `xyz` (world), turned by the unit quaternion `wxyz`, within the
    tolerances."""

    link: str
    xyz: np.ndarray
    wxyz: np.ndarray
    position_tolerance: float
    angle_tolerance: float


@dataclass
class MoveItProblem:
    """A MoveIt request on its scene, read: the scene (the group's joints its coordinates, the others held), the
    start, the goals and what the request asks of the motion.

    Attributes:
        scene: The scene (app.scene.custom.CustomScene).
        group: The planning group's name ("" for every joint).
        start_state: Every joint's start position, by name (a response's trajectory_start).
        start: The start, one value per coordinate of the scene.
        joint_goals: (k, dim) the joint-space goals.
        pose_goals: The pose goals (solved by app.planning.moveit).
        velocity_scale: The request's velocity scaling factor (1 when it gives none).
        acceleration_scale: The same for accelerations.
        seconds: The request's allowed planning time (None: none given).
    """

    scene: custom.CustomScene
    group: str
    start_state: dict[str, float]
    start: np.ndarray
    joint_goals: np.ndarray
    pose_goals: list[PoseGoal]
    velocity_scale: float
    acceleration_scale: float
    seconds: float | None


def read_problem(
    *,
    request: str | Path,
    scene: str | Path | None,
    robot: str | Path,
    srdf: str | Path | None = None,
    package_path: list[str] = (),
    cache_dir: Path | None = None,
    **options,
) -> MoveItProblem:
    """The problem a MotionPlanRequest file poses on a PlanningScene file (None: an empty world, the robot at 0) for
    the URDF `robot` with its SRDF (needed for a group name). `options`: CustomSpec keys the files do not set
    (mesh_method, resolution, velocity_limits, ...). Every fault is one UserError; a bad group name's code is
    INVALID_GROUP_NAME."""
    planning = read_message(scene, PlanningScene, "MoveIt planning scene") if scene else PlanningScene()
    asked = read_message(request, MotionPlanRequest, "MoveIt request")
    names = (Path(scene).name if scene else None, Path(request).name)
    _refuse_unsupported(planning, asked, *names)
    robot_path = Path(robot).expanduser().resolve()
    model = _urdf(robot_path, parse_package_paths(list(package_path)))
    joints = urdf_joints(model)
    frames = _Frames(model, joints, srdf, planning)
    movable = [j.name for j in joints.values() if j.kind in ("revolute", "continuous", "prismatic")]
    mimic = {m["joint"] for m in model.mimics()}
    fixed = set(joints) - set(movable)
    start_state = _start_state(planning, asked, movable, fixed, *names)
    group_joints = _group_joints(asked.group_name, srdf, joints, model)
    hold = {name: start_state[name] for name in movable if name not in group_joints and name not in mimic}
    world_file, object_links = _world_file(planning, frames, model, cache_dir, Path(scene).stem if scene else "")
    spec = CustomSpec(
        description=f"MoveIt request {names[1]}" + (f" on {names[0]}" if names[0] else ""),
        robot=str(robot_path),
        package_path=list(package_path),
        env=[str(world_file)] if world_file else [],
        srdf=str(srdf or ""),
        hold=hold,
        allowed_collisions=_allowed(planning.allowed_collision_matrix, model.links, object_links, names[0]),
        **options,
    )
    built = custom.build_scene(spec, cache_dir=cache_dir, progress=False, source=names[0] or names[1])
    coordinates = built.coordinate_names
    start = np.array([start_state[name] for name in coordinates])
    joint_goals, pose_goals = _goals(asked, coordinates, start_state, hold, frames, names[1])
    unknown = sorted({goal.link for goal in pose_goals} - (model.links or set()))
    if unknown:
        raise UserError(f"{names[1]}: goal link(s) {', '.join(unknown)} not in {model.path.name}", "INVALID_LINK_NAME")
    return MoveItProblem(
        scene=built,
        group=asked.group_name,
        start_state=dict(zip(built.joint_names, built.positions(start).tolist())),
        start=start,
        joint_goals=joint_goals,
        pose_goals=pose_goals,
        velocity_scale=_scaling(asked.max_velocity_scaling_factor, "velocity"),
        acceleration_scale=_scaling(asked.max_acceleration_scaling_factor, "acceleration"),
        seconds=_planning_time(asked.allowed_planning_time, names[1]),
    )


def _refuse_unsupported(planning: PlanningScene, asked: MotionPlanRequest, scene: str | None, request: str) -> None:
    """What the files ask that this planner cannot honour, refused rather than left out."""
    if planning.is_diff:
        raise UserError(f"{scene}: is_diff is true: a diff changes a scene this file does not hold; give a full scene")
    if planning.world.octomap.octomap.data:
        raise UserError(f"{scene}: octomaps are not supported; give the world as collision objects")
    for where, state in ((scene, planning.robot_state), (request, asked.start_state)):
        if state.attached_collision_objects:
            raise UserError(f"{where}: attached collision objects are not supported")
        if not all(_is_identity(t) for t in state.multi_dof_joint_state.transforms):
            raise UserError(
                f"{where}: a multi-DOF joint away from the origin is not supported (the URDF's robot stands at the "
                "world origin)"
            )
    path = asked.path_constraints
    if path.joint_constraints or path.position_constraints or path.orientation_constraints:
        raise UserError(f"{request}: path constraints are not supported")


def _is_identity(t: Transform) -> bool:
    """Whether a multi-DOF joint's transform leaves the robot where its URDF puts it (MotionBenchMaker's scenes
    carry a virtual joint at the origin)."""
    p, q = t.translation, t.rotation
    return max(abs(p.x), abs(p.y), abs(p.z)) < 1e-9 and abs(abs(q.w) - 1) < 1e-9


def _urdf(robot_path: Path, packages: dict[str, Path]) -> ModelFile:
    if robot_path.suffix.lower() != ".urdf":
        raise UserError(f"a MoveIt problem's robot is a URDF (with its SRDF), got {robot_path.name}")
    return read_model_file(check_input(robot_path, "model file"), packages)


def _start_state(
    planning: PlanningScene,
    asked: MotionPlanRequest,
    movable: list[str],
    fixed: set[str],
    scene: str | None,
    request: str,
) -> dict[str, float]:
    """Every movable joint's start: the scene's robot state, the request's start state over it, else 0. A fixed
    joint's position is passed over (a URDF that fixes the fingers is posed in files that name them)."""
    state = dict.fromkeys(movable, 0.0)
    for where, joint_state in ((scene, planning.robot_state.joint_state), (request, asked.start_state.joint_state)):
        if len(joint_state.name) != len(joint_state.position):
            raise UserError(
                f"{where}: joint_state has {len(joint_state.name)} names and {len(joint_state.position)} positions",
                "INVALID_ROBOT_STATE",
            )
        for name, position in zip(joint_state.name, joint_state.position):
            if name in fixed:
                continue
            if name not in state:
                raise UserError(
                    f"{where}: joint_state names '{name}', no movable joint of the robot", "INVALID_ROBOT_STATE"
                )
            if not math.isfinite(position):
                raise UserError(f"{where}: joint '{name}' is at {position}", "INVALID_ROBOT_STATE")
            state[name] = float(position)
    return state


def _group_joints(name: str, srdf, joints: dict, model: ModelFile) -> set[str]:
    """The joints of SRDF group `name` (every joint when the name is empty), as MoveIt takes a group: its joints,
    each chain's joints from base to tip, each link's parent joint, and its subgroups'."""
    if not name:
        return set(joints)
    if not srdf:
        raise UserError(f"group '{name}' needs the SRDF that defines it (--srdf)", "INVALID_GROUP_NAME")
    groups = read_srdf_groups(Path(srdf))
    parent_joint = {j.child: j for j in joints.values()}
    found: set[str] = set()

    def add(group_name: str, seen: tuple) -> None:
        if group_name not in groups:
            known = ", ".join(sorted(groups)) or "none"
            raise UserError(f"no group '{group_name}' in {Path(srdf).name} (groups: {known})", "INVALID_GROUP_NAME")
        if group_name in seen:
            raise UserError(f"{Path(srdf).name}: group '{group_name}' contains itself", "INVALID_GROUP_NAME")
        group = groups[group_name]
        for joint in group.joints:
            if joint not in joints:
                raise UserError(f"group '{group_name}': no joint '{joint}' in {model.path.name}", "INVALID_GROUP_NAME")
            found.add(joint)
        for link in group.links:
            if link in parent_joint:
                found.add(parent_joint[link].name)
        for base, tip in group.chains:
            link = tip
            while link != base:
                if link not in parent_joint:
                    raise UserError(
                        f"group '{group_name}': no chain from '{base}' to '{tip}' in {model.path.name}",
                        "INVALID_GROUP_NAME",
                    )
                found.add(parent_joint[link].name)
                link = parent_joint[link].parent
        for sub in group.subgroups:
            add(sub, (*seen, group_name))

    add(name, ())
    return found


class _Frames:
    """The poses of the frames a MoveIt file may name, in the planning frame (the robot's root link, at the world's
    origin): see the module's docstring."""

    def __init__(self, model: ModelFile, joints: dict, srdf, planning: PlanningScene):
        from pydrake.math import RigidTransform, RollPitchYaw

        children = {j.child for j in joints.values()}
        roots = sorted((model.links or set()) - children)
        self.root = roots[0] if len(roots) == 1 else ""
        self.known = {self.root: RigidTransform(), "": RigidTransform()}
        for frame in read_srdf_fixed_frames(Path(srdf)) if srdf else []:
            self.known[frame] = RigidTransform()
        # Links fixed to the root through fixed joints only: their pose is the same in every configuration.
        parent_joint = {j.child: j for j in joints.values()}
        for link in model.links or ():
            X, at = RigidTransform(), link
            while at in parent_joint and parent_joint[at].kind == "fixed":
                j = parent_joint[at]
                X = RigidTransform(RollPitchYaw(j.rpy), j.xyz).multiply(X)
                at = j.parent
            if at == self.root:
                self.known[link] = X
        for stamped in planning.fixed_frame_transforms:
            parent = self.pose(stamped.header.frame_id, "a fixed frame transform")
            t = stamped.transform
            self.known[stamped.child_frame_id] = parent.multiply(rigid_transform(t.translation, t.rotation))

    def pose(self, frame: str, what: str):
        if frame not in self.known:
            fixed = sorted(name for name in self.known if name)
            raise UserError(
                f"{what} is in frame '{frame}', which is neither the planning frame nor fixed to it "
                f"(known: {', '.join(fixed[:8])}{' ...' if len(fixed) > 8 else ''})",
                "FRAME_TRANSFORM_FAILURE",
            )
        return self.known[frame]


def rigid_transform(p: Vector3, q: Quaternion):
    """A message's position and orientation as a RigidTransform (one UserError if they are not numbers)."""
    from pydrake.common.eigen_geometry import Quaternion as DrakeQuaternion
    from pydrake.math import RigidTransform, RotationMatrix

    wxyz = _unit_quaternion(q)
    xyz = np.array([p.x, p.y, p.z], float)
    if not np.all(np.isfinite(xyz)):
        raise UserError(f"a position must be finite numbers, got {xyz.tolist()}")
    return RigidTransform(RotationMatrix(DrakeQuaternion(wxyz)), xyz)


def _unit_quaternion(q: Quaternion) -> np.ndarray:
    """(w, x, y, z) normalised; all zeros is the identity, as MoveIt reads it."""
    wxyz = np.array([q.w, q.x, q.y, q.z], float)
    norm = float(np.linalg.norm(wxyz))
    if not math.isfinite(norm):
        raise UserError(f"a quaternion must be finite numbers, got {wxyz.tolist()}")
    return np.array([1.0, 0.0, 0.0, 0.0]) if norm == 0 else wxyz / norm


def _world_file(
    planning: PlanningScene, frames: _Frames, model: ModelFile, cache_dir, stem: str
) -> tuple[Path | None, set]:
    """The scene's collision objects as one static SDF model in the cache, one link per object (None without any),
    and the objects' names."""
    links, seen = [], set()
    for k, obj in enumerate(planning.world.collision_objects):
        name = obj.id
        what = f"collision object '{name}'" if name else f"collision object {k + 1}"
        if not name or "::" in name or name != name.strip():
            raise UserError(f"{what} needs an id (a name without '::' or surrounding spaces)", "INVALID_OBJECT_NAME")
        if name in seen or name in (model.links or ()):
            other = "another object" if name in seen else "a robot link"
            raise UserError(f"{what}: {other} has the same name", "INVALID_OBJECT_NAME")
        seen.add(name)
        if obj.operation not in (ADD, APPEND):  # a full scene's objects are added
            raise UserError(f"{what}: operation {obj.operation} (REMOVE or MOVE) has no place in a full scene")
        if obj.meshes or obj.planes:
            kind = "meshes" if obj.meshes else "planes"
            raise UserError(f"{what}: {kind} are not supported (give it as primitives: box, sphere, cylinder)")
        if len(obj.primitive_poses) != len(obj.primitives):
            raise UserError(f"{what}: {len(obj.primitives)} primitives but {len(obj.primitive_poses)} primitive poses")
        X_WO = frames.pose(obj.header.frame_id, what).multiply(rigid_transform(obj.pose.position, obj.pose.orientation))
        shapes = [
            _collision(f"{name}_{i}", shape, X_WO.multiply(rigid_transform(pose.position, pose.orientation)), what)
            for i, (shape, pose) in enumerate(zip(obj.primitives, obj.primitive_poses))
        ]
        links.append(f"    <link name={quoteattr(name)}>\n{''.join(shapes)}    </link>\n")
    if not links:
        return None, seen
    text = (
        '<?xml version="1.0"?>\n<sdf version="1.9">\n  <model name="moveit_world">\n    <static>true</static>\n'
        + "".join(links)
        + "  </model>\n</sdf>\n"
    )
    root = Path(cache_dir).absolute() if cache_dir else cache_root()
    # Named after the scene file (so is the scene: "ur3_on_cart-in-shelf"), in a folder named by its content.
    path = root / "moveit" / hashlib.sha256(text.encode()).hexdigest()[:16] / f"{stem}.sdf"
    write_if_changed(path, text)
    return path, seen


def _collision(name: str, shape: SolidPrimitive, X, what: str) -> str:
    """One primitive as an SDF <collision> and <visual> at pose X (a cylinder's axis along z, as in MoveIt)."""
    kinds = {number: (kind, count) for kind, (number, count) in PRIMITIVES.items()}
    if shape.type not in kinds:
        raise UserError(f"{what}: unknown primitive type {shape.type} (1 BOX, 2 SPHERE, 3 CYLINDER)")
    kind, count = kinds[shape.type]
    d = np.asarray(shape.dimensions, float)
    if kind == "CONE":
        raise UserError(f"{what}: cones are not supported (give it as a cylinder or boxes)")
    if d.shape != (count,) or not np.all(np.isfinite(d) & (d > 0)):
        raise UserError(f"{what}: a {kind.lower()} needs {count} positive dimension(s), got {shape.dimensions}")
    d = d.tolist()  # (plain floats: their repr is the number)
    if kind == "BOX":
        geometry = f"<box><size>{d[0]!r} {d[1]!r} {d[2]!r}</size></box>"
    elif kind == "SPHERE":
        geometry = f"<sphere><radius>{d[0]!r}</radius></sphere>"
    else:
        geometry = f"<cylinder><radius>{d[1]!r}</radius><length>{d[0]!r}</length></cylinder>"
    rpy = X.rotation().ToRollPitchYaw().vector()
    pose = " ".join(repr(float(v)) for v in [*X.translation(), *rpy])
    return "".join(
        f"      <{element} name={quoteattr(f'{name}_{element}')}><pose>{pose}</pose>"
        f"<geometry>{geometry}</geometry></{element}>\n"
        for element in ("collision", "visual")
    )


def _allowed(acm: AllowedCollisionMatrix, links, objects: set, scene: str | None) -> list[list[str]]:
    """The pairs the allowed-collision matrix allows (entries between known names only: a MoveIt dump names every
    link, and objects the world may not hold), each once."""
    names = acm.entry_names
    if len(acm.entry_values) != len(names) or any(len(row.enabled) != len(names) for row in acm.entry_values):
        raise UserError(f"{scene}: allowed_collision_matrix needs one entry of {len(names)} values per entry name")
    if len(acm.default_entry_values) != len(acm.default_entry_names):
        raise UserError(f"{scene}: allowed_collision_matrix: default_entry_names and _values differ in length")
    known = set(links or ()) | objects
    pairs = {
        tuple(sorted((a, b)))
        for i, a in enumerate(names)
        for j, b in enumerate(names)
        if acm.entry_values[i].enabled[j] and a != b and a in known and b in known
    }
    for name, allowed in zip(acm.default_entry_names, acm.default_entry_values):
        if allowed and name in known:
            pairs |= {tuple(sorted((name, other))) for other in known if other != name}
    # Two objects never collide with each other here (static bodies), and filtering their pair would be refused.
    return [list(pair) for pair in sorted(pairs) if not set(pair) <= objects]


def _goals(
    asked: MotionPlanRequest,
    coordinates: list[str],
    start: dict[str, float],
    hold: dict[str, float],
    frames: _Frames,
    request: str,
) -> tuple[np.ndarray, list[PoseGoal]]:
    """The request's goal constraints: one joint goal or one pose goal each."""
    if not asked.goal_constraints:
        raise UserError(f"{request}: no goal_constraints", "INVALID_GOAL_CONSTRAINTS")
    joint_goals, pose_goals = [], []
    for k, c in enumerate(asked.goal_constraints):
        what = f"{request}: goal {k + 1}"
        if c.visibility_constraints:
            raise UserError(f"{what}: visibility constraints are not supported", "INVALID_GOAL_CONSTRAINTS")
        if c.joint_constraints and (c.position_constraints or c.orientation_constraints):
            raise UserError(
                f"{what}: joint constraints with link constraints are not supported (give one kind)",
                "INVALID_GOAL_CONSTRAINTS",
            )
        if c.joint_constraints:
            joint_goals.append(_joint_goal(c.joint_constraints, coordinates, start, hold, what))
        else:
            pose_goals.append(_pose_goal(c, frames, what))
    return np.array(joint_goals).reshape(-1, len(coordinates)), pose_goals


def _joint_goal(constraints, coordinates: list[str], start: dict, hold: dict, what: str) -> np.ndarray:
    """The goal configuration: the constrained joints at their positions, the group's other joints at the start."""
    goal = dict(start)
    for c in constraints:
        if not math.isfinite(c.position):
            raise UserError(f"{what}: joint '{c.joint_name}' position is {c.position}", "INVALID_GOAL_CONSTRAINTS")
        if c.joint_name in hold:
            if not -c.tolerance_below - 1e-9 <= c.position - hold[c.joint_name] <= c.tolerance_above + 1e-9:
                raise UserError(
                    f"{what}: joint '{c.joint_name}' is not in the group, and stays at {hold[c.joint_name]:g}",
                    "INVALID_GOAL_CONSTRAINTS",
                )
            continue
        if c.joint_name not in goal:
            raise UserError(f"{what}: no movable joint '{c.joint_name}'", "INVALID_GOAL_CONSTRAINTS")
        goal[c.joint_name] = float(c.position)
    return np.array([goal[name] for name in coordinates])


def _pose_goal(c: Constraints, frames: _Frames, what: str) -> PoseGoal:
    """A position and an orientation constraint on one link, as the link's goal pose (the target point offset taken
    back to the link's origin) and tolerances: the region's sphere radius or smallest half box side, and the smallest
    axis tolerance."""
    if len(c.position_constraints) != 1 or len(c.orientation_constraints) != 1:
        raise UserError(
            f"{what}: a goal needs joint constraints, or one position and one orientation constraint on a link",
            "INVALID_GOAL_CONSTRAINTS",
        )
    position, orientation = c.position_constraints[0], c.orientation_constraints[0]
    if position.link_name != orientation.link_name or not position.link_name:
        raise UserError(
            f"{what}: the position and orientation constraints must name one link "
            f"('{position.link_name}', '{orientation.link_name}')",
            "INVALID_LINK_NAME",
        )
    region = position.constraint_region
    if len(region.primitives) != 1 or len(region.primitive_poses) != 1 or region.meshes:
        raise UserError(f"{what}: the position constraint's region must be one primitive", "INVALID_GOAL_CONSTRAINTS")
    shape, d = region.primitives[0], np.asarray(region.primitives[0].dimensions, float)
    if shape.type == PRIMITIVES["SPHERE"][0] and d.shape == (1,):
        tolerance = float(d[0])
    elif shape.type == PRIMITIVES["BOX"][0] and d.shape == (3,):
        tolerance = float(d.min()) / 2
    else:
        raise UserError(f"{what}: the position region must be a sphere or a box", "INVALID_GOAL_CONSTRAINTS")
    region_pose = region.primitive_poses[0]
    X_WF = frames.pose(position.header.frame_id, f"{what}'s position constraint")
    p_W = X_WF.multiply(rigid_transform(region_pose.position, Quaternion())).translation()
    R_W = (
        frames.pose(orientation.header.frame_id, f"{what}'s orientation constraint")
        .rotation()
        .multiply(rigid_transform(Vector3(), orientation.orientation).rotation())
    )
    offset = np.array([position.target_point_offset.x, position.target_point_offset.y, position.target_point_offset.z])
    angles = [orientation.absolute_x_axis_tolerance, orientation.absolute_y_axis_tolerance]
    angles.append(orientation.absolute_z_axis_tolerance)
    if not (math.isfinite(tolerance) and all(map(math.isfinite, angles)) and np.all(np.isfinite(offset))):
        raise UserError(f"{what}: tolerances and offsets must be finite numbers", "INVALID_GOAL_CONSTRAINTS")
    return PoseGoal(
        link=position.link_name,
        xyz=p_W - R_W.matrix() @ offset,
        wxyz=R_W.ToQuaternion().wxyz(),
        position_tolerance=max(tolerance, MIN_POSITION_TOLERANCE),
        angle_tolerance=max(min(angles), MIN_ANGLE_TOLERANCE),
    )


def _scaling(factor: float, kind: str) -> float:
    """A scaling factor as MoveIt takes it: 0 (not set) is 1; outside (0, 1] is 1 too, with a warning."""
    if factor == 0:
        return 1.0
    if not 0 < factor <= 1:
        warnings.warn(
            f"max_{kind}_scaling_factor {factor:g} is not in (0, 1]: 1 is used, as MoveIt does",
            PlannerWarning,
            stacklevel=2,
        )
        return 1.0
    return float(factor)


def _planning_time(seconds: float, request: str) -> float | None:
    if seconds == 0:
        return None
    if not 0 < seconds < math.inf:
        raise UserError(f"{request}: allowed_planning_time must be a positive number of seconds, got {seconds:g}")
    return float(seconds)
