"""One leg of a path (app.motion.blends: from rest to rest, its corners blended) timed with Drake's Toppra, within the
velocity and acceleration limits between Toppra's grid points too."""

from __future__ import annotations

import functools
import itertools
import logging
import math

import numpy as np

# pydrake is imported inside the functions that use it, so that importing the package does not load Drake.
from app.motion.blends import Leg

# Toppra grid: points over a leg's straight pieces, and per blend (other sizes in turn if Toppra fails on one).
GRID_STRAIGHT, GRID_BLEND = 32, (16, 12, 20, 24)
# Toppra is given limits this much tighter, for what lies between the points _excess checks.
LIMIT_MARGIN = 1e-3
# Points per Toppra grid interval at which the timed speed is checked (see _excess).
SPEED_POINTS = 16


def _grid(leg: Leg, per_blend: int, on_breaks: bool) -> np.ndarray:
    """Toppra's grid: per_blend intervals per blend, GRID_STRAIGHT over the leg's straight pieces; on the pieces'
    breaks (where the curvature jumps), or else at the intervals' middles, none on a break."""
    end = leg.path.end_time()
    grid = []
    for s0, s1, corner in leg.pieces:
        n = per_blend if corner is not None else max(1, math.ceil(GRID_STRAIGHT * (s1 - s0) / end))
        grid.append(s0 + (np.arange(n) + (1.0 if on_breaks else 0.5)) / n * (s1 - s0) - leg.offset)
    # Toppra demands the grid's ends be the path's exactly, and a point on the last break, computed as
    # s0 + (s1 - s0), can round past it.
    inner = np.unique(np.concatenate(grid))
    tiny = 1e-12 * max(end, 1.0)
    return np.concatenate([[leg.path.start_time()], inner[(inner > tiny) & (inner < end - tiny)], [end]])


def _toppra(plant, leg: Leg, v: np.ndarray, a: np.ndarray):
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


def _excess(leg: Leg, s_of_t, v: np.ndarray, a: np.ndarray) -> float:
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
    breaks = times_at(s_of_t, np.array([p[0] - leg.offset for p in leg.pieces[1:]]))
    inside = knots[:-1, None] + np.diff(knots)[:, None] * (np.arange(1, SPEED_POINTS) / SPEED_POINTS)
    edges = np.concatenate([knots, breaks])
    edges = np.clip(np.concatenate([edges - 1e-9, edges + 1e-9]), 0.0, trajectory.end_time())
    speed = np.abs(trajectory.MakeDerivative(1).vector_values(np.concatenate([edges, inside.ravel()]))) / v[:, None]
    push = np.abs(trajectory.MakeDerivative(2).vector_values(edges)) / a[:, None]  # linear between edges
    return max(speed.max(), math.sqrt(push.max()))


def times_at(s_of_t, s: np.ndarray) -> np.ndarray:
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


def timed_leg(plant, leg: Leg, v: np.ndarray, a: np.ndarray):
    """The leg's trajectory q(t) and its s(t), within the limits."""
    from pydrake.trajectories import PathParameterizedTrajectory

    s_of_t = _toppra(plant, leg, v, a)
    # Slowed where the checked points come within half the margin of a limit: the other half is for the peaks
    # between them (seen up to 1e-5 of the limit with SPEED_POINTS = 16).
    stretch = _excess(leg, s_of_t, v, a) / (1 - LIMIT_MARGIN / 2)
    if stretch > 1.0:
        s_of_t.ScaleTime(stretch)
    return PathParameterizedTrajectory(leg.path, s_of_t), s_of_t


class LegNotTimed(RuntimeError):
    """Toppra found no time parameterization for this leg (the caller may stop at one of its corners and try again)."""

    def __init__(self, leg: Leg):
        super().__init__("Toppra found no time parameterization for a path leg")
        self.leg = leg
