"""Time parameterization of a polyline with Drake's Toppra: smooth through the corners where that is proved free,
stopping only where it is not (or where the caller wants a stop).

The corner problem: on a piecewise-linear path Toppra sees zero curvature at the corners and does not slow down, so
the joint velocity would jump there. Stopping at every corner (rest to rest per segment) avoids that but makes the
robot stop at each waypoint. Here each corner is rounded instead by a parabolic blend -- a quadratic Bezier curve
from a point `radius` before the corner, through the corner as control point, to the point `radius` after it -- so
the path is C1 and Toppra slows down just as much as its curvature needs. A blend leaves the checked polyline, so
the whole curve is certified (app.checking.certify); a blend that cannot be certified is halved, and after TIGHTEN
halvings the corner becomes a stop (the path is cut there into legs, each timed from rest to rest). What is proved
is that curve, not the polyline: where the polyline's edges are proved already only the blends are, and otherwise
(`prove_blends`, what the planner asks first) the straight parts between the blends are, not the corners the blends
cut off.

The path parameter s is arc length in the space's weighted metric along the polyline, and a blend of radius r
spans s in [corner - r, corner + r], so straight parts keep their s whatever the blends: a straight piece that was
certified stays certified when a neighbouring blend shrinks.

Waypoints must be unwrapped first (`ConfigurationSpace.unwrap`), so that continuous angles take the short way.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import logging
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

# pydrake is imported inside the functions that use it, so that importing the package does not load Drake.
from app.checking.certify import CLEARANCE, Certifier, straight_edges
from app.errors import UserError
from app.motion.path import distinct
from app.motion.trajectory import Trajectory

# A blend's first radius: this fraction of the shorter of its two segments (at most 1/2, so blends never overlap).
BLEND = 0.5
# Halvings of a blend that fails certification before its corner becomes a stop.
TIGHTEN = 8
# Toppra grid: points over a leg's straight pieces, and per blend (other sizes in turn if Toppra fails on one).
GRID_STRAIGHT, GRID_BLEND = 32, (16, 12, 20, 24)
# Toppra is given limits this much tighter, for what lies between the points _excess checks.
LIMIT_MARGIN = 1e-3
# Points per Toppra grid interval at which the timed speed is checked (see _excess).
SPEED_POINTS = 16
# A straight line between two samples that the certificate cannot prove in this many parts gets a sample between.
LINE_CUTS = 8
# The longest motion timed (s): a day. Limits scaled further down are refused (check_duration).
MAX_DURATION = 86400.0
# Piece derivatives are linear in s up to rounding of their cubic Hermite form: a little slack on the travel bound.
_SLACK = 1 + 1e-9


@dataclass
class _Leg:
    """A stretch of the path timed from rest to rest: waypoints first..last, blended at the corners in between."""

    first: int
    last: int
    offset: float  # global s of the leg's start; its Drake path runs over s - offset
    path: object  # PiecewisePolynomial, C1, pieces of degree <= 2
    pieces: list  # (s0, s1, corner or None), global s


def _leg(W: np.ndarray, tangent: np.ndarray, arc: np.ndarray, radii: np.ndarray, first: int, last: int) -> _Leg:
    from pydrake.trajectories import PiecewisePolynomial

    tiny = 1e-12 * max(arc[-1], 1.0)
    breaks, values, slopes, pieces = [arc[first]], [W[first]], [tangent[first]], []
    for i in range(first + 1, last + 1):
        r = radii[i] if i < last else 0.0
        if arc[i] - r > breaks[-1] + tiny:  # the straight piece of segment i-1 up to the blend (or the leg's end)
            pieces.append((breaks[-1], arc[i] - r, None))
            breaks.append(arc[i] - r)
            values.append(W[i] - r * tangent[i - 1])
            slopes.append(tangent[i - 1])
        if i < last:
            pieces.append((breaks[-1], arc[i] + r, i))
            breaks.append(arc[i] + r)
            values.append(W[i] + r * tangent[i])
            slopes.append(tangent[i])
    path = PiecewisePolynomial.CubicHermite(np.array(breaks) - arc[first], np.array(values).T, np.array(slopes).T)
    return _Leg(first, last, arc[first], path, pieces)


def _legs(W, tangent, arc, radii) -> list[_Leg]:
    """The legs between stops: the ends and every corner whose radius is 0."""
    stops = [0] + [i for i in range(1, len(W) - 1) if radii[i] == 0] + [len(W) - 1]
    return [_leg(W, tangent, arc, radii, a, b) for a, b in itertools.pairwise(stops)]


class _Curve:
    """position(s), variation(s0, s1) and derivatives(s0, s1) over the global s of all legs, for the certifier: each
    for arrays of s, with one Drake call per leg they fall on."""

    def __init__(self, legs: list[_Leg]):
        self.legs = legs
        self.starts = np.array([leg.offset for leg in legs])
        self.rates = [leg.path.MakeDerivative(1) for leg in legs]
        self._last = None  # see _end_rates

    def _leg_of(self, s: np.ndarray) -> np.ndarray:
        return np.maximum(np.searchsorted(self.starts, s, side="right") - 1, 0)

    def _values(self, paths: list, s: np.ndarray, leg_of: np.ndarray) -> np.ndarray:
        """paths[leg_of[i]] at s[i] (global s), rows of the result."""
        out = np.empty((len(s), self.legs[0].path.rows()))
        for k in np.unique(leg_of).tolist():
            rows = np.flatnonzero(leg_of == k)
            out[rows] = paths[k].vector_values(s[rows] - self.legs[k].offset).T
        return out

    def position(self, s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, float)
        return self._values([leg.path for leg in self.legs], s, self._leg_of(s))

    def variation(self, s0: np.ndarray, s1: np.ndarray) -> np.ndarray:
        # Within a piece the derivative is linear in s, so each coordinate's travel, the integral of its magnitude,
        # is in closed form: the mean of the two ends' magnitudes, or where it changes sign, the two triangles
        # either side of its zero, (d0^2 + d1^2) / (2 (|d0| + |d1|)).
        s0, s1, d0, d1 = self._end_rates(s0, s1)
        a, b = np.abs(d0), np.abs(d1)
        mean = np.where(d0 * d1 >= 0, 0.5 * (a + b), (a * a + b * b) / (2 * np.maximum(a + b, 1e-300)))
        return mean * (s1 - s0)[:, None] * _SLACK

    def derivatives(self, s0: np.ndarray, s1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        # Within a piece the derivative is linear in s: the second derivative is its change over the span.
        s0, s1, d0, d1 = self._end_rates(s0, s1)
        return d0, d1, np.abs(d1 - d0) / np.maximum(s1 - s0, 1e-300)[:, None] * _SLACK

    def _end_rates(self, s0, s1) -> tuple[np.ndarray, ...]:
        """(s0, s1, dq/ds at s0, at s1) of pieces within one leg piece each. The certifier asks variation and
        derivatives of the same pieces in each round: the last answer is kept, so Drake evaluates them once."""
        s0, s1 = np.asarray(s0, float), np.asarray(s1, float)
        key = (s0.tobytes(), s1.tobytes())
        if self._last is None or self._last[0] != key:
            leg = self._leg_of(0.5 * (s0 + s1))
            self._last = key, (s0, s1, self._values(self.rates, s0, leg), self._values(self.rates, s1, leg))
        return self._last[1]


def _certified_radii(
    certifier: Certifier,
    W,
    tangent,
    arc,
    radii,
    tighten: int,
    known: np.ndarray,
    clearance: float,
    give_up: bool = False,
) -> tuple[np.ndarray, list[int], dict]:
    """Blend radii tightened until every blend keeps `clearance` and the corner of the polyline it cuts off is
    free (a corner that never is becomes a stop), the segments whose straight part failed (indices into W's
    segments; none: the whole curve, and the polyline, are certified), and the cost.

    A segment's straight part runs between its corners' blends. As a blend shrinks, the straight parts beside it
    grow and keep their s, so only what they gain is proved. The polyline's corner a blend cuts off is within
    radius / 4 x the change of tangent of the blend, coordinate by coordinate (at the blend's middle), so where
    that moves no pair more than clearance / 2 the blend's proof covers it; otherwise it is proved itself, to keep
    clearance / 2 (the path polyline is part of the answer: a controller may follow it). Each round proves the
    blends, corners and straight parts it has in one certifier call. known: per segment, whether it is certified
    already (then so is its straight part, and its half of each corner). give_up: a straight part that fails ends
    the proof (for a caller that will prove the path another way or change it, rather than time it uncertified)."""
    line, tiny = straight_edges(W, arc), 1e-12 * max(arc[-1], 1.0)
    weights = certifier.checker.space.weights
    radii, halvings, done = radii.copy(), np.zeros(len(W), int), set()
    proved = np.tile([np.inf, -np.inf], (len(W) - 1, 1))  # per segment, the span of its straight part proved
    cornered = np.zeros(len(W))  # per corner, the radius up to which the polyline it cuts off is proved
    turn = np.abs(np.diff(tangent[: len(W) - 1], axis=0, prepend=tangent[:1]))  # per corner i, |t_i - t_i-1|
    covered = certifier.bound.pair_travel(turn / 4).max(axis=(-2, -1))  # per corner, per unit of radius
    refused: set[int] = set()
    cost = {"pieces": 0, "distance_queries": 0, "seconds": 0.0, "rounds": 0}
    while True:
        straight = []  # (segment, s0, s1): what its straight part has gained since the last round
        for j in np.flatnonzero(~known):
            s0, s1, (lo, hi) = arc[j] + radii[j], arc[j + 1] - radii[j + 1], proved[j]
            if j in refused or s1 - s0 <= tiny:
                continue
            gained = [(s0, s1)] if lo > hi else [(a, b) for a, b in ((s0, lo), (hi, s1)) if b - a > tiny]
            straight += [(int(j), *span) for span in gained]
        curve = _Curve(_legs(W, tangent, arc, radii))
        todo = [p for leg in curve.legs for p in leg.pieces if p[2] is not None and p not in done]
        # Corners whose cut-off the blend's proof does not cover: their polyline proved, each half apart (the
        # polyline's variation holds within one segment); a known segment's half is proved already.
        inside = np.arange(1, len(W) - 1)
        small = covered[inside] * radii[inside] <= clearance / 2
        cornered[inside[small]] = np.maximum(cornered[inside[small]], radii[inside[small]])
        near = inside[~small & (radii[inside] > cornered[inside])].tolist()
        corners = [
            (i, s0, s1)
            for i in near
            for j, s0, s1 in ((i - 1, arc[i] - radii[i], arc[i]), (i, arc[i], arc[i] + radii[i]))
            if not known[j]
        ]
        intervals = (
            [(s0, s1) for _, s0, s1 in straight]
            + [(-s1, -s0) for s0, s1, _ in todo]
            + [(s0, s1) for _, s0, s1 in corners]
        )
        margins = [clearance] * (len(straight) + len(todo)) + [clearance / 2] * len(corners)
        # A corner that fails once cut in LINE_CUTS is cheaper to tighten (halving its blend) than to prove finer.
        floors = [certifier.floor] * (len(straight) + len(todo)) + [
            max(
                certifier.floor, np.linalg.norm(line.variation(np.array([s0]), np.array([s1]))[0] * weights) / LINE_CUTS
            )
            for _, s0, s1 in corners
        ]
        failed = _certify(certifier, _Both(line, curve, W.shape[1]), intervals, margins, floors)
        for key in ("pieces", "distance_queries", "seconds"):
            cost[key] += failed[key]
        first_blend, first_corner = len(straight), len(straight) + len(todo)
        failed_straight = {k for k in failed["failed"] if k < first_blend}
        failed_blends = {k - first_blend for k in failed["failed"] if first_blend <= k < first_corner}
        failed_corners = {corners[k - first_corner][0] for k in failed["failed"] if k >= first_corner}
        for i in near:
            if i not in failed_corners:
                cornered[i] = radii[i]
        cost["rounds"] += 1
        for k, (j, s0, s1) in enumerate(straight):
            if k in failed_straight:
                refused.add(j)
            else:
                proved[j] = min(proved[j, 0], s0), max(proved[j, 1], s1)
        done.update(p for k, p in enumerate(todo) if k not in failed_blends)
        corners = {todo[k][2] for k in failed_blends} | failed_corners
        if not corners or refused and give_up:
            return radii, sorted(refused), cost
        for i in corners:
            halvings[i] += 1
            radii[i] = radii[i] / 2 if halvings[i] <= tighten else 0.0


def _certify(certifier: Certifier, curve, intervals: list, clearances: list, floors: list) -> dict:
    """The certifier's stats on the intervals of `curve`, each to keep its clearance, cut no finer than its floor
    (none asked for: no cost)."""
    if not intervals:
        return {"failed": [], "pieces": 0, "distance_queries": 0, "seconds": 0.0}
    return certifier.certify(curve, intervals, np.array(clearances, float), np.array(floors, float))[1]


class _Both:
    """The polyline (`line`: position, variation) at s >= 0 and the blended curve at -s, so that one certifier call
    proves pieces of both (its rounds batch their distance queries together); negating s is exact, and both curves
    are W[0] at s = 0."""

    def __init__(self, line: tuple, curve: _Curve, dim: int):
        self.line, self.curve, self.dim = line, curve, dim

    def position(self, s: np.ndarray) -> np.ndarray:
        out, curved = np.empty((len(s), self.dim)), s < 0
        out[~curved] = self.line.position(s[~curved])
        out[curved] = self.curve.position(-s[curved])
        return out

    def variation(self, s0: np.ndarray, s1: np.ndarray) -> np.ndarray:
        out, curved = np.empty((len(s0), self.dim)), s0 + s1 < 0
        out[~curved] = self.line.variation(s0[~curved], s1[~curved])
        out[curved] = self.curve.variation(-s1[curved], -s0[curved])
        return out

    def derivatives(self, s0: np.ndarray, s1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        # On the curve, q(s) = curve(-s): the velocities change sign, and s0 is the curve's later end.
        out = [np.empty((len(s0), self.dim)) for _ in range(3)]
        curved = s0 + s1 < 0
        for o, x in zip(out, self.line.derivatives(s0[~curved], s1[~curved])):
            o[~curved] = x
        at_1, at_0, dd = self.curve.derivatives(-s1[curved], -s0[curved])
        out[0][curved], out[1][curved], out[2][curved] = -at_0, -at_1, dd
        return tuple(out)


def _first_radii(lengths: np.ndarray) -> np.ndarray:
    """Each corner's first blend radius: at most half of each segment it touches, or all of the first or last
    segment (the path's ends have no blend to share it with), so that blends never overlap."""
    share = np.full(len(lengths), BLEND)
    share[[0, -1]] = 2 * BLEND
    radii = np.zeros(len(lengths) + 1)
    radii[1:-1] = np.minimum(share[:-1] * lengths[:-1], share[1:] * lengths[1:])
    return radii


def _grid(leg: _Leg, per_blend: int, on_breaks: bool) -> np.ndarray:
    """Toppra's grid: per_blend intervals per blend, GRID_STRAIGHT over the leg's straight pieces; on the pieces'
    breaks (where the curvature jumps), or else at the intervals' middles, none on a break."""
    length = leg.pieces[-1][1] - leg.offset
    grid = [np.zeros(1)]
    for s0, s1, corner in leg.pieces:
        n = per_blend if corner is not None else max(1, math.ceil(GRID_STRAIGHT * (s1 - s0) / length))
        grid.append(s0 + (np.arange(n) + (1.0 if on_breaks else 0.5)) / n * (s1 - s0) - leg.offset)
    return np.unique(np.concatenate(grid + [[length]]))


def _toppra(plant, leg: _Leg, v: np.ndarray, a: np.ndarray):
    """Toppra from rest to rest along the leg: s(t). Drake's Toppra now and then finds no solution, or one with NaNs,
    for numerical reasons (seen on a symmetric zigzag with grid points on the breaks, at several grid sizes), so
    other grids are tried then; Drake's error line for each failed try is kept quiet."""
    from pydrake.multibody.optimization import Toppra

    if plant.num_positions() != leg.path.rows():  # mimic joints: fewer coordinates than the plant has positions
        plant = _sliders(leg.path.rows())
    drake_log = logging.getLogger("drake")
    level = drake_log.level
    drake_log.setLevel(logging.CRITICAL)
    try:
        for on_breaks, per_blend in itertools.product((True, False), GRID_BLEND):
            toppra = Toppra(leg.path, plant, _grid(leg, per_blend, on_breaks))
            toppra.AddJointVelocityLimit(-v * (1 - LIMIT_MARGIN), v * (1 - LIMIT_MARGIN))
            toppra.AddJointAccelerationLimit(-a * (1 - LIMIT_MARGIN), a * (1 - LIMIT_MARGIN))
            s_of_t = toppra.SolvePathParameterization()
            # A "solution" can hold NaNs (seen on a tunnel path); evaluating the path at them aborts the process.
            if s_of_t is not None and np.all(np.isfinite(s_of_t.vector_values(s_of_t.get_segment_times()))):
                return s_of_t
    finally:
        drake_log.setLevel(level)
    raise RuntimeError("Toppra found no time parameterization for a path leg")


@functools.cache
def _sliders(dim: int):
    """A plant of `dim` prismatic joints. Toppra demands a plant with as many positions as the path has rows, and
    uses it only for torque and frame limits, which are not asked for here; a path in the coordinates of a scene with
    mimic joints has fewer rows than its plant has positions, and this plant stands in."""
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.multibody.tree import PrismaticJoint, SpatialInertia

    plant = MultibodyPlant(0.0)
    parent = plant.world_body()
    for i in range(dim):
        body = plant.AddRigidBody(f"slider{i}", SpatialInertia.SolidSphereWithMass(1.0, 0.1))
        plant.AddJoint(PrismaticJoint(f"slider{i}", parent.body_frame(), body.body_frame(), [1.0, 0.0, 0.0]))
        parent = body
    plant.Finalize()
    return plant


def _excess(leg: _Leg, s_of_t, v: np.ndarray, a: np.ndarray) -> float:
    """By how much the timed leg exceeds its limits, as the factor its time must be stretched by (<= 1: within).

    Toppra enforces the limits at its grid points only. Between them s'' is constant, so on each piece (where q''
    is constant and q' linear in s) the acceleration q'' s'^2 + q' s'' is linear in s: its extremes lie at the
    grid's knots and the pieces' breaks, both sides of each, which are checked. The speed q' s' can peak inside a
    grid interval on a blend (an audit found 2.2e-4 over the limit with only the midpoints looked at), so each
    interval is looked at SPEED_POINTS times; LIMIT_MARGIN covers what lies between those.
    """
    from pydrake.trajectories import PathParameterizedTrajectory

    trajectory = PathParameterizedTrajectory(leg.path, s_of_t)
    knots = np.array(s_of_t.get_segment_times())
    breaks = _when(s_of_t, np.array([p[0] - leg.offset for p in leg.pieces[1:]]))
    inside = knots[:-1, None] + np.diff(knots)[:, None] * (np.arange(1, SPEED_POINTS) / SPEED_POINTS)
    edges = np.concatenate([knots, breaks])
    edges = np.clip(np.concatenate([edges - 1e-9, edges + 1e-9]), 0.0, trajectory.end_time())
    speed = np.abs(trajectory.MakeDerivative(1).vector_values(np.concatenate([edges, inside.ravel()]))) / v[:, None]
    push = np.abs(trajectory.MakeDerivative(2).vector_values(edges)) / a[:, None]  # linear between edges
    return max(speed.max(), math.sqrt(push.max()))


def _when(s_of_t, s: np.ndarray) -> np.ndarray:
    """The times at which the increasing s(t) reaches each s. Toppra's s(t) is piecewise quadratic, so each time is
    the root of its segment's quadratic, fitted through s at the segment's ends and middle (two evaluations in all,
    where bisection to rounding took sixty)."""
    knots = np.asarray(s_of_t.get_segment_times())
    at_knots = s_of_t.vector_values(knots).ravel()
    at_middle = s_of_t.vector_values(0.5 * (knots[:-1] + knots[1:])).ravel()
    segment = np.clip(np.searchsorted(at_knots, s, side="right") - 1, 0, len(knots) - 2)
    s0, s1, sm = at_knots[segment], at_knots[segment + 1], at_middle[segment]
    # s = s0 + b u + c u^2 over the segment's u in [0, 1]; the root in the form that stays exact as c -> 0.
    b = 4 * (sm - s0) - (s1 - s0)
    c = (s1 - s0) - b
    rise = np.clip(s - s0, 0.0, s1 - s0)
    denominator = b + np.sqrt(np.maximum(b * b + 4 * c * rise, 0.0))
    u = np.where(denominator > 0, 2 * rise / np.where(denominator > 0, denominator, 1.0), 0.0)
    return knots[segment] + np.clip(u, 0.0, 1.0) * np.diff(knots)[segment]


def _timed_leg(plant, leg: _Leg, v: np.ndarray, a: np.ndarray):
    """The leg's trajectory q(t) and its s(t), within the limits."""
    from pydrake.trajectories import PathParameterizedTrajectory

    s_of_t = _toppra(plant, leg, v, a)
    # Slowed where the checked points come within half the margin of a limit: the other half is for the peaks
    # between them (seen up to 1e-5 of the limit with SPEED_POINTS = 16).
    stretch = _excess(leg, s_of_t, v, a) / (1 - LIMIT_MARGIN / 2)
    if stretch > 1.0:
        s_of_t.ScaleTime(stretch)
    return PathParameterizedTrajectory(leg.path, s_of_t), s_of_t


class _LegNotTimed(RuntimeError):
    def __init__(self, leg: _Leg):
        super().__init__("Toppra found no time parameterization for a path leg")
        self.leg = leg


class _Timed(NamedTuple):
    """A timed leg: when it starts, its q(t) and s(t), and the leg."""

    start: float
    trajectory: object  # PathParameterizedTrajectory over the leg's own time
    s_of_t: object
    leg: _Leg


def _time_legs(plant, W, arc, legs, v, a, dt, joint_names, chords: _Chords | None) -> Trajectory:
    """Each leg timed from rest to rest, the legs one after another, sampled as _sample_times says; chords: the
    clearance the certified curve keeps, and its motion bound (None: not certified)."""
    timed, waypoint_times, t = [], np.zeros(len(W)), 0.0
    for leg in legs:
        try:
            trajectory, s_of_t = _timed_leg(plant, leg, v, a)
        except RuntimeError:
            raise _LegNotTimed(leg) from None
        # When the motion passes each waypoint (a blended corner: the blend's middle, nearest the corner).
        inside = np.arange(leg.first, leg.last + 1)
        waypoint_times[inside] = t + _when(s_of_t, arc[inside] - leg.offset)
        timed.append(_Timed(t, trajectory, s_of_t, leg))
        t += trajectory.end_time()
    return _sample(timed, W, waypoint_times, _sample_times(timed, dt, chords), joint_names, chords)


class _Chords:
    """How the straight lines between a certified curve's samples are proved: the curve keeps `clearance`, the lines
    must keep half of it; `certifier` (its motion bound says how far a pair's distance can change over a change of
    q, and it proves the lines the bound alone does not cover); `cost` sums those proofs."""

    def __init__(self, clearance: float, certifier: Certifier):
        self.clearance, self.certifier = clearance, certifier
        self.cost = {"pieces": 0, "distance_queries": 0, "seconds": 0.0}


def _sample_times(timed: list[_Timed], dt: float, chords: _Chords | None) -> np.ndarray:
    """Every dt from 0, the end, each stop between legs (the robot rests there; a straight line across one would
    cut its corner), and, for a certified curve, more wherever the straight line between two samples is not proved
    to keep half the clearance.

    Within a leg q(s) is C1 with q'' constant on each piece (0 on straight ones, where the line lies on the curve),
    so the straight line between q(s_a) and q(s_b) lies within (s_b - s_a)^2 / 8 x max |q''| of the curve,
    coordinate by coordinate (linear interpolation's error); moved that far, a pair's distance changes by at most the
    motion bound's pair travel. A line where that is at most clearance / 2 keeps half the clearance; the others are
    proved by the certificate, and one that fails is cut in two at the middle of its s (each half within a quarter
    of it), until every line is covered. A controller that interpolates linearly between the samples then keeps
    clearance / 2."""
    duration = timed[-1].start + timed[-1].trajectory.end_time() if timed else 0.0
    times = np.arange(int(np.floor(duration / dt + 1e-9)) + 1) * dt
    times = np.union1d(times, [part.start for part in timed[1:]] + [duration])
    times = times[np.concatenate([[True], np.diff(times) > 1e-9])]
    if chords is None:
        return times
    more = [times]
    for part in timed:
        blends = [(s0, s1) for s0, s1, corner in part.leg.pieces if corner is not None]
        if not blends:
            continue
        end = part.trajectory.end_time()
        local = np.clip(times[(times >= part.start - 1e-9) & (times <= part.start + end + 1e-9)] - part.start, 0, end)
        s = part.s_of_t.vector_values(local).ravel()
        spans = np.array(blends) - part.leg.offset
        bend = np.abs(part.leg.path.MakeDerivative(2).vector_values(spans.mean(axis=1)).T)  # (blends, dim)
        a, b = s[:-1], s[1:]
        while len(a):
            overlap = (a[:, None] < spans[None, :, 1]) & (b[:, None] > spans[None, :, 0])
            off = (b - a)[:, None] ** 2 / 8 * np.max(np.where(overlap[:, :, None], bend[None], 0.0), axis=1) * _SLACK
            reach = chords.certifier.bound.pair_travel(off).max(axis=(-2, -1))
            ask = np.flatnonzero(reach > chords.clearance / 2)
            failed = _prove_lines(chords, part.leg.path, a[ask], b[ask])
            a, b = a[ask[failed]], b[ask[failed]]
            middle = 0.5 * (a + b)
            more.append(part.start + _when(part.s_of_t, middle))
            a, b = np.concatenate([a, middle]), np.concatenate([middle, b])
    return np.unique(np.concatenate(more))


def _prove_lines(chords: _Chords, path, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Indices of the straight lines from path(a[i]) to path(b[i]) (a leg's own s) not proved to keep half the
    clearance."""
    if not len(a):
        return np.zeros(0, int)
    ends = np.empty((2 * len(a), path.rows()))
    ends[0::2], ends[1::2] = path.vector_values(a).T, path.vector_values(b).T
    knots = np.arange(len(ends), dtype=float)
    intervals = [(2.0 * i, 2.0 * i + 1) for i in range(len(a))]
    # A line that fails once cut in LINE_CUTS is cheaper to split between samples (a quarter of its distance from the
    # curve each) than to prove finer.
    weights = chords.certifier.checker.space.weights
    floor = np.linalg.norm((ends[1::2] - ends[0::2]) * weights, axis=1) / LINE_CUTS
    _, stats = chords.certifier.certify(straight_edges(ends, knots), intervals, chords.clearance / 2, floor)
    for key in chords.cost:
        chords.cost[key] += stats[key]
    return np.array(stats["failed"], int)


def _sample(timed: list[_Timed], W, waypoint_times, times, joint_names, chords: _Chords | None) -> Trajectory:
    dim = W.shape[1]
    positions = np.tile(W[0], (len(times), 1))
    velocities, accelerations = np.zeros((len(times), dim)), np.zeros((len(times), dim))
    if timed:
        # Each leg's samples in one call per quantity (a call per sample cost more than Toppra on short paths).
        starts = np.array([part.start for part in timed])
        leg = np.clip(np.searchsorted(starts, times, side="right") - 1, 0, len(timed) - 1)
        for k, part in enumerate(timed):
            rows = np.flatnonzero(leg == k)
            if len(rows):
                trajectory = part.trajectory
                local = np.minimum(times[rows] - part.start, trajectory.end_time())
                positions[rows] = trajectory.vector_values(local).T
                velocities[rows] = trajectory.MakeDerivative(1).vector_values(local).T
                accelerations[rows] = trajectory.MakeDerivative(2).vector_values(local).T
    positions[-1], velocities[-1] = W[-1], 0.0  # exactly the goal, at rest
    names = list(joint_names) if joint_names is not None else [f"q[{i}]" for i in range(dim)]
    return Trajectory(
        joint_names=names,
        times=times,
        positions=positions,
        velocities=velocities,
        accelerations=accelerations,
        waypoints=W.copy(),
        waypoint_times=waypoint_times,
        certified=chords is not None,
        clearance=chords.clearance if chords is not None else None,
    )


def _prepare(waypoints, velocity_limits, acceleration_limits, weights):
    """Waypoints without repeats, unit tangents and arc lengths in the weighted metric, finite positive limits."""
    W, tangent, arc, _ = _geometry(waypoints, weights)
    v = np.asarray(velocity_limits, float)
    a = np.asarray(acceleration_limits, float)
    if not (np.all(v > 0) and np.all(a > 0)):
        raise ValueError("velocity and acceleration limits must be positive")
    # An unlimited joint is limited by the others; Toppra wants finite bounds.
    v, a = np.where(np.isfinite(v), v, 1e9), np.where(np.isfinite(a), a, 1e9)
    check_duration(W, v, a)
    return W, v, a, tangent, arc


def shortest_duration(waypoints, velocity_limits, acceleration_limits) -> float:
    """A lower bound on how long any motion along the polyline takes from rest to rest under these limits: each
    segment at least its slowest coordinate's travel over its speed limit, and each coordinate, whose speed can
    grow by at most a t from the start and must fall to 0 by the end, at least 2 sqrt(total travel / a)."""
    steps = np.abs(np.diff(np.atleast_2d(np.asarray(waypoints, float)), axis=0))
    if not len(steps):
        return 0.0
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        by_speed = np.sum(np.max(steps / velocity_limits, axis=1))
        by_push = np.max(2 * np.sqrt(steps.sum(axis=0) / acceleration_limits))
    return float(np.nan_to_num(max(by_speed, by_push), nan=np.inf))


def check_duration(waypoints, velocity_limits, acceleration_limits) -> None:
    """UserError when the motion along the waypoints would take longer than MAX_DURATION under these limits (limits
    scaled down that far: Toppra's numbers would underflow, and no controller waits that long)."""
    least = shortest_duration(waypoints, velocity_limits, acceleration_limits)
    if least > MAX_DURATION:
        raise UserError(
            f"under these velocity and acceleration limits the motion would take at least {_spelled(least)}, more "
            "than a day: use larger limits or scaling factors"
        )


def _spelled(seconds: float) -> str:
    if not np.isfinite(seconds):
        return "forever"
    unit, size = next(
        (u, k) for u, k in (("years", 365.25 * 86400), ("days", 86400), ("h", 3600), ("s", 1)) if seconds >= k or k == 1
    )
    return f"{seconds / size:.3g} {unit}"


def _geometry(waypoints, weights):
    """Waypoints without repeats, unit tangents, arc lengths in the weighted metric, and which waypoints were kept."""
    P = np.atleast_2d(np.asarray(waypoints, float))
    kept = distinct(P)
    W = P[kept]
    steps = np.diff(W, axis=0)
    lengths = np.linalg.norm(steps * weights, axis=1)
    tangent = steps / lengths[:, None] if len(W) > 1 else np.zeros((0, W.shape[1]))
    arc = np.concatenate([[0.0], np.cumsum(lengths)])
    return W, np.vstack([tangent, tangent[-1:]]) if len(W) > 1 else tangent, arc, kept


@dataclass(frozen=True)
class BlendProof:
    """The curve a path's trajectory follows, certified ahead of its timing (prove_blends) to keep `clearance`: its
    blend radii, and the path's edges whose straight part could not be proved (none: the whole curve is
    certified)."""

    path: np.ndarray
    radii: np.ndarray
    failed: list[int]
    cost: dict
    clearance: float

    def reversed(self) -> BlendProof:
        """The proof of the same curve run backwards (a blend is symmetric about its corner)."""
        failed = sorted(len(self.path) - 2 - i for i in self.failed)
        return dataclasses.replace(self, path=self.path[::-1].copy(), radii=self.radii[::-1].copy(), failed=failed)


def prove_blends(
    certifier: Certifier, path: np.ndarray, known=(), clearance: float = CLEARANCE, tighten: int = TIGHTEN
) -> BlendProof:
    """The curve time_path makes of `path` (a path of the certifier's checker, wrapped) certified to keep
    `clearance`: its blends, the straight parts of its edges between them, and the corners the blends cut off (to
    keep half of it, see _certified_radii). Stops at the first straight part that fails. known: indices of the
    path's edges certified already (to keep `clearance`), whose straight parts are not proved again."""
    space = certifier.checker.space
    W, tangent, arc, kept = _geometry(space.unwrap(path), space.weights)
    edge = kept[1:] - 1  # each of W's segments as an edge of the path (repeated waypoints are skipped)
    if len(W) < 2:
        cost = {"pieces": 0, "distance_queries": 0, "seconds": 0.0, "rounds": 0}
        return BlendProof(path.copy(), np.zeros(len(W)), [], cost, clearance)
    known = np.isin(edge, list(known))
    radii, failed, cost = _certified_radii(
        certifier, W, tangent, arc, _first_radii(np.diff(arc)), tighten, known, clearance, give_up=True
    )
    return BlendProof(path.copy(), radii, [int(edge[j]) for j in failed], cost, clearance)


def parameterize(
    plant,
    waypoints: np.ndarray,
    velocity_limits: np.ndarray,
    acceleration_limits: np.ndarray,
    dt: float = 0.02,
    joint_names: list[str] | None = None,
) -> Trajectory:
    """Rest to rest at every waypoint: each straight segment timed on its own (what a scripted job's leg wants
    where it stops). Not certified: it is exactly the polyline, as free as its checks say."""
    W, v, a, tangent, arc = _prepare(waypoints, velocity_limits, acceleration_limits, np.ones(np.shape(waypoints)[-1]))
    legs = _legs(W, tangent, arc, np.zeros(len(W))) if len(W) > 1 else []
    return _time_legs(plant, W, arc, legs, v, a, dt, joint_names, chords=None)


def scaled_limits(scene, velocity_scale: float = 1.0, acceleration_scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The scene's velocity and acceleration limits times these fractions of them, each in (0, 1] (MoveIt's
    max_velocity_scaling_factor and max_acceleration_scaling_factor)."""
    for name, scale in (("velocity_scale", velocity_scale), ("acceleration_scale", acceleration_scale)):
        if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not 0 < scale <= 1:
            raise UserError(f"{name} must be a fraction in (0, 1], got {scale!r}")
    v, a = np.asarray(scene.velocity_limits, float), np.asarray(scene.acceleration_limits, float)
    return v * velocity_scale, a * acceleration_scale


def time_path(
    checker,
    path: np.ndarray,
    dt: float,
    *,
    certifier=None,
    edges_proved: bool = False,
    proof: BlendProof | None = None,
    velocity_scale: float = 1.0,
    acceleration_scale: float = 1.0,
    clearance: float = CLEARANCE,
) -> Trajectory:
    """A path of the checker's scene (wrapped waypoints) timed by parameterize_smooth under the scene's limits, scaled
    by velocity_scale and acceleration_scale (see scaled_limits), certified to keep `clearance`; it carries the
    scene's mimic joints. proof: the path's curve certified already (prove_blends), whose radii are then used as
    they are."""
    trajectory = parameterize_smooth(
        checker,
        checker.space.unwrap(path),
        *scaled_limits(checker.scene, velocity_scale, acceleration_scale),
        dt,
        checker.space.names,
        certifier=certifier,
        edges_proved=edges_proved,
        proof=proof,
        clearance=clearance,
    )
    return dataclasses.replace(trajectory, position_map=checker.scene.position_map)


def parameterize_smooth(
    checker,
    waypoints: np.ndarray,
    velocity_limits: np.ndarray,
    acceleration_limits: np.ndarray,
    dt: float = 0.02,
    joint_names: list[str] | None = None,
    floor: float | None = None,
    tighten: int = TIGHTEN,
    stats: dict | None = None,
    certifier: Certifier | None = None,
    edges_proved: bool = False,
    proof: BlendProof | None = None,
    clearance: float = CLEARANCE,
) -> Trajectory:
    """Blended corners, certified to keep `clearance` (see the module doc), timed with Toppra.

    The trajectory is `certified` when the whole executed curve keeps the clearance (blends and straight pieces)
    and the polyline the corners it cuts off, with half of it; its samples are then placed so that the straight
    lines between them keep half of it too (_sample_times). If a straight piece of the polyline itself cannot be
    certified, the curve is still timed and returned, uncertified.
    floor: the certificate's bisection floor (default: app.checking.certify's); tighten: halvings of a failing blend
    before its corner becomes a stop. stats, if given, receives: stops (corners the robot stops at), pieces,
    distance_queries and seconds (certification), rounds (of blend tightening). certifier: one to reuse (its
    distances are cached). edges_proved: every straight edge of the waypoints' polyline is certified already (the
    planner's certificate, to keep `clearance`): then only the blends are. proof: the curve certified already
    (prove_blends on the wrapped waypoints these are unwrapped from): its radii and clearance are used.
    """
    W, v, a, tangent, arc = _prepare(waypoints, velocity_limits, acceleration_limits, checker.space.weights)
    known = np.full(max(len(W) - 1, 0), edges_proved)
    radii = np.zeros(len(W))
    certified, cost = False, {"pieces": 0, "distance_queries": 0, "seconds": 0.0, "rounds": 0}
    if proof is not None:
        if len(proof.radii) != len(W):
            raise ValueError("the blend proof is of other waypoints")
        radii, certified, clearance = proof.radii.copy(), not proof.failed, proof.clearance
    elif len(W) > 1:
        certifier = certifier or Certifier(checker, floor)
        first = _first_radii(np.diff(arc))
        radii, failed, cost = _certified_radii(certifier, W, tangent, arc, first, tighten, known, clearance)
        certified = not failed
    while True:
        legs = _legs(W, tangent, arc, radii) if len(W) > 1 else []
        try:
            chords = None
            if certified:
                certifier = certifier or Certifier(checker, floor)
                chords = _Chords(clearance, certifier)
            trajectory = _time_legs(checker.oracle.plant, W, arc, legs, v, a, dt, joint_names, chords)
            if chords is not None:
                cost = {k: cost[k] + chords.cost.get(k, 0) for k in cost}
            break
        except _LegNotTimed as failed:
            # Toppra fails on a blend of extreme curvature (seen: a corner 2e-5 from the next one, left by a partial
            # shortcut): the failing leg's tightest blend becomes a stop, and the path is timed again (a rare
            # case); a leg with no blend left fails the query.
            corners = np.arange(failed.leg.first + 1, failed.leg.last)
            corners = corners[radii[corners] > 0]
            if not len(corners):
                raise
            radii[corners[np.argmin(radii[corners])]] = 0.0
            if certified and not edges_proved:  # the polyline by that corner was cut off by its blend: prove it
                certifier = certifier or Certifier(checker, floor)
                radii, refused, more = _certified_radii(certifier, W, tangent, arc, radii, tighten, known, clearance)
                cost = {k: cost[k] + more[k] for k in cost}
                certified = not refused
    if stats is not None:
        stats.update(cost, stops=int(np.sum(radii[1:-1] == 0)))
    return trajectory
