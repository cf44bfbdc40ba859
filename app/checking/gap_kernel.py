"""The shape gaps' tiers (app.checking.shape_gaps), compiled: one row (configuration, pair) at a time.

A certificate round asks for a few ends and a few hundred rows past the bounding spheres; in numpy each tier was
dozens of calls on arrays that small, and the calls' overhead, not the arithmetic, was the round's time (on a mesh
arm, most of it: benchmark pages). Row by row in compiled code the arithmetic is all that is left. numba compiles
these on first use and caches the machine code beside this file (or in its user cache where that is not
writable), so only a first run pays for it.

`shapes` are the ShapeGaps tables (see there), as a tuple: per geometry a box core, a disc, a ball and a radius
about its centre; special, and an ellipsoid's semi-axes; hull, and a hull's vertices about its centre, rows
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
