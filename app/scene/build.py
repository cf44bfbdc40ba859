"""Stage (d): the Drake diagram, as Drake's RobotDiagramBuilder makes it from model directives.

A scene's diagram (`build_diagram`): the models the directives name, the robot's model instances, and on the
SceneGraph model itself, so that every context, the collision checker (which copies the model's filters when made)
and the certificate's pair list see the same pairs, the collision filters: adjacent links (across links without
collision geometry too, as MoveIt has them) and an SRDF's pairs. Then what the stages after read of it as plain
data: each position's joint and limits (`joint_table`), whether the robot is one body.

For a custom scene also the robot alone (`measure_robot`): its coordinates, limits and size, which set the
edge-check step and so the environment's mesh tolerance; and how often its mesh links' hulls collide where their
pieces do not (`hull_disagreement`).
"""

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from app.errors import UserError
from app.scene.cspace import PositionMap
from app.scene.drake_parser import (
    add_packages,
    builder_with_packages,
    model_loading,
    parser_error,
    robot_diagram_builder,
)
from app.scene.emit import write_if_changed
from app.scene.files import MAX_MODEL_NUMBER
from app.scene.spec import mimic_limited

# pydrake is imported inside the functions that use it, so that importing the package does not load Drake.


def add_directives(parser, path: Path, packages: dict[str, Path], label: str) -> None:
    """The models of the directives file `path` (named `label` in messages) added through `parser`, whose package
    map gets `packages` first."""
    from pydrake.multibody.parsing import LoadModelDirectives, ProcessModelDirectives

    add_packages(parser, packages)
    try:
        with model_loading():
            ProcessModelDirectives(LoadModelDirectives(str(path)), parser)
    except Exception as exc:
        raise UserError(f"cannot load {label}: {' '.join(str(exc).split())[:300]}") from None


@dataclass
class BuiltDiagram:
    """A scene's Drake diagram and what was decided building it."""

    diagram: object  # pydrake's RobotDiagram
    plant: object  # its MultibodyPlant
    robot_instances: list  # the model instances that move
    adjacent_pairs: list[tuple[str, str]]  # body pairs left out beyond Drake's own (exclude_adjacent_bodies)
    robot_links: dict[str, str]  # the robot's bodies by scoped name ("robot::forearm") -> link name


def build_diagram(
    add_models, robot: list[str], srdf_pairs: list, srdf: str, bad: str, allowed: list[list[str]] = ()
) -> BuiltDiagram:
    """The diagram of the models `add_models(parser)` adds, whose instances named `robot` move; adjacent links,
    the SRDF's `srdf_pairs` (read from `srdf`, for messages) and the `allowed` body pairs (robot or environment
    bodies) filtered. `bad` starts a message about the scene."""
    builder = robot_diagram_builder()
    plant = builder.plant()
    add_models(builder.parser())
    for name in robot:
        if not plant.HasModelInstanceNamed(name):
            raise UserError(f"{bad}: no model instance named '{name}'")
    instances = [plant.GetModelInstanceByName(n) for n in robot]
    plant.Finalize()
    adjacent = exclude_adjacent_bodies(plant, builder.scene_graph(), instances)
    exclude_body_pairs(plant, builder.scene_graph(), instances, srdf_pairs, srdf)
    exclude_allowed_pairs(plant, builder.scene_graph(), allowed, bad)
    diagram = builder.Build()
    plant = diagram.plant()
    links = {
        body.scoped_name().to_string(): body.name()
        for instance in instances
        for body in map(plant.get_body, plant.GetBodyIndices(instance))
    }
    return BuiltDiagram(diagram, plant, instances, adjacent, links)


def joint_table(plant) -> dict:
    """Per plant position: its name (a joint's, with [k] for a joint of several), whether it is an angle, its
    limits; and the velocity limits."""
    from pydrake.multibody.tree import JointIndex

    positions = plant.num_positions()
    names, angular = [""] * positions, np.zeros(positions, bool)
    for i in range(plant.num_joints()):
        joint = plant.get_joint(JointIndex(i))
        for k in range(joint.num_positions()):
            index = joint.position_start() + k
            names[index] = joint.name() if joint.num_positions() == 1 else f"{joint.name()}[{k}]"
            angular[index] = joint.type_name() == "revolute"
    return {
        "names": names,
        "angular": angular,
        "lower": plant.GetPositionLowerLimits(),
        "upper": plant.GetPositionUpperLimits(),
        "velocity": plant.GetVelocityUpperLimits(),
    }


def robot_is_one_body(plant, instances) -> bool:
    """A robot that is one rigid body (an OMPL.app problem's) has nothing to collide with itself."""
    with_geometry = sum(
        bool(plant.GetCollisionGeometriesForBody(plant.get_body(b)))
        for instance in instances
        for b in plant.GetBodyIndices(instance)
    )
    return with_geometry <= 1


