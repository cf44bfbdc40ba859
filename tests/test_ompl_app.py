"""OMPL.app problem files (app.scene.ompl_app): a small problem written here in OMPL.app's own format (a .cfg and
Z_UP COLLADA meshes), whose collisions tell its conventions apart (the up-axis turn, the re-centring on the mean
vertex, axis-angle and yaw poses), a plan through it, and bad input. (OMPL.app's own resources are not committed:
its licence forbids redistribution; docs/own-robot.md reports them planned from a checkout.)"""

import json
import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("collada")

from app.errors import UserError  # noqa: E402
from app.scene import ompl_app  # noqa: E402

# The robot: a wedge, triangle (0,0) (3,0) (0,3) in the file's x-y, z from 0 to 1, placed by its node at (20, 5, 0).
# Its 6 corners each lie on 3 faces (18 distinct corner normals): mean vertex (21, 6, 0.5) in the file, not its
# box's centre (21.5, 6.5, 0.5) nor its origin. Z_UP turned to y up, (x, y, z) -> (x, z, -y): centre (21, 0.5, -6),
# and about it the wedge spans x [-1, 2], y [-0.5, 0.5], z [-2, 1].
_A, _B, _C = (0, 0, 0), (3, 0, 0), (0, 3, 0)
_A1, _B1, _C1 = (0, 0, 1), (3, 0, 1), (0, 3, 1)
WEDGE = [
    (_A, _C, _B),
    (_A1, _B1, _C1),
    (_A, _B, _B1),
    (_A, _B1, _A1),
    (_A, _A1, _C1),
    (_A, _C1, _C),
    (_B, _C, _C1),
    (_B, _C1, _B1),
]
WEDGE_NODE = (20.0, 5.0, 0.0)
CENTRE = [21.0, 0.5, -6.0]
# The wall: the file's plane y = 0 for |x|, |z| <= 4, which is OMPL.app's plane z = 0 (|x|, |y| <= 4).
WALL = [((-4, 0, -4), (4, 0, -4), (4, 0, 4)), ((-4, 0, -4), (4, 0, 4), (-4, 0, 4))]


def collada(triangles, up_axis="Z_UP", translation=(0.0, 0.0, 0.0)) -> str:
    """A COLLADA file as SketchUp writes them: one <triangles> without normals, under a node with a <matrix>."""
    points = [p for tri in triangles for p in tri]
    floats = " ".join(f"{c:g}" for p in points for c in p)
    x, y, z = translation
    return f"""<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><up_axis>{up_axis}</up_axis></asset>
  <library_geometries><geometry id="g"><mesh>
    <source id="g-pos"><float_array id="g-arr" count="{3 * len(points)}">{floats}</float_array>
      <technique_common><accessor source="#g-arr" count="{len(points)}" stride="3">
        <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
      </accessor></technique_common></source>
    <vertices id="g-vtx"><input semantic="POSITION" source="#g-pos"/></vertices>
    <triangles count="{len(triangles)}"><input semantic="VERTEX" source="#g-vtx" offset="0"/>
      <p>{" ".join(str(i) for i in range(len(points)))}</p></triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="s"><node id="n">
    <matrix>1 0 0 {x:g} 0 1 0 {y:g} 0 0 1 {z:g} 0 0 0 1</matrix>
    <instance_geometry url="#g"/>
  </node></visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#s"/></scene>
</COLLADA>
"""


def cfg(robot="robot.dae", world="world.dae", start=(0, 0, 2.25, 1, 0, 0, 0), goal=(0, 0, -1.25, 1, 0, 0, 0), **extra):
    """An SE(3) problem file; `extra` keys (dots as __) replace or add [problem] lines, None drops one."""
    keys = ["x", "y", "z", "axis.x", "axis.y", "axis.z", "theta"]
    lines = {"name": "wall", "robot": robot, "world": world}
    lines.update({f"start.{k}": v for k, v in zip(keys, start)})
    lines.update({f"goal.{k}": v for k, v in zip(keys, goal)})
    lines.update({"volume.min.x": -8, "volume.min.y": -3, "volume.min.z": -4})
    lines.update({"volume.max.x": 8, "volume.max.y": 3, "volume.max.z": 4})
    lines.update({k.replace("__", "."): v for k, v in extra.items()})
    body = "\n".join(f"{k} = {v}" for k, v in lines.items() if v is not None)
    return f"[problem]\n{body}\n\n[benchmark]\ntime_limit=10.0\n\n[planner]\nprm=\n"


