"""Your own arm, planned safely: a six-joint URDF arm with non-convex mesh links, an SRDF and a mesh workcell (all
made here, none from robots/), self-collision on by default, a tool-pose goal; and the pieces behind it (SRDF
filters, mesh links decomposed, pose flags)."""

import json
import math
import re

import numpy as np
import pytest

pytest.importorskip("trimesh")

import trimesh  # noqa: E402

from app.checking.oracle import CollisionOracle  # noqa: E402
from app.scene.custom import CustomSpec, build_scene, load_scene  # noqa: E402
from app.scene.files import ROOT  # noqa: E402
from independent import fine_points, raw_free  # noqa: E402
from mesh_shapes import extrude_x  # noqa: E402

W = 0.06  # link thickness (m)
INERTIAL = '<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'


def _box(size: str, xyz: str) -> str:
    return f'<collision><origin xyz="{xyz}"/><geometry><box size="{size}"/></geometry></collision>'


def _mesh(rpy: str = "0 0 0") -> str:
    return f'<collision><origin rpy="{rpy}"/><geometry><mesh filename="meshes/l.obj"/></geometry></collision>'


# Upper arm and forearm are one L-shaped mesh (a 0.3 m bar with a 0.15 m leg at its far end): its convex hull fills
# the L's inner corner, so hulls collide where the links do not.
LINKS = {
    "base_link": _box("0.2 0.2 0.1", "0 0 0.05"),
    "shoulder": _box("0.1 0.1 0.1", "0 0 0.05"),
    "upper_arm": _mesh(f"0 {-math.pi / 2!r} 0"),  # the bar upright, the leg pointing back
    "forearm": _mesh(),
    "wrist1": _box("0.06 0.06 0.06", "0.03 0 0"),
    "wrist2": _box("0.06 0.06 0.06", "0.03 0 0"),
    "flange": _box("0.04 0.05 0.05", "0.02 0 0"),
}
JOINTS = [  # name, parent, child, origin, axis, limit (rad)
    ("j1", "base_link", "shoulder", "0 0 0.1", "0 0 1", 3.1),
    ("j2", "shoulder", "upper_arm", "0 0 0.1", "0 1 0", 2.0),
    ("j3", "upper_arm", "forearm", "0 0 0.3", "0 1 0", 2.8),
    ("j4", "forearm", "wrist1", "0.33 0 0", "1 0 0", 3.1),
    ("j5", "wrist1", "wrist2", "0.06 0 0", "0 1 0", 2.0),
    ("j6", "wrist2", "flange", "0.06 0 0", "1 0 0", 3.1),
]
ADJACENT = [(parent, child) for _, parent, child, *_ in JOINTS]
NEVER = [("base_link", "upper_arm"), ("wrist1", "flange")]  # never touched at 3000 random configurations
START = "-1.5,0,0,0,0,0"  # the arm turned to the post's side: it must go round or over the post
FOLDED = "0,0,2,0,0,0"  # the forearm folded down into the shoulder
GOAL_POSE = [0.45, 0.15, 0.3, 0, 90, 0]  # above the table, the flange's x axis pointing down


def _srdf(pairs) -> str:
    lines = ['<?xml version="1.0"?>', '<robot name="my_arm">']
    lines += [f'  <disable_collisions link1="{a}" link2="{b}" reason="Never"/>' for a, b in pairs]
    return "\n".join(lines + ["</robot>", ""])


def _urdf() -> str:
    out = ['<?xml version="1.0"?>', '<robot name="my_arm">']
    out += [f'  <link name="{name}">{INERTIAL}{xml}</link>' for name, xml in LINKS.items()]
    for name, parent, child, xyz, axis, limit in JOINTS:
        out.append(
            f'  <joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}"/><axis xyz="{axis}"/><limit lower="{-limit}" upper="{limit}" effort="1" '
            'velocity="1"/></joint>'
        )
    return "\n".join(out + ["</robot>", ""])


