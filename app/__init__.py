"""Narrow-passage PRM planning on Drake: Lévy-flight and random-walk bridge samplers feeding a lazy roadmap.

    import app

    oracle = app.CollisionOracle(app.load_scene("bar"))  # one per scene, shared by every query on it
    result = app.plan(oracle, app.PlanSettings(sampler="lfbs", seed=0))
    result.trajectory.positions  # (N, 9), with velocities, accelerations and joint names

    cell = app.CellRoadmap.build(oracle, app.BuildSettings(nodes=1000))  # once per work cell
    cell.solve(start, [goal_a, goal_b])  # many queries, each reaching any of its goals; cell.save(path)
    moved = cell.changed([app.read_change_file("moved.yaml")])  # the cell changed: the roadmap repaired, not rebuilt

Everything a user needs is named in `__all__`; the rest of the package is implementation.
"""

import os

# Drake's parallel collision batches use OpenMP. By default its idle threads spin for a while after each batch,
# holding the second core while the Python loop that follows wants it: with many small batches (walkers, edge
# rounds) that made 2 threads slower than 1. Passive waiting gives the core back. Must be set before libgomp loads.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from app.checking.budget import Budget  # noqa: E402
from app.checking.certify import certify_path  # noqa: E402
from app.checking.context import QueryContext  # noqa: E402
from app.checking.oracle import CollisionOracle, from_checker  # noqa: E402
from app.errors import InvalidEndpoint, NoPath, Note, PlannerWarning, SamplerBudgetExceeded, UserError  # noqa: E402
from app.motion.trajectory import Trajectory, TrajectoryFile  # noqa: E402
from app.planning.cell import BuildSettings, CellRoadmap  # noqa: E402
from app.planning.query import Query, plan  # noqa: E402
from app.planning.result import PlanResult  # noqa: E402
from app.planning.settings import PlanSettings  # noqa: E402
from app.samplers import SAMPLERS, Sampler, make_sampler  # noqa: E402
from app.scene.changes import (  # noqa: E402
    Attachment,
    CellChange,
    Move,
    Placement,
    Solid,
    changed_scene,
)
from app.scene.cspace import ConfigurationSpace  # noqa: E402
from app.scene.custom import build_scene, load_scene  # noqa: E402
from app.scene.model import Scene, scene_names  # noqa: E402
from app.scene.moveit_diff import read_change_file  # noqa: E402
from app.scene.spec import CustomSpec  # noqa: E402

__all__ = [
    # scenes and the collision oracle
    "Scene",
    "load_scene",
    "scene_names",
    "CustomSpec",
    "build_scene",
    "CollisionOracle",
    "from_checker",
    "QueryContext",
    "ConfigurationSpace",
    # a path of the user's, proved free between its points
    "certify_path",
    # planning
    "plan",
    "PlanSettings",
    "PlanResult",
    "Query",
    "Budget",
    # a work cell's roadmap, built once and queried many times
    "CellRoadmap",
    "BuildSettings",
    # a cell that changes: obstacles added, moved or removed, payloads attached (CellRoadmap.changed repairs); a
    # change file is a CellChange YAML or a MoveIt planning-scene diff
    "CellChange",
    "Solid",
    "Move",
    "Attachment",
    "Placement",
    "read_change_file",
    "changed_scene",
    # samplers
    "SAMPLERS",
    "Sampler",
    "make_sampler",
    # the motion
    "Trajectory",
    "TrajectoryFile",
    # errors
    "UserError",
    "InvalidEndpoint",
    "NoPath",
    "SamplerBudgetExceeded",
    # warnings (one line each on the command line)
    "PlannerWarning",
    "Note",
]
