"""Stage (b) of a custom scene: the meshes its inputs name, prepared (decomposed into validated convex pieces and
cached by app.scene.meshes, or converted to .obj where Drake cannot read them), with what each became.

The robot's: a mesh robot, or each <collision> mesh of its URDF/SDF (conservative: a link's pieces may be larger
than the link, never smaller; CAD exports become hulls in seconds instead of failing exact validation after
minutes), plus the same model with Drake's hull per mesh link, against which the scene measures what the pieces
change. The environment's: each mesh, and each <collision> mesh of its models, at the tolerance the edge-check step
sets (so it comes after the robot, whose size sets the step), with each mesh's box placed at its pose.
"""

import json
import os
import subprocess
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.errors import PlannerWarning, UserError
from app.scene.meshes import cache
from app.scene.meshes.cache import Decomposition
from app.scene.model_files import ModelFile, is_convertible
from app.scene.spec import SceneInputs

# pydrake is imported inside the functions that use it, so that importing the package does not load Drake.


@dataclass
class MeshOptions:
    """How meshes are decomposed: the spec's method and tolerance (None: the decomposer's default), the cache."""

    method: str
    tolerance: float | None
    cache_dir: Path | None
    progress: bool

    def decompose(self, path: Path, conservative: bool = False, scale: float = 1.0) -> Decomposition:
        return cache.decompose(
            path,
            method=self.method,
            tolerance=self.tolerance,
            cache_dir=self.cache_dir,
            progress=self.progress,
            conservative=conservative,
            scale=scale,
        )

    def built(self, requests: list[tuple[Path, bool, float]]) -> dict[tuple, Decomposition]:
        """Decompose the meshes of `requests` (path, conservative, scale) that are not cached yet, every other one
        (largest first) in a child interpreter while this one builds the rest: a robot of several heavy meshes
        loads the first time in about half the time on two cores. Returns what was built, by request, each as
        built (not from the cache); the caller reads the others from the cache (what failed, with its error)."""
        todo = []
        for path, conservative, scale in dict.fromkeys(requests):
            try:
                if not cache.is_cached(path, self.method, self.tolerance, cache_dir=self.cache_dir,
                                       conservative=conservative, scale=scale):  # fmt: skip
                    todo.append((path, conservative, scale))
            except UserError:
                pass  # (said again, in one line, when the caller asks for it)
        if len(todo) < 2:
            return {}
        todo.sort(key=lambda request: -request[0].stat().st_size)
        theirs = [
            {"path": str(path), "method": self.method, "tolerance": self.tolerance, "progress": False,
             "cache_dir": str(self.cache_dir) if self.cache_dir else None, "conservative": conservative, "scale": scale}
            for path, conservative, scale in todo[1::2]
        ]  # fmt: skip
        child = subprocess.Popen(
            [
                sys.executable,
                "-c",
                "import sys; from app.scene.meshes.cache import decompose_each; decompose_each(sys.argv[1])",
                json.dumps(theirs),
            ],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env={**os.environ, "PYTHONPATH": os.pathsep.join(path for path in sys.path if path)},
        )
        built = {}
        try:
            for request in todo[::2]:
                try:
                    built[request] = self.decompose(*request)
                except UserError:
                    pass  # (stored: raised again when the caller asks for it)
            child.wait()
        finally:
            child.kill()
        for request in todo[1::2]:
            try:
                found = self.decompose(*request)
            except UserError:
                continue
            if found.from_cache:  # (else the child failed to store it, and this process built it just now)
                found.from_cache, found.seconds = False, found.build_seconds
            built[request] = found
        return built


@dataclass
class PreparedModel:
    """A model file's meshes, prepared: per <collision> holding one mesh (app.scene.model_files.ModelFile.
    collision_meshes), in file order, its decomposition (None: not decomposed, Drake takes each mesh's hull); and
    the .obj in the cache of each mesh file Drake cannot read that stays referenced."""

    model: ModelFile
    decompositions: list[Decomposition] | None
    converted: dict[Path, Path] = field(default_factory=dict)