def _l_link(length=0.3, height=0.15) -> trimesh.Trimesh:
    """The L in the x-z plane, W thick: a bar along x from the origin, a leg up at its far end."""
    section = np.array([(0, 0), (length, 0), (length, height), (length - W, height), (length - W, W), (0, W)])
    mesh = extrude_x(section - [0, W / 2], W)  # the section lies in (y, z); swap x and y to lay the bar along x
    mesh.vertices = mesh.vertices[:, [1, 0, 2]]
    mesh.fix_normals()
    return mesh


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    """A folder with my_arm.urdf (+ meshes/l.obj), my_arm.srdf and workcell.obj: a table and a post, one mesh."""
    d = tmp_path_factory.mktemp("my_arm")
    (d / "meshes").mkdir()
    _l_link().export(d / "meshes" / "l.obj")
    (d / "my_arm.urdf").write_text(_urdf())
    (d / "my_arm.srdf").write_text(_srdf(ADJACENT + NEVER))
    T = trimesh.transformations.translation_matrix
    table = trimesh.creation.box([0.4, 0.8, 0.04], T([0.55, 0, 0.1]))
    post = trimesh.creation.box([0.05, 0.05, 0.5], T([0.35, -0.3, 0.35]))
    trimesh.util.concatenate([table, post]).export(d / "workcell.obj")
    return d


