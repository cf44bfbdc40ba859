"""Bring your own robot and environment: any URDF/SDF robot (or a mesh as a free-flying rigid body) among mesh or
SDF/URDF obstacles, turned into an ordinary Scene the oracle and planner accept.

How: the inputs are written as Drake model directives + a problem file into a scene directory under the cache
(`<cache>/scenes/<hash>/`) and loaded with the existing Scene class. `CustomScene` only adds the user's package
paths to the parser's package map before the directives are processed.

Inputs (the keys of a custom scene file, see `CustomSpec`; `plan` takes the same as flags):
- robot: a .urdf/.sdf file, or a mesh (.obj/.stl/.dae/...) which becomes a free-flying rigid body.
  A URDF/SDF robot whose root is not attached to the world is welded to it at the origin, unless `floating` is set:
  then (as for a mesh) it is carried by prismatic x, y, z and revolute yaw, pitch, roll joints (R = Rz Ry Rx, as
  robots/l_body.urdf), so its first six coordinates are x, y, z, yaw, pitch, roll.
- env: mesh files (decomposed into validated convex pieces, see app.scene.meshes) or .sdf/.urdf files; `env_pose`
  x,y,z (m), roll,pitch,yaw (degrees) places them (once for all, or once per env).
- collisions / srdf: self-collision counts unless `collisions: environment`; an SRDF's <disable_collisions> pairs
  (adjacent links, pairs that cannot touch) are left out. Mesh links are decomposed like environment meshes, so
  self-collision is judged on the validated pieces, not on Drake's convex hull of each link.
- velocity_limits / acceleration_limits: one positive number per coordinate (default: the model's velocity limits,
  1 where it has none; accelerations twice the velocity limits, as for a shipped scene).
- bounds: per coordinate `lo..hi`, comma separated: either one per coordinate, or, for a floating robot, three for
  x, y, z only (the angles then wrap on [-pi, pi); further joints keep their model limits). Default for a floating
  robot: the environment's bounding box, grown by the robot's radius, and stretched to include start and goal;
  for a jointed arm: its joint limits.

Every refusal an input can earn comes before any mesh work (`check_model`, `_checked_inputs`): a model file's XML,
its numbers (joint limits and speeds, mimic factors, offsets and sizes: finite and within MAX_MODEL_NUMBER), its
<mimic> elements, its mesh references (known packages, existing files), and Drake's own parser on the model without
its geometry; for a URDF robot also its joint types, mimic joints and the number of start, goal, limit and bounds
values. What ROS tools accept but Drake refuses only in visuals (a material defined twice, a material used but
never defined) is tolerated: the URDF given to Drake is fixed up, and one line says what was ignored. Messages name
the user's files, never the files generated in the cache.
"""

import collections
import contextlib
import functools
import hashlib
import json
import logging
import math
import re
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from app.errors import UserError
from app.io import check_input, write_atomically
from app.scene import meshes
from app.scene.cspace import PositionMap
from app.scene.model import MIN_RESOLUTION, PACKAGES, Scene, model_loading, robot_diagram_builder

# pydrake is imported inside the functions that use it, so that importing the package does not load Drake.

ROBOT_SUFFIXES = {".urdf", ".sdf"}
# Default mesh tolerance of environment meshes, as a fraction of the edge-check step. The tolerance is how far the
# convex pieces may reach beyond the surface. Edges are checked every `resolution`: between two checks the robot
# moves up to a step, so the planner already misses overlaps about half a step deep; pieces half a step proud are
# of that order, finer than it resolves (a gap narrows by at most one step). Tied to the mesh's own size instead
# (0.2 % of its diagonal), a 3,072-triangle torus rejected CoACD's 15 pieces and fell back to ~1,500 face plates.
# Robot meshes keep app.scene.meshes' default.
ENV_TOLERANCE_PER_STEP = 0.5
CARRIER_JOINTS = ("x", "y", "z", "yaw", "pitch", "roll")
# The largest number taken from a model file or the inputs for a joint limit or speed (m or rad, per s for speeds), a
# mimic multiplier or offset, an offset, a size or a bound (m): as meshes.MAX_COORDINATE, far beyond any robot or
# building (a revolute joint allowed 1e6 rad turns 160,000 times) and far below where the planner's differences and
# sums overflow (joint limits of +-1e300 made the bounds' diagonal infinite) or doubles lose the millimetres.
MAX_MODEL_NUMBER = meshes.MAX_COORDINATE


@dataclass
class CustomSpec:
    """The keys of a custom scene file (YAML), also built from `plan`'s flags. Paths in a file are relative to it."""

    description: str = ""
    robot: str = ""  # .urdf/.sdf, or a mesh file (a free-flying body)
    package_path: list[str] = field(default_factory=list)  # NAME=DIR
    floating: bool = False  # carry a URDF/SDF robot's root in SE(3) instead of welding it to the world
    env: list[str] = field(default_factory=list)  # mesh or .sdf/.urdf files
    env_pose: list[float] = field(default_factory=list)  # 6 numbers (x,y,z m; roll,pitch,yaw deg), or 6 per env
    start: list[float] = field(default_factory=list)  # empty: the robot's home (zero, clipped into the bounds)
    goal: list[float] = field(default_factory=list)  # empty: the home too (a caller then sets it, e.g. from a pose)
    bounds: list[str] = field(default_factory=list)  # "lo..hi" per coordinate, or per x,y,z of a floating robot
    collisions: str = "all"  # "all": the robot against itself too; "environment": only against the obstacles
    srdf: str = ""  # MoveIt SRDF whose <disable_collisions> body pairs are not checked
    resolution: float = 0.0  # edge-check step in the weighted metric; 0: default_resolution (the robot's size)
    mesh_method: str = "auto"  # auto | convex | shell | coacd | faces
    mesh_tolerance: float = 0.0  # 0: half the edge-check step (environment), 0.2 % of its size (robot mesh)
    velocity_limits: list[float] = field(default_factory=list)  # per coordinate; empty: the model's (else 1)
    acceleration_limits: list[float] = field(default_factory=list)  # per coordinate; empty: 2x the velocity limits


class CustomScene(Scene):
    """A Scene from generated files, loaded with the user's package paths in the package map. `source` names the
    scene for messages (the user's scene file, else the robot's file): the generated problem and directives files
    are the cache's business, never named to the user."""

    def __init__(self, problem_path: Path, packages: dict[str, Path], name: str, info: dict, source: str = ""):
        self.extra_packages = dict(packages)
        self.info = info  # what was built: decompositions, timings
        self.source = source or name
        self._generated = Path(problem_path).name
        try:
            super().__init__(str(problem_path))
        except UserError as exc:  # (build_scene checks first what it can; this names whatever it did not)
            raise self._in_users_words(exc) from None
        self.name = name
        self.recipe = functools.partial(CustomScene, problem_path, self.extra_packages, name, {}, self.source)

    def add_models(self, parser) -> None:
        for package, directory in self.extra_packages.items():
            if not parser.package_map().Contains(package):
                parser.package_map().Add(package, str(directory))
        try:
            super().add_models(parser)
        except UserError as exc:
            raise self._in_users_words(exc) from None

    def _in_users_words(self, exc: UserError) -> UserError:
        """`exc` naming the scene by `source` instead of the generated problem or directives file, and files by name."""
        directives = getattr(getattr(self, "problem", None), "directives", "scene.dmd.yaml")
        text = str(exc).replace(f"bad scene file {self._generated}", f"bad scene {self.source}")
        text = text.replace(f"cannot load {directives}", f"cannot load the scene of {self.source}")
        exc.args = (user_words(text),)
        return exc


# An absolute path (or file:// URI) in a message: the user knows their files by name, and the cache's by none.
_ABSOLUTE_PATH = re.compile(r"(?<![\w./])(?:file:)?/+(?:[^\s'\"<>:/]+/)+([^\s'\"<>:/]+)")


def user_words(text: str) -> str:
    """`text` with every absolute path cut to its file name (a model copied into the cache keeps its name)."""
    return _ABSOLUTE_PATH.sub(r"\1", text)


