"""OMPL.app problem files (.cfg) as scenes: a free-flying rigid body among environment meshes, in OMPL.app's frame.

OMPL.app (github.com/ompl/omplapp, read at commit 9c67afb) ships the classic rigid-body benchmarks as a .cfg file
plus two meshes. Read naively (the meshes in their file coordinates, the robot about its file origin) the same numbers
describe another, usually trivial problem: the start and goal then sit away from the passage they were chosen for.
The conventions reproduced here, and where each comes from:

- The file is INI: section [problem] with `robot` and `world` (mesh files, relative to the .cfg: gui/ompl_app.py
  lines 231-234 join them to the file's folder; benchmark/CFGBenchmark.cpp line 95 also searches it first), `start.*`,
  `goal.*` and optional `volume.min.*`/`volume.max.*`. [benchmark] and [planner] hold planner settings, not the
  problem, and are not read ([planner] repeats keys on purpose: each `aps=` is another planner). A key given twice in
  [problem] is refused (OMPL's option parser refuses it too) rather than the last one silently winning, and every
  number there must be within app.scene.files.MAX_COORDINATE in size.
- 3-D or 2-D: a problem with `start.z` and `start.axis.*` is SE(3), one with none of them SE(2)
  (benchmark/BenchmarkOptions.cpp lines 222-246, isSE2Problem/isSE3Problem). A `control` key (kinematic_car,
  dynamic_car: gui/ompl_app.py lines 220-227) or a `statespace` (dubins, reedsshepp: benchmark/BenchmarkTypes.cpp
  lines 165-181) asks for a car, not a rigid body: such a problem is refused rather than planned as another one.
- SE(3) pose: position (x, y, z) and `setAxisAngle(axis.x, axis.y, axis.z, theta)` (benchmark/BenchmarkTypes.cpp
  lines 100-106; gui/ompl_app.py lines 246-259); OMPL normalises the axis, and a zero axis is the identity. The
  robot's frame is placed by translation * rotation (geometry/detail/FCLStateValidityChecker.h lines 51-52).
- SE(2) pose: (x, y) and `setYaw(theta)` (BenchmarkTypes.cpp lines 47-49), placed at height 0 rotated by theta about
  z (FCLStateValidityChecker.h lines 73-74): the plane is z = 0 of the converted mesh frame.
- Bounds bound the robot frame's position: the volume when given (BenchmarkTypes.cpp lines 79-88, 140-152), else the
  environment's vertex bounding box (geometry/RigidBodyGeometry.cpp lines 127-145 with factor 1, add 0, lines 45/53 of
  RigidBodyGeometry.h; used only when no bounds are set: apps/detail/appUtil.cpp lines 75-89), then stretched to hold
  start and goal (appUtil.cpp lines 23-73, called at apps/AppBase.h line 108, after the volume is set). In 2-D only
  x and y are bounded; the angles are free (they wrap).
- Meshes are read by assimp with aiProcess_GenNormals | Triangulate | JoinIdenticalVertices | SortByPType |
  OptimizeGraph (RigidBodyGeometry.cpp lines 52-57, 97-102); no importer property is set (no SetProperty anywhere
  in OMPL.app), so assimp's COLLADA loader applies the file's <unit meter> and converts its <up_axis> to Y up by a
  rotation on the root node: Z_UP maps (x, y, z) to (x, z, -y), X_UP maps it to (-y, x, z) (assimp
  code/AssetLib/Collada/ColladaLoader.cpp, InternReadFile: "Apply unit-size scale calculation" and "Convert to Y_UP,
  if different orientation", unless AI_CONFIG_IMPORT_COLLADA_IGNORE_UP_DIRECTION; the up-axis turn is in the
  2008 loader already, the unit in today's). Every OMPL.app resource is Z_UP: hence its 3-D problems have y up
  and negative z, and its 2-D mazes, drawn in their files' x-z plane, lie in the converted x-y plane. Other formats
  (STL, OBJ, PLY, OFF) have no up axis and keep their coordinates (glTF, y up by definition, too).
- Vertices are taken through the node hierarchy's transforms (geometry/detail/assimpUtil.cpp lines 63-76).
- The robot mesh is re-centred on its mean vertex: getRobotCenter (RigidBodyGeometry.cpp lines 173-181) is the mean
  of every vertex of every mesh (assimpUtil.cpp lines 109-117), and the robot's triangles are shifted by minus that
  (geometry/detail/FCLMethodWrapper.h lines 258-262, 298-300); in 2-D the centre's z is kept at 0
  (RigidBodyGeometry.cpp lines 166-168). "Every vertex" is after assimp's processing: one mesh per COLLADA primitive
  element (<triangles>, <polylist>, and also <lines>, whose vertices count although they are never collision
  geometry), each with its face corners joined where position, normal and texture coordinates are all equal
  (JoinIdenticalVertices; a mesh without normals gets face normals first, GenNormals). `load_mesh` counts so:
  per primitive, the distinct (position, normal, texture coordinates) corners; assimp joins within a small position
  epsilon, this exactly. For STL/OBJ/PLY/OFF files a corner is told apart by its position and face normal.
- Collision is FCL between triangle soups (FCLMethodWrapper.h lines 104-125): surfaces only. Here the meshes go through
  app.scene.meshes' validated convex decomposition: a closed part is solid, so a robot wholly inside a closed
  obstacle, valid for OMPL.app, is in collision here; open surfaces (most SketchUp exports) are thin plates in both.
  Self-collision is off (a single rigid body: apps/SE3RigidBodyPlanning.h lines 37-40). The scene's edge-check step is
  app.scene.custom's (a quarter of the robot's thickness), not OMPL's 1 % of the space's extent.

The scene is an app.scene.custom scene: an SE(3) robot is a mesh robot on the carrier joints x, y, z, yaw, pitch,
roll (R = Rz Ry Rx); an SE(2) robot has joints x, y, yaw only. Its coordinates are OMPL.app's frame, not turned to
Drake's z-up: start, goal and bounds read as in the file.
"""

