"""Narrow gaps of the workspace and the placements the planner draws there (app.samplers.workspace)."""

import numpy as np
import pytest

from app.checking.budget import Budget, BudgetSpent
from app.errors import NoPath
from app.planning.query import plan
from app.planning.settings import PlanSettings
from app.samplers.workspace import SEARCH_LIMIT, WorkspaceGaps


def test_a_gap_is_between_two_facing_obstacles_closer_than_the_width(oracles):
    oracle = oracles("joint3d")  # a wall at x 45..55 with a 10 x 10 hole at y, z 45..55
    points = {
        "in the hole": ([50, 50, 50], True),
        "in front of the hole": ([43, 50, 50], True),  # the hole's edges face each other across it
        "far in front of the wall": ([30, 30, 30], False),
        "just in front of the wall": ([44, 20, 50], False),  # one obstacle only
        "inside the wall": ([50, 20, 50], False),
    }
    found = oracle.workspace.environment_gaps(np.array([p for p, _ in points.values()], float), width=20.0)
    assert dict(zip(points, found.tolist())) == {name: gap for name, (_, gap) in points.items()}
    # The same hole is no gap for a width below its 10
    assert not oracle.workspace.environment_gaps(np.array([[50.0, 50, 50]]), width=9.0)[0]


def test_a_free_body_is_shifted_into_a_gap_and_an_arm_is_not(oracles):
    rng = np.random.default_rng(0)
    body = WorkspaceGaps(oracles("joint3d").context(), rng)
    assert body.axes.tolist() == [0, 1, 2] and np.allclose(body.directions, np.eye(3))
    arm = WorkspaceGaps(oracles("window").context(), rng)
    assert arm.axes.tolist() == []
    # The cart is welded to the world: its pieces never move and are never placed.
    centres = oracles("window").workspace.robot_geometry_centres(oracles("window").space.uniform(rng, 8))
    still = np.ptp(centres, axis=0).max(axis=1) < 1e-12
    assert still.any() and set(arm.moving) == set(np.flatnonzero(~still))


@pytest.mark.parametrize("scene", ["joint3d", "window"])
def test_every_placement_puts_a_moving_piece_at_a_gap_point(oracles, scene):
    oracle = oracles(scene).context()
    rng = np.random.default_rng(1)
    gaps = WorkspaceGaps(oracle, rng)
    while len(gaps.points) < 50:
        gaps.search(rng)
    Q = gaps.place(rng, 400)
    assert len(Q) and oracle.space.within_bounds(Q).all()
    centres = oracle.workspace.robot_geometry_centres(Q)[:, gaps.moving]  # (n, pieces, 3)
    distance = np.linalg.norm(centres[:, :, None, :] - gaps.points[None, None], axis=-1).min(axis=(1, 2))
    # exactly there when translations can shift it; within the tolerance for an arm
    assert distance.max() <= (1e-9 if len(gaps.axes) else gaps.tolerance)


def test_an_empty_workspace_has_no_gap_after_a_bounded_search(tmp_path):
    from app.checking.oracle import CollisionOracle
    from app.scene.custom import CustomSpec, build_scene

    spec = CustomSpec(robot="examples/trap/cube.obj", bounds=["-2..2", "-2..2", "-2..2"], start=[0] * 6)
    oracle = CollisionOracle(build_scene(spec, cache_dir=tmp_path, progress=False)).context()
    rng = np.random.default_rng(0)
    gaps = WorkspaceGaps(oracle, rng)
    while not gaps.exhausted:
        gaps.search(rng)
    assert len(gaps.points) == 0 and gaps.searched == SEARCH_LIMIT and oracle.checks == 0


def test_joint3d_needs_the_gap_placements_to_pass_the_hole_on_a_small_budget(oracles):
    oracle = oracles("joint3d")
    budget = Budget(checks=60_000)
    result = plan(oracle, PlanSettings(seed=0, budget=budget))
    assert result.workspace_on_path > 0 and result.trajectory.certified
    P = result.roadmap_path  # its edges go through the hole; its nodes may all lie at the hole's mouths
    assert oracle.workspace.in_passage(np.vstack([oracle.space.interpolate(a, b) for a, b in zip(P[:-1], P[1:])])).any()
    with pytest.raises(NoPath, match="budget of 60000 collision checks spent"):  # the sampler alone needs about 400k
        plan(oracle, PlanSettings(seed=0, budget=budget, workspace=0.0))


