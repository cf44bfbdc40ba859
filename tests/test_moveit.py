"""MoveIt problems in and out (app.scene.moveit, app.planning.moveit, plan --moveit-*): small PlanningScene and
MotionPlanRequest files for the shipped UR3 on its cart, written here."""

import json
import math

import numpy as np
import pytest

from app.checking.oracle import CollisionOracle
from app.errors import UserError
from app.motion.trajectory import TrajectoryFile
from app.planning.ik import pose_error, robot_frame, tool_pose
from app.planning.moveit import duration, goal_configurations
from app.scene.cspace import PositionMap
from app.scene.files import PACKAGES
from app.scene.moveit import read_problem
from app.scene.moveit_messages import read_response

ROBOTS_DIR = PACKAGES["npp_robots"]
URDF = ROBOTS_DIR / "ur3_on_cart.urdf"
ARM = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
WRIST = ARM[3:]
# The robot state of the scenes below: an arm reaching out, clear of the cart.
STATE = [0.0, -1.0, 1.0, -1.5, -1.57, 0.0]
IDENTITY = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}


@pytest.fixture
def srdf(tmp_path):
    """The shipped SRDF (its group `arm`: a chain) with groups `wrist` (joints) and `both` (a group and a link)."""
    text = (ROBOTS_DIR / "ur3_on_cart.srdf").read_text()
    groups = (
        '  <group name="wrist"><joint name="wrist_1_joint"/><joint name="wrist_2_joint"/>'
        '<joint name="wrist_3_joint"/></group>\n'
        '  <group name="both"><group name="wrist"/><link name="upper_arm_link"/></group>\n'
    )
    path = tmp_path / "ur3.srdf"
    path.write_text(text.replace("</robot>", groups + "</robot>"))
    return path


def write(path, message: dict):
    path.write_text(json.dumps(message))  # (JSON is YAML)
    return path


def box_object(name: str, centre, size=0.04, frame="world", **extra) -> dict:
    return {
        "header": {"frame_id": frame},
        "id": name,
        "primitives": [{"type": 1, "dimensions": [size] * 3}],
        "primitive_poses": [{"position": dict(zip("xyz", centre)), "orientation": IDENTITY}],
        **extra,
    }


def scene_file(tmp_path, objects=(), acm=None, name="scene.yaml", state=STATE) -> object:
    message = {
        "name": "test",
        "robot_state": {"joint_state": {"name": ARM, "position": list(state)}},
        "world": {"collision_objects": list(objects)},
    }
    if acm:
        message["allowed_collision_matrix"] = acm
    return write(tmp_path / name, message)


def joint_request(tmp_path, goal: dict, group="arm", name="request.yaml", **extra) -> object:
    constraints = [
        {"joint_name": j, "position": v, "tolerance_above": 1e-3, "tolerance_below": 1e-3} for j, v in goal.items()
    ]
    return write(
        tmp_path / name, {"group_name": group, "goal_constraints": [{"joint_constraints": constraints}], **extra}
    )


def problem(tmp_path, srdf, objects=(), acm=None, goal=None, **extra):
    request = joint_request(tmp_path, goal or {"shoulder_pan_joint": 0.5}, **extra)
    return read_problem(request=request, scene=scene_file(tmp_path, objects, acm), robot=URDF, srdf=srdf)


def nozzle_at(oracle, q) -> np.ndarray:
    """The middle of the torch's nozzle (14 cm out of tool0 along its z): a 2 cm box round it touches the torch
    alone."""
    return tool_pose(oracle, q, robot_frame(oracle, "tool0")).multiply([0.0, 0.0, 0.14])


def unscoped(pairs) -> list[tuple[str, str]]:
    return sorted(tuple(sorted(name.split("::")[-1] for name in pair)) for pair in pairs)


