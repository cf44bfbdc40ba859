"""How far a robot geometry can move along a piece of motion: the motion bound the certificate (app.checking.certify)
weighs the distances at a piece's ends against.

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

A second bound starts from the motion itself (MotionBound.piece_bounds): at each end of a piece, the speed of
g's points from its centre's velocity and its angular velocity (a Jacobian product, in which joints turning the arm
both ways cancel, where the sum above adds them up), plus how much that speed can change along the piece (products
of the joints' rates and speeds, and the curve's own acceleration). Both hold; each pair takes the lesser. On the
UR3 the travel bound was 1.6 times the farthest any point moved at the median over cell queries' pieces.

Relative motion. Two robot geometries' distance is the same measured in the frame of the last body their chains
to the world share, where only the joints below it move them: for such a pair the bound B_PQ sums the two rates
over the coordinates of the joints the chains do not share (the cart and the shoulder never bring the wrist nearer
the upper arm). For a robot-environment pair, B_PQ = B_P.
"""

from __future__ import annotations

import weakref
from types import SimpleNamespace
from typing import NamedTuple

import numpy as np

from app.checking.kinematics import TreeKinematics
from app.checking.shape_gaps import centred_shape, describe_shape, shape_radius

# max_distance slightly above half the largest pair bound, so an unreported pair passes strictly.
MAX_DISTANCE_MARGIN = 1.0 + 1e-6
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
                    rates.append(_rates(chain, shape_radius(*describe_shape(inspector, geometry), pose), space))
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
        # Where a pair's rates count a coordinate (shared: 0), as (rows, coordinates, rows) for batched products;
        # symmetric in the two rows, as pair_rates is.
        self._unshared = (self.pair_rates > 0).astype(float).transpose(0, 2, 1).copy()
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

    def piece_bounds(self, variation: np.ndarray, local: _Local, end_a, end_b, derivatives=None) -> tuple:
        """Bounds (n, rows, rows) on how much each pair's distance changes along n pieces of motion, and the rates
        (n, rows, dim) that hold all along them: piece p moves coordinate j by at most variation[p, j] between the
        configurations end_a[p] and end_b[p] of `local`. derivatives: (da, db, dd), each (n, dim), the curve's
        velocity at the pieces' ends and a bound on its acceleration, per unit of a parameter tau running from 0 to
        1 along each piece; with them each pair takes the lesser of the two bounds (see the module doc).

        Rates: a revolute joint moves a geometry's points at most its lever arm per radian, and along the piece that
        arm grows by no more than the joints between the axis and the geometry move its points (a joint's own turn
        does not change it), so each end's lever plus that growth bounds the arm -- the lesser of the two ends',
        and never more than the rate anywhere in the space. The travel sums them over the coordinates the pair
        counts.

        The bound from the motion itself: at an end, a point x of a geometry moves at |v_c + w x (x - c)| <= |v_c| +
        |w| rho (centre c, radius rho about it), and along the piece its speed changes at most M = sum_j rates_j
        (|q_j'| (|q_j'| [j revolute] + 2 sum_{k revolute, inboard of j} |q_k'|) + |q_j''|) per unit of tau -- the
        derivative of joint j's column of the Jacobian along joint k is w_k x J_j for k inboard of or at j and
        w_j x J_k outboard of it, each at most the outboard one's rate. So by tau a point has moved at most tau V_a
        + tau^2 M / 2 <= tau (V_a + M / 2) from end a, and as much the other way from end b: two points (one per
        geometry) move their distance by at most the larger of the two sums. Joints that turn the arm both ways
        about parallel axes (the UR3's shoulder, elbow and wrist) cancel here; the travel adds them up."""
        arms = self._levers
        along = derivatives is not None
        da, db, dd = derivatives if along else (np.zeros((0, 0)),) * 3
        from app.checking import kernels  # loads numba on first use (see there)

        return kernels.piece_travel(
            np.ascontiguousarray(variation, float),
            np.ascontiguousarray(end_a, np.int64),
            np.ascontiguousarray(end_b, np.int64),
            local.levers,
            self.rates,
            arms.below,
            self._unshared,
            along,
            *(np.ascontiguousarray(x, float) for x in (da, db, dd)),
            local.linear,
            local.angular,
            local.radius,
            arms.revolute,
            _SLACK,
        )

    @staticmethod
    def max_distance(pair_travel: np.ndarray) -> np.ndarray:
        """The max_distance at which every unreported pair passes: half the largest pair bound (the environment-
        environment entry counts nothing, and is 0)."""
        return 0.5 * pair_travel.max(axis=(-2, -1)) * MAX_DISTANCE_MARGIN + 1e-12


class _LeverArms:
    """Lever arms of a robot's geometries about its revolute axes, at given configurations (see
    MotionBound.local): from each axis (a line through its joint frame's origin) to the geometry's centre, plus
    the geometry's radius about that centre; and with them each geometry's Jacobian columns at its centre (see
    _Local), for MotionBound.piece_bounds."""

    def __init__(self, kinematics: TreeKinematics, axes, columns, centres, radius, below, rates, slides, chain):
        self._kinematics = kinematics
        self._axes = axes  # unit axis per revolute joint, in its frame on the child body
        self._columns = columns  # its coordinate
        self._centres = centres  # frames (after the axes' frames) of the robot rows' centres
        self._radius = radius  # per robot row, about its centre
        # below[row, j, k]: coordinate k moves the row's geometry relative to coordinate j's axis (see `of`).
        self.below = below.astype(float)
        self._rates = rates
        # Per prismatic joint: its frame (after the centres'), its unit axis in that frame, its coordinate.
        self._slide_frames = np.array([frame for frame, _, _ in slides], np.int64)
        self._slide_axes = np.array([axis for _, axis, _ in slides], float).reshape(-1, 3)
        self._slide_columns = np.array([column for _, _, column in slides], np.int64)
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
            _, _, centre, radius[row] = centred_shape(*describe_shape(inspector, geometry))
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
        from app.checking import kernels

        levers, linear, angular = kernels.lever_arms(
            R,
            p,
            self._axes,
            self._columns,
            self._centres,
            self._radius,
            self._chain,
            self._slide_frames,
            self._slide_axes,
            self._slide_columns,
            self._rates.shape[1],
        )
        shapes = self._centres
        return _Local(levers, linear, angular, np.append(self._radius, 0.0), R[:, shapes], p[:, shapes])


class _Local(NamedTuple):
    """A robot's kinematics at configurations (n): lever arms (see MotionBound.local), and per coordinate and row (the
    environment's last), the velocity of the row's centre and the geometry's angular velocity per unit of the
    coordinate, (n, dim, rows x 3); the rows' radii about their centres; and the robot rows' shapes' rotations (n,
    rows, 3, 3) and centres (n, rows, 3)."""

    levers: np.ndarray
    linear: np.ndarray
    angular: np.ndarray
    radius: np.ndarray
    rotations: np.ndarray
    centres: np.ndarray


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


# Per shared oracle, its MotionBound, made once; gone with the oracle.
_per_oracle: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def motion_bound(oracle) -> MotionBound:
    """The shared oracle's MotionBound, computed once per oracle."""
    if oracle not in _per_oracle:
        _per_oracle[oracle] = MotionBound(oracle)
    return _per_oracle[oracle]