def test_the_papers_protocol_draws_no_placements(oracles):
    result = plan(oracles("bar-3link"), PlanSettings(seed=0, narrow=40, uniform=40, full_roadmap=True))
    assert result.stats.roadmap.workspace_nodes == 0 and result.stats.point_queries == 0


def test_gaps_out_of_the_robots_reach_hand_the_rounds_back_to_the_sampler(oracles, monkeypatch):
    from app.samplers.workspace import WorkspaceGaps as Gaps

    def unreachable(self, rng, n=0, stop=None):  # a gap no placement can bring a piece to (far outside the bounds)
        self.points, self.searched = np.array([[1e4, 1e4, 0.0]]), self.searched + 1
        return 1

    monkeypatch.setattr(Gaps, "search", unreachable)
    result = plan(oracles("bar"), PlanSettings(seed=0))
    assert result.stats.roadmap.workspace_nodes == 0 and result.stats.roadmap.narrow_nodes > 0
    assert result.trajectory.certified


def exhaustive_gaps(oracle, P, width, distances=None):
    """The gap test by its definition: every pair of environment pieces within `width` of the point, one by one.
    `distances(p)`: each environment piece's (signed distance, unit gradient) at p; Drake's by default."""
    query = oracle.query_object(oracle.scene.start)

    def drakes(p):
        found = query.ComputeSignedDistanceToPoint(p, width)
        return [(r.distance, r.grad_W) for r in found if not oracle.is_robot_geometry(r.id_G)]

    out = []
    for p in P:
        near = [(d, g) for d, g in (distances or drakes)(p) if d <= width]
        free = bool(near) and min(d for d, _ in near) > 0
        out.append(
            free
            and any(
                a[0] + b[0] < width and float(np.dot(a[1], b[1])) < -0.5
                for i, a in enumerate(near)
                for b in near[i + 1 :]
            )
        )
    return np.array(out)


@pytest.mark.parametrize("scene", ["joint3d", "maze", "window"])
def test_the_gap_search_finds_what_the_definition_finds(oracles, scene):
    oracle = oracles(scene)
    rng = np.random.default_rng(4)
    gaps = WorkspaceGaps(oracle.context(), rng)
    while len(gaps.points) < 20:
        gaps.search(rng)
    # Random points, and points about the gaps found (where the two-stage query and the pair test decide).
    around = np.repeat(gaps.points[:20], 10, axis=0) + rng.normal(0, gaps.width / 3, (200, 3))
    P = np.vstack([rng.uniform(gaps.lower, gaps.upper, (300, 3)), around])
    found = oracle.workspace.environment_gaps(P, gaps.width)
    assert np.array_equal(found, exhaustive_gaps(oracle, P, gaps.width))
    assert 0 < found.sum() < len(P)


