"""A scene: Drake model directives (robot + obstacles) plus a problem file (bounds, start, goal, passage, metric).

`Scene` holds the result of its stages: the problem file read as data (app.scene.problem), the Drake diagram built
from the directives with its collision filters (app.scene.build), and the configuration space derived from the two
(app.scene.coordinates). Everything the rest of the pipeline needs about the robot's configuration space (which
coordinates are angles, which wrap, how to weigh them) is read here once.
"""

import dataclasses
import functools
from pathlib import Path

import numpy as np

from app.errors import UserError
from app.io import check_input
from app.scene.build import add_directives, build_diagram, joint_table, robot_is_one_body
from app.scene.coordinates import derive_space, passage_boxes
from app.scene.files import PACKAGES, SCENES_DIR
from app.scene.model_files import read_srdf
from app.scene.problem import ProblemFile, directives_file, named_file, read_problem

# pydrake is imported inside the functions that use it, so that importing the package (as the command line does)
# does not load Drake.


def scene_names() -> list[str]:
    """The shipped scenes' names, sorted (`python -m app scenes`)."""
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


class Scene:
    """A loaded scene: the Drake RobotDiagram and the configuration-space facts read from it and the problem file.

    Attributes:
        name: The scene's name (its problem file's stem).
        path: Its problem file.
        diagram: The Drake RobotDiagram (robot and obstacles).
        plant: Its MultibodyPlant.
        dim: The number of coordinates.
        coordinate_names: One name per coordinate: the order of start, goal and every configuration.
        joint_names: Every joint position's name, mimic joints' included: what a trajectory file carries.
        lower: (dim,) lower bounds.
        upper: (dim,) upper bounds.
        start: (dim,) the problem file's start.
        goal: (dim,) the problem file's goal.
        resolution: The edge-check step in the weighted metric.
        step: The sampler step the problem file sets (None: `default_step`'s).
        self_collisions: Whether the robot's collisions with itself count.
    """

    def __init__(self, name_or_path: str):
        self.path = scene_path(name_or_path)
        self.name = self.path.stem
        # How another process loads this very scene (a roadmap built on several processes): picklable, no Drake.
        self.recipe = functools.partial(Scene, str(self.path))
        self.problem = problem = read_problem(self.path)
        self.disabled_pairs = read_srdf(named_file(self.path, problem.srdf)) if problem.srdf else []
        self.allowed_collisions = [tuple(pair) for pair in problem.allowed_collisions]
        built = build_diagram(
            self.add_models, problem.robot, self.disabled_pairs, problem.srdf, self._bad, problem.allowed_collisions
        )
        self.diagram, self.plant = built.diagram, built.plant
        self.robot_instances, self.adjacent_pairs = built.robot_instances, built.adjacent_pairs
        self.robot_links = built.robot_links
        self._hold_space(joint_table(self.plant), problem)
        self.self_collisions = problem.collisions == "all"
        self.one_body = robot_is_one_body(self.plant, self.robot_instances)
        self._find_frames(problem)

    @property
    def _bad(self) -> str:
        """How a refusal of this scene's problem file starts."""
        return f"bad scene file {self.path.name}"

    def _hold_space(self, table: dict, problem: ProblemFile) -> None:
        space = derive_space(table, problem, self._bad)
        self.position_map = space.position_map
        self.dim = space.dim
        self.joint_names = space.joint_names  # every position's, mimic joints' included: what a trajectory carries
        self.coordinate_names = space.coordinate_names
        self.angular, self.continuous = space.angular, space.continuous
        self.lower, self.upper, self.weights = space.lower, space.upper, space.weights
        self.start, self.goal = space.start, space.goal
        self.resolution, self.step = space.resolution, space.step
        self.velocity_limits, self.acceleration_limits = space.velocity_limits, space.acceleration_limits

    def _find_frames(self, problem: ProblemFile) -> None:
        """`passage_frame` and `passage_boxes`; `tool_frame` (a Frame or None), `poses` (name -> RigidTransform of
        the tool frame in the world) and `pass_through` (the names of the poses a job does not stop at)."""
        from pydrake.math import RigidTransform, RollPitchYaw

        bad, frame = self._bad, problem.passage.frame
        if frame and not self.plant.HasFrameNamed(frame):
            raise UserError(f"{bad}: passage frame '{frame}' not in the model")
        self.passage_frame = self.plant.GetFrameByName(frame) if frame else None
        self.passage_boxes = passage_boxes(problem, bad)
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

    def positions(self, Q: np.ndarray) -> np.ndarray:
        """The plant's positions at configurations Q (..., dim): Q itself unless mimic joints follow coordinates."""
        return Q if self.position_map is None else self.position_map.positions(Q)

    def packages(self) -> dict[str, Path]:
        """The packages the scene's model files are found in (package://NAME/...): the shipped ones."""
        return dict(PACKAGES)

    def add_models(self, parser) -> None:
        """Load the scene's models (robot and obstacles) into `parser`'s plant, e.g. for a second diagram to view."""
        path = directives_file(self.path, self.problem)
        add_directives(parser, path, self.packages(), self.problem.directives)

    def summary(self) -> dict:
        """What `python -m app scenes --json` says of the scene (docs/schemas/scenes.json)."""
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
