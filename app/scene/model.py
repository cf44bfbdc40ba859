"""A scene: Drake model directives (robot + obstacles) plus a problem file (bounds, start, goal, passage, metric).

The problem file is loaded with Drake's typed YAML loader, so an unknown or misspelt key is an error rather than a
silently ignored setting. Everything the rest of the pipeline needs about the robot's configuration space (which
coordinates are angles, which wrap, how to weigh them) is read here once.
"""

import collections
import contextlib
import dataclasses
import functools
import logging
import math
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.errors import UserError
from app.io import check_input
from app.scene.cspace import ConfigurationSpace, PositionMap

# pydrake is imported inside the functions that use it, so that importing the package (as the command line does)
# does not load Drake.

ROOT = Path(__file__).resolve().parents[2]
SCENES_DIR = ROOT / "scenes"
MIN_RESOLUTION = 1e-5  # the finest edge-check step, as a fraction of the weighted diagonal of the bounds
PACKAGES = {"npp_robots": ROOT / "robots", "npp_scenes": SCENES_DIR}


@dataclass
class Box:
    """An axis-aligned workspace box (world frame)."""

    lo: list[float] = field(default_factory=list)
    hi: list[float] = field(default_factory=list)


@dataclass
class PassageSpec:
    """A sample counts as "in the passage" when the origin of `frame` lies in one of `boxes`."""

    frame: str = ""
    boxes: list[Box] = field(default_factory=list)


@dataclass
class ToolPose:
    """A named pose of the scene's tool frame in the world: position (m) and roll-pitch-yaw (degrees, Drake's
    convention R = Rz(yaw) Ry(pitch) Rx(roll)). Goals of arm scenes are reached from these by inverse kinematics.
    `stop`: a job's robot comes to rest here (a weld point, a grasp); false: it passes through (an approach)."""

    name: str = ""
    xyz: list[float] = field(default_factory=list)
    rpy_deg: list[float] = field(default_factory=list)
    stop: bool = True


@dataclass
class Mimic:
    """A joint that follows another (URDF <mimic>): position = multiplier * the followed joint's + offset. It is no
    coordinate of the configuration space (see app.scene.cspace.PositionMap)."""

    joint: str = ""
    follows: str = ""
    multiplier: float = 1.0
    offset: float = 0.0


@dataclass
class ProblemFile:
    description: str = ""
    directives: str = ""  # a *.dmd.yaml file beside the problem file
    robot: list[str] = field(default_factory=list)  # model instances that move; everything else is environment
    # Which collisions count: "environment" (robot vs. obstacles) or "all" (also robot vs. itself).
    collisions: str = "environment"
    collisions_why: str = ""
    # An SRDF (MoveIt's format; a path relative to the problem file, or package://npp_robots/...) whose
    # <disable_collisions link1= link2=/> robot body pairs are never checked (adjacent links never are: see
    # exclude_adjacent_bodies).
    srdf: str = ""
    lower: list[float] = field(default_factory=list)  # default: the model's joint limits
    upper: list[float] = field(default_factory=list)
    start: list[float] = field(default_factory=list)
    goal: list[float] = field(default_factory=list)
    # Metric weight per coordinate, so that metres and radians compare (an angle's weight is the lever arm it swings).
    weights: list[float] = field(default_factory=list)
    resolution: float = 0.5  # edge-check step in the weighted metric
    step: float = 0.0  # default sampler step a for this scene (0: a tenth of its largest linear extent)
    passage: PassageSpec = field(default_factory=PassageSpec)
    velocity_limits: list[float] = field(default_factory=list)  # default: the model's
    acceleration_limits: list[float] = field(default_factory=list)  # default: 2x the velocity limits
    view: str = "2d"  # how `show` draws it: "2d" top view or "3d"
    tool_frame: str = ""  # the frame `poses` are poses of (arm scenes); required when poses are given
    poses: list[ToolPose] = field(default_factory=list)  # named tool poses, in file order (e.g. a weld seam)
    mimic: list[Mimic] = field(default_factory=list)  # joints that follow others: not planned coordinates


