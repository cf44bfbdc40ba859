"""Bring your own robot and environment (app.scene.custom): a mesh robot flies through a non-convex mesh channel
whose convex hull would block it, URDF robots with package paths, custom scene files, and bad input."""

import json
import re
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("trimesh")

import trimesh  # noqa: E402

from app.errors import InvalidEndpoint, Note, UserError  # noqa: E402
from app.scene.custom import ENV_TOLERANCE_PER_STEP, CustomSpec, build_scene, load_scene  # noqa: E402
from mesh_shapes import open_u, u_channel  # noqa: E402
from meshcat_page import commands  # noqa: E402

# The channel (tests/mesh_shapes.py) runs along x in [-2, 2]; slot |y| < 1 above the floor z > 0.5, walls to z = 2.
# A 0.6 cube kept to |y| <= 1.7 and z <= 2.2 can pass neither over the walls (needs z >= 2.3) nor round them
# (needs |y| >= 1.8): only through the slot. The U's convex hull would close the slot.
BOUNDS = ["-3.5..3.5", "-1.7..1.7", "0.8..2.2"]
START = [-3.0, 1.5, 2.1, 0, 0, 0]
GOAL = [3.0, -1.5, 0.9, 0, 0, 0]
IN_SLOT = [0.0, 0.0, 1.5, 0, 0, 0]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("byo")
    u_channel().export(d / "channel.stl")
    open_u().export(d / "open_channel.dae")
    trimesh.creation.box([0.6, 0.6, 0.6]).export(d / "cube.obj")
    return d


def _spec(files, env="channel.stl", **kw):
    args = dict(robot=str(files / "cube.obj"), env=[str(files / env)], start=START, goal=GOAL, bounds=BOUNDS)
    args.update(kw)
    return CustomSpec(**args)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("cache")


@pytest.fixture(scope="module")
def channel_oracle(files, cache):
    from app.checking.oracle import CollisionOracle

    scene = build_scene(_spec(files), cache_dir=cache, progress=False)
    return CollisionOracle(scene)


def test_floating_mesh_robot_has_six_coordinates(channel_oracle):
    scene = channel_oracle.scene
    assert scene.coordinate_names == ["x", "y", "z", "yaw", "pitch", "roll"]
    assert scene.lower[:3].tolist() == [-3.5, -1.7, 0.8] and scene.upper[:3].tolist() == [3.5, 1.7, 2.2]
    assert scene.continuous[3:].all() and not scene.continuous[:3].any()
    assert scene.weights[3] == pytest.approx(scene.weights[5]) and scene.weights[3] > 0.4  # the cube's radius


def test_the_decomposition_not_the_hull_is_used(channel_oracle):
    o = channel_oracle.context()
    assert o.is_free(np.array(IN_SLOT))  # inside the U's convex hull, yet free
    assert not o.is_free(np.array([0.0, 1.25, 1.5, 0, 0, 0]))  # in a wall
    assert not o.is_free(np.array([0.0, 0.0, 0.5, 0, 0, 0]))  # in the floor
    along = o.edges_free(np.array([[-3.0, 0, 1.5, 0, 0, 0]]), np.array([[3.0, 0, 1.5, 0, 0, 0]]))
    across = o.edges_free(np.array([[0.0, 0, 1.5, 0, 0, 0]]), np.array([[0.0, 1.6, 1.5, 0, 0, 0]]))
    assert along[0] and not across[0]
    assert not o.edge_free(np.array(START), np.array(GOAL))


def test_environment_pieces_are_anchored_to_the_world(channel_oracle):
    """On the world body SceneGraph keeps them in its static broad-phase tree; on a welded body they would be moved
    and re-sorted on every query."""
    from pydrake.geometry import Role

    inspector = channel_oracle.model.scene_graph().model_inspector()
    robot = channel_oracle.robot_geometries
    env = [g for g in inspector.GetAllGeometryIds(Role.kProximity) if g not in robot]
    assert len(env) == channel_oracle.scene.info["decompositions"][1]["pieces"] > 1 and robot  # the channel's
    assert all(inspector.GetFrameId(g) == inspector.world_frame_id() for g in env)
    assert all(inspector.GetFrameId(g) != inspector.world_frame_id() for g in robot)
    # Collisions with them are named by piece (the world body would say nothing).
    named = channel_oracle.diagnostics.colliding_bodies(np.array([0.0, 1.25, 1.5, 0, 0, 0]))
    assert named[0][0].startswith("env0_piece")


def test_default_mesh_tolerance_follows_the_edge_check_step_on_a_torus(files, tmp_path):
    """The environment's tolerance is half the edge-check step, not 0.2 % of the mesh's size: a solid torus becomes
    a few dozen valid pieces reaching into the solid, not hundreds of face plates."""
    trimesh.creation.torus(1.0, 0.3, major_sections=24, minor_sections=12).export(tmp_path / "torus.obj")
    spec = CustomSpec(
        robot=str(files / "cube.obj"),
        env=[str(tmp_path / "torus.obj")],
        start=[0, 0, 1, 0, 0, 0],
        goal=[0, 0, -1, 0, 0, 0],
    )
    scene = build_scene(spec, cache_dir=tmp_path, progress=False)
    torus = scene.info["decompositions"][1]
    assert torus["validation"]["ok"] and torus["validation"]["tolerance"] == pytest.approx(
        ENV_TOLERANCE_PER_STEP * scene.resolution
    )
    assert torus["method"] == "split" and torus["pieces"] <= 80