# ---- the scene ----------------------------------------------------------------------------------------------------
def test_a_box_is_placed_where_header_frame_object_pose_and_primitive_pose_put_it(tmp_path, srdf):
    empty = CollisionOracle(problem(tmp_path, srdf).scene)
    q = np.array(STATE)
    x, y, z = nozzle_at(empty, q)
    # In base_link's frame (0.5 m above the cart's origin), the object turned 90 degrees about z: the primitive's
    # (y, -x) is the world's (x, y).
    turned = {"x": 0.0, "y": 0.0, "z": math.sin(math.pi / 4), "w": math.cos(math.pi / 4)}
    placed = box_object(
        "box", (y, -x, z - 0.5), size=0.02, frame="base_link", pose={"position": IDENTITY, "orientation": turned}
    )
    inside = CollisionOracle(problem(tmp_path, srdf, [placed]).scene)
    assert empty.free(q) and not inside.free(q)
    assert unscoped(inside.diagnostics.colliding_bodies(q)) == [("box", "torch")]
    # 5 cm aside, across the nozzle's axis (the nozzle 1 cm and the box 1 cm from their middles): free.
    aside = nozzle_at(empty, q) + 0.05 * tool_pose(empty, q, robot_frame(empty, "tool0")).rotation().matrix()[:, 0]
    beside = box_object("box", aside, size=0.02)
    assert CollisionOracle(problem(tmp_path, srdf, [beside]).scene).free(q)


def test_spheres_and_cylinders_and_robowflex_lists_read_as_ros2_mappings(tmp_path, srdf):
    ros2 = {
        "header": {"frame_id": "world"},
        "id": "post",
        "primitives": [{"type": 3, "dimensions": [0.4, 0.03]}, {"type": 2, "dimensions": [0.05]}],
        "primitive_poses": [
            {"position": {"x": -0.3, "y": 0.3, "z": 0.7}, "orientation": IDENTITY},
            {"position": {"x": -0.3, "y": 0.3, "z": 0.95}, "orientation": IDENTITY},
        ],
    }
    robowflex = {
        **ros2,
        "primitives": [{"type": "cylinder", "dimensions": [0.4, 0.03]}, {"type": "Sphere", "dimensions": [0.05]}],
        "primitive_poses": [
            {"position": [-0.3, 0.3, 0.7], "orientation": [0, 0, 0, 1]},
            {"position": [-0.3, 0.3, 0.95], "orientation": [0, 0, 0, 1]},
        ],
    }
    a = problem(tmp_path, srdf, [ros2]).scene
    b = problem(tmp_path, srdf, [robowflex]).scene
    assert a.info["env"] == b.info["env"] and len(a.info["env"]) == 1  # one world file, the same content
    text = open(a.info["env"][0]).read()
    assert "<cylinder><radius>0.03</radius><length>0.4</length>" in text and "<sphere><radius>0.05</radius>" in text
    assert "<pose>-0.3 0.3 0.95 " in text


def test_an_allowed_link_object_entry_is_not_checked_and_others_still_are(tmp_path, srdf):
    q = np.array(STATE)
    empty = CollisionOracle(problem(tmp_path, srdf).scene)
    box = box_object("box", nozzle_at(empty, q), size=0.02)
    allowed = {
        "entry_names": ["box", "torch"],
        "entry_values": [{"enabled": [False, True]}, {"enabled": [True, False]}],
    }
    oracle = CollisionOracle(problem(tmp_path, srdf, [box], acm=allowed).scene)
    assert oracle.free(q)
    # The box still counts for the other links: the wrist put into it collides.
    wrist = box_object("box", tool_pose(empty, q, robot_frame(empty, "wrist_2_link")).translation(), size=0.02)
    assert not CollisionOracle(problem(tmp_path, srdf, [wrist], acm=allowed).scene).free(q)
    anything = {"default_entry_names": ["box"], "default_entry_values": [True]}
    assert CollisionOracle(problem(tmp_path, srdf, [wrist], acm=anything).scene).free(q)


