"""Lower bounds on the distance of two shapes, for the certificate (app.checking.certify), from the shapes' support
functions; and each shape's description, centre and radius, which the motion bound (app.checking.motion_bound) takes
too.

Distances. Drake computes box-box and sphere pairs in closed form, but pairs with a cylinder, capsule, ellipsoid or
mesh by GJK, whose answers can be too large -- unsafe here (seen near a maze pillar's corner, and by centimetres for
two nearly coaxial cylinders of the UR3's wrist and torch: benchmark pages). So for every counted pair
of that kind, reported by Drake or not, the certificate uses a lower bound of its own: the largest gap between the
two shapes along three directions -- Drake's separating direction, and the normals of each shape at the near points
that a few alternating projections onto the two shapes find -- from the shapes' support functions (the gap along
any direction bounds the distance from below). On the maze's corner it matched the true distance to 1e-15. A mesh
(its convex hull) counts as its hull's box -- which holds it, so the box's distance and support are a lower and an
upper bound of the hull's -- except where a bound must be tight, which takes the hull's vertices.
Bounds are tiered (bounding spheres, a centre to the other shape, gaps with boxes, gaps with vertices): a pair
stops at the first that puts it beyond the limit D (the query's max_distance, see app.checking.certify) or, on mesh
scenes, as far apart as the pieces at that end need (its largest B_PQ over them, app.checking.motion_bound: with any
positive distance at the other end the pair then passes), so most pairs cost a sphere test.
"""

from __future__ import annotations

import itertools
import weakref
from typing import NamedTuple

import numpy as np

from app.scene.shapes import hull_vertices

# A pair's key: its smaller geometry index * PAIR_KEY + its larger one.
PAIR_KEY = 1 << 31


def describe_shape(inspector, geometry) -> tuple[str, object]:
    """A shape as (kind, data), for its radius and its support function."""
    from pydrake.geometry import Box, Capsule, Convex, Cylinder, Ellipsoid, Mesh, Sphere

    shape = inspector.GetShape(geometry)
    if isinstance(shape, Box):
        return "box", np.array([shape.width(), shape.depth(), shape.height()]) / 2
    if isinstance(shape, Sphere):
        return "sphere", shape.radius()
    if isinstance(shape, (Cylinder, Capsule)):
        return type(shape).__name__.lower(), (shape.radius(), shape.length() / 2)
    if isinstance(shape, Ellipsoid):
        return "ellipsoid", np.array([shape.a(), shape.b(), shape.c()])
    if isinstance(shape, (Mesh, Convex)):  # Drake's proximity engine uses a mesh's convex hull
        return "vertices", hull_vertices(shape)
    raise ValueError(f"geometry '{inspector.GetName(geometry)}': no certificate for a {type(shape).__name__}")


def centred_shape(kind: str, data) -> tuple[str, object, np.ndarray, float]:
    """(kind, data, centre, radius) of a shape described about its centre, in its own frame: a mesh's vertices
    about the middle of their box (an obstacle piece is posed in the world frame, so about its frame's origin its
    bounding sphere would hold the world), other shapes about their frame's origin; radius: its farthest point."""
    from pydrake.math import RigidTransform

    centre = np.zeros(3)
    if kind == "vertices":
        centre = 0.5 * (data.min(axis=0) + data.max(axis=0))
        data = data - centre
    return kind, data, centre, shape_radius(kind, data, RigidTransform())


def shape_radius(kind: str, data, pose) -> float:
    """Largest distance from the origin of the frame the shape is posed in (pose X_FG) to a point of the shape."""
    if kind in ("box", "vertices"):
        corners = data if kind == "vertices" else np.array(list(itertools.product(*[[-h, h] for h in data])))
        return float(np.linalg.norm(pose.multiply(corners.T), axis=0).max())
    extent = {
        "sphere": lambda: data,
        "cylinder": lambda: np.hypot(*data),
        "capsule": lambda: sum(data),
        "ellipsoid": lambda: data.max(),
    }[kind]()
    return float(np.linalg.norm(pose.translation()) + extent)