def test_default_step_follows_the_robot_not_its_face_plates(files, cache):
    """An open U as the robot is bounded by thin hulls of its walls; the step is a quarter of the U's smallest width
    (2, its height), not of a wall's thickness."""
    spec = CustomSpec(
        robot=str(files / "open_channel.dae"),
        env=[],
        start=[0, 0, 0, 0, 0, 0],
        goal=[1, 0, 0, 0, 0, 0],
        bounds=["-5..5", "-5..5", "-5..5"],
    )
    scene = build_scene(spec, cache_dir=cache, progress=False)
    assert scene.info["decompositions"][0]["method"] == "split"
    assert scene.resolution == pytest.approx(0.25 * 2.0, rel=0.02)


def test_plan_goes_through_the_channel(channel_oracle):
    from app.planning.query import plan
    from app.planning.settings import PlanSettings

    result = plan(channel_oracle, PlanSettings(narrow=60, uniform=120, seed=1, smooth_rounds=10))
    path = result.path
    assert np.allclose(path[0], START) and np.allclose(path[-1], GOAL)
    # Densify the path: where it crosses x = 0 it is inside the slot.
    dense = np.vstack([np.linspace(a, b, 50) for a, b in zip(path[:-1], path[1:])])
    middle = dense[np.abs(dense[:, 0]) < 0.2]
    assert len(middle) and np.all(np.abs(middle[:, 1]) < 0.7) and np.all(middle[:, 2] < 2.2)


def test_open_collada_channel_and_second_build_is_cached(files, tmp_path, monkeypatch):
    from app.checking.oracle import CollisionOracle
    from app.scene.meshes import decomposition

    first = build_scene(_spec(files, env="open_channel.dae"), cache_dir=tmp_path, progress=False)
    assert first.info["decompositions"][1]["method"] == "split"
    oracle = CollisionOracle(first).context()
    assert oracle.is_free(np.array(IN_SLOT)) and not oracle.is_free(np.array([0.0, 1.0, 1.5, 0, 0, 0]))
    assert oracle.edge_free(np.array([-3.0, 0, 1.5, 0, 0, 0]), np.array([3.0, 0, 1.5, 0, 0, 0]))
    # Calling it now fails: the second build reads the cache
    monkeypatch.setattr(decomposition, "decompose_parts", None)
    again = build_scene(_spec(files, env="open_channel.dae"), cache_dir=tmp_path, progress=False)
    assert all(d["from_cache"] for d in again.info["decompositions"])


def test_env_pose_moves_the_mesh(files, cache):
    from app.checking.oracle import CollisionOracle

    # Channel turned to run along y and lifted by 10: the slot is now |x| < 1, z in 10.5..12.
    spec = _spec(
        files,
        env_pose=[0, 0, 10, 0, 0, 90],
        bounds=["-1.7..1.7,-3.5..3.5,10.8..12.2"],
        start=[0, -3, 11.5, 0, 0, 0],
        goal=[0, 3, 11.5, 0, 0, 0],
    )
    oracle = CollisionOracle(build_scene(spec, cache_dir=cache, progress=False)).context()
    assert oracle.edge_free(oracle.scene.start, oracle.scene.goal)
    assert not oracle.is_free(np.array([1.25, 0, 11.5, 0, 0, 0]))