from __future__ import annotations

import configparser
import hashlib
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from app.errors import UserError
from app.io import check_input, write_atomically
from app.scene import custom
from app.scene.files import MAX_COORDINATE
from app.scene.files import MESH_SUFFIXES as READ_SUFFIXES
from app.scene.meshes.cache import cache_root, obj_bytes, writable_folder
from app.scene.meshes.reading import load_mesh as load_triangles
from app.scene.spec import CustomSpec

# assimp's COLLADA up-axis conversion to Y up, as the matrix applied to a column vector (ColladaLoader.cpp).
UP_AXIS_TO_Y_UP = {
    "X_UP": np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
    "Y_UP": np.eye(3),
    "Z_UP": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
}
# Bump when the converted meshes or generated files change: they are cached by content.
CONVERSION_VERSION = "1"
_SE3_KEYS = ("z", "axis.x", "axis.y", "axis.z")
# The mesh formats both assimp and app.scene.meshes read (assimp has no VTK reader).
MESH_SUFFIXES = READ_SUFFIXES - {".vtk"}


@dataclass
class OmplAppProblem:
    """The [problem] section of an OMPL.app .cfg, checked."""

    path: Path
    name: str
    robot: Path
    world: Path
    planar: bool  # SE(2): x, y, theta; else SE(3)
    start: list[float]  # SE(2): x, y, theta; SE(3): x, y, z, axis x, y, z, theta
    goal: list[float]
    volume: tuple[list[float], list[float]] | None  # (min, max) of x, y (2-D) or x, y, z; None: not given


@dataclass
class OmplAppMesh:
    """A mesh as OMPL.app sees it: triangles in the converted frame, and the mean vertex assimp's scene has."""

    vertices: np.ndarray  # (n, 3)
    faces: np.ndarray  # (m, 3)
    mean_vertex: np.ndarray  # (3,)
    up_axis: str = ""  # the COLLADA file's <up_axis> ("" for other formats)
    info: dict = field(default_factory=dict)


