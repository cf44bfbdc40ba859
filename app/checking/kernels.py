"""The inner loops of the certificate, the forward kinematics and the edge checks, compiled with numba: the shape
gaps' tiers (app.checking.shape_gaps) one row (configuration, pair) at a time, the motion bound's per-piece sums
(app.checking.motion_bound) and the test of each piece (app.checking.certify) one piece at a time, the products
along a kinematic tree (app.checking.kinematics), the points of a batch of edges in the order they are checked
(app.checking.context), and the lazy search's steps around its checks: the next candidate path, and a colliding edge
out of its graph and its shortest-path trees (app.planning.roadmap, app.planning.graph).

A certificate round asks for a few ends and pieces, a few hundred rows past the bounding spheres: in numpy each step
was dozens of calls on arrays that small, and the calls' overhead, not the arithmetic, was the round's time (on a
mesh arm most of it: benchmark pages). In compiled loops the arithmetic is all that is left, done in the order
written (no fast-math), so a seed's answers do not depend on the machine. numba compiles these on a machine's first
run and caches the machine code beside this file (or in its user cache where that is not writable); the benchmark
pages say what that costs. The oracle loads every kernel as it is made (`load`), so that no query's time includes
it; the other callers import this module inside their functions, so that importing the package (the command line's
parser) does not load numba.

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

# Points and directions are 3-tuples of floats, not arrays: a row's tiers would otherwise allocate a dozen small
# arrays, which cost more than their arithmetic.


@njit(cache=True)
def _project(R, p, core, disc, ball, x):
    """The point of a posed shape nearest to x (a hull's box's; an ellipsoid's centre), in the world."""
    d0, d1, d2 = x[0] - p[0], x[1] - p[1], x[2] - p[2]
    l0 = R[0, 0] * d0 + R[1, 0] * d1 + R[2, 0] * d2
    l1 = R[0, 1] * d0 + R[1, 1] * d1 + R[2, 1] * d2
    l2 = R[0, 2] * d0 + R[1, 2] * d1 + R[2, 2] * d2
    n0, n1, n2 = min(max(l0, -core[0]), core[0]), min(max(l1, -core[1]), core[1]), min(max(l2, -core[2]), core[2])
    if disc > 0:
        shrink = min(1.0, disc / max(math.sqrt(l0 * l0 + l1 * l1), 1e-300))
        n0, n1 = l0 * shrink, l1 * shrink
    r0, r1, r2 = l0 - n0, l1 - n1, l2 - n2
    shrink = min(1.0, ball / max(math.sqrt(r0 * r0 + r1 * r1 + r2 * r2), 1e-300))
    n0, n1, n2 = n0 + r0 * shrink, n1 + r1 * shrink, n2 + r2 * shrink
    return (
        p[0] + R[0, 0] * n0 + R[0, 1] * n1 + R[0, 2] * n2,
        p[1] + R[1, 0] * n0 + R[1, 1] * n1 + R[1, 2] * n2,
        p[2] + R[2, 0] * n0 + R[2, 1] * n1 + R[2, 2] * n2,
    )


@njit(cache=True)
def _length(x0, x1, x2):
    return math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)


@njit(cache=True)
def _distance_to(g, R, p, x, shapes):
    """A lower bound on the distance from x to posed shape g: to its nearest point as _project finds it (a hull's
    box holds the hull, so it is no farther), or for an ellipsoid, to its bounding sphere."""
    core, disc, ball, radius, special = shapes[:5]
    if special[g]:
        return max(_length(p[0] - x[0], p[1] - x[1], p[2] - x[2]) - radius[g], 0.0)
    y = _project(R, p, core[g], disc[g], ball[g], x)
    return _length(y[0] - x[0], y[1] - x[1], y[2] - x[2])