def test_a_relative_cache_folder_works(files, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("NPP_CACHE_DIR", "cache")
    scene = build_scene(_spec(files, env="open_channel.dae"), progress=False)
    assert scene.dim == 6 and (tmp_path / "cache" / "meshes").is_dir()


def test_custom_scene_file(files, cache):
    scene_file = files / "byo.yaml"
    scene_file.write_text(
        "robot: cube.obj\nenv: [channel.stl]\nbounds: ['-3.5..3.5', '-1.7..1.7', '0.8..2.2']\n"
        f"start: {START}\ngoal: {GOAL}\n"
    )
    scene = load_scene(str(scene_file), cache_dir=cache)
    assert scene.dim == 6 and scene.name == "cube-in-channel"
    with pytest.raises(UserError, match="bad scene file"):
        (files / "bad.yaml").write_text("robot: cube.obj\nenvv: []\n")
        load_scene(str(files / "bad.yaml"), cache_dir=cache)


def test_every_scene_command_takes_a_custom_scene_file(files, tmp_path, monkeypatch, capsys):
    from app.cli import main

    monkeypatch.setenv("NPP_CACHE_DIR", str(tmp_path / "cache"))
    scene_file = files / "byo_cli.yaml"
    scene_file.write_text(
        "robot: cube.obj\nenv: [channel.stl]\nbounds: ['-3.5..3.5', '-1.7..1.7', '0.8..2.2']\n"
        f"start: {START}\ngoal: {GOAL}\n"
    )
    scene = str(scene_file)
    assert main(["show", scene, "--png", str(tmp_path / "show.png")]) == 0
    assert (
        main(["sample", scene, "--sampler", "lfbs", "-k", "5", "--step", "0.5", "--png", str(tmp_path / "samples.png")])
        == 0
    )
    assert "no passage region declared" in capsys.readouterr().out
    assert (
        main(
            [
                "plan",
                scene,
                "--narrow",
                "60",
                "--uniform",
                "120",
                "--seed",
                "1",
                "--smooth",
                "5",
                "--out",
                str(tmp_path / "traj.json"),
            ]
        )
        == 0
    )
    monkeypatch.setenv("DRAKE_ALLOW_NETWORK", "meshcat")  # the viewer needs Meshcat even to export a page
    assert main(["view", scene, "--trajectory", str(tmp_path / "traj.json"), "--html", str(tmp_path / "v.html")]) == 0
    assert "cube" in (tmp_path / "v.html").read_text()
    # The planning panel: up and down at once; its start and goal robots are copies of the mesh robot.
    assert (
        main(["gui", scene, "--wait", "0", "--html", str(tmp_path / "g.html"), "--state", str(tmp_path / "g.json")])
        == 0
    )
    drawn = {c["path"] for c in commands((tmp_path / "g.html").read_text()) if c["type"] == "set_object"}
    assert any(path.startswith("/goal/") for path in drawn)
    assert json.loads((tmp_path / "g.json").read_text())["goal_free"]


def test_pictures_draw_mesh_pieces(channel_oracle):
    import matplotlib.pyplot as plt

    from app.draw import Picture

    picture = Picture(channel_oracle)
    assert picture.solids.count("obstacle") >= 3  # the channel's convex pieces (its floor and two walls at least)
    faces = len(picture._faces.polygons)
    picture.add_robot(np.array(IN_SLOT), "tab:blue", 0.9, "robot")
    assert picture.solids.count("robot") == 1 and len(picture._faces.polygons) > faces  # the cube
    plt.close(picture.fig)


# ---- URDF robots and package paths ---------------------------------------------------------------------------------
ARM = """<?xml version="1.0"?>
<robot name="arm">
  <link name="base"><collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <link name="link1">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0.5 0 0"/><geometry><mesh filename="package://my_arm/meshes/link.obj"/></geometry>
    </collision>
  </link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="link1"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>
"""


@pytest.fixture(scope="module")
def arm_package(tmp_path_factory):
    root = tmp_path_factory.mktemp("my_arm")
    (root / "meshes").mkdir()
    trimesh.creation.box([1.0, 0.1, 0.1]).export(root / "meshes" / "link.obj")
    trimesh.creation.box([1.0, 0.1, 0.1]).export(root / "meshes" / "link.stl")
    (root / "arm.urdf").write_text(ARM)
    # The same arm with an STL collision mesh (Drake cannot read it) and a relative DAE visual.
    (root / "arm_stl.urdf").write_text(
        ARM.replace("link.obj", "link.stl").replace(
            "<collision><origin",
            '<visual><origin xyz="0.5 0 0"/><geometry><mesh filename="meshes/link.dae"/>'
            "</geometry></visual>\n    <collision><origin",
        )
    )
    trimesh.creation.box([1.0, 0.1, 0.1]).export(root / "meshes" / "link.dae")
    return root


@pytest.mark.parametrize("urdf", ["arm.urdf", "arm_stl.urdf"])
def test_urdf_arm_with_a_package_path(arm_package, tmp_path, urdf):
    from app.checking.oracle import CollisionOracle

    # A post at x = 0.8, y = 0 stands in the link's way at j1 = 0 (the link reaches x = 1, at z = 0.3).
    post = trimesh.creation.box([0.1, 0.1, 1.0], trimesh.transformations.translation_matrix([0.8, 0, 0.5]))
    post.export(tmp_path / "post.stl")
    spec = CustomSpec(
        robot=str(arm_package / urdf),
        package_path=[f"my_arm={arm_package}"],
        env=[str(tmp_path / "post.stl")],
        start=[1.0],
        goal=[-1.0],
    )
    scene = build_scene(spec, cache_dir=tmp_path, progress=False)
    assert scene.dim == 1 and scene.lower.tolist() == [-3] and scene.upper.tolist() == [3]
    oracle = CollisionOracle(scene).context()
    assert oracle.is_free(np.array([1.0])) and not oracle.is_free(np.array([0.0]))
    assert not oracle.edge_free(np.array([1.0]), np.array([-1.0]))


def test_a_robot_of_ones_own_sets_its_limits(arm_package, tmp_path):
    spec = CustomSpec(robot=str(arm_package / "arm.urdf"), package_path=[f"my_arm={arm_package}"])
    default = build_scene(spec, cache_dir=tmp_path, progress=False)
    assert default.velocity_limits.tolist() == [1.0]  # the URDF's
    assert default.acceleration_limits.tolist() == [2.0]  # twice that, as for a shipped scene
    spec.velocity_limits, spec.acceleration_limits = [0.5], [3.0]
    given = build_scene(spec, cache_dir=tmp_path, progress=False)
    assert given.velocity_limits.tolist() == [0.5] and given.acceleration_limits.tolist() == [3.0]


@pytest.mark.parametrize("urdf", ["arm.urdf", "arm_stl.urdf"])
def test_unknown_package_is_one_line(arm_package, tmp_path, urdf):
    spec = CustomSpec(robot=str(arm_package / urdf), start=[1.0], goal=[-1.0], bounds=["-3..3"])
    with pytest.raises(UserError, match=r"unknown package 'my_arm' \(add the package path my_arm=DIR\)"):
        build_scene(spec, cache_dir=tmp_path, progress=False)


@pytest.mark.parametrize(
    "change, message",
    [
        (dict(robot="missing.urdf"), "robot file not found"),
        (dict(env=["missing.stl"]), "environment file not found"),
        (dict(robot="broken.urdf"), "cannot load broken.urdf"),
        (dict(env=["garbage.stl"]), "cannot read mesh garbage.stl"),
        (dict(robot="cube.txt"), "unsupported type"),
        (dict(bounds=["1..0"]), "bad bounds item"),
        (dict(bounds=["0..1", "0..1"]), "6 lo..hi items needed"),
        (dict(start=[0, 0]), "start needs 6 numbers"),
        (dict(goal=[0, 0, 0, float("nan"), 0, 0]), "goal needs finite numbers, yaw is nan"),
        (dict(env_pose=[1, 2]), "env pose needs 6"),
        (dict(package_path=["nodir"]), "NAME=DIR"),
        (dict(package_path=["p=/no/such/dir"]), "directory not found"),
        (dict(velocity_limits=[1, 2]), "velocity_limits needs 6 numbers"),
        (dict(acceleration_limits=[1, 1, 1, 1, 1, 0]), "acceleration_limits must be positive"),
    ],
)
def test_bad_input_is_a_one_line_user_error(files, cache, change, message):
    (files / "broken.urdf").write_text("<robot name='b'><link name='a'></robot>")
    (files / "garbage.stl").write_bytes(b"garbage")
    (files / "cube.txt").write_text("x")
    spec = _spec(files)
    for key, value in change.items():
        if key in ("robot",):
            value = str(files / value)
        if key == "env":
            value = [str(files / v) for v in value]
        setattr(spec, key, value)
    with pytest.raises(UserError, match=message) as info:
        build_scene(spec, cache_dir=cache, progress=False)
    assert type(info.value) is UserError and "\n" not in str(info.value)


LATER_LINK = """  <link name="link2">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><mesh filename="{mesh}"/></geometry></collision>
  </link>
  <joint name="j2" type="revolute"><parent link="link1"/><child link="link2"/><origin xyz="1 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>"""


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda t: t.replace('lower="-3"', 'lower="-1e300"'), "joint 'j1': lower limit -1e300 is out of range"),
        (lambda t: t.replace('upper="3"', 'upper="inf"'), "joint 'j1': upper limit inf is not a finite number"),
        (lambda t: t.replace('<parent link="base"/>', '<parent link="nowhere"/>'), "Could not find link named"),
        (lambda t: t.replace("</robot>", LATER_LINK.format(mesh="package://other/m.stl")), "unknown package 'other'"),
        (
            lambda t: t.replace("</robot>", LATER_LINK.format(mesh="package://my_arm/meshes/none.stl")),
            "mesh file not found: package://my_arm/meshes/none.stl",
        ),
        (lambda t: t.replace("</limit>", "").replace('velocity="1"/>', 'velocity="1"/><mimic joint="j0"/>'), "'j0'"),
        (lambda t: t.replace("<robot", "<robot><link").replace("</robot>", "</robot></robot>"), "cannot load"),
    ],
)
def test_a_refusal_comes_before_any_mesh_work(arm_package, tmp_path, change, message):
    """The arm's mesh link (an STL: converted, then decomposed) comes first in the file; each fault is found later
    in the file, or only by Drake's parser, yet refused before the mesh is read: nothing is written to the cache."""
    robot = arm_package / "late_fault.urdf"
    robot.write_text(change((arm_package / "arm_stl.urdf").read_text()))
    spec = CustomSpec(robot=str(robot), package_path=[f"my_arm={arm_package}"], start=[1.0], goal=[-1.0])
    with pytest.raises(UserError, match=message) as info:
        build_scene(spec, cache_dir=tmp_path / "cache", progress=False)
    assert "\n" not in str(info.value) and "late_fault.urdf" in str(info.value)
    assert not any(p.is_file() for p in (tmp_path / "cache").rglob("*")), "mesh work was done before the refusal"