@pytest.fixture(scope="module")
def problem_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("ompl_app")
    (d / "robot.dae").write_text(collada(WEDGE, translation=WEDGE_NODE))
    (d / "world.dae").write_text(collada(WALL))
    (d / "wall.cfg").write_text(cfg())
    return d


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("cache")


@pytest.fixture(scope="module")
def wall_oracle(problem_dir, cache):
    from app.checking.oracle import CollisionOracle

    return CollisionOracle(ompl_app.build_scene(problem_dir / "wall.cfg", cache_dir=cache, progress=False))


def test_robot_mesh_is_turned_to_y_up_and_centred_on_its_mean_vertex(problem_dir):
    robot = ompl_app.load_mesh(problem_dir / "robot.dae")
    assert robot.up_axis == "Z_UP" and robot.info["counted_vertices"] == 18
    np.testing.assert_allclose(robot.mean_vertex, CENTRE, atol=1e-9)
    np.testing.assert_allclose(robot.vertices.min(axis=0) - CENTRE, [-1, -0.5, -2], atol=1e-9)
    np.testing.assert_allclose(robot.vertices.max(axis=0) - CENTRE, [2, 0.5, 1], atol=1e-9)
    wall = ompl_app.load_mesh(problem_dir / "world.dae")
    np.testing.assert_allclose(wall.vertices.min(axis=0), [-4, -4, 0], atol=1e-9)
    np.testing.assert_allclose(wall.vertices.max(axis=0), [4, 4, 0], atol=1e-9)


