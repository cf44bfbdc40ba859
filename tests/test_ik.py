"""Inverse kinematics: tool poses of the arm scenes to free configurations, checked by forward kinematics."""

import math

import numpy as np
import pytest

from app.cli import exit_code
from app.errors import InvalidEndpoint, UserError
from app.planning import ik

POSITION_TOLERANCE = ik.POSITION_TOLERANCE * (1 + 1e-6)
ANGLE_TOLERANCE = ik.ANGLE_TOLERANCE * (1 + 1e-6)


def tool_pose(oracle, q):
    """The tool frame in the world at q, from the plant on a context of its own."""
    plant = oracle.plant
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, q)
    return plant.CalcRelativeTransform(context, plant.world_frame(), oracle.scene.tool_frame)


def assert_reaches(oracle, q, X_target, position_tolerance=POSITION_TOLERANCE, angle_tolerance=ANGLE_TOLERANCE):
    X = tool_pose(oracle, q)
    assert np.linalg.norm(X.translation() - X_target.translation()) <= position_tolerance
    R = X_target.rotation().matrix().T @ X.rotation().matrix()
    angle = math.acos(np.clip((np.trace(R) - 1) / 2, -1, 1))
    assert angle <= angle_tolerance


@pytest.mark.parametrize("name", ["welding", "window"])
def test_every_pose_solves_to_a_free_configuration_within_tolerance(oracles, name):
    oracle = oracles(name)
    solutions = ik.solve_poses(oracle, np.random.default_rng(0))
    assert list(solutions) == list(oracle.scene.poses)
    for pose, q in solutions.items():
        assert oracle.space.within_bounds(q)[0]
        assert oracle.context().is_free(q), pose
        assert_reaches(oracle, q, oracle.scene.poses[pose])


def test_weld_seam_solutions_form_a_chain(oracles):
    """Each seam pose is solved nearest the previous one, so consecutive configurations stay close."""
    oracle = oracles("welding")
    solutions = [q for name, q in ik.solve_poses(oracle, np.random.default_rng(1)).items() if name.startswith("seam_")]
    assert len(solutions) == 4
    steps = [oracle.space.distance(a, b) for a, b in zip(solutions, solutions[1:])]
    assert max(steps) < 0.3  # weighted metric, metres of tool-tip travel; seam points are 0.02 m apart


def test_the_problem_file_goals_reach_their_poses(oracles):
    # goals are stored to 4 decimals, so allow a fraction of a millimetre more
    assert_reaches(
        oracles("welding"),
        oracles("welding").scene.goal,
        oracles("welding").scene.poses["seam_0"],
        2e-3,
        math.radians(1),
    )
    assert_reaches(
        oracles("window"), oracles("window").scene.goal, oracles("window").scene.poses["reach"], 2e-3, math.radians(1)
    )


@pytest.mark.parametrize("scene, pose", [("welding", "seam_0"), ("window", "reach")])
def test_a_scene_goal_is_its_jobs_arm_posture_at_that_pose(oracles, scene, pose):
    """What `plan` and `bench ompl` solve for a job scene is the job's own hard query: the goal is the posture the
    job's IK chain reaches that pose in, not another arm posture for the same tool pose."""
    oracle = oracles(scene)
    home = oracle.space.wrap(oracle.scene.start)
    job = ik.solve_poses(oracle, np.random.default_rng(0), reference=home)[pose]
    assert oracle.space.distance(job, oracle.scene.goal) < 0.05  # weighted: metres of tool-tip travel


def test_the_reference_is_preferred(oracles):
    oracle = oracles("window")
    goal = oracle.scene.goal  # itself a solution for "reach"
    q = ik.solve_pose(oracle, "reach", np.random.default_rng(2), reference=goal)
    assert oracle.space.distance(goal, q) < 0.05


def test_a_pose_out_of_reach_is_an_invalid_endpoint(oracles):
    from pydrake.math import RigidTransform

    oracle = oracles("window")
    with pytest.raises(InvalidEndpoint, match=r"pose '\[2.000, 0.000, 0.600\]' cannot be reached") as info:
        ik.solve_pose(oracle, RigidTransform([2.0, 0.0, 0.6]), np.random.default_rng(0), seeds=16)
    assert exit_code(info.value) == 3


