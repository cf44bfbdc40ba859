"""A custom scene's spec as plain data (stage (a)): the keys a user gives (`CustomSpec`, from a scene file or `plan`'s
flags) and the same inputs checked, with paths resolved and model files read (`SceneInputs`), and the checks that
refuse bad input, each a one-line UserError. No Drake objects, and no Drake: app.scene.inputs reads the files and
asks Drake's parser about a URDF; what is built from the inputs comes in the stages after."""

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.errors import UserError
from app.io import check_input
from app.scene.cspace import PositionMap
from app.scene.files import MAX_MODEL_NUMBER, MESH_SUFFIXES, MODEL_SUFFIXES
from app.scene.model_files import ModelFile

# The coordinates a floating robot (a mesh robot, or a URDF/SDF robot with `floating`) is carried by, first.
CARRIER_JOINTS = ("x", "y", "z", "yaw", "pitch", "roll")


@dataclass
class CustomSpec:
    """The keys of a custom scene file (YAML), also built from `plan`'s flags. Paths in a file are relative to it.

    Attributes:
        description: A line about the scene.
        robot: The robot: .urdf/.sdf, or a mesh file (a free-flying body).
        package_path: NAME=DIR entries that resolve package://NAME/... in the robot's files.
        floating: Carry a URDF/SDF robot's root in SE(3) instead of welding it to the world.
        env: Obstacles: mesh or .sdf/.urdf files.
        env_pose: 6 numbers (x, y, z in m; roll, pitch, yaw in degrees), or 6 per env file.
        start: The start, one value per coordinate; empty: the robot's home (zero, clipped into the bounds).
        goal: The goal; empty: the home too (a caller then sets it, e.g. from a pose).
        bounds: "lo..hi" per coordinate, or per x, y, z of a floating robot.
        collisions: "all": the robot against itself too; "environment": only against the obstacles.
        srdf: A MoveIt SRDF whose <disable_collisions> body pairs are not checked.
        resolution: The edge-check step in the weighted metric; 0: default_resolution (the robot's size).
        mesh_method: auto (hulls that hold each mesh and stay within its tolerance of it, a robot link's within
            5 mm), convex, shell, coacd or faces.
        mesh_tolerance: How far a decomposition may reach beyond the mesh surface; 0: half the edge-check step
            (environment), 0.2 % of its size (robot mesh).
        velocity_limits: Per coordinate; empty: the model's (else 1).
        acceleration_limits: Per coordinate; empty: twice the velocity limits.
        hold: Joints that stay where they are, by name: position (no coordinates of the space; e.g. a MoveIt
            request's joints outside its planning group). Start, goal, bounds and limits then name the others.
        allowed_collisions: Pairs of bodies (robot links, or links of an environment SDF) never checked against each
            other (a MoveIt allowed-collision matrix's entries; an SRDF's pairs name robot links only).
    """

    description: str = ""
    robot: str = ""
    package_path: list[str] = field(default_factory=list)
    floating: bool = False
    env: list[str] = field(default_factory=list)
    env_pose: list[float] = field(default_factory=list)
    start: list[float] = field(default_factory=list)
    goal: list[float] = field(default_factory=list)
    bounds: list[str] = field(default_factory=list)
    collisions: str = "all"
    srdf: str = ""
    resolution: float = 0.0
    mesh_method: str = "auto"
    mesh_tolerance: float = 0.0
    velocity_limits: list[float] = field(default_factory=list)
    acceleration_limits: list[float] = field(default_factory=list)
    hold: dict[str, float] = field(default_factory=dict)
    allowed_collisions: list[list[str]] = field(default_factory=list)


@dataclass
class SceneInputs:
    """A spec's inputs, checked, with paths resolved and every model file read (app.scene.inputs.read_inputs)."""

    packages: dict[str, Path]
    robot_path: Path
    robot_kind: str  # "model" or "mesh"
    floating: bool  # carried by the x, y, z, yaw, pitch, roll joints
    env_paths: list[Path]
    env_kinds: list[str]
    env_poses: list[list[float]]
    bounds: list[tuple[float, float]]
    srdf_path: Path | None
    srdf_pairs: list[tuple[str, str]]
    models: dict[Path, ModelFile]  # every model file named (robot, environment), read once

    @property
    def robot_model(self) -> ModelFile | None:
        return self.models.get(self.robot_path)

    def mimics(self) -> list[dict]:
        """The robot's mimic joints (a URDF's <mimic> elements), as the problem file's `mimic` entries."""
        model = self.robot_model
        return model.mimics() if model is not None and model.urdf else []


# ---- the keys -----------------------------------------------------------------------------------------------------
def check_keys(spec: CustomSpec, methods: tuple[str, ...]) -> None:
    """The keys that need no file: a robot given, known choices, step and tolerance not negative."""
    if not spec.robot:
        raise UserError("a robot is required (a .urdf/.sdf file or a mesh)")
    if spec.collisions not in ("environment", "all"):
        raise UserError("collisions must be 'environment' or 'all'")
    if spec.mesh_method not in methods:
        raise UserError(f"unknown mesh method '{spec.mesh_method}' (known: {', '.join(methods)})")
    if not (0 <= spec.resolution < math.inf and 0 <= spec.mesh_tolerance < math.inf):
        raise UserError("resolution and mesh tolerance must be finite and not negative")


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


