"""Continuous collision certification by conservative advancement: a motion is proved free, not only sampled.

Motion bound. For robot geometry g and coordinate j, rates[g, j] bounds how far any point of g moves per unit of
q_j, at every configuration: 1 for a prismatic joint; for a revolute joint, the distance from its axis to the
farthest point of g, bounded without knowing q by the triangle inequality -- the fixed offsets along the chain
from the joint to g's body (a prismatic joint on the way adds its largest travel within the bounds) plus g's
radius about its body origin, taken from the shape. So along any motion a point of g travels at most
B_g = sum_j rates[g, j] * (travel of q_j).

Where the ends of a piece are known, the revolute rates are taken there instead (Schwarzer, Saha and Latombe's
bound): the distance from the joint's axis to g's centre plus g's radius about it, at each end, grown by how far
the joints between the axis and g move g's points along the piece (the arm depends on those joints alone), the
lesser of the two ends and never more than the rate anywhere. An arm folded near its base moves its tool much
less per radian of the shoulder than the outstretched arm the rate anywhere assumes: on the UR3 the tool's bound
is about half, and proving a piece takes fewer, longer parts.

A second bound starts from the motion itself (MotionBound.pair_travel_along): at each end of a piece, the speed of
g's points from its centre's velocity and its angular velocity (a Jacobian product, in which joints turning the arm
both ways cancel, where the sum above adds them up), plus how much that speed can change along the piece (products
of the joints' rates and speeds, and the curve's own acceleration). Both hold; each pair takes the lesser. On the
UR3 the travel bound was 1.6 times the farthest any point moved at the median over cell queries' pieces.

Relative motion. Two robot geometries' distance is the same measured in the frame of the last body their chains
to the world share, where only the joints below it move them: for such a pair the bound B_PQ sums the two rates
over the coordinates of the joints the chains do not share (the cart and the shoulder never bring the wrist nearer
the upper arm). For a robot-environment pair, B_PQ = B_P.

Certificate. Signed distance changes no faster than that, so if at the ends a, b of a piece of motion
d_PQ(a) + d_PQ(b) > B_PQ for every pair the scene counts, P and Q never touch in between:
d(t) >= d(a) - B_PQ(a..t) and d(t) >= d(b) - B_PQ(t..b), and the two add up to at most B_PQ. With a clearance c,
d_PQ(a) + d_PQ(b) > B_PQ + 2c leaves d(t) >= c all along the piece, in the same way. An interval starts
as pieces a few resolutions long (a longer piece seldom passes whole, and a round of pieces costs a fixed part
besides its distance queries); a piece that fails is cut into parts (as many as its ends' distances fall short,
2 to 8); one that still fails once its motion is shorter than the floor (in the space's weighted metric) is
reported as colliding. Each interval is cut nearest to contact first, several pieces of every interval at a time
with their ends bounded in one batch (see Certifier).
A piece that certainly fails -- some pair's B_PQ exceeds the sum of upper bounds on its distance at the two ends,
the distances between a point inside each shape -- is cut before its ends are asked (on mesh scenes, where asking
costs most): no lower bound could pass it, and it falls short by at least that factor.

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
stops at the first that puts it beyond the limit D (below) or, on mesh scenes, as far apart as the pieces at that
end need (its largest B_PQ over them: with any positive distance at the other end the pair then passes), so most
pairs cost a sphere test. Where a pair is not settled without Drake's direction, it is bounded along the direction
Drake last gave for it (ends of one motion are near each other; mesh scenes) and, failing that, Drake's direction
is asked for that pair alone.
Every distance is lowered by a rounding allowance (1e-9 of the resolution).

max_distance. A query reports only the pairs within its max_distance D, so an unreported pair is at least D apart
at that end. Each end is queried with D just above half the largest B_PQ of the pieces it bounds: a pair
unreported at both ends then passes, and Drake computes no more pairs than the test needs (pairs of the GJK kind
count as unreported when their own bound is at least D). Where no counted pair is of a kind Drake computes exactly,
the pairwise query is not asked at all: it has a fixed cost (some 60 us a configuration on the UR3, with nothing
within D), GJK on a mesh's hull costs time per vertex besides, and our bounds cover every pair anyway, Drake's
direction being asked per pair where needed. A pair in contact cannot pass a piece even then: its lower bound is at
most 0, and only a configuration with such a bound is asked whether it is in contact (HasCollisions), so that its
pieces fail at once. Distances are cached per configuration, so ends shared by adjacent pieces, and by rounds of a
caller that retries, are asked once.
"""

from __future__ import annotations

import heapq
import itertools
import math
import time
import weakref
from types import SimpleNamespace
from typing import NamedTuple

import numpy as np

from app.checking.kinematics import TreeKinematics
from app.checking.protocol import Checker
from app.scene.shapes import hull_vertices

# What a planned motion is proved to keep from everything by default (scene length units: metres for the robots): a
# margin for the proofs that the straight lines a controller draws between its samples, and the path polyline, are
# free too (app.motion.timing), not a safety padding -- a larger one (PlanSettings.clearance) pads the motion, for
# more collision checks, as the planner's own checks do not pad (benchmark pages).
CLEARANCE = 1e-5
# A piece is cut until its motion is shorter than resolution / FLOOR_DIVISOR (weighted metric).
FLOOR_DIVISOR = 256
# max_distance slightly above half the largest pair bound, so an unreported pair passes strictly.
_MARGIN = 1.0 + 1e-6
# Shape pairs Drake computes signed distance for in closed form.
_EXACT = {
    frozenset(pair)
    for pair in [("Box",), ("Sphere",), ("Box", "Sphere"), ("Sphere", "Capsule"), ("Sphere", "Cylinder")]
}
# Alternating projections between two shapes, for the direction of their gap.
PROJECTIONS = 2
# Pair key: smaller geometry index * _KEY + larger.
_KEY = 1 << 31
# Slack on bounds computed from derivatives and rotations, for their rounding.
_SLACK = 1 + 1e-9