@pytest.fixture(autouse=True)
def _cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("NPP_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "npp-cache"))


def _oracle(arm, **keys) -> CollisionOracle:
    spec = dict(robot=str(arm / "my_arm.urdf"), env=[str(arm / "workcell.obj")], srdf=str(arm / "my_arm.srdf"))
    return CollisionOracle(build_scene(CustomSpec(**{**spec, **keys}), progress=False))


def _docs_command() -> list[str]:
    """The own-arm command of docs/own-robot.md, continuation lines joined."""
    page = re.sub(r"\\\n\s*", "", (ROOT / "docs" / "own-robot.md").read_text())
    line = next(line for line in page.splitlines() if line.startswith("python -m app plan --robot my_arm.urdf --srdf"))
    return line.split()[3:]  # after "python -m app"


def test_own_arm_is_planned_from_a_tool_pose_with_self_collision_on(arm, cli, monkeypatch):
    from app.planning.ik import robot_frame

    monkeypatch.chdir(arm)
    command = _docs_command()
    assert command[0] == "plan" and f"--start={START}" in command
    assert command[command.index("--goal-pose") + 1] == ",".join(f"{v:g}" for v in GOAL_POSE)
    result = cli(*command, "--json")
    assert result.returncode == 0, result.stderr
    answer = json.loads(result.stdout)
    assert answer["success"] and answer["self_collision"] is True

    # Independently: every state of the trajectory, and the path at a fine step, collides with nothing that counts.
    oracle = _oracle(arm)
    states = np.array(answer["trajectory"]["positions"])
    path = np.array(answer["path"])
    assert np.allclose(states[0], [float(v) for v in START.split(",")])
    assert all(raw_free(oracle, q) for q in states)
    assert all(raw_free(oracle, q) for q in fine_points(oracle, path, oracle.scene.resolution / 2))
    # The tool (no --tool: the last body of the chain) ends at the requested pose.
    from pydrake.math import RigidTransform, RollPitchYaw

    tool = robot_frame(oracle)
    assert tool.body().name() == "flange"
    context = oracle.plant.CreateDefaultContext()
    oracle.plant.SetPositions(context, states[-1])
    X = tool.CalcPoseInWorld(context)
    wanted = RigidTransform(RollPitchYaw(np.radians(GOAL_POSE[3:])), GOAL_POSE[:3])
    assert np.linalg.norm(X.translation() - wanted.translation()) < 2e-3
    assert wanted.rotation().inverse().multiply(X.rotation()).ToAngleAxis().angle() < math.radians(1)

    # A start folded into the arm is refused, naming the bodies.
    folded = [a.replace(START, FOLDED) for a in command]
    result = cli(*folded, "--json")
    assert result.returncode == 3
    error = json.loads(result.stdout)["error"]
    assert error["code"] == "START_STATE_IN_COLLISION" and "forearm" in error["message"]


def test_no_self_collision_accepts_the_folded_start_and_says_so(arm, cli, monkeypatch):
    monkeypatch.chdir(arm)
    command = [a.replace(START, FOLDED) for a in _docs_command()]
    result = cli(*command, "--no-self-collision")
    assert result.returncode == 0, result.stderr
    assert "self-collision off" in result.stdout


def test_srdf_pairs_are_left_out_of_every_answer(arm, tmp_path):
    """Disabling the folded pair (forearm, shoulder) frees the folded configuration for the raw query, the batched
    checker, the bodies and contacts it reports, and the certificate's pair list."""
    from app.checking.certify import certify_path

    folded = np.array([float(v) for v in FOLDED.split(",")])
    plain = _oracle(arm).context()
    assert not plain.is_free(folded)
    assert ("robot::forearm", "robot::shoulder") in plain.diagnostics.colliding_bodies(folded)
    (tmp_path / "fold.srdf").write_text(_srdf(ADJACENT + NEVER + [("shoulder", "forearm")]))
    oracle = _oracle(arm, srdf=str(tmp_path / "fold.srdf")).context()
    assert plain.diagnostics.colliding_bodies(folded) == [("robot::forearm", "robot::shoulder")]  # that pair alone
    assert oracle.is_free(folded) and oracle.oracle.checker.CheckConfigCollisionFree(folded)
    assert oracle.are_free(np.repeat(folded[None], 16, axis=0)).all()  # the batched path
    assert oracle.diagnostics.colliding_bodies(folded) == [] and not oracle.diagnostics.contacts(folded)["self"]
    near = folded.copy()
    near[2] -= 0.3
    certify_path(oracle, np.array([near, near + [0, 0, 0.01, 0, 0, 0]]))  # no pair the certificate does not count


def test_unknown_srdf_link_is_one_line(arm, tmp_path, cli, one_line_error, monkeypatch):
    (tmp_path / "typo.srdf").write_text(_srdf([("forearm", "elbw"), ("wrsit", "flange")]))
    monkeypatch.chdir(arm)
    result = cli("plan", "--robot", "my_arm.urdf", "--srdf", tmp_path / "typo.srdf", "--start", "0,0,0,0,0,0")
    line = one_line_error(result, 2)
    assert "elbw" in line and "wrsit" in line and "forearm" not in line
    assert "--srdf needs --robot" in one_line_error(cli("plan", "window", "--srdf", tmp_path / "typo.srdf"), 2)


def test_mesh_links_are_decomposed_and_the_hull_difference_measured(arm):
    """Without the SRDF: the upper arm's hull fills the L's corner and meets the base, which its pieces never do."""
    scene = _oracle(arm, srdf="").scene
    links = [d for d in scene.info["decompositions"] if d["mesh"] == "l.obj"]
    assert links and all(d["pieces"] >= 2 and d["validation"]["ok"] for d in links)
    measured = scene.info["mesh_links"]
    assert measured["pieces_self_collision"] < measured["hull_self_collision"]
    assert measured["hull_only"] == pytest.approx(measured["hull_self_collision"] - measured["pieces_self_collision"])
    assert measured["hull_only"] > 0


def test_scene_file_takes_srdf_and_collisions(arm):
    (arm / "cell.yaml").write_text(
        "robot: my_arm.urdf\nenv: [workcell.obj]\nsrdf: my_arm.srdf\ncollisions: environment\n"
        "start: [0, 0, 2, 0, 0, 0]\n"
    )
    scene = load_scene(str(arm / "cell.yaml"))
    assert not scene.self_collisions and len(scene.disabled_pairs) == len(ADJACENT + NEVER)
    assert np.allclose(scene.goal, 0)  # no goal: the home configuration
    assert CollisionOracle(scene).context().is_free(np.array([0, 0, 2.0, 0, 0, 0]))


@pytest.mark.parametrize(
    "flags, code, words",
    [
        (["--goal", "0,0,0,0,0,0", "--goal-pose", "0.4,0,0.3,0,90,0"], 2, "either --goal or --goal-pose"),
        (["--goal-pose", "0.4,0,0.3"], 2, "needs 6 numbers"),
        (["--goal-pose", "0.4,0,0.3,0,90,0", "--tool", "gripper"], 2, "unknown tool frame 'gripper'"),
        (["--goal-pose", "5,0,0.3,0,90,0"], 3, "pose '5,0,0.3,0,90,0' cannot be reached"),
    ],
)
def test_pose_flags(arm, cli, one_line_error, monkeypatch, flags, code, words):
    monkeypatch.chdir(arm)
    result = cli("plan", "--robot", "my_arm.urdf", "--env", "workcell.obj", "--start", "0,0,0,0,0,0", *flags, "--json")
    assert words in one_line_error(result, code)
    if code == 3:
        assert json.loads(result.stdout)["error"]["code"] == "NO_IK_SOLUTION"
