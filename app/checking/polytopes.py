"""Signed distances from many workspace points to an environment of convex polytopes, in numpy.

The workspace gap search asks, for thousands of points, which environment pieces lie within a gap's width and in
which direction. SceneGraph answers one point per call, each call dear among the thousand pieces of a decomposed
mesh, and refuses points near some sliver hulls. Boxes and convex hulls (the pieces of every shipped scene and of
every decomposed mesh) are polytopes: a point's distance to one is the least of its triangles', and the point is
inside where every face plane has it behind: a handful of products per point and triangle, done for a whole batch
at once. A KD-tree of the points and the pieces' bounding boxes leave out the pieces a point cannot reach.
"""

from __future__ import annotations

import numpy as np

# Triangle rows (a point and a triangle of a piece near it) handled at once: about 200 MB of temporaries.
ROWS = 1 << 20
# Points times pieces up to which every pair goes to the bounding-box test without the KD-tree.
DENSE = 4096


class Polytopes:
    """Convex polytopes fixed in the world, each given by its faces: loops of world-frame vertices (k, 3) in order
    around the face, either way round."""

    def __init__(self, faces: list[list[np.ndarray]]):
        corners, pieces = [], []
        for index, loops in enumerate(faces):
            for loop in loops:
                loop = np.asarray(loop, float)
                for i in range(1, len(loop) - 1):  # a convex face as a fan of triangles
                    corners.append((loop[0], loop[i], loop[i + 1]))
                    pieces.append(index)
        T = np.array(corners, float).reshape(-1, 3, 3)
        vertices = [np.concatenate(loops).reshape(-1, 3) if loops else np.zeros((1, 3)) for loops in faces]
        # Each face turned to look outward: away from a point inside its piece, the mean of its vertices.
        mean = np.array([v.mean(axis=0) for v in vertices]).reshape(-1, 3)
        normal = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
        inward = np.einsum("ij,ij->i", normal, T[:, 0] - mean[np.asarray(pieces, int)]) < 0
        T[inward], normal[inward] = T[inward][:, [0, 2, 1]], -normal[inward]
        area = np.linalg.norm(normal, axis=1)
        # A sliver of no area adds no point to its piece's surface (its edges belong to its neighbours) and no
        # direction to its inside.
        keep = area > 1e-12 * max(float(np.abs(T).max(initial=0.0)), 1.0) ** 2
        self.triangles, self.normals = T[keep], normal[keep] / area[keep, None]
        self.offsets = np.einsum("ij,ij->i", self.normals, self.triangles[:, 0])  # planes: n . x = offset
        self.edges = self.triangles[:, 1:] - self.triangles[:, :1]  # b - a, c - a
        E = self.edges
        self.dots = np.stack([(E[:, 0] ** 2).sum(1), (E[:, 0] * E[:, 1]).sum(1), (E[:, 1] ** 2).sum(1)], axis=1)
        self.piece = np.asarray(pieces, int)[keep]
        self.count = len(faces)
        # Triangles are listed piece by piece: a piece's run starts at `start`.
        self.start = np.searchsorted(self.piece, np.arange(self.count))
        self.size = np.bincount(self.piece, minlength=self.count)
        self.lower = np.array([v.min(axis=0) for v in vertices]).reshape(-1, 3)
        self.upper = np.array([v.max(axis=0) for v in vertices]).reshape(-1, 3)
        self.centres = (self.lower + self.upper) / 2
        self.radii = np.array([np.linalg.norm(v - c, axis=1).max() for v, c in zip(vertices, self.centres)])

    def near(self, P: np.ndarray, reach: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The points (n, 3) and pieces within `reach` (n,) of each other, with their signed distances:
        (point index, distance, unit gradient of the distance at the point, (m, 3)), by point. A point inside a
        piece has a negative distance (to the nearest face plane, exact for a convex piece) and no gradient (zero)."""
        P = np.atleast_2d(np.asarray(P, float))
        none = np.empty(0, int), np.empty(0), np.empty((0, 3))
        if not self.count or not len(P):
            return none
        points, pieces = pairs_near(P, reach, self.centres, self.radii)
        # The distance to a piece's bounding box is a lower bound of the distance to the piece.
        outside = np.maximum(self.lower[pieces] - P[points], P[points] - self.upper[pieces])
        box = np.linalg.norm(np.maximum(outside, 0), axis=1)
        keep = (box <= reach[points]) & (self.size[pieces] > 0)
        points, pieces = points[keep], pieces[keep]
        if not len(points):
            return none
        # Pairs in chunks of about ROWS triangle rows: a point among hundreds of pieces needs thousands of rows.
        rows = np.cumsum(self.size[pieces])
        if rows[-1] <= ROWS:
            at, distance, closest = self._distances(P[points], pieces, reach[points])
            points = points[at]
        else:
            found = []
            for chunk in np.split(np.arange(len(points)), np.searchsorted(rows, np.arange(ROWS, rows[-1], ROWS))):
                at, distance, closest = self._distances(P[points[chunk]], pieces[chunk], reach[points[chunk]])
                found.append((points[chunk][at], distance, closest))
            points, distance, closest = (np.concatenate(column) for column in zip(*found))
        gradient = np.zeros_like(closest)
        outside = distance > 0
        gradient[outside] = (P[points[outside]] - closest[outside]) / distance[outside, None]
        return points, distance, gradient

    def _distances(self, P: np.ndarray, pieces: np.ndarray, reach: np.ndarray) -> tuple[np.ndarray, ...]:
        """Of the points (m, 3) and pieces (m,), the pairs within `reach` (m,): their indices, signed distances and
        the pieces' nearest surface points. The greatest height above a piece's face planes is a lower bound of the
        distance (its signed distance, inside), so pieces it puts beyond reach are dropped before the triangles."""
        runs = self.size[pieces]
        first = np.cumsum(runs) - runs  # where each pair's run of triangles starts in the flat rows below
        row = _runs(self.start[pieces], runs)
        pair = np.repeat(np.arange(len(pieces)), runs)
        height = np.einsum("ij,ij->i", P[pair], self.normals[row]) - self.offsets[row]
        depth = np.maximum.reduceat(height, first)  # <= 0: behind every face plane, inside
        inside = depth <= 0
        at = np.flatnonzero(~inside & (depth <= reach))
        inside = np.flatnonzero(inside)
        if not len(at):  # (most points of a sparse scene: nothing within reach, or inside only)
            return inside, depth[inside], P[inside]
        # A convex piece's nearest point to a point outside lies on a face that faces the point.
        wanted = np.zeros(len(pieces), bool)
        wanted[at] = True
        facing = np.flatnonzero((height > 0) & wanted[pair])
        row, pair = row[facing], pair[facing]
        runs = np.bincount(pair, minlength=len(pieces))[at]
        first = np.cumsum(runs) - runs
        p, a, ab, ac = P[pair], self.triangles[row, 0], self.edges[row, 0], self.edges[row, 1]
        st = _point_triangle(p - a, ab, ac, self.dots[row])
        closest = a + st[:, :1] * ab + st[:, 1:] * ac
        d = np.linalg.norm(p - closest, axis=1)
        best = _argmin_runs(d, first, runs)
        near = d[best] <= reach[at]
        pairs = np.concatenate([inside, at[near]])
        distance = np.concatenate([depth[inside], d[best][near]])
        closest = np.concatenate([P[inside], closest[best][near]])
        order = np.argsort(pairs, kind="stable")
        return pairs[order], distance[order], closest[order]


def pairs_near(
    P: np.ndarray, reach: np.ndarray, centres: np.ndarray, radii: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The (point, piece) pairs, by point, that may lie within `reach` (n,) of each other, of the points (n, 3) and
    the pieces in the spheres about `centres` (k, 3) of `radii` (k,): every pair when there are few, else the
    points within the greatest reach of each piece's sphere, from a KD-tree of the points (each piece asked with its
    own radius, which a tree of the pieces could not: it had to take the largest)."""
    count = len(radii)
    if count * len(P) <= DENSE:  # few pairs: every one, cheaper than building the tree
        return np.divmod(np.arange(count * len(P)), count)
    from scipy.spatial import cKDTree  # (not loaded when the command line starts)

    lists = cKDTree(P).query_ball_point(centres, radii + reach.max(), return_sorted=False)
    pieces = np.repeat(np.arange(count), [len(found) for found in lists])
    points = np.concatenate(lists).astype(int) if len(pieces) else np.empty(0, int)
    order = np.argsort(points, kind="stable")
    return points[order], pieces[order]


def _runs(first: np.ndarray, runs: np.ndarray) -> np.ndarray:
    """The indices of runs of rows: `runs` rows from each `first`, one after another."""
    return np.arange(runs.sum()) - np.repeat(np.cumsum(runs) - runs, runs) + np.repeat(first, runs)


def _point_triangle(ap: np.ndarray, ab: np.ndarray, ac: np.ndarray, dots: np.ndarray) -> np.ndarray:
    """The nearest point of each triangle (a, b, c) to its point p, as coefficients (s, t) of a + s ab + t ac,
    (m, 2), given p - a, b - a and c - a (m, 3) and the triangle's ab.ab, ab.ac, ac.ac (m, 3): Ericson's
    Voronoi-region test ("Real-Time Collision Detection", 5.1.5), every region's answer computed and the first region
    that holds the point taken, so every row costs two products."""
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    d3, d4 = d1 - dots[:, 0], d2 - dots[:, 1]  # with p - b
    d5, d6 = d1 - dots[:, 1], d2 - dots[:, 2]  # with p - c
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):  # a region's formula divides by zero only outside it
        total = va + vb + vc
        st = np.stack([vb / total, vc / total], axis=1)  # inside the face
        w_bc, w_ac, w_ab = (d4 - d3) / ((d4 - d3) + (d5 - d6)), d2 / (d2 - d6), d1 / (d1 - d3)
    zero, one = np.zeros_like(d1), np.ones_like(d1)
    regions = [  # the last that holds wins: listed from the face outward, Ericson's order reversed
        ((va <= 0) & (d4 >= d3) & (d5 >= d6), 1 - w_bc, w_bc),  # edge bc
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), zero, w_ac),  # edge ac
        ((d6 >= 0) & (d5 <= d6), zero, one),  # vertex c
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), w_ab, zero),  # edge ab
        ((d3 >= 0) & (d4 <= d3), one, zero),  # vertex b
        ((d1 <= 0) & (d2 <= 0), zero, zero),  # vertex a
    ]
    for holds, s, t in regions:
        st[holds, 0], st[holds, 1] = s[holds], t[holds]
    return st


