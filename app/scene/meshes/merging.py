"""A mesh's convex bounds: a few hulls that hold it and stay near it. A check's cost grows with the pieces near each
other, and a CAD link's or a scene export's faces can make hundreds or thousands. `split_hulls` makes them top down
(the mesh's hull, split until every hull's surface stays near the mesh: a fine CAD mesh of tens of thousands of
triangles in seconds), `merged_pieces` merges pieces pairwise bottom up (a split's halves, or a validated
decomposition's pieces)."""

from __future__ import annotations

import heapq

import numpy as np

from app.scene.meshes.pieces import Piece, hull_piece, thickened
from app.scene.meshes.validation import components

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


class Surface:
    """A mesh's surface as points no farther than `spacing` from any point of it (each triangle halved until its
    corners lie within `spacing` of its centre; the centres kept) in a k-d tree: bounds on the distance to the
    surface, within `spacing` of the truth, for many points at once. (An exact distance asks every triangle near
    the point: on a fine CAD mesh, hundreds.) A second tree of points `_COARSE` times as far apart answers first
    for points far from the surface, where the fine tree's search would visit a great many of its points."""

    def __init__(self, mesh, spacing: float):
        self.triangles = np.asarray(mesh.triangles, float)
        self.tree, self._face = _surface_tree(self.triangles, spacing)
        self.spacing = spacing
        self._coarse = _surface_tree(self.triangles, spacing * _COARSE)[0]

    def near(self, points: np.ndarray, radius) -> np.ndarray:
        """Whether each point is surely within `radius` of the surface."""
        radius = np.broadcast_to(radius, (len(points),))
        return self.tree.query(points, distance_upper_bound=float(np.max(radius, initial=0.0)))[0] < radius

    def farther(self, points: np.ndarray, radius) -> np.ndarray:
        """Whether each point is surely farther than `radius` from the surface."""
        radius = np.broadcast_to(radius, (len(points),))
        far = self._coarse.query(points)[0] - self.spacing * _COARSE > radius
        unsure = np.flatnonzero(~far)
        bound = float(np.max(radius[unsure], initial=0.0)) + self.spacing
        far[unsure] = self.tree.query(points[unsure], distance_upper_bound=bound)[0] - self.spacing > radius[unsure]
        return far

    def holds(self, triangles: np.ndarray, reach: float) -> np.ndarray:
        """Whether each triangle (n, 3, 3) lies within `reach` of one face of the mesh, the face nearest its centre:
        distance to a triangle is convex, so it is largest at a corner. (A large triangle lying on the mesh's
        surface passes whole, where `near` would halve it to the spacing.)"""
        from trimesh.triangles import closest_point

        held = np.zeros(len(triangles), bool)
        # (A centre farther than `reach` from the surface cannot pass; asking the coarse tree first spares the fine
        # tree's search far from the surface.)
        centres = triangles.mean(axis=1)
        could = np.flatnonzero(self._coarse.query(centres)[0] - self.spacing * _COARSE <= reach)
        distance, nearest = self.tree.query(centres[could], distance_upper_bound=reach + self.spacing)
        could, nearest = could[np.isfinite(distance)], nearest[np.isfinite(distance)]
        corners = triangles[could].reshape(-1, 3)
        faces = np.repeat(self.triangles[self._face[nearest]], 3, axis=0)
        held[could] = (
            np.linalg.norm(closest_point(faces, corners) - corners, axis=1).reshape(-1, 3).max(axis=1) <= reach
        )
        return held


# How much farther apart the points of `Surface`'s coarse tree are than its fine tree's.
_COARSE = 8


def _surface_tree(triangles: np.ndarray, spacing: float):
    """A k-d tree of points no farther than `spacing` from any point of the triangles (see `Surface`), and the
    triangle each point lies on."""
    from scipy.spatial import cKDTree

    face, centres, owners = np.arange(len(triangles)), [], []
    while len(triangles):
        middle = triangles.mean(axis=1)
        small = np.linalg.norm(triangles - middle[:, None], axis=2).max(axis=1) <= spacing
        centres.append(middle[small])
        owners.append(face[small])
        triangles, face = _halved(triangles[~small]), np.tile(face[~small], 2)
    return cKDTree(np.vstack(centres)), np.concatenate(owners)


# Fixed ray directions for `Enclosure` (trimesh's own retries go in a random one: not repeatable).
_RAYS = np.array([[0.4395064455, 0.617598629942, 0.652231566745], [0.8, -0.6, 0.0], [-0.36, -0.48, 0.8]])