MIMIC_WITHOUT_ROOM = """  <link name="link2">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision>
  </link>
  <joint name="j2" type="revolute"><parent link="link1"/><child link="link2"/><origin xyz="1 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/><mimic joint="j1" offset="10"/></joint>
</robot>"""
BOX = ["-1..1,-1..1,-1..1"]
TWO_BODIES = """<?xml version="1.0"?>
<robot name="two"><link name="a"><collision><geometry><box size="1 1 1"/></geometry></collision></link>
  <link name="b"><collision><geometry><box size="1 1 1"/></geometry></collision></link></robot>
"""


@pytest.mark.parametrize(
    "change, keys, message",
    [
        (lambda t: t.replace("</robot>", '<link name="loose"/></robot>'), dict(floating=True, bounds=BOX), "found 2"),
        (lambda t: re.sub(r"<collision>.*?</collision>", "", t, flags=re.S), {}, "has no collision geometry"),
        (lambda t: t.replace("</robot>", MIMIC_WITHOUT_ROOM), {}, "joint 'j1': no position keeps the joints"),
        (lambda t: t, dict(env=["two.urdf"]), "two.urdf: an environment model must be static or one rigid body"),
    ],
)
def test_what_a_urdfs_bodies_tell_is_refused_before_any_mesh_work(arm_package, tmp_path, change, keys, message):
    """Drake's parser on the URDF without its geometry tells its root bodies and joints, and the XML its collision
    elements: a floating robot with two roots, a robot without collision geometry, a mimic joint that leaves no room,
    an environment URDF of two free bodies are refused before the arm's STL link is converted."""
    robot = arm_package / "body_fault.urdf"
    robot.write_text(change((arm_package / "arm_stl.urdf").read_text()))
    (tmp_path / "two.urdf").write_text(TWO_BODIES)
    keys["env"] = [str(tmp_path / name) for name in keys.get("env", [])]
    spec = CustomSpec(robot=str(robot), package_path=[f"my_arm={arm_package}"], **keys)
    with pytest.raises(UserError, match=message) as info:
        build_scene(spec, cache_dir=tmp_path / "cache", progress=False)
    assert "\n" not in str(info.value)
    assert not (tmp_path / "cache").exists(), "mesh work was done before the refusal"