def _argmin_runs(values: np.ndarray, first: np.ndarray, runs: np.ndarray) -> np.ndarray:
    """The row of the least value in each run of rows (starting at `first`, `runs` long, none empty)."""
    least = np.minimum.reduceat(values, first)
    hit = values == np.repeat(least, runs)
    rows = np.flatnonzero(hit)
    owner = np.repeat(np.arange(len(first)), runs)[rows]
    return rows[np.searchsorted(owner, np.arange(len(first)))]


def gaps(points: np.ndarray, distance: np.ndarray, gradient: np.ndarray, n: int, width: float) -> np.ndarray:
    """Whether each of n points lies in a gap narrower than `width`, given its obstacles within reach (point index,
    distance, gradient; by point, as `Polytopes.near` returns them): two of them on roughly opposite sides (their
    gradients more than 120 degrees apart) whose distances add up to less than `width`.

    One of two such obstacles is nearer than width/2: each of those is paired with the obstacles of its point no
    nearer than itself and near enough, in chunks of about ROWS pairs (a point among hundreds of pieces has
    thousands); each point's nearest obstacle first, and the others only for the points that are no gap yet."""
    gap = np.zeros(n, bool)
    if not len(points):
        return gap
    # Each point's obstacles by distance: an obstacle nearer than width/2 pairs with those after it, up to width
    # less its own distance.
    order = np.lexsort((distance, points))
    points, distance, gradient = points[order], distance[order], gradient[order]
    key = points * (4.0 * width) + np.clip(distance, -width, width)
    near = np.flatnonzero(distance < width / 2)
    runs = np.searchsorted(key, key[near] + (width - 2 * distance[near]), side="left") - near - 1
    near, runs = near[runs > 0], runs[runs > 0]
    # Each point's nearest obstacle first: most gaps show with it, and their points need no more pairs.
    nearest = np.concatenate([[True], points[1:] != points[:-1]])[near]
    for take in (nearest, ~nearest):
        take = take & ~gap[points[near]]
        if not take.any():
            continue
        first, count = near[take], runs[take]
        cost = np.cumsum(count)
        for chunk in np.split(np.arange(len(first)), np.searchsorted(cost, np.arange(ROWS, cost[-1], ROWS))):
            a = np.repeat(first[chunk], count[chunk])
            b = _runs(first[chunk] + 1, count[chunk])
            facing = np.einsum("ij,ij->i", gradient[a], gradient[b]) < -0.5
            gap[points[a[facing]]] = True
    return gap