@njit(cache=True)
def _support(g, R, n0, n1, n2, exact, shapes):
    """max over posed shape g of n . (x - its centre), for a world direction n (unit): exact, or for a hull, its
    box's (larger) unless `exact`."""
    core, disc, ball, _, special, semi, hull, vstart, verts = shapes
    u0 = R[0, 0] * n0 + R[1, 0] * n1 + R[2, 0] * n2
    u1 = R[0, 1] * n0 + R[1, 1] * n1 + R[2, 1] * n2
    u2 = R[0, 2] * n0 + R[1, 2] * n1 + R[2, 2] * n2
    if special[g]:
        return _length(semi[g, 0] * u0, semi[g, 1] * u1, semi[g, 2] * u2)
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
    d0, d1, d2 = d[0], d[1], d[2]
    return (
        d0 * (pa[0] - pb[0])
        + d1 * (pa[1] - pb[1])
        + d2 * (pa[2] - pb[2])
        - _support(a, Ra, -d0, -d1, -d2, exact, shapes)
        - _support(b, Rb, d0, d1, d2, exact, shapes)
    )


@njit(cache=True)
def _unit(x0, x1, x2):
    """x / |x|, or NaN where it is too short to give a direction."""
    length = _length(x0, x1, x2)
    if length > 1e-12:
        return (x0 / length, x1 / length, x2 / length)
    return (np.nan, np.nan, np.nan)


