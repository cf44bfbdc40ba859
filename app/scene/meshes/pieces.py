"""Convex pieces and how they are made: a convex hull (`hull_piece`), hulls merged while that adds little
(`hull_groups`, robot links), exact flat pieces grown from adjacent faces (`face_pieces`) and pieces that reach into
a closed part's own solid (`shell_pieces`). See the package's docstring for when each is used."""

from __future__ import annotations

import heapq
import sys
from dataclasses import dataclass

import numpy as np

# How far a shell piece may stand proud of the surface, as a fraction of the tolerance: validation rejects pieces
# holding points 0.9 tolerance from the surface, and a shell piece's hull has no extra thickness (a face piece has).
SHELL_REACH = 0.6


def progress_bar(**kwargs):
    """A tqdm bar on stderr, cleared when done; only on a terminal (so logs and one-line errors stay clean)."""
    from tqdm import tqdm

    disable = True if kwargs.pop("disable", False) else None  # None: tqdm's own "is stderr a terminal?"
    return tqdm(file=sys.stderr, leave=False, disable=disable, **kwargs)


# ---- pieces -------------------------------------------------------------------------------------------------------
@dataclass
class Piece:
    """A convex piece: its vertices, triangles (outward) and half-spaces A x + b <= 0."""

    vertices: np.ndarray
    faces: np.ndarray
    equations: np.ndarray  # (m, 4): unit normal, offset


def hull_piece(points: np.ndarray) -> Piece:
    from scipy.spatial import ConvexHull

    hull = ConvexHull(np.asarray(points, float))
    verts = hull.points[hull.vertices]
    remap = np.zeros(len(hull.points), int)
    remap[hull.vertices] = np.arange(len(hull.vertices))
    faces = remap[hull.simplices]
    # Orient every triangle outward (scipy's simplices are not consistently wound).
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    inward = np.einsum("ij,ij->i", np.cross(b - a, c - a), hull.equations[:, :3]) < 0
    faces[inward] = faces[inward][:, [0, 2, 1]]
    return Piece(verts, faces, hull.equations.copy())


def thickened(points: np.ndarray, thickness: float) -> np.ndarray:
    """`points`, doubled along each direction they have (nearly) no extent in, half `thickness` to each side: a flat
    or straight point set (a planar cap, a 2-face sliver) then has a solid convex hull that still holds it."""
    points = np.asarray(points, float)
    centred = points - points.mean(axis=0)
    axes = np.linalg.svd(centred, full_matrices=False)[2]  # (a part has a triangle at least: 3 points, 3 axes)
    for axis in axes[np.ptp(centred @ axes.T, axis=0) < thickness]:
        points = np.vstack([points + 0.5 * thickness * axis, points - 0.5 * thickness * axis])
    return points


def hull_groups(point_sets: list[np.ndarray], tolerance: float) -> tuple[list[Piece], list[list[int]]]:
    """Conservative pieces for parts taken as their convex hulls: each part's hull, and parts merged into one hull
    while that adds little. Largest first, a part joins the group whose hull grows least by it, if the merged hull's
    volume exceeds the group's hull plus the part's by at most `tolerance` times the merged hull's area (a layer
    `tolerance` thick on average): a CAD export's unstitched caps, fillet strips and 2-face slivers join the body
    they lie on, whereas two shells at an angle (an L) stay two hulls. Flat parts are thickened by tolerance / 5 (as
    a face piece is). Every hull contains its parts, so the pieces are never smaller than the mesh. Returns the
    pieces and each one's parts (indices into point_sets)."""
    from scipy.spatial import ConvexHull

    hulls = [ConvexHull(thickened(p, tolerance / 5)) for p in point_sets]
    groups = []  # [hull vertices, ConvexHull, member parts]
    for i in np.argsort([-h.volume for h in hulls], kind="stable"):
        hull = hulls[i]
        points = hull.points[hull.vertices]
        lo, hi = points.min(axis=0) - tolerance, points.max(axis=0) + tolerance
        best, best_added = None, np.inf
        for group in groups:
            if np.any(group[0].min(axis=0) > hi) or np.any(group[0].max(axis=0) < lo):
                continue
            merged = ConvexHull(np.vstack([group[0], points]))
            added = merged.volume - group[1].volume - hull.volume
            if added <= tolerance * merged.area and added < best_added:
                best, best_added, best_merged = group, added, merged
        if best is None:
            groups.append([points, hull, [int(i)]])
        else:
            best[0], best[1] = best_merged.points[best_merged.vertices], best_merged
            best[2].append(int(i))
    return [hull_piece(g[0]) for g in groups], [g[2] for g in groups]