def test_allowed_link_pairs_leave_self_collisions_out(tmp_path, srdf):
    empty = CollisionOracle(problem(tmp_path, srdf).scene)
    rng = np.random.default_rng(1)
    # A configuration in which the arm collides with itself alone (the cart is the robot's too: no world object).
    q = next(q for q in empty.space.uniform(rng, 500) if not empty.free(q))
    pairs = unscoped(empty.diagnostics.colliding_bodies(q))
    names = sorted({name for pair in pairs for name in pair})
    matrix = {
        "entry_names": names,
        "entry_values": [{"enabled": [(a, b) in pairs or (b, a) in pairs for b in names]} for a in names],
    }
    assert CollisionOracle(problem(tmp_path, srdf, acm=matrix).scene).free(q)


# ---- the request --------------------------------------------------------------------------------------------------
def test_a_partial_start_keeps_the_scene_state_and_the_group_holds_the_rest(tmp_path, srdf):
    start = {"joint_state": {"name": ["elbow_joint"], "position": [1.2]}}
    request = joint_request(tmp_path, {"wrist_1_joint": -1.0}, group="wrist", start_state=start)
    read = read_problem(request=request, scene=scene_file(tmp_path), robot=URDF, srdf=srdf)
    expected = dict(zip(ARM, STATE), elbow_joint=1.2)
    assert read.start_state == expected
    assert read.scene.coordinate_names == WRIST
    assert read.scene.position_map.held == {j: expected[j] for j in ARM[:3]}
    assert read.start.tolist() == [expected[j] for j in WRIST]
    # The group's joints the goal does not name stay where they start.
    assert read.joint_goals.tolist() == [[-1.0, expected["wrist_2_joint"], expected["wrist_3_joint"]]]


def test_groups_of_chains_joints_links_and_subgroups(tmp_path, srdf):
    def planned(group):
        request = joint_request(tmp_path, {"wrist_3_joint": 0.0}, group=group)
        return read_problem(request=request, scene=None, robot=URDF, srdf=srdf).scene.coordinate_names

    assert planned("arm") == ARM
    assert planned("both") == ["shoulder_lift_joint", *WRIST]  # a link's group has its parent joint
    assert planned("") == ARM


def test_a_pose_goal_is_solved_by_ik_for_the_link_it_names(tmp_path, srdf):
    x, y, z = 0.25, 0.2, 0.75
    goal = {
        "position_constraints": [
            {
                "header": {"frame_id": "world"},
                "link_name": "tool0",
                "constraint_region": {
                    "primitives": [{"type": 2, "dimensions": [0.001]}],
                    "primitive_poses": [{"position": {"x": x, "y": y, "z": z}, "orientation": IDENTITY}],
                },
            }
        ],
        "orientation_constraints": [
            {
                "header": {"frame_id": "world"},
                "link_name": "tool0",
                "orientation": {"x": 1.0, "y": 0.0, "z": 0.0, "w": 0.0},
                "absolute_x_axis_tolerance": 0.01,
                "absolute_y_axis_tolerance": 0.01,
                "absolute_z_axis_tolerance": 0.01,
            }
        ],
    }
    request = write(tmp_path / "pose.yaml", {"group_name": "arm", "goal_constraints": [goal]})
    read = read_problem(request=request, scene=scene_file(tmp_path), robot=URDF, srdf=srdf)
    assert read.pose_goals[0].link == "tool0" and read.pose_goals[0].position_tolerance == 0.001
    oracle = CollisionOracle(read.scene)
    goals = goal_configurations(oracle, read, seed=0)
    from pydrake.math import RigidTransform, RollPitchYaw

    target = RigidTransform(RollPitchYaw(math.pi, 0, 0), [x, y, z])
    for q in goals:
        position, angle = pose_error(oracle, q, target, robot_frame(oracle, "tool0"))
        assert position <= 0.001 and angle <= 0.01 and oracle.free(q)