# ---- parsing inputs -----------------------------------------------------------------------------------------------
def parse_package_paths(items: list[str], base: Path | None = None) -> dict[str, Path]:
    packages = {}
    for item in items:
        name, sep, directory = item.partition("=")
        if not sep or not name.strip() or not directory.strip():
            raise UserError(f"a package path needs NAME=DIR, got '{item}'")
        path = Path(directory.strip()).expanduser()
        if base is not None and not path.is_absolute():
            path = base / path
        if not path.is_dir():
            raise UserError(f"package '{name.strip()}': directory not found: {directory.strip()}")
        packages[name.strip()] = path.resolve()
    return packages


def parse_bounds(items: list[str]) -> list[tuple[float, float]]:
    """'lo..hi' items (or one comma-separated string of them) -> [(lo, hi), ...], finite with lo < hi."""
    out = []
    for item in ",".join(items).split(","):
        if not item.strip():
            continue
        lo, sep, hi = item.partition("..")
        try:
            pair = (float(lo), float(hi))
        except ValueError:
            pair = None
        if not sep or pair is None or not all(map(math.isfinite, pair)) or not pair[0] < pair[1]:
            raise UserError(f"bad bounds item '{item.strip()}': need lo..hi with finite lo < hi")
        if max(map(abs, pair)) > MAX_MODEL_NUMBER:
            raise UserError(f"bad bounds item '{item.strip()}': bounds must be within +-{MAX_MODEL_NUMBER:g}")
        out.append(pair)
    return out


def parse_poses(values: list[float], count: int) -> list[list[float]]:
    values = [float(v) for v in values]
    if not values:
        return [[0.0] * 6] * count
    if not all(map(math.isfinite, values)) or len(values) not in (6, 6 * count):
        raise UserError(
            f"env pose needs 6 finite numbers x,y,z,roll,pitch,yaw (once, or once per env); got {len(values)}"
        )
    if any(abs(v) > MAX_MODEL_NUMBER for i, v in enumerate(values) if i % 6 < 3):
        raise UserError(f"env pose: x, y, z must be within +-{MAX_MODEL_NUMBER:g} m")
    if len(values) == 6:
        return [values] * count
    return [values[6 * i : 6 * i + 6] for i in range(count)]


def _kind(path: Path, what: str) -> str:
    if not path.is_file():
        raise UserError(f"{what} file not found: {path}")
    suffix = path.suffix.lower()
    if suffix in ROBOT_SUFFIXES:
        check_input(path, "model file")
        return "model"
    if suffix in meshes.MESH_SUFFIXES:
        check_input(path, "mesh file")
        return "mesh"
    raise UserError(
        f"{what} file {path.name}: unsupported type '{suffix}' (use .urdf, .sdf or a mesh: "
        f"{', '.join(sorted(meshes.MESH_SUFFIXES))})"
    )


# ---- probing models -----------------------------------------------------------------------------------------------
def _parser_error(exc: Exception, path: Path) -> UserError:
    """Drake's refusal of the model file `path` (the user's: a copy in the cache has the same name) in one line."""
    text = user_words(" ".join(str(exc).split()))
    if "unknown package" in text:
        match = re.search(r"unknown package '([^']+)'", text)
        name = match.group(1) if match else "?"
        return UserError(f"cannot load {path.name}: unknown package '{name}' (add the package path {name}=DIR)")
    return UserError(f"cannot load {path.name}: {text[:300]}")


def _new_builder(packages: dict[str, Path]):
    builder = robot_diagram_builder()
    package_map = builder.parser().package_map()
    for name, directory in {**{k: Path(v) for k, v in PACKAGES.items()}, **packages}.items():
        if not package_map.Contains(name):
            package_map.Add(name, str(directory))
    return builder


def probe_model(path: Path, packages: dict[str, Path]) -> dict:
    """Parse a URDF/SDF on its own: the model's name, bodies not attached to the world (floating) and their names."""
    builder = _new_builder(packages)
    plant = builder.plant()
    try:
        instances = builder.parser().AddModels(str(path))
        plant.Finalize()
    except Exception as exc:  # pydrake raises RuntimeError (parse errors, unknown packages, bad meshes)
        raise _parser_error(exc, path) from None
    if len(instances) != 1:
        raise UserError(f"{path.name}: expected one model, found {len(instances)}")
    floating = sorted(plant.get_body(b).name() for b in plant.GetFloatingBaseBodies())
    return {
        "name": plant.GetModelInstanceName(instances[0]),
        "floating": floating,
        "positions": plant.num_positions(),
        "static": plant.num_bodies() <= 1,
    }


def read_mimics(path: Path) -> list[dict]:
    """The <mimic> elements of a URDF's joints, as the problem file's `mimic` entries: each such joint follows
    another (multiplier 1 and offset 0 unless given). Drake's URDF parser ignores them in kinematics (a continuous
    plant only records a coupler constraint that no query uses), so they are read here."""
    if path.suffix.lower() != ".urdf":
        return []
    root = _xml_root(path.read_text(errors="replace"), path)
    mimics = []
    for joint in root.findall("joint"):  # (a <transmission>'s <joint> children are no joints)
        element = joint.find("mimic")
        if element is None:
            continue
        try:
            multiplier, offset = float(element.get("multiplier", 1.0)), float(element.get("offset", 0.0))
        except ValueError:
            raise UserError(f"{path.name}: joint '{joint.get('name')}': <mimic> needs numbers") from None
        mimics.append(
            {
                "joint": joint.get("name", ""),
                "follows": element.get("joint", ""),
                "multiplier": multiplier,
                "offset": offset,
            }
        )
    return mimics


def probe_robot(
    directives: Path, packages: dict[str, Path], instances: list[str], mimics: list[dict], robot_file: Path
) -> dict:
    """Load the robot part of the directives: coordinate names, limits, and the robot's size (for weights). A
    joint in `mimics` is no coordinate; the limits of the one it follows keep it within its own. Messages name
    `robot_file` (the user's), not the generated directives."""
    from pydrake.multibody.parsing import LoadModelDirectives, ProcessModelDirectives
    from pydrake.multibody.tree import JointIndex

    builder = _new_builder(packages)
    plant = builder.plant()
    try:
        ProcessModelDirectives(LoadModelDirectives(str(directives)), builder.parser())
        plant.Finalize()
    except Exception as exc:
        raise _parser_error(exc, robot_file) from None
    nq = plant.num_positions()
    names, kinds = [""] * nq, [""] * nq
    for i in range(plant.num_joints()):
        joint = plant.get_joint(JointIndex(i))
        for k in range(joint.num_positions()):
            names[joint.position_start() + k] = joint.name()
            kinds[joint.position_start() + k] = joint.type_name()
    if plant.GetFloatingBaseBodies():
        raise UserError(
            "the robot still has a free-floating body after welding its root; connect its parts with joints"
        )
    bad = sorted({k for k in kinds if k not in ("revolute", "prismatic")})
    if bad:
        raise UserError(f"robot joints of type {', '.join(bad)} are not supported (revolute and prismatic only)")
    # Size: from the robot's collision geometry (oriented boxes) at the default configuration. `reach` is the
    # largest distance of any of it from the robot's first body's origin (an angle's lever arm); `thin` the median
    # over bodies of the smallest width of all of a body's geometry together (how far a step may move the robot
    # without skipping a thin wall). Per body, not per geometry: a body made of thin pieces (a mesh split into face
    # plates) is as thick as the whole, and the edge-check step must not follow the plates' thickness.
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
    reach = float(np.max(np.linalg.norm(np.vstack(corners) - root, axis=1)))
    thin = float(np.median(widths))
    lower, upper, velocity = (
        plant.GetPositionLowerLimits(),
        plant.GetPositionUpperLimits(),
        plant.GetVelocityUpperLimits(),
    )
    # (check_model has refused a URDF's; an SDF's limits are first seen here)
    for what, values in (("lower limit", lower), ("upper limit", upper), ("velocity limit", velocity)):
        huge = np.isfinite(values) & (np.abs(values) > MAX_MODEL_NUMBER)
        if huge.any():
            i = int(np.flatnonzero(huge)[0])
            raise UserError(
                f"{robot_file.name}: joint '{names[i]}': {what} {values[i]:g} is out of range (limits must be within "
                f"+-{MAX_MODEL_NUMBER:g} m or rad)"
            )
    try:
        mimic = PositionMap.of(names, [(m["joint"], m["follows"], m["multiplier"], m["offset"]) for m in mimics])
    except UserError as exc:
        raise UserError(f"{robot_file.name}: {exc}") from None
    if mimic is not None:
        (mimic_lower, mimic_upper), mimic_velocity = (
            mimic.coordinate_limits(lower, upper),
            mimic.coordinate_speeds(velocity),
        )
        planned = mimic.planned
        names, kinds = [names[i] for i in planned], [kinds[i] for i in planned]
        lower, upper = np.maximum(lower[planned], mimic_lower), np.minimum(upper[planned], mimic_upper)
        velocity = np.minimum(velocity[planned], mimic_velocity)
        if np.any(lower >= upper):
            bad = names[int(np.flatnonzero(lower >= upper)[0])]
            raise UserError(
                f"{robot_file.name}: joint '{bad}': no position keeps the joints that mimic it within their limits"
            )
    return {
        "names": names,
        "kinds": kinds,
        "lower": lower,
        "upper": upper,
        "velocity": velocity,
        "reach": reach,
        "thin": thin,
        "mimic": mimics,
    }


