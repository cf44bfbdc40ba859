"""`--bag DIR`: a planned trajectory as a ROS 2 bag, read back with rosbags as a ROS tool would."""

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

rosbags = pytest.importorskip("rosbags")

from app.motion.rosbag import DEFAULT_DISTRO, DISTROS, MESSAGE_TYPE, TOPIC  # noqa: E402


def read_bag(folder) -> list:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(folder) as reader:
        return [
            (connection.topic, connection.msgtype, store.deserialize_cdr(data, connection.msgtype))
            for connection, _, data in reader.messages()
        ]


def seconds(duration) -> float:
    return duration.sec + 1e-9 * duration.nanosec


def test_a_planned_trajectory_reads_back_as_one_joint_trajectory(cli, tmp_path):
    bag, out = tmp_path / "bag", tmp_path / "t.json"
    result = cli("plan", "bar-3link", "--out", out, "--bag", bag)
    assert result.returncode == 0, result.stderr
    assert f"wrote {bag}" in result.stderr.splitlines() and f"wrote {out}" in result.stderr.splitlines()
    file = json.loads(out.read_text())
    (topic, msgtype, message), *others = read_bag(bag)
    assert not others and topic == TOPIC and msgtype == MESSAGE_TYPE == message.__msgtype__
    assert message.joint_names == file["joint_names"]
    assert len(message.points) == len(file["time_from_start"]) > 2
    times = np.array([seconds(p.time_from_start) for p in message.points])
    assert np.all(np.diff(times) > 0) and times[0] == 0
    assert np.allclose(times, file["time_from_start"], atol=1e-9)
    for key in ("positions", "velocities", "accelerations"):
        assert np.array_equal(np.array([getattr(p, key) for p in message.points]), np.array(file[key])), key
    assert not list(tmp_path.glob(".*"))  # no temporary folder left beside it
    assert sorted(p.name for p in bag.iterdir()) == ["bag.db3", "metadata.yaml"]  # named as ros2 bag names them


def test_view_writes_the_bag_of_a_trajectory_file(cli, tmp_path):
    out = tmp_path / "t.json"
    assert cli("plan", "bar", "--out", out).returncode == 0
    result = cli("view", "bar", "--trajectory", out, "--bag", tmp_path / "bag", "--json")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["bag"] == str(tmp_path / "bag")
    (_, _, message), *_ = read_bag(tmp_path / "bag")
    assert np.array_equal(np.array([p.positions for p in message.points]), json.loads(out.read_text())["positions"])


def test_an_existing_folder_is_refused_before_planning_and_nothing_is_written(cli, tmp_path):
    (tmp_path / "bag").mkdir()
    result = cli("plan", "bar", "--out", tmp_path / "t.json", "--bag", tmp_path / "bag")
    assert result.returncode == 2 and "exists already" in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"] and not list((tmp_path / "bag").iterdir())


def test_a_failed_write_leaves_no_half_bag(tmp_path, monkeypatch):
    from app.motion import rosbag
    from app.motion.trajectory import Trajectory

    trajectory = Trajectory(["a"], np.array([0.0, 1.0]), np.zeros((2, 1)), np.zeros((2, 1)), np.zeros((2, 1)),
                            np.zeros((2, 1)), np.array([0.0, 1.0]))  # fmt: skip
    from rosbags.rosbag2 import Writer

    def fail(*args):
        assert list(tmp_path.iterdir()), "the bag's folder was started"
        raise RuntimeError("disk full")

    monkeypatch.setattr(Writer, "write", fail)
    with pytest.raises(RuntimeError, match="disk full"):
        rosbag.write_bag(tmp_path / "bag", trajectory)
    assert not list(tmp_path.iterdir())


