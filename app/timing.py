"""Time parameterization of a checked polyline with Drake's Toppra, stopping at every waypoint.

The corner problem: on a piecewise-linear path Toppra sees zero curvature at the corners and does not slow down,
so the joint velocity would jump there. Here each straight segment is parameterized on its own, from rest to rest
(Drake's Toppra starts and ends each path at zero path velocity), and the segments are concatenated. The executed
path is then exactly the polyline that was collision-checked -- no blend leaves it -- and velocities and
accelerations stay within the limits everywhere, at the cost of a stop per waypoint (smoothing keeps them few).

Waypoints must be unwrapped first (`ConfigurationSpace.unwrap`), so that continuous angles take the short way.
"""
from __future__ import annotations

import numpy as np
# pydrake is imported inside `parameterize`, so that importing the package does not load Drake.

from app.trajectory import Trajectory


def _segment(plant, qa: np.ndarray, qb: np.ndarray, v: np.ndarray, a: np.ndarray):
    from pydrake.multibody.optimization import CalcGridPointsOptions, Toppra
    from pydrake.trajectories import PathParameterizedTrajectory, PiecewisePolynomial

    path = PiecewisePolynomial.FirstOrderHold([0.0, 1.0], np.column_stack([qa, qb]))
    # Along a straight segment the box limits do not vary with s, so a coarse grid is exact up to where the
    # switch points fall: 33 points (min_points 20) end within 0.2 % of the closed-form rest-to-rest time on maze
    # and window legs, at a fifth of the default grid's (129 points) cost.
    options = CalcGridPointsOptions()
    options.min_points = 20
    grid = Toppra.CalcGridPoints(path, options)
    toppra = Toppra(path, plant, grid)
    toppra.AddJointVelocityLimit(-v, v)
    toppra.AddJointAccelerationLimit(-a, a)
    s_of_t = toppra.SolvePathParameterization()
    if s_of_t is None:
        raise RuntimeError("Toppra found no time parameterization for a path segment")
    return PathParameterizedTrajectory(path, s_of_t)


def parameterize(plant, waypoints: np.ndarray, velocity_limits: np.ndarray, acceleration_limits: np.ndarray,
                 dt: float = 0.02, joint_names: list[str] | None = None) -> Trajectory:
    """Rest-to-rest Toppra per segment of the (unwrapped) waypoints, sampled every dt (and at the end)."""
    W = np.atleast_2d(np.asarray(waypoints, float))
    v = np.asarray(velocity_limits, float)
    a = np.asarray(acceleration_limits, float)
    if not (np.all(v > 0) and np.all(a > 0)):
        raise ValueError("velocity and acceleration limits must be positive")
    # An unlimited joint is limited by the others; Toppra wants finite bounds.
    v, a = np.where(np.isfinite(v), v, 1e9), np.where(np.isfinite(a), a, 1e9)
    segments, arrivals, t = [], [0.0], 0.0
    for qa, qb in zip(W[:-1], W[1:]):
        if np.allclose(qa, qb, rtol=0.0, atol=1e-12):
            arrivals.append(t)
            continue
        traj = _segment(plant, qa, qb, v, a)
        segments.append((t, traj))
        t += traj.end_time()
        arrivals.append(t)
    duration = t
    n = int(np.floor(duration / dt + 1e-9))
    times = np.arange(n + 1) * dt
    if duration - times[-1] > 1e-9:
        times = np.append(times, duration)
    dim = W.shape[1]
    positions = np.tile(W[0], (len(times), 1))
    velocities, accelerations = np.zeros((len(times), dim)), np.zeros((len(times), dim))
    starts = np.array([s[0] for s in segments]) if segments else np.zeros(0)
    for i, time in enumerate(times):
        if not segments:
            continue
        k = int(np.clip(np.searchsorted(starts, time, side="right") - 1, 0, len(segments) - 1))
        t0, traj = segments[k]
        local = min(time - t0, traj.end_time())
        positions[i] = traj.value(local).ravel()
        velocities[i] = traj.EvalDerivative(local, 1).ravel()
        accelerations[i] = traj.EvalDerivative(local, 2).ravel()
    if segments:
        positions[-1] = W[-1]  # exactly the goal, not Toppra's last evaluation of it
        velocities[-1] = 0.0  # and at rest there
    names = list(joint_names) if joint_names is not None else [f"q[{i}]" for i in range(dim)]
    return Trajectory(joint_names=names, times=times, positions=positions, velocities=velocities,
                      accelerations=accelerations, waypoints=W.copy(), waypoint_times=np.array(arrivals))
