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

# Alternating projections between two shapes, for the direction of their gap.
PROJECTIONS = 2
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
        self.special = {}  # geometry index -> semi-axes of an ellipsoid
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
                self.special[i] = data
        self.is_special = np.isin(np.arange(count), list(self.special))
        self.is_hull = np.isin(np.arange(count), list(hulls))
        self.hulls = hulls

    def near(self, rotation, centre, centres, nhat, limit: np.ndarray, need: np.ndarray) -> tuple[np.ndarray, ...]:
        """(configurations, pairs, bounds): the rows (configuration k, pair) whose lower bound is below limit[k],
        and their bounds, given the shapes' poses -- rotation(k, g) (n, 3, 3) and centre(k, g) (n, 3; the shape's
        centre, see offset) of geometries g in configurations k (index arrays), and every shape's centre in every
        configuration, centres (configurations, geometries, 3) -- Drake's direction from b to a where it reported the
        pair in that configuration (nhat (configurations, pairs, 3), else NaN), and the distance that settles each
        row (need (configurations, pairs)). Each row keeps the first of the tiered bounds that reaches min(need,
        limit) (see the class doc). The bounding spheres are taken for every row at once, with no row gathered: most
        rows stop there, and gathering them took longer than the test."""
        a, b = self.pairs.T
        n, count = len(limit), len(self.pairs)
        spheres = (
            _norm((centres[:, a] - centres[:, b]).reshape(-1, 3)).reshape(n, count) - self.radius[a]
        ) - self.radius[b]
        settle = np.minimum(need, limit[:, None]).ravel()
        bound = spheres.ravel()
        live = np.flatnonzero(bound < settle)
        k, pair = np.divmod(live, count)
        bound[live] = self._closer(k, pair, bound[live], rotation, centre, nhat.reshape(-1, 3)[live], settle[live])
        below = np.flatnonzero(bound < np.repeat(limit, count))
        k, pair = np.divmod(below, count)
        return k, pair, bound[below]

    def _closer(self, k, pair, bound, rotation, centre, nhat, settle) -> np.ndarray:
        """The bounds of rows (configuration k, pair) whose bounding spheres (`bound`) did not reach `settle`: from
        a's centre to shape b, and the other way, then the gaps along three directions, each on the rows the tier
        before left below `settle` (see near)."""
        a, b = self.pairs[pair].T
        pa, pb = centre(k, a), centre(k, b)
        live = np.arange(len(k))
        B = self._posed(b, rotation(k, b), pb)
        bound = np.maximum(bound, self._distance_to(B, pa) - self.radius[a])
        keep = np.flatnonzero(bound < settle)
        live, B = live[keep], _rows(B, keep)
        A = self._posed(a[live], rotation(k[live], a[live]), pa[live])
        bound[live] = np.maximum(bound[live], self._distance_to(A, B.p) - B.radius)
        keep = np.flatnonzero(bound[live] < settle[live])
        live, A, B = live[keep], _rows(A, keep), _rows(B, keep)
        bound[live] = np.maximum(bound[live], self._gap(A, B, nhat[live], settle[live]))
        return bound

    def along(self, k, pair, rotation, centre, d: np.ndarray) -> np.ndarray:
        """The gaps of rows (configuration k, pair) along directions d (unit, from the pair's second shape to its
        first), hulls by their vertices: a lower bound on each row's distance (see near for rotation and centre)."""
        a, b = self.pairs[pair].T
        A = self._posed(a, rotation(k, a), centre(k, a))
        B = self._posed(b, rotation(k, b), centre(k, b))
        return self._along(A, B, d, exact=True)

    def _posed(self, g: np.ndarray, R: np.ndarray, p: np.ndarray) -> _Posed:
        return _Posed(R, p, self.core[g], self.disc[g], self.ball[g], self.radius[g], g)

    def _gap(self, A: _Posed, B: _Posed, nhat: np.ndarray, settle: np.ndarray) -> np.ndarray:
        """The largest gap between the shapes along three directions: Drake's where it has one, and the normals of
        each shape at the near points that alternating projections onto the two shapes find (a mesh as its box, an
        ellipsoid as its centre). Any direction's gap bounds the distance from below; a normal of a shape makes that
        shape's side of the bound exact. Hulls count as their boxes first; the rows with a hull still below `settle`
        are bounded again with the hull's vertices, along Drake's direction if it has one (GJK's direction between
        two hulls is close to theirs; it costs one pair query where the hull's face normals would cost faces x
        vertices per pair), else along the projections'."""
        on_a = A.p
        for _ in range(PROJECTIONS):
            on_b = self._project(B, on_a)
            on_a = self._project(A, on_b)
        n = np.stack([on_a - on_b, on_a - self._project(B, on_a), nhat], 1)
        length = np.linalg.norm(n, axis=2)
        n = np.where(length[..., None] > 1e-12, n / np.maximum(length, 1e-300)[..., None], np.nan)
        best = self._best_gap(A, B, n, np.isfinite(n[:, :, 0]), exact=False)
        again = np.flatnonzero((self.is_hull[A.g] | self.is_hull[B.g]) & (best < settle)) if self.hulls else []
        if len(again):
            m = n[again]
            use = np.isfinite(m[:, :, 0])
            use[:, :2] &= ~use[:, 2:]  # Drake's direction alone where there is one
            best[again] = np.maximum(best[again], self._best_gap(_rows(A, again), _rows(B, again), m, use, exact=True))
        return best

    def _best_gap(self, A: _Posed, B: _Posed, n: np.ndarray, use: np.ndarray, exact: bool) -> np.ndarray:
        """Per row, the largest gap along the directions n[row, j] (unit, from B to A) where use[row, j]; -inf
        where none. A direction every row has goes in one call without gathering the rows; the rest in one more."""
        gaps = np.full(use.shape, -np.inf)
        every = use.all(axis=0)
        for j in np.flatnonzero(every).tolist():
            gaps[:, j] = self._along(A, B, n[:, j], exact)
        partial = np.flatnonzero(~every)
        row, column = np.nonzero(use[:, partial])
        if len(row):
            column = partial[column]
            gaps[row, column] = self._along(_rows(A, row), _rows(B, row), n[row, column], exact)
        return gaps.max(axis=1)

    def _along(self, A: _Posed, B: _Posed, d: np.ndarray, exact: bool) -> np.ndarray:
        """The gap of each pair of rows A[i], B[i] along d[i] (unit, from B to A). With hulls' vertices both shapes'
        supports go in one call (they cost one product per hull and call); in closed form, two calls cost less than
        gathering the rows into one."""
        if not exact:
            return np.einsum("ij,ij->i", d, A.p - B.p) - self._support(A, -d, False) - self._support(B, d, False)
        both = _Posed(*(np.concatenate(fields) for fields in zip(A, B)))
        support = self._support(both, np.concatenate([-d, d]), exact)
        return np.einsum("ij,ij->i", d, A.p - B.p) - support[: len(d)] - support[len(d) :]

    def _support(self, S: _Posed, n: np.ndarray, exact: bool) -> np.ndarray:
        """max over each posed shape of n . (x - its centre), for world directions n (unit rows): exact, or for a
        hull, its box's (larger) unless `exact`."""
        u = np.einsum("mji,mj->mi", S.R, n)
        out = (S.core * np.abs(u)).sum(1) + S.disc * np.hypot(u[:, 0], u[:, 1]) + S.ball
        if exact:  # rows by hull, one product with each hull's vertices
            rows = np.flatnonzero(self.is_hull[S.g])
            rows = rows[np.argsort(S.g[rows], kind="stable")]
            starts = np.flatnonzero(np.diff(S.g[rows], prepend=-1))
            for group, g in zip(np.split(rows, starts[1:]), S.g[rows[starts]].tolist()):
                out[group] = (u[group] @ self.hulls[g].T).max(1)
        for i in np.unique(S.g[self.is_special[S.g]]):  # ellipsoids
            m = S.g == i
            out[m] = np.linalg.norm(self.special[i] * u[m], axis=1)
        return out

    def _project(self, S: _Posed, x: np.ndarray) -> np.ndarray:
        """The point of each posed shape nearest to x, in the world (a hull's box's; an ellipsoid's centre)."""
        local = np.einsum("mji,mj->mi", S.R, x - S.p)
        near = np.clip(local, -S.core, S.core)
        disc = S.disc > 0
        if disc.any():
            near[disc, :2] = local[disc, :2] * _shrink(local[disc, :2], S.disc[disc])
        near += (local - near) * _shrink(local - near, S.ball)
        return S.p + np.einsum("mij,mj->mi", S.R, near)

    def _distance_to(self, S: _Posed, x: np.ndarray) -> np.ndarray:
        """A lower bound on the distance from x to each posed shape: to its nearest point as _project finds it (a
        hull's box holds the hull, so it is no farther), or for an ellipsoid, to its bounding sphere."""
        exact = _norm(self._project(S, x) - x)
        rough = np.maximum(_norm(S.p - x) - S.radius, 0.0)
        return np.where(self.is_special[S.g], rough, exact)