@pytest.mark.slow
def test_a_pose_reachable_only_in_collision_is_an_invalid_endpoint(oracles):
    """The TCP inside the fixture in the enclosure: kinematically fine, never free."""
    from pydrake.math import RigidTransform, RollPitchYaw

    oracle = oracles("window")
    inside = RigidTransform(RollPitchYaw(0, math.pi / 2, 0), [0.68, 0.0, 0.56])
    with pytest.raises(InvalidEndpoint, match="cannot be reached collision-free"):
        ik.solve_pose(oracle, inside, np.random.default_rng(0), seeds=16)


def test_an_unknown_pose_name_is_a_user_error(oracles):
    with pytest.raises(UserError, match="unknown pose 'nowhere'.*known: window, reach, place"):
        ik.solve_pose(oracles("window"), "nowhere", np.random.default_rng(0))


def test_a_scene_without_a_tool_frame_has_no_poses(oracles):
    from pydrake.math import RigidTransform

    with pytest.raises(UserError, match="no tool frame"):
        ik.solve_pose(oracles("bar"), RigidTransform(), np.random.default_rng(0))


def test_pose_goal_places_the_scene_tool_frame_by_default(oracles):
    """`plan --goal-pose` on a shipped UR3 scene: metres and degrees, the scene's tool frame (tcp), the solution nearest
    the reference; another frame by name."""
    from pydrake.math import RigidTransform, RollPitchYaw

    oracle = oracles("window")
    assert ik.robot_frame(oracle).name() == "tcp"
    q = ik.pose_goal(oracle, [0.66, 0.0, 0.65, 0, 90, 0])
    assert_reaches(oracle, q, RigidTransform(RollPitchYaw(0, math.pi / 2, 0), [0.66, 0.0, 0.65]))
    assert oracle.context().is_free(q)
    # The scene's goal solves this very pose ('reach'): given as the reference, it is what comes back.
    near = ik.pose_goal(oracle, [0.66, 0.0, 0.65, 0, 90, 0], reference=oracle.scene.goal)
    assert oracle.space.distance(near, oracle.scene.goal) < 0.01
    assert ik.robot_frame(oracle, "tool0").name() == "tool0"
    assert ik.robot_frame(oracles("bar")).body().name() == "link7"  # no tool frame: the chain's last body


def test_a_tool_line_keeps_the_tool_on_the_segment_and_the_arm_in_its_posture(oracles):
    """window -> reach: the torch pushed 21 cm straight on through the hatch. Every configuration of the line puts
    the tool on the segment between the two poses, level as they are, in order, and no step is a jump."""
    from pydrake.math import RigidTransform

    oracle = oracles("window")
    rng = np.random.default_rng(0)
    c = ik.solve_poses(oracle, rng, ["window", "reach"], reference=oracle.scene.start)
    line = ik.tool_line(oracle, c["window"], c["reach"], rng)
    assert line is not None and len(line) == math.ceil(0.21 / ik.TOOL_STEP) - 1
    a, b = tool_pose(oracle, c["window"]).translation(), tool_pose(oracle, c["reach"]).translation()
    along = []
    for q in line:
        X = tool_pose(oracle, q)
        t = float((X.translation() - a) @ (b - a) / ((b - a) @ (b - a)))
        assert np.linalg.norm(X.translation() - (a + t * (b - a))) <= POSITION_TOLERANCE
        # level as both poses are: within their own IK tolerance of the slerp between them
        level = RigidTransform(oracle.scene.poses["window"].rotation(), X.translation())
        assert_reaches(oracle, q, level, angle_tolerance=2 * ANGLE_TOLERANCE)
        along.append(t)
    assert np.all(np.diff(along) > 0) and 0 < along[0] and along[-1] < 1
    P = np.vstack([c["window"], line, c["reach"]])
    # a tool step of s metres moves the arm about 3.5 s in the scene's metric (lever arms are upper bounds)
    assert oracle.space.distance(P[:-1], P[1:]).max() < 5 * 0.21 / (len(line) + 1)
    assert ik.tool_line(oracle, c["window"], oracle.scene.start, rng) is None  # home is another posture: a jump