def _smallest_width(points: np.ndarray) -> float:
    """The smallest extent of a point set along its principal axes (a box fitted to it)."""
    centred = points - points.mean(axis=0)
    axes = np.linalg.svd(centred, full_matrices=False)[2]
    extents = np.ptp(centred @ axes.T, axis=0)
    return float(extents.min()) if len(extents) == 3 else 0.0


# ---- model files: every refusal before any mesh work ------------------------------------------------------------
# The numeric attributes of a URDF checked (per element name; each number of a list): finite, within
# MAX_MODEL_NUMBER. Joint limits and speeds are checked apart (`_check_limit`).
_URDF_NUMBERS = {
    "origin": ("xyz",),
    "axis": ("xyz",),
    "box": ("size",),
    "cylinder": ("radius", "length"),
    "sphere": ("radius",),
    "capsule": ("radius", "length"),
    "mesh": ("scale",),
    "mimic": ("multiplier", "offset"),
}
_COMMENT = re.compile(r"<!--.*?-->", re.S)
_MATERIAL = re.compile(r"<material\b(?P<attrs>[^>]*?)(?:/>|>(?P<body>.*?)</material\s*>)", re.S)
_VISUAL = re.compile(r"<visual\b[^>]*?(?<!/)>.*?</visual\s*>", re.S)
_GEOMETRY_ELEMENTS = re.compile(
    r"<(collision|visual)\b[^>]*?/>|<(collision|visual)\b.*?</\2\s*>|<material\b[^>]*?/>|<material\b.*?</material\s*>",
    re.S,
)
_notes_said: set[str] = set()  # the notes this process has printed (a scene may be built more than once)


@dataclass
class ModelCheck:
    """What `check_model` found in a model file that it did not refuse: notes for the user (one line per file), and
    for a URDF the joints Drake's parser makes of it (name, type, positions, ephemeral), in position order."""

    notes: list[str] = field(default_factory=list)
    joints: list[tuple[str, str, int, bool]] | None = None


def check_model(path: Path, packages: dict[str, Path]) -> ModelCheck:
    """Every refusal a URDF/SDF file can earn, before any mesh work, as one-line UserErrors naming the file: its XML,
    its numbers and <mimic> elements (a URDF's), its mesh references (unknown packages, missing mesh files) and, for a
    URDF, Drake's parser on the model without its geometry (which needs no mesh read)."""
    text = _blank_comments(path.read_text(errors="replace"))
    root = _xml_root(text, path)
    found = ModelCheck()
    urdf = path.suffix.lower() == ".urdf"
    if urdf:
        _check_urdf_numbers(root, path)
        for joint in root.findall("joint"):
            count = len(joint.findall("mimic"))
            if count > 1:
                raise UserError(
                    f"{path.name}: joint '{joint.get('name')}' has {count} <mimic> elements; a joint follows one joint"
                )
    for m in re.finditer(_MESH_REF, text):
        _mesh_target(_ref_parts(m)[1], path, packages)
    if urdf:
        found.joints = _urdf_joints(text, path, packages)
        found.notes = drake_materials(text)[1]
    return found


def _blank_comments(text: str) -> str:
    """`text` with its XML comments blanked out (each character a space, lines kept): a commented-out element is
    none, and Drake's line numbers still point into the user's file."""
    return _COMMENT.sub(lambda m: re.sub(r"[^\n]", " ", m.group(0)), text)


def _xml_root(text: str, path: Path):
    """The root element of a model file's text, or one line: "cannot load NAME: the XML error". A prefix used but
    never declared (`<drake:...>` without xmlns:drake, which Drake's own parser takes) is declared for the reading."""
    try:
        return ET.fromstring(text)
    except ET.ParseError as exc:
        if "unbound prefix" not in str(exc):
            raise UserError(f"cannot load {path.name}: {exc}") from None
    prefixes = set(re.findall(r"</?([A-Za-z_][\w.-]*):[A-Za-z_]", text)) - {"xml"}
    declared = set(re.findall(r"xmlns:([A-Za-z_][\w.-]*)\s*=", text))
    extra = "".join(f' xmlns:{p}="urn:undeclared:{p}"' for p in sorted(prefixes - declared))
    head = re.search(r"<(?![?!])[A-Za-z_][\w.:-]*", text)
    try:
        return ET.fromstring(text[: head.end()] + extra + text[head.end() :] if head else text)
    except ET.ParseError as exc:
        raise UserError(f"cannot load {path.name}: {exc}") from None


def _local(tag) -> str:
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""


def _check_urdf_numbers(root, path: Path) -> None:
    """A URDF's joint limits and speeds, mimic factors, offsets and sizes: finite and within MAX_MODEL_NUMBER, and a
    joint's lower limit not above its upper one (Drake's parser takes +-1e300; the planner then overflows, and an
    inverted limit or a negative speed stops the process inside Drake). Text that is no number is Drake's to refuse."""
    for kind in ("link", "joint"):
        for owner in root.findall(kind):
            where = f"{path.name}: {kind} '{owner.get('name')}'"
            for element in owner.iter():
                for attribute in _URDF_NUMBERS.get(_local(element.tag), ()):
                    raw = element.get(attribute)
                    try:
                        values = [float(v) for v in raw.split()] if raw is not None else []
                    except ValueError:
                        continue
                    if not all(math.isfinite(v) and abs(v) <= MAX_MODEL_NUMBER for v in values):
                        raise UserError(
                            f'{where}: <{_local(element.tag)} {attribute}="{raw.strip()}"> is out of range (numbers '
                            f"here must be finite and within +-{MAX_MODEL_NUMBER:g})"
                        )
            if kind == "joint":
                _check_limit(owner, where)


def _check_limit(joint, where: str) -> None:
    limit = joint.find("limit")
    if limit is None:
        return
    # A continuous (or fixed, floating, planar) joint's lower and upper are not limits: Drake reads them for
    # revolute and prismatic joints only.
    names = ("lower", "upper", "velocity") if joint.get("type") in ("revolute", "prismatic") else ("velocity",)
    values = {}
    for name in names:
        raw = limit.get(name)
        try:
            value = float(raw) if raw is not None else None
        except ValueError:
            continue  # (Drake's parser says what it expected)
        what = "velocity limit" if name == "velocity" else f"{name} limit"
        if value is not None and not math.isfinite(value):
            raise UserError(f"{where}: {what} {raw.strip()} is not a finite number")
        if value is not None and abs(value) > MAX_MODEL_NUMBER:
            raise UserError(
                f"{where}: {what} {raw.strip()} is out of range (limits must be within +-{MAX_MODEL_NUMBER:g} m or rad)"
            )
        values[name] = value
    if values.get("velocity") is not None and values["velocity"] < 0:
        raise UserError(f"{where}: velocity limit {limit.get('velocity').strip()} is negative")
    lower, upper = values.get("lower"), values.get("upper")
    if lower is not None and upper is not None and lower > upper:
        raise UserError(f"{where}: lower limit {limit.get('lower').strip()} is above upper limit {upper:g}")