# ---- reading --------------------------------------------------------------------------------------------------
def read_problem(path: str | Path) -> OmplAppProblem:
    """Parse and check an OMPL.app problem file; meshes must exist. One-line UserError for anything wrong."""
    path = check_input(Path(path), "OMPL.app problem file")
    section = _problem_section(path)
    present = [f"{end}.{k}" for end in ("start", "goal") for k in _SE3_KEYS if f"{end}.{k}" in section]
    planar = not present
    if present and len(present) != 2 * len(_SE3_KEYS):
        missing = [f"{end}.{k}" for end in ("start", "goal") for k in _SE3_KEYS if f"{end}.{k}" not in section]
        raise UserError(f"{path.name}: an SE(3) problem needs {', '.join(missing)} too (or none of them for SE(2))")
    pose_keys = ["x", "y", "theta"] if planar else ["x", "y", "z", "axis.x", "axis.y", "axis.z", "theta"]
    start = [_number(path, section, f"start.{k}") for k in pose_keys]
    goal = [_number(path, section, f"goal.{k}") for k in pose_keys]
    volume = _volume(path, section, "xy" if planar else "xyz")
    return OmplAppProblem(
        path=path,
        name=section.get("name", path.stem).strip() or path.stem,
        robot=_mesh_file_named(path, section, "robot"),
        world=_mesh_file_named(path, section, "world"),
        planar=planar,
        start=start,
        goal=goal,
        volume=volume,
    )


def _problem_section(path: Path) -> configparser.SectionProxy:
    """The file's [problem] section: given once, each key once, and no car's (`control`, `statespace`)."""
    parser = configparser.ConfigParser(interpolation=None, strict=False)
    text = path.read_text(errors="replace")
    try:
        parser.read_string(text, source=path.name)
    except configparser.Error as exc:
        raise UserError(f"bad OMPL.app problem {path.name}: {' '.join(str(exc).split())[:200]}") from None
    twice = _repeated_key(parser, text, "problem")
    if twice is not None:
        key, first, again = twice
        raise UserError(f"bad OMPL.app problem {path.name}: [problem] {key} is given twice (lines {first} and {again})")
    if not parser.has_section("problem"):
        raise UserError(f"bad OMPL.app problem {path.name}: no [problem] section")
    section = parser["problem"]
    for key in ("control", "statespace"):
        if section.get(key, "").strip():
            raise UserError(
                f"{path.name}: {key} = {section[key].strip()} asks for a car, not a free rigid body; only geometric "
                "rigid-body problems (SE(2), SE(3)) are supported"
            )
    return section


def _number(path: Path, section, key: str) -> float:
    if key not in section:
        raise UserError(f"{path.name}: [problem] has no {key}")
    try:
        value = float(section[key])
    except ValueError:
        raise UserError(f"{path.name}: {key} = {section[key]!r} is not a number") from None
    if not math.isfinite(value):
        raise UserError(f"{path.name}: {key} must be a finite number, got {section[key]}")
    if abs(value) > MAX_COORDINATE:  # (as a mesh's coordinates: beyond it, bounds overflow when subtracted)
        raise UserError(
            f"{path.name}: {key} = {section[key].strip()} is out of range (at most {MAX_COORDINATE:g} in size)"
        )
    return value


def _mesh_file_named(path: Path, section, key: str) -> Path:
    if not section.get(key, "").strip():
        raise UserError(f"{path.name}: [problem] has no {key} (a mesh file)")
    file = (path.parent / section[key].strip()).resolve()
    if not file.is_file():
        raise UserError(f"{path.name}: {key} mesh not found: {file}")
    if file.suffix.lower() not in MESH_SUFFIXES:
        raise UserError(
            f"{path.name}: {key} mesh {file.name}: unsupported format (use {', '.join(sorted(MESH_SUFFIXES))})"
        )
    return file


def _volume(path: Path, section, axes: str) -> tuple[list[float], list[float]] | None:
    """volume.min.* and volume.max.* (all of them, or none: None), min below max on every axis."""
    volume_keys = [f"volume.{end}.{a}" for end in ("min", "max") for a in axes]
    given = [k for k in volume_keys if k in section]
    if not given:
        return None
    if len(given) != len(volume_keys):
        missing = sorted(set(volume_keys) - set(given))
        raise UserError(f"{path.name}: the volume needs {', '.join(missing)} too")
    lo = [_number(path, section, f"volume.min.{a}") for a in axes]
    hi = [_number(path, section, f"volume.max.{a}") for a in axes]
    if not all(a < b for a, b in zip(lo, hi)):
        raise UserError(f"{path.name}: volume.min must be below volume.max on every axis")
    return lo, hi


