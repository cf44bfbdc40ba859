"""The certificate's inner loops, compiled with numba: the shape gaps' tiers (app.checking.shape_gaps) one row
(configuration, pair) at a time, the motion bound's per-piece sums (app.checking.motion_bound) and the test of each
piece (app.checking.certify) one piece at a time.

A certificate round asks for a few ends and pieces, a few hundred rows past the bounding spheres: in numpy each step
was dozens of calls on arrays that small, and the calls' overhead, not the arithmetic, was the round's time (on a
mesh arm most of it: benchmark pages). In compiled loops the arithmetic is all that is left, done in the same order
(no fast-math), so a seed's answers do not depend on the machine. numba compiles these on first use and caches the
machine code beside this file (or in its user cache where that is not writable): only a first run pays for it (the
benchmark pages say how much). The callers import this module when they first need it, so that importing the
package (the command line's parser) does not load numba.

Shape gaps. `shapes` are the ShapeGaps tables (see there), as a tuple: per geometry a box core, a disc, a ball and a
radius about its centre; special, and an ellipsoid's semi-axes; hull, and a hull's vertices about its centre, rows
vstart[g]:vstart[g + 1] of verts. `poses` (shape_gaps.Poses): every shape's centre in configuration k, centres[k, g];
its rotation, robot_R[k, slot[g]] for a robot geometry (slot >= 0), env_R[g] for the environment's.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# Alternating projections between two shapes, for the direction of their gap.
PROJECTIONS = 2


@njit(cache=True)
def _project(R, p, core, disc, ball, x):
    """The point of a posed shape nearest to x (a hull's box's; an ellipsoid's centre), in the world."""
    local = np.empty(3)
    for i in range(3):
        local[i] = R[0, i] * (x[0] - p[0]) + R[1, i] * (x[1] - p[1]) + R[2, i] * (x[2] - p[2])
    near = np.empty(3)
    for i in range(3):
        near[i] = min(max(local[i], -core[i]), core[i])
    if disc > 0:
        shrink = min(1.0, disc / max(math.sqrt(local[0] ** 2 + local[1] ** 2), 1e-300))
        near[0], near[1] = local[0] * shrink, local[1] * shrink
    rest = math.sqrt((local[0] - near[0]) ** 2 + (local[1] - near[1]) ** 2 + (local[2] - near[2]) ** 2)
    shrink = min(1.0, ball / max(rest, 1e-300))
    for i in range(3):
        near[i] += (local[i] - near[i]) * shrink
    out = np.empty(3)
    for i in range(3):
        out[i] = p[i] + R[i, 0] * near[0] + R[i, 1] * near[1] + R[i, 2] * near[2]
    return out


@njit(cache=True)
def _distance_to(g, R, p, x, shapes):
    """A lower bound on the distance from x to posed shape g: to its nearest point as _project finds it (a hull's
    box holds the hull, so it is no farther), or for an ellipsoid, to its bounding sphere."""
    core, disc, ball, radius, special = shapes[:5]
    if special[g]:
        return max(math.sqrt((p[0] - x[0]) ** 2 + (p[1] - x[1]) ** 2 + (p[2] - x[2]) ** 2) - radius[g], 0.0)
    y = _project(R, p, core[g], disc[g], ball[g], x)
    return math.sqrt((y[0] - x[0]) ** 2 + (y[1] - x[1]) ** 2 + (y[2] - x[2]) ** 2)


@njit(cache=True)
def _support(g, R, n, exact, shapes):
    """max over posed shape g of n . (x - its centre), for a world direction n (unit): exact, or for a hull, its
    box's (larger) unless `exact`."""
    core, disc, ball, _, special, semi, hull, vstart, verts = shapes
    u0 = R[0, 0] * n[0] + R[1, 0] * n[1] + R[2, 0] * n[2]
    u1 = R[0, 1] * n[0] + R[1, 1] * n[1] + R[2, 1] * n[2]
    u2 = R[0, 2] * n[0] + R[1, 2] * n[1] + R[2, 2] * n[2]
    if special[g]:
        return math.sqrt((semi[g, 0] * u0) ** 2 + (semi[g, 1] * u1) ** 2 + (semi[g, 2] * u2) ** 2)
    if exact and hull[g]:
        best = -np.inf
        for v in range(vstart[g], vstart[g + 1]):
            best = max(best, verts[v, 0] * u0 + verts[v, 1] * u1 + verts[v, 2] * u2)
        return best
    c = core[g]
    return c[0] * abs(u0) + c[1] * abs(u1) + c[2] * abs(u2) + disc[g] * math.hypot(u0, u1) + ball[g]


@njit(cache=True)
def _along(a, Ra, pa, b, Rb, pb, d, exact, shapes):
    """The gap of shapes a and b along d (unit, from b to a)."""
    minus = -d
    return (
        d[0] * (pa[0] - pb[0])
        + d[1] * (pa[1] - pb[1])
        + d[2] * (pa[2] - pb[2])
        - _support(a, Ra, minus, exact, shapes)
        - _support(b, Rb, d, exact, shapes)
    )


@njit(cache=True)
def _unit(v):
    """v / |v|, or NaN where it is too short to give a direction."""
    length = math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2)
    return v / length if length > 1e-12 else np.full(3, np.nan)


