"""A scene made from a user's own Drake `SceneGraphCollisionChecker` (`app.from_checker`): its diagram, robot model
instances and collision filters as they are, and the configuration space derived from its plant as a problem file's
would be (stage (e), app.scene.coordinates), the problem's fields given as keywords."""

from __future__ import annotations

import numpy as np

from app.scene.build import joint_table, robot_is_one_body
from app.scene.coordinates import derive_space
from app.scene.problem import ProblemFile


class CheckerScene:
    """What the planner reads of a scene, for a diagram the user built and checks collisions on (see
    app.scene.model.Scene for the attributes). Every position of the plant is a coordinate; a pair the checker's
    collision filter matrix filters is never counted (`filtered_body_pairs`); self-collision counts wherever the
    checker counts it. No passage, tool poses or helper processes (another process cannot rebuild the diagram)."""

    def __init__(self, checker, name: str = "own", **problem):
        self.collision_checker = checker
        self.name = self.description = name
        self.recipe = None
        self.diagram, self.plant = checker.model(), checker.plant()
        self.robot_instances = list(checker.robot_model_instances())
        # Start and goal are a query's to give; the scene's (a query's default) are the plant's default positions.
        default = list(map(float, self.plant.GetDefaultPositions()))
        problem = {"start": default, "goal": default, **problem}
        space = derive_space(joint_table(self.plant), ProblemFile(**problem), f"from_checker({name})")
        self.position_map = space.position_map
        self.dim, self.joint_names, self.coordinate_names = space.dim, space.joint_names, space.coordinate_names
        self.angular, self.continuous = space.angular, space.continuous
        self.lower, self.upper, self.weights = space.lower, space.upper, space.weights
        self.start, self.goal = space.start, space.goal
        self.resolution, self.step = space.resolution, space.step
        self.velocity_limits, self.acceleration_limits = space.velocity_limits, space.acceleration_limits
        self.filtered_body_pairs = _filtered_pairs(checker)
        robot = {int(b) for i in self.robot_instances for b in self.plant.GetBodyIndices(i)}
        self.self_collisions = any(a in robot and b in robot for a, b in _unfiltered_pairs(checker))
        self.one_body = robot_is_one_body(self.plant, self.robot_instances)
        self.passage_frame, self.passage_boxes, self.tool_frame = None, [], None
        self.poses, self.pass_through, self.disabled_pairs, self.robot_links = {}, set(), [], {}

    def positions(self, Q: np.ndarray) -> np.ndarray:
        return Q if self.position_map is None else self.position_map.positions(Q)


def _filtered_pairs(checker) -> list[tuple[int, int]]:
    """The body index pairs (i < j) the checker's collision filter matrix filters (1: by its user, -1: always)."""
    matrix = np.asarray(checker.GetFilteredCollisionMatrix())
    i, j = np.nonzero(np.triu(matrix != 0, 1))
    return list(zip(i.tolist(), j.tolist()))


def _unfiltered_pairs(checker) -> list[tuple[int, int]]:
    matrix = np.asarray(checker.GetFilteredCollisionMatrix())
    i, j = np.nonzero(np.triu(matrix == 0, 1))
    return list(zip(i.tolist(), j.tolist()))
