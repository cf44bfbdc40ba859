"""Continuous collision certification by conservative advancement: a motion is proved free, not only sampled.

Motion bound. For robot geometry g and coordinate j, rates[g, j] bounds how far any point of g moves per unit of
q_j, at every configuration: 1 for a prismatic joint; for a revolute joint, the distance from its axis to the
farthest point of g, bounded without knowing q by the triangle inequality -- the fixed offsets along the chain
from the joint to g's body (a prismatic joint on the way adds its largest travel within the bounds) plus g's
radius about its body origin, taken from the shape. So along any motion a point of g travels at most
B_g = sum_j rates[g, j] * (travel of q_j).

Certificate. Signed distance changes no faster than the shapes move, so if at the ends a, b of a piece of motion
d_PQ(a) + d_PQ(b) > B_P + B_Q for every pair the scene counts (B = 0 for the environment), P and Q never touch in
between: d(t) >= d(a) - travel(a..t) and d(t) >= d(b) - travel(t..b), and the two travels add up to at most
B_P + B_Q. A piece that fails is bisected; one that still fails once its motion is shorter than the floor (in
the space's weighted metric) is reported as colliding.

Distances. Drake computes box-box and sphere pairs in closed form, but pairs with a cylinder, capsule, ellipsoid or
mesh by GJK, whose answers were measured up to 0.34 mm too large (the maze's hull at 1 cm from a pillar's corner;
0.07 mm on the window). Too large is unsafe, so such a pair's distance is replaced by a lower bound of our own: the
gap between the two shapes along Drake's separating direction, from the shapes' support functions (the gap along
any direction bounds the distance from below). It came out up to 0.2 mm below the true distance on the maze.

max_distance. A query reports only the pairs within its max_distance D, so an unreported pair is at least D apart
at that end. Each end is queried with D just above half the largest B_P + B_Q of the pieces it bounds: a pair
unreported at both ends then passes, and Drake computes no more pairs than the test needs. (Drake is asked a
little farther, REPORT_SLACK, so that a pair its GJK error leaves out is surely beyond D.) Distances are cached
per configuration, so ends shared by adjacent pieces, and by rounds of a caller that retries, are asked once.
"""
from __future__ import annotations

import itertools
import time
import weakref
from typing import NamedTuple

import numpy as np

# A piece is bisected until its motion is shorter than resolution / FLOOR_DIVISOR (weighted metric).
FLOOR_DIVISOR = 256
# max_distance slightly above half the largest pair bound, so an unreported pair passes strictly.
_MARGIN = 1.0 + 1e-6
# Pairs are asked for this fraction of the resolution beyond the distance needed (over ten times the GJK errors
# measured), so that a pair left out at max_distance + slack is surely beyond max_distance.
REPORT_SLACK = 0.1
# Shape pairs Drake computes signed distance for in closed form.
_EXACT = {frozenset(pair) for pair in [("Box",), ("Sphere",), ("Box", "Sphere"), ("Sphere", "Capsule"),
                                       ("Sphere", "Cylinder")]}
# Pair key: smaller geometry index * _KEY + larger.
_KEY = 1 << 31


class MotionBound:
    """Per robot geometry, per coordinate: the largest distance any point of the geometry moves per unit of that
    coordinate, at any configuration within the space's bounds."""

    def __init__(self, oracle):
        plant = oracle.plant
        inspector = oracle.model.scene_graph().model_inspector()
        inboard = {}
        for index in plant.GetJointIndices():
            joint = plant.get_joint(index)
            inboard[joint.child_body().index()] = joint
        self.rows, rates = {}, []
        for instance in oracle.scene.robot_instances:
            for body_index in plant.GetBodyIndices(instance):
                chain = _chain(inboard, body_index)
                for geometry in plant.GetCollisionGeometriesForBody(plant.get_body(body_index)):
                    self.rows[geometry] = len(rates)
                    pose = inspector.GetPoseInFrame(geometry)
                    rates.append(_rates(chain, _radius(*_describe(inspector, geometry), pose), oracle.space))
        # The last row (zeros) stands for every environment geometry: it does not move.
        self.rates = np.vstack(rates + [np.zeros(oracle.space.dim)])
        self.self_pairs = oracle.scene.self_collisions

    def row(self, geometry_id) -> int:
        return self.rows.get(geometry_id, -1)

    def travel(self, variation: np.ndarray) -> np.ndarray:
        """Bound on how far any point of each geometry moves when coordinate j travels variation[j] (>= 0)."""
        return self.rates @ variation

    def max_distance(self, travel: np.ndarray) -> float:
        """The max_distance at which every unreported pair passes: half the largest B_P + B_Q of a counted pair."""
        top = np.sort(travel)[-2:]
        largest = top.sum() if self.self_pairs else top[-1]
        return 0.5 * largest * _MARGIN + 1e-12