@contextlib.contextmanager
def _drake_quiet_about(marker: str):
    """Drake's log records that contain `marker` dropped while the block runs."""
    logger = logging.getLogger("drake")

    def keep(record: logging.LogRecord) -> bool:
        return marker not in record.getMessage()

    logger.addFilter(keep)
    try:
        yield
    finally:
        logger.removeFilter(keep)


def _urdf_joints(text: str, path: Path, packages: dict[str, Path]) -> list[tuple[str, str, int, bool]]:
    """Drake's parser on the URDF without its geometry and materials (lines kept, so its messages point into the
    user's file): its refusal, else the joints it makes (name, type, positions, ephemeral: a joint Drake adds to a
    body attached to nothing), in position order. Its warnings are left to the real load, which summarises them."""
    from pydrake.multibody.tree import JointIndex

    bare = _GEOMETRY_ELEMENTS.sub(lambda m: "\n" * m.group(0).count("\n"), text)
    builder = _new_builder(packages)
    plant = builder.plant()
    literal = "<literal-string>.urdf"
    try:
        with _drake_quiet_about(literal):
            builder.parser().AddModelsFromString(bare, "urdf")
            plant.Finalize()
    except Exception as exc:  # pydrake raises RuntimeError
        message = " ".join(str(exc).split()).replace(f"{literal}:", "line ").replace(literal, path.name)
        raise _parser_error(RuntimeError(message), path) from None
    joints = [plant.get_joint(JointIndex(i)) for i in range(plant.num_joints())]
    joints.sort(key=lambda j: j.position_start())
    return [(j.name(), j.type_name(), j.num_positions(), j.is_ephemeral()) for j in joints if j.num_positions()]


def drake_materials(text: str) -> tuple[str, list[str]]:
    """A URDF's text with the materials Drake refuses and ROS tools (urdfdom, RViz) take fixed up, and what was done.
    Drake reads the robot's own <material> elements, then each visual's, and refuses a name defined twice (an inline
    repeat of the same colour aside) and a name used before any definition; here the first definition of a name is
    kept (a later top-level one dropped, a later inline one reduced to a reference to it), and a reference to a name
    defined nowhere before it is dropped (that visual keeps Drake's default colour). Lines are kept."""
    visuals = [m.span() for m in _VISUAL.finditer(text)]
    found = []
    for m in _MATERIAL.finditer(text):
        name = re.search(r"\bname\s*=\s*([\"'])(.*?)\1", m.group("attrs"))
        if name is None:  # (Gazebo's <material>Gazebo/Grey</material>: not Drake's)
            continue
        inline = any(a <= m.start() < b for a, b in visuals)
        found.append((m, name.group(2), inline, _material_definition(m.group("body") or "")))
    defined_somewhere = collections.Counter(name for _, name, _, definition in found if definition is not None)
    defined: dict[str, tuple] = {}
    edits, notes = [], []
    for m, name, inline, definition in [f for f in found if not f[2]] + [f for f in found if f[2]]:
        if definition is None:
            if name not in defined:
                edits.append((m.span(), ""))
                notes.append(
                    f"material '{name}' is used before it is defined (that visual's colour left default)"
                    if name in defined_somewhere
                    else f"material '{name}' is used but never defined (visual colour left default)"
                )
        elif name not in defined:
            defined[name] = definition
        elif not (inline and definition == defined[name]):
            edits.append((m.span(), f"<material name={quoteattr(name)}/>" if inline else ""))
            times = "twice" if defined_somewhere[name] == 2 else f"{defined_somewhere[name]} times"
            notes.append(f"material '{name}' is defined {times} (the first definition is used)")
    for (start, end), replacement in sorted(edits, reverse=True):
        text = text[:start] + replacement + "\n" * text[start:end].count("\n") + text[end:]
    return text, list(dict.fromkeys(notes))


def _material_definition(body: str) -> tuple | None:
    """A material's colour and texture as Drake compares them; None when it has neither (a reference by name)."""
    rgba = re.search(r"<color\b[^>]*\brgba\s*=\s*([\"'])(.*?)\1", body)
    texture = re.search(r"<texture\b[^>]*\bfilename\s*=\s*([\"'])(.*?)\1", body)
    if rgba is None and texture is None:
        return None
    try:
        colour = tuple(float(v) for v in rgba.group(2).split()) if rgba else None
    except ValueError:
        colour = rgba.group(2)
    return colour, texture.group(2) if texture else None


def _say_notes(path: Path, notes: list[str]) -> None:
    line = f"note: {path.name}: {'; '.join(notes)}"
    if notes and line not in _notes_said:
        _notes_said.add(line)
        print(line, file=sys.stderr)


# ---- model files with meshes Drake cannot read ------------------------------------------------------------------
def resolve_uri(uri: str, relative_to: Path, packages: dict[str, Path]) -> Path | None:
    """package://NAME/rest, file:///abs, an absolute or a relative path -> a Path; None for other schemes."""
    if uri.startswith("package://"):
        name, _, rest = uri[len("package://") :].partition("/")
        known = {**{k: Path(v) for k, v in PACKAGES.items()}, **packages}
        if name not in known:
            raise UserError(
                f"cannot load {relative_to.name}: unknown package '{name}' (add the package path {name}=DIR)"
            )
        return known[name] / rest
    if uri.startswith("file://"):
        return Path(uri[len("file://") :])
    if "://" in uri:
        return None
    path = Path(uri)
    return path if path.is_absolute() else relative_to.parent / path


_MESH_REF = r'(filename\s*=\s*")([^"]+)(")|(<uri>\s*)([^<]+?)(\s*</uri>)'


def _ref_parts(m) -> tuple[str, str, str]:
    return (m.group(1), m.group(2), m.group(3)) if m.group(2) else (m.group(4), m.group(5), m.group(6))


def _is_mesh(uri: str) -> bool:
    return Path(uri.split("?")[0]).suffix.lower() in meshes.MESH_SUFFIXES


def _mesh_target(uri: str, path: Path, packages: dict[str, Path]) -> Path | None:
    """The file a reference in the model file `path` names (None for another URI scheme); an unknown package, or a
    mesh file that is not there, is a UserError naming `path`."""
    target = resolve_uri(uri, path, packages)
    if target is not None and _is_mesh(uri) and not target.is_file():
        raise UserError(f"cannot load {path.name}: mesh file not found: {uri}")
    return target