class MotionBound:
    """Per robot geometry, per coordinate: the largest distance any point of the geometry moves per unit of that
    coordinate, at any configuration within the space's bounds; and per pair of geometries, the same for how fast
    their distance can change.

    Two robot geometries' distance is the same seen from the last body their chains to the world share, in whose
    frame only the joints below that body move either of them: so a robot-robot pair's rates are the two
    geometries' rates on the coordinates of the joints the two chains do not share, and 0 on the shared ones
    (the cart and the shoulder do not bring the wrist nearer the upper arm)."""

    def __init__(self, oracle):
        plant = oracle.plant
        inspector = oracle.model.scene_graph().model_inspector()
        inboard = {}
        for index in plant.GetJointIndices():
            joint = plant.get_joint(index)
            inboard[joint.child_body().index()] = joint
        # Rates per plant position; with mimic joints there are more of them than coordinates (folded in below).
        space, mimic = oracle.space, oracle.scene.position_map
        if mimic is not None:
            lower, upper = mimic.position_bounds(space.lower, space.upper)
            space = SimpleNamespace(dim=len(lower), lower=lower, upper=upper)
        self.rows, rates, moved_by = {}, [], []
        for instance in oracle.scene.robot_instances:
            for body_index in plant.GetBodyIndices(instance):
                chain = _chain(inboard, body_index)
                for geometry in plant.GetCollisionGeometriesForBody(plant.get_body(body_index)):
                    self.rows[geometry] = len(rates)
                    pose = inspector.GetPoseInFrame(geometry)
                    rates.append(_rates(chain, _radius(*_describe(inspector, geometry), pose), space))
                    moved_by.append(_coordinates(chain, space.dim))
        # The last row (zeros) stands for every environment geometry: it does not move.
        self.rates = np.vstack(rates + [np.zeros(space.dim)])
        # pair_rates[P, Q]: how fast the distance of P and Q can change per unit of each coordinate.
        moved_by = np.vstack(moved_by + [np.zeros(space.dim, bool)])
        shared = moved_by[:, None, :] & moved_by[None, :, :]
        self.pair_rates = (self.rates[:, None, :] + self.rates[None, :, :]) * ~shared
        if mimic is not None:
            # A unit of a coordinate moves its joint by 1 and each joint mimicking it by |multiplier|. Shared joints
            # are left out per position first: two fingers on one coordinate do not share their joints.
            spread = np.abs(mimic.matrix)
            self.rates, self.pair_rates = self.rates @ spread, self.pair_rates @ spread
        if not oracle.scene.self_collisions:  # robot-robot pairs do not count
            self.pair_rates[:-1, :-1] = 0.0
        self._unshared = self.pair_rates > 0  # where a pair's rates count a coordinate (shared: 0)
        self._levers = None if mimic is not None else _LeverArms.of(oracle, inboard, self.rows, self.rates)

    def row(self, geometry_id) -> int:
        return self.rows.get(geometry_id, -1)

    def travel(self, variation: np.ndarray) -> np.ndarray:
        """Bound on how far any point of each geometry moves when coordinate j travels variation[j] (>= 0)."""
        return self.rates @ variation

    def pair_travel(self, variation: np.ndarray) -> np.ndarray:
        """Bounds on how much each pair's distance changes, (..., rows, rows), for variations (..., dim), anywhere
        in the space."""
        return np.einsum("pqj,...j->...pq", self.pair_rates, variation)

    def local(self, Q: np.ndarray) -> _Local | None:
        """The robot's kinematics at the configurations Q (n, dim), for the bounds of pieces with known ends: per
        configuration, geometry row and coordinate, the lever arm -- the distance from the coordinate's revolute
        axis to the farthest point of the geometry there (inf for other coordinates and the environment row) --
        and the velocity of the row's centre and its angular velocity per unit of the coordinate (see _Local).
        None where this robot has no such bounds (mimic joints, joints other than revolute, prismatic and weld):
        its pieces take the bound anywhere in the space."""
        return None if self._levers is None else self._levers(Q)

    def piece_rates(self, variation: np.ndarray, levers_a: np.ndarray, levers_b: np.ndarray) -> np.ndarray:
        """Rates (n, rows, dim) that hold all along pieces of motion (n, dim) with their ends' levers (n, rows, dim):
        a revolute joint moves a geometry's points at most its lever arm per radian, and along the piece that arm
        grows by no more than the joints between the axis and the geometry move its points (a joint's own turn
        does not change it), so each end's lever plus that growth bounds the arm -- the lesser of the two ends',
        and never more than the rate anywhere in the space."""
        slack = self._levers.slack(variation)
        return np.minimum(self.rates, np.minimum(levers_a, levers_b) + slack)

    def pair_travel_of(self, variation: np.ndarray, rates: np.ndarray) -> np.ndarray:
        """pair_travel for pieces of motion (n, dim) whose rates all along them are `rates` (n, rows, dim)."""
        moved = rates * variation[:, None, :]
        return np.einsum("npj,pqj->npq", moved, self._unshared) + np.einsum("nqj,pqj->npq", moved, self._unshared)

    def pair_travel_along(self, rates: np.ndarray, at_a: _Local, at_b: _Local, da, db, dd) -> np.ndarray:
        """Bounds (n, rows, rows) on how much each pair's distance changes along pieces of a curve, from the curve's
        velocity at the pieces' ends, da and db (n, dim), and a bound dd (n, dim) on its acceleration, all per unit
        of a parameter tau running from 0 to 1 along each piece; at_a, at_b: the local kinematics at the ends (see
        `local`), rates: as piece_rates (every point of the row's geometry lies within rates[j] of axis j all along
        the piece).

        Where the bound from the travel sums every joint's share of the motion, this one starts from the motion
        itself: at an end, a point x of a geometry moves at |v_c + w x (x - c)| <= |v_c| + |w| rho (centre c, radius
        rho about it), and along the piece its speed changes at most M = sum_j rates_j (|q_j'| (|q_j'| [j revolute] +
        2 sum_{k revolute, inboard of j} |q_k'|) + |q_j''|) per unit of tau -- the derivative of joint j's column of
        the Jacobian along joint k is w_k x J_j for k inboard of or at j and w_j x J_k outboard of it, each at most
        the outboard one's rate. So by tau a point has moved at most tau V_a + tau^2 M / 2 <= tau (V_a + M / 2) from
        end a, and as much the other way from end b: two points (one per geometry) move their distance by at most
        the larger of the two sums. Joints that turn the arm both ways about parallel axes (the UR3's shoulder,
        elbow and wrist) cancel here; the travel adds them up."""
        arms = self._levers
        speed = 0.5 * (np.abs(da) + np.abs(db) + dd)  # |q'| all along the piece: q' changes by at most dd
        turning = speed * arms.revolute
        inboard = np.einsum("nk,rkj->nrj", turning, arms.below)
        change = np.einsum(
            "nrj,nrj->nr", rates, speed[:, None, :] * (turning[:, None, :] + 2 * inboard) + dd[:, None, :]
        )
        reach_a = at_a.speed(da) + 0.5 * change
        reach_b = at_b.speed(db) + 0.5 * change
        pairs = np.maximum(reach_a[:, :, None] + reach_a[:, None, :], reach_b[:, :, None] + reach_b[:, None, :])
        return pairs * _SLACK

    @staticmethod
    def max_distance(pair_travel: np.ndarray) -> np.ndarray:
        """The max_distance at which every unreported pair passes: half the largest pair bound (the environment-
        environment entry counts nothing, and is 0)."""
        return 0.5 * pair_travel.max(axis=(-2, -1)) * _MARGIN + 1e-12