# Drake's URDF parser warns about each element it ignores, once per parse. These elements are ROS controller,
# calibration, transmission and friction settings a planner never reads (an xArm7 description drew 70 such warnings).
# A load says in one line per file what it ignored (each element once per process: a custom scene parses its robot
# several times) instead of a warning per element per parse. Each pattern names the element it is about.
HARMLESS_URDF_WARNINGS = (
    r"The tag '(safety_controller|calibration)' found as a child of '\w+' is currently unsupported and will be ignored",
    r"A joint has specified a non-zero value for the '(friction)' attribute of a joint/dynamics tag",
    r"A '\w+' element contains a (mechanicalReduction) element with a value",
    r"A <(transmission)> has a type that isn't 'SimpleTransmission'",
    r"A link has specified the '(group)' attribute on the <collision> tag",
    r"A joint has specified a value for the '(coulomb_window)' attribute",
)
_HARMLESS = re.compile(r"^(.*?):(\d+): warning: (?:" + "|".join(HARMLESS_URDF_WARNINGS) + ")")
_harmless_seen: set[tuple[str, str, str]] = set()  # (file name, line, element) already summarised
_harmless_new: dict[str, collections.Counter] | None = None  # per file name and element, while model_loading runs


def _drop_harmless(record: logging.LogRecord) -> bool:
    found = _HARMLESS.match(record.getMessage())
    if found is None or _harmless_new is None or found.group(1).startswith("<"):  # (a string parsed: no file)
        return True
    # By file name and line: the cached copies of a model (its mesh links rewritten, lines kept) are the same elements.
    name, line = Path(found.group(1)).name, found.group(2)
    element = next(g for g in found.groups()[2:] if g)
    if (name, line, element) not in _harmless_seen:
        _harmless_seen.add((name, line, element))
        _harmless_new.setdefault(name, collections.Counter())[element] += 1
    return False


@contextlib.contextmanager
def model_loading():
    """Drake's known-harmless URDF warnings (HARMLESS_URDF_WARNINGS) kept off stderr while models load, and
    summarised in one line per file at the end of the outermost block (nothing if every one was summarised before):
    `note: arm.urdf: Drake ignored 70 elements it does not use for planning (friction x35, mechanicalReduction x35)`.
    """
    global _harmless_new
    if _harmless_new is not None:  # an enclosing block summarises
        yield
        return
    logger = logging.getLogger("drake")
    _harmless_new = {}
    logger.addFilter(_drop_harmless)
    try:
        yield
    finally:
        logger.removeFilter(_drop_harmless)
        found, _harmless_new = _harmless_new, None
        for name, counts in found.items():
            parts = ", ".join(f"{element} x{count}" for element, count in sorted(counts.items()))
            total = sum(counts.values())
            print(
                f"note: {name}: Drake ignored {total} element{'s' if total > 1 else ''} it does not use for planning "
                f"({parts})",
                file=sys.stderr,
            )


def robot_diagram_builder():
    """Drake's RobotDiagramBuilder; Drake's refusal to start (e.g. DRAKE_ALLOW_NETWORK forbids fetching the
    drake_models package it registers in every parser) becomes one line for the user."""
    from pydrake.planning import RobotDiagramBuilder

    try:
        return RobotDiagramBuilder(time_step=0.0)
    except RuntimeError as exc:
        reason = " ".join(str(exc).split())
        if "DRAKE_ALLOW_NETWORK" in reason:  # Drake registers drake_models in every parser, used or not
            reason += (
                " (unset DRAKE_ALLOW_NETWORK or add package_map to it: no file of that package is used, so nothing"
                " is fetched)"
            )
        raise UserError(f"Drake cannot start its model parser: {reason}") from None


def scene_names() -> list[str]:
    return sorted(p.stem for p in SCENES_DIR.glob("*.yaml") if not p.name.endswith(".dmd.yaml"))


def scene_path(name_or_path: str) -> Path:
    """A shipped scene's name, or the path of a problem file."""
    candidate = Path(name_or_path)
    if candidate.suffix == ".yaml":
        return check_input(candidate, "scene file").resolve()
    path = SCENES_DIR / f"{name_or_path}.yaml"
    if not path.is_file():
        raise UserError(f"unknown scene '{name_or_path}' (known: {', '.join(scene_names())})")
    return path


def read_problem(path: Path) -> ProblemFile:
    from pydrake.common.yaml import yaml_load_typed

    check_input(path, "scene file")
    try:
        problem = yaml_load_typed(schema=ProblemFile, filename=str(path))
    except Exception as exc:  # the loader raises RuntimeError, ValueError or yaml errors; all mean a bad file
        detail = " ".join(str(exc).split())
        raise UserError(f"bad scene file {path.name}: {detail[:300]}") from None
    if problem.collisions not in ("environment", "all"):
        raise UserError(f"bad scene file {path.name}: collisions must be 'environment' or 'all'")
    if problem.view not in ("2d", "3d"):
        raise UserError(f"bad scene file {path.name}: view must be '2d' or '3d'")
    if not problem.directives or not problem.robot:
        raise UserError(f"bad scene file {path.name}: 'directives' and 'robot' are required")
    return problem