def test_a_wrong_number_of_start_values_comes_before_any_mesh_work(arm_package, tmp_path):
    spec = CustomSpec(robot=str(arm_package / "arm_stl.urdf"), package_path=[f"my_arm={arm_package}"], start=[1, 2])
    with pytest.raises(UserError, match=r"start needs 1 numbers \(j1\), got 2"):
        build_scene(spec, cache_dir=tmp_path / "cache", progress=False)
    assert not (tmp_path / "cache").exists()


MATERIALS = {
    # Defined twice (Drake refuses a repeated definition, even of the same colour), and used but never defined.
    "top": '<material name="carbon_fiber"><color rgba="0.79 0.82 0.93 1"/></material>\n'
    '  <material name="carbon_fiber"><color rgba="0.2 0.2 0.2 1"/></material>',
    "visual": '<visual><geometry><box size="0.2 0.2 0.1"/></geometry><material name="black"/></visual>'
    '<visual><geometry><box size="0.2 0.2 0.1"/></geometry><material name="carbon_fiber"/></visual>',
}


def test_materials_ros_tools_take_are_fixed_up_for_drake_with_one_note(arm_package, tmp_path):
    """As seen in a Kinova j2s6s200 description (carbon_fiber defined twice) and a UR5 + Robotiq one (black used,
    never defined): urdfdom and RViz load them, Drake refuses them; only visual colour is at stake."""
    robot = arm_package / "arm_colours.urdf"
    robot.write_text(
        ARM.replace('<robot name="arm">', f'<robot name="arm">\n  {MATERIALS["top"]}').replace(
            '<link name="base">', f'<link name="base">{MATERIALS["visual"]}'
        )
    )
    spec = CustomSpec(robot=str(robot), package_path=[f"my_arm={arm_package}"], start=[1.0], goal=[-1.0])
    with pytest.warns(Note) as given:
        scene = build_scene(spec, cache_dir=tmp_path, progress=False)
    assert scene.dim == 1
    assert [str(w.message) for w in given if w.category is Note] == [
        "arm_colours.urdf: material 'carbon_fiber' is defined twice (the first definition is used); material "
        "'black' is used but never defined (visual colour left default)"
    ]


def test_drakes_warnings_about_elements_a_planner_does_not_use_are_one_line(arm_package, tmp_path):
    """ROS descriptions carry transmissions, joint friction and Gazebo settings (an xArm7's drew 70 warnings)."""
    ros = """  <link name="link2"><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/>
    </inertial><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <joint name="j2" type="revolute"><parent link="link1"/><child link="link2"/><origin xyz="1 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/><dynamics friction="0.3"/></joint>
  <transmission name="t1"><type>transmission_interface/SimpleTransmission</type>
    <joint name="j1"><hardwareInterface>PositionJointInterface</hardwareInterface></joint>
    <actuator name="m1"><mechanicalReduction>100</mechanicalReduction></actuator></transmission>
  <transmission name="t2"><type>transmission_interface/SimpleTransmission</type>
    <joint name="j2"><hardwareInterface>PositionJointInterface</hardwareInterface></joint>
    <actuator name="m2"><mechanicalReduction>50</mechanicalReduction></actuator></transmission>
  <gazebo reference="link2"><material>Gazebo/Grey</material></gazebo>
</robot>"""
    robot = arm_package / "arm_ros.urdf"
    robot.write_text(
        ARM.replace('velocity="1"/></joint>', 'velocity="1"/><dynamics friction="0.3"/></joint>').replace(
            "</robot>", ros
        )
    )
    spec = CustomSpec(robot=str(robot), package_path=[f"my_arm={arm_package}"], start=[1.0, 0], goal=[-1.0, 0])
    with pytest.warns(Note) as given:
        build_scene(spec, cache_dir=tmp_path, progress=False)
        build_scene(spec, cache_dir=tmp_path, progress=False)  # (said once per process)
    assert [str(w.message) for w in given if w.category is Note] == [
        "arm_ros.urdf: Drake ignored 4 elements it does not use for planning (friction x2, mechanicalReduction x2)"
    ]


