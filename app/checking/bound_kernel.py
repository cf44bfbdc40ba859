"""The motion bound's per-piece sums (app.checking.motion_bound), compiled: one piece at a time.

A certificate round bounds a few pieces, each over every pair of a robot's geometries and its coordinates: in numpy,
a few dozen calls on arrays of that size, whose overhead, not their arithmetic, was the time (see gap_kernel). numba
compiles these on first use and caches the machine code beside this file (or in its user cache).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def lever_arms(R, p, axes, columns, centres, radius, chain, slide_frames, slide_axes, slide_columns, dim):
    """MotionBound.local's arrays at n configurations, from the poses R (n, frames, 3, 3) and p (n, frames, 3) of
    the revolute axes' frames (the first len(axes)), the robot rows' centres (frames `centres`) and the prismatic
    joints' frames (`slide_frames`): per configuration, row (the environment's last) and coordinate, the lever arm
    about the coordinate's axis (inf where it has none), and the row centre's velocity and its angular velocity per
    unit of the coordinate, coordinates first (n, dim, rows x 3)."""
    n, rows = R.shape[0], len(radius)
    levers = np.full((n, rows + 1, dim), np.inf)
    linear = np.zeros((n, dim, (rows + 1) * 3))
    angular = np.zeros((n, dim, (rows + 1) * 3))
    u = np.empty(3)
    for k in range(n):
        for a in range(len(axes)):
            j = columns[a]
            for i in range(3):
                u[i] = R[k, a, i, 0] * axes[a, 0] + R[k, a, i, 1] * axes[a, 1] + R[k, a, i, 2] * axes[a, 2]
            for r in range(rows):
                v0 = p[k, centres[r], 0] - p[k, a, 0]
                v1 = p[k, centres[r], 1] - p[k, a, 1]
                v2 = p[k, centres[r], 2] - p[k, a, 2]
                t0, t1, t2 = u[1] * v2 - u[2] * v1, u[2] * v0 - u[0] * v2, u[0] * v1 - u[1] * v0
                levers[k, r, j] = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2) + radius[r]
                if chain[r, j]:
                    linear[k, j, 3 * r], linear[k, j, 3 * r + 1], linear[k, j, 3 * r + 2] = t0, t1, t2
                    angular[k, j, 3 * r], angular[k, j, 3 * r + 1], angular[k, j, 3 * r + 2] = u[0], u[1], u[2]
        for s in range(len(slide_frames)):
            f, j = slide_frames[s], slide_columns[s]
            for i in range(3):
                axis = slide_axes[s]
                u[i] = R[k, f, i, 0] * axis[0] + R[k, f, i, 1] * axis[1] + R[k, f, i, 2] * axis[2]
            for r in range(rows):
                for i in range(3):
                    linear[k, j, 3 * r + i] = u[i] if chain[r, j] else 0.0
    return levers, linear, angular


@njit(cache=True)
def _speed(velocity, linear, angular, radius, out):
    """Into out (rows): the largest speed of a point of each row's geometry, |v_c| + |w| rho, at the coordinates'
    velocity (dim), from one configuration's linear and angular (dim, rows x 3)."""
    for r in range(len(radius)):
        v0 = v1 = v2 = w0 = w1 = w2 = 0.0
        for j in range(len(velocity)):
            v0 += velocity[j] * linear[j, 3 * r]
            v1 += velocity[j] * linear[j, 3 * r + 1]
            v2 += velocity[j] * linear[j, 3 * r + 2]
            w0 += velocity[j] * angular[j, 3 * r]
            w1 += velocity[j] * angular[j, 3 * r + 1]
            w2 += velocity[j] * angular[j, 3 * r + 2]
        out[r] = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2) + math.sqrt(w0 * w0 + w1 * w1 + w2 * w2) * radius[r]


@njit(cache=True)
def piece_travel(
    variation, end_a, end_b, levers, rates, below, unshared, along, da, db, dd, linear, angular, radius, revolute, slack
):
    """Bounds (n, rows, rows) on how much each pair's distance changes along n pieces, and the rates (n, rows, dim)
    that hold all along them (see MotionBound.piece_bounds; where `along`, the lesser of the two bounds): piece p
    moves each coordinate by variation[p] between ends end_a[p] and end_b[p], rows of the local arrays levers (ends,
    rows, dim), linear and angular (ends, dim, rows x 3); da, db, dd (n, dim): the curve's velocity at the ends and a
    bound on its acceleration, per unit of a parameter running from 0 to 1 along the piece."""
    n, dim = variation.shape
    rows = rates.shape[0]
    out = np.empty((n, rows, rows))
    piece_rates = np.empty((n, rows, dim))
    own = np.empty((rows, rows))
    reach_a, reach_b = np.empty(rows), np.empty(rows)
    speed, turning = np.empty(dim), np.empty(dim)
    for q in range(n):
        a, b = end_a[q], end_b[q]
        piece = piece_rates[q]
        # The rates: each end's lever plus how far the joints between the axis and the row move it.
        for r in range(rows):
            for j in range(dim):
                grow = 0.0
                for k in range(dim):
                    grow += rates[r, k] * variation[q, k] * below[r, j, k]
                piece[r, j] = min(rates[r, j], min(levers[a, r, j], levers[b, r, j]) + grow)
        # The travel: P's over the coordinates the pair counts, plus Q's.
        own[:] = 0.0
        for P in range(rows):
            for j in range(dim):
                share = piece[P, j] * variation[q, j]
                if share != 0.0:
                    for Q in range(rows):
                        own[P, Q] += share * unshared[P, j, Q]
        for P in range(rows):
            for Q in range(rows):
                out[q, P, Q] = own[P, Q] + own[Q, P]
        if not along:
            continue
        # The bound from the motion: the speed of each row's points at either end, plus how much it can change.
        for j in range(dim):
            speed[j] = 0.5 * (abs(da[q, j]) + abs(db[q, j]) + dd[q, j])
            turning[j] = speed[j] if revolute[j] else 0.0
        _speed(da[q], linear[a], angular[a], radius, reach_a)
        _speed(db[q], linear[b], angular[b], radius, reach_b)
        for r in range(rows):
            change = 0.0
            for j in range(dim):
                inboard = 0.0
                for k in range(dim):
                    inboard += turning[k] * below[r, k, j]
                change += piece[r, j] * (speed[j] * (turning[j] + 2 * inboard) + dd[q, j])
            reach_a[r] += 0.5 * change
            reach_b[r] += 0.5 * change
        for P in range(rows):
            for Q in range(rows):
                bound = max(reach_a[P] + reach_a[Q], reach_b[P] + reach_b[Q]) * slack
                out[q, P, Q] = min(out[q, P, Q], bound)
    return out, piece_rates