def prism_piece(
    polygon_2d: np.ndarray, origin: np.ndarray, u: np.ndarray, v: np.ndarray, n: np.ndarray, h_lo: float, h_hi: float
) -> Piece:
    """A convex polygon (counter-clockwise in the (u, v) plane, n = u x v) extruded from height h_lo to h_hi."""
    m = len(polygon_2d)
    base = origin + polygon_2d[:, :1] * u + polygon_2d[:, 1:2] * v
    verts = np.vstack([base + h_lo * n, base + h_hi * n])
    faces = [[0, k + 1, k] for k in range(1, m - 1)]  # bottom, facing -n
    faces += [[m, m + k, m + k + 1] for k in range(1, m - 1)]  # top, facing +n
    for k in range(m):
        a, b = k, (k + 1) % m
        faces += [[a, b, m + b], [a, m + b, m + a]]
    eqs = [np.r_[-n, h_lo + np.dot(n, origin)], np.r_[n, -(h_hi + np.dot(n, origin))]]
    for k in range(m):
        p, q = polygon_2d[k], polygon_2d[(k + 1) % m]
        edge = q - p
        out2 = np.array([edge[1], -edge[0]]) / np.linalg.norm(edge)  # right of a CCW edge = outside
        out3 = out2[0] * u + out2[1] * v
        point = origin + p[0] * u + p[1] * v
        eqs.append(np.r_[out3, -np.dot(out3, point)])
    return Piece(verts, np.array(faces), np.array(eqs))


