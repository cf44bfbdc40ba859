"""Mimic joints (URDF <mimic>): a two-link arm whose gripper's right finger follows the left one is planned in three
coordinates, and every plant position, collision answer, certificate and trajectory sees the right finger where the
URDF puts it: right = -left + OFFSET."""

import json

import numpy as np
import pytest

from app.checking.certify import MotionBound, certify_path
from app.checking.oracle import CollisionOracle
from app.errors import UserError
from app.motion.trajectory import TrajectoryFile
from app.scene.custom import CustomSpec, build_scene
from app.scene.model import Scene
from independent import fine_points, raw_free

OFFSET = 0.005  # right finger = -left + OFFSET; its limits [-0.03, 0.005] keep left within [0, 0.035]
INERTIAL = '<inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>'
SAFETY = '<safety_controller soft_lower_limit="-2.9" soft_upper_limit="2.9" k_position="100" k_velocity="40"/>'
URDF = f"""<?xml version="1.0"?>
<robot name="gripper_arm">
  <link name="base"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <link name="upper">{INERTIAL}<collision><origin xyz="0.15 0 0"/><geometry><box size="0.2 0.05 0.05"/></geometry>
    </collision></link>
  <link name="fore">{INERTIAL}<collision><origin xyz="0.1 0 0"/><geometry><box size="0.2 0.05 0.05"/></geometry>
    </collision></link>
  <link name="left">{INERTIAL}<collision><geometry><box size="0.02 0.02 0.06"/></geometry></collision></link>
  <link name="right">{INERTIAL}<collision><geometry><box size="0.02 0.02 0.06"/></geometry></collision></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/>{SAFETY}</joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/><origin xyz="0.3 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="1" velocity="1"/>{SAFETY}</joint>
  <joint name="finger_left" type="prismatic"><parent link="fore"/><child link="left"/><origin xyz="0.2 0 0.06"/>
    <axis xyz="0 1 0"/><limit lower="0" upper="0.04" effort="1" velocity="0.2"/></joint>
  <joint name="finger_right" type="prismatic"><parent link="fore"/><child link="right"/><origin xyz="0.2 0 -0.06"/>
    <axis xyz="0 1 0"/><limit lower="-0.03" upper="0.005" effort="1" velocity="0.1"/>
    <mimic joint="finger_left" multiplier="-1" offset="{OFFSET}"/></joint>
</robot>
"""
# A thin plate across the right finger's travel: free with the gripper closed (left 0) and open (left 0.035), hit in
# between. Only the right finger reaches it: the left one and the forearm pass above it.
PLATE = """<?xml version="1.0"?>
<sdf version="1.7"><model name="plate"><static>true</static><link name="l">
  <collision name="c"><pose>0.5 -0.0125 -0.06 0 0 0</pose><geometry><box><size>0.02 0.005 0.04</size></box></geometry>
  </collision></link></model></sdf>
"""


def right_finger(left):
    return -np.asarray(left) + OFFSET


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mimic")
    (folder / "arm.urdf").write_text(URDF)
    (folder / "plate.sdf").write_text(PLATE)
    return folder


@pytest.fixture(scope="module")
def oracle(files, tmp_path_factory):
    spec = CustomSpec(robot=str(files / "arm.urdf"), env=[str(files / "plate.sdf")], collisions="all")
    return CollisionOracle(build_scene(spec, cache_dir=tmp_path_factory.mktemp("cache"), progress=False))


def test_a_mimic_joint_is_no_coordinate_and_keeps_its_limits(oracle):
    scene = oracle.scene
    assert scene.coordinate_names == ["shoulder", "elbow", "finger_left"]
    assert scene.joint_names == ["shoulder", "elbow", "finger_left", "finger_right"]
    assert oracle.plant.num_positions() == 4
    # The right finger's limits [-0.03, 0.005] shrink the left one's [0, 0.04] to [0, 0.035]; its speed limit 0.1
    # (multiplier -1) the left one's 0.2 to 0.1.
    assert scene.lower[2] == pytest.approx(0.0) and scene.upper[2] == pytest.approx(0.035)
    assert scene.velocity_limits[2] == pytest.approx(0.1)
    q = np.array([0.3, -0.2, 0.01])
    assert scene.positions(q) == pytest.approx([0.3, -0.2, 0.01, right_finger(0.01)])
    # Drake sees the right finger where the map puts it.
    context = oracle.plant.CreateDefaultContext()
    oracle.plant.SetPositions(context, scene.positions(q))
    right = oracle.plant.GetBodyByName("right").EvalPoseInWorld(context).translation()
    left = oracle.plant.GetBodyByName("left").EvalPoseInWorld(context).translation()
    assert np.linalg.norm(right[:2] - left[:2]) == pytest.approx(0.01 - right_finger(0.01))


def test_a_scene_without_mimic_joints_has_no_map():
    scene = Scene("bar-3link")
    q = scene.start
    assert scene.position_map is None and scene.positions(q) is q
    assert scene.joint_names == scene.coordinate_names