def convert_model_meshes(
    path: Path,
    packages: dict[str, Path],
    cache_dir: Path | None,
    decompose_options: dict | None = None,
    info: list | None = None,
) -> Path:
    """`path` itself when nothing needs changing; else a rewritten copy in the cache where
    - with `decompose_options` (environment models and robots' mesh links): each <collision> holding a mesh becomes
      one <collision> per validated convex piece of it (app.scene.meshes.decompose), since Drake would use the mesh's
      convex hull; the pieces stay on the link's body, so they are never checked against each other;
    - mesh references Drake cannot read (.stl, .dae, ...) point to converted .obj files (without decompose_options
      that means their convex hull, conservative);
    - every other relative or package:// reference is made absolute (the copy lives elsewhere);
    - (a URDF) the materials Drake refuses and ROS tools take are fixed up (`drake_materials`).
    Comments are blanked and lines kept, so Drake's messages point into the user's file. `info` collects what each
    decomposition did. (`check_model` has refused what it can before this runs any decomposition.)"""
    original = path.read_text(errors="replace")
    text = _blank_comments(original)
    if path.suffix.lower() == ".urdf":
        text = drake_materials(text)[0]
    refs = re.compile(_MESH_REF)
    blocks = re.compile(r"<collision\b.*?</collision>", re.S)

    def convertible(uri):
        return Path(uri.split("?")[0]).suffix.lower() in meshes.CONVERTIBLE_SUFFIXES

    decompose_here = decompose_options is not None and any(
        _is_mesh(_ref_parts(m)[1]) for b in blocks.finditer(text) for m in refs.finditer(b.group(0))
    )
    refit = path.suffix.lower() == ".urdf" and text != _blank_comments(original)  # (materials fixed up)
    if not decompose_here and not refit and not any(convertible(_ref_parts(m)[1]) for m in refs.finditer(text)):
        return path
    for m in refs.finditer(text):  # every reference checked before the first decomposition starts
        _mesh_target(_ref_parts(m)[1], path, packages)

    def resolved(uri):
        return _mesh_target(uri, path, packages)

    def absolute(m):
        head, uri, tail = _ref_parts(m)
        target = resolved(uri)
        if target is None:
            return m.group(0)
        if convertible(uri):
            target = meshes.converted_obj(target, cache_dir)
        return f"{head}{target if m.group(2) else f'file://{target}'}{tail}"

    def split_collision(b):
        block = b.group(0)
        found = [m for m in refs.finditer(block) if _is_mesh(_ref_parts(m)[1])]
        if len(found) != 1:
            return block
        m = found[0]
        target = resolved(_ref_parts(m)[1])
        if target is None:
            return block
        decomposition = meshes.decompose(target, **decompose_options)
        if info is not None:
            info.append(_describe(target, decomposition))
        copies = []
        for k, piece in enumerate(decomposition.pieces):
            head, _, tail = _ref_parts(m)
            uri = str(piece) if m.group(2) else f"file://{piece}"
            copy = block[: m.start()] + f"{head}{uri}{tail}" + block[m.end() :]
            copy = re.sub(r'(<collision\b[^>]*\bname\s*=\s*")([^"]*)(")', rf"\g<1>\g<2>_piece{k}\g<3>", copy, count=1)
            copies.append(copy if not copies else copy.replace("\n", " "))  # (all on the block's own lines)
        return "".join(copies)

    if decompose_here:
        text = blocks.sub(split_collision, text)
    rewritten = refs.sub(absolute, text)  # (idempotent on the pieces' absolute .obj paths)
    key = hashlib.sha256(rewritten.encode()).hexdigest()[:24]
    out = (cache_dir or meshes.cache_root()) / "models" / key / path.name
    _write(out, rewritten)
    return out


# ---- generated files ----------------------------------------------------------------------------------------------
_INERTIAL = '<inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>'


def carrier_urdf(name: str, body_xml: str = "") -> str:
    """Prismatic x, y, z then revolute yaw, pitch, roll (no limits: the problem file's bounds rule), ending in a link
    `body` holding `body_xml` (collision/visual elements)."""
    links = ["origin", "px", "py", "pz", "yawed", "pitched", "body"]
    axes = ["1 0 0", "0 1 0", "0 0 1", "0 0 1", "0 1 0", "1 0 0"]
    out = [
        f'<?xml version="1.0"?>\n<robot name="{name}" xmlns:drake="http://drake.mit.edu">',
        '  <link name="origin"/>',
    ]
    for link in links[1:-1]:
        out.append(f'  <link name="{link}">{_INERTIAL}</link>')
    out.append(f'  <link name="body">{_INERTIAL}\n{body_xml}  </link>')
    for k, joint in enumerate(CARRIER_JOINTS):
        kind = "prismatic" if k < 3 else "continuous"
        limit = (
            '<limit lower="-1e4" upper="1e4" effort="1" velocity="10"/>'
            if k < 3
            else '<limit effort="1" velocity="10"/>'
        )
        out.append(
            f'  <joint name="{joint}" type="{kind}"><parent link="{links[k]}"/><child link="{links[k + 1]}"/>'
            f'<axis xyz="{axes[k]}"/>{limit}</joint>'
        )
    out.append("</robot>\n")
    return "\n".join(out)


def _mesh_elements_urdf(decomposition: meshes.Decomposition) -> str:
    lines = [
        f'    <collision name="piece{i}"><geometry><mesh filename={quoteattr(str(p))}><drake:declare_convex/></mesh>'
        f"</geometry></collision>"
        for i, p in enumerate(decomposition.pieces)
    ]
    lines.append(f"    <visual><geometry><mesh filename={quoteattr(str(decomposition.visual))}/></geometry></visual>")
    return "\n".join(lines) + "\n"


def env_urdf(name: str, decomposition: meshes.Decomposition, pose: list[float]) -> str:
    """The pieces as convex collision shapes and the original mesh as the visual, all on the URDF link named `world`
    (which Drake takes as the world body itself), placed at pose. On the world body SceneGraph registers them as
    *anchored* geometry: its broad phase keeps them in a tree built once, whereas geometry on a body (even one welded
    to the world, as in a static SDF model) is dynamic: re-posed and re-sorted on every query, which makes a check
    among many pieces far dearer (docs/benchmarks.md, "Mesh scenes")."""
    x, y, z, r, p, w = pose
    origin = f'<origin xyz="{x!r} {y!r} {z!r}" rpy="' + " ".join(f"{math.radians(a)!r}" for a in (r, p, w)) + '"/>'
    lines = [
        '<?xml version="1.0"?>',
        f'<robot name="{name}" xmlns:drake="http://drake.mit.edu">',
        '  <link name="world">',
    ]
    # Geometry names are unique per frame, and every environment shares the world's: so they carry the model's name.
    for i, piece in enumerate(decomposition.pieces):
        lines.append(
            f'    <collision name="{name}_piece{i}">{origin}<geometry><mesh filename={quoteattr(str(piece))}>'
            f"<drake:declare_convex/></mesh></geometry></collision>"
        )
    lines.append(
        f'    <visual name="{name}_mesh">{origin}<geometry><mesh filename={quoteattr(str(decomposition.visual))}/>'
        "</geometry></visual>"
    )
    lines += ["  </link>", "</robot>", ""]
    return "\n".join(lines)


def _quoted_uri(path: Path | str) -> str:
    # A JSON string is a YAML double-quoted scalar: '#', ': ' and quotes in a path stay part of it.
    return json.dumps(f"file://{path}")


def _pose_yaml(pose: list[float]) -> str:
    x, y, z, r, p, w = pose
    return (
        f"    X_PC:\n      translation: [{x!r}, {y!r}, {z!r}]\n      rotation: !Rpy {{ deg: [{r!r}, {p!r}, {w!r}] }}\n"
    )