class _LeverArms:
    """Lever arms of a robot's geometries about its revolute axes, at given configurations (see
    MotionBound.local): from each axis (a line through its joint frame's origin) to the geometry's centre, plus
    the geometry's radius about that centre; and with them each geometry's Jacobian columns at its centre (see
    _Local), for MotionBound.pair_travel_along."""

    def __init__(self, kinematics: TreeKinematics, axes, columns, centres, radius, below, rates, slides, chain):
        self._kinematics = kinematics
        self._axes = axes  # unit axis per revolute joint, in its frame on the child body
        self._columns = columns  # its coordinate
        self._centres = centres  # frames (after the axes' frames) of the robot rows' centres
        self._radius = radius  # per robot row, about its centre
        self.below = below  # (rows, dim, dim): coordinate k moves a row's geometry relative to coordinate j's axis
        self._rates = rates
        self._slides = slides  # per prismatic joint: (frame after the centres', unit axis in it, coordinate)
        self._chain = chain  # (rows, dim): the coordinates that move each row
        self.revolute = np.isin(np.arange(rates.shape[1]), columns)

    @classmethod
    def of(cls, oracle, inboard: dict, rows: dict, rates: np.ndarray) -> _LeverArms | None:
        from pydrake.math import RigidTransform

        plant = oracle.plant
        inspector = oracle.model.scene_graph().model_inspector()
        dim = rates.shape[1]
        frames, axes, columns = [], [], []
        for index in plant.GetJointIndices():
            joint = plant.get_joint(index)
            if joint.type_name() == "revolute" and joint.num_positions() == 1:
                frames.append((joint.child_body(), joint.frame_on_child().GetFixedPoseInBodyFrame()))
                axes.append(joint.revolute_axis())
                columns.append(joint.position_start())
        radius, below = np.zeros(len(rows)), np.zeros((len(rows) + 1, dim, dim), bool)
        chain = np.zeros((len(rows) + 1, dim), bool)
        for geometry, row in rows.items():
            body = plant.GetBodyFromFrameId(inspector.GetFrameId(geometry))
            _, _, centre, radius[row] = _centred(*_describe(inspector, geometry))
            frames.append((body, inspector.GetPoseInFrame(geometry).multiply(RigidTransform(centre))))
            # The joints from the geometry's body up: each one's coordinates move it about the axes above.
            moved = np.zeros(dim, bool)
            for joint in _chain(inboard, body.index()):
                below[row, joint.position_start() : joint.position_start() + joint.num_positions()] = moved
                moved[joint.position_start() : joint.position_start() + joint.num_positions()] = True
            chain[row] = moved
        slides = []
        for index in plant.GetJointIndices():
            joint = plant.get_joint(index)
            if joint.type_name() == "prismatic":
                frames.append((joint.child_body(), joint.frame_on_child().GetFixedPoseInBodyFrame()))
                axis = np.asarray(joint.translation_axis(), float)
                slides.append((len(frames) - 1, axis / np.linalg.norm(axis), joint.position_start()))
        kinematics = TreeKinematics.of(plant, frames)
        if kinematics is None:
            return None
        centres = np.zeros(len(rows), int)
        centres[list(rows.values())] = len(axes) + np.arange(len(rows))
        return cls(
            kinematics,
            np.array(axes).reshape(-1, 3),
            np.array(columns, int),
            centres,
            radius,
            below,
            rates,
            slides,
            chain,
        )

    def __call__(self, Q: np.ndarray) -> _Local:
        R, p = self._kinematics.poses(Q)
        n, count, dim, rows = len(Q), len(self._columns), self._rates.shape[1], len(self._radius)
        u = np.einsum("naij,aj->nai", R[:, :count], self._axes)[:, :, None, :]  # world axes (n, axes, 1, 3)
        v = p[:, None, self._centres] - p[:, :count, None]  # axis point to centre (n, axes, rows, 3)
        # u x v: the centre's velocity per unit turn of the axis; its length, the centre's distance from the axis.
        turn = np.stack(
            [
                u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1],
                u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2],
                u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0],
            ],
            axis=3,
        )
        levers = np.full((n, rows + 1, dim), np.inf)
        levers[:, :-1, self._columns] = np.sqrt((turn * turn).sum(axis=3)).transpose(0, 2, 1) + self._radius[:, None]
        # Per row and coordinate, the centre's velocity and the angular velocity per unit of it (the environment
        # row and the coordinates that do not move a row: 0).
        linear, angular = np.zeros((n, rows + 1, dim, 3)), np.zeros((n, rows + 1, dim, 3))
        moves = self._chain[:-1, self._columns].T[None, :, :, None]  # (1, axes, rows, 1)
        linear[:, :-1, self._columns] = (turn * moves).transpose(0, 2, 1, 3)
        angular[:, :-1, self._columns] = (u * moves).transpose(0, 2, 1, 3)
        for frame, axis, column in self._slides:
            linear[:, :-1, column] = (R[:, frame] @ axis)[:, None] * self._chain[None, :-1, column, None]
        return _Local(levers, linear, angular, np.append(self._radius, 0.0))

    def slack(self, variation: np.ndarray) -> np.ndarray:
        """How much each row's lever arm about each coordinate's axis can grow over a piece of motion (n, dim):
        what the coordinates between that axis and the geometry move the geometry's points, (n, rows, dim)."""
        moved = self._rates[None] * variation[:, None, :]  # (n, rows, k)
        return np.einsum("nrk,rjk->nrj", moved, self.below)


class _Local(NamedTuple):
    """A robot's kinematics at configurations (n): lever arms (see MotionBound.local), and per row (the environment's
    last) and coordinate, the velocity of the row's centre and the geometry's angular velocity per unit of the
    coordinate, (n, rows, dim, 3); the rows' radii about their centres."""

    levers: np.ndarray
    linear: np.ndarray
    angular: np.ndarray
    radius: np.ndarray

    def rows(self, k: np.ndarray) -> _Local:
        return _Local(self.levers[k], self.linear[k], self.angular[k], self.radius)

    def speed(self, velocity: np.ndarray) -> np.ndarray:
        """The largest speed of a point of each row's geometry, (n, rows), with the coordinates' velocities (n, dim)
        at these configurations: |v_c| + |w| rho."""
        v = np.einsum("nrjx,nj->nrx", self.linear, velocity)
        w = np.einsum("nrjx,nj->nrx", self.angular, velocity)
        return np.sqrt((v * v).sum(axis=2)) + np.sqrt((w * w).sum(axis=2)) * self.radius


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
            raise ValueError(
                f"joint '{joint.name()}' of type {kind}: the motion bound handles revolute, prismatic "
                "and weld joints only"
            )
        reach += slide + np.linalg.norm(joint.frame_on_parent().GetFixedPoseInBodyFrame().translation())
    return rates


def _coordinates(chain: list, dim: int) -> np.ndarray:
    """Which coordinates the joints of a chain own."""
    mask = np.zeros(dim, bool)
    for joint in chain:
        mask[joint.position_start() : joint.position_start() + joint.num_positions()] = True
    return mask


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
        return "vertices", hull_vertices(shape)
    raise ValueError(f"geometry '{inspector.GetName(geometry)}': no certificate for a {type(shape).__name__}")


def _centred(kind: str, data) -> tuple[str, object, np.ndarray, float]:
    """(kind, data, centre, radius) of a shape described about its centre, in its own frame: a mesh's vertices
    about the middle of their box (an obstacle piece is posed in the world frame, so about its frame's origin its
    bounding sphere would hold the world), other shapes about their frame's origin; radius: its farthest point."""
    from pydrake.math import RigidTransform

    centre = np.zeros(3)
    if kind == "vertices":
        centre = 0.5 * (data.min(axis=0) + data.max(axis=0))
        data = data - centre
    return kind, data, centre, _radius(kind, data, RigidTransform())


def _radius(kind: str, data, pose) -> float:
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