@njit(cache=True)
def _gap(a, Ra, pa, b, Rb, pb, nhat, settle, shapes):
    """The largest gap between shapes a and b along three directions: Drake's where it has one (nhat, else NaN), and
    the normals of each shape at the near points that alternating projections onto the two find (a mesh as its box,
    an ellipsoid as its centre). With a hull and still below `settle`: again with the hull's vertices, along Drake's
    direction if it has one, else along the projections'."""
    core, disc, ball, hull = shapes[0], shapes[1], shapes[2], shapes[6]
    on_a = (pa[0], pa[1], pa[2])
    on_b = on_a
    for _ in range(PROJECTIONS):
        on_b = _project(Rb, pb, core[b], disc[b], ball[b], on_a)
        on_a = _project(Ra, pa, core[a], disc[a], ball[a], on_b)
    back = _project(Rb, pb, core[b], disc[b], ball[b], on_a)
    directions = (
        _unit(on_a[0] - on_b[0], on_a[1] - on_b[1], on_a[2] - on_b[2]),
        _unit(on_a[0] - back[0], on_a[1] - back[1], on_a[2] - back[2]),
        _unit(nhat[0], nhat[1], nhat[2]),
    )
    best = -np.inf
    for d in directions:
        if math.isfinite(d[0]):
            best = max(best, _along(a, Ra, pa, b, Rb, pb, d, False, shapes))
    if (hull[a] or hull[b]) and best < settle:
        drake = math.isfinite(directions[2][0])
        for j in range(3):
            d = directions[j]
            if math.isfinite(d[0]) and (j == 2 or not drake):
                best = max(best, _along(a, Ra, pa, b, Rb, pb, d, True, shapes))
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
            apart = _length(
                centres[k, a, 0] - centres[k, b, 0],
                centres[k, a, 1] - centres[k, b, 1],
                centres[k, a, 2] - centres[k, b, 2],
            )
            bound = apart - radius[a] - radius[b]
            settle = min(need[k, q], limit[k])
            if bound < settle:  # most rows stop at their spheres: no views are made for them
                pa, pb = centres[k, a], centres[k, b]
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
        out[i] = _along(a, Ra, centres[k, a], b, Rb, centres[k, b], (d[i, 0], d[i, 1], d[i, 2]), True, shapes)
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
def body_poses(turn, bend, tables, parent, moving, welded_R, welded_p):
    """World rotations (n, bodies, 3, 3) and positions (n, bodies, 3) of a tree's bodies, parents before children
    (app.checking.kinematics): body b's pose in its parent's frame is welded_*[b] where moving[b] < 0, else the
    12 numbers [1, turn, bend] @ tables[moving[b]] (R row-major, then p), turn and bend (n, moving bodies) being
    sin q and 1 - cos q of a revolute joint, q and 0 of a prismatic one; parent -1: the world."""
    n, bodies = turn.shape[0], len(parent)
    R, p = np.empty((n, bodies, 3, 3)), np.empty((n, bodies, 3))
    local = np.empty(12)
    for k in range(n):
        for b in range(bodies):
            if parent[b] < 0:
                R[k, b] = np.eye(3)
                p[k, b] = 0.0
                continue
            m = moving[b]
            if m < 0:
                for j in range(9):
                    local[j] = welded_R[b, j // 3, j % 3]
                for j in range(3):
                    local[9 + j] = welded_p[b, j]
            else:
                for j in range(12):
                    local[j] = tables[m, 0, j] + turn[k, m] * tables[m, 1, j] + bend[k, m] * tables[m, 2, j]
            P = R[k, parent[b]]
            for i in range(3):
                for j in range(3):
                    R[k, b, i, j] = P[i, 0] * local[j] + P[i, 1] * local[3 + j] + P[i, 2] * local[6 + j]
                p[k, b, i] = p[k, parent[b], i] + (P[i, 0] * local[9] + P[i, 1] * local[10] + P[i, 2] * local[11])
    return R, p


@njit(cache=True)
def frame_origins_at(R, p, body, frame_p):
    """The world origin (n, 3) of a frame at frame_p[i] on body[i] in configuration i, from the bodies' world poses
    R (n, bodies, 3, 3) and p (n, bodies, 3)."""
    out = np.empty((len(body), 3))
    for k in range(len(body)):
        B, x = R[k, body[k]], frame_p[k]
        for i in range(3):
            out[k, i] = p[k, body[k], i] + (B[i, 0] * x[0] + B[i, 1] * x[1] + B[i, 2] * x[2])
    return out


@njit(cache=True)
def frame_poses(R, p, body, frame_R, frame_p):
    """World rotations (n, frames, 3, 3) and origins (n, frames, 3) of frames fixed on bodies (frame f on body[f] at
    (frame_R[f], frame_p[f])), from the bodies' world poses R (n, bodies, 3, 3) and p (n, bodies, 3)."""
    n, frames = R.shape[0], len(body)
    rotations, origins = np.empty((n, frames, 3, 3)), np.empty((n, frames, 3))
    for k in range(n):
        for f in range(frames):
            B, X, x = R[k, body[f]], frame_R[f], frame_p[f]
            for i in range(3):
                for j in range(3):
                    rotations[k, f, i, j] = B[i, 0] * X[0, j] + B[i, 1] * X[1, j] + B[i, 2] * X[2, j]
                origins[k, f, i] = p[k, body[f], i] + (B[i, 0] * x[0] + B[i, 1] * x[1] + B[i, 2] * x[2])
    return rotations, origins


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


@njit(cache=True)
def _coarse_to_fine(n, out):
    """Indices 0..n-1 into out[:n], endpoints first, then by bisection (van der Corput): a collision shows early."""
    if n <= 2:
        for i in range(n):
            out[i] = i
        return
    seen = np.zeros(n, np.bool_)
    out[0], out[1], seen[0], seen[n - 1] = 0, n - 1, True, True
    count, denominator = 2, 2
    while count < n:
        for k in range(1, denominator, 2):
            i = int(round(k * (n - 1) / denominator))  # round half to even, as Python's round
            if not seen[i]:
                seen[i] = True
                out[count] = i
                count += 1
        denominator *= 2


@njit(cache=True)
def _wrap(x):
    """An angle into [-pi, pi) as numpy's (x + pi) % (2 pi) - pi: the remainder is the identity on [0, 2 pi), so only
    an angle past it pays for fmod."""
    y = x + np.pi
    return (y if 0.0 <= y < 2 * np.pi else y % (2 * np.pi)) - np.pi


@njit(cache=True)
def edge_points(Q1, Q2, resolution, skip, done, table, wrapped):
    """The points of the straight edges Q1[e] -> Q2[e] (the short way round on the continuous angles `wrapped`) in
    the order an edge check asks them (context.QueryContext.edges_status). table: the space's lower and upper bounds
    as within_bounds compares, and its weights, as rows. An edge of length L (weighted) is cut into
    n = max(1, ceil(L / resolution)) segments; its n + 1 points are ordered coarse to fine, the first `skip` and the
    next done[e] left out, and asked round by round (round r: the points at positions 2^r - 1 .. 2^(r+1) - 2 of an
    edge's order), edge by edge within a round. Returns the points (wrapped into [-pi, pi) on the continuous angles),
    their edge, whether each is within the bounds, each edge's last point's index (-1: none), per point the index
    past its round's last point, the first point out of bounds (the count: none), and how many points rounds 0-2
    hold (at least 1: a check's opening slice)."""
    m, dim = Q1.shape
    D, n = np.empty((m, dim)), np.empty(m, np.int64)
    for e in range(m):
        for c in range(dim):
            D[e, c] = Q2[e, c] - Q1[e, c]
        for c in wrapped:
            D[e, c] = _wrap(D[e, c])
        squares = 0.0
        for c in range(dim):
            x = D[e, c] * table[2, c]
            squares += x * x
        n[e] = max(1, math.ceil(math.sqrt(squares) / resolution))
    length = np.maximum(n + 1 - skip, 0)
    total, top = 0, 0
    for e in range(m):
        if length[e] > done[e]:
            total += length[e] - done[e]
            top = max(top, length[e])
    first = np.zeros(m + 1, np.int64)
    for e in range(m):
        first[e + 1] = first[e] + n[e] + 1
    order = np.empty(first[m], np.int64)
    for e in range(m):
        if length[e] > done[e]:
            _coarse_to_fine(n[e] + 1, order[first[e] :])
    points, owner = np.empty((total, dim)), np.empty(total, np.int64)
    inside, last, round_end = np.empty(total, np.bool_), np.full(m, -1, np.int64), np.empty(total, np.int64)
    k, r, outside, opening = 0, 0, total, total
    while (1 << r) <= top:
        start = k
        for e in range(m):
            for j in range(max((1 << r) - 1, done[e]), min((1 << (r + 1)) - 1, length[e])):
                t = order[first[e] + skip + j] / n[e]
                point = points[k]
                for c in range(dim):
                    point[c] = Q1[e, c] + t * D[e, c]
                for c in wrapped:
                    point[c] = _wrap(point[c])
                within = True
                for c in range(dim):
                    within &= table[0, c] <= point[c] <= table[1, c]
                if not within and outside == total:
                    outside = k
                owner[k], inside[k], last[e] = e, within, k
                k += 1
        round_end[start:k] = k
        if r == 2:
            opening = k
        r += 1
    return points, owner, inside, last, round_end, outside, max(opening, 1)


@njit(cache=True)
def kill_edges(rows, ends, alive, keys, lengths, synced):
    """Edge rows found to collide (app.planning.roadmap.Roadmap._kill): not alive, and those merged into the search's
    graph (rows below synced) out of it, their two entries' lengths infinite (an entry's key: from << 32 | to, in
    sorted keys). Returns how many were merged."""
    merged = 0
    for r in rows:
        alive[r] = False
        if r < synced:
            u, v = ends[r, 0], ends[r, 1]
            lengths[np.searchsorted(keys, u << 32 | v)] = np.inf
            lengths[np.searchsorted(keys, v << 32 | u)] = np.inf
            merged += 1
    return merged


@njit(cache=True)
def cut_tree(P, pred, first, kids, dead):
    """Edges P (node index pairs) are gone from a shortest-path tree (predecessors pred; a node's children
    kids[first[v]:first[v + 1]]): the child end of each that is a tree edge, and every node below it, dead (a dead
    node's subtree is dead already)."""
    stack = np.empty(len(dead), np.int64)
    for i in range(len(P)):
        u, v = P[i, 0], P[i, 1]
        child = v if pred[v] == u else u if pred[u] == v else -1
        if child < 0 or dead[child]:
            continue
        stack[0], size = child, 1
        while size:
            size -= 1
            w = stack[size]
            dead[w] = True
            for k in range(first[w], first[w + 1]):
                stack[size] = kids[k]
                size += 1


@njit(cache=True)
def _entry(indptr, indices, u, v):
    """Where the entry (u, v) of a CSR graph with sorted indices is."""
    lo, hi = indptr[u], indptr[u + 1]
    while lo < hi:
        mid = (lo + hi) // 2
        if indices[mid] < v:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True)