def file_kind(path: Path, what: str) -> str:
    """The kind of an existing input file within its kind's size: "model" (a URDF/SDF) or "mesh"."""
    if not path.is_file():
        raise UserError(f"{what} file not found: {path}")
    suffix = path.suffix.lower()
    if suffix in MODEL_SUFFIXES:
        check_input(path, "model file")
        return "model"
    if suffix in MESH_SUFFIXES:
        check_input(path, "mesh file")
        return "mesh"
    raise UserError(
        f"{what} file {path.name}: unsupported type '{suffix}' (use .urdf, .sdf or a mesh: "
        f"{', '.join(sorted(MESH_SUFFIXES))})"
    )


# ---- the coordinates ----------------------------------------------------------------------------------------------
def coordinate_names(
    robot_path: Path, floating: bool, found: ModelFile | None, held: dict[str, float]
) -> list[str] | None:
    """The scene's coordinates as far as they are known before any mesh work (a mesh robot's carrier; a URDF
    robot's joints as Drake's parser makes them, mimic and `held` joints left out, after the carrier's when it
    floats); None for an SDF robot. Joint types the planner does not take, mimic joints that cannot follow,
    mimicked joints whose mimic joints leave them no room, and held joints outside their limits, are refused."""
    if found is None:
        if floating and held:
            raise UserError("a mesh robot has no joints to hold")
        return list(CARRIER_JOINTS) if floating else None
    if found.joints is None:
        return None
    joints = [(name, kind, count) for name, kind, count, ephemeral in found.joints if not ephemeral]
    bad = sorted({kind for _, kind, _ in joints if kind not in ("revolute", "prismatic")})
    if bad:
        raise UserError(f"robot joints of type {', '.join(bad)} are not supported (revolute and prismatic only)")
    names = [name for name, _, count in joints for _ in range(count)]
    mimics = found.mimics()
    try:
        mimic = PositionMap.of(names, [(m["joint"], m["follows"], m["multiplier"], m["offset"]) for m in mimics], held)
    except UserError as exc:
        raise UserError(f"{robot_path.name}: {exc}") from None
    if mimic is None:
        planned = names
    else:
        planned = mimic_limited(mimic, names, np.array(found.lower), np.array(found.upper), robot_path)[0]
    return (list(CARRIER_JOINTS) if floating else []) + planned


def mimic_limited(
    mimic: PositionMap, names: list[str], lower: np.ndarray, upper: np.ndarray, robot_file: Path
) -> tuple[list[str], np.ndarray, np.ndarray]:
    """The planned coordinates' names and position limits (positions' `names`, `lower`, `upper` in plant order):
    a mimicked joint's limits narrowed so that the joints mimicking it stay within theirs; one with no room left,
    or a held joint outside its limits, is a UserError naming it."""
    try:
        mimic.check_held(lower, upper)
    except UserError as exc:
        raise UserError(f"{robot_file.name}: {exc}") from None
    mimic_lower, mimic_upper = mimic.coordinate_limits(lower, upper)
    planned = mimic.planned
    names = [names[i] for i in planned]
    lower, upper = np.maximum(lower[planned], mimic_lower), np.minimum(upper[planned], mimic_upper)
    if np.any(lower >= upper):
        bad = names[int(np.flatnonzero(lower >= upper)[0])]
        raise UserError(
            f"{robot_file.name}: joint '{bad}': no position keeps the joints that mimic it within their limits"
        )
    return names, lower, upper


def check_vector(values, nq: int, what: str, names: list[str]) -> np.ndarray:
    """One finite number per coordinate, each within MAX_MODEL_NUMBER."""
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


def check_vectors(spec: CustomSpec, names: list[str]) -> None:
    """Start, goal and limits hold one finite number per coordinate: checked as soon as the robot's coordinates are
    known, before any mesh is decomposed (an SDF robot's: before the environment's)."""
    given = {
        "start": spec.start,
        "goal": spec.goal,
        "velocity_limits": spec.velocity_limits,
        "acceleration_limits": spec.acceleration_limits,
    }
    for what, values in given.items():
        if values:
            check_vector(values, len(names), what, names)


def check_bounds_count(bounds: list[tuple[float, float]], names: list[str], floating: bool) -> None:
    if bounds and not (len(bounds) == len(names) or (floating and len(bounds) == 3)):
        raise UserError(
            f"bounds: {len(names)} lo..hi items needed (one per coordinate: {', '.join(names)})"
            + (" or 3 for x, y, z" if floating else "")
            + f"; got {len(bounds)}"
        )


# ---- the models ---------------------------------------------------------------------------------------------------
def check_srdf_links(srdf_path: Path, pairs: list[tuple[str, str]], robot: ModelFile | None) -> None:
    """The SRDF names only links of the URDF robot (an SDF's nested models scope their names, so its links are
    checked when it is loaded)."""
    if robot is None or robot.links is None:
        return
    unknown = sorted({name for pair in pairs for name in pair} - robot.links)
    if unknown:
        raise UserError(f"SRDF {srdf_path.name}: unknown link(s) {', '.join(unknown)} (not bodies of the robot)")


def check_robot_roots(path: Path, roots: list[str], floating: bool) -> None:
    """A floating robot is carried by its one body attached to nothing (a welded one has every such body welded)."""
    if floating and len(roots) != 1:
        raise UserError(
            f"{path.name}: a floating robot needs one root body not attached to the world, found {len(roots)}"
        )


def check_environment_roots(path: Path, roots: list[str], pose: list[float]) -> None:
    """An environment model is static (nothing attached to nothing: it stays where its file puts it) or one rigid
    body (welded at its pose)."""
    if len(roots) > 1:
        raise UserError(f"{path.name}: an environment model must be static or one rigid body")
    if not roots and any(pose):
        raise UserError(f"{path.name}: a static SDF model cannot be moved by an env pose; set its <pose> in the file")
