"""Stage (a) of a custom scene: its inputs read and checked, every file once, before any mesh is read.

`read_inputs` refuses whatever it can as one-line UserErrors naming the user's file: the keys, package paths,
file types and sizes, env poses, bounds, each model file (app.scene.model_files: its XML, numbers, <mimic> elements,
references) and, for a URDF, Drake's parser on it without its geometry (which reads no mesh): its joints, their
types and limits, mimic joints that cannot follow, its root bodies (a floating robot has one; an environment model
is static or one rigid body), the SRDF's links, and the number of start, goal, limit and bounds values. An SDF is
read by Drake only with its meshes, once they are converted (app.scene.emit): what Drake's parser refuses in it, and
its coordinates, are known then. (So is one refusal that the meshes decide: a floating robot given no bounds takes
them from the environment meshes' box, and with none of them is refused in app.scene.coordinates; a robot mesh that
cannot be read is named first.) Notes on what a model file had ignored follow once all passed.
"""

import warnings
from pathlib import Path

from app.errors import Note, UserError
from app.io import check_input
from app.scene.drake_parser import read_bare_urdf
from app.scene.files import MESH_METHODS
from app.scene.model_files import ModelFile, read_model_file, read_srdf
from app.scene.spec import (
    CustomSpec,
    SceneInputs,
    check_bounds_count,
    check_environment_roots,
    check_keys,
    check_robot_roots,
    check_srdf_links,
    check_vectors,
    coordinate_names,
    file_kind,
    parse_bounds,
    parse_package_paths,
    parse_poses,
)

_notes_said: set[str] = set()  # the notes this process has printed (a scene may be built more than once)


def read_inputs(spec: CustomSpec, base: Path) -> SceneInputs:
    """Every check that needs no mesh read, so bad input fails before any (slow) mesh decomposition (see the module's
    docstring). Relative paths are taken from `base`."""

    def resolve(p: str) -> Path:
        path = Path(p).expanduser()
        return (path if path.is_absolute() else base / path).resolve()

    check_keys(spec, MESH_METHODS)
    packages = parse_package_paths(spec.package_path, base)
    robot_path = resolve(spec.robot)
    robot_kind = file_kind(robot_path, "robot")
    env_paths = [resolve(p) for p in spec.env]
    env_kinds = [file_kind(p, "environment") for p in env_paths]
    poses = parse_poses(spec.env_pose, len(env_paths)) if env_paths else []
    if spec.env_pose and not env_paths:
        raise UserError("an env pose needs an environment file")
    models: dict[Path, ModelFile] = {}
    for path, kind in [(robot_path, robot_kind), *zip(env_paths, env_kinds)]:
        if kind == "model" and path not in models:
            models[path] = read_model(path, packages)
    srdf_path = resolve(spec.srdf) if spec.srdf else None
    srdf_pairs = read_srdf(srdf_path) if srdf_path is not None else []
    if srdf_path is not None:
        check_srdf_links(
            srdf_path, srdf_pairs, models.get(robot_path) if robot_path.suffix.lower() == ".urdf" else None
        )
    bounds = parse_bounds(spec.bounds)
    floating = robot_kind == "mesh" or spec.floating
    names = coordinate_names(robot_path, floating, models.get(robot_path), spec.hold)
    if names is not None:
        check_vectors(spec, names)
        check_bounds_count(bounds, names, floating)
    _check_urdf_bodies(models, robot_path, floating, zip(env_paths, poses))
    for path, model in models.items():
        _say_notes(path, model.notes)
    return SceneInputs(
        packages, robot_path, robot_kind, floating, env_paths, env_kinds, poses, bounds, srdf_path, srdf_pairs, models
    )


def read_model(path: Path, packages: dict[str, Path]) -> ModelFile:
    """A model file read (app.scene.model_files) and, for a URDF, Drake's parser on it without its geometry."""
    model = read_model_file(path, packages)
    if model.urdf:
        found = read_bare_urdf(model.text, path, packages)
        model.joints, model.roots = found["joints"], found["floating"]
        model.lower, model.upper = found["lower"], found["upper"]
    return model


def _check_urdf_bodies(models: dict[Path, ModelFile], robot_path: Path, floating: bool, env) -> None:
    """What a URDF's bodies tell before its meshes are read: a robot with collision geometry (on some link) and, if
    it floats, one root body; an environment model static or one rigid body. (An SDF's are told when it is read.)"""
    robot = models.get(robot_path)
    if robot is not None and robot.urdf:
        if not robot.collision_links:
            raise UserError("the robot has no collision geometry")
        check_robot_roots(robot_path, robot.roots, floating)
    for path, pose in env:
        model = models.get(path)
        if model is not None and model.urdf:
            check_environment_roots(path, model.roots, pose)


def _say_notes(path: Path, notes: list[str]) -> None:
    line = f"{path.name}: {'; '.join(notes)}"
    if notes and line not in _notes_said:
        _notes_said.add(line)
        warnings.warn(line, Note, stacklevel=3)


# ---- scene files --------------------------------------------------------------------------------------------------
def is_custom_scene_file(path: Path) -> bool:
    """A YAML scene file whose `robot` is a file name (not a list of model instances) or that has an `env` key."""
    from pydrake.common.yaml import yaml_load

    try:
        data = yaml_load(filename=str(path))
    except Exception:
        return False
    return isinstance(data, dict) and (isinstance(data.get("robot"), str) or "env" in data)


def read_spec(path: Path) -> CustomSpec:
    """A custom scene file's keys (Drake's typed YAML loader: an unknown key is an error)."""
    from pydrake.common.yaml import yaml_load_typed

    check_input(path, "scene file")
    try:
        return yaml_load_typed(schema=CustomSpec, filename=str(path))
    except Exception as exc:
        raise UserError(f"bad scene file {path.name}: {' '.join(str(exc).split())[:300]}") from None