class Enclosure:
    """Where a link's mesh encloses a point, for `stays_near`: a line through it in one of a few fixed directions
    crosses one of its connected parts, or the whole mesh, an odd number of times on each side; the next direction
    is tried only where the two sides disagree for some part. (A point outside a closed surface sees even counts
    both ways; a hole in a part spoils only the lines through it; a CAD export's open patches may close a solid
    only together.) Only how tight a link's hulls are rests on this: they hold its faces whatever it says. One ray
    cast per direction and side for all the parts at once."""

    def __init__(self, mesh):
        self.mesh = mesh
        self.groups = components(mesh)  # each connected part's faces
        self.part_of = np.empty(len(mesh.faces), int)
        for k, part in enumerate(self.groups):
            self.part_of[part] = k
        self.parts = len(self.groups)

    def contains(self, points: np.ndarray) -> np.ndarray:
        inside = np.zeros(len(points), bool)
        lo, hi = self.mesh.bounds
        todo = np.flatnonzero(np.all((points >= lo) & (points <= hi), axis=1))
        n = self.parts + 1  # a cell per (point, part), and one for the whole mesh
        for ray in _RAYS:
            if not len(todo):
                break
            odd = []
            for side in (ray, -ray):
                triangles, rays = self.mesh.ray.intersects_id(
                    points[todo], np.tile(side, (len(todo), 1)), multiple_hits=True
                )[:2]
                cells, counts = np.unique(
                    np.r_[rays * n + self.part_of[triangles], rays * n + n - 1], return_counts=True
                )
                odd.append(cells[counts % 2 == 1])
            found = np.zeros(len(todo), bool)
            found[np.intersect1d(odd[0], odd[1]) // n] = True
            unsure = np.zeros(len(todo), bool)
            unsure[np.setxor1d(odd[0], odd[1]) // n] = True
            inside[todo[found]] = True
            todo = todo[~found & unsure]  # even both ways for every part: outside
        return inside


def split_hulls(
    mesh, surface: Surface, reach: float, thickness: float, enclosure: Enclosure | None = None
) -> list[Piece]:
    """Convex hulls that hold the mesh, each with its whole surface within `reach` of the mesh's surface or where
    it is enclosed (`enclosure`; as `stays_near` tests it). The hull of all the faces if it passes; else each
    connected part's, longest first (a CAD export's cap or sliver inside a hull taken already adds none), and a
    hull that strays farther split into the hulls of its faces' two halves (`_halves`). Each face lies in a hull,
    so the hulls hold the mesh (never a false free), open or closed. Flat groups are thickened by `thickness` (see
    `thickened`); one face's hull is the face, so the splitting ends. What no surface test sees: a cavity reached
    through an opening under 2 `reach` wide is filled, as by any hull."""
    vertices = np.asarray(mesh.vertices, float)
    faces = np.asarray(mesh.faces)
    centres = np.asarray(mesh.triangles_center, float)
    size = float(np.linalg.norm(mesh.extents))

    def hull_of(group: np.ndarray) -> Piece:
        return hull_piece(thickened(vertices[np.unique(faces[group])], thickness))

    def passes(hull: Piece) -> bool:
        return stays_near(hull.vertices[hull.faces], [], surface, reach, enclosure)

    whole = hull_of(np.arange(len(faces)))
    if passes(whole):
        return [whole]
    parts = enclosure.groups if enclosure is not None else components(mesh)
    spans = [np.linalg.norm(np.ptp(vertices[faces[part]].reshape(-1, 3), axis=0)) for part in parts]
    hulls = []
    for part in (parts[k] for k in np.argsort(spans, kind="stable")[::-1]):
        corners = vertices[np.unique(faces[part])]
        if any(np.all(corners @ h.equations[:, :3].T + h.equations[:, 3] <= 1e-9 * size) for h in hulls):
            continue
        todo = [part]
        while todo:
            group = todo.pop()
            hull = hull_of(group)
            if len(group) == 1 or passes(hull):
                hulls.append(hull)
            else:
                todo += _halves(group, centres, vertices, faces)
    return hulls


def _halves(group: np.ndarray, centres: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> list[np.ndarray]:
    """The group's faces in two halves by a plane across one of their principal axes, at the median of their
    centres or at the middle of their span: of those six cuts, the one whose halves' hulls hold the least volume
    (the cut that removes most of what the group's hull added)."""
    from scipy.spatial import ConvexHull, QhullError

    spread = centres[group] - centres[group].mean(axis=0)
    best = (np.inf, [group[: len(group) // 2], group[len(group) // 2 :]])  # (centres all in one point)
    for axis in np.linalg.svd(spread, full_matrices=False)[2]:
        along = spread @ axis
        for cut in (np.median(along), (along.min() + along.max()) / 2):
            below = along < cut
            if below.all() or not below.any():
                continue
            halves = [group[~below], group[below]]
            try:
                volume = sum(ConvexHull(vertices[np.unique(faces[half])]).volume for half in halves)
            except QhullError:
                volume = 0.0  # a flat half: nothing added
            if volume < best[0]:
                best = (volume, halves)
    return best[1]


def merged_pieces(
    pieces: list[Piece],
    surface: Surface,
    reach: float,
    most: int = MOST_LINK_PIECES,
    inside_is_near: bool = True,
    enclosure: Enclosure | None = None,
):
    """`pieces` merged pairwise into convex hulls while more than `most` are left, least added volume first (the
    merged hull's volume over the two hulls'), a pair only if its hull's surface stays within `reach` of the mesh's
    surface, or where it is enclosed (`enclosure`), or (`inside_is_near`: pieces that stray no farther than the
    caller allows for) of the original pieces (`stays_near`). A piece is tried only with its few nearest (by their
    corners), within `reach`: farther ones would bridge a gap. Returns the pieces and each one's members (indices
    into `pieces`)."""
    from scipy.spatial import ConvexHull
    from scipy.spatial.distance import cdist

    live = {}  # key: corners, volume, members
    boxes = np.full((2 * len(pieces), 2, 3), np.nan)  # per key its corners' box (lo, hi); NaN once merged away
    candidates = []  # (added volume, tie-break, a, b, merged hull)
    tried = set()

    def add(key: int, corners: np.ndarray, volume: float, members: list[int]) -> None:
        live[key] = (corners, volume, members)
        boxes[key] = corners.min(axis=0), corners.max(axis=0)

    def pair_with_neighbours(a: int) -> None:
        pa, va, _ = live[a]
        lo, hi = boxes[:, 0], boxes[:, 1]
        close = np.all((lo - hi[a] <= reach) & (lo[a] - hi <= reach), axis=1)  # (False for a NaN box)
        close[a] = False
        gaps = sorted((cdist(pa, live[b][0]).min(), b) for b in np.flatnonzero(close).tolist())
        for gap, b in gaps[:_NEIGHBOURS]:
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
        if not stays_near(bridging, pieces if inside_is_near else [], surface, reach, enclosure):
            continue
        add(next_key, hull.points[hull.vertices], hull.volume, live.pop(a)[2] + live.pop(b)[2])
        boxes[[a, b]] = np.nan
        pair_with_neighbours(next_key)
        next_key += 1
    return [hull_piece(entry[0]) for entry in live.values()], [entry[2] for entry in live.values()]


def stays_near(
    triangles: np.ndarray, pieces: list[Piece], surface: Surface, reach: float, enclosure: Enclosure | None = None
) -> bool:
    """Whether every point of the triangles (n, 3, 3) lies within `reach` of a piece (none: the mesh alone) or of the
    mesh's surface, or where the mesh encloses it (`enclosure`: where no obstacle can be).
    Distance is 1-Lipschitz, so a triangle passes when its centre lies deep enough inside a piece, or near enough
    to the mesh's surface, for the circle through its corners to pass; the others are halved. A centre enclosed
    at depth d passes a triangle of radius up to `reach` + d: a point of it outside the solid is no farther
    from the surface than from the centre, less d. It fails at once where a centre lies outside some plane of every
    piece by more than `reach` (farther than that from them all), where (no pieces) a centre lies surely farther
    than `reach` from the mesh and is not enclosed, and where one a quarter of `reach` across or smaller does not
    pass (so it is cautious by up to that much)."""
    if not len(triangles):
        return True  # (one piece held the other)
    corners = triangles.reshape(-1, 3)
    boxes = np.array([(p.vertices.min(axis=0) - reach, p.vertices.max(axis=0) + reach) for p in pieces])
    boxes = boxes.reshape(-1, 2, 3)
    nearby = np.flatnonzero(
        np.all(boxes[:, 0] <= corners.max(axis=0), axis=1) & np.all(boxes[:, 1] >= corners.min(axis=0), axis=1)
    )
    if pieces and not len(nearby):
        return False  # (pieces hold the mesh's surface: far from them all is far from it)
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
        if pieces and np.any(outside > reach):
            return False
        # Inside a piece, the depth bounds the distance to it; outside, an offset is only a lower bound on the
        # distance, so such a centre asks the mesh.
        passed = (outside <= 0) & (reach - outside >= radii)
        ask = ~passed & (radii < reach)
        if ask.any():
            passed[ask] = surface.near(centres[ask], reach - radii[ask])
        if not passed.all():
            passed[~passed] = surface.holds(triangles[~passed], reach)
        if not pieces and not passed.all():
            # A centre surely farther than `reach` from the mesh, and not enclosed, breaks the rule itself: no
            # need to halve its triangle down to a quarter of `reach` to say so.
            rest = np.flatnonzero(~passed)
            far = rest[surface.farther(centres[rest], reach)]
            if len(far) and (enclosure is None or not enclosure.contains(centres[far]).all()):
                return False
        if enclosure is not None and not passed.all():
            # Enclosed, a triangle passes if its radius is under reach + the centre's depth: ask only those whose
            # centre lies that deep if it is enclosed at all (the ray casts are the test's cost).
            could = np.flatnonzero(~passed)
            deep = radii[could] > reach
            deep[deep] = surface.farther(centres[could[deep]], radii[could[deep]] - reach)
            could = could[(radii[could] <= reach) | deep]
            passed[could] = enclosure.contains(centres[could])
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