def _repeated_key(parser: configparser.ConfigParser, text: str, wanted: str) -> tuple[str, int, int] | None:
    """The first key given twice in section `wanted` (which may itself appear more than once), with the lines of both,
    read line by line as configparser reads them: a line indented deeper than its key's continues that key's value,
    comments and blank lines are no keys, keys are compared as configparser stores them (lower case)."""
    section, seen, indent, in_value = None, {}, 0, False
    for number, line in enumerate(text.splitlines(), 1):
        stripped = line.strip()
        if not stripped or stripped[0] in "#;":
            continue
        depth = len(line) - len(line.lstrip())
        if in_value and depth > indent:
            continue
        indent, in_value = depth, False
        header = parser.SECTCRE.match(stripped)
        if header:
            section = header.group("header")
            continue
        option = parser._optcre.match(stripped)  # (the pattern configparser itself reads options with)
        if option is None:
            continue
        in_value = True
        if section != wanted:
            continue
        key = parser.optionxform(option.group("option").rstrip())
        if key in seen:
            return key, seen[key], number
        seen[key] = number
    return None


def load_mesh(path: str | Path) -> OmplAppMesh:
    """The triangles and the mean vertex of a mesh file as OMPL.app's assimp import has them (module docstring)."""
    path = check_input(Path(path), "mesh file")
    if path.suffix.lower() == ".dae":
        return _load_collada(path)
    mesh = load_triangles(path)
    vertices, faces = np.asarray(mesh.vertices, float), np.asarray(mesh.faces)
    corners = np.hstack([vertices[faces].reshape(-1, 3), np.repeat(mesh.face_normals, 3, axis=0)])
    distinct = np.unique(corners, axis=0)
    return OmplAppMesh(vertices, faces, distinct[:, :3].mean(axis=0), info={"counted_vertices": len(distinct)})


def _load_collada(path: Path) -> OmplAppMesh:
    try:
        import collada
        from collada.common import DaeBrokenRefError, DaeUnsupportedError
    except ImportError:
        raise UserError("mesh support needs the 'meshes' extra: pip install -e '.[meshes]'") from None
    try:
        with warnings.catch_warnings():  # pycollada builds numpy.matrix objects, which numpy warns about
            warnings.simplefilter("ignore", PendingDeprecationWarning)
            document = collada.Collada(str(path), ignore=[DaeUnsupportedError, DaeBrokenRefError])
            primitives = (
                [p for g in document.scene.objects("geometry") for p in g.primitives()] if document.scene else []
            )
    except Exception as exc:  # pycollada raises many types (DaeError, XML errors, KeyError, ...)
        raise UserError(
            f"cannot read mesh {path.name}: {' '.join(str(exc).split())[:200] or type(exc).__name__}"
        ) from None
    up_axis = str(document.assetInfo.upaxis or "Y_UP")
    unit = float(document.assetInfo.unitmeter or 1.0)
    if up_axis not in UP_AXIS_TO_Y_UP or not (math.isfinite(unit) and unit > 0):
        raise UserError(f"cannot read mesh {path.name}: up axis {up_axis!r}, unit {unit!r}")
    to_ompl = unit * UP_AXIS_TO_Y_UP[up_axis]
    triangles, counted = [], []
    for primitive in primitives:
        if primitive.vertex is None or not np.asarray(primitive.vertex_index).size:
            continue
        faces_of = _triangle_set(primitive)
        if faces_of is not None:
            triangles.append(np.asarray(faces_of.vertex)[np.asarray(faces_of.vertex_index)])
        counted.append(_distinct_corners(primitive, faces_of))
    if not triangles:
        raise UserError(f"cannot read mesh {path.name}: no triangles in it")
    soup = np.vstack(triangles).reshape(-1, 3) @ to_ompl.T
    if not np.all(np.isfinite(soup)):
        raise UserError(f"cannot read mesh {path.name}: a vertex has a coordinate that is not a finite number")
    vertices, inverse = np.unique(soup, axis=0, return_inverse=True)
    faces = inverse.reshape(-1, 3)
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    everything = np.vstack(counted) @ to_ompl.T
    return OmplAppMesh(
        vertices,
        faces,
        everything.mean(axis=0),
        up_axis,
        {"counted_vertices": len(everything), "primitives": len(counted), "unit": unit},
    )