def _chain(inboard: dict, body_index) -> list:
    """The joints from a body up to the world, nearest first."""
    chain = []
    while body_index in inboard:
        joint = inboard[body_index]
        chain.append(joint)
        body_index = joint.parent_body().index()
    return chain


def _rates(chain: list, radius: float, space) -> np.ndarray:
    """Rates of one geometry whose points lie within `radius` of its body origin."""
    rates = np.zeros(space.dim)
    reach = radius  # bound on the distance from the current joint's child body origin to any point of the geometry
    for joint in chain:
        reach += np.linalg.norm(joint.frame_on_child().GetFixedPoseInBodyFrame().translation())
        kind, start = joint.type_name(), joint.position_start()
        if kind == "revolute":
            rates[start] = reach  # the axis passes through the joint frame's origin: distance to it bounds the lever
            slide = 0.0
        elif kind == "prismatic":
            rates[start] = np.linalg.norm(joint.translation_axis())
            slide = rates[start] * max(abs(space.lower[start]), abs(space.upper[start]))
        elif kind == "weld":
            slide = np.linalg.norm(joint.X_FM().translation())
        else:
            raise ValueError(f"joint '{joint.name()}' of type {kind}: the motion bound handles revolute, prismatic "
                             "and weld joints only")
        reach += slide + np.linalg.norm(joint.frame_on_parent().GetFixedPoseInBodyFrame().translation())
    return rates


def _describe(inspector, geometry) -> tuple[str, object]:
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
        hull = shape.GetConvexHull()
        return "vertices", np.array([hull.vertex(i) for i in range(hull.num_vertices())])
    raise ValueError(f"geometry '{inspector.GetName(geometry)}': no certificate for a {type(shape).__name__}")


def _radius(kind: str, data, pose) -> float:
    """Largest distance from the origin of the frame the shape is posed in (pose X_FG) to a point of the shape."""
    if kind in ("box", "vertices"):
        corners = data if kind == "vertices" else np.array(list(itertools.product(*[[-h, h] for h in data])))
        return float(np.linalg.norm(pose.multiply(corners.T), axis=0).max())
    extent = {"sphere": lambda: data, "cylinder": lambda: np.hypot(*data), "capsule": lambda: sum(data),
              "ellipsoid": lambda: data.max()}[kind]()
    return float(np.linalg.norm(pose.translation()) + extent)


def _support(kind: str, data, u: np.ndarray) -> float:
    """max over the shape of u . x, in the shape's own frame (u a unit vector)."""
    if kind == "box":
        return float(data @ np.abs(u))
    if kind == "sphere":
        return data
    if kind == "cylinder":
        return data[0] * np.hypot(u[0], u[1]) + data[1] * abs(u[2])
    if kind == "capsule":
        return data[0] + data[1] * abs(u[2])
    if kind == "ellipsoid":
        return float(np.linalg.norm(data * u))
    return float((data @ u).max())


_bounds: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def motion_bound(oracle) -> MotionBound:
    """The oracle's MotionBound, computed once per oracle."""
    if oracle not in _bounds:
        _bounds[oracle] = MotionBound(oracle)
    return _bounds[oracle]


