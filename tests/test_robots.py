"""The quadrotor and the UR3-on-cart models, and the maze, tunnel, welding and window scenes built on them."""

import importlib.util
import math
import re
from collections import Counter

import numpy as np
import pytest

from app.errors import UserError
from app.scene.files import ROOT, SCENES_DIR
from app.scene.model import Scene

UAV_SCENES = ["maze", "tunnel"]
ARM_SCENES = ["welding", "window"]
UAV_AND_ARM_SCENES = UAV_SCENES + ARM_SCENES

# Standard UR3 DH parameters (Universal Robots' published table).
DH_D = [0.1519, 0.0, 0.0, 0.11235, 0.08535, 0.0819]
DH_A = [0.0, -0.24365, -0.21325, 0.0, 0.0, 0.0]
DH_ALPHA = [math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0]


def dh_forward(q) -> np.ndarray:
    """Base -> flange as the product of standard DH links Rz(q) Tz(d) Tx(a) Rx(alpha)."""
    T = np.eye(4)
    for qi, d, a, alpha in zip(q, DH_D, DH_A, DH_ALPHA):
        c, s, ca, sa = math.cos(qi), math.sin(qi), math.cos(alpha), math.sin(alpha)
        T = T @ np.array([[c, -s * ca, s * sa, a * c], [s, c * ca, -c * sa, a * s], [0, sa, ca, d], [0, 0, 0, 1]])
    return T


def test_ur3_forward_kinematics_matches_the_dh_table(oracles):
    oracle = oracles("welding")
    plant = oracle.plant
    context = plant.CreateDefaultContext()
    base, tool0 = plant.GetFrameByName("base_link"), plant.GetFrameByName("tool0")
    rng = np.random.default_rng(3)
    for q in rng.uniform(-2 * math.pi, 2 * math.pi, size=(200, 6)):
        plant.SetPositions(context, q)
        X = plant.CalcRelativeTransform(context, base, tool0).GetAsMatrix4()
        assert np.allclose(X, dh_forward(q), atol=1e-12)
    # The TCP is 0.18 m out along the flange's z axis.
    tcp = plant.GetFrameByName("tcp")
    X = plant.CalcRelativeTransform(context, tool0, tcp)
    assert np.allclose(X.translation(), [0, 0, 0.18]) and np.allclose(X.rotation().matrix(), np.eye(3))


def test_ur3_limits_are_the_real_ones(oracles):
    scene = oracles("welding").scene
    plant = scene.plant
    assert scene.dim == 6
    assert scene.coordinate_names == [
        "shoulder_pan_joint",
        "shoulder_lift_joint",
        "elbow_joint",
        "wrist_1_joint",
        "wrist_2_joint",
        "wrist_3_joint",
    ]
    assert np.allclose(plant.GetVelocityUpperLimits(), [math.pi] * 3 + [2 * math.pi] * 3)  # 180 and 360 deg/s
    assert np.allclose(plant.GetPositionUpperLimits()[:5], 2 * math.pi)
    assert np.allclose(plant.GetPositionLowerLimits()[:5], -2 * math.pi)
    assert scene.continuous.tolist() == [False] * 5 + [True]  # the last joint turns without end
    assert np.allclose(scene.lower, -math.pi) and np.allclose(scene.upper, math.pi)  # planning bounds


def _pair_counts(oracle, Q) -> Counter:
    """How often each robot-robot geometry pair penetrates over the configurations Q (unfiltered context)."""
    plant = oracle.plant
    context = plant.GetMyContextFromRoot(oracle.model.CreateDefaultContext())
    inspector = oracle.model.scene_graph().model_inspector()
    counts = Counter()
    for q in Q:
        plant.SetPositions(context, q)
        pairs = plant.get_geometry_query_input_port().Eval(context).ComputePointPairPenetration()
        counts.update(
            {
                tuple(sorted((inspector.GetName(p.id_A), inspector.GetName(p.id_B))))
                for p in pairs
                if oracle.is_robot_geometry(p.id_A) and oracle.is_robot_geometry(p.id_B)
            }
        )
    return counts