def test_a_scene_refusal_names_the_users_file_not_a_generated_one(tmp_path):
    """Whatever build_scene leaves to the Scene is said of the user's scene (its source), and paths into the cache
    are cut to file names."""
    from app.scene.custom import CustomScene
    from app.scene.drake_parser import user_words
    from app.scene.files import ROOT

    (tmp_path / "scene.dmd.yaml").write_text((ROOT / "scenes" / "bar-3link.dmd.yaml").read_text())
    generated = tmp_path / "problem-0123456789abcdef.yaml"
    problem = (ROOT / "scenes" / "bar-3link.yaml").read_text().replace("bar-3link.dmd.yaml", "scene.dmd.yaml")
    assert "weights: [1, 1, 12, 8, 4]" in problem
    generated.write_text(problem.replace("weights: [1, 1, 12, 8, 4]", "weights: [1, 1, -12, 8, 4]"))
    with pytest.raises(UserError) as info:
        CustomScene(generated, {}, "arm-in-bars", {}, "my_cell.yaml")
    assert str(info.value) == "bad scene my_cell.yaml: weights must be positive"
    assert user_words("cannot load file:///root/.cache/npp/models/0a1b/arm.urdf:12: error: x") == (
        "cannot load arm.urdf:12: error: x"
    )
    assert user_words("//tmp/cell/arm.sdf:5: error: x, 1/2 of /a/b") == "arm.sdf:5: error: x, 1/2 of b"


SDF_ARM = """<?xml version="1.0"?>
<sdf version="1.9"><model name="arm">
  <link name="a"><collision name="c"><geometry><box><size>0.1 0.1 0.1</size></box></geometry></collision></link>
  <link name="b"><pose>0.3 0 0 0 0 0</pose>
    <collision name="c"><geometry><box><size>0.1 0.1 0.1</size></box></geometry></collision></link>
  <joint name="j" type="prismatic"><parent>a</parent><child>b</child>
    <axis><xyz>1 0 0</xyz><limit><lower>{lower}</lower><upper>{upper}</upper></limit></axis></joint>
</model></sdf>
"""


@pytest.mark.parametrize(
    "lower, upper, message",
    [
        ("-1e300", "1e300", r"^arm.sdf: joint 'j': lower limit -1e\+300 is out of range"),
        ("1", "-1", r"^cannot load arm.sdf: arm.sdf:\d+: error: The lower limit must be lower"),
    ],
)
def test_an_sdf_robots_limits_are_refused_naming_the_joint(tmp_path, lower, upper, message):
    """An SDF is not read ahead as a URDF is: its limits are refused when Drake has read it, as one line."""
    (tmp_path / "arm.sdf").write_text(SDF_ARM.format(lower=lower, upper=upper))
    with pytest.raises(UserError, match=message):
        build_scene(CustomSpec(robot=str(tmp_path / "arm.sdf"), start=[0], goal=[0.5]), cache_dir=tmp_path)


def test_start_in_collision_is_an_invalid_endpoint(channel_oracle):
    from app.planning.query import plan
    from app.planning.settings import PlanSettings

    with pytest.raises(InvalidEndpoint):
        plan(channel_oracle, PlanSettings(narrow=5, uniform=5), start=[0.0, 1.25, 1.5, 0, 0, 0])


def test_cli_flags(files, arm_package, tmp_path, monkeypatch, cli, one_line_error):
    """`plan --robot ... --env ...`: exit codes and one-line errors."""
    monkeypatch.setenv("NPP_CACHE_DIR", str(tmp_path))
    common = [
        "plan",
        "--robot",
        str(files / "cube.obj"),
        "--env",
        str(files / "channel.stl"),
        "--bounds=" + ",".join(BOUNDS),
        "--goal",
        ",".join(map(str, GOAL)),
    ]
    assert "start" in one_line_error(cli(*common, "--start", "0,1.25,1.5,0,0,0"), 3)
    out = tmp_path / "traj.json"
    result = cli(
        *common,
        "--start=" + ",".join(map(str, START)),
        "--narrow",
        "60",
        "--uniform",
        "120",
        "--seed",
        "1",
        "--json",
        "--out",
        out,
    )
    assert result.returncode == 0, result.stderr
    assert out.is_file() and '"success":true' in result.stdout
    bad = [
        (["plan", "--robot", str(files / "nope.urdf"), "--start", "0", "--goal", "0"], 2, "robot file not found"),
        (
            ["plan", "--robot", str(arm_package / "arm.urdf"), "--start", "0", "--goal", "0"],
            2,
            "unknown package 'my_arm'",
        ),
        (common + ["--start=" + ",".join(map(str, START)), "--env-pose", "1,2"], 2, "env pose needs 6"),
        (common + ["--start=" + ",".join(map(str, START)), "--env-pose", "1,2,x"], 2, "argument --env-pose"),
        (common + ["--start=" + ",".join(map(str, START)), "--bounds", "0..x"], 2, "bad bounds item"),
        (["plan", "bar", "--robot", str(files / "cube.obj"), "--start", "0", "--goal", "0"], 2, "not both"),
        (["plan", "--env", str(files / "channel.stl")], 2, "--env needs --robot"),
        (["plan", "bar", "--acceleration-limits", "1"], 2, "--acceleration-limits needs --robot"),
        (common + ["--start=" + ",".join(map(str, START)), "--velocity-limits", "1,1,-1"], 2, "positive numbers"),
        (common + ["--start=" + ",".join(map(str, START)), "--acceleration-limits", "1,1"], 2, "needs 6 numbers"),
    ]
    for argv, code, words in bad:
        assert words in one_line_error(cli(*argv), code), argv


