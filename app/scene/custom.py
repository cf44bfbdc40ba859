"""Bring your own robot and environment: any URDF/SDF robot (or a mesh as a free-flying rigid body) among mesh or
SDF/URDF obstacles, turned into an ordinary Scene the oracle and planner accept.

Inputs (the keys of a custom scene file, see app.scene.spec.CustomSpec; `plan` takes the same as flags):
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

The route (`build_scene`), stage by stage, each a module: (a) the inputs read and checked as plain data, every
refusal before any mesh work (app.scene.inputs, app.scene.spec); then the robot alone: (b) its meshes
(app.scene.prepare_meshes), (c) its model files and directives (app.scene.emit), (d) Drake's measure of it
(app.scene.build.measure_robot), whose size sets the edge-check step; then the scene: (b) the environment's meshes at
the tolerance that step sets, (c) their files, the scene's directives and its problem file (its numbers from
app.scene.coordinates.custom_problem), (d) the Drake diagram and (e) the configuration space, which the Scene class
makes from the generated problem file, as another process does from `Scene.recipe`.
"""

import dataclasses
import functools
import time
from pathlib import Path

from app.errors import UserError
from app.io import check_input
from app.scene.build import hull_disagreement, measure_robot
from app.scene.coordinates import custom_problem
from app.scene.drake_parser import model_loading, user_words
from app.scene.emit import (
    SceneFiles,
    emit_environment,
    emit_robot,
    write_hull_directives,
    write_problem,
    write_scene_dir,
)
from app.scene.files import PACKAGES
from app.scene.inputs import is_custom_scene_file, read_inputs, read_spec
from app.scene.meshes.cache import cache_root
from app.scene.model import Scene
from app.scene.prepare_meshes import MeshOptions, prepare_environment, prepare_robot
from app.scene.spec import CustomSpec, check_vectors

# Default mesh tolerance of environment meshes, as a fraction of the edge-check step. The tolerance is how far the
# convex pieces may reach beyond the surface. Edges are checked every `resolution`: between two checks the robot
# moves up to a step, so the planner already misses overlaps about half a step deep; pieces half a step proud are
# of that order, finer than it resolves (a gap narrows by at most one step). Tied to the mesh's own size instead
# (0.2 % of its diagonal), a 3,072-triangle torus rejected CoACD's 15 pieces and fell back to ~1,500 face plates.
# Robot meshes keep app.scene.meshes' default.
ENV_TOLERANCE_PER_STEP = 0.5


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

    def packages(self) -> dict[str, Path]:
        """The shipped packages and the user's (which win a name)."""
        return {**PACKAGES, **self.extra_packages}

    def add_models(self, parser) -> None:
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


@model_loading()
def build_scene(
    spec: CustomSpec, base: Path | None = None, cache_dir: Path | None = None, progress: bool = True, source: str = ""
) -> CustomScene:
    """The Scene for `spec`. Relative paths are taken from `base` (the scene file's directory, or the cwd). `source`
    names the scene in messages (its file's name; default: the robot file's)."""
    started = time.perf_counter()
    cache_dir = Path(cache_dir).absolute() if cache_dir else None  # (see meshes.cache.cache_root)
    root = cache_dir or cache_root()
    inputs = read_inputs(spec, base or Path.cwd())
    options = MeshOptions(spec.mesh_method, spec.mesh_tolerance or None, cache_dir, progress)
    # The robot alone first (a scene directory of its own): its size sets the edge-check step, and the step sets
    # how closely the environment's pieces must follow its surfaces.
    robot_meshes = prepare_robot(inputs, options)
    files = SceneFiles()
    emit_robot(files, inputs, robot_meshes, root)
    robot_dir = write_scene_dir(files, inputs.packages, root)
    robot = measure_robot(
        robot_dir / "robot.dmd.yaml",
        inputs.packages,
        files.robot_instances,
        inputs.mimics(),
        inputs.robot_path,
        spec.hold,
    )
    resolution = spec.resolution or robot.default_resolution()
    check_vectors(spec, robot.names)  # (an SDF robot's coordinates are known only now)
    env_options = dataclasses.replace(options, tolerance=spec.mesh_tolerance or ENV_TOLERANCE_PER_STEP * resolution)
    env_meshes = prepare_environment(inputs, env_options)
    emit_environment(files, inputs, env_meshes, root)
    scene_dir = write_scene_dir(files, inputs.packages, root)
    problem = custom_problem(spec, inputs, robot, files.robot_instances, env_meshes.boxes, resolution)
    problem_path = write_problem(scene_dir, problem)
    info = {
        "robot": str(inputs.robot_path),
        "env": [str(p) for p in inputs.env_paths],
        "decompositions": robot_meshes.described + env_meshes.described,
        "prepare_seconds": time.perf_counter() - started,
    }
    if files.hull_robot_file is not None:
        write_hull_directives(scene_dir, *files.hull_robot_file)
        srdf = (inputs.srdf_path, inputs.srdf_pairs)
        info["mesh_links"] = hull_disagreement(
            scene_dir, *files.hull_robot_file, inputs.packages, srdf, files.robot_instances
        )
    name = f"{inputs.robot_path.stem}-in-{'+'.join(p.stem for p in inputs.env_paths) or 'nothing'}"
    load_started = time.perf_counter()
    scene = CustomScene(problem_path, inputs.packages, name, info, source or inputs.robot_path.name)
    info["drake_load_seconds"] = time.perf_counter() - load_started
    info["scene_dir"] = str(scene_dir)
    return scene


def load_scene(name_or_path: str, cache_dir: Path | None = None) -> Scene:
    """A shipped scene, a problem file, or a custom scene file (robot/env keys): the one loader commands need."""
    path = Path(name_or_path)
    if path.suffix == ".yaml" and is_custom_scene_file(check_input(path, "scene file")):
        return build_scene(read_spec(path), base=path.resolve().parent, cache_dir=cache_dir, source=path.name)
    return Scene(name_or_path)