def test_the_ur3_joints_are_named_as_in_ur_description(oracles):
    from app.scene.files import PACKAGES

    urdf = ET.parse(PACKAGES["npp_robots"] / "ur3_on_cart.urdf")
    moving = [j.get("name") for j in urdf.getroot().iter("joint") if j.get("type") != "fixed"]
    expected = [f"{name}_joint" for name in ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")]
    assert moving == expected
    assert oracles("welding").space.names == expected


def metadata(folder) -> dict:
    from ruamel.yaml import YAML

    return YAML(typ="safe").load((folder / "metadata.yaml").read_text())["rosbag2_bagfile_information"]


@pytest.mark.parametrize("distro", DISTROS)
def test_each_distributions_bag_reads_back_with_its_metadata_version(tmp_path, distro):
    """--ros-distro humble writes version 5 as Humble's rosbag2 0.15 writes and reads it: a topic's QoS profiles a
    string (as<std::string>() in its metadata parser), and none of the fields later versions added; iron 8, jazzy 9
    (QoS profiles a list, which Humble cannot parse). Each reads back whole, and its header is stamped 0:
    ros2_control's joint trajectory controller then starts it on arrival, where it refuses a stamp whose trajectory
    ends in the past."""
    import sqlite3

    from app.motion import rosbag
    from app.motion.trajectory import Trajectory

    times = np.array([0.0, 0.5, 1.25])
    positions = np.array([[0.0, 1.0], [0.5, 1.5], [1.0, 2.0]])
    trajectory = Trajectory(["a", "b"], times, positions, positions / 2, positions / 4, positions, times)
    rosbag.write_bag(tmp_path / "bag", trajectory, distro=distro)
    (topic, msgtype, message), *others = read_bag(tmp_path / "bag")
    assert not others and (topic, msgtype) == (TOPIC, MESSAGE_TYPE) and message.joint_names == ["a", "b"]
    assert (message.header.stamp.sec, message.header.stamp.nanosec) == (0, 0)
    assert np.allclose([seconds(p.time_from_start) for p in message.points], times, atol=1e-9)
    for key, values in (("positions", positions), ("velocities", positions / 2), ("accelerations", positions / 4)):
        assert np.array_equal([getattr(p, key) for p in message.points], values), key
    info = metadata(tmp_path / "bag")
    assert info["version"] == DISTROS[distro] and info["storage_identifier"] == "sqlite3"
    (topic_info,) = info["topics_with_message_count"]
    qos = topic_info["topic_metadata"]["offered_qos_profiles"]
    assert isinstance(qos, list) if distro == "jazzy" else qos == ""
    with sqlite3.connect(tmp_path / "bag" / "bag.db3") as database:
        assert database.execute("SELECT metadata_version FROM metadata").fetchall() == [(DISTROS[distro],)]
    if distro == "humble":
        assert DISTROS[distro] == 5
        assert not {"custom_data", "ros_distro"} & set(info)
        assert "type_description_hash" not in topic_info["topic_metadata"]
        assert {"files", "compression_format", "compression_mode", "relative_file_paths"} <= set(info)


def test_ros_distro_picks_the_bag_version_from_the_command_line(cli, tmp_path, one_line_error):
    out = tmp_path / "t.json"
    assert cli("plan", "bar", "--out", out).returncode == 0
    result = cli("view", "bar", "--trajectory", out, "--bag", tmp_path / "humble", "--ros-distro", "humble")
    assert result.returncode == 0, result.stderr
    assert metadata(tmp_path / "humble")["version"] == 5
    assert cli("view", "bar", "--trajectory", out, "--bag", tmp_path / "default").returncode == 0
    assert metadata(tmp_path / "default")["version"] == DISTROS[DEFAULT_DISTRO] == 8
    assert "--ros-distro needs --bag" in one_line_error(cli("plan", "bar", "--ros-distro", "humble"), 2)
    assert "--ros-distro" in one_line_error(cli("view", "bar", "--trajectory", out, "--bag", tmp_path / "x",
                                                "--ros-distro", "foxy"), 2)  # fmt: skip


def write_ros_bag(folder, names, times, positions, messages=1):
    """A bag as a ROS tool might record it: `messages` copies of one JointTrajectory, its points positions only."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    types = store.types
    points = [
        types["trajectory_msgs/msg/JointTrajectoryPoint"](
            positions=np.ascontiguousarray(q, float),
            velocities=np.zeros(0),
            accelerations=np.zeros(0),
            effort=np.zeros(0),
            time_from_start=types["builtin_interfaces/msg/Duration"](sec=int(t), nanosec=int(round(t % 1 * 1e9))),
        )
        for t, q in zip(times, positions)
    ]
    header = types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=5, nanosec=0), frame_id="")
    message = types[MESSAGE_TYPE](header=header, joint_names=names, points=points)
    with Writer(folder, version=8) as writer:
        connection = writer.add_connection(TOPIC, MESSAGE_TYPE, typestore=store)
        for i in range(messages):
            writer.write(connection, i, store.serialize_cdr(message, MESSAGE_TYPE))


def test_view_replays_the_bag_plan_wrote(cli, tmp_path):
    """`view --trajectory BAG` reads a bag back: written again, it holds the same points as the plan's file."""
    out, bag, again = tmp_path / "t.json", tmp_path / "bag", tmp_path / "again"
    assert cli("plan", "bar-3link", "--out", out, "--bag", bag).returncode == 0
    result = cli("view", "bar-3link", "--trajectory", bag, "--bag", again)
    assert result.returncode == 0, result.stderr
    file = json.loads(out.read_text())
    (_, _, message), *_ = read_bag(again)
    for key in ("positions", "velocities", "accelerations"):
        assert np.array_equal(np.array([getattr(p, key) for p in message.points]), np.array(file[key])), key


def test_a_ros_tools_bag_is_read_by_joint_name_with_rates_estimated(cli, tmp_path):
    """Joints in another order, positions only, two messages: the first is read, its joints put in the scene's
    order, its velocities estimated; a note says which message was read."""
    out = tmp_path / "t.json"
    assert cli("plan", "bar", "--out", out).returncode == 0
    file = json.loads(out.read_text())
    names, times, P = file["joint_names"], np.array(file["time_from_start"]), np.array(file["positions"])
    write_ros_bag(tmp_path / "ros", names[::-1], times, P[:, ::-1], messages=2)
    result = cli("view", "bar", "--trajectory", tmp_path / "ros", "--bag", tmp_path / "again")
    assert result.returncode == 0, result.stderr
    assert "note: bag ros holds 2 joint trajectories: the first is read" in result.stderr.splitlines()
    (_, _, message), *_ = read_bag(tmp_path / "again")
    assert message.joint_names == names
    assert np.allclose([p.positions for p in message.points], P)
    V = np.array([p.velocities for p in message.points])
    inner = slice(1, -1)  # central differences of the samples: close to the planned velocities inside
    assert np.allclose(V[inner], np.array(file["velocities"])[inner], atol=0.05 * np.abs(file["velocities"]).max())


def test_a_folder_that_is_no_bag_or_a_bag_without_the_scenes_joints_is_one_line(cli, tmp_path, one_line_error):
    (tmp_path / "empty").mkdir()
    args = ("--bag", tmp_path / "again")
    said = one_line_error(cli("view", "bar", "--trajectory", tmp_path / "empty", *args), 2)
    assert "empty is not a ROS 2 bag" in said
    write_ros_bag(tmp_path / "other", ["a", "b"], [0.0, 1.0], [[0, 0], [1, 1]])
    said = one_line_error(cli("view", "bar", "--trajectory", tmp_path / "other", *args), 2)
    assert "other: the trajectory has no joint" in said
    assert not (tmp_path / "again").exists()