BLOCK_SDF = """<?xml version="1.0"?>
<sdf version="1.9"><model name="block">{static}<link name="block">
  <collision name="c"><geometry><box><size>0.5 0.5 0.5</size></box></geometry></collision>
</link></model></sdf>
"""
PUCK_URDF = """<?xml version="1.0"?>
<robot name="puck"><link name="puck">
  <inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>
  <collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision>
</link></robot>
"""


def test_floating_urdf_robot_among_sdf_obstacles(tmp_path, cache):
    from app.checking.oracle import CollisionOracle

    (tmp_path / "puck.urdf").write_text(PUCK_URDF)
    (tmp_path / "block.sdf").write_text(BLOCK_SDF.format(static=""))
    spec = CustomSpec(
        robot=str(tmp_path / "puck.urdf"),
        floating=True,
        env=[str(tmp_path / "block.sdf")],
        env_pose=[1, 0, 0, 0, 0, 45],
        start=[0, 0, 0, 0, 0, 0],
        goal=[2, 0, 0, 0, 0, 0],
        bounds=["-1..3,-1..1,-1..1"],
    )
    scene = build_scene(spec, cache_dir=cache, progress=False)
    assert scene.coordinate_names == ["x", "y", "z", "yaw", "pitch", "roll"]
    oracle = CollisionOracle(scene).context()
    assert oracle.is_free(scene.start) and not oracle.is_free(np.array([1.0, 0, 0, 0, 0, 0]))
    # the block is turned 45 degrees: its corner reaches 0.35 along y from its centre
    assert not oracle.is_free(np.array([1.0, 0.36, 0, 0, 0, 0])) and oracle.is_free(np.array([1.0, 0.5, 0, 0, 0, 0]))


def test_static_sdf_cannot_be_moved(tmp_path, cache):
    (tmp_path / "puck.urdf").write_text(PUCK_URDF)
    (tmp_path / "static.sdf").write_text(BLOCK_SDF.format(static="<static>true</static>"))
    spec = CustomSpec(
        robot=str(tmp_path / "puck.urdf"),
        floating=True,
        env=[str(tmp_path / "static.sdf")],
        env_pose=[1, 0, 0, 0, 0, 0],
        start=[0] * 6,
        goal=[0] * 6,
        bounds=["-1..3,-1..1,-1..1"],
    )
    with pytest.raises(UserError, match="static SDF model cannot be moved"):
        build_scene(spec, cache_dir=cache, progress=False)
    spec.env_pose = []
    assert build_scene(spec, cache_dir=cache, progress=False).dim == 6


def test_floating_arm_has_the_carrier_first(arm_package, cache):
    spec = CustomSpec(
        robot=str(arm_package / "arm.urdf"),
        package_path=[f"my_arm={arm_package}"],
        floating=True,
        start=[0, 0, 0, 0, 0, 0, 1],
        goal=[1, 1, 1, 0, 0, 0, -1],
        bounds=["-2..2,-2..2,-2..2"],
    )
    scene = build_scene(spec, cache_dir=cache, progress=False)
    assert scene.coordinate_names == ["x", "y", "z", "yaw", "pitch", "roll", "j1"]
    assert scene.lower.tolist()[:3] == [-2, -2, -2] and scene.lower[6] == -3 and scene.upper[6] == 3


CHANNEL_SDF = """<?xml version="1.0"?>
<sdf version="1.9"><model name="channel"><static>true</static><link name="channel">
  <visual name="v"><geometry><mesh><uri>meshes/channel.stl</uri></mesh></geometry></visual>
  <collision name="c"><geometry><mesh><uri>meshes/channel.stl</uri></mesh></geometry></collision>
</link></model></sdf>
"""