def test_sweeping_the_mimic_finger_through_an_obstacle_is_not_certified(oracle):
    wide = oracle.scene.upper[2]  # 0.035, to rounding
    closed, opened = np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, wide])
    assert oracle.free(closed) and oracle.free(opened)
    # Independently: the plant's positions written out here, checked on SceneGraph directly.
    points = fine_points(oracle, np.array([closed, opened]), 1e-4)
    by_hand = np.column_stack([points, right_finger(points[:, 2])])
    hit = [not raw_free(oracle, p) for p in by_hand]
    assert any(hit) and not hit[0] and not hit[-1]
    ok, stats = certify_path(oracle.context(), np.array([closed, opened]))
    assert not ok and stats["distance_queries"] > 2  # bisected down to the contact, not refused at an end
    # The same opening with the arm turned away from the plate is proved free.
    away = np.array([[1.5, 0.0, 0.0], [1.5, 0.0, wide]])
    assert all(raw_free(oracle, np.append(p, right_finger(p[2]))) for p in fine_points(oracle, away, 1e-3))
    assert certify_path(oracle.context(), away)[0]


def test_the_two_fingers_distance_changes_with_their_one_coordinate(oracle):
    """The fingers' joints are not shared, though one coordinate drives both: their pair's rate counts both."""
    bound = MotionBound(oracle)
    rows = {
        oracle.plant.GetBodyByName(name).name(): bound.row(oracle.plant.GetCollisionGeometriesForBody(body)[0])
        for name in ("left", "right")
        for body in [oracle.plant.GetBodyByName(name)]
    }
    assert bound.rates[rows["right"], 2] >= 1.0  # the right finger moves with finger_left
    assert bound.pair_rates[rows["left"], rows["right"], 2] >= 2.0


def test_a_plan_keeps_equal_fingers_equal_and_writes_every_joint(tmp_path, cli, monkeypatch):
    monkeypatch.setenv("NPP_CACHE_DIR", str(tmp_path / "cache"))
    # A file name this process has not parsed yet, so its parser warnings are new (they are summarised once).
    out, bag, robot = tmp_path / "motion.json", tmp_path / "bag", tmp_path / "fingers_follow.urdf"
    robot.write_text(URDF)
    args = ["--robot", robot, "--start", "0,0,0.02", "--goal", "1.5,0.5,0.02", "--seed", "1"]
    result = cli("plan", *args, "--json", "--out", out, "--bag", bag)
    assert result.returncode == 0, result.stderr
    answer = json.loads(result.stdout)
    trajectory = answer["trajectory"]
    assert trajectory["joint_names"] == ["shoulder", "elbow", "finger_left", "finger_right"]
    P = np.array(trajectory["positions"])
    assert np.allclose(P[:, 2], 0.02) and np.allclose(P[:, 3], right_finger(0.02))
    assert np.allclose(np.array(trajectory["velocities"])[:, 2:], 0.0)
    assert answer["path"][0] == [0.0, 0.0, 0.02]  # the answer's configurations are the planned coordinates
    # The parser's warnings about the two <safety_controller> elements: one line, not one per element per parse.
    assert "found as a child of" not in result.stderr
    notes = [line for line in result.stderr.splitlines() if line.startswith("note:")]
    assert notes == [
        "note: fingers_follow.urdf: Drake ignored 2 elements it does not use for planning (safety_controller x2)"
    ]

    # The file reads back as coordinates (`view` writes its bag from it); one whose mimic joint does not follow is
    # refused.
    file = json.loads(out.read_text())
    assert all(len(row) == 4 for key in ("waypoints", "narrow_samples") for row in file.get(key, []))
    (tmp_path / "scene.yaml").write_text(f"robot: {robot.name}\n")
    shown = cli("view", tmp_path / "scene.yaml", "--trajectory", out, "--bag", tmp_path / "bag2")
    assert shown.returncode == 0, shown.stderr
    scene = build_scene(CustomSpec(robot=str(robot)), progress=False)
    read = TrajectoryFile.from_json(file, scene.dim, position_map=scene.position_map)
    assert read.trajectory.positions.shape[1] == 3
    assert np.allclose(read.trajectory.joints()[1], P)
    file["positions"][1][3] += 0.001
    with pytest.raises(UserError, match="mimic joint 'finger_right'"):
        TrajectoryFile.from_json(file, scene.dim, position_map=scene.position_map)

    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    for folder in (bag, tmp_path / "bag2"):
        with Reader(folder) as reader:
            (connection, _, raw), *_ = list(reader.messages())
            message = store.deserialize_cdr(raw, connection.msgtype)
        assert list(message.joint_names) == trajectory["joint_names"]
        assert np.allclose([point.positions for point in message.points], P)


def test_pose_answers_name_the_tool_frame_and_certificates_say_what_they_left_out(files, cli, monkeypatch, tmp_path):
    monkeypatch.setenv("NPP_CACHE_DIR", str(tmp_path))
    args = ["--robot", files / "arm.urdf", "--start", "0,0,0.02", "--no-self-collision"]
    result = cli("plan", *args, "--goal-pose", "0.3,0.2,0.06,0,0,90", "--tool", "left", "--json")
    assert result.returncode == 0, result.stderr
    answer = json.loads(result.stdout)
    assert answer["tool_frame"] == {"name": "left", "chosen": "tool"}
    assert answer["certified"] and answer["certified_collisions"] == "environment"
    assert answer["self_collision"] is False

    # Without --tool the pose places the robot's last body, here the mimic finger, and the answer says so.
    text = cli("plan", *args, "--goal-pose", "0.3,0.2,-0.06,0,0,90")
    assert text.returncode == 0, text.stderr
    assert "certified to keep" in text.stdout and "(continuous; self-collision not checked)" in text.stdout
    assert "tool      right placed by the pose(s) (the robot's last body; --tool FRAME picks another)" in text.stdout
