"""Whether convex pieces stand for a mesh: every free point near it stays free and its surface is covered
(`validate`), and how much volume they add (`volume_report`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from app.scene.meshes.pieces import Piece, progress_bar

# trimesh (optional, slow to import) is imported inside the functions that use it.


def components(mesh) -> list[np.ndarray]:
    """Face indices of each connected part (faces sharing an edge)."""
    import trimesh

    return [
        np.asarray(c)
        for c in trimesh.graph.connected_components(mesh.face_adjacency, nodes=np.arange(len(mesh.faces)), min_len=1)
    ]


def inside_any(points: np.ndarray, pieces: list[Piece], margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Per point: the depth by which it lies inside its deepest piece (-inf when near none; only pieces whose box
    grown by `margin` holds the point are looked at), and that piece's index (-1: none)."""
    depth = np.full(len(points), -np.inf)
    which = np.full(len(points), -1)
    order = np.argsort(points[:, 0], kind="stable")
    xs = points[order, 0]
    for index, piece in enumerate(pieces):
        lo, hi = piece.vertices.min(axis=0) - margin, piece.vertices.max(axis=0) + margin
        window = order[np.searchsorted(xs, lo[0], "left") : np.searchsorted(xs, hi[0], "right")]
        cand = window[np.all((points[window, 1:] >= lo[1:]) & (points[window, 1:] <= hi[1:]), axis=1)]
        if len(cand) == 0:
            continue
        d = -(points[cand] @ piece.equations[:, :3].T + piece.equations[:, 3]).max(axis=1)
        deeper = d > depth[cand]
        depth[cand[deeper]] = d[deeper]
        which[cand[deeper]] = index
    return depth, which


def within(points: np.ndarray, mesh, radius) -> np.ndarray:
    """Whether each point is within `radius` (one, or one per point) of the mesh surface (exact point-triangle
    distances, but only to the triangles whose box the point's radius-box touches: much cheaper than a
    nearest-point query)."""
    from trimesh.triangles import closest_point

    radius = np.broadcast_to(np.asarray(radius, float), (len(points),))
    tree = mesh.triangles_tree
    ids, counts = tree.intersection_v(points - radius[:, None], points + radius[:, None])
    near = np.zeros(len(points), bool)
    if len(ids) == 0:
        return near
    ids = np.asarray(ids, np.int64)
    owner = np.repeat(np.arange(len(points)), np.asarray(counts, np.int64))
    triangles = np.asarray(mesh.triangles)
    for chunk in range(0, len(ids), 200_000):
        tri, who = ids[chunk : chunk + 200_000], owner[chunk : chunk + 200_000]
        distance = np.linalg.norm(closest_point(triangles[tri], points[who]) - points[who], axis=1)
        near[who[distance < radius[who]]] = True
    return near


def inside_solids(points: np.ndarray, solids: list) -> np.ndarray:
    inside = np.zeros(len(points), bool)
    for solid in solids:
        lo, hi = solid.bounds
        cand = np.flatnonzero(np.all((points >= lo) & (points <= hi), axis=1) & ~inside)
        if len(cand):
            inside[cand[solid.contains(points[cand])]] = True
    return inside


@dataclass
class Validation:
    ok: bool
    tolerance: float
    near_surface_points: int = 0
    free_points: int = 0
    violations: int = 0
    worst_depth: float = 0.0
    uncovered: int = 0
    surface_points: int = 0
    message: str = ""
    bad_pieces: list = field(default_factory=list)  # pieces holding a free point
    uncovered_faces: list = field(default_factory=list)  # faces with a surface sample no piece covers