def test_ur3_self_collision_geometry_is_sane(oracles):
    """No pair of non-adjacent links overlaps for (nearly) all joint values, and the home pose touches nothing."""
    oracle = oracles("window")
    assert not _pair_counts(oracle, [oracle.scene.start])
    assert oracle.diagnostics.clearance(oracle.scene.start, 0.2) > 0.01
    Q = oracle.space.uniform(np.random.default_rng(5), 1500)
    counts = _pair_counts(oracle, Q)
    worst = max(counts.values()) / len(Q)
    assert worst < 0.6, counts.most_common(3)
    # the arm does hit itself and its cart somewhere, so self-collision is on and matters
    assert any("cart" in a or "cart" in b for a, b in counts)
    assert any("cart" not in a and "cart" not in b for a, b in counts)


def test_ur3_srdf_pairs_never_touch(oracles, tmp_path):
    """The UR3 scenes load robots/ur3_on_cart.srdf; its pairs, checked here on the same scene without it at fresh
    random configurations, never come within a few millimetres (the generator kept 1 cm)."""
    from app.checking.oracle import CollisionOracle

    disabled = {frozenset(pair) for pair in oracles("window").scene.disabled_pairs}
    assert disabled and oracles("welding").scene.disabled_pairs == oracles("window").scene.disabled_pairs
    (tmp_path / "window.dmd.yaml").write_text((SCENES_DIR / "window.dmd.yaml").read_text())
    (tmp_path / "window.yaml").write_text(re.sub(r"srdf: .*\n", "", WINDOW))
    oracle = CollisionOracle(Scene(str(tmp_path / "window.yaml")))
    assert not oracle.scene.disabled_pairs
    plant, inspector = oracle.plant, oracle.model.scene_graph().model_inspector()
    context = plant.GetMyContextFromRoot(oracle.model.CreateDefaultContext())
    close = set()
    for q in oracle.space.uniform(np.random.default_rng(11), 2000):
        plant.SetPositions(context, q)
        for p in plant.get_geometry_query_input_port().Eval(context).ComputeSignedDistancePairwiseClosestPoints(0.003):
            bodies = frozenset(plant.GetBodyFromFrameId(inspector.GetFrameId(g)).name() for g in (p.id_A, p.id_B))
            close.add(bodies)
    assert close and not close & disabled


def test_quadrotor_model_and_safety_hull(oracles):
    from pydrake.geometry import Cylinder, Role

    scene = oracles("maze").scene
    plant = scene.plant
    assert scene.dim == 4 and scene.coordinate_names == ["x", "y", "z", "yaw"]
    assert scene.continuous.tolist() == [False, False, False, True]
    assert np.allclose(plant.GetVelocityUpperLimits(), [2, 2, 2, 1.5])
    assert np.allclose(scene.acceleration_limits, [2.5, 2.5, 2.5, 3.0])
    inspector = oracles("maze").model.scene_graph().model_inspector()
    body = plant.GetBodyByName("body")
    hull = [g for g in plant.GetCollisionGeometriesForBody(body)]
    assert len(hull) == 1
    shape = inspector.GetShape(hull[0])
    assert isinstance(shape, Cylinder)
    # Every visual part lies inside the hull with at least 0.1 m to spare, sideways and vertically.
    frame_id = plant.GetBodyFrameIdOrThrow(body.index())
    visuals = inspector.GetGeometries(frame_id, Role.kIllustration)
    assert len(visuals) >= 9
    reach, top = 0.0, 0.0
    for g in visuals:
        part, X = inspector.GetShape(g), inspector.GetPoseInFrame(g)
        if isinstance(part, Cylinder):  # the motors and rotor discs stand upright
            assert np.allclose(X.rotation().matrix()[:, 2], [0, 0, 1])
            reach = max(reach, np.linalg.norm(X.translation()[:2]) + part.radius())
            top = max(top, abs(X.translation()[2]) + part.length() / 2)
            continue
        half = np.array([part.width(), part.depth(), part.height()]) / 2
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
        points = corners @ X.rotation().matrix().T + X.translation()
        reach = max(reach, np.linalg.norm(points[:, :2], axis=1).max())
        top = max(top, np.abs(points[:, 2]).max())
    assert 0.24 < reach <= 0.25  # the 0.5 m span
    assert shape.radius() - reach >= 0.1 - 1e-9 and shape.length() / 2 - top >= 0.1 - 1e-9  # the margin