def _hull_2d(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull (monotone chain), collinear points dropped."""
    pts = np.unique(np.round(points, 12), axis=0)
    if len(pts) < 3:
        return pts
    pts = pts[np.lexsort((pts[:, 1], pts[:, 0]))]

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in pts[::-1]:
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def _area_2d(poly: np.ndarray) -> float:
    if len(poly) < 3:
        return 0.0
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _plane_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
    u = np.cross(n, a)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


def _grow_patches(mesh, begin, extend, finish, desc: str, progress: bool) -> tuple[list[Piece], list[int]]:
    """Greedy region growing, shared by the "faces" and "shell" methods: seeds in order of decreasing area; a seed's
    neighbours (faces sharing an edge, normal within 60 degrees of the seed's) join while `extend(state, face)`
    returns a new state (None: refused, not tried again for this patch). `begin(seed)` makes a patch's state,
    `finish(state)` its piece (None: none could be made). Returns the pieces and each one's faces, seed first."""
    faces = np.asarray(mesh.faces)
    normals = np.asarray(mesh.face_normals, float)
    neighbours = [[] for _ in range(len(faces))]
    for a, b in np.asarray(mesh.face_adjacency):
        neighbours[a].append(b)
        neighbours[b].append(a)
    centres = np.asarray(mesh.triangles_center)

    def distance(a, b):
        return float(np.linalg.norm(centres[a] - centres[b]))

    assigned = np.zeros(len(faces), bool)
    pieces, groups = [], []
    bar = progress_bar(total=len(faces), desc=desc, unit="face", disable=not progress)
    areas = np.asarray(mesh.area_faces, float)
    # A face with no area (collinear corners) has no plane: it seeds nothing (its neighbours cover its edges).
    flat = areas <= 1e-12 * float(np.linalg.norm(mesh.extents)) ** 2
    for seed in np.argsort(-areas, kind="stable"):
        if assigned[seed] or flat[seed]:
            continue
        n = normals[seed]
        state = begin(int(seed))
        assigned[seed] = True
        members, refused = [int(seed)], set()
        # Nearest face first: round patches, which a curvature limit lets grow largest.
        frontier = [(distance(seed, g), g) for g in neighbours[seed]]
        heapq.heapify(frontier)
        while frontier:
            _, g = heapq.heappop(frontier)
            if assigned[g] or g in refused or normals[g] @ n <= 0.5:
                continue
            grown = extend(state, int(g))
            if grown is None:
                refused.add(g)
                continue
            state = grown
            assigned[g] = True
            members.append(int(g))
            for x in neighbours[g]:
                if not assigned[x]:
                    heapq.heappush(frontier, (distance(seed, x), x))
        bar.update(len(members))
        pieces.append(finish(state))
        groups.append(members)
    bar.close()
    return pieces, groups


def face_pieces(mesh, slab: float, thickness: float, progress: bool = True, with_seeds: bool = False):
    """Exact pieces: adjacent faces grown greedily into flat convex patches (see the module docstring).
    With `with_seeds`, also each piece's first face (to tell which part of the mesh it belongs to).
    A patch's state: its seed face's plane (normal n, basis u v, origin), the 2-D hull of its faces projected on
    it, the sum of their projected areas, and their corners' heights above it."""
    vertices = np.asarray(mesh.vertices, float)
    faces = np.asarray(mesh.faces)
    normals = np.asarray(mesh.face_normals, float)
    areas = np.asarray(mesh.area_faces, float)
    eps_area = 1e-9

    def begin(seed):
        n = normals[seed]
        u, v = _plane_basis(n)
        origin = vertices[faces[seed][0]]
        tri = vertices[faces[seed]] - origin
        return n, u, v, origin, _hull_2d(np.c_[tri @ u, tri @ v]), areas[seed], list(tri @ n)

    def extend(state, g):
        n, u, v, origin, hull, area_sum, heights = state
        tri = vertices[faces[g]] - origin
        h_all = heights + list(tri @ n)
        if max(h_all) - min(h_all) > slab:
            return None
        t2 = np.c_[tri @ u, tri @ v]
        e1, e2 = t2[1] - t2[0], t2[2] - t2[0]
        projected = 0.5 * float(e1[0] * e2[1] - e1[1] * e2[0])
        if projected <= 0:
            return None  # folded over: its projection would overlap its neighbours'
        new_hull = _hull_2d(np.vstack([hull, t2]))
        new_sum = area_sum + projected
        rim = 0.5 * slab * float(np.linalg.norm(new_hull - np.roll(new_hull, 1, axis=0), axis=1).sum())
        if _area_2d(new_hull) > new_sum * (1 + 1e-7) + eps_area * new_sum + rim:  # (validation checks it)
            return None  # the hull would add area that is not surface
        return n, u, v, origin, new_hull, new_sum, h_all

    def finish(state):
        n, u, v, origin, hull, _, heights = state
        if len(hull) < 3:
            return None  # a sliver with no area
        return prism_piece(hull, origin, u, v, n, min(heights) - thickness / 2, max(heights) + thickness / 2)

    pieces, groups = _grow_patches(mesh, begin, extend, finish, "exact pieces", progress)
    kept = [k for k, piece in enumerate(pieces) if piece is not None]
    pieces = [pieces[k] for k in kept]
    return (pieces, [groups[k][0] for k in kept]) if with_seeds else pieces


def shell_pieces(mesh, tolerance: float, progress: bool = True) -> tuple[list[Piece], list[list[int]]]:
    """Pieces of a closed part that reach into its own solid (see the module docstring), and each one's faces: a
    patch of surface faces plus each of its corners moved inward along the vertex normal by half the wall's
    thickness there (one ray cast per vertex), as a convex hull. A face joins the patch while no vertex, edge
    midpoint or face centre of the whole mesh lies deeper than `SHELL_REACH * tolerance` inside the grown hull: a
    dent of the patch itself, or the wall's far side, would. So a patch bulging outward grows until its hull nears
    the far side of the wall; a hollow one stays within reach of flat. Sparse probes miss some overhangs (the hull
    of a U-shaped end face fills the U's slot): validation finds those pieces and the decomposition replaces them
    by face pieces."""
    from scipy.spatial import ConvexHull, QhullError, cKDTree

    vertices = np.asarray(mesh.vertices, float)
    faces = np.asarray(mesh.faces)
    reach = SHELL_REACH * tolerance
    inward = -np.asarray(mesh.vertex_normals, float)
    # Cast from just inside the surface, so a vertex's own faces are not the hit.
    lift = 1e-6 * float(np.linalg.norm(mesh.extents))
    origins = vertices + lift * inward
    hits, rays, _ = mesh.ray.intersects_location(origins, inward, multiple_hits=False)
    thickness = np.zeros(len(vertices))
    thickness[rays] = np.linalg.norm(hits - origins[rays], axis=1)
    inner = vertices + 0.5 * thickness[:, None] * inward
    edges = np.asarray(mesh.edges_unique)
    probes = np.vstack([vertices, vertices[edges].mean(axis=1), np.asarray(mesh.triangles_center)])
    tree = cKDTree(probes)

    def fits(corners) -> bool:
        points = np.vstack([vertices[corners], inner[corners]])
        try:
            hull = ConvexHull(points)
        except QhullError:
            return False  # flat: no wall behind these faces
        centre = points.mean(axis=0)
        inside = probes[tree.query_ball_point(centre, float(np.linalg.norm(points - centre, axis=1).max()))]
        # Any probe inside the hull shrunk by `reach`? A few facets at a time: most probes fall out early.
        for block in range(0, len(hull.equations), 16):
            eq = hull.equations[block : block + 16]
            inside = inside[(inside @ eq[:, :3].T + eq[:, 3]).max(axis=1) < -reach]
            if not len(inside):
                return True
        return False

    def extend(corners, g):
        grown = np.union1d(corners, faces[g])
        return grown if fits(grown) else None

    def finish(corners):
        try:
            return hull_piece(np.vstack([vertices[corners], inner[corners]]))
        except QhullError:
            return None  # no wall behind these faces (a sliver)

    pieces, groups = _grow_patches(mesh, lambda seed: np.asarray(faces[seed]), extend, finish, "shell pieces", progress)
    return faces_instead(mesh, pieces, groups, [k for k, p in enumerate(pieces) if p is None], tolerance)


def faces_instead(mesh, pieces: list, groups: list, replace: list[int], tolerance: float):
    """`pieces` (and their face `groups`) with those at the indices `replace` swapped for face pieces of their
    faces: exact, thin, valid where a thick piece was not."""
    if not replace:
        return pieces, groups
    faces = sorted({f for k in replace for f in groups[k]})
    new, seeds = face_pieces(
        mesh.submesh([faces], append=True),
        slab=tolerance / 2,
        thickness=tolerance / 5,
        progress=False,
        with_seeds=True,
    )
    keep = [k for k in range(len(pieces)) if k not in set(replace)]
    return [pieces[k] for k in keep] + new, [groups[k] for k in keep] + [[faces[s]] for s in seeds]