@njit(cache=True)
def _gap(a, Ra, pa, b, Rb, pb, nhat, settle, shapes):
    """The largest gap between shapes a and b along three directions: Drake's where it has one (nhat, else NaN), and
    the normals of each shape at the near points that alternating projections onto the two find (a mesh as its box,
    an ellipsoid as its centre). With a hull and still below `settle`: again with the hull's vertices, along Drake's
    direction if it has one, else along the projections'."""
    core, disc, ball, hull = shapes[0], shapes[1], shapes[2], shapes[6]
    on_a = pa.copy()
    on_b = pb.copy()
    for _ in range(PROJECTIONS):
        on_b = _project(Rb, pb, core[b], disc[b], ball[b], on_a)
        on_a = _project(Ra, pa, core[a], disc[a], ball[a], on_b)
    directions = np.empty((3, 3))
    directions[0] = _unit(on_a - on_b)
    directions[1] = _unit(on_a - _project(Rb, pb, core[b], disc[b], ball[b], on_a))
    directions[2] = _unit(nhat)
    best = -np.inf
    for j in range(3):
        if math.isfinite(directions[j, 0]):
            gap = _along(a, Ra, pa, b, Rb, pb, directions[j], False, shapes)
            best = max(best, gap)
    if (hull[a] or hull[b]) and best < settle:
        drake = math.isfinite(directions[2, 0])
        for j in range(3):
            if math.isfinite(directions[j, 0]) and (j == 2 or not drake):
                gap = _along(a, Ra, pa, b, Rb, pb, directions[j], True, shapes)
                best = max(best, gap)
    return best


@njit(cache=True)
def _rotation(k, g, poses):
    _, env_R, robot_R, slot = poses
    return robot_R[k, slot[g]] if slot[g] >= 0 else env_R[g]


@njit(cache=True)
def near_bounds(pairs, poses, nhat, limit, need, shapes):
    """Lower bounds (configurations, pairs) on the distance of every pair in every configuration, each row stopping
    at the first tier that reaches min(need, limit): bounding spheres, each centre to the other shape, the gaps
    along three directions (see ShapeGaps.near)."""
    centres, radius = poses[0], shapes[3]
    n, count = need.shape
    out = np.empty((n, count))
    for k in range(n):
        for q in range(count):
            a, b = pairs[q, 0], pairs[q, 1]
            pa, pb = centres[k, a], centres[k, b]
            apart = math.sqrt((pa[0] - pb[0]) ** 2 + (pa[1] - pb[1]) ** 2 + (pa[2] - pb[2]) ** 2)
            bound = apart - radius[a] - radius[b]
            settle = min(need[k, q], limit[k])
            if bound < settle:
                Rb = _rotation(k, b, poses)
                bound = max(bound, _distance_to(b, Rb, pb, pa, shapes) - radius[a])
                if bound < settle:
                    Ra = _rotation(k, a, poses)
                    bound = max(bound, _distance_to(a, Ra, pa, pb, shapes) - radius[b])
                    if bound < settle:
                        bound = max(bound, _gap(a, Ra, pa, b, Rb, pb, nhat[k, q], settle, shapes))
            out[k, q] = bound
    return out


@njit(cache=True)
def gaps_along(ks, qs, d, pairs, poses, shapes):
    """The gaps of rows (configuration ks[i], pair qs[i]) along directions d[i] (unit, from the pair's second shape
    to its first), hulls by their vertices."""
    centres = poses[0]
    out = np.empty(len(ks))
    for i in range(len(ks)):
        k, a, b = ks[i], pairs[qs[i], 0], pairs[qs[i], 1]
        Ra, Rb = _rotation(k, a, poses), _rotation(k, b, poses)
        out[i] = _along(a, Ra, centres[k, a], b, Rb, centres[k, b], d[i], True, shapes)
    return out


@njit(cache=True)
def largest_per_end(travel, piece, first, pairs):
    """Per end, per pair of the gaps: the largest bound on the pair's change, travel[piece[i], a, b], over the pieces
    i in first[e]:first[e + 1] (the rows of end e; the last end's run to the end of `piece`)."""
    out = np.empty((len(first), len(pairs)))
    for e in range(len(first)):
        stop = first[e + 1] if e + 1 < len(first) else len(piece)
        for q in range(len(pairs)):
            a, b = pairs[q, 0], pairs[q, 1]
            largest = travel[piece[first[e]], a, b]
            for i in range(first[e] + 1, stop):
                largest = max(largest, travel[piece[i], a, b])
            out[e, q] = largest
    return out


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


@njit(cache=True)
def clear_pieces(pieces, end_a, end_b, first, counts, keys, distance, row_a, row_b, limit, travel):
    """The certificate's test of pieces (certify._clear): piece i is pieces[i] of travel (pieces, rows, rows), its
    ends end_a[i] and end_b[i] of a table of ends, each end's pairs rows first[e]:first[e] + counts[e] of keys
    (sorted within an end), distance, row_a, row_b, and its limit. Per piece: whether every pair either end reports
    is farther apart, summed over the two ends, than its bound (an end that does not report a pair has it at least
    its limit apart); by what factor the worst pair's bound exceeds its two distances (at least 1); the least of
    every pair's two distances less its bound (a pair neither end reports: both limits less the largest bound)."""
    n = len(pieces)
    passed, short, slack = np.ones(n, np.bool_), np.ones(n), np.empty(n)
    for i in range(n):
        bounds = travel[pieces[i]]
        least = limit[end_a[i]] + limit[end_b[i]] - bounds.max()
        for side in range(2):
            this, other = (end_a[i], end_b[i]) if side == 0 else (end_b[i], end_a[i])
            j, stop = first[other], first[other] + counts[other]
            for r in range(first[this], first[this] + counts[this]):
                while j < stop and keys[j] < keys[r]:
                    j += 1
                there = distance[j] if j < stop and keys[j] == keys[r] else limit[other]
                bound = bounds[row_a[r], row_b[r]]
                total = distance[r] + there
                if total <= bound:
                    passed[i] = False
                short[i] = max(short[i], bound / max(total, 1e-300))
                least = min(least, total - bound)
        slack[i] = least
    return passed, short, slack