# ---- collision filters --------------------------------------------------------------------------------------------
def exclude_body_pairs(plant, scene_graph, instances, pairs: list[tuple[str, str]], srdf) -> None:
    """Exclude collisions between the geometries of each named body pair of the robot `instances` on the
    SceneGraph model (before contexts are made). Names no robot body carries -> one UserError naming them all."""

    def body(name):
        found = [plant.GetBodyByName(name, i) for i in instances if plant.HasBodyNamed(name, i)]
        return found[0] if found else None

    unknown = sorted({name for pair in pairs for name in pair if body(name) is None})
    if unknown:
        raise UserError(f"SRDF {Path(srdf).name}: unknown link(s) {', '.join(unknown)} (not bodies of the robot)")
    _exclude_between(plant, scene_graph, [(body(a), body(b)) for a, b in pairs])


def exclude_allowed_pairs(plant, scene_graph, pairs: list[list[str]], bad: str) -> None:
    """Exclude collisions between each pair of bodies named in `pairs`, each name that of one body of any model
    (a robot link, a link of an environment SDF); a name no body or several carry -> one UserError."""
    from pydrake.multibody.tree import BodyIndex

    bodies: dict[str, list] = {}
    for i in range(plant.num_bodies()):
        body = plant.get_body(BodyIndex(i))
        bodies.setdefault(body.name(), []).append(body)
    for pair in pairs:
        if len(pair) != 2:
            raise UserError(f"{bad}: an allowed collision names two bodies, got {list(pair)}")
        for name in pair:
            if len(bodies.get(name, [])) != 1:
                how = "no body has" if name not in bodies else "several bodies have"
                raise UserError(f"{bad}: allowed collision {pair[0]} - {pair[1]}: {how} the name '{name}'")
    _exclude_between(plant, scene_graph, [(bodies[a][0], bodies[b][0]) for a, b in pairs])


def _exclude_between(plant, scene_graph, bodies: list) -> None:
    """Exclude collisions between the geometries of each pair of bodies, on the SceneGraph model."""
    from pydrake.geometry import CollisionFilterDeclaration, GeometrySet

    declaration = CollisionFilterDeclaration()
    for a, b in bodies:
        declaration.ExcludeBetween(
            GeometrySet(plant.GetCollisionGeometriesForBody(a)), GeometrySet(plant.GetCollisionGeometriesForBody(b))
        )
    scene_graph.collision_filter_manager().Apply(declaration)


def adjacent_bodies(plant, instances) -> list[tuple]:
    """The robot's adjacent body pairs as MoveIt's Setup Assistant finds them ("Adjacent" in the SRDF it writes):
    bodies with collision geometry that a joint joins, directly or across bodies without collision geometry (a
    virtual link, a flange frame), which are left out of the chain: the bodies next to such a body, before and
    after it, are all adjacent to one another. Only the robot `instances`' own bodies and joints count (the world
    is none of them)."""
    robot = {body.index() for instance in instances for body in map(plant.get_body, plant.GetBodyIndices(instance))}
    neighbours = {index: set() for index in robot}
    for joint in map(plant.get_joint, plant.GetJointIndices()):
        a, b = joint.parent_body().index(), joint.child_body().index()
        if a in robot and b in robot and a != b:
            neighbours[a].add(b)
            neighbours[b].add(a)
    for index in sorted(robot):
        if plant.GetCollisionGeometriesForBody(plant.get_body(index)):
            continue
        around = neighbours.pop(index)
        for other in around:
            neighbours[other] |= around - {other}
            neighbours[other].discard(index)
    pairs = {tuple(sorted((a, b))) for a, near in neighbours.items() for b in near}
    return [(plant.get_body(a), plant.get_body(b)) for a, b in sorted(pairs)]


def exclude_adjacent_bodies(plant, scene_graph, instances) -> list[tuple[str, str]]:
    """Exclude collisions between the robot's adjacent bodies (`adjacent_bodies`) on the SceneGraph model, as MoveIt
    never checks them: two links that meet at a joint touch there by design, whether or not a link without geometry
    sits between them. Drake itself leaves out only a joint's parent and child and bodies welded together. Returns
    the (name, name) pairs this adds to Drake's (usually none: they need a body without geometry between two)."""
    inspector = scene_graph.model_inspector()
    added = []
    for a, b in adjacent_bodies(plant, instances):
        ours, theirs = plant.GetCollisionGeometriesForBody(a), plant.GetCollisionGeometriesForBody(b)
        if not all(inspector.CollisionFiltered(g, h) for g in ours for h in theirs):
            added.append((a, b))
    _exclude_between(plant, scene_graph, added)
    return [(a.name(), b.name()) for a, b in added]