def xml_root(path: Path, failure: str):
    """The root element of an XML file (a URDF, an SRDF), or one line: `failure`, the file's name and the error."""
    import xml.etree.ElementTree as ET

    try:
        return ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise UserError(f"{failure} {path.name}: {exc}") from None


def read_srdf(path: Path) -> list[tuple[str, str]]:
    """The (link1, link2) pairs of an SRDF's <disable_collisions> elements."""
    check_input(path, "SRDF file")
    root = xml_root(path, "bad SRDF")
    pairs = []
    for element in root.iter("disable_collisions"):
        a, b = element.get("link1"), element.get("link2")
        if not a or not b:
            raise UserError(f"bad SRDF {path.name}: <disable_collisions> needs link1 and link2")
        pairs.append((a, b))
    return pairs


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


class Scene:
    """A loaded scene: the Drake RobotDiagram and the configuration-space facts read from it and the problem file."""

    def __init__(self, name_or_path: str):
        from pydrake.multibody.tree import JointIndex

        self.path = scene_path(name_or_path)
        self.name = self.path.stem
        # How another process loads this very scene (a roadmap built on several processes): picklable, no Drake.
        self.recipe = functools.partial(Scene, str(self.path))
        self.problem = problem = read_problem(self.path)

        builder = robot_diagram_builder()
        plant = builder.plant()
        self.add_models(builder.parser())
        for name in problem.robot:
            if not plant.HasModelInstanceNamed(name):
                raise UserError(f"bad scene file {self.path.name}: no model instance named '{name}'")
        self.robot_instances = [plant.GetModelInstanceByName(n) for n in problem.robot]
        plant.Finalize()
        # On the SceneGraph model itself, so every context, the collision checker (which copies the model's filters
        # when made) and the certificate's pair list all see the same pairs: adjacent links (across links without
        # collision geometry too, as MoveIt has them) and the SRDF's pairs.
        self.adjacent_pairs = exclude_adjacent_bodies(plant, builder.scene_graph(), self.robot_instances)
        self.disabled_pairs = read_srdf(self._file(problem.srdf)) if problem.srdf else []
        exclude_body_pairs(plant, builder.scene_graph(), self.robot_instances, self.disabled_pairs, problem.srdf)
        self.diagram = builder.Build()
        self.plant = self.diagram.plant()
        # The robot's bodies by the scoped name messages give them ("robot::forearm") -> the link name an SRDF uses.
        self.robot_links = {
            body.scoped_name().to_string(): body.name()
            for instance in self.robot_instances
            for body in map(self.plant.get_body, self.plant.GetBodyIndices(instance))
        }

        # Per plant position first; the planned coordinates are the positions of joints that mimic none.
        positions = self.plant.num_positions()
        names, angular = [""] * positions, np.zeros(positions, bool)
        for i in range(self.plant.num_joints()):
            joint = self.plant.get_joint(JointIndex(i))
            for k in range(joint.num_positions()):
                index = joint.position_start() + k
                names[index] = joint.name() if joint.num_positions() == 1 else f"{joint.name()}[{k}]"
                angular[index] = joint.type_name() == "revolute"
        try:
            self.position_map = PositionMap.of(
                names, [(m.joint, m.follows, m.multiplier, m.offset) for m in problem.mimic]
            )
        except UserError as exc:
            raise UserError(f"bad scene file {self.path.name}: {exc}") from None
        planned = self.position_map.planned if self.position_map else np.arange(positions)
        position_lower, position_upper = self.plant.GetPositionLowerLimits(), self.plant.GetPositionUpperLimits()
        self.dim = nq = len(planned)
        self.joint_names = names  # every position's, mimic joints' included: what a trajectory carries
        self.coordinate_names = [names[i] for i in planned]
        self.angular = angular = angular[planned]
        model_lower, model_upper = position_lower[planned], position_upper[planned]
        # An angle with no joint limit wraps: it lives on a circle, and the metric takes the short way round.
        self.continuous = angular & ~np.isfinite(model_lower) & ~np.isfinite(model_upper)
        model_lower = np.where(self.continuous, -math.pi, model_lower)
        model_upper = np.where(self.continuous, math.pi, model_upper)
        mimic_lower, mimic_upper = (
            self.position_map.coordinate_limits(position_lower, position_upper)
            if self.position_map
            else (-np.inf, np.inf)
        )
        # A mimicked coordinate's bounds keep its mimic joints within their limits (a limited coordinate: no wrap).
        self.continuous &= ~np.isfinite(mimic_lower) & ~np.isfinite(mimic_upper)

        self.lower = np.maximum(self._vector("lower", problem.lower, model_lower), mimic_lower)
        self.upper = np.minimum(self._vector("upper", problem.upper, model_upper), mimic_upper)
        if not np.all(np.isfinite(self.lower) & np.isfinite(self.upper)) or np.any(self.lower >= self.upper):
            raise UserError(f"bad scene file {self.path.name}: bounds must be finite with lower < upper")
        self.weights = self._vector("weights", problem.weights, np.ones(nq))
        if np.any(self.weights <= 0):
            raise UserError(f"bad scene file {self.path.name}: weights must be positive")
        self.start = self._vector("start", problem.start, None)
        self.goal = self._vector("goal", problem.goal, None)
        diagonal = float(np.linalg.norm((self.upper - self.lower) * self.weights))
        # Edges are checked at points this far apart: a finer step makes an edge check of millions of points, one
        # longer than the diagonal checks every edge at its two ends only.
        if not (math.isfinite(problem.resolution) and MIN_RESOLUTION * diagonal <= problem.resolution <= diagonal):
            raise UserError(
                f"bad scene file {self.path.name}: resolution must be from {MIN_RESOLUTION:g} x the bounds' diagonal "
                f"({MIN_RESOLUTION * diagonal:.3g}) to the diagonal ({diagonal:.3g}), got {problem.resolution:g}"
            )
        self.resolution = float(problem.resolution)
        if not (problem.step >= 0 and math.isfinite(problem.step)):
            raise UserError(f"bad scene file {self.path.name}: step must be a non-negative number")
        self.step = float(problem.step) or None
        if self.step:
            try:
                ConfigurationSpace.of(self).check_step(self.step)
            except UserError as exc:
                raise UserError(f"bad scene file {self.path.name}: {exc}") from None
        model_velocity = self.plant.GetVelocityUpperLimits()
        self.velocity_limits = self._vector("velocity_limits", problem.velocity_limits, model_velocity[planned])
        if self.position_map:  # a mimic joint moves |multiplier| times as fast as its coordinate
            self.velocity_limits = np.minimum(self.velocity_limits, self.position_map.coordinate_speeds(model_velocity))
        self.acceleration_limits = self._vector(
            "acceleration_limits", problem.acceleration_limits, 2.0 * self.velocity_limits
        )
        for key in ("velocity_limits", "acceleration_limits"):  # refused now, not after a plan has been found
            limits = getattr(self, key)
            if np.any(limits <= 0):
                bad = int(np.flatnonzero(limits <= 0)[0])
                raise UserError(
                    f"bad scene file {self.path.name}: '{key}' must be positive, item {bad + 1} "
                    f"({self.coordinate_names[bad]}) is {limits[bad]:g}"
                )
        self.self_collisions = problem.collisions == "all"
        # A robot that is one rigid body (an OMPL.app problem's) has nothing to collide with itself.
        self.one_body = (
            sum(
                bool(self.plant.GetCollisionGeometriesForBody(self.plant.get_body(b)))
                for instance in self.robot_instances
                for b in self.plant.GetBodyIndices(instance)
            )
            <= 1
        )

        spec = problem.passage
        if spec.frame and not self.plant.HasFrameNamed(spec.frame):
            raise UserError(f"bad scene file {self.path.name}: passage frame '{spec.frame}' not in the model")
        self.passage_frame = self.plant.GetFrameByName(spec.frame) if spec.frame else None
        try:
            self.passage_boxes = [
                (np.array(b.lo, float).reshape(3), np.array(b.hi, float).reshape(3)) for b in spec.boxes
            ]
        except ValueError:
            raise UserError(f"bad scene file {self.path.name}: passage boxes need 3-vectors lo and hi") from None
        for k, (lo, hi) in enumerate(self.passage_boxes):
            if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo <= hi)):
                raise UserError(
                    f"bad scene file {self.path.name}: passage box {k + 1} needs finite lo <= hi, got lo {lo.tolist()}"
                    f" and hi {hi.tolist()}"
                )
        self._read_poses(problem)

    def positions(self, Q: np.ndarray) -> np.ndarray:
        """The plant's positions at configurations Q (..., dim): Q itself unless mimic joints follow coordinates."""
        return Q if self.position_map is None else self.position_map.positions(Q)

    def _read_poses(self, problem: ProblemFile) -> None:
        """`tool_frame` (a Frame or None), `poses` (name -> RigidTransform of the tool frame in the world) and
        `pass_through` (the names of the poses a job does not stop at)."""
        from pydrake.math import RigidTransform, RollPitchYaw

        bad = f"bad scene file {self.path.name}"
        if problem.tool_frame and not self.plant.HasFrameNamed(problem.tool_frame):
            raise UserError(f"{bad}: tool frame '{problem.tool_frame}' not in the model")
        if problem.poses and not problem.tool_frame:
            raise UserError(f"{bad}: 'poses' need a 'tool_frame'")
        self.tool_frame = self.plant.GetFrameByName(problem.tool_frame) if problem.tool_frame else None
        self.poses = {}
        self.pass_through = {pose.name for pose in problem.poses if not pose.stop}
        for pose in problem.poses:
            if not pose.name or pose.name in self.poses:
                raise UserError(f"{bad}: every pose needs a unique name (got '{pose.name}')")
            values = np.array(list(pose.xyz) + list(pose.rpy_deg), float)
            if len(pose.xyz) != 3 or len(pose.rpy_deg) != 3 or not np.all(np.isfinite(values)):
                raise UserError(f"{bad}: pose '{pose.name}' needs xyz and rpy_deg, 3 finite numbers each")
            self.poses[pose.name] = RigidTransform(RollPitchYaw(np.radians(values[3:])), values[:3])

    def add_models(self, parser) -> None:
        """Load the scene's models (robot and obstacles) into `parser`'s plant, e.g. for a second diagram to view."""
        from pydrake.multibody.parsing import LoadModelDirectives, ProcessModelDirectives

        directives_path = self.path.parent / self.problem.directives
        if not directives_path.is_file():
            raise UserError(f"bad scene file {self.path.name}: directives file not found: {self.problem.directives}")
        check_input(directives_path, "model directives")
        for package, directory in PACKAGES.items():
            if not parser.package_map().Contains(package):
                parser.package_map().Add(package, str(directory))
        try:
            with model_loading():
                ProcessModelDirectives(LoadModelDirectives(str(directives_path)), parser)
        except Exception as exc:
            raise UserError(f"cannot load {self.problem.directives}: {' '.join(str(exc).split())[:300]}") from None

    def _file(self, uri: str) -> Path:
        """A file named in the problem file: package://NAME/rest of a shipped package, else relative to the file."""
        if uri.startswith("package://"):
            name, _, rest = uri[len("package://") :].partition("/")
            if name not in PACKAGES:
                raise UserError(f"bad scene file {self.path.name}: unknown package '{name}' in {uri}")
            return PACKAGES[name] / rest
        return self.path.parent / uri

    def _vector(self, key: str, values: list[float], default: "np.ndarray | None") -> np.ndarray:
        if not values:
            if default is None:
                raise UserError(f"bad scene file {self.path.name}: '{key}' is required")
            return np.asarray(default, float).copy()
        vector = np.asarray(values, float)
        if vector.shape != (self.dim,):
            raise UserError(f"bad scene file {self.path.name}: '{key}' needs {self.dim} numbers, got {len(values)}")
        if not np.all(np.isfinite(vector)):
            bad = int(np.flatnonzero(~np.isfinite(vector))[0])
            raise UserError(
                f"bad scene file {self.path.name}: '{key}' needs finite numbers, item {bad + 1} is {vector[bad]}"
            )
        return vector

    def summary(self) -> dict:
        return {
            "name": self.name,
            "description": self.problem.description,
            "dof": self.dim,
            "coordinates": self.coordinate_names,
            "lower": self.lower.tolist(),
            "upper": self.upper.tolist(),
            "start": self.start.tolist(),
            "goal": self.goal.tolist(),
            "collisions": self.problem.collisions,
            "self_collision": self.self_collisions,
            "disabled_pairs": len(self.disabled_pairs),
            "passage_frame": self.problem.passage.frame,
            "passage_boxes": [dataclasses.asdict(b) for b in self.problem.passage.boxes],
            "tool_frame": self.problem.tool_frame,
            "poses": [p.name for p in self.problem.poses],
            "mimic": [dataclasses.asdict(m) for m in self.problem.mimic],
        }