class ShapeGaps:
    """Lower bounds on the distance of the counted pairs whose distance Drake computes by GJK (see the module doc).

    Shapes as a box core (half sizes), a disc (radius, in the x-y plane) and a ball (radius) summed: a box is a
    core, a sphere a ball, a capsule a z segment and a ball, a cylinder a z segment and a disc -- one formula for the
    nearest point and for the support function of all four. A mesh (Drake uses its convex hull) is its hull's box in
    its own frame for nearest points and first bounds (the box holds the hull, so the distance to the box and its
    support are a lower and an upper bound of the hull's), and its hull's vertices where a bound must be tight.
    Ellipsoids are handled apart ("special").

    Tiers. Most rows need no tight bound: a row is settled by the first bound that reaches its `need` (how far
    apart the pair must be at this end for the pieces being certified, see Certifier._distances in
    app.checking.certify) or its `limit` (beyond which the pair is left out): bounding spheres, then each centre to
    the other shape, then the gaps along three directions with boxes for hulls, and only then the gaps of hull pairs
    with the hulls' vertices. Each is a lower bound of the distance, so a row keeps the largest it found."""

    def __init__(self, oracle, geometries: list, robot: np.ndarray, exact: np.ndarray):
        inspector = oracle.model.scene_graph().model_inspector()
        self.pairs = np.array(
            [
                (i, j)
                for i, j in itertools.combinations(range(len(geometries)), 2)
                if (robot[i] or robot[j])
                and not exact[i, j]
                and (oracle.scene.self_collisions or not (robot[i] and robot[j]))
                and not inspector.CollisionFiltered(geometries[i], geometries[j])
            ],
            int,
        ).reshape(-1, 2)
        self.keys = self.pairs[:, 0] * PAIR_KEY + self.pairs[:, 1]
        count = len(geometries)
        self.core, self.disc, self.ball = np.zeros((count, 3)), np.zeros(count), np.zeros(count)
        self.radius = np.zeros(count)  # about the shape's centre
        # A shape's centre in its own frame (see centred_shape), about which a mesh's vertices are kept.
        self.offset = np.zeros((count, 3))
        semi = np.zeros((count, 3))  # an ellipsoid's semi-axes
        hulls = {}  # geometry index -> a mesh hull's vertices (n, 3) about its centre
        for i in np.unique(self.pairs):
            kind, data, self.offset[i], self.radius[i] = centred_shape(*describe_shape(inspector, geometries[i]))
            if kind == "box":
                self.core[i] = data
            elif kind == "sphere":
                self.ball[i] = data
            elif kind in ("cylinder", "capsule"):
                self.core[i, 2] = data[1]
                (self.disc if kind == "cylinder" else self.ball)[i] = data[0]
            elif kind == "vertices":
                self.core[i] = np.abs(data).max(axis=0)
                hulls[i] = data
            else:
                semi[i] = data
        special = semi.any(axis=1)
        hull = np.zeros(count, bool)
        hull[list(hulls)] = True
        sizes = [len(hulls[g]) if g in hulls else 0 for g in range(count)]
        vstart = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        verts = np.concatenate([hulls[g] for g in sorted(hulls)] or [np.zeros((0, 3))]).astype(float)
        # The shape tables, in the order the kernels take them.
        self._tables = (self.core, self.disc, self.ball, self.radius, special, semi, hull, vstart, verts)

    def near(self, poses: Poses, nhat, limit: np.ndarray, need: np.ndarray) -> tuple[np.ndarray, ...]:
        """(configurations, pairs, bounds): the rows (configuration k, pair) whose lower bound is below limit[k],
        and their bounds, given the shapes' poses in each configuration, Drake's direction from b to a where it
        reported the pair in that configuration (nhat (configurations, pairs, 3), else NaN), and the distance that
        settles each row (need (configurations, pairs)). Each row keeps the first of the tiered bounds that reaches
        min(need, limit) (see the class doc)."""
        # The kernels load numba on first use (see there).
        from app.checking import kernels

        bound = kernels.near_bounds(self.pairs, tuple(poses), nhat, limit, need, self._tables)
        k, pair = np.nonzero(bound < limit[:, None])
        return k, pair, bound[k, pair]

    def along(self, k, pair, poses: Poses, d: np.ndarray) -> np.ndarray:
        """The gaps of rows (configuration k, pair) along directions d (unit, from the pair's second shape to its
        first), hulls by their vertices: a lower bound on each row's distance."""
        from app.checking import kernels

        return kernels.gaps_along(k, pair, np.ascontiguousarray(d, float), self.pairs, tuple(poses), self._tables)


class Poses(NamedTuple):
    """The shapes' poses in n configurations: every shape's centre (n, geometries, 3; see ShapeGaps.offset), and
    its rotation -- robot[k, slot[g]] for a robot geometry (slot >= 0), environment[g] for the others."""

    centres: np.ndarray
    environment: np.ndarray
    robot: np.ndarray
    slot: np.ndarray


# Per shared oracle, its ShapeGaps, made once; gone with the oracle.
_per_oracle: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def shape_gaps(oracle, geometries: list, robot: np.ndarray, exact: np.ndarray) -> ShapeGaps:
    """The shared oracle's ShapeGaps, made once per oracle."""
    if oracle not in _per_oracle:
        _per_oracle[oracle] = ShapeGaps(oracle, geometries, robot, exact)
    return _per_oracle[oracle]