def test_sdf_environment_with_a_non_convex_mesh_is_decomposed(files, tmp_path, cache):
    """Drake would take the SDF's mesh as its convex hull and close the slot: its collision is split into pieces."""
    from app.checking.oracle import CollisionOracle

    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "channel.stl").write_bytes((files / "channel.stl").read_bytes())
    (tmp_path / "channel.sdf").write_text(CHANNEL_SDF)
    scene = build_scene(_spec(files, env=str(tmp_path / "channel.sdf")), cache_dir=cache, progress=False)
    assert scene.info["decompositions"][1]["mesh"] == "channel.stl"
    oracle = CollisionOracle(scene).context()
    assert oracle.is_free(np.array(IN_SLOT)) and not oracle.is_free(np.array([0.0, 1.25, 1.5, 0, 0, 0]))


def test_an_upright_flat_piece_is_drawn_as_a_line_from_above():
    import matplotlib.pyplot as plt

    from app.draw import _top_view

    fig, ax = plt.subplots()
    _top_view(ax, np.array([[0, 0, 0], [1, 1, 0], [2, 2, 1], [0, 0, 1.0]]), edgecolor="k", facecolor="b")
    assert len(ax.lines) == 1 and not ax.patches
    assert np.allclose(sorted(map(tuple, np.array(ax.lines[0].get_xydata()))), [(0, 0), (2, 2)])
    plt.close(fig)


def test_the_certificate_bounds_mesh_distances_closely(channel_oracle):
    """The certificate's own lower bounds for mesh pieces (posed in the world frame, far from their points) must be
    near Drake's distances, not only below them: a loose bound makes free motions unprovable."""
    from app.checking.certify import Certifier

    oracle = channel_oracle.context()
    certifier = Certifier(oracle)
    rng = np.random.default_rng(0)
    # Along the slot, turned a little: the walls' pieces on both sides are near, none touching.
    Q = [np.array([x, 0.0, 1.5, *rng.uniform(-0.2, 0.2, 3)]) for x in np.linspace(-2.5, 2.5, 11)]
    for q in Q:
        clearance = oracle.diagnostics.clearance(q, max_distance=2.0)
        # Asked only within a limit below the clearance, Drake reports no pair: the bounds alone must clear it.
        # (First: an answer is cached per configuration, and one asked within 2.0 would serve the smaller limit.)
        limit = 0.8 * clearance
        assert min(certifier.distances(q, limit).values(), default=limit) >= 0.5 * clearance
        assert min(certifier.distances(q, 2.0).values()) <= clearance + 1e-3


def test_a_cache_folder_with_uri_characters_in_its_name_works(files, tmp_path):
    """The generated model directives (YAML) and models (XML) name cached files by path: '&', ' #' (a YAML
    comment), '%' and spaces in the cache's path must reach Drake as they are."""
    scene = build_scene(_spec(files, mesh_method="faces"), cache_dir=tmp_path / "a&b #c%20d", progress=False)
    assert scene.dim == 6


def test_the_trap_example_is_bounded_and_its_cube_escapes(tmp_path, monkeypatch, capsys):
    """examples/trap: a 3,072-triangle closed, non-convex shell. Built from an empty cache it becomes hulls within
    the edge-check step's tolerance of it, and the cube leaves through the opening on a certified path."""
    from app.cli import main

    monkeypatch.setenv("NPP_CACHE_DIR", str(tmp_path / "cache"))
    scene = str(Path(__file__).parent.parent / "examples" / "trap" / "trap.yaml")
    # A check budget (not seconds), so the answer does not depend on the machine's load: ~2,300 checks are spent.
    assert main(["plan", scene, "--budget", "200kchecks", "--json"]) == 0
    answer = json.loads(capsys.readouterr().out)
    assert answer["success"] and answer["certified"]
    path = np.array(answer["path"])
    assert np.linalg.norm(path[:, :3], axis=1).max() > 1.3  # out of the shell: round it, not through the wall
    built = load_scene(scene, cache_dir=tmp_path / "cache").info["decompositions"]
    trap = next(d for d in built if d["mesh"] == "trap.obj")
    assert trap["method"] == "split" and trap["pieces"] < 400 and trap["from_cache"]


def test_ones_own_robot_and_environment_are_drawn_in_different_colours(channel_oracle, monkeypatch):
    """Neither a mesh robot nor an STL environment brings a colour: the viewer gives each its own."""
    from app.viewer import ENVIRONMENT_COLOUR, ROBOT_COLOUR, ViewData, show
    from meshcat_page import commands

    monkeypatch.setenv("DRAKE_ALLOW_NETWORK", "meshcat")
    html = show(channel_oracle.scene, ViewData()).html()
    colours = {}  # model instance -> colours of its illustration meshes, as 0xRRGGBB
    for c in commands(html):
        if c["type"] == "set_object" and c["path"].startswith("/drake/illustration/"):
            instance = c["path"].split("/")[3]
            colours.setdefault(instance, set()).update(m["color"] for m in c["object"].get("materials", []))
    hex_colour = lambda rgba: int.from_bytes(bytes(int(255 * x) for x in rgba[:3]), "big")  # noqa: E731 (as Drake)
    robot = set(channel_oracle.scene.problem.robot)
    assert {i for i in colours if i in robot} and {i for i in colours if i not in robot}
    for instance, seen in colours.items():
        assert seen == {hex_colour(ROBOT_COLOUR if instance in robot else ENVIRONMENT_COLOUR)}, instance
