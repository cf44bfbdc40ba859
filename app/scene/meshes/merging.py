"""A robot link's pieces merged into fewer convex hulls (`merged_pieces`), each staying near the link: a check's cost
grows with the pieces of the links near each other, and a CAD link's decomposition can hold hundreds."""

from __future__ import annotations

import heapq

import numpy as np

from app.scene.meshes.pieces import Piece, hull_piece
from app.scene.meshes.validation import within

# How far (metres) a merged piece may reach beyond its link's mesh: a robot link never collides falsely where the
# real mesh has this much clearance. (A merged hull holds its pieces, so it never makes a false "free".)
MERGE_REACH = 0.005
# Merging stops once a link has this many pieces: on a UR5's CAD links, fewer added volume for little speed, and
# some links could not go lower within MERGE_REACH (docs/benchmarks-history.md, "Mesh scenes").
MOST_LINK_PIECES = 8
# A merge whose test would look at more triangles than this is refused (cautious, and bounded in time).
_MOST_TRIANGLES = 20_000
# Each piece is tried with this many of its nearest (a hull per pair is most of the time).
_NEIGHBOURS = 8


def merged_pieces(pieces: list[Piece], mesh, reach: float, most: int = MOST_LINK_PIECES):
    """`pieces` merged pairwise into convex hulls while more than `most` are left, least added volume first (the
    merged hull's volume over the two hulls'), a pair only if its hull's surface stays within `reach` of the
    original pieces or the mesh's surface (`stays_near`). A piece is tried only with its few nearest (by their
    corners), within `reach`: farther ones would bridge a gap. Returns the pieces and each one's members (indices
    into `pieces`)."""
    from scipy.spatial import ConvexHull
    from scipy.spatial.distance import cdist

    live = {}  # key: corners, volume, members, box (lo, hi)
    candidates = []  # (added volume, tie-break, a, b, merged hull)
    tried = set()

    def add(key: int, corners: np.ndarray, volume: float, members: list[int]) -> None:
        live[key] = (corners, volume, members, corners.min(axis=0), corners.max(axis=0))

    def pair_with_neighbours(a: int) -> None:
        pa, va, _, lo_a, hi_a = live[a]
        gaps = []
        for b, (pb, _, _, lo_b, hi_b) in live.items():
            if b != a and not (np.any(lo_a - hi_b > reach) or np.any(lo_b - hi_a > reach)):
                gaps.append((cdist(pa, pb).min(), b))
        for gap, b in sorted(gaps)[:_NEIGHBOURS]:
            if gap <= reach and (min(a, b), max(a, b)) not in tried:
                tried.add((min(a, b), max(a, b)))
                hull = ConvexHull(np.vstack([pa, live[b][0]]))
                heapq.heappush(candidates, (hull.volume - va - live[b][1], len(candidates), a, b, hull))

    for k, piece in enumerate(pieces):
        add(k, piece.vertices, ConvexHull(piece.vertices).volume, [k])
    for k in range(len(pieces)):
        pair_with_neighbours(k)
    next_key = len(pieces)
    while len(live) > most and candidates:
        _, _, a, b, hull = heapq.heappop(candidates)
        if a not in live or b not in live:
            continue
        # A hull face whose corners all come from one side lies on that side's surface, already near the mesh.
        from_a = hull.simplices < len(live[a][0])
        bridging = hull.points[hull.simplices[from_a.any(axis=1) & ~from_a.all(axis=1)]]
        if not stays_near(bridging, pieces, mesh, reach):
            continue
        add(next_key, hull.points[hull.vertices], hull.volume, live.pop(a)[2] + live.pop(b)[2])
        pair_with_neighbours(next_key)
        next_key += 1
    return [hull_piece(entry[0]) for entry in live.values()], [entry[2] for entry in live.values()]


def stays_near(triangles: np.ndarray, pieces: list[Piece], mesh, reach: float) -> bool:
    """Whether every point of the triangles (n, 3, 3) lies within `reach` of a piece or of the mesh's surface.
    Distance is 1-Lipschitz, so a triangle passes when its centre lies deep enough inside a piece, or near enough
    to the mesh's surface, for the circle through its corners to pass; the others are halved. It fails at once
    where a centre lies outside some plane of every piece by more than `reach` (farther than that from them all),
    and where one a quarter of `reach` across or smaller does not pass (so it is cautious by up to that much)."""
    if not len(triangles):
        return True  # (one piece held the other)
    corners = triangles.reshape(-1, 3)
    boxes = np.array([(p.vertices.min(axis=0) - reach, p.vertices.max(axis=0) + reach) for p in pieces])
    nearby = np.flatnonzero(
        np.all(boxes[:, 0] <= corners.max(axis=0), axis=1) & np.all(boxes[:, 1] >= corners.min(axis=0), axis=1)
    )
    if not len(nearby):
        return False
    axis = np.ptp(corners, axis=0).argmax()
    while len(triangles):
        if len(triangles) > _MOST_TRIANGLES:
            return False
        triangles = triangles[np.argsort(triangles[:, :, axis].mean(axis=1))]  # chunks of centres close together
        centres = triangles.mean(axis=1)
        radii = np.linalg.norm(triangles - centres[:, None], axis=2).max(axis=1)
        outside = np.concatenate(
            [_least_offset(chunk, pieces, nearby, boxes) for chunk in np.array_split(centres, -(-len(centres) // 256))]
        )
        if np.any(outside > reach):
            return False
        # Inside a piece, the depth bounds the distance to it; outside, an offset is only a lower bound on the
        # distance, so such a centre asks the mesh.
        passed = (outside <= 0) & (reach - outside >= radii)
        ask = ~passed & (radii < reach)
        if ask.any():
            passed[ask] = within(centres[ask], mesh, reach - radii[ask])
        if np.any(~passed & (radii <= reach / 4)):
            return False
        triangles = _halved(triangles[~passed])
    return True


def _least_offset(points: np.ndarray, pieces: list[Piece], nearby: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Per point, the least over the pieces of its largest plane offset: minus its depth inside a piece, or a
    distance to them all it does not exceed (inf: no piece's box, grown by reach, holds it)."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    near = nearby[np.all(boxes[nearby, 0] <= hi, axis=1) & np.all(boxes[nearby, 1] >= lo, axis=1)]
    if not len(near):
        return np.full(len(points), np.inf)
    planes = np.vstack([pieces[k].equations for k in near])
    starts = np.cumsum([0] + [len(pieces[k].equations) for k in near[:-1]])
    return np.maximum.reduceat(points @ planes[:, :3].T + planes[:, 3], starts, axis=1).min(axis=1)


def _halved(triangles: np.ndarray) -> np.ndarray:
    """Each triangle as the two its longest edge's midpoint makes (slivers, common among bridging faces, then need
    far fewer pieces than by splitting in four)."""
    longest = np.linalg.norm(triangles - np.roll(triangles, -1, axis=1), axis=2).argmax(axis=1)  # edge k: k -> k+1
    a, b, c = (np.take_along_axis(triangles, ((longest + k) % 3)[:, None, None], axis=1)[:, 0] for k in range(3))
    middle = (a + b) / 2
    return np.concatenate([np.stack([a, middle, c], axis=1), np.stack([middle, b, c], axis=1)])