def validate(
    mesh,
    pieces: list[Piece],
    tolerance: float,
    samples: int = 6000,
    seed: int = 0,
    solids: list | None = None,
    progress: bool = False,
    bounds: list[Piece] | None = None,
) -> Validation:
    """Does the decomposition keep every free point of the original mesh free, and cover its surface?

    `solids`: the mesh's closed parts (inside them is not free space); default: the whole mesh if it is closed.
    `bounds`: pieces that hold their parts by design (convex hulls): inside them is not free space either, and they
    count for coverage; `pieces` are the ones tested.
    Samples (fixed seed):
    - near-surface points: surface samples (area-weighted, plus face centroids, `samples` in all) moved a
      distance `tolerance` along the face normal, both ways, then kept only if their true distance to the surface
      is >= 0.9 tolerance and they are inside no solid;
    - free-space points: `samples` uniform in the mesh's box grown by 2 tolerance, kept under the same rule.
    Asserts: no kept point lies inside any convex piece by more than 1e-9 of the mesh size (a piece that adds
    volume farther than `tolerance` from the surface fails: e.g. the convex hull of a U-shaped channel fills the
    channel), and every surface sample is within `tolerance` of some piece (nothing of the obstacle was dropped).
    """
    import trimesh

    rng = np.random.default_rng(seed)
    if solids is None:
        solids = [mesh] if (mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0) else []
    diag = float(np.linalg.norm(mesh.extents))
    points, face_index = trimesh.sample.sample_surface(mesh, samples // 2, seed=int(rng.integers(1 << 31)))
    centroids = np.asarray(mesh.triangles_center)
    face_ids = np.arange(len(centroids))
    if len(centroids) > samples // 2:
        face_ids = rng.choice(len(centroids), samples // 2, replace=False)
    surface = np.vstack([points, centroids[face_ids]])
    surface_faces = np.r_[face_index, face_ids]
    normals = np.asarray(mesh.face_normals)[surface_faces]
    near = np.vstack([surface + tolerance * normals, surface - tolerance * normals])
    lo, hi = mesh.bounds[0] - 2 * tolerance, mesh.bounds[1] + 2 * tolerance
    free = rng.uniform(lo, hi, size=(samples, 3))
    candidates = np.vstack([near, free])
    bar = progress_bar(total=4, desc=f"validating {len(pieces)} pieces", disable=not progress)
    keep = ~within(candidates, mesh, 0.9 * tolerance)
    bar.update(1)
    keep[keep] &= ~inside_solids(candidates[keep], solids)
    if bounds:
        keep[keep] &= inside_any(candidates[keep], bounds, margin=0.0)[0] < 0
    bar.update(1)
    kept = candidates[keep]
    n_near = int(keep[: len(near)].sum())
    depth, which = inside_any(kept, pieces, margin=0.0)
    bar.update(1)
    bad = depth > 1e-9 * diag
    # Coverage: each surface sample inside or within tolerance of a piece (max plane distance <= tolerance).
    reach, _ = inside_any(surface, pieces + (bounds or []), margin=tolerance)
    bar.update(1)
    bar.close()
    missing = reach < -tolerance
    result = Validation(
        ok=not bad.any() and not missing.any(),
        tolerance=tolerance,
        near_surface_points=n_near,
        free_points=int(keep[len(near) :].sum()),
        violations=int(bad.sum()),
        worst_depth=float(depth[bad].max()) if bad.any() else 0.0,
        uncovered=int(missing.sum()),
        surface_points=len(surface),
        bad_pieces=sorted(set(which[bad].tolist())),
        uncovered_faces=sorted(set(surface_faces[missing].tolist())),
    )
    if bad.any():
        result.message = (
            f"{result.violations} of {len(kept)} free points are inside a piece (up to {result.worst_depth:.3g} deep)"
        )
    elif missing.any():
        result.message = f"{result.uncovered} of {len(surface)} surface points are not covered by any piece"
    return result


def volume_report(mesh, pieces: list[Piece], closed: bool, samples: int = 20000, seed: int = 0) -> dict:
    """How much the pieces add, estimated from `samples` uniform points (fixed seed) in the pieces' box. Relative to
    the mesh when it is `closed` (`added`: the volume inside a piece but outside the mesh's closed parts, over
    theirs), else to the mesh's convex hull (`added`: the pieces' volume over the hull's, minus 1; at most about 0,
    as every piece lies in the hull save a flat part's thickness)."""
    rng = np.random.default_rng(seed)
    corners = np.vstack([p.vertices for p in pieces])
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    box = float(np.prod(hi - lo))
    points = rng.uniform(lo, hi, (samples, 3))
    in_pieces = inside_any(points, pieces, margin=0.0)[0] >= 0
    hull = float(mesh.convex_hull.volume)
    report = {"samples": samples, "pieces": float(in_pieces.mean() * box), "hull": hull}
    if closed:  # (each part apart: overlapping closed shells are common, and one ray-parity test would miscount)
        in_mesh = inside_solids(points, [mesh.submesh([c], append=True) for c in components(mesh)])
        report.update(mesh=float(in_mesh.mean() * box), relative_to="mesh")
        report["added"] = float((in_pieces & ~in_mesh).mean() / max(in_mesh.mean(), 1 / samples))
    else:
        report.update(mesh=None, relative_to="hull", added=report["pieces"] / hull - 1 if hull > 0 else 0.0)
    return report