def _triangle_set(primitive):
    """A COLLADA primitive's triangles (pycollada's BoundTriangleSet), None for lines."""
    if hasattr(primitive, "triangleset"):  # <polylist>, <polygons>: triangulated
        return primitive.triangleset()
    return primitive if hasattr(primitive, "triangles") else None


def _distinct_corners(primitive, faces_of) -> np.ndarray:
    """The positions of one primitive's corners, counted once per distinct (position, normal, texture coordinates):
    the vertices assimp's JoinIdenticalVertices leaves in that primitive's mesh."""
    index = np.asarray(primitive.vertex_index).reshape(-1)
    columns = [np.asarray(primitive.vertex)[index]]
    if primitive.normal is not None and primitive.normal_index is not None:
        columns.append(np.asarray(primitive.normal)[np.asarray(primitive.normal_index).reshape(-1)])
    elif faces_of is not None:  # no normals in the file: GenNormals gives each corner its face's normal
        corners = np.asarray(faces_of.vertex)[np.asarray(faces_of.vertex_index)]
        normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
        columns = [corners.reshape(-1, 3), np.repeat(normal, 3, axis=0)]
    for coords, coord_index in zip(
        getattr(primitive, "texcoordset", ()) or (), getattr(primitive, "texcoord_indexset", ()) or ()
    ):
        coord_index = np.asarray(coord_index).reshape(-1)
        if len(coord_index) == len(columns[0]):
            columns.append(np.asarray(coords)[coord_index])
    return np.unique(np.hstack(columns), axis=0)[:, :3]


# ---- poses --------------------------------------------------------------------------------------------------------
def axis_angle_rotation(axis: list[float], theta: float):
    """OMPL's SO3 setAxisAngle as a Drake RotationMatrix: the axis normalised, a zero axis giving the identity."""
    from pydrake.common.eigen_geometry import AngleAxis
    from pydrake.math import RotationMatrix

    norm = float(np.linalg.norm(axis))
    if norm < 1e-12:
        return RotationMatrix()
    return RotationMatrix(AngleAxis(theta, np.asarray(axis, float) / norm))


def coordinates(problem: OmplAppProblem, pose: list[float]) -> list[float]:
    """A start or goal of the file as the scene's coordinates: x, y, theta (SE(2)); x, y, z, yaw, pitch, roll
    (SE(3), R = Rz(yaw) Ry(pitch) Rx(roll), the carrier's joints)."""
    if problem.planar:
        return list(pose)
    from pydrake.math import RollPitchYaw

    roll, pitch, yaw = RollPitchYaw(axis_angle_rotation(pose[3:6], pose[6])).vector()
    return [*pose[:3], float(yaw), float(pitch), float(roll)]


def position_bounds(problem: OmplAppProblem, world: OmplAppMesh) -> tuple[np.ndarray, np.ndarray]:
    """OMPL.app's bounds on the robot frame's position: the volume, else the environment's vertex box; stretched to
    hold start and goal."""
    dims = 2 if problem.planar else 3
    if problem.volume is not None:
        lo, hi = np.array(problem.volume[0]), np.array(problem.volume[1])
    else:
        lo, hi = world.vertices.min(axis=0)[:dims], world.vertices.max(axis=0)[:dims]
    ends = np.array([problem.start[:dims], problem.goal[:dims]])
    return np.minimum(lo, ends.min(axis=0)), np.maximum(hi, ends.max(axis=0))


# ---- the scene ----------------------------------------------------------------------------------------------------
def _cached_file(cache_dir: Path | None, key_text: str, name: str, content: str | bytes) -> Path:
    """`name` holding `content` in a cache folder named by a hash of `key_text`, written (atomically) unless it holds
    exactly that already: what is there is compared, never trusted (a file someone else put there would be another
    shape)."""
    data = content.encode() if isinstance(content, str) else content
    key = hashlib.sha256((CONVERSION_VERSION + key_text).encode()).hexdigest()[:24]
    target = (cache_dir or cache_root()) / "ompl_app" / key / name
    try:
        same = target.is_file() and target.read_bytes() == data
    except OSError:
        same = False
    if not same:
        write_atomically(writable_folder(target.parent) / name, data)
    return target