class _Posed(NamedTuple):
    """Shapes of the gaps' pairs, one a row, posed: rotation, centre, and their ShapeGaps parameters."""

    R: np.ndarray
    p: np.ndarray
    core: np.ndarray
    disc: np.ndarray
    ball: np.ndarray
    radius: np.ndarray
    g: np.ndarray  # geometry indices


def _rows(S: _Posed, rows) -> _Posed:
    return _Posed(*(field[rows] for field in S))


def _shrink(v: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Factors that bring vectors v (rows) within `radius` of the origin, (n, 1)."""
    return np.minimum(1.0, radius / np.maximum(_norm(v), 1e-300))[:, None]


def _norm(v: np.ndarray) -> np.ndarray:
    """Lengths of the rows of v (n, 3): np.linalg.norm's checks cost more than the sum on a few thousand rows."""
    return np.sqrt(np.einsum("ij,ij->i", v, v))


# Per shared oracle, its ShapeGaps, made once; gone with the oracle.
_per_oracle: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def shape_gaps(oracle, geometries: list, robot: np.ndarray, exact: np.ndarray) -> ShapeGaps:
    """The shared oracle's ShapeGaps, made once per oracle (its hulls' support tables fill as they are used)."""
    if oracle not in _per_oracle:
        _per_oracle[oracle] = ShapeGaps(oracle, geometries, robot, exact)
    return _per_oracle[oracle]