@pytest.mark.parametrize("name, side, up", [("maze", 0.1, 0.25), ("tunnel", 0.12, 0.28)])
def test_uav_passage_is_narrow_but_open(oracles, name, side, up):
    oracle = oracles(name).context()
    Q = oracle.space.uniform(np.random.default_rng(11), 6000)
    free = Q[oracle.are_free(Q)]
    assert len(free) > 3000
    assert oracle.workspace.in_passage(free).mean() < 0.02
    # The passage is open: the vehicle fits through its middle at any yaw (the hull is round) ...
    lo, hi = oracle.scene.passage_boxes[0]
    middle = (lo + hi) / 2
    for yaw in np.linspace(-3, 3, 7):
        assert oracle.is_free(np.r_[middle, yaw])
    # ... but only just: a little sideways, up or down and it touches.
    for offset in ([0, side, 0], [0, -side, 0], [0, 0, up], [0, 0, -up]):
        assert not oracle.is_free(np.r_[middle + offset, 0.0])


def test_maze_window_is_the_only_way_across(oracles):
    """Walls are full height: at the dividing wall's x, only the window is free."""
    oracle = oracles("maze").context()
    ys, zs = np.linspace(0.35, 19.65, 200), np.linspace(0.2, 2.8, 14)
    Q = np.array([[10.0, y, z, 0.0] for y in ys for z in zs])
    free = Q[oracle.are_free(Q)]
    assert len(free) > 0
    assert np.all(np.abs(free[:, 1] - 15.0) < 0.1) and np.all(np.abs(free[:, 2] - 1.5) < 0.25)


@pytest.mark.parametrize("name, count", [("welding", 5), ("window", 3)])
def test_arm_scenes_carry_tool_poses(oracles, name, count):
    scene = oracles(name).scene
    assert scene.tool_frame is not None and scene.tool_frame.name() == "tcp"
    assert len(scene.poses) == count
    assert scene.summary()["tool_frame"] == "tcp"


def test_other_scenes_have_no_poses(oracles):
    scene = oracles("bar").scene
    assert scene.tool_frame is None and scene.poses == {}


def test_welding_seam_pose_is_read_as_position_and_rpy_degrees(oracles):
    X = oracles("welding").scene.poses["seam_2"]
    assert np.allclose(X.translation(), [-0.16, -0.08, 0.52])
    # rpy (-153, -59, 90) deg: the torch axis (z) points down into the corner of web and pan, along the seam
    assert np.allclose(X.rotation().matrix()[:, 2], [-0.454, 0.764, -0.459], atol=1e-3)


def _world_box(oracle, query, geometry) -> tuple[np.ndarray, np.ndarray]:
    """Corners of a box or cylinder geometry's bounding box in the world (exact for the axis-aligned boxes here,
    and never smaller than the shape)."""
    from pydrake.geometry import Box, Cylinder

    shape = oracle.model.scene_graph().model_inspector().GetShape(geometry)
    if isinstance(shape, Box):
        half = np.array([shape.width(), shape.depth(), shape.height()]) / 2
    else:
        assert isinstance(shape, Cylinder), shape
        half = np.array([shape.radius(), shape.radius(), shape.length() / 2])
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    world = query.GetPoseInWorld(geometry).multiply(corners.T).T
    return world.min(axis=0), world.max(axis=0)