# ---- the command line ---------------------------------------------------------------------------------------------
def test_plan_answers_a_response_whose_trajectory_is_ours_and_held_joints_never_move(cli, tmp_path, srdf):
    start = {"joint_state": {"name": ["elbow_joint"], "position": [1.2]}}
    request = joint_request(tmp_path, {"wrist_1_joint": -1.0, "wrist_2_joint": -0.5}, group="wrist", start_state=start)
    scene = scene_file(tmp_path, [box_object("table", (0.4, 0.0, 0.4), size=0.1)])
    out, trajectory = tmp_path / "response.yaml", tmp_path / "trajectory.json"
    args = ["--moveit-request", request, "--moveit-scene", scene, "--robot", URDF, "--srdf", srdf]
    result = cli("plan", *args, "--moveit-out", out, "--out", trajectory, "--json")
    assert result.returncode == 0, result.stderr
    answer = json.loads(result.stdout)
    assert answer["moveit"] == {"group": "wrist", "error_code": 1, "response": str(out)}
    written = TrajectoryFile.read(
        trajectory,
        3,
        PositionMap.of(ARM, [], {"shoulder_pan_joint": 0.0, "shoulder_lift_joint": -1.0, "elbow_joint": 1.2}),
    )
    names, positions, _, _ = written.trajectory.joints()
    P = np.array(positions)
    held = [names.index(j) for j in ARM[:3]]
    assert np.all(P[:, held] == [0.0, -1.0, 1.2])  # held exactly where they start, in every sample
    response = read_response(out)
    assert response.error_code.val == 1 and response.group_name == "wrist"
    assert response.trajectory_start.joint_state.name == ARM
    assert response.trajectory_start.joint_state.position == [0.0, -1.0, 1.2, *STATE[3:]]
    points = response.trajectory.joint_trajectory.points
    assert response.trajectory.joint_trajectory.joint_names == WRIST
    assert len(points) == len(written.trajectory.times)
    moving = [names.index(j) for j in WRIST]
    for point, t, row in zip(points, written.trajectory.times, P[:, moving]):
        assert point.positions == pytest.approx(row.tolist(), abs=1e-12)
        assert point.time_from_start.sec + 1e-9 * point.time_from_start.nanosec == pytest.approx(t, abs=1e-9)
    assert points[-1].positions == pytest.approx([-1.0, -0.5, STATE[5]])


def test_the_request_scales_velocity_and_its_planning_time_limits_the_budget(cli, tmp_path, srdf):
    scene = scene_file(tmp_path)

    def planned(**extra):
        request = joint_request(tmp_path, {"shoulder_pan_joint": 3.0}, name="scaled.yaml", **extra)
        result = cli(
            "plan", "--moveit-request", request, "--moveit-scene", scene, "--robot", URDF, "--srdf", srdf, "--json"
        )
        assert result.returncode == 0, result.stderr
        return json.loads(result.stdout)

    full, half = planned(), planned(max_velocity_scaling_factor=0.5, allowed_planning_time=7.0)
    assert half["trajectory"]["time_from_start"][-1] > 1.3 * full["trajectory"]["time_from_start"][-1]
    assert half["budget"].startswith("7s") and not full["budget"].startswith("7s")