def test_the_gap_search_on_a_decomposed_mesh_finds_what_the_definition_finds(tmp_path, monkeypatch):
    """An environment of convex hulls (a U channel bounded by hulls): the numpy distances to the hulls' triangles
    decide as exact distances to the hulls do (trimesh's), about the channel's inside and around its outside.
    (Drake 1.51's ComputeSignedDistanceToPoint is no reference here: it gives one of these hulls distance -1.04 at
    a point 1.04 outside it.)"""
    import trimesh
    from pydrake.geometry import Role

    from app.checking.oracle import CollisionOracle
    from app.scene.custom import CustomSpec, build_scene
    from mesh_shapes import u_channel

    monkeypatch.setenv("NPP_CACHE_DIR", str(tmp_path / "cache"))
    u_channel(4.0).apply_transform(trimesh_turn()).export(tmp_path / "u.obj")
    spec = CustomSpec(robot="examples/trap/cube.obj", env=[str(tmp_path / "u.obj")], bounds=["-3..3"] * 3)
    oracle = CollisionOracle(build_scene(spec, progress=False))
    inspector = oracle.model.scene_graph().model_inspector()
    pieces = [g for g in inspector.GetAllGeometryIds(Role.kProximity) if not oracle.is_robot_geometry(g)]
    assert len(pieces) > 1 and {type(inspector.GetShape(g)).__name__ for g in pieces} == {"Convex"}
    query = oracle.query_object(oracle.scene.start)
    hulls = []
    for g in pieces:
        polygons = inspector.GetShape(g).GetConvexHull()
        corners = np.array([polygons.vertex(i) for i in range(polygons.num_vertices())])
        hulls.append(trimesh.convex.convex_hull(corners).apply_transform(query.GetPoseInWorld(g).GetAsMatrix4()))

    def exact(p):
        found = []
        for hull in hulls:
            closest, distance, _ = trimesh.proximity.closest_point(hull, p[None])
            inside = hull.contains(p[None])[0]
            direction = (p - closest[0]) / max(distance[0], 1e-12)
            found.append((-distance[0], -direction) if inside else (distance[0], direction))
        return found

    rng = np.random.default_rng(2)
    P = rng.uniform(-3, 3, (600, 3))
    found = oracle.workspace.environment_gaps(P, 2.5)
    assert np.array_equal(found, exhaustive_gaps(oracle, P, 2.5, exact))
    assert 0 < found.sum() < len(P)


def trimesh_turn() -> np.ndarray:
    """A turn about an oblique axis, so no face of the channel lies along the world's axes."""
    import trimesh

    return trimesh.transformations.rotation_matrix(0.7, [1.0, 2.0, 3.0])


def test_a_turned_boxs_distances_are_exact_inside_and_out():
    """Polytopes against the closed form of a box's signed distance, in the box's own frame."""
    from scipy.spatial.transform import Rotation

    from app.checking.polytopes import Polytopes

    R, t, half = Rotation.from_rotvec([0.3, -0.8, 0.5]).as_matrix(), np.array([1.0, -2.0, 0.5]), np.array([1, 2, 3.0])
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    faces = [
        [corners[[i for i in range(8) if (i >> (2 - axis)) & 1 == side][j]] for j in (0, 1, 3, 2)]
        for axis in range(3)
        for side in (0, 1)
    ]
    box = Polytopes([[loop @ R.T + t for loop in faces]])
    P = t + np.random.default_rng(0).uniform(-6, 6, (2000, 3))
    points, distance, gradient = box.near(P, np.full(len(P), 20.0))
    assert points.tolist() == list(range(len(P)))
    local = (P - t) @ R  # the points in the box's frame
    outside = np.maximum(np.abs(local) - half, 0)
    expected = np.where(
        np.linalg.norm(outside, axis=1) > 0, np.linalg.norm(outside, axis=1), (np.abs(local) - half).max(axis=1)
    )
    assert np.allclose(distance, expected, atol=1e-12) and (expected < 0).sum() > 50
    out = expected > 0
    towards = np.sign(local) * outside / np.linalg.norm(outside, axis=1, keepdims=True).clip(1e-300)
    assert np.allclose(gradient[out], towards[out] @ R.T, atol=1e-9)
    # Beyond reach, nothing: a point 1 beyond a face is found within 1.5 and not within 0.5.
    near = t + R @ np.array([2.0, 0, 0])
    assert len(box.near(near[None], np.array([1.5]))[0]) == 1 and not len(box.near(near[None], np.array([0.5]))[0])


def test_a_gap_search_ends_when_the_budget_is_spent(oracles):
    checker = oracles("maze").context()
    P = np.random.default_rng(0).uniform(0, 20, (4096, 3))
    with pytest.raises(BudgetSpent):
        checker.environment_gaps(P, 1.0, stop=checker.stop(Budget(seconds=0.0)))
    assert checker.point_queries == 0  # polled before the first batch of points