class _Gaps:
    """Lower bounds on the distance of the counted pairs whose distance Drake computes by GJK (see the module doc).

    Shapes as a box core (half sizes), a disc (radius, in the x-y plane) and a ball (radius) summed: a box is a
    core, a sphere a ball, a capsule a z segment and a ball, a cylinder a z segment and a disc -- one formula for the
    nearest point and for the support function of all four. A mesh (Drake uses its convex hull) is its hull's box in
    its own frame for nearest points and first bounds (the box holds the hull, so the distance to the box and its
    support are a lower and an upper bound of the hull's), and its hull's vertices where a bound must be tight.
    Ellipsoids are handled apart ("special").

    Tiers. Most rows need no tight bound: a row is settled by the first bound that reaches its `need` (how far
    apart the pair must be at this end for the pieces being certified, see Certifier._ends) or its `limit` (beyond
    which the pair is left out): bounding spheres, then each centre to the other shape, then the gaps along three
    directions with boxes for hulls, and only then the gaps of hull pairs with the hulls' vertices. Each is a lower
    bound of the distance, so a row keeps the largest it found."""

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
        self.keys = self.pairs[:, 0] * _KEY + self.pairs[:, 1]
        count = len(geometries)
        self.core, self.disc, self.ball = np.zeros((count, 3)), np.zeros(count), np.zeros(count)
        self.radius = np.zeros(count)  # about the shape's centre
        # A shape's centre in its own frame (see _centred), about which a mesh's vertices are kept.
        self.offset = np.zeros((count, 3))
        self.special = {}  # geometry index -> semi-axes of an ellipsoid
        hulls = {}  # geometry index -> a mesh hull's vertices (n, 3) about its centre
        for i in np.unique(self.pairs):
            kind, data, self.offset[i], self.radius[i] = _centred(*_describe(inspector, geometries[i]))
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

    def near(self, rotation, centre, nhat: np.ndarray, limit: np.ndarray, need: np.ndarray) -> tuple[np.ndarray, ...]:
        """(configurations, pairs, bounds): the rows (configuration k, pair) whose lower bound is below limit[k],
        and their bounds, given the shapes' poses -- rotation(k, g) (n, 3, 3) and centre(k, g) (n, 3; the shape's
        centre, see offset) of geometries g in configurations k (index arrays) -- Drake's direction from b to a where
        it reported the pair in that configuration (nhat (configurations, pairs, 3), else NaN), and the distance
        that settles each row (need (configurations, pairs)). All configurations are done at once."""
        k = np.repeat(np.arange(len(limit)), len(self.pairs))
        pair = np.tile(np.arange(len(self.pairs)), len(limit))
        bounds = self.bounds(k, pair, rotation, centre, nhat.reshape(-1, 3), limit[k], need.ravel())
        below = np.flatnonzero(bounds < limit[k])
        return k[below], pair[below], bounds[below]

    def bounds(self, k, pair, rotation, centre, nhat, limit, need) -> np.ndarray:
        """Lower bounds on the distance of rows (configuration k, pair) (see near), each at least as large as the
        first tier's that reached min(need, limit) of the row; nhat, limit and need per row."""
        a, b = self.pairs[pair].T
        pa, pb = centre(k, a), centre(k, b)
        settle = np.minimum(need, limit)
        # Bounding spheres; then from a's centre to shape b, and the other way, on the rows left.
        bound = _norm(pa - pb) - self.radius[a] - self.radius[b]
        live = np.flatnonzero(bound < settle)
        B = self._posed(b[live], rotation(k[live], b[live]), pb[live])
        bound[live] = np.maximum(bound[live], self._distance_to(B, pa[live]) - self.radius[a[live]])
        keep = np.flatnonzero(bound[live] < settle[live])
        live, B = live[keep], _rows(B, keep)
        A = self._posed(a[live], rotation(k[live], a[live]), pa[live])
        bound[live] = np.maximum(bound[live], self._distance_to(A, B.p) - B.radius)
        keep = np.flatnonzero(bound[live] < settle[live])
        live, A, B = live[keep], _rows(A, keep), _rows(B, keep)
        bound[live] = np.maximum(bound[live], self._gap(A, B, nhat[live], settle[live]))
        return bound

    def along(self, k, pair, rotation, centre, d: np.ndarray) -> np.ndarray:
        """The gaps of rows (configuration k, pair) along directions d (unit, from the pair's second shape to its
        first), hulls by their vertices: a lower bound on each row's distance (see bounds for rotation and centre)."""
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
    """Shapes of the gaps' pairs, one a row, posed: rotation, centre, and their _Gaps parameters."""

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


# Per shared oracle, what its certifiers all use, made once: {kind: object}; gone with the oracle.
_per_oracle: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _shared(oracle, kind: str, make):
    made = _per_oracle.setdefault(oracle, {})
    if kind not in made:
        made[kind] = make()
    return made[kind]


def _gaps(oracle, geometries: list, robot: np.ndarray, exact: np.ndarray) -> _Gaps:
    """The shared oracle's _Gaps, made once per oracle (its hulls' support tables fill as they are used)."""
    return _shared(oracle, "gaps", lambda: _Gaps(oracle, geometries, robot, exact))


def motion_bound(oracle) -> MotionBound:
    """The shared oracle's MotionBound, computed once per oracle."""
    return _shared(oracle, "motion bound", lambda: MotionBound(oracle))