def next_candidate(order, at, taken, pred_a, pred_b, dead_a, dead_b, indptr, indices, rows_of, checked, nodes, rows):
    """The lazy search's next candidate path (app.planning.roadmap.Roadmap.shortest_path): the first node m of
    order[at:] that no candidate on these trees has taken, whose path up each shortest-path tree (predecessors pred_a,
    pred_b) has lost no edge (dead_a, dead_b), and whose two tree paths do not cross. Its path -- the first tree's
    root to m, then m to the second tree's root -- goes into nodes, each node marked taken, and the rows of its edges
    not yet checked into rows (an edge's row: rows_of at its entry in the graph indptr, indices). Returns the
    position after m, the path's node count and the unchecked rows' count; a position of -1 when no node is left."""
    on_path = np.zeros(len(taken), np.bool_)
    for i in range(at, len(order)):
        m = order[i]
        if taken[m] or dead_a[m] or dead_b[m]:
            continue
        count, v = 1, m
        nodes[0] = m
        while pred_a[v] >= 0:
            v = pred_a[v]
            nodes[count] = v
            count += 1
        nodes[:count] = nodes[:count][::-1].copy()
        v = m
        while pred_b[v] >= 0:
            v = pred_b[v]
            nodes[count] = v
            count += 1
        crossing, marked = False, 0
        while marked < count and not crossing:
            crossing = on_path[nodes[marked]]
            on_path[nodes[marked]] = True
            marked += 1
        for j in range(marked):
            on_path[nodes[j]] = False
        if crossing:
            continue
        unchecked = 0
        for j in range(count):
            taken[nodes[j]] = True
            if j:
                row = rows_of[_entry(indptr, indices, nodes[j - 1], nodes[j])]
                if not checked[row]:
                    rows[unchecked] = row
                    unchecked += 1
        return i + 1, count, unchecked
    return -1, 0, 0