@pytest.mark.parametrize("name", ARM_SCENES)
def test_the_cart_stands_clear_of_every_obstacle(oracles, name):
    """Drake never checks bodies welded to the world against each other, so the planner cannot notice a cart (or the
    arm's base on it) placed inside a chassis or a wall: every such geometry is at least 2 cm from every obstacle,
    measured here on the shapes' own bounding boxes."""
    from pydrake.geometry import Role

    oracle = oracles(name)
    plant, inspector = oracle.plant, oracle.model.scene_graph().model_inspector()
    query = oracle.query_object(oracle.scene.start)
    welded = {body.index() for body in plant.GetBodiesWeldedTo(plant.world_body())}
    fixed, obstacles = [], []
    for geometry in inspector.GetAllGeometryIds(Role.kProximity):
        body = plant.GetBodyFromFrameId(inspector.GetFrameId(geometry))
        if oracle.is_robot_geometry(geometry):
            if body.index() in welded:
                fixed.append((body.name(), _world_box(oracle, query, geometry)))
        else:
            obstacles.append((inspector.GetName(geometry), _world_box(oracle, query, geometry)))
    assert {"cart", "base_link"} <= {body for body, _ in fixed} and len(obstacles) > 5
    for body, (lo, hi) in fixed:
        for obstacle, (olo, ohi) in obstacles:
            gap = np.linalg.norm(np.maximum(0.0, np.maximum(olo - hi, lo - ohi)))
            assert gap >= 0.02, (body, obstacle, gap)


WINDOW = (SCENES_DIR / "window.yaml").read_text()


@pytest.mark.parametrize(
    "text, expected",
    [
        (WINDOW.replace("tool_frame: tcp", "tool_frame: nose"), "tool frame 'nose'"),
        (WINDOW.replace("tool_frame: tcp\n", ""), "'poses' need a 'tool_frame'"),
        (WINDOW.replace("{name: place,", "{name: reach,"), "unique name"),
        (WINDOW.replace("xyz: [0.10, 0.40, 0.45]", "xyz: [0.10, 0.40]"), "pose 'place' needs xyz"),
        (re.sub(r"rpy_deg: \[180, 0, 0\]", "rpy: [3.14, 0, 0]", WINDOW), "rpy"),  # unknown key
    ],
)
def test_bad_pose_entries_are_rejected(tmp_path, text, expected):
    (tmp_path / "window.dmd.yaml").write_text((SCENES_DIR / "window.dmd.yaml").read_text())
    path = tmp_path / "custom.yaml"
    path.write_text(text)
    with pytest.raises(UserError, match=expected):
        Scene(str(path))


def test_obstacle_files_match_their_generator():
    spec = importlib.util.spec_from_file_location("make_box_obstacles", SCENES_DIR / "make_box_obstacles.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for filename, (model, comment, boxes) in module.FILES.items():
        assert (SCENES_DIR / filename).read_text() == module.sdf(model, comment, boxes()), filename


def test_models_are_primitive_shapes_only():
    for name in ("quadrotor.urdf", "ur3_on_cart.urdf"):
        text = (ROOT / "robots" / name).read_text()
        assert "<mesh" not in text and "package://" not in text


@pytest.mark.parametrize("name", UAV_AND_ARM_SCENES)
def test_batched_and_single_checks_agree_on_the_uav_and_arm_scenes(oracles, name):
    """The cart is welded to the world yet part of the robot: the checker's batch path and the raw SceneGraph path
    must still see the same pairs (cart-arm counts, cart-floor obstacles never move relative to each other)."""
    oracle = oracles(name).context()
    Q = oracle.space.uniform(np.random.default_rng(7), 600)
    batch = oracle.are_free(Q)
    single = np.array([oracle.is_free(q) for q in Q])
    assert np.array_equal(batch, single)
    assert 0.05 < batch.mean() < 0.98