class Certifier:
    """Certifies pieces of motion on one checker's oracle, keeping the distances it has asked for across calls (and
    across queries: a caller may hand it another query's checker, whose `distance_queries` it then counts in).

    Each interval's pieces are cut nearest to contact first: the parts of a piece that failed its test go by the
    distance at its ends, interpolated to each part's middle (the parts beside its nearer end first), the leftmost
    first among equals. Whether an interval is proved does not
    depend on the order (every piece of its subdivision must pass), but a failing interval stops at its first
    failure, and this order dives to where the motion comes nearest an obstacle, where leftmost first would prove
    everything before it (a factor of several in distance queries on a grazing edge: benchmark pages).
    WIDTH pieces of every interval (more where few intervals are left: ROUND_MIN) are taken at a time and their
    ends bounded together: Drake is asked per configuration, but the gaps (numpy) run once over all those
    configurations and pairs, where one configuration at a time spent most of its time in numpy's call overhead."""

    # Pieces taken from each interval at a time: more batches more, but may do more work past a failure.
    WIDTH = 16
    # A failing piece is cut into as many equal parts as its ends' distances fall short of its bound, at least 2 and
    # at most SPLIT_MAX: the parts then pass if the distances in between are like those at its ends, in one round
    # where halving would take several (fewer rounds and fewer queries than halving: benchmark pages).
    SPLIT_MAX = 8
    # Before the first round an interval is cut into pieces of at most FIRST_PIECE x the resolution (weighted
    # metric). A round costs a fixed part besides its distance queries, and a longer piece seldom passes whole: on
    # cell queries this asked 15-20 % more queries in about half the rounds, for a quarter less time (benchmark
    # pages).
    FIRST_PIECE = 4
    # A round takes more than WIDTH pieces of an interval when fewer than ROUND_MIN would be taken in all (a single
    # straight move otherwise needs a round per WIDTH of its pieces), unless a piece of that interval fell short by
    # CLOSING or more in the round before: it may be closing on a contact, and a failing interval stops at its
    # first failure, so it keeps to WIDTH pieces nearest to contact.
    ROUND_MIN = 64
    CLOSING = 4

    # Most (configuration, pair) rows one call to the gaps works on, to keep its arrays small.
    BATCH_ROWS = 1 << 17

    def __init__(self, checker: Checker, floor: float | None = None):
        from pydrake.geometry import Role

        clock = time.perf_counter()
        oracle = checker.oracle
        self.checker = checker
        self.bound = motion_bound(oracle)
        self.floor = floor if floor is not None else oracle.space.resolution / FLOOR_DIVISOR
        self._cache = {}  # configuration bytes -> _End, or None where it collides
        self._rounding = 1e-9 * oracle.space.resolution
        inspector = oracle.model.scene_graph().model_inspector()
        geometries = inspector.GetAllGeometryIds(Role.kProximity)
        # A small integer per geometry, for pair keys, by the GeometryId's value (cheaper to hash than the id).
        self._index_of_value = {g.get_value(): i for i, g in enumerate(geometries)}
        self._ids = list(geometries)
        self._rows = np.array([self.bound.row(g) for g in geometries], np.int64)  # -1: environment
        kinds = [type(inspector.GetShape(g)).__name__ for g in geometries]
        self._exact = np.array([[frozenset((a, b)) in _EXACT for b in kinds] for a in kinds], bool)
        self._gaps = _gaps(oracle, geometries, self._rows >= 0, self._exact)
        # Whether Drake's pairwise query is asked, for every pair within the limit with its direction: where a
        # counted pair is of a kind Drake computes exactly (its distance is used). Otherwise most pairs are settled
        # by our bounds alone, and Drake is asked for the direction of the others, one pair at a time, and where a
        # bound comes out at or below 0 whether anything is in contact (see the module doc and _ends).
        robot = self._rows >= 0
        counted = np.triu(robot[:, None] | robot[None, :], 1) & self._exact
        if not oracle.scene.self_collisions:
            counted &= ~(robot[:, None] & robot[None, :])
        self._ask_all = any(
            not inspector.CollisionFiltered(geometries[i], geometries[j]) for i, j in zip(*np.nonzero(counted))
        )
        # Pieces that certainly fail are cut unasked where asking costs most: on mesh scenes (see _certain_shortfall).
        self._cut_unasked = not self._ask_all and bool(self._gaps.hulls)
        # The direction Drake last gave for each pair of the gaps (world frame), NaN before it gave one.
        self._recent = np.full((len(self._gaps.pairs), 3), np.nan)
        # Shape poses for the gaps: the environment's never change; the robot's are taken per configuration, in
        # robot slots (slot -1: environment).
        self._robot = [g for i, g in enumerate(geometries) if self._rows[i] >= 0]
        self._slot = np.full(len(geometries), -1)
        self._slot[self._rows >= 0] = np.arange(len(self._robot))
        plant = oracle.plant
        self._kinematics = TreeKinematics.of(
            plant,
            [(plant.GetBodyFromFrameId(inspector.GetFrameId(g)), inspector.GetPoseInFrame(g)) for g in self._robot],
            oracle.scene.position_map,
        )
        query = oracle.query_object(oracle.scene.start)
        poses = [query.GetPoseInWorld(g) for g in geometries]
        self._R = np.array([X.rotation().matrix() for X in poses]).reshape(-1, 3, 3)
        self._p = np.array([X.translation() for X in poses]).reshape(-1, 3)
        # A point inside each shape, in its frame (its centre; a hull's mean vertex), and in the world for the
        # environment's.
        self._inside = self._gaps.offset.copy()
        for i, vertices in self._gaps.hulls.items():
            self._inside[i] += vertices.mean(axis=0)
        self._anchors = self._p + np.einsum("gij,gj->gi", self._R, self._inside)
        self._centres = self._p + np.einsum("gij,gj->gi", self._R, self._gaps.offset)
        self.seconds = time.perf_counter() - clock  # all this certifier's work: set-up, then every certify()

    def certify(self, curve, intervals, clearance=0.0, floor=None) -> tuple[bool, dict]:
        """Whether the curve keeps at least `clearance` (0: is free; one for all intervals or one per interval)
        from everything over each interval (s0, s1) of `intervals`: every pair's bound on a piece is taken
        2 x clearance larger, so that d(a) + d(b) > B + 2c leaves d >= c all along (see the module doc). floor: how
        short a failing piece may be cut before its interval fails (one for all or one per interval; default the
        certifier's), for a caller with a cheaper way round a failure than proving it finer.

        The curve (a Motion, or any object with the same methods) gives position(s), and variation(s0, s1), a bound
        on each coordinate's travel between s0 and s1, for s0 < s1 within one interval; and, if it has them,
        derivatives(s0, s1): the velocity dq/ds at s0 and at s1 and a bound on |d2q/ds2| between them, each
        coordinate's (then pieces are also bounded from the motion itself: MotionBound.pair_travel_along). All
        take arrays of s, (n,), and give rows, (n, dim): a round asks for all its pieces in one call.
        The curve must stay within the space's bounds between in-bound ends (a straight edge or a blend does).
        stats: failed (indices of intervals not certified), pieces (certified), distance_queries, seconds.
        """
        position, variation = curve.position, curve.variation
        derivatives = getattr(curve, "derivatives", None)
        clock, queries = time.perf_counter(), self.checker.distance_queries
        # Per interval, a heap of its pieces still to prove, as (distance at the ends of the piece they halve, start,
        # end): nearest to contact first.
        intervals = np.array(list(intervals), float).reshape(-1, 2)
        margins = 2 * np.broadcast_to(np.asarray(clearance, float), (len(intervals),))
        floors = np.broadcast_to(np.asarray(self.floor if floor is None else floor, float), (len(intervals),))
        heaps = {}
        if len(intervals):
            space = self.checker.space
            length = np.linalg.norm(variation(intervals[:, 0], intervals[:, 1]) * space.weights, axis=1)
            parts = np.ceil(length / (self.FIRST_PIECE * space.resolution)).clip(1, None).astype(int)
            for i, ((a, b), n) in enumerate(zip(intervals.tolist(), parts.tolist())):
                heaps[i] = [(0.0, s0, s1) for s0, s1 in itertools.pairwise(_cuts(a, b, n))]
        failed, pieces = [], 0
        closing: set[int] = set()  # intervals with a piece that fell CLOSING short or more in the last round
        while heaps:
            wide = max(self.WIDTH, math.ceil(self.ROUND_MIN / len(heaps)))
            todo = [
                (i, heapq.heappop(heap)[1:])
                for i, heap in heaps.items()
                for _ in range(min(self.WIDTH if i in closing else wide, len(heap)))
            ]
            spans = np.array([ab for _, ab in todo])
            variations = variation(spans[:, 0], spans[:, 1]).reshape(len(todo), -1)
            ends = list(dict.fromkeys(s for _, ab in todo for s in ab))
            slot = {s: j for j, s in enumerate(ends)}
            by_end = np.array([slot[s] for _, ab in todo for s in ab])  # piece p's ends are rows 2p and 2p + 1
            Q = position(np.array(ends))
            local = self.bound.local(Q)
            if local is None:
                travel = self.bound.pair_travel(variations)
            else:
                at_a, at_b = local.rows(by_end[0::2]), local.rows(by_end[1::2])
                rates = self.bound.piece_rates(variations, at_a.levers, at_b.levers)
                travel = self.bound.pair_travel_of(variations, rates)
                if derivatives is not None:  # both bounds hold: the lesser (per unit of tau = (s - s0) / span)
                    span = (spans[:, 1] - spans[:, 0])[:, None]
                    da, db, dd = derivatives(spans[:, 0], spans[:, 1])
                    along = self.bound.pair_travel_along(rates, at_a, at_b, da * span, db * span, dd * span**2)
                    travel = np.minimum(travel, along)
            travel = travel + margins[[i for i, _ in todo]][:, None, None]
            # A piece whose pairs are certainly too near at its ends for its bound fails whatever their distances: it
            # is cut unasked, into as many parts as it certainly falls short (its ends are asked as its parts' ends).
            certain = self._certain_shortfall(Q, by_end, travel)
            # Each end of the other pieces is asked at the largest max_distance of the pieces it bounds, and each pair
            # there is bounded until it reaches the largest of its bounds on those pieces (shared ends once).
            rows = np.flatnonzero(np.repeat(certain <= 1.0, 2))
            rows = rows[np.argsort(by_end[rows], kind="stable")]
            ordered = by_end[rows]
            first = np.flatnonzero(np.concatenate([[len(rows) > 0], ordered[1:] != ordered[:-1]]))
            asked = by_end[rows[first]]
            limits, need = np.zeros(0), None
            if len(rows):
                pairs = self._rows[self._gaps.pairs]
                limits = np.maximum.reduceat(np.repeat(self.bound.max_distance(travel), 2)[rows], first)
                if not self._ask_all:  # where Drake's query is cheap, settling pairs early saves nothing measurable
                    need = _largest_by_group(travel[rows // 2][:, pairs[:, 0], pairs[:, 1]], first)
            found = self._distances(list(Q[asked]), limits.tolist(), need)
            asked = [ends[j] for j in asked.tolist()]
            ends = dict(zip(asked, found))
            lengths = np.linalg.norm(variations * self.checker.space.weights, axis=1)
            clear, short = _clear([ends.get(a) for _, (a, b) in todo], [ends.get(b) for _, (a, b) in todo], travel)
            parts = np.clip(np.ceil(np.maximum(short, certain)), 2, self.SPLIT_MAX).astype(int)
            doomed = (certain > 1.0).tolist()
            far = (np.maximum(short, certain) >= self.CLOSING).tolist()
            closing = {i for (i, _), f in zip(todo, far) if f}
            for (i, (a, b)), passed, length, n, unasked in zip(
                todo, clear.tolist(), lengths.tolist(), parts.tolist(), doomed
            ):
                if i not in heaps:
                    continue
                if passed:
                    pieces += 1
                elif length <= floors[i] or not unasked and (ends[a] is None or ends[b] is None):
                    failed.append(i)
                    del heaps[i]
                else:
                    near_a, near_b = (0.0, 0.0) if unasked else (ends[a].nearest(), ends[b].nearest())
                    for j, (s0, s1) in enumerate(itertools.pairwise(_cuts(a, b, n))):
                        heapq.heappush(heaps[i], (near_a + (near_b - near_a) * (j + 0.5) / n, s0, s1))
            heaps = {i: heap for i, heap in heaps.items() if heap}
        stats = {
            "failed": sorted(failed),
            "pieces": pieces,
            "distance_queries": self.checker.distance_queries - queries,
            "seconds": time.perf_counter() - clock,
        }
        self.seconds += stats["seconds"]
        return not failed, stats

    def _certain_shortfall(self, Q: np.ndarray, by_end: np.ndarray, travel: np.ndarray) -> np.ndarray:
        """Per piece (ends Q[by_end[2p]] and Q[by_end[2p + 1]], pair bounds travel[p]), a factor by which its bound
        certainly exceeds its ends' distances for some pair of the gaps: the largest B_PQ / (U_a + U_b), with U an
        upper bound on the pair's distance at an end -- the distance between a point inside each shape (its centre,
        a hull's mean vertex). Our lower bounds are at most U, so a piece with a factor above 1 fails its test, and
        by at least that factor (0 without pairs, and where pieces are not cut unasked)."""
        if not self._cut_unasked or not len(self._gaps.pairs):
            return np.zeros(len(travel))
        rotations, centres = self._robot_poses(Q)
        anchors = np.repeat(self._anchors[None], len(Q), axis=0)
        anchors[:, self._slot >= 0] = centres + np.einsum("nrij,rj->nri", rotations, self._inside[self._slot >= 0])
        a, b = self._gaps.pairs.T
        upper = np.linalg.norm(anchors[:, a] - anchors[:, b], axis=2)  # (ends, pairs)
        bound = travel[:, self._rows[a], self._rows[b]]  # (pieces, pairs)
        return (bound / np.maximum(upper[by_end[0::2]] + upper[by_end[1::2]], 1e-300)).max(axis=1)

    def distances(self, q: np.ndarray, max_distance: float, pair_travel: np.ndarray | None = None) -> dict | None:
        """The distances the certificate uses at q, {frozenset of the pair's two GeometryIds: distance}, for the
        pairs closer than max_distance (those left out are at least that far apart); None if q collides. With
        pair_travel (rows, rows: the pieces' bounds, see _distances) a pair's bound stops where it reaches that."""
        pairs = self._rows[self._gaps.pairs]
        need = None if pair_travel is None else pair_travel[None, pairs[:, 0], pairs[:, 1]]
        end = self._distances([q], [max_distance], need)[0]
        if end is None:
            return None
        return {
            frozenset((self._ids[k // _KEY], self._ids[k % _KEY])): d
            for k, d in zip(end.keys.tolist(), end.distance.tolist())
        }

    def _distances(self, Q: list, limits: list, pair_travel: np.ndarray | None = None) -> list:
        """For each configuration, the pairs within its limit (an _End), from the cache when it was asked at a
        limit at least as large; None if it collides or lies outside the bounds. pair_travel[k, pair] (pairs of the
        gaps): the largest bound on the pair's change over the pieces configuration k ends; a pair's lower bound
        that reaches it at this end is enough for those pieces, given any positive one at their other end (so no
        tighter bound is sought); without it every pair below the limit is bounded as tightly as the certificate
        can."""
        keys = [np.asarray(q, float).tobytes() for q in Q]
        todo = []
        for k, (key, q, limit) in enumerate(zip(keys, Q, limits)):
            cached = self._cache.get(key, False)
            if cached is False or (cached is not None and cached.limit < limit):
                todo.append((key, np.asarray(q, float), limit, None if pair_travel is None else pair_travel[k]))
        per_batch = max(1, self.BATCH_ROWS // max(1, len(self._gaps.pairs)))
        for first in range(0, len(todo), per_batch):
            self.checker.poll()  # a proof keeps to its query's time limit (among many pieces a batch is dear)
            self._ends(todo[first : first + per_batch])
        return [self._cache[key] for key in keys]

    def _ends(self, todo: list) -> None:
        """Into the cache: the certificate's distances at each (key, q, limit, pair travel) of `todo` -- Drake's for
        the pairs it computes exactly, our lower bound for the others (a pair left out is at least `limit` apart);
        None where q is out of bounds or in contact."""
        for key, *_ in todo:
            self._cache[key] = None
        inside = self.checker.space.within_bounds(np.array([q for _, q, *_ in todo]))
        todo = [item for item, keep in zip(todo, inside.tolist()) if keep]
        # Drake's pairs of every configuration as rows (configuration, first, second geometry, distance); reading a
        # GeometryId costs more than the distance, so each is read once and mapped through its integer value.
        # Without the pairwise query Drake is asked nothing yet: where every pair's lower bound comes out positive
        # nothing touches, and only a configuration with a bound at or below 0 is asked about contact (at the end).
        if self._ask_all:
            answers = [self.checker.signed_distances(q, limit) for _, q, limit, _ in todo]
        else:
            answers = [[] for _ in todo]
            self.checker.count_bounded(len(todo))
        value = self._index_of_value
        found = np.array(
            [(value[p.id_A.get_value()], value[p.id_B.get_value()], p.distance) for pairs in answers for p in pairs],
            float,
        ).reshape(-1, 3)
        config = np.repeat(np.arange(len(answers)), [len(pairs) for pairs in answers])
        touching = np.unique(config[found[:, 2] <= 0])
        kept = np.setdiff1d(np.arange(len(answers)), touching)
        if not len(kept):
            return
        # Renumber the configurations left, 0..len(kept)-1.
        renumber = np.full(len(answers), -1)
        renumber[kept] = np.arange(len(kept))
        position = np.flatnonzero(renumber[config] >= 0)
        config, found = renumber[config[position]], found[position]
        index = found[:, :2].astype(np.int64)
        swapped = index[:, 0] > index[:, 1]
        index.sort(axis=1)  # a pair is the same whichever geometry Drake names first
        keys = index[:, 0] * _KEY + index[:, 1]
        exact = self._exact[index[:, 0], index[:, 1]]
        # Drake's separating directions, for the pairs of the gaps only.
        flat = [p for pairs in answers for p in pairs]
        directions = np.array([flat[j].nhat_BA_W for j in position[~exact].tolist()], float).reshape(-1, 3)
        nhat = self._directions(len(kept), config[~exact], keys[~exact], swapped[~exact], directions)
        if not self._ask_all:  # Drake's directions for the pairs it reported, kept for the rows it did not
            reported = np.isfinite(nhat[:, :, 0])
            last = len(nhat) - 1 - reported[::-1].argmax(axis=0)  # the last configuration that reported each pair
            pairs = np.flatnonzero(reported.any(axis=0))
            self._recent[pairs] = nhat[last[pairs], pairs]
        drake = [todo[k] for k in kept.tolist()]
        limits = np.array([limit for _, _, limit, _ in drake])
        Q = np.array([q for _, q, _, _ in drake])
        # What settles each pair (see _distances): its bound over the pieces, with room for the rounding allowance.
        if drake[0][3] is None:
            need = np.repeat(limits[:, None], len(self._gaps.pairs), axis=1)
        else:
            need = np.array([travel for *_, travel in drake]).reshape(len(drake), -1)
        need = need * _MARGIN + 2 * self._rounding + 1e-12

        # One table of poses, the environment's then each configuration's robot geometries.
        # Centres are the shapes' (see _Gaps.offset), not their frames' origins.
        rotations, centres = self._robot_poses(Q)
        centres = centres + np.einsum("nrij,rj->nri", rotations, self._gaps.offset[self._slot >= 0])
        rotations = np.concatenate([self._R, rotations.reshape(-1, 3, 3)])
        centres = np.concatenate([self._centres, centres.reshape(-1, 3)])
        slot, count, robots = self._slot, len(self._slot), len(self._robot)

        def row(k, g):
            return np.where(slot[g] >= 0, count + k * robots + slot[g], g)

        def rotation(k, g):
            return rotations[row(k, g)]

        def centre(k, g):
            return centres[row(k, g)]

        near_k, near_pair, bounds = self._gaps.near(rotation, centre, nhat, limits, need)
        # A pair Drake's query left out is farther apart than the limit by Drake's reckoning, but without Drake's
        # direction our bound can fall far below that: alternating projections converge slowly between long shapes
        # side by side (the UR3's upper arm and torch 9.8 mm apart were bounded at -2.4 mm), and such a pair fails
        # every piece down to the floor. So those pairs not settled are bounded again: along the direction Drake
        # last gave for the pair (ends of one motion are near each other, and any direction gives a lower bound),
        # then, where that is not enough either, along Drake's direction for the pair alone.

        def tighten(rows, directions):
            """Bound rows again along these directions; the rows still not settled."""
            k, pair = near_k[rows], near_pair[rows]
            bounds[rows] = np.maximum(bounds[rows], self._gaps.along(k, pair, rotation, centre, directions))
            return rows[bounds[rows] < need[k, pair]]

        rows = np.flatnonzero(np.isnan(nhat[near_k, near_pair, 0]) & (bounds < need[near_k, near_pair]))
        known = np.isfinite(self._recent[near_pair[rows], 0]) if not self._ask_all else np.zeros(len(rows), bool)
        if known.any():
            rows = np.concatenate([tighten(rows[known], self._recent[near_pair[rows[known]]]), rows[~known]])
        if len(rows):
            asked = np.empty((len(rows), 3))
            for k in np.unique(near_k[rows]).tolist():
                mine = np.flatnonzero(near_k[rows] == k)
                pairs = self._gaps.pairs[near_pair[rows[mine]]].tolist()
                replies = self.checker.pair_distances(Q[k], [(self._ids[i], self._ids[j]) for i, j in pairs])
                for r, (i, _), answer in zip(mine.tolist(), pairs, replies):
                    # Drake's direction from the pair's second geometry to its first, in our order.
                    direction = answer.nhat_BA_W if answer.id_A == self._ids[i] else -answer.nhat_BA_W
                    asked[r] = self._recent[near_pair[rows[r]]] = direction
            tighten(rows, asked)
        # A configuration in contact stays None: its pieces fail at once (a bound at or below 0 could only fail them
        # by cutting them down to the floor).
        doubtful = np.unique(near_k[bounds <= 0]).tolist()
        in_contact = {k for k in doubtful if self.checker.in_contact(Q[k])}
        # Every configuration's distances -- Drake's exact ones and our bounds below the limit -- sorted by
        # configuration, then key.
        below = bounds < limits[near_k]
        near_k, near_pair, bounds = near_k[below], near_pair[below], bounds[below]
        config = np.concatenate([config[exact], near_k])
        index = np.concatenate([index[exact], self._gaps.pairs[near_pair]])
        keys = np.concatenate([keys[exact], self._gaps.keys[near_pair]])
        distance = np.concatenate([found[exact, 2], bounds]) - self._rounding
        order = np.lexsort((keys, config))
        rows = self._rows[index[order]]
        split = np.cumsum(np.bincount(config, minlength=len(drake)))[:-1]
        parts = zip(*(np.split(array, split) for array in (keys[order], distance[order], rows[:, 0], rows[:, 1])))
        for k, ((key, _, limit, _), part) in enumerate(zip(drake, parts)):
            if k not in in_contact:
                self._cache[key] = _End(limit, *part)

    def _robot_poses(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotations (n, robots, 3, 3) and centres (n, robots, 3) of the robot geometries at configurations Q."""
        if self._kinematics is not None:
            return self._kinematics.poses(Q)
        rotations, centres = [], []
        for q in Q:
            query = self.checker.oracle.query_object(q)
            poses = [query.GetPoseInWorld(g) for g in self._robot]
            # Copied now: Drake's poses are views into the query's cache, which the next configuration overwrites.
            rotations.append(np.array([X.rotation().matrix() for X in poses]))
            centres.append(np.array([X.translation() for X in poses]))
        return np.reshape(rotations, (len(Q), -1, 3, 3)), np.reshape(centres, (len(Q), -1, 3))

    def _directions(self, configurations: int, config, keys, swapped, directions) -> np.ndarray:
        """Drake's separating directions (nhat_BA_W) of the GJK-kind pairs it reported -- rows of (configuration,
        pair key, whether Drake named the pair's geometries the other way round, direction) -- as (configurations,
        pairs of the gaps, 3), turned to point from the pair's second geometry to its first in our order; NaN where
        not reported."""
        at = np.searchsorted(self._gaps.keys, keys)  # the gaps' keys are sorted (pairs in lexicographic order)
        if np.any(at >= len(self._gaps.keys)) or np.any(self._gaps.keys[at.clip(max=len(self._gaps.keys) - 1)] != keys):
            raise RuntimeError("Drake reported a pair the certificate does not count (collision policy mismatch)")
        nhat = np.full((configurations, len(self._gaps.keys), 3), np.nan)
        nhat[config, at] = np.where(swapped[:, None], -1.0, 1.0) * directions
        return nhat


def _cuts(a: float, b: float, n: int) -> list[float]:
    """a, b and the points that cut [a, b] into n equal parts, in order."""
    return [a, *(a + (b - a) * j / n for j in range(1, n)), b]


class _End(NamedTuple):
    """Distances at one end of a piece: the pairs within `limit`, by key, sorted."""

    limit: float
    keys: np.ndarray
    distance: np.ndarray
    row_a: np.ndarray
    row_b: np.ndarray

    def nearest(self) -> float:
        """The least distance of a pair here (the limit if none is reported)."""
        return min(float(self.distance.min()), self.limit) if len(self.distance) else self.limit


def _largest_by_group(values: np.ndarray, first: np.ndarray) -> np.ndarray:
    """The largest row of each group of consecutive rows of `values` (groups start at `first`), elementwise; as
    np.maximum.reduceat, which is slow on 2-d arrays, where groups here have one or two rows (an end bounds the
    pieces either side of it)."""
    size = np.diff(first, append=len(values))
    largest = values[first]
    for j in range(1, int(size.max(initial=1))):
        more = np.flatnonzero(size > j)
        largest[more] = np.maximum(largest[more], values[first[more] + j])
    return largest


def _clear(ends_a: list, ends_b: list, pair_travel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The certificate for pieces (ends a[p], b[p], pair bounds pair_travel[p]), all at once: whether every pair
    reported at either end of a piece is farther apart, summed over the two ends, than its distance can change (a pair
    an end does not report is at least that end's limit apart; False where an end is None: it collides), and by what
    factor the worst pair's bound exceeds its two distances (1 where none does, or an end collides)."""
    ok = np.array([a is not None and b is not None for a, b in zip(ends_a, ends_b)], bool)
    short = np.ones(len(ok))
    if not ok.any():
        return ok, short
    # The distinct ends, and per piece which of them it joins.
    slots, table = {}, []
    for end in itertools.chain(ends_a, ends_b):
        if end is not None and id(end) not in slots:
            slots[id(end)] = len(table)
            table.append(end)
    pieces = np.flatnonzero(ok)
    a = np.array([slots[id(ends_a[p])] for p in pieces.tolist()], np.int64)
    b = np.array([slots[id(ends_b[p])] for p in pieces.tolist()], np.int64)
    counts = np.array([len(end.keys) for end in table], np.int64)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    keys = np.concatenate([end.keys for end in table])
    distance = np.concatenate([end.distance for end in table])
    row_a = np.concatenate([end.row_a for end in table])
    row_b = np.concatenate([end.row_b for end in table])
    limit = np.array([end.limit for end in table])
    # Keys of every end in one sorted array: each end's keys are sorted, and ends follow in slot order.
    span = int(keys.max()) + 1 if len(keys) else 1
    tagged = np.repeat(np.arange(len(table), dtype=np.int64), counts) * span + keys
    failures, shortfall = np.zeros(len(pieces), np.int64), np.ones(len(pieces))
    for this, other in ((a, b), (b, a)):
        # Every pair `this` end of each piece reports, with its distance at the `other` end (or that end's limit).
        piece = np.repeat(np.arange(len(pieces)), counts[this])
        row = (
            first[this][piece] + np.arange(len(piece)) - np.repeat(np.cumsum(counts[this]) - counts[this], counts[this])
        )
        wanted = other[piece] * span + keys[row]
        at = np.searchsorted(tagged, wanted).clip(max=max(len(tagged) - 1, 0))
        found = tagged[at] == wanted if len(tagged) else np.zeros(len(wanted), bool)
        there = np.where(found, distance[at], limit[other[piece]])
        bound = pair_travel[pieces[piece], row_a[row], row_b[row]]
        failures += np.bincount(piece[distance[row] + there <= bound], minlength=len(pieces))
        np.maximum.at(shortfall, piece, bound / np.maximum(distance[row] + there, 1e-300))
    ok[pieces] = failures == 0
    short[pieces] = shortfall
    return ok, short


class Motion(NamedTuple):
    """A curve for Certifier.certify: position(s), variation(s0, s1) and derivatives(s0, s1) (see there)."""

    position: object
    variation: object
    derivatives: object = None


def certify_curve(oracle, curve, knots, floor: float | None = None, clearance: float = 0.0) -> tuple[bool, dict]:
    """Certify the curve (see Certifier.certify) over [knots[0], knots[-1]], its variation and derivatives holding
    between two consecutive knots. stats["failed"]: indices of the knot intervals that failed."""
    knots = np.asarray(knots, float)
    return Certifier(oracle, floor).certify(curve, itertools.pairwise(knots), clearance)


def polyline(space, P: np.ndarray) -> Motion:
    """The polyline P (straight edges, the short way) with parameter s = i + t on edge i."""
    return straight_edges(space.unwrap(P), np.arange(len(P), dtype=float))


def straight_edges(W: np.ndarray, knots: np.ndarray) -> Motion:
    """The polyline W (unwrapped: straight from each waypoint to the next) with edge i running from s = knots[i] to
    knots[i + 1] (increasing)."""
    rate = np.diff(W, axis=0) / np.diff(knots)[:, None]

    def edge(s: np.ndarray) -> np.ndarray:
        return np.clip(np.searchsorted(knots, s, side="right") - 1, 0, len(rate) - 1)

    def position(s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, float)
        i = edge(s)
        return W[i] + (s - knots[i])[:, None] * rate[i]

    def variation(s0: np.ndarray, s1: np.ndarray) -> np.ndarray:
        s0, s1 = np.asarray(s0, float), np.asarray(s1, float)
        return np.abs(rate[edge(0.5 * (s0 + s1))]) * (s1 - s0)[:, None]

    def derivatives(s0: np.ndarray, s1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        velocity = rate[edge(0.5 * (np.asarray(s0, float) + np.asarray(s1, float)))]
        return velocity, velocity, np.zeros_like(velocity)

    return Motion(position, variation, derivatives)


def certify_path(oracle, P: np.ndarray, floor: float | None = None, clearance: float = 0.0) -> tuple[bool, dict]:
    """Certify that every straight edge of the polyline P (in oracle.space) keeps at least `clearance` from
    everything (0: is free). stats["failed"]: the edges that failed."""
    P = np.atleast_2d(np.asarray(P, float))
    if len(P) < 2:
        P = np.vstack([P, P])
    return certify_curve(oracle, polyline(oracle.space, P), np.arange(len(P)), floor, clearance)