@pytest.mark.parametrize(
    "objects, goal, group, message, code",
    [
        ([], {"shoulder_pan_joint": 0.5}, "legs", "no group 'legs'", -15),
        ([{**box_object("cone", (1, 1, 1)), "primitives": [{"type": 4, "dimensions": [0.1, 0.05]}]}], {}, "arm",
         "cones are not supported", 99999),
        ([{**box_object("mesh", (1, 1, 1)), "meshes": [{"vertices": [], "triangles": []}]}], {}, "arm",
         "meshes are not supported", 99999),
        ([box_object("shelf", (1, 1, 1), frame="camera")], {}, "arm", "frame 'camera'", -21),
        ([], {"knee_joint": 0.5}, "arm", "no movable joint 'knee_joint'", -16),
        ([], {"shoulder_pan_joint": 0.5}, "wrist", "is not in the group", -16),
    ],
)  # fmt: skip
def test_bad_problems_are_one_line_exit_2_and_a_failure_response(
    cli, one_line_error, tmp_path, srdf, objects, goal, group, message, code
):
    request = joint_request(tmp_path, goal or {"shoulder_pan_joint": 0.5}, group=group)
    scene, out = scene_file(tmp_path, objects), tmp_path / "response.yaml"
    result = cli(
        "plan",
        "--moveit-request",
        request,
        "--moveit-scene",
        scene,
        "--robot",
        URDF,
        "--srdf",
        srdf,
        "--moveit-out",
        out,
    )
    assert message in one_line_error(result, 2)
    response = read_response(out)
    assert response.error_code.val == code and response.trajectory.joint_trajectory.points == []
    assert response.group_name == group


def test_files_that_are_no_messages_are_refused_in_one_line(cli, one_line_error, tmp_path, srdf):
    request = joint_request(tmp_path, {"shoulder_pan_joint": 0.5})
    broken = tmp_path / "broken.yaml"
    broken.write_text("world: {collision_objects: [")
    result = cli("plan", "--moveit-request", request, "--moveit-scene", broken, "--robot", URDF)
    assert "bad MoveIt planning scene broken.yaml" in one_line_error(result, 2)
    wrong = write(tmp_path / "wrong.yaml", {"world": {"collision_objects": {"id": "not a list"}}})
    result = cli("plan", "--moveit-request", request, "--moveit-scene", wrong, "--robot", URDF)
    assert "bad MoveIt planning scene wrong.yaml" in one_line_error(result, 2)
    result = cli("plan", "--moveit-request", request, "--robot", URDF, "--start", "0,0,0,0,0,0")
    assert "give it without --start" in one_line_error(result, 2)
    result = cli("plan", "--moveit-request", request, "--robot", URDF, "--json")  # a group, but no SRDF
    answer = json.loads(result.stdout)
    assert result.returncode == 2 and answer["error"]["code"] == "INVALID_GROUP_NAME"
    jsonschema = pytest.importorskip("jsonschema")
    jsonschema.validate(answer, json.loads((ROBOTS_DIR.parent / "docs" / "schemas" / "failure.json").read_text()))


def test_the_documented_example_plans_under_its_shelf(cli, tmp_path):
    example = ROBOTS_DIR.parent / "examples" / "moveit"
    out = tmp_path / "response.yaml"
    args = ["--moveit-scene", example / "scene.yaml", "--moveit-request", example / "request.yaml", "--robot", URDF]
    result = cli("plan", *args, "--srdf", ROBOTS_DIR / "ur3_on_cart.srdf", "--moveit-out", out, "--json")
    assert result.returncode == 0, result.stderr
    response = read_response(out)
    assert response.error_code.val == 1 and response.group_name == "arm"
    assert response.trajectory.joint_trajectory.joint_names == ARM
    assert response.trajectory_start.joint_state.position == [0.0, -1.0, 1.2, -1.5, -1.57, 0.0]


def test_plan_hold_keeps_a_joint_still_for_any_robot(cli, tmp_path):
    out = tmp_path / "held.json"
    result = cli("plan", "--robot", URDF, "--hold", "shoulder_pan_joint=0.3", "--start", "-1,1,0,0,0", "--goal",
                 "-1.5,1.5,0.5,0.5,0", "--out", out)  # fmt: skip
    assert result.returncode == 0, result.stderr
    written = TrajectoryFile.read(out, 5, PositionMap.of(ARM, [], {"shoulder_pan_joint": 0.3}))
    names, positions, velocities, _ = written.trajectory.joints()
    assert names == ARM and np.all(positions[:, 0] == 0.3) and np.all(velocities[:, 0] == 0.0)
    assert positions[-1, 1:].tolist() == pytest.approx([-1.5, 1.5, 0.5, 0.5, 0.0])
    result = cli("plan", "--robot", URDF, "--hold", "shoulder_pan_joint=9", "--start", "0,0,0,0,0")
    assert "held joint 'shoulder_pan_joint' at 9 is outside its limits" in result.stderr and result.returncode == 2