def _mesh_file(cache_dir: Path | None, name: str, vertices: np.ndarray, faces: np.ndarray) -> Path:
    key = hashlib.sha256(np.ascontiguousarray(vertices).tobytes() + np.ascontiguousarray(faces).tobytes()).hexdigest()
    return _cached_file(cache_dir, key, f"{name}.obj", obj_bytes(vertices, faces))


def planar_urdf(name: str, mesh: Path, lo: np.ndarray, hi: np.ndarray) -> str:
    """A robot moving in the plane z = 0: prismatic x, y (limited to the bounds) and a continuous yaw about z."""
    inertial = '<inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>'
    geometry = f"<geometry><mesh filename={quoteattr(str(mesh))}/></geometry>"
    return "\n".join(
        [
            '<?xml version="1.0"?>',
            f'<robot name="{name}">',
            '  <link name="origin"/>',
            f'  <link name="px">{inertial}</link>',
            f'  <link name="py">{inertial}</link>',
            f'  <link name="body">{inertial}<collision name="body">{geometry}</collision>'
            f"<visual>{geometry}</visual></link>",
            f'  <joint name="x" type="prismatic"><parent link="origin"/><child link="px"/><axis xyz="1 0 0"/>'
            f'<limit lower="{float(lo[0])!r}" upper="{float(hi[0])!r}" effort="1" velocity="10"/></joint>',
            f'  <joint name="y" type="prismatic"><parent link="px"/><child link="py"/><axis xyz="0 1 0"/>'
            f'<limit lower="{float(lo[1])!r}" upper="{float(hi[1])!r}" effort="1" velocity="10"/></joint>',
            '  <joint name="yaw" type="continuous"><parent link="py"/><child link="body"/><axis xyz="0 0 1"/>'
            '<limit effort="1" velocity="10"/></joint>',
            "</robot>",
            "",
        ]
    )


def scene_spec(problem: OmplAppProblem, cache_dir: Path | None = None, **options) -> tuple[CustomSpec, dict]:
    """The custom scene spec for `problem` (converted meshes written to the cache) and what the conversion found.
    `options` are further CustomSpec keys (mesh_method, mesh_tolerance, resolution, velocity/acceleration limits)."""
    robot, world = load_mesh(problem.robot), load_mesh(problem.world)
    centre = robot.mean_vertex.copy()
    if problem.planar:
        centre[2] = 0.0
    lo, hi = position_bounds(problem, world)
    robot_file = _mesh_file(cache_dir, problem.robot.stem, robot.vertices - centre, robot.faces)
    world_file = _mesh_file(cache_dir, problem.world.stem, world.vertices, world.faces)
    bounds = [f"{float(a)!r}..{float(b)!r}" for a, b in zip(lo, hi)]
    if problem.planar:
        text = planar_urdf("robot", robot_file, lo, hi)
        robot_file = _cached_file(cache_dir, text, f"{problem.robot.stem}.urdf", text)
        bounds.append(f"{-math.pi!r}..{math.pi!r}")
    spec = CustomSpec(
        description=f"OMPL.app problem {problem.name} ({problem.path.name}, {'SE(2)' if problem.planar else 'SE(3)'})",
        robot=str(robot_file),
        env=[str(world_file)],
        start=coordinates(problem, problem.start),
        goal=coordinates(problem, problem.goal),
        bounds=bounds,
        collisions="environment",
        **options,
    )
    found = {
        "problem": str(problem.path),
        "motion": "SE(2)" if problem.planar else "SE(3)",
        "robot_centre": centre.tolist(),
        "up_axis": {"robot": robot.up_axis, "world": world.up_axis},
        "position_bounds": [lo.tolist(), hi.tolist()],
    }
    return spec, found


def build_scene(
    path: str | Path, cache_dir: Path | None = None, progress: bool = True, **options
) -> custom.CustomScene:
    """The scene of an OMPL.app problem file: read, meshes converted to OMPL.app's frame, then
    app.scene.custom.build_scene. `options`: CustomSpec keys the file does not set (see `scene_spec`)."""
    problem = read_problem(path)
    spec, found = scene_spec(problem, cache_dir, **options)
    scene = custom.build_scene(
        spec, base=problem.path.parent, cache_dir=cache_dir, progress=progress, source=problem.path.name
    )
    scene.info["ompl_app"] = found
    return scene