def test_scene_poses_and_bounds(wall_oracle):
    scene = wall_oracle.scene
    assert scene.coordinate_names == ["x", "y", "z", "yaw", "pitch", "roll"]
    np.testing.assert_allclose(scene.start, [0, 0, 2.25, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(scene.goal, [0, 0, -1.25, 0, 0, 0], atol=1e-12)
    assert scene.lower[:3].tolist() == [-8, -3, -4] and scene.upper[:3].tolist() == [8, 3, 4]
    assert scene.continuous[3:].all() and not scene.self_collisions and scene.one_body
    assert scene.info["ompl_app"]["robot_centre"] == pytest.approx(CENTRE)


# The wedge about its centre spans z [p - 2, p + 1] at height p (identity): it meets the wall z = 0 for p in [-1, 2].
# Re-centred on its box's centre it would span [p - 1.5, p + 1.5]; not re-centred at all, z [p + 5, p + 8]; with the
# wall left in its file frame (the plane y = 0) every pose here would collide. Turned by pi about x: [p - 1, p + 2].
@pytest.mark.parametrize(
    "height, rotation, collides",
    [
        (1.75, (1, 0, 0, 0), True),
        (2.25, (1, 0, 0, 0), False),
        (-0.75, (1, 0, 0, 0), True),
        (-1.25, (1, 0, 0, 0), False),
        (1.75, (1, 0, 0, math.pi), False),
        (-1.25, (2, 0, 0, math.pi), True),  # OMPL normalises the axis
    ],
)
def test_collisions_follow_ompl_app_conventions(wall_oracle, problem_dir, height, rotation, collides):
    problem = ompl_app.read_problem(problem_dir / "wall.cfg")
    q = ompl_app.coordinates(problem, [0.0, 0.0, height, *rotation])
    assert wall_oracle.free(np.array(q)) is (not collides)


def test_axis_angle_matches_ompl():
    """The pose's rotation against OMPL's own SO3 setAxisAngle (the ompl wheel; it has no ompl.app to compare the
    whole problem with)."""
    ob = pytest.importorskip("ompl.base")
    from pydrake.math import RollPitchYaw

    problem = ompl_app.OmplAppProblem(Path("p.cfg"), "p", Path("r"), Path("w"), False, [], [], None)
    rng = np.random.default_rng(3)
    space = ob.SE3StateSpace()
    for _ in range(20):
        axis, theta = rng.normal(size=3), rng.uniform(-4, 4)
        state = space.allocState()
        state.rotation().setAxisAngle(*axis, theta)
        r = state.rotation()
        _, _, _, yaw, pitch, roll = ompl_app.coordinates(problem, [1, 2, 3, *axis, theta])
        q = RollPitchYaw(roll, pitch, yaw).ToQuaternion()
        ours, theirs = np.array([q.w(), q.x(), q.y(), q.z()]), np.array([r.w, r.x, r.y, r.z])
        assert min(np.abs(ours - theirs).max(), np.abs(ours + theirs).max()) < 1e-9


def test_plan_through_the_cli_is_certified(problem_dir, tmp_path, monkeypatch, cli):
    monkeypatch.setenv("NPP_CACHE_DIR", str(tmp_path))
    result = cli("plan", "--ompl-app", problem_dir / "wall.cfg", "--seed", "2", "--json")
    assert result.returncode == 0, result.stderr
    answer = json.loads(result.stdout)
    assert answer["success"] and answer["certified"] and answer["certified_collisions"] == "all"
    path = np.array(answer["path"])
    np.testing.assert_allclose(path[0], [0, 0, 2.25, 0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(path[-1], [0, 0, -1.25, 0, 0, 0], atol=1e-9)
    # Round the wall's edge: some waypoint has the wedge (x from -1 to 2 about its centre) clear of |x| <= 4.
    assert np.any((path[:, 0] > 4.5) | (path[:, 0] < -4.5))
    summary = cli("plan", "--ompl-app", problem_dir / "wall.cfg", "--seed", "2").stdout
    assert "SE(3); COLLADA up axis, turned to y up as assimp does: robot Z_UP, world Z_UP" in summary
    assert "re-centred on its mean vertex (21, 0.5, -6)" in summary


def test_planar_problem(tmp_path):
    """SE(2): x, y, yaw in the plane z = 0, the robot's centre kept at z = 0 (its z is not re-centred). A plate at
    OMPL x = 3, y in [-4, 4], z in [-10, -4] meets the wedge (z in [-8, -5] uncentred) at x = 1.5 unless it is
    turned by pi about z."""
    from app.checking.oracle import CollisionOracle

    (tmp_path / "robot.dae").write_text(collada(WEDGE, translation=WEDGE_NODE))
    plate = [((3, 4, -4), (3, 10, -4), (3, 10, 4)), ((3, 4, -4), (3, 10, 4), (3, 4, 4))]
    (tmp_path / "plate.dae").write_text(collada(plate))
    text = "\n".join(
        [
            "[problem]",
            "robot = robot.dae",
            "world = plate.dae",
            "start.x = 0.5",
            "start.y = 0",
            "start.theta = 0",
            "goal.x = 1.5",
            "goal.y = 0",
            "goal.theta = 3.141592653589793",
            "volume.min.x = -6",
            "volume.min.y = -6",
            "volume.max.x = 6",
            "volume.max.y = 6",
            "",
        ]
    )
    (tmp_path / "planar.cfg").write_text(text)
    scene = ompl_app.build_scene(tmp_path / "planar.cfg", cache_dir=tmp_path / "cache", progress=False)
    assert scene.coordinate_names == ["x", "y", "yaw"] and scene.continuous.tolist() == [False, False, True]
    assert scene.lower[:2].tolist() == [-6, -6] and scene.upper[:2].tolist() == [6, 6]
    assert scene.info["ompl_app"]["robot_centre"] == pytest.approx([21.0, 0.5, 0.0])
    oracle = CollisionOracle(scene)
    assert oracle.free(np.array([0.5, 0, 0])) and oracle.free(np.array([1.5, 0, math.pi]))
    assert not oracle.free(np.array([1.5, 0, 0]))


def test_bounds_hold_start_and_goal_and_default_to_the_environment(problem_dir, tmp_path):
    for name in ("robot.dae", "world.dae"):
        (tmp_path / name).write_text((problem_dir / name).read_text())
    (tmp_path / "out.cfg").write_text(cfg(start=(10, 0, 2.25, 1, 0, 0, 0)))
    problem = ompl_app.read_problem(tmp_path / "out.cfg")
    world = ompl_app.load_mesh(problem.world)
    lo, hi = ompl_app.position_bounds(problem, world)
    assert lo.tolist() == [-8, -3, -4] and hi.tolist() == [10, 3, 4]
    volume = {f"volume__{end}__{a}": None for end in ("min", "max") for a in "xyz"}
    (tmp_path / "none.cfg").write_text(cfg(**volume))
    lo, hi = ompl_app.position_bounds(ompl_app.read_problem(tmp_path / "none.cfg"), world)
    assert lo.tolist() == [-4, -4, -1.25] and hi.tolist() == [4, 4, 2.25]  # the wall's box, stretched to the ends


@pytest.mark.parametrize(
    "extra, words",
    [
        ({"start__theta": None}, "no start.theta"),
        ({"goal__axis__y": None}, "goal.axis.y too"),
        ({"control": "dynamic_car"}, "car"),
        ({"robot": "missing.dae"}, "robot mesh not found"),
        ({"world": "world.xyz"}, "unsupported format"),
        ({"start__x": "nan"}, "finite"),
        ({"volume__max__z": -5}, "volume.min must be below"),
        ({"volume__max__z": None}, "volume.max.z too"),
        ({"volume__min__x": "-1e308", "volume__max__x": "1e308"}, "volume.min.x = -1e308 is out of range"),
        ({"goal__theta": "1e300"}, "goal.theta = 1e300 is out of range"),
    ],
)
def test_bad_problem_files(problem_dir, tmp_path, cli, one_line_error, extra, words):
    for name in ("robot.dae", "world.dae"):
        (tmp_path / name).write_text((problem_dir / name).read_text())
    (tmp_path / "world.xyz").write_text("1 2 3\n")
    (tmp_path / "bad.cfg").write_text(cfg(**extra))
    with pytest.raises(UserError, match=words):
        ompl_app.read_problem(tmp_path / "bad.cfg")
    assert words in one_line_error(cli("plan", "--ompl-app", tmp_path / "bad.cfg"), 2)


def test_a_key_given_twice_in_the_problem_is_refused_and_planner_repeats_are_not(problem_dir, tmp_path, cli):
    """OMPL's option parser refuses a repeated key; configparser (non-strict, as [planner] needs: each `aps=` is
    another planner) would let the last one win without a word."""
    for name in ("robot.dae", "world.dae"):
        (tmp_path / name).write_text((problem_dir / name).read_text())
    text = cfg().replace("[planner]\nprm=\n", "[planner]\naps=\naps.name=APS1\naps=\naps.name=APS4\n")
    (tmp_path / "ok.cfg").write_text(text.replace("name = wall", "name = wall\n  continued on a second line"))
    assert ompl_app.read_problem(tmp_path / "ok.cfg").goal[2] == -1.25
    lines = text.splitlines()
    first = lines.index("goal.z = -1.25") + 1
    (tmp_path / "twice.cfg").write_text(text.replace("goal.z = -1.25", "goal.z = -1.25\n# again:\ngoal.z = 9"))
    with pytest.raises(UserError, match=rf"\[problem\] goal.z is given twice \(lines {first} and {first + 2}\)"):
        ompl_app.read_problem(tmp_path / "twice.cfg")
    # Across a second [problem] section (which configparser merges into the first) and in another case.
    (tmp_path / "sections.cfg").write_text(text + "\n[problem]\nGOAL.Z = 9\n")
    with pytest.raises(UserError, match=r"goal.z is given twice"):
        ompl_app.read_problem(tmp_path / "sections.cfg")
    answer = cli("plan", "--ompl-app", tmp_path / "twice.cfg", "--json")
    assert answer.returncode == 2 and len(answer.stdout.splitlines()) == 1
    assert answer.stderr.count("\n") == 1 and "twice.cfg" in answer.stderr and "Traceback" not in answer.stderr


def test_a_cached_conversion_is_compared_not_trusted(problem_dir, tmp_path):
    """The converted meshes are written to the cache by content key; a file found there under that name is used only
    if it holds exactly what this conversion makes (a file put there by someone else would be another shape)."""
    problem = ompl_app.read_problem(problem_dir / "wall.cfg")
    spec, _ = ompl_app.scene_spec(problem, cache_dir=tmp_path)
    robot, world = Path(spec.robot), Path(spec.env[0])
    made = robot.read_bytes()
    robot.write_bytes(world.read_bytes())  # the wall in place of the wedge
    again, _ = ompl_app.scene_spec(problem, cache_dir=tmp_path)
    assert Path(again.robot) == robot and robot.read_bytes() == made


def test_cli_refusals(problem_dir, tmp_path, monkeypatch, cli, one_line_error):
    monkeypatch.setenv("NPP_CACHE_DIR", str(tmp_path))
    cfg_file = problem_dir / "wall.cfg"
    assert "not found" in one_line_error(cli("plan", "--ompl-app", tmp_path / "none.cfg"), 2)
    assert "--robot" in one_line_error(cli("plan", "--ompl-app", cfg_file, "--robot", problem_dir / "robot.dae"), 2)
    assert "SCENE" in one_line_error(cli("plan", "bar", "--ompl-app", cfg_file), 2)
    # The start in collision (the wedge through the wall): exit 3, and with --json one object saying so.
    (tmp_path / "robot.dae").write_text((problem_dir / "robot.dae").read_text())
    (tmp_path / "world.dae").write_text((problem_dir / "world.dae").read_text())
    (tmp_path / "hit.cfg").write_text(cfg(start=(0, 0, 0.5, 1, 0, 0, 0)))
    assert "start" in one_line_error(cli("plan", "--ompl-app", tmp_path / "hit.cfg"), 3)
    result = cli("plan", "--ompl-app", tmp_path / "hit.cfg", "--json")
    answer = json.loads(result.stdout)
    assert result.returncode == 3 and answer["success"] is False
    assert answer["error"]["code"] == "START_STATE_IN_COLLISION"