class Certifier:
    """Certifies pieces of motion for one oracle, keeping the distances it has asked for across calls."""

    def __init__(self, oracle, floor: float | None = None):
        from pydrake.geometry import Role

        self.oracle = oracle
        self.bound = motion_bound(oracle)
        self.floor = floor if floor is not None else oracle.space.resolution / FLOOR_DIVISOR
        self._cache = {}  # configuration bytes -> _End, or None where it collides
        self.slack = oracle.space.resolution * REPORT_SLACK
        inspector = oracle.model.scene_graph().model_inspector()
        geometries = inspector.GetAllGeometryIds(Role.kProximity)
        self._indices = {g: i for i, g in enumerate(geometries)}  # a small integer per geometry, for pair keys
        self._rows = np.array([self.bound.row(g) for g in geometries], np.int64)  # -1: environment
        kinds = [type(inspector.GetShape(g)).__name__ for g in geometries]
        # Pairs Drake computes in closed form; the others (GJK) get a lower bound of our own (see the module doc).
        self._exact = np.array([[frozenset((a, b)) in _EXACT for b in kinds] for a in kinds], bool)
        self._shapes = {}

    def certify(self, position, variation, intervals) -> tuple[bool, dict]:
        """Whether the curve `position(s)` is free over each interval (s0, s1) of `intervals`.

        variation(s0, s1) bounds each coordinate's travel between s0 and s1, for s0 < s1 within one interval.
        The curve must stay within the space's bounds between in-bound ends (a straight edge or a blend does).
        stats: failed (indices of intervals not certified), pieces (certified), distance_queries, seconds.
        """
        clock, queries = time.perf_counter(), self.oracle.distance_queries
        intervals = [(float(a), float(b)) for a, b in intervals]
        hint = {}  # shared ends are asked once, at the larger max_distance of the intervals they bound
        for a, b in intervals:
            need = self._need(variation(a, b))
            hint[a], hint[b] = max(hint.get(a, 0.0), need), max(hint.get(b, 0.0), need)
        failed, pieces = [], 0
        for i, (a, b) in enumerate(intervals):
            count = self._interval(position, variation, a, b, hint)
            if count is None:
                failed.append(i)
            else:
                pieces += count
        stats = {"failed": failed, "pieces": pieces, "distance_queries": self.oracle.distance_queries - queries,
                 "seconds": time.perf_counter() - clock}
        return not failed, stats

    def _need(self, variation: np.ndarray) -> float:
        return self.bound.max_distance(self.bound.travel(variation))

    def _interval(self, position, variation, s0: float, s1: float, hint: dict) -> int | None:
        """How many pieces certify [s0, s1] (bisecting as needed), or None if some piece cannot be certified."""
        stack, pieces = [(s0, s1)], 0
        while stack:
            a, b = stack.pop()
            var = variation(a, b)
            travel = self.bound.travel(var)
            need = self.bound.max_distance(travel)
            ends = [self._distances(position(s), max(need, hint.get(s, 0.0))) for s in (a, b)]
            if ends[0] is None or ends[1] is None:
                return None
            if _clear(ends[0], ends[1], travel):
                pieces += 1
                continue
            if np.linalg.norm(var * self.oracle.space.weights) <= self.floor:
                return None
            m = 0.5 * (a + b)
            hint[m] = max(self._need(variation(a, m)), self._need(variation(m, b)))
            stack += [(m, b), (a, m)]  # the left half first: a collision near the start shows up early
        return pieces

    def _distances(self, q: np.ndarray, max_distance: float):
        """The pairs within max_distance at q (an _End), from the cache when it was asked at a max_distance at
        least as large; None if q collides or lies outside the bounds."""
        q = np.asarray(q, float)
        key = q.tobytes()
        if key in self._cache:
            cached = self._cache[key]
            if cached is None or cached.limit >= max_distance:
                return cached
        end = None
        if self.oracle.space.within_bounds(q)[0]:
            # Asked a little farther than needed: a pair Drake's inexact distance leaves out is then surely beyond.
            pairs = self.oracle.signed_distances(q, max_distance + self.slack)
            end = self._end(q, pairs, max_distance)
        self._cache[key] = end
        return end

    def _end(self, q: np.ndarray, pairs: list, limit: float):
        distance = np.fromiter((p.distance for p in pairs), float, len(pairs))
        if np.any(distance <= 0):
            return None
        ix = self._indices
        index = np.array([(ix[p.id_A], ix[p.id_B]) for p in pairs], np.int64).reshape(-1, 2)
        inexact = [k for k, (a, b) in enumerate(index) if not self._exact[a, b]]
        if inexact:
            query = self.oracle.query_object(q)
            for k in inexact:
                distance[k] = min(distance[k], self._lower_bound(query, pairs[k]))
        index.sort(axis=1)  # a pair is the same whichever geometry Drake names first
        keys = index[:, 0] * _KEY + index[:, 1]
        order = np.argsort(keys)
        rows = self._rows[index[order]]
        return _End(limit, keys[order], distance[order], rows[:, 0], rows[:, 1])

    def _lower_bound(self, query, pair) -> float:
        """A distance no larger than the true one, whatever Drake's error: the gap between the two shapes along
        Drake's separating direction, from their support functions (any direction's gap bounds the distance)."""
        n = pair.nhat_BA_W
        X_A, X_B = query.GetPoseInWorld(pair.id_A), query.GetPoseInWorld(pair.id_B)
        lowest_a = n @ X_A.translation() - _support(*self._shape(pair.id_A), X_A.rotation().matrix().T @ -n)
        highest_b = n @ X_B.translation() + _support(*self._shape(pair.id_B), X_B.rotation().matrix().T @ n)
        return lowest_a - highest_b

    def _shape(self, geometry):
        if geometry not in self._shapes:
            self._shapes[geometry] = _describe(self.oracle.model.scene_graph().model_inspector(), geometry)
        return self._shapes[geometry]


