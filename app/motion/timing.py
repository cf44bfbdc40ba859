"""Time parameterization of a polyline with Drake's Toppra: smooth through the corners where that is proved free,
stopping only where it is not (or where the caller wants a stop). The entry points: time_path (a planned path of a
scene), parameterize_smooth (waypoints, blended), parameterize (waypoints, rest to rest at each), scaled_limits,
check_duration and shortest_duration; and, from app.motion.blends, prove_blends and BlendProof. What they are made
of: the blended curve and its proof (app.motion.blends), Toppra on each leg between stops (app.motion.leg_timing),
and the samples a controller is given (app.motion.trajectory_samples).

Waypoints must be unwrapped first (`ConfigurationSpace.unwrap`), so that continuous angles take the short way.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from app.checking.budget import Stop
from app.checking.certify import CLEARANCE, Certifier
from app.errors import UserError
from app.motion.blends import (
    TIGHTEN,
    BlendProof,
    certified_radii,
    first_radii,
    legs_between_stops,
    path_geometry,
    prove_blends,
)
from app.motion.leg_timing import LegNotTimed
from app.motion.trajectory import Trajectory
from app.motion.trajectory_samples import Chords, time_legs

# The longest motion timed (s): a day. Limits scaled further down are refused (check_duration).
MAX_DURATION = 86400.0

# prove_blends and BlendProof are named here too: callers take them with the timing.
__all__ = [
    "MAX_DURATION",
    "BlendProof",
    "check_duration",
    "parameterize",
    "parameterize_smooth",
    "prove_blends",
    "scaled_limits",
    "shortest_duration",
    "time_path",
]


def _prepare(waypoints, velocity_limits, acceleration_limits, weights):
    """Waypoints without repeats, unit tangents and arc lengths in the weighted metric, finite positive limits."""
    W, tangent, arc, _ = path_geometry(waypoints, weights)
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
    legs = legs_between_stops(W, tangent, arc, np.zeros(len(W))) if len(W) > 1 else []
    return time_legs(plant, W, arc, legs, v, a, dt, joint_names, chords=None)


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
    stop: Stop | None = None,
) -> Trajectory:
    """A path of the checker's scene (wrapped waypoints) timed by parameterize_smooth under the scene's limits, scaled
    by velocity_scale and acceleration_scale (see scaled_limits), certified to keep `clearance`; it carries the
    scene's mimic joints. proof: the path's curve certified already (prove_blends), whose radii are then used as
    they are. stop: what bounds its proofs (their time limit and cancel flag)."""
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
        stop=stop,
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
    stop: Stop | None = None,
) -> Trajectory:
    """Blended corners, certified to keep `clearance` (app.motion.blends), timed with Toppra.

    The trajectory is `certified` when the whole executed curve keeps the clearance (blends and straight pieces)
    and the polyline the corners it cuts off, with half of it; its samples are then placed so that the straight
    lines between them keep half of it too (app.motion.trajectory_samples). If a straight piece of the polyline
    itself cannot be certified, the curve is still timed and returned, uncertified.
    floor: the certificate's bisection floor (default: app.checking.certify's); tighten: halvings of a failing blend
    before its corner becomes a stop. stats, if given, receives: stops (corners the robot stops at), pieces,
    distance_queries and seconds (certification), rounds (of blend tightening). certifier: one to reuse (its
    distances are cached). edges_proved: every straight edge of the waypoints' polyline is certified already (the
    planner's certificate, to keep `clearance`): then only the blends are. proof: the curve certified already
    (prove_blends on the wrapped waypoints these are unwrapped from): its radii and clearance are used. stop: what
    bounds the proofs.
    """
    W, v, a, tangent, arc = _prepare(waypoints, velocity_limits, acceleration_limits, checker.space.weights)
    known = np.full(max(len(W) - 1, 0), edges_proved)
    radii, margins = np.zeros(len(W)), None
    certified, cost = False, {"pieces": 0, "distance_queries": 0, "seconds": 0.0, "rounds": 0}
    if proof is not None:
        if len(proof.radii) != len(W):
            raise ValueError("the blend proof is of other waypoints")
        radii, certified, clearance, margins = proof.radii.copy(), not proof.failed, proof.clearance, proof.margins
    elif len(W) > 1:
        certifier = certifier or Certifier(checker, floor)
        first = first_radii(np.diff(arc))
        radii, failed, cost, margins = certified_radii(
            certifier, W, tangent, arc, first, tighten, known, clearance, stop=stop
        )
        certified = not failed
    while True:
        legs = legs_between_stops(W, tangent, arc, radii) if len(W) > 1 else []
        try:
            chords = None
            if certified:
                certifier = certifier or Certifier(checker, floor)
                chords = Chords(clearance, certifier, stop, margins)
            trajectory = time_legs(checker.oracle.plant, W, arc, legs, v, a, dt, joint_names, chords)
            if chords is not None:
                cost = {k: cost[k] + chords.cost.get(k, 0) for k in cost}
            break
        except LegNotTimed as failed:
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
                radii, refused, more, margins = certified_radii(
                    certifier, W, tangent, arc, radii, tighten, known, clearance, stop=stop
                )
                cost = {k: cost[k] + more[k] for k in cost}
                certified = not refused
    if stats is not None:
        stats.update(cost, stops=int(np.sum(radii[1:-1] == 0)))
    return trajectory