def test_held_joints_and_the_mimic_joints_that_follow_them():
    names = ["a", "b", "c", "d"]
    mapped = PositionMap.of(names, [("d", "b", 2.0, 0.1)], {"b": 0.5, "c": -1.0})
    assert mapped.planned.tolist() == [0] and mapped.held == {"b": 0.5, "c": -1.0, "d": 1.1}
    assert mapped.positions(np.array([[3.0]])).tolist() == [[3.0, 0.5, -1.0, 1.1]]
    A, b = mapped.equalities()  # what IK holds them by
    assert np.allclose(A @ [3.0, 0.5, -1.0, 1.1], b)
    with pytest.raises(UserError, match="hold that joint instead"):
        PositionMap.of(names, [("d", "b", 2.0, 0.1)], {"d": 0.0})
    with pytest.raises(UserError, match="outside its limits"):
        PositionMap.of(names, [], {"a": 4.0}).check_held(np.full(4, -math.pi), np.full(4, math.pi))


def test_durations_carry_nanoseconds_into_seconds():
    assert duration(1.9999999999) == duration(2.0)
    assert (duration(0.25).sec, duration(0.25).nanosec) == (0, 250_000_000)


MBM = ROBOTS_DIR.parent / "examples" / "moveit" / "mbm-panda"
PANDA = ROBOTS_DIR / "panda"


def test_a_motionbenchmaker_problem_plans_for_the_shipped_panda(cli, tmp_path):
    """Robowflex's forms as MotionBenchMaker writes them: allowed-collision rows as bare lists, a virtual joint at
    the origin, and finger joints the URDF fixes (one with a <mimic>) named in the joint states."""
    box = MBM / "box"
    found = read_problem(
        request=box / "request0001.yaml", scene=box / "scene0001.yaml", robot=PANDA / "panda.urdf",
        srdf=PANDA / "panda.srdf",
    )  # fmt: skip
    assert found.group == "panda_arm" and found.scene.position_map is None  # the fingers are fixed, not held
    assert ("panda_hand", "panda_leftfinger") in unscoped(found.scene.allowed_collisions)
    out = tmp_path / "response.yaml"
    args = ["--moveit-scene", box / "scene0001.yaml", "--moveit-request", box / "request0001.yaml"]
    result = cli("plan", *args, "--robot", PANDA / "panda.urdf", "--srdf", PANDA / "panda.srdf", "--moveit-out", out)
    assert result.returncode == 0, result.stderr
    assert "warning" not in result.stderr.lower()  # Drake's are summarised in one note
    response = read_response(out)
    assert response.error_code.val == 1 and response.trajectory.joint_trajectory.joint_names[0] == "panda_joint1"


def test_a_multi_dof_joint_away_from_the_origin_is_refused(tmp_path, srdf):
    state = {"joint_names": ["virtual_joint"], "transforms": [{"translation": [0, 0, 0.5], "rotation": [0, 0, 0, 1]}]}
    scene = write(
        tmp_path / "scene.yaml",
        {"robot_state": {"joint_state": {"name": ARM, "position": STATE}, "multi_dof_joint_state": state}},
    )
    request = joint_request(tmp_path, {"shoulder_pan_joint": 0.5})
    with pytest.raises(UserError, match="multi-DOF joint away from the origin"):
        read_problem(request=request, scene=scene, robot=URDF, srdf=srdf)