class _End(NamedTuple):
    """Distances at one end of a piece: the pairs within `limit`, by key, sorted."""

    limit: float
    keys: np.ndarray
    distance: np.ndarray
    row_a: np.ndarray
    row_b: np.ndarray


def _clear(a: _End, b: _End, travel: np.ndarray) -> bool:
    """The certificate for one piece: every pair reported at either end is farther apart, summed over the two
    ends, than both its shapes can move (a pair an end does not report is at least that end's limit apart)."""
    return _pass(a, b, travel) and _pass(b, a, travel)


def _pass(a: _End, b: _End, travel: np.ndarray) -> bool:
    """The certificate for the pairs `a` reports, with their distance at `b`, or b's limit where b has none."""
    other = np.full(len(a.keys), b.limit)
    if len(b.keys):
        at = np.searchsorted(b.keys, a.keys).clip(max=len(b.keys) - 1)
        found = b.keys[at] == a.keys
        other[found] = b.distance[at[found]]
    return bool(np.all(a.distance + other > travel[a.row_a] + travel[a.row_b]))


def certify_curve(oracle, position, variation, knots, floor: float | None = None) -> tuple[bool, dict]:
    """Certify the curve position(s) over [knots[0], knots[-1]]; variation(s0, s1) bounds each coordinate's
    travel for s0 < s1 between two consecutive knots. stats["failed"]: indices of the knot intervals that failed."""
    knots = np.asarray(knots, float)
    return Certifier(oracle, floor).certify(position, variation, itertools.pairwise(knots))


def polyline(space, P: np.ndarray):
    """(position, variation) of the polyline P with parameter s = i + t on edge i (straight, the short way)."""
    W = space.unwrap(P)
    D = np.diff(W, axis=0)

    def edge(s: float) -> int:
        return min(max(int(s), 0), len(D) - 1)

    def position(s: float) -> np.ndarray:
        i = edge(s)
        return W[i] + (s - i) * D[i]

    def variation(s0: float, s1: float) -> np.ndarray:
        return np.abs(D[edge(0.5 * (s0 + s1))]) * (s1 - s0)

    return position, variation


def certify_path(oracle, P: np.ndarray, floor: float | None = None) -> tuple[bool, dict]:
    """Certify every straight edge of the polyline P (in oracle.space). stats["failed"]: the edges that failed."""
    P = np.atleast_2d(np.asarray(P, float))
    if len(P) < 2:
        P = np.vstack([P, P])
    position, variation = polyline(oracle.space, P)
    return certify_curve(oracle, position, variation, np.arange(len(P)), floor)