def round_pieces_sdf(rng) -> str:
    """A static SDF model of spheres, capsules and cylinders (and a box) turned at random, a ring of them about the
    origin with gaps between neighbours."""
    collisions = []
    for k in range(12):
        angle = 2 * np.pi * k / 12
        x, y, z = 2.0 * np.cos(angle), 2.0 * np.sin(angle), rng.uniform(-0.5, 0.5)
        roll, pitch, yaw = rng.uniform(-np.pi, np.pi, 3)
        kind = ["sphere", "capsule", "cylinder", "box"][k % 4]
        size = rng.uniform(0.3, 0.6)
        geometry = {
            "sphere": f"<sphere><radius>{size}</radius></sphere>",
            "capsule": f"<capsule><radius>{size / 2}</radius><length>{3 * size}</length></capsule>",
            "cylinder": f"<cylinder><radius>{size}</radius><length>{2 * size}</length></cylinder>",
            "box": f"<box><size>{size} {2 * size} {size}</size></box>",
        }[kind]
        collisions.append(
            f'<collision name="{kind}{k}"><pose>{x} {y} {z} {roll} {pitch} {yaw}</pose>'
            f"<geometry>{geometry}</geometry></collision>"
        )
    return (
        '<?xml version="1.0"?><sdf version="1.9"><model name="ring"><static>true</static><link name="ring">'
        + "".join(collisions)
        + "</link></model></sdf>\n"
    )


def test_the_gap_search_among_round_shapes_finds_what_scenegraph_finds(tmp_path, monkeypatch):
    """Spheres, capsules and cylinders answered in closed form (app.checking.round_shapes): each point's pieces
    within reach, distances and gradients as SceneGraph's point queries give them, and so the same gaps."""
    from pydrake.geometry import Role

    from app.checking.oracle import CollisionOracle
    from app.scene.custom import CustomSpec, build_scene

    monkeypatch.setenv("NPP_CACHE_DIR", str(tmp_path / "cache"))
    rng = np.random.default_rng(5)
    (tmp_path / "ring.sdf").write_text(round_pieces_sdf(rng))
    spec = CustomSpec(robot="examples/trap/cube.obj", env=[str(tmp_path / "ring.sdf")], bounds=["-3..3"] * 3)
    oracle = CollisionOracle(build_scene(spec, progress=False))
    inspector = oracle.model.scene_graph().model_inspector()
    pieces = [g for g in inspector.GetAllGeometryIds(Role.kProximity) if not oracle.is_robot_geometry(g)]
    kinds = {type(inspector.GetShape(g)).__name__ for g in pieces}
    assert kinds == {"Sphere", "Capsule", "Cylinder", "Box"}
    P = np.vstack([rng.uniform(-3, 3, (400, 3)), rng.uniform(-2.5, 2.5, (400, 3)) * [1, 1, 0.3]])
    reach = rng.uniform(0.1, 1.5, len(P))
    points, distance, gradient = oracle.workspace._point_distances(P, reach)
    query = oracle.query_object(oracle.scene.start)
    expected = [
        (i, r.distance, *r.grad_W)
        for i, p in enumerate(P)
        for r in query.ComputeSignedDistanceToPoint(p, reach[i])
        if not oracle.is_robot_geometry(r.id_G)
    ]
    found = np.column_stack([points, distance, gradient])
    assert len(found) == len(expected) > 100 and np.all(np.diff(points) >= 0)
    # Each point's answers in the same order (by distance) on both sides.
    order, drake = np.lexsort((found[:, 1], found[:, 0])), np.array(expected)
    drake = drake[np.lexsort((drake[:, 1], drake[:, 0]))]
    assert np.array_equal(found[order, 0], drake[:, 0])
    assert np.allclose(found[order, 1], drake[:, 1], rtol=0, atol=1e-9)
    outside = drake[:, 1] > 0  # (the polytopes give no gradient inside)
    assert np.allclose(found[order][outside, 2:], drake[outside, 2:], rtol=0, atol=1e-6)
    gaps = oracle.workspace.environment_gaps(P, 1.0)
    assert np.array_equal(gaps, exhaustive_gaps(oracle, P, 1.0))
    assert 0 < gaps.sum() < len(P)