# ---- the robot alone ----------------------------------------------------------------------------------------------
@dataclass
class RobotMeasure:
    """The robot alone as Drake loads it: its planned coordinates (names, joint types, position and velocity
    limits; a mimicked joint's kept so that its mimic joints stay within theirs), its size, and its mimic joints."""

    names: list[str]
    kinds: list[str]
    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    reach: float  # the largest distance of its collision geometry from its first body's origin (a lever arm)
    thin: float  # the median over its bodies of their smallest width
    mimic: list[dict]

    def default_resolution(self) -> float:
        """The edge-check step: a quarter of the robot's thickness (median over its bodies of their smallest width),
        so a step cannot carry it across a wall as thick as itself; at least 1/1000 of its reach."""
        return max(0.25 * self.thin, 1e-3 * max(self.reach, 1e-6))


def measure_robot(
    directives: Path,
    packages: dict[str, Path],
    instances: list[str],
    mimics: list[dict],
    robot_file: Path,
    held: dict[str, float],
) -> RobotMeasure:
    """Load the robot part of the directives: coordinate names, limits, and the robot's size (for weights). A
    joint in `mimics` is no coordinate; the limits of the one it follows keep it within its own. A `held` joint is
    none either. Messages name `robot_file` (the user's), not the generated directives."""
    from pydrake.multibody.parsing import LoadModelDirectives, ProcessModelDirectives

    builder = builder_with_packages(packages)
    plant = builder.plant()
    try:
        ProcessModelDirectives(LoadModelDirectives(str(directives)), builder.parser())
        plant.Finalize()
    except Exception as exc:
        raise parser_error(exc, robot_file) from None
    names, kinds = _position_joints(plant)
    if plant.GetFloatingBaseBodies():
        raise UserError(
            "the robot still has a free-floating body after welding its root; connect its parts with joints"
        )
    bad = sorted({k for k in kinds if k not in ("revolute", "prismatic")})
    if bad:
        raise UserError(f"robot joints of type {', '.join(bad)} are not supported (revolute and prismatic only)")
    reach, thin = _robot_size(builder, plant, instances)
    lower, upper, velocity = _checked_limits(plant, names, robot_file)
    try:
        mimic = PositionMap.of(names, [(m["joint"], m["follows"], m["multiplier"], m["offset"]) for m in mimics], held)
    except UserError as exc:
        raise UserError(f"{robot_file.name}: {exc}") from None
    if mimic is not None:
        kinds = [kinds[i] for i in mimic.planned]
        velocity = np.minimum(velocity[mimic.planned], mimic.coordinate_speeds(velocity))
        names, lower, upper = mimic_limited(mimic, names, lower, upper, robot_file)
    return RobotMeasure(names, kinds, lower, upper, velocity, reach, thin, mimics)


def _position_joints(plant) -> tuple[list[str], list[str]]:
    """Per plant position: its joint's name and type."""
    from pydrake.multibody.tree import JointIndex

    nq = plant.num_positions()
    names, kinds = [""] * nq, [""] * nq
    for i in range(plant.num_joints()):
        joint = plant.get_joint(JointIndex(i))
        for k in range(joint.num_positions()):
            names[joint.position_start() + k] = joint.name()
            kinds[joint.position_start() + k] = joint.type_name()
    return names, kinds


def _robot_size(builder, plant, instances: list[str]) -> tuple[float, float]:
    """From the robot's collision geometry (oriented boxes) at the default configuration: `reach`, the largest
    distance of any of it from the robot's first body's origin (an angle's lever arm), and `thin`, the median over
    bodies of the smallest width of all of a body's geometry together (how far a step may move the robot without
    skipping a thin wall). Per body, not per geometry: a body made of thin pieces (a mesh split into face plates)
    is as thick as the whole, and the edge-check step must not follow the plates' thickness."""
    inspector = builder.scene_graph().model_inspector()
    context = plant.CreateDefaultContext()
    bodies = [plant.get_body(b) for inst in instances for b in plant.GetBodyIndices(plant.GetModelInstanceByName(inst))]
    root = bodies[0].EvalPoseInWorld(context).translation()
    corners, widths = [], []
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    for body in bodies:
        X_WB = body.EvalPoseInWorld(context)
        body_corners = []
        for geometry in plant.GetCollisionGeometriesForBody(body):
            obb = inspector.GetObbInGeometryFrame(geometry)
            if obb is None:
                continue
            X_WO = X_WB @ inspector.GetPoseInFrame(geometry) @ obb.pose()
            local = signs * obb.half_width()
            body_corners.append((X_WO.rotation().matrix() @ local.T).T + X_WO.translation())
        if body_corners:
            corners += body_corners
            widths.append(_smallest_width(np.vstack(body_corners)))
    if not corners:
        raise UserError("the robot has no collision geometry")
    return float(np.max(np.linalg.norm(np.vstack(corners) - root, axis=1))), float(np.median(widths))


