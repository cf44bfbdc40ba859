"""Closed-form point distances to spheres, capsules and cylinders (app.checking.round_shapes) against SceneGraph's
point queries, which they replace in the workspace gap search."""

import numpy as np
import pytest

from app.checking.round_shapes import RoundShapes

REACH = 50.0


def drake_answers(pieces):
    """SceneGraph holding the pieces (rotation, origin, radius, half length, cylinder; a sphere where the half length
    is 0 and it is no cylinder) as anchored proximity geometries, asked one point at a time: `ask(P, reach)` gives
    each piece's (distance, gradient), NaN where it is beyond reach, (k, n) and (k, n, 3)."""
    from pydrake.geometry import Capsule, Cylinder, GeometryInstance, ProximityProperties, SceneGraph, Sphere
    from pydrake.math import RigidTransform, RotationMatrix

    graph = SceneGraph()
    source = graph.RegisterSource("pieces")
    row = {}
    for k, (R, t, radius, half, cylinder) in enumerate(pieces):
        shape = Cylinder(radius, 2 * half) if cylinder else Capsule(radius, 2 * half) if half else Sphere(radius)
        g = graph.RegisterAnchoredGeometry(
            source, GeometryInstance(RigidTransform(RotationMatrix(R), t), shape, f"{k}")
        )
        graph.AssignRole(source, g, ProximityProperties())
        row[g] = k
    context = graph.CreateDefaultContext()  # the query object reads it: kept alive by the closure

    def ask(P, reach):
        query = graph.get_query_output_port().Eval(context)
        distance, gradient = np.full((len(row), len(P)), np.nan), np.full((len(row), len(P), 3), np.nan)
        for i, p in enumerate(P):
            for answer in query.ComputeSignedDistanceToPoint(p, reach):
                distance[row[answer.id_G], i], gradient[row[answer.id_G], i] = answer.distance, answer.grad_W
        return distance, gradient

    return ask


def our_answers(piece, P, reach):
    """RoundShapes' answers for one piece, as drake_answers gives them for it."""
    points, d, g = RoundShapes([piece]).near(P, np.full(len(P), reach))
    assert np.all(np.diff(points) > 0)  # by point, one answer each
    distance, gradient = np.full(len(P), np.nan), np.full((len(P), 3), np.nan)
    distance[points], gradient[points] = d, g
    return distance, gradient


def random_pieces(rng, n):
    from scipy.spatial.transform import Rotation

    pieces = []
    for k in range(n):
        kind = k % 3  # sphere, capsule, cylinder
        R = Rotation.from_rotvec(rng.normal(size=3)).as_matrix()
        radius, half = rng.uniform(0.05, 2.0), rng.uniform(0.05, 2.0)
        pieces.append((R, rng.uniform(-3, 3, 3), radius, 0.0 if kind == 0 else half, kind == 2))
    return pieces


def telling_points(piece, rng):
    """Points, in the world, where the shapes' cases meet: the centre, the axis inside and beyond the ends, the
    barrel and the rims, on and just off the surface, and the middle plane; then random points about the piece."""
    R, t, radius, half, _ = piece
    eps = 1e-7
    local = [[0, 0, 0], [0, 0, half / 2], [0, 0, -half], [0, 0, half + radius / 2], [0, 0, -half - 2 * radius]]
    for s in (1 - eps, 1, 1 + eps):
        local += [[s * radius, 0, 0], [0, -s * radius, half / 3], [s * radius * 0.6, s * radius * 0.8, half]]
        local += [[0, 0, s * (half + radius)], [radius / 2, 0, -s * half], [s * radius, 0, s * half]]
        local += [[radius * 0.3, radius * 0.1, s * half * 1.5 + radius]]
    local = np.array(local, float)
    scale = radius + half
    spread = rng.normal(0, 1, (600, 3)) * scale * rng.choice([0.3, 1, 3], (600, 1))
    return np.vstack([local @ R.T + t, spread + t])


def test_distances_and_gradients_are_scenegraphs():
    """Random poses and sizes of each shape, and points inside, outside, on the axes and about the rims and caps:
    SceneGraph's pieces within reach, distances to 1e-9 and gradients (to 1e-6, where they are unique)."""
    rng = np.random.default_rng(0)
    pieces = random_pieces(rng, 24)
    ask = drake_answers(pieces)
    for k, piece in enumerate(pieces):
        P = telling_points(piece, rng)
        reach = piece[2] * 0.45  # beyond reach: left out, as SceneGraph leaves it out
        for threshold in (REACH, reach):
            expected, expected_gradient = ask(P, threshold)
            distance, gradient = our_answers(piece, P, threshold)
            found = ~np.isnan(expected[k])
            assert np.array_equal(~np.isnan(distance), found), (k, threshold)
            assert np.allclose(distance[found], expected[k][found], rtol=0, atol=1e-9)
            assert np.allclose(gradient[found], expected_gradient[k][found], rtol=0, atol=1e-6)
            assert np.allclose(np.linalg.norm(gradient[found], axis=1), 1)
        assert 0 < (expected[k] < 0).sum() < len(P) - 10  # inside and out


@pytest.mark.parametrize("kind", ["sphere", "capsule", "cylinder"])
def test_the_gradient_follows_drakes_documented_choice_where_it_is_not_unique(kind):
    """At a sphere's centre and on a capsule's segment the gradient is the piece's x axis, as Drake documents; a
    cylinder's is the barrel's normal in its x direction on its axis where the barrel is nearer than a cap, the top's
    at its centre where a cap is nearer (a flat cylinder), both sides' at a rim, normalised, and the barrel's when
    the barrel and a cap are equally near. The pose turns and shifts the piece by exact numbers, so that Drake and
    numpy see the same point in the piece's frame."""
    R = np.array([[0.0, -1, 0], [0, 0, -1], [1, 0, 0]])  # x -> world z, y -> world -x, z -> world -y
    t = np.array([0.5, -1.25, 2.0])
    radius, half = 1.0, {"sphere": 0.0, "capsule": 0.75, "cylinder": 0.25}[kind]
    piece = (R, t, radius, half, kind == "cylinder")
    if kind == "cylinder":
        local = {  # point in the piece's frame: gradient in the piece's frame
            (0.0, 0.0, 0.0): [0, 0, 1],  # the caps are 0.25 away, the barrel 1
            (0.0, 0.0, -0.125): [0, 0, -1],
            (1.0, 0.0, 0.25): [np.sqrt(0.5), 0, np.sqrt(0.5)],  # a rim
            (0.0, -1.0, -0.25): [0, -np.sqrt(0.5), -np.sqrt(0.5)],
            (0.875, 0.0, 0.125): [1, 0, 0],  # barrel and top equally near
        }
        thick = (R, t, radius, 2.0, True)  # on the axis of a long cylinder: the barrel, along x
        assert np.allclose(our_answers(thick, [t + R @ [0, 0, 0.5]], REACH)[1], [R[:, 0]])
    else:
        local = {(0.0, 0.0, z): [1, 0, 0] for z in {0.0, half / 2, -half}}
    P = np.array([t + R @ p for p in local])
    distance, gradient = our_answers(piece, P, REACH)
    expected, expected_gradient = drake_answers([piece])(P, REACH)
    assert np.allclose(gradient, np.array(list(local.values())) @ R.T, rtol=0, atol=1e-12)
    assert np.allclose(gradient, expected_gradient[0], rtol=0, atol=1e-12)
    assert np.allclose(distance, expected[0], rtol=0, atol=1e-12)
