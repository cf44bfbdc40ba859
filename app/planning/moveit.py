"""A MoveIt request answered (app.scene.moveit reads it): its pose goals solved by IK, and the answer as a
`moveit_msgs/MotionPlanResponse` YAML file, a failure's too (MoveIt answers a failure with its error code)."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from app.errors import InvalidEndpoint
from app.io import write_atomically
from app.motion.trajectory import Trajectory
from app.planning.ik import robot_frame, solve_pose
from app.scene.moveit import MoveItProblem
from app.scene.moveit_messages import (
    ERROR_CODES,
    Duration,
    JointState,
    JointTrajectory,
    JointTrajectoryPoint,
    MotionPlanResponse,
    MoveItErrorCodes,
    RobotState,
    RobotTrajectory,
)


def goal_configurations(oracle, problem: MoveItProblem, *, seed: int = 0) -> np.ndarray:
    """The request's goals as configurations (k, dim), any of which the plan may reach: its joint goals, then every
    distinct free IK solution of each pose goal, nearest the start first. None reachable: the last pose goal's
    InvalidEndpoint (NO_IK_SOLUTION)."""
    from pydrake.common.eigen_geometry import Quaternion
    from pydrake.math import RigidTransform, RotationMatrix

    goals = [problem.joint_goals]
    failure = None
    for k, goal in enumerate(problem.pose_goals):
        pose = RigidTransform(RotationMatrix(Quaternion(goal.wxyz)), goal.xyz)
        try:
            found = solve_pose(
                oracle,
                pose,
                np.random.default_rng([seed, k]),
                problem.start,
                frame=robot_frame(oracle, goal.link),
                label=f"of {goal.link} at {', '.join(f'{v:.4g}' for v in goal.xyz)}",
                position_tolerance=goal.position_tolerance,
                angle_tolerance=goal.angle_tolerance,
                every=True,
            )
        except InvalidEndpoint as exc:
            failure = exc
            continue
        goals.append(found)
    configurations = np.vstack(goals)
    if not len(configurations):
        raise failure
    return configurations


def response(
    problem_or_start: MoveItProblem | dict[str, float],
    group: str = "",
    *,
    trajectory: Trajectory | None = None,
    held: dict[str, float] | None = None,
    planning_time: float = 0.0,
    code: str = "SUCCESS",
) -> MotionPlanResponse:
    """The MotionPlanResponse of a problem (or of a start state and group, when the problem could not be read
    whole): the trajectory's joints but the held ones (the group's), every sample with its time from start; an empty
    trajectory on failure. `code`: our errors' code names (app.errors), MoveIt's FAILURE for one it has not."""
    if isinstance(problem_or_start, MoveItProblem):
        start, group = problem_or_start.start_state, problem_or_start.group
        held = problem_or_start.scene.position_map.held if problem_or_start.scene.position_map else {}
    else:
        start, held = problem_or_start, held or {}
    joint_trajectory = JointTrajectory()
    if trajectory is not None:
        names, positions, velocities, accelerations = trajectory.joints()
        moving = [i for i, name in enumerate(names) if name not in held]
        joint_trajectory.joint_names = [names[i] for i in moving]
        joint_trajectory.points = [
            JointTrajectoryPoint(
                positions=positions[k, moving].tolist(),
                velocities=velocities[k, moving].tolist(),
                accelerations=accelerations[k, moving].tolist(),
                time_from_start=duration(float(t)),
            )
            for k, t in enumerate(trajectory.times)
        ]
    return MotionPlanResponse(
        trajectory_start=RobotState(joint_state=JointState(name=list(start), position=list(start.values()))),
        group_name=group,
        trajectory=RobotTrajectory(joint_trajectory=joint_trajectory),
        planning_time=float(planning_time),
        error_code=MoveItErrorCodes(val=ERROR_CODES.get(code, ERROR_CODES["FAILURE"])),
    )


def duration(seconds: float) -> Duration:
    """builtin_interfaces/Duration of `seconds` (nanoseconds rounded, carried into seconds at 1e9)."""
    whole = math.floor(seconds)
    nanoseconds = round((seconds - whole) * 1e9)
    if nanoseconds >= 1_000_000_000:
        whole, nanoseconds = whole + 1, nanoseconds - 1_000_000_000
    return Duration(sec=int(whole), nanosec=int(nanoseconds))


def write_response(path: str | os.PathLike, answer: MotionPlanResponse) -> Path:
    """The response as YAML, atomically (app.io)."""
    from pydrake.common.yaml import yaml_dump_typed

    return write_atomically(path, yaml_dump_typed(answer))
