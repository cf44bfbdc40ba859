"""A timed path's samples, what a controller is given: its legs (app.motion.leg_timing) one after another, sampled
every dt, at every stop, and, for a certified curve, wherever the straight line between two samples needs one more
to be proved.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from app.checking.budget import Stop
from app.checking.certify import Certifier, straight_edges
from app.motion.blends import CURVE_SLACK, LINE_CUTS, Leg, Margins
from app.motion.leg_timing import LegNotTimed, timed_leg, times_at
from app.motion.trajectory import Trajectory


class _Timed(NamedTuple):
    """A timed leg: when it starts, its q(t) and s(t), and the leg."""

    start: float
    trajectory: object  # PathParameterizedTrajectory over the leg's own time
    s_of_t: object
    leg: Leg


def time_legs(plant, W, arc, legs, v, a, dt, joint_names, chords: Chords | None) -> Trajectory:
    """Each leg timed from rest to rest, the legs one after another, sampled as _sample_times says; chords: the
    clearance the certified curve keeps, and its motion bound (None: not certified)."""
    timed, waypoint_times, t = [], np.zeros(len(W)), 0.0
    for leg in legs:
        try:
            trajectory, s_of_t = timed_leg(plant, leg, v, a)
        except RuntimeError:
            raise LegNotTimed(leg) from None
        # When the motion passes each waypoint (a blended corner: the blend's middle, nearest the corner).
        inside = np.arange(leg.first, leg.last + 1)
        waypoint_times[inside] = t + times_at(s_of_t, arc[inside] - leg.offset)
        timed.append(_Timed(t, trajectory, s_of_t, leg))
        t += trajectory.end_time()
    return _sample(timed, W, waypoint_times, _sample_times(timed, dt, chords), joint_names, chords)


class Chords:
    """How the straight lines between a certified curve's samples are proved: the curve keeps `clearance`, the lines
    must keep half of it; `certifier` (its motion bound says how far a pair's distance can change over a change of
    q, and it proves the lines the bound alone does not cover), `stop` what bounds those proofs; `cost` sums them;
    `margins`: what the curve's proof found it keeps, piece by piece (app.motion.blends.Margins; None: only
    `clearance` is known)."""

    def __init__(
        self, clearance: float, certifier: Certifier, stop: Stop | None = None, margins: Margins | None = None
    ):
        self.clearance, self.certifier, self.stop, self.margins = clearance, certifier, stop, margins
        self.cost = {"pieces": 0, "distance_queries": 0, "seconds": 0.0}


def _sample_times(timed: list[_Timed], dt: float, chords: Chords | None) -> np.ndarray:
    """Every dt from 0, the end, each stop between legs (the robot rests there; a straight line across one would
    cut its corner), and, for a certified curve, more wherever the straight line between two samples is not proved
    to keep half the clearance.

    Within a leg q(s) is C1 with q'' constant on each piece (0 on straight ones, where the line lies on the curve),
    so the straight line between q(s_a) and q(s_b) lies within (s_b - s_a)^2 / 8 x max |q''| of the curve,
    coordinate by coordinate (linear interpolation's error); moved that far, a pair's distance changes by at most the
    motion bound's pair travel. A line where that is at most the curve's margin over its span less clearance / 2
    keeps half the clearance (the margin: what the curve's proof found its pieces keep, or else the clearance); the
    others are proved by the certificate, and one that fails is cut in two at the middle of its s (each half within
    a quarter of it), until every line is covered. A controller that interpolates linearly between the samples then
    keeps clearance / 2."""
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
        kept = chords.margins.on([part.leg]) if chords.margins is not None else None
        a, b = s[:-1], s[1:]
        while len(a):
            overlap = (a[:, None] < spans[None, :, 1]) & (b[:, None] > spans[None, :, 0])
            off = (
                (b - a)[:, None] ** 2 / 8 * np.max(np.where(overlap[:, :, None], bend[None], 0.0), axis=1) * CURVE_SLACK
            )
            reach = chords.certifier.bound.pair_travel(off).max(axis=(-2, -1))
            keeps = np.full(len(a), chords.clearance)
            if kept is not None:
                offset = part.leg.offset
                keeps = np.maximum(keeps, chords.margins.least(kept, a + offset, b + offset))
            ask = np.flatnonzero(reach > keeps - chords.clearance / 2)
            failed = _prove_lines(chords, part.leg.path, a[ask], b[ask])
            a, b = a[ask[failed]], b[ask[failed]]
            middle = 0.5 * (a + b)
            more.append(part.start + times_at(part.s_of_t, middle))
            a, b = np.concatenate([a, middle]), np.concatenate([middle, b])
    return np.unique(np.concatenate(more))


def _prove_lines(chords: Chords, path, a: np.ndarray, b: np.ndarray) -> np.ndarray:
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
    lines = straight_edges(ends, knots)
    _, stats = chords.certifier.certify(lines, intervals, chords.clearance / 2, floor, stop=chords.stop)
    for key in chords.cost:
        chords.cost[key] += stats[key]
    return np.array(stats["failed"], int)


def _sample(timed: list[_Timed], W, waypoint_times, times, joint_names, chords: Chords | None) -> Trajectory:
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