def _smallest_width(points: np.ndarray) -> float:
    """The smallest extent of a point set along its principal axes (a box fitted to it)."""
    centred = points - points.mean(axis=0)
    axes = np.linalg.svd(centred, full_matrices=False)[2]
    extents = np.ptp(centred @ axes.T, axis=0)
    return float(extents.min()) if len(extents) == 3 else 0.0


def _checked_limits(plant, names: list[str], robot_file: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The plant's position and velocity limits, each within MAX_MODEL_NUMBER (app.scene.model_files has refused a
    URDF's; an SDF's are first seen here)."""
    lower, upper, velocity = (
        plant.GetPositionLowerLimits(),
        plant.GetPositionUpperLimits(),
        plant.GetVelocityUpperLimits(),
    )
    for what, values in (("lower limit", lower), ("upper limit", upper), ("velocity limit", velocity)):
        huge = np.isfinite(values) & (np.abs(values) > MAX_MODEL_NUMBER)
        if huge.any():
            i = int(np.flatnonzero(huge)[0])
            raise UserError(
                f"{robot_file.name}: joint '{names[i]}': {what} {values[i]:g} is out of range (limits must be within "
                f"+-{MAX_MODEL_NUMBER:g} m or rad)"
            )
    return lower, upper, velocity


def hull_disagreement(
    scene_dir: Path,
    pieces_file: Path,
    hull_file: Path,
    packages: dict[str, Path],
    srdf: tuple[Path | None, list],
    robot_instances: list[str],
    samples=300,
) -> dict:
    """How often the robot alone collides with itself at uniform random configurations (seeded), with its mesh links
    as Drake's convex hulls (robot-hulls.dmd.yaml) and as the validated pieces (robot.dmd.yaml), adjacent links and
    the SRDF's pairs (`srdf`: its path and pairs) left out in both, as the scene leaves them out: `hull_only` is the
    fraction that collide as hulls but not as pieces, what the decomposition saves self-collision checking from."""
    srdf_path, pairs = srdf
    exact = scene_dir / "robot.dmd.yaml"
    hulls = scene_dir / "robot-hulls.dmd.yaml"
    # Kept beside the scene, keyed by what decides it (the pieces' and hulls' cache files are named by content): a
    # cached load should not spend two robot set-ups and 600 checks on it again. (The last item: measured with the
    # adjacent links across links without geometry left out, which earlier measurements counted.)
    key = hashlib.sha256(
        repr((exact.read_text(), str(pieces_file), str(hull_file), pairs, samples, "adjacent")).encode()
    )
    kept = scene_dir / f"hull-disagreement-{key.hexdigest()[:16]}.json"
    if kept.is_file():
        return json.loads(kept.read_text())
    rng = np.random.default_rng(0)
    collide, Q = [], None
    for directives in (hulls, exact):
        hits, Q = _self_collisions(directives, packages, robot_instances, (srdf_path, pairs), rng, Q, samples)
        collide.append(hits)
    found = {
        "samples": samples,
        "hull_self_collision": float(collide[0].mean()),
        "pieces_self_collision": float(collide[1].mean()),
        "hull_only": float((collide[0] & ~collide[1]).mean()),
    }
    write_if_changed(kept, json.dumps(found) + "\n")
    return found


def _self_collisions(directives: Path, packages, robot_instances, srdf, rng, Q, samples) -> tuple:
    """Whether the robot of `directives` collides at each configuration of Q (drawn first, within the joint limits
    or one turn, when Q is None), with adjacent links and the SRDF's pairs left out; and Q."""
    from pydrake.multibody.parsing import LoadModelDirectives, ProcessModelDirectives

    srdf_path, pairs = srdf
    builder = builder_with_packages(packages)
    plant = builder.plant()
    ProcessModelDirectives(LoadModelDirectives(str(directives)), builder.parser())
    plant.Finalize()
    instances = [plant.GetModelInstanceByName(n) for n in robot_instances]
    exclude_adjacent_bodies(plant, builder.scene_graph(), instances)
    exclude_body_pairs(plant, builder.scene_graph(), instances, pairs, srdf_path)
    diagram = builder.Build()
    root = diagram.CreateDefaultContext()
    context = diagram.plant().GetMyContextFromRoot(root)
    if Q is None:  # the same configurations for both, within the joint limits (none: one turn)
        lower, upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
        lower, upper = np.where(np.isfinite(lower), lower, -math.pi), np.where(np.isfinite(upper), upper, math.pi)
        Q = rng.uniform(lower, upper, (samples, plant.num_positions()))
    port = diagram.plant().get_geometry_query_input_port()
    hits = []
    for q in Q:
        diagram.plant().SetPositions(context, q)
        hits.append(port.Eval(context).HasCollisions())
    return np.array(hits), Q