def _world_box(bounds: np.ndarray, pose: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """The world-frame box around a local box moved by pose (corners transformed)."""
    from pydrake.math import RigidTransform, RollPitchYaw

    X = RigidTransform(RollPitchYaw(np.radians(pose[3:])), pose[:3])
    corners = np.array([[bounds[i][0], bounds[j][1], bounds[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    world = (X.rotation().matrix() @ corners.T).T + X.translation()
    return world.min(axis=0), world.max(axis=0)


def _write(path: Path, text: str) -> None:
    """Write only when different (other processes may read the file meanwhile)."""
    if path.is_file() and path.read_text() == text:
        return
    write_atomically(meshes.writable_folder(path.parent) / path.name, text)


# ---- the builder --------------------------------------------------------------------------------------------------
@model_loading()
def build_scene(
    spec: CustomSpec, base: Path | None = None, cache_dir: Path | None = None, progress: bool = True, source: str = ""
) -> CustomScene:
    """The Scene for `spec`. Relative paths are taken from `base` (the scene file's directory, or the cwd). `source`
    names the scene in messages (its file's name; default: the robot file's)."""
    import time

    started = time.perf_counter()
    cache_dir = Path(cache_dir).absolute() if cache_dir else None  # (see meshes.cache_root)
    inputs = _checked_inputs(spec, base or Path.cwd())
    mesh_options = {
        "method": spec.mesh_method,
        "tolerance": spec.mesh_tolerance or None,
        "cache_dir": cache_dir,
        "progress": progress,
    }
    models = _Models()
    robot_instances = _add_robot(models, inputs, mesh_options, cache_dir)
    robot_directives = list(models.directives)
    # The robot alone first (a scene directory of its own): its size sets the edge-check step, and the step sets
    # how closely the environment's pieces must follow its surfaces.
    root = cache_dir or meshes.cache_root()
    robot_dir = _write_scene_dir(models, robot_directives, inputs.packages, root)
    mimics = read_mimics(inputs.robot_path) if inputs.robot_kind == "model" else []
    coords = probe_robot(robot_dir / "robot.dmd.yaml", inputs.packages, robot_instances, mimics, inputs.robot_path)
    resolution = spec.resolution or default_resolution(coords)
    _check_vectors(spec, coords)
    env_options = {**mesh_options, "tolerance": spec.mesh_tolerance or ENV_TOLERANCE_PER_STEP * resolution}
    env_boxes = _add_environment(models, inputs, env_options, cache_dir)
    scene_dir = _write_scene_dir(models, robot_directives, inputs.packages, root)
    problem = _problem(spec, inputs, coords, robot_instances, env_boxes, resolution)
    text = json.dumps(problem, indent=1) + "\n"  # JSON is YAML
    problem_path = scene_dir / f"problem-{hashlib.sha256(text.encode()).hexdigest()[:16]}.yaml"
    _write(problem_path, text)
    info = {
        "robot": str(inputs.robot_path),
        "env": [str(p) for p in inputs.env_paths],
        "decompositions": models.decompositions,
        "prepare_seconds": time.perf_counter() - started,
    }
    if models.hull_robot_file is not None:
        info["mesh_links"] = hull_disagreement(scene_dir, *models.hull_robot_file, inputs, robot_instances)
    name = f"{inputs.robot_path.stem}-in-{'+'.join(p.stem for p in inputs.env_paths) or 'nothing'}"
    load_started = time.perf_counter()
    scene = CustomScene(problem_path, inputs.packages, name, info, source or inputs.robot_path.name)
    info["drake_load_seconds"] = time.perf_counter() - load_started
    info["scene_dir"] = str(scene_dir)
    return scene


@dataclass
class _Inputs:
    """A spec's inputs, checked, with paths resolved."""

    packages: dict[str, Path]
    robot_path: Path
    robot_kind: str  # "model" or "mesh"
    floating: bool  # carried by the x, y, z, yaw, pitch, roll joints
    env_paths: list[Path]
    env_kinds: list[str]
    env_poses: list[list[float]]
    bounds: list[tuple[float, float]]
    srdf_path: Path | None


def _checked_inputs(spec: CustomSpec, base: Path) -> _Inputs:
    """Every check that needs no mesh read, so bad input fails before any (slow) mesh decomposition: the inputs
    themselves, each model file (`check_model`), the SRDF's links, and where the coordinates are known by now (a mesh
    robot's; a URDF robot's, from Drake's parser on it without geometry) their joint types, mimic joints and the
    number of start, goal, limit and bounds values. Notes on what a model file had ignored follow once all passed."""

    def resolve(p: str) -> Path:
        path = Path(p).expanduser()
        return (path if path.is_absolute() else base / path).resolve()

    if not spec.robot:
        raise UserError("a robot is required (a .urdf/.sdf file or a mesh)")
    if spec.collisions not in ("environment", "all"):
        raise UserError("collisions must be 'environment' or 'all'")
    if spec.mesh_method not in meshes.METHODS:
        raise UserError(f"unknown mesh method '{spec.mesh_method}' (known: {', '.join(meshes.METHODS)})")
    if not (0 <= spec.resolution < math.inf and 0 <= spec.mesh_tolerance < math.inf):
        raise UserError("resolution and mesh tolerance must be finite and not negative")
    packages = parse_package_paths(spec.package_path, base)
    robot_path = resolve(spec.robot)
    robot_kind = _kind(robot_path, "robot")
    env_paths = [resolve(p) for p in spec.env]
    env_kinds = [_kind(p, "environment") for p in env_paths]
    poses = parse_poses(spec.env_pose, len(env_paths)) if env_paths else []
    if spec.env_pose and not env_paths:
        raise UserError("an env pose needs an environment file")
    checked = {}
    for path, kind in [(robot_path, robot_kind), *zip(env_paths, env_kinds)]:
        if kind == "model" and path not in checked:
            checked[path] = check_model(path, packages)
    srdf_path = resolve(spec.srdf) if spec.srdf else None
    if srdf_path is not None:
        _check_srdf_links(srdf_path, robot_path if robot_path.suffix.lower() == ".urdf" else None)
    bounds = parse_bounds(spec.bounds)
    floating = robot_kind == "mesh" or spec.floating
    names = _coordinate_names(robot_path, floating, checked.get(robot_path))
    if names is not None:
        _check_vectors(spec, {"names": names})
        _check_bounds_count(bounds, names, floating)
    for path, found in checked.items():
        _say_notes(path, found.notes)
    return _Inputs(packages, robot_path, robot_kind, floating, env_paths, env_kinds, poses, bounds, srdf_path)


def _coordinate_names(robot_path: Path, floating: bool, found: ModelCheck | None) -> list[str] | None:
    """The scene's coordinates as far as they are known before any mesh work (a mesh robot's carrier; a URDF
    robot's joints as Drake's parser makes them, mimic joints left out, after the carrier's when it floats); None
    for an SDF robot. Joint types the planner does not take, and mimic joints that cannot follow, are refused."""
    if found is None:
        return list(CARRIER_JOINTS) if floating else None
    if found.joints is None:
        return None
    joints = [(name, kind, count) for name, kind, count, ephemeral in found.joints if not ephemeral]
    bad = sorted({kind for _, kind, _ in joints if kind not in ("revolute", "prismatic")})
    if bad:
        raise UserError(f"robot joints of type {', '.join(bad)} are not supported (revolute and prismatic only)")
    names = [name for name, _, count in joints for _ in range(count)]
    mimics = read_mimics(robot_path)
    try:
        mimic = PositionMap.of(names, [(m["joint"], m["follows"], m["multiplier"], m["offset"]) for m in mimics])
    except UserError as exc:
        raise UserError(f"{robot_path.name}: {exc}") from None
    planned = [names[i] for i in mimic.planned] if mimic is not None else names
    return (list(CARRIER_JOINTS) if floating else []) + planned


def _check_bounds_count(bounds: list[tuple[float, float]], names: list[str], floating: bool) -> None:
    if bounds and not (len(bounds) == len(names) or (floating and len(bounds) == 3)):
        raise UserError(
            f"bounds: {len(names)} lo..hi items needed (one per coordinate: {', '.join(names)})"
            + (" or 3 for x, y, z" if floating else "")
            + f"; got {len(bounds)}"
        )


def _check_srdf_links(srdf_path: Path, model_path: Path | None) -> None:
    """The SRDF parses and names only links of the URDF `model_path` (read from its XML: before any mesh work; an
    SDF's nested models scope their names, so its links are checked when it is loaded)."""
    import xml.etree.ElementTree as ET

    from app.scene.model import read_srdf

    pairs = read_srdf(srdf_path)
    if model_path is None:
        return
    try:
        links = {link.get("name") for link in ET.parse(model_path).getroot().iter("link")}
    except ET.ParseError:
        return  # the model's own load reports it
    unknown = sorted({name for pair in pairs for name in pair} - links)
    if unknown:
        raise UserError(f"SRDF {srdf_path.name}: unknown link(s) {', '.join(unknown)} (not bodies of the robot)")


@dataclass
class _Models:
    """The scene's model directives (@DIR@ stands for the scene directory) and the files generated for them."""

    directives: list[str] = field(default_factory=lambda: ["directives:"])
    files: dict[str, str] = field(default_factory=dict)  # generated file name -> text
    decompositions: list[dict] = field(default_factory=list)  # what each mesh decomposition did
    # (the robot file with decomposed mesh links, the same with Drake's hull per mesh link), if it has mesh links
    hull_robot_file: tuple[Path, Path] | None = None


def _add_robot(models: _Models, inputs: _Inputs, mesh_options: dict, cache_dir: Path | None) -> list[str]:
    """Directives for the robot (a mesh on the carrier joints, or a URDF/SDF welded or carried); its instances."""
    if inputs.robot_kind == "mesh":
        decomposition = meshes.decompose(inputs.robot_path, **mesh_options)
        models.decompositions.append(_describe(inputs.robot_path, decomposition))
        models.files["robot.urdf"] = carrier_urdf("robot", _mesh_elements_urdf(decomposition))
        models.directives += [
            "- add_model:",
            "    name: robot",
            f"    file: {_quoted_uri('@DIR@/robot.urdf')}",
            "- add_weld:",
            "    parent: world",
            "    child: robot::origin",
        ]
        return ["robot"]
    before = len(models.decompositions)
    found = models.decompositions
    # A link's mesh may be larger than the link, never smaller: CAD exports (open slivers, unstitched faces) become
    # hulls in seconds instead of failing exact validation after minutes (app.scene.meshes.choose_method).
    link_options = {**mesh_options, "conservative": True}
    robot_file = convert_model_meshes(inputs.robot_path, inputs.packages, cache_dir, link_options, found)
    if len(models.decompositions) > before:
        # The same robot with Drake's convex hull per mesh link, to measure what the decomposition changes.
        models.hull_robot_file = (robot_file, convert_model_meshes(inputs.robot_path, inputs.packages, cache_dir))
    probe = probe_model(robot_file, inputs.packages)
    if not inputs.floating:
        models.directives += ["- add_model:", "    name: robot", f"    file: {_quoted_uri(robot_file)}"]
        for body in probe["floating"]:
            models.directives += ["- add_weld:", "    parent: world", f"    child: robot::{body}"]
        return ["robot"]
    if len(probe["floating"]) != 1:
        raise UserError(
            f"{inputs.robot_path.name}: a floating robot needs one root body not attached to the world, "
            f"found {len(probe['floating'])}"
        )
    # The carrier first, so that its x, y, z, yaw, pitch, roll are the first six coordinates.
    models.files["carrier.urdf"] = carrier_urdf("carrier")
    models.directives += [
        "- add_model:",
        "    name: carrier",
        f"    file: {_quoted_uri('@DIR@/carrier.urdf')}",
        "- add_weld:",
        "    parent: world",
        "    child: carrier::origin",
        "- add_model:",
        "    name: robot",
        f"    file: {_quoted_uri(robot_file)}",
        "- add_weld:",
        "    parent: carrier::body",
        f"    child: robot::{probe['floating'][0]}",
    ]
    return ["carrier", "robot"]


def _add_environment(
    models: _Models, inputs: _Inputs, mesh_options: dict, cache_dir: Path | None
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Directives for the environment models (static, or one rigid body welded at its pose); the world boxes
    (lo, hi) of the mesh ones, for default bounds."""
    boxes = []
    for i, (path, kind, pose) in enumerate(zip(inputs.env_paths, inputs.env_kinds, inputs.env_poses)):
        name = f"env{i}"
        if kind == "mesh":
            decomposition = meshes.decompose(path, **mesh_options)
            models.decompositions.append(_describe(path, decomposition))
            models.files[f"{name}.urdf"] = env_urdf(name, decomposition, pose)
            models.directives += ["- add_model:", f"    name: {name}", f"    file: {_quoted_uri(f'@DIR@/{name}.urdf')}"]
            boxes.append(_world_box(np.array(decomposition.extent()), pose))
            continue
        model_file = convert_model_meshes(path, inputs.packages, cache_dir, mesh_options, models.decompositions)
        probe = probe_model(model_file, inputs.packages)
        models.directives += ["- add_model:", f"    name: {name}", f"    file: {_quoted_uri(model_file)}"]
        if probe["floating"]:
            models.directives += [
                "- add_weld:",
                "    parent: world",
                f"    child: {name}::{probe['floating'][0]}",
                _pose_yaml(pose).rstrip("\n"),
            ]
            if len(probe["floating"]) > 1:
                raise UserError(f"{path.name}: an environment model must be static or one rigid body")
        elif any(pose):
            raise UserError(
                f"{path.name}: a static SDF model cannot be moved by an env pose; set its <pose> in the file"
            )
    return boxes


def _write_scene_dir(models: _Models, robot_directives: list[str], packages: dict[str, Path], root: Path) -> Path:
    """The scene directory, named by a hash of what defines it: the generated files, robot.dmd.yaml (the robot
    alone, whose coordinates are the scene's: the environment adds none) and scene.dmd.yaml."""
    key_text = "\n".join(models.directives) + "".join(models.files.values()) + repr(sorted(packages.items()))
    scene_dir = root / "scenes" / hashlib.sha256(key_text.encode()).hexdigest()[:24]
    for name, text in models.files.items():
        _write(scene_dir / name, text)
    # @DIR@ only stands inside quoted URIs (_quoted_uri), so it is replaced by the folder escaped as in one.
    folder = json.dumps(str(scene_dir))[1:-1]
    _write(scene_dir / "robot.dmd.yaml", "\n".join(robot_directives).replace("@DIR@", folder) + "\n")
    _write(scene_dir / "scene.dmd.yaml", "\n".join(models.directives).replace("@DIR@", folder) + "\n")
    return scene_dir


def _problem(
    spec: CustomSpec,
    inputs: _Inputs,
    coords: dict,
    robot_instances: list[str],
    env_boxes: list[tuple[np.ndarray, np.ndarray]],
    resolution: float,
) -> dict:
    """The problem file's keys: start, goal, limits and weights from the probed robot, and the edge-check step."""
    nq = len(coords["names"])
    angular = np.array([k == "revolute" for k in coords["kinds"]])
    home = np.zeros(nq)
    start = _vector(spec.start, nq, "start", coords["names"]) if spec.start else home
    goal = _vector(spec.goal, nq, "goal", coords["names"]) if spec.goal else home
    lower, upper = _limits(coords, angular, inputs, start, goal, env_boxes)
    start = start if spec.start else np.clip(home, lower, upper)
    goal = goal if spec.goal else np.clip(home, lower, upper)
    # Weights: an angle's weight is the lever arm it swings (the robot's radius or reach), metres weigh 1.
    lever = max(coords["reach"], 1e-6)
    weights = np.where(angular, lever, 1.0)
    with np.errstate(over="ignore", invalid="ignore"):
        diagonal = float(np.linalg.norm((upper - lower) * weights))
    if not math.isfinite(diagonal):
        raise UserError("the bounds are too large to plan in: their diagonal is not a finite number (give bounds)")
    # (as app.scene.model.Scene checks it: here, so that the message names the value, not a generated file)
    if not MIN_RESOLUTION * diagonal <= resolution <= diagonal:
        raise UserError(
            f"resolution must be from {MIN_RESOLUTION:g} x the bounds' diagonal ({MIN_RESOLUTION * diagonal:.3g}) to "
            f"the diagonal ({diagonal:.3g}), got {resolution:g}"
        )
    env_names = ", ".join(p.name for p in inputs.env_paths) or "-"
    # A joint without a velocity limit gets 1 (m/s or rad/s), so the trajectory has a sensible duration.
    model_velocity = np.where(np.isfinite(coords["velocity"]) & (coords["velocity"] > 0), coords["velocity"], 1.0)
    limits = {}
    for key, given in (("velocity_limits", spec.velocity_limits), ("acceleration_limits", spec.acceleration_limits)):
        if given:
            limits[key] = _vector(given, nq, key, coords["names"])
            if not np.all(limits[key] > 0):
                raise UserError(f"{key} must be positive numbers")
            limits[key] = limits[key].tolist()
    return {
        "description": spec.description or f"{inputs.robot_path.name} among {env_names}",
        "directives": "scene.dmd.yaml",
        "robot": robot_instances,
        "collisions": spec.collisions,
        "srdf": str(inputs.srdf_path or ""),
        "lower": lower.tolist(),
        "upper": upper.tolist(),
        "start": start.tolist(),
        "goal": goal.tolist(),
        "weights": weights.tolist(),
        "resolution": float(resolution),
        "view": "3d",
        "velocity_limits": model_velocity.tolist(),
        "mimic": coords["mimic"],
        **limits,  # the Scene's default accelerations: twice its velocity limits
    }


def _check_vectors(spec: CustomSpec, coords: dict) -> None:
    """Start, goal and limits hold one finite number per coordinate: checked as soon as the robot is known, before
    the environment's meshes are decomposed (which can take minutes)."""
    given = {
        "start": spec.start,
        "goal": spec.goal,
        "velocity_limits": spec.velocity_limits,
        "acceleration_limits": spec.acceleration_limits,
    }
    for what, values in given.items():
        if values:
            _vector(values, len(coords["names"]), what, coords["names"])


def default_resolution(coords: dict) -> float:
    """The edge-check step: a quarter of the robot's thickness (median over its bodies of their smallest width), so a
    step cannot carry it across a wall as thick as itself; at least 1/1000 of its reach."""
    return max(0.25 * coords["thin"], 1e-3 * max(coords["reach"], 1e-6))


def _limits(
    coords: dict,
    angular: np.ndarray,
    inputs: _Inputs,
    start: np.ndarray,
    goal: np.ndarray,
    env_boxes: list[tuple[np.ndarray, np.ndarray]],
) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper limits: the given bounds, else the joints' own (angles without any: one turn); a floating robot's
    x, y, z default to the environment's box grown by the robot's reach and stretched to hold start and goal."""
    nq = len(coords["names"])
    floating, bounds = inputs.floating, inputs.bounds
    lower = np.where(np.isfinite(coords["lower"]), coords["lower"], -math.pi)
    upper = np.where(np.isfinite(coords["upper"]), coords["upper"], math.pi)
    lower = np.where(angular | np.isfinite(coords["lower"]), lower, np.nan)
    upper = np.where(angular | np.isfinite(coords["upper"]), upper, np.nan)
    if floating:
        lower[:3], upper[:3] = -1e4, 1e4
        lower[3:6], upper[3:6] = -math.pi, math.pi
    if bounds:
        _check_bounds_count(bounds, coords["names"], floating)
        if len(bounds) == nq:
            lower, upper = np.array([b[0] for b in bounds]), np.array([b[1] for b in bounds])
        else:
            lower[:3], upper[:3] = [b[0] for b in bounds], [b[1] for b in bounds]
    elif floating:
        if not env_boxes:
            raise UserError("a floating robot with no environment needs bounds for x, y, z")
        margin = coords["reach"]
        env_lo = np.min([lo for lo, _ in env_boxes], axis=0)
        env_hi = np.max([hi for _, hi in env_boxes], axis=0)
        lower[:3] = np.minimum(env_lo - margin, np.minimum(start[:3], goal[:3]))
        upper[:3] = np.maximum(env_hi + margin, np.maximum(start[:3], goal[:3]))
    if not np.all(np.isfinite(lower) & np.isfinite(upper)):
        missing = [coords["names"][i] for i in range(nq) if not (np.isfinite(lower[i]) and np.isfinite(upper[i]))]
        raise UserError(f"no limits for {', '.join(missing)}: give bounds")
    if np.any(lower >= upper):
        i = int(np.flatnonzero(lower >= upper)[0])
        raise UserError(
            f"{inputs.robot_path.name}: joint '{coords['names'][i]}': lower limit {lower[i]:g} is not below upper "
            f"limit {upper[i]:g}, no room to move (give bounds)"
        )
    return lower, upper


def _describe(path: Path, d: meshes.Decomposition) -> dict:
    if len(d.pieces) > 400:
        import sys

        print(
            f"warning: {path.name} became {len(d.pieces)} convex pieces (tolerance "
            f"{d.validation.get('tolerance', 0):.3g} m); Drake's set-up time grows with the square of that (about "
            f"5 s at 1000, 20 s at 2000); a larger --mesh-tolerance gives fewer",
            file=sys.stderr,
        )
    return {
        "mesh": path.name,
        "method": d.method,
        "pieces": len(d.pieces),
        "parts": d.parts,
        "volume": d.volume,
        "from_cache": d.from_cache,
        "seconds": round(d.seconds, 3),
        "validation": {
            k: d.validation.get(k) for k in ("ok", "tolerance", "near_surface_points", "free_points", "violations")
        },
    }


def _vector(values, nq: int, what: str, names: list[str]) -> np.ndarray:
    vector = np.asarray(values, float)
    if vector.shape != (nq,):
        raise UserError(f"{what} needs {nq} numbers ({', '.join(names)}), got {len(values)}")
    if not np.all(np.isfinite(vector)):
        bad = int(np.flatnonzero(~np.isfinite(vector))[0])
        raise UserError(f"{what} needs finite numbers, {names[bad]} is {vector[bad]}")
    if np.any(np.abs(vector) > MAX_MODEL_NUMBER):
        bad = int(np.flatnonzero(np.abs(vector) > MAX_MODEL_NUMBER)[0])
        raise UserError(f"{what} needs numbers within +-{MAX_MODEL_NUMBER:g}, {names[bad]} is {vector[bad]:g}")
    return vector


def hull_disagreement(
    scene_dir: Path, pieces_file: Path, hull_file: Path, inputs: _Inputs, robot_instances: list[str], samples=300
) -> dict:
    """How often the robot alone collides with itself at uniform random configurations (seeded), with its mesh links
    as Drake's convex hulls and as the validated pieces (adjacent links and SRDF pairs left out in both, as the scene
    leaves them out): `hull_only` is the fraction that collide as hulls but not as pieces, what the decomposition
    saves self-collision checking from."""
    from pydrake.multibody.parsing import LoadModelDirectives, ProcessModelDirectives

    from app.scene.model import exclude_adjacent_bodies, exclude_body_pairs, read_srdf

    pairs = read_srdf(inputs.srdf_path) if inputs.srdf_path else []
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
    _write(hulls, exact.read_text().replace(str(pieces_file), str(hull_file)))
    rng = np.random.default_rng(0)
    collide = []
    for directives in (hulls, exact):
        builder = _new_builder(inputs.packages)
        plant = builder.plant()
        ProcessModelDirectives(LoadModelDirectives(str(directives)), builder.parser())
        plant.Finalize()
        instances = [plant.GetModelInstanceByName(n) for n in robot_instances]
        exclude_adjacent_bodies(plant, builder.scene_graph(), instances)
        exclude_body_pairs(plant, builder.scene_graph(), instances, pairs, inputs.srdf_path)
        diagram = builder.Build()
        root = diagram.CreateDefaultContext()
        context = diagram.plant().GetMyContextFromRoot(root)
        if not collide:  # the same configurations for both, within the joint limits (none: one turn)
            lower, upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
            lower, upper = np.where(np.isfinite(lower), lower, -math.pi), np.where(np.isfinite(upper), upper, math.pi)
            Q = rng.uniform(lower, upper, (samples, plant.num_positions()))
        port = diagram.plant().get_geometry_query_input_port()
        hits = []
        for q in Q:
            diagram.plant().SetPositions(context, q)
            hits.append(port.Eval(context).HasCollisions())
        collide.append(np.array(hits))
    found = {
        "samples": samples,
        "hull_self_collision": float(collide[0].mean()),
        "pieces_self_collision": float(collide[1].mean()),
        "hull_only": float((collide[0] & ~collide[1]).mean()),
    }
    _write(kept, json.dumps(found) + "\n")
    return found


# ---- entry points -------------------------------------------------------------------------------------------------
def is_custom_scene_file(path: Path) -> bool:
    """A YAML scene file whose `robot` is a file name (not a list of model instances) or that has an `env` key."""
    from pydrake.common.yaml import yaml_load

    try:
        data = yaml_load(filename=str(path))
    except Exception:
        return False
    return isinstance(data, dict) and (isinstance(data.get("robot"), str) or "env" in data)


def read_spec(path: Path) -> CustomSpec:
    from pydrake.common.yaml import yaml_load_typed

    check_input(path, "scene file")
    try:
        return yaml_load_typed(schema=CustomSpec, filename=str(path))
    except Exception as exc:
        raise UserError(f"bad scene file {path.name}: {' '.join(str(exc).split())[:300]}") from None


def load_scene(name_or_path: str, cache_dir: Path | None = None) -> Scene:
    """A shipped scene, a problem file, or a custom scene file (robot/env keys): the one loader commands need."""
    path = Path(name_or_path)
    if path.suffix == ".yaml" and is_custom_scene_file(check_input(path, "scene file")):
        return build_scene(read_spec(path), base=path.resolve().parent, cache_dir=cache_dir, source=path.name)
    return Scene(name_or_path)