@dataclass
class PreparedRobot:
    mesh: Decomposition | None = None  # a mesh robot's pieces
    model: PreparedModel | None = None  # a URDF/SDF robot's
    hulls: PreparedModel | None = None  # the same with Drake's hull per mesh link (if it has mesh links)
    described: list[dict] = field(default_factory=list)  # what each decomposition did, in order


@dataclass
class PreparedEnvironment:
    entries: list = field(default_factory=list)  # per env file: a Decomposition (a mesh) or a PreparedModel
    boxes: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)  # the meshes' world boxes (lo, hi)
    described: list[dict] = field(default_factory=list)


def prepare_robot(inputs: SceneInputs, options: MeshOptions) -> PreparedRobot:
    """The robot's meshes: a mesh robot's pieces, or its model's mesh links (see the module's docstring)."""
    robot = PreparedRobot()
    if inputs.robot_kind == "mesh":
        robot.mesh = options.decompose(inputs.robot_path)
        robot.described.append(describe(inputs.robot_path, robot.mesh))
        return robot
    robot.model = prepare_model(inputs.robot_model, options, robot.described, conservative=True)
    if robot.model.decompositions:
        robot.hulls = prepare_model(inputs.robot_model, options, None)
    return robot


def prepare_environment(inputs: SceneInputs, options: MeshOptions) -> PreparedEnvironment:
    """The environment's meshes, in the order of its files: each mesh's pieces, each model's collision meshes."""
    env = PreparedEnvironment()
    for path, kind, pose in zip(inputs.env_paths, inputs.env_kinds, inputs.env_poses):
        if kind == "mesh":
            decomposition = options.decompose(path)
            env.described.append(describe(path, decomposition))
            env.entries.append(decomposition)
            env.boxes.append(world_box(np.array(decomposition.extent()), pose))
        else:
            env.entries.append(prepare_model(inputs.models[path], options, env.described))
    return env


def prepare_model(
    model: ModelFile, options: MeshOptions, described: list | None, conservative: bool = False
) -> PreparedModel:
    """With `described` (a list to add to): each <collision> mesh decomposed; without: none (the hull version). Then
    every other mesh reference Drake cannot read converted to .obj."""
    decompositions = None
    if described is not None:
        decompositions = []
        if model.has_collision_mesh():
            built = options.built([(found[0], conservative, found[1]) for found in model.collision_meshes() if found])
            for found in model.collision_meshes():
                if found is None:
                    continue
                target, scale = found
                decomposition = built.get((target, conservative, scale)) or options.decompose(
                    target, conservative, scale
                )
                described.append(describe(target, decomposition))
                decompositions.append(decomposition)
    converted = {}
    for uri in model.kept_uris(decomposing=described is not None):
        target = model.targets[uri]
        if target is not None and is_convertible(uri) and target not in converted:
            converted[target] = cache.converted_obj(target, options.cache_dir)
    return PreparedModel(model, decompositions, converted)


def world_box(bounds: np.ndarray, pose: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """The world-frame box around a local box moved by pose (corners transformed)."""
    from pydrake.math import RigidTransform, RollPitchYaw

    X = RigidTransform(RollPitchYaw(np.radians(pose[3:])), pose[:3])
    corners = np.array([[bounds[i][0], bounds[j][1], bounds[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    world = (X.rotation().matrix() @ corners.T).T + X.translation()
    return world.min(axis=0), world.max(axis=0)


def describe(path: Path, d: Decomposition) -> dict:
    """What a decomposition did, for the scene's info and `plan`'s answer; a warning when it made many pieces."""
    if len(d.pieces) > 400:
        warnings.warn(
            f"{path.name} became {len(d.pieces)} convex pieces (tolerance "
            f"{d.validation.get('tolerance', 0):.3g} m); Drake's set-up time grows with the square of that (about "
            f"5 s at 1000, 20 s at 2000); a larger --mesh-tolerance gives fewer",
            PlannerWarning,
            stacklevel=2,
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