def load() -> None:
    """Every kernel compiled (on a machine's first run) or loaded from the cache now, for the argument types its
    callers pass: the oracle calls this as it is made, so that no query's time includes it."""
    f, i, b = np.zeros, (lambda *shape: np.zeros(shape, np.int64)), (lambda *shape: np.zeros(shape, np.bool_))
    j = np.zeros(1, np.int32)  # scipy's predecessors and a CSR graph's index arrays
    vstart = i(3)
    shapes = (f((2, 3)), f(2), f(2), f(2), b(2), f((2, 3)), b(2), vstart, f((0, 3)))
    poses = (f((1, 2, 3)), f((2, 3, 3)), f((1, 1, 3, 3)), i(2))
    pairs = i(1, 2)
    near_bounds(pairs, poses, f((1, 1, 3)), f(1), f((1, 1)), shapes)
    gaps_along(i(1), i(1), f((1, 3)), pairs, poses, shapes)
    largest_per_end(f((1, 2, 2)), i(1), i(1), pairs)
    R, p = body_poses(f((1, 1)), f((1, 1)), f((1, 3, 12)), i(1) - 1, i(1) - 1, f((1, 3, 3)), f((1, 3)))
    frame_poses(R, p, i(1), f((1, 3, 3)), f((1, 3)))
    frame_origins_at(R, p, i(1), f((1, 3)))
    levers, linear, angular = lever_arms(R, p, f((0, 3)), i(0), i(1), f(1), b(2, 1), i(0), f((0, 3)), i(0), 1)
    rows = f((2, 1))
    piece_travel(
        f((1, 1)),
        i(1),
        i(1),
        levers,
        rows,
        f((2, 1, 1)),
        f((2, 1, 2)),
        True,
        *(f((1, 1)),) * 3,
        linear,
        angular,
        f(2),
        b(1),
        1.0,
    )
    clear_pieces(i(1), i(1), i(1), i(1), i(1), i(0), f(0), i(0), i(0), f(1), f((1, 2, 2)))
    edge_points(f((1, 1)), f((1, 1)), 1.0, 2, i(1), f((3, 1)), i(0))
    next_candidate(i(1), 0, b(1), j - 1, j - 1, b(1), b(1), np.zeros(2, np.int32), j[:0], i(0), b(0), i(1), i(1))
    cut_tree(i(1, 2), j - 1, i(2), i(1), b(1))
    kill_edges(i(1), i(1, 2), b(1), i(2), f(2), 1)
