"""Mesh obstacles and mesh robots for Drake: format conversion, convex decomposition, validation and an on-disk cache.

Drake reads .obj/.vtk/.gltf for collision (not .stl/.dae) and its proximity engine treats a mesh as its convex hull,
so a non-convex mesh must become a set of convex pieces. The mesh is split into connected parts (faces sharing an
edge) and a method is chosen per part (`choose_method`):

- "convex": the part is closed (watertight, consistently wound, positive volume) and equals its own hull: 1 piece.
- "shell": closed but not convex: pieces that reach into the part's own solid, where the robot cannot be anyway
  (`shell_pieces`). A patch of faces plus its corners moved inward by half the wall's thickness, as one convex
  hull, grows while it holds no other point of the surface deeper than SHELL_REACH * tolerance. A side that bulges
  outward (a sphere seen from outside, a thick wall's face) becomes a few large caps; a hollow side stays within
  reach of flat. Seconds on a few thousand triangles, with far fewer pieces than "faces" makes and where CoACD can
  fail validation (docs/benchmarks.md, "Mesh scenes"). Pieces that fail validation become face pieces (once); if
  the part still fails, it moves on to "coacd".
- "coacd": CoACD approximate decomposition, pre-processing off (it thickens thin walls), in a child process with a
  time limit (it can crash or run for minutes). Falls back to "faces" when it fails or its pieces fail validation.
- "faces": open or thin parts (typical COLLADA scene exports): exact pieces. Adjacent faces are grown into one
  piece while they fit in a slab of width `tolerance / 2` along the seed face's normal and their projection onto
  that plane is nearly convex (all faces facing the same way; the 2-D hull's area exceeds the projected faces' by at
  most a rim of mean width slab/2 along its perimeter: a curved surface projects to a slightly non-convex outline,
  and an exact test stopped most patches at two triangles), so every point of the piece lies within about
  tolerance/2 (+ thickness/2) of the original surface. Coplanar adjacent triangles are the exact special case.
  Each piece is that flat convex polygon extruded by `thickness` = tolerance/5 (a prism).

Robot links (`conservative`, see `choose_method`) take no exact method that may cost minutes: open parts (CAD
exports: unstitched faces, 2-face slivers) and closed parts whose shell pieces fail become convex hulls, merged by
`hull_groups`; these contain their parts (never too small) and are exempt from the free-space test. `--mesh-method
convex` forces hulls for every part. `volume_report` states what the pieces add.

Every decomposition is validated against the original surface (`validate`); parts whose pieces hold free points
move on to their next method. The result, or the failure, is cached on disk (`cache_root()`), keyed by the mesh
file's content hash, the method request, the parameters, DECOMPOSER_VERSION and CoACD's version. An entry's manifest
holds a sha256 of every file, and the manifest itself is sealed with an HMAC-SHA256 under a per-user secret key kept
outside the cache (`key_path()`): checksums alone only catch accidents, since whoever writes a cache folder can write
matching checksums for pieces that do not contain the mesh (a false "free" for the planner). An entry whose seal is
missing or wrong is rebuilt, not trusted; so is a converted .obj (`converted_obj`), sealed the same way. Entries are
built in a staging folder and renamed into place, so concurrent runs see a whole entry or none.

Load cost: SceneGraph's registration cost grows quadratically with the number of geometries (docs/benchmarks.md,
"Mesh scenes"), so merging faces into few pieces matters as much as the decomposition.
(Check cost need not grow so: app.scene.custom anchors environment pieces to the world, see `env_urdf`.)

The tolerance is the caller's choice; `default_tolerance` (0.2 % of the mesh's size) knows nothing of the robot, so
app.scene.custom derives environment tolerances from the edge-check step instead.
"""

from __future__ import annotations

import hashlib
import heapq
import hmac
import json
import os
import secrets
import shutil
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from app.errors import UserError
from app.io import check_input, write_atomically

# trimesh and coacd (optional, slow to import) are imported inside the functions that use them.

# Bump when anything that changes the pieces (or the files of an entry) changes: old cache entries then go unused.
DECOMPOSER_VERSION = "5"
CACHE_ENV = "NPP_CACHE_DIR"
KEY_ENV = "NPP_KEY_FILE"
KEY_BYTES = 32
DRAKE_MESH_SUFFIXES = {".obj", ".vtk", ".gltf"}
CONVERTIBLE_SUFFIXES = {".stl", ".dae", ".ply", ".off", ".glb"}
MESH_SUFFIXES = DRAKE_MESH_SUFFIXES | CONVERTIBLE_SUFFIXES
METHODS = ("auto", "convex", "shell", "coacd", "faces")
# How far a shell piece may stand proud of the surface, as a fraction of the tolerance: validation rejects pieces
# holding points 0.9 tolerance from the surface, and a shell piece's hull has no extra thickness (a face piece has).
SHELL_REACH = 0.6
# The largest mesh coordinate taken (metres, after COLLADA's unit): far beyond any robot or building, far below where
# doubles lose the millimetres (at 1e6 m their spacing is 1e-10 m) and trimesh's vertex merging overflows.
MAX_COORDINATE = 1e6


def writable_folder(folder: Path) -> Path:
    """`folder`, made if missing; one line naming the cache's variable where it cannot be."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        reason = exc.strerror or exc
        raise UserError(f"cannot write {folder}: {reason} (set {CACHE_ENV} to a writable folder)") from None
    return folder


def cache_root() -> Path:
    """$NPP_CACHE_DIR, else $XDG_CACHE_HOME/npp, else ~/.cache/npp; absolute (generated model files name the
    cached meshes by file:// URIs, which must not depend on the working directory)."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV]).absolute()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return (Path(base) / "npp").absolute()


# ---- the cache's key ----------------------------------------------------------------------------------------------
def key_path() -> Path:
    """The secret key that seals cache entries: $NPP_KEY_FILE, else $XDG_CONFIG_HOME/npp/cache.key, else
    ~/.config/npp/cache.key. Outside the cache on purpose: a cache folder is something one may be handed, copy or
    share, and a seal made with a key that travels with it would prove nothing."""
    if os.environ.get(KEY_ENV):
        return Path(os.environ[KEY_ENV]).expanduser().absolute()
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return (Path(base) / "npp" / "cache.key").absolute()


_keys: dict[Path, bytes | None] = {}  # per key file: its key, or None when it cannot be used (said once)


def cache_key() -> bytes | None:
    """This user's key (made on first use), or None when it cannot be read or made: then one line says so and no
    cached entry is reused in this process (entries are still written, unsealed, so they are never trusted)."""
    path = key_path()
    if path not in _keys:
        try:
            _keys[path] = _load_key(path)
        except OSError as exc:
            reason = exc.strerror or str(exc)
            _warn(
                f"cannot use the mesh cache key {path}: {reason}; cached meshes are not reused (set {KEY_ENV} to a "
                "file of yours)"
            )
            _keys[path] = None
    return _keys[path]


def _load_key(path: Path) -> bytes:
    """The key in `path`; made when missing: KEY_BYTES random bytes in a private temporary file, linked into place
    (mode 0600, whole or not at all; when two processes make it at once, both then read the one that was linked
    first). A key file that others may read or write, or not of the key's size, is refused (OSError)."""
    for _ in range(3):
        try:
            with open(path, "rb") as f:
                status = os.fstat(f.fileno())
                key = f.read(KEY_BYTES + 1)
        except FileNotFoundError:
            _make_key(path)
            continue
        if hasattr(os, "getuid") and status.st_uid != os.getuid():
            raise OSError(0, "it belongs to another user")
        if status.st_mode & 0o077:
            raise OSError(0, f"others may read or write it (mode {status.st_mode & 0o777:o}; chmod 600 it)")
        if len(key) != KEY_BYTES:
            raise OSError(0, f"it holds {len(key)} bytes, not a key of {KEY_BYTES}")
        return key
    raise OSError(0, "it vanished while being made")


def _make_key(path: Path) -> None:
    path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)  # mode 0600
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(secrets.token_bytes(KEY_BYTES))
            f.flush()
            os.fsync(f.fileno())
        try:
            os.link(tmp, path)  # fails if another process made the key meanwhile: theirs is kept
        except FileExistsError:
            pass
        except OSError:  # a filesystem without hard links
            if not path.exists():
                os.rename(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _seal(key: bytes, kind: str, payload: bytes) -> str:
    """HMAC-SHA256 of `payload` under `key`, for `kind` of record (so a seal of one kind is none of another)."""
    return hmac.new(key, kind.encode() + b"\0" + payload, hashlib.sha256).hexdigest()


def _canonical(record: dict) -> bytes:
    """The one byte string of a JSON record (as read back: lists, not tuples), which its seal covers."""
    return json.dumps(record, sort_keys=True, separators=(",", ":")).encode()


def _warn(message: str) -> None:
    """A line on stderr, as this module reports everything it does not raise (its progress bars go there too)."""
    print(f"warning: {message}", file=sys.stderr)


def _progress(**kwargs):
    """A tqdm bar on stderr, cleared when done; only on a terminal (so logs and one-line errors stay clean)."""
    from tqdm import tqdm

    disable = True if kwargs.pop("disable", False) else None  # None: tqdm's own "is stderr a terminal?"
    return tqdm(file=sys.stderr, leave=False, disable=disable, **kwargs)


# ---- reading ------------------------------------------------------------------------------------------------------
def load_mesh(path: str | Path):
    """A trimesh.Trimesh from any format trimesh reads (DAE via pycollada); scenes are flattened with their transforms.

    Raises UserError (one line) for a missing, oversized, unreadable or empty mesh, a non-finite or huge coordinate
    (checked before trimesh's processing, which would drop a NaN vertex's faces without a word), or triangles that
    all have no area (collinear or coincident vertices)."""
    path = check_input(path, "mesh file")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise UserError(
            f"unsupported mesh format '{path.suffix}' ({path.name}); use one of {', '.join(sorted(MESH_SUFFIXES))}"
        )
    try:
        import trimesh
    except ImportError:
        raise UserError("mesh support needs the 'meshes' extra: pip install -e '.[meshes]'") from None
    try:
        loaded = trimesh.load(str(path), force="mesh", process=False)
    except ImportError:  # trimesh guesses the text encoding of bytes no format explains with an optional module
        raise UserError(f"cannot read mesh {path.name}: not a valid {path.suffix} file") from None
    except Exception as exc:  # trimesh raises many types (ValueError, KeyError, collada errors, ...)
        raise UserError(
            f"cannot read mesh {path.name}: {' '.join(str(exc).split())[:200] or type(exc).__name__}"
        ) from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise UserError(f"cannot read mesh {path.name}: not a valid {path.suffix} file (no triangles in it)")
    mesh = loaded
    if path.suffix.lower() == ".dae":
        scale = _collada_unit(path)
        if scale != 1.0:  # trimesh ignores COLLADA's <unit meter="..."/>; Drake works in metres
            mesh.apply_scale(scale)
    vertices = np.asarray(mesh.vertices)
    if not np.all(np.isfinite(vertices)):
        row = int(np.flatnonzero(~np.isfinite(vertices).all(axis=1))[0])
        raise UserError(f"cannot read mesh {path.name}: vertex {row + 1} has a coordinate that is not a finite number")
    if np.abs(vertices).max(initial=0.0) > MAX_COORDINATE:
        raise UserError(
            f"cannot read mesh {path.name}: coordinates up to {np.abs(vertices).max():.3g}; the limit is "
            f"{MAX_COORDINATE:g} (metres)"
        )
    mesh.process()
    mesh.remove_unreferenced_vertices()
    mask = mesh.nondegenerate_faces()
    if not mask.all():
        mesh.update_faces(mask)
    if len(mesh.faces) == 0 or mesh.extents is None or not np.linalg.norm(mesh.extents) > 0:
        raise UserError(f"cannot read mesh {path.name}: every triangle has zero area (collinear vertices)")
    return mesh


def _collada_unit(path: Path) -> float:
    """Metres per unit of a COLLADA file (its <asset><unit meter=...>), 1 when absent or unreadable. (The file's
    up_axis is not applied: the mesh is used in its own coordinates, Z up as Drake's.)"""
    import re

    head = path.read_bytes()[:20000].decode("utf-8", "replace")
    match = re.search(r'<unit\b[^>]*\bmeter\s*=\s*"([^"]+)"', head)
    try:
        value = float(match.group(1)) if match else 1.0
    except ValueError:
        return 1.0
    return value if np.isfinite(value) and value > 0 else 1.0


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


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
    axes = np.linalg.svd(centred)[2]  # (a part has a triangle at least: 3 points, 3 axes)
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
    bar = _progress(total=len(faces), desc=desc, unit="face", disable=not progress)
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
    of a U-shaped end face fills the U's slot): validation finds those pieces and `_decompose_parts` replaces them
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


_COACD_CHILD = """
import sys, numpy as np, coacd
data = np.load(sys.argv[1])
coacd.set_log_level("error")
out = {}
for m in range(int(data["count"])):
    parts = coacd.run_coacd(coacd.Mesh(data[f"vertices{m}"], data[f"faces{m}"]), threshold=float(data["threshold"]),
                            preprocess_mode="off", seed=0)
    out.update({f"m{m}_{i}": np.asarray(v, float) for i, (v, _) in enumerate(parts)})
    print(m, flush=True)
np.savez(sys.argv[2], **out)
"""


class MethodFailed(Exception):
    """A decomposition method could not produce pieces (crash, time-out); the next method is tried."""


def coacd_pieces(meshes: list, threshold: float, timeout: float = 120.0, progress: bool = True) -> list[list[Piece]]:
    """CoACD on each closed mesh, in one child process: CoACD can crash (segfault on non-manifold input) or run for
    minutes, so it runs apart, with a time limit (`timeout` seconds per mesh)."""
    import subprocess

    try:
        import coacd  # noqa: F401  (only to fail early with a clear message)
    except ImportError:
        raise UserError("CoACD is not installed: pip install -e '.[meshes]'") from None
    with tempfile.TemporaryDirectory(prefix="npp-coacd-") as tmp:
        source, target = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        arrays = {"count": len(meshes), "threshold": threshold}
        for m, mesh in enumerate(meshes):
            arrays[f"vertices{m}"] = np.asarray(mesh.vertices, float)
            arrays[f"faces{m}"] = np.asarray(mesh.faces, np.int64)
        np.savez(source, **arrays)
        child = subprocess.Popen(
            [sys.executable, "-c", _COACD_CHILD, str(source), str(target)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        faces = sum(len(m.faces) for m in meshes)
        bar = _progress(
            desc=f"CoACD ({len(meshes)} part(s), {faces} faces)",
            bar_format="{desc}: {elapsed}",
            mininterval=0.5,
            disable=not progress,
        )
        started = time.perf_counter()
        limit = timeout * len(meshes)
        try:
            while child.poll() is None:
                if time.perf_counter() - started > limit:
                    child.kill()
                    child.wait()
                    raise MethodFailed(f"CoACD did not finish in {limit:.0f} s")
                time.sleep(0.1)
                bar.update(1)
        finally:
            bar.close()
        if child.returncode != 0 or not target.is_file():
            raise MethodFailed(f"CoACD failed (exit code {child.returncode})")
        result = [[] for _ in meshes]
        with np.load(target) as out:
            for k in sorted(out.files, key=lambda k: tuple(int(x) for x in k[1:].split("_"))):
                v = out[k]
                if len(v) >= 4:
                    result[int(k[1:].split("_")[0])].append(hull_piece(v))
    return result


def classify(mesh) -> dict:
    """Facts the method choice rests on."""
    closed = bool(mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0)
    volume = float(mesh.volume) if closed else 0.0
    hull_volume = float(mesh.convex_hull.volume) if closed else 0.0  # only a closed mesh can be its own hull
    return {
        "faces": int(len(mesh.faces)),
        "closed": closed,
        "volume": volume,
        "hull_volume": hull_volume,
        "convex": closed and hull_volume <= volume * (1 + 1e-6) + 1e-12,
    }


def choose_method(facts: dict, conservative: bool = False) -> list[str]:
    """Methods to try in order: closed and convex -> one piece; closed -> shell pieces (seconds), then CoACD
    (minutes), then exact faces; else exact faces. `conservative` (a robot's links): a closed part that is not
    convex -> shell pieces, else its hull; any other part -> its hull (merged, see `hull_groups`): never smaller
    than the mesh, never minutes."""
    if facts["convex"]:
        return ["convex"] if conservative else ["convex", "faces"]
    if facts["closed"]:
        return ["shell", "convex"] if conservative else ["shell", "coacd", "faces"]
    return ["convex"] if conservative else ["faces"]


# ---- validation ---------------------------------------------------------------------------------------------------
def _inside_any(points: np.ndarray, pieces: list[Piece], margin: float) -> tuple[np.ndarray, np.ndarray]:
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


def _within(points: np.ndarray, mesh, radius: float) -> np.ndarray:
    """Whether each point is within `radius` of the mesh surface (exact point-triangle distances, but only to the
    triangles whose box the point's radius-box touches: much cheaper than a nearest-point query)."""
    from trimesh.triangles import closest_point

    tree = mesh.triangles_tree
    ids, counts = tree.intersection_v(points - radius, points + radius)
    near = np.zeros(len(points), bool)
    if len(ids) == 0:
        return near
    ids = np.asarray(ids, np.int64)
    owner = np.repeat(np.arange(len(points)), np.asarray(counts, np.int64))
    triangles = np.asarray(mesh.triangles)
    for chunk in range(0, len(ids), 200_000):
        tri, who = ids[chunk : chunk + 200_000], owner[chunk : chunk + 200_000]
        distance = np.linalg.norm(closest_point(triangles[tri], points[who]) - points[who], axis=1)
        near[who[distance < radius]] = True
    return near


def _inside_solids(points: np.ndarray, solids: list) -> np.ndarray:
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
    bar = _progress(total=4, desc=f"validating {len(pieces)} pieces", disable=not progress)
    keep = ~_within(candidates, mesh, 0.9 * tolerance)
    bar.update(1)
    keep[keep] &= ~_inside_solids(candidates[keep], solids)
    if bounds:
        keep[keep] &= _inside_any(candidates[keep], bounds, margin=0.0)[0] < 0
    bar.update(1)
    kept = candidates[keep]
    n_near = int(keep[: len(near)].sum())
    depth, which = _inside_any(kept, pieces, margin=0.0)
    bar.update(1)
    bad = depth > 1e-9 * diag
    # Coverage: each surface sample inside or within tolerance of a piece (max plane distance <= tolerance).
    reach, _ = _inside_any(surface, pieces + (bounds or []), margin=tolerance)
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


def _method_name(methods: dict) -> str:
    used = [m for m, n in methods.items() if n]
    return used[0] if len(used) == 1 else "mixed"


def _components(mesh) -> list[np.ndarray]:
    """Face indices of each connected part (faces sharing an edge)."""
    import trimesh

    return [
        np.asarray(c)
        for c in trimesh.graph.connected_components(mesh.face_adjacency, nodes=np.arange(len(mesh.faces)), min_len=1)
    ]


def _decompose_parts(
    mesh,
    method: str,
    tolerance: float,
    coacd_threshold: float,
    coacd_timeout: float,
    progress: bool,
    label: str,
    conservative: bool = False,
):
    """Choose a method per connected part, build, validate the whole; a part whose pieces fail moves on to its next
    method. With `conservative` (or method "convex") hulls stand for their parts as bounds, merged by `hull_groups`
    and exempt from the free-space test (they are larger than their parts by design). Returns (pieces, owner part
    per piece, the validation rounds, pieces per method, parts per method)."""
    groups = _components(mesh)
    part_of_face = np.empty(len(mesh.faces), int)
    for i, g in enumerate(groups):
        part_of_face[g] = i
    # A closed part has at least 4 faces; smaller ones (triangle soups) skip the per-part mesh and its facts.
    parts = [mesh.submesh([g], append=True) if len(g) >= 4 else None for g in groups]
    open_facts = {"faces": 0, "closed": False, "volume": 0.0, "hull_volume": 0.0, "convex": False}
    part_facts = [classify(p) if p is not None else open_facts for p in parts]
    solids = [p for p, f in zip(parts, part_facts) if f["closed"]]
    bounding = conservative or method == "convex"
    orders = [[method] if method != "auto" else choose_method(f, conservative) for f in part_facts]
    level = [0] * len(parts)
    built: dict[int, list[Piece]] = {}
    shell_groups: dict[int, list] = {}  # a shell part's face groups, piece by piece
    mended = set()
    notes = []
    tried = []
    while True:
        # (Re)build the parts without pieces at their current method: convex hulls, CoACD in one child, faces merged.
        todo = [i for i in range(len(parts)) if i not in built]
        for i in todo:
            while orders[i][level[i]] in ("shell", "coacd") and not part_facts[i]["closed"]:
                notes.append(f"part {i}: {orders[i][level[i]]} needs a closed mesh")
                if level[i] + 1 >= len(orders[i]):
                    raise UserError(
                        f"no valid convex decomposition for {label}: {orders[i][level[i]]} needs a closed mesh"
                    )
                level[i] += 1
        hull_parts = [i for i in todo if orders[i][level[i]] == "convex"]
        if bounding and hull_parts:
            points = [mesh.vertices[np.unique(mesh.faces[groups[i]])] for i in hull_parts]
            hulls, members = hull_groups(points, tolerance)
            built.update({i: [] for i in hull_parts})
            for piece, group in zip(hulls, members):
                built[hull_parts[group[0]]].append(piece)
        else:
            built.update({i: [hull_piece(parts[i].vertices)] for i in hull_parts})
        for i in todo:
            if orders[i][level[i]] == "shell":
                built[i], shell_groups[i] = shell_pieces(parts[i], tolerance, progress=progress)
        coacd_parts = [i for i in todo if orders[i][level[i]] == "coacd"]
        if coacd_parts:
            try:
                for i, pieces in zip(
                    coacd_parts, coacd_pieces([parts[i] for i in coacd_parts], coacd_threshold, coacd_timeout, progress)
                ):
                    built[i] = pieces
            except MethodFailed as exc:
                notes.append(str(exc))
                for i in coacd_parts:
                    if level[i] + 1 >= len(orders[i]):
                        raise UserError(f"no valid convex decomposition for {label}: {exc}") from None
                    level[i] += 1
                continue
        face_parts = [i for i in todo if orders[i][level[i]] == "faces"]
        if face_parts:
            face_ids = np.concatenate([groups[i] for i in face_parts])
            joined = mesh.submesh([face_ids], append=True)
            joined_owner = part_of_face[face_ids]
            pieces, seeds = face_pieces(
                joined, slab=tolerance / 2, thickness=tolerance / 5, progress=progress, with_seeds=True
            )
            for i in face_parts:
                built[i] = []
            for piece, seed in zip(pieces, seeds):
                built[joined_owner[seed]].append(piece)
        pieces, owner = [], []
        for i in range(len(parts)):
            pieces += built[i]
            owner += [i] * len(built[i])
        final = [orders[i][level[i]] for i in range(len(parts))]
        methods = {m: sum(len(built[i]) for i in range(len(parts)) if final[i] == m) for m in METHODS[1:]}
        exempt = [bounding and final[i] == "convex" for i in owner]
        checked = [k for k in range(len(pieces)) if not exempt[k]]
        bounds = [pieces[k] for k in range(len(pieces)) if exempt[k]]
        if checked:
            check = validate(
                mesh, [pieces[k] for k in checked], tolerance, solids=solids, progress=progress, bounds=bounds
            )
            check.bad_pieces = [checked[k] for k in check.bad_pieces]
        else:
            check = Validation(ok=True, tolerance=tolerance, message="convex hulls only: they contain their parts")
        record = asdict(check)
        record.pop("bad_pieces"), record.pop("uncovered_faces")
        tried.append({"methods": methods, "pieces": len(pieces), "notes": list(notes), **record})
        if check.ok:
            return pieces, owner, tried, methods, {m: final.count(m) for m in METHODS[1:] if m in final}
        blamed = {owner[k] for k in check.bad_pieces} | {int(part_of_face[f]) for f in check.uncovered_faces}
        # A shell part's few bad pieces become face pieces (once) before the part moves on to its next method.
        mend = {i for i in blamed if orders[i][level[i]] == "shell" and i not in mended}
        mend -= {int(part_of_face[f]) for f in check.uncovered_faces}
        for i in mend:
            first = owner.index(i)
            bad = [k - first for k in check.bad_pieces if owner[k] == i]
            built[i], shell_groups[i] = faces_instead(parts[i], built[i], shell_groups[i], bad, tolerance)
            notes.append(f"part {i}: {len(bad)} shell piece(s) held free points and became face pieces")
            mended.add(i)
        blamed -= mend
        if mend and not blamed:
            continue
        stuck = [i for i in blamed if level[i] + 1 >= len(orders[i])]
        if stuck or not blamed:
            raise UserError(
                f"no valid convex decomposition for {label}: {check.message}"
                + (f" ({len(stuck)} part(s) have no other method)" if stuck else "")
            )
        for i in blamed:
            level[i] += 1
            del built[i]


# ---- the cache ----------------------------------------------------------------------------------------------------
@dataclass
class Decomposition:
    """A cache entry: convex pieces as .obj files (for Drake) plus the original as .obj (for visuals)."""

    directory: Path
    method: str
    pieces: list[Path]
    visual: Path
    facts: dict = field(default_factory=dict)
    validation: dict = field(default_factory=dict)
    parts: dict = field(default_factory=dict)  # connected parts per method
    volume: dict = field(default_factory=dict)  # what the pieces add (`volume_report`)
    seconds: float = 0.0
    from_cache: bool = False
    bounds: list = field(default_factory=list)  # the mesh's box [lo, hi], from the verified manifest

    def extent(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array(self.bounds[0]), np.array(self.bounds[1])


def obj_bytes(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """A Wavefront .obj of the triangles, exactly as `_write_obj` writes it."""
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    return ("\n".join(lines) + "\n").encode()


def _write_obj(path: Path, vertices: np.ndarray, faces: np.ndarray) -> str:
    """Write a Wavefront .obj; returns the sha256 of what was written."""
    data = obj_bytes(vertices, faces)
    path.write_bytes(data)
    return hashlib.sha256(data).hexdigest()


def default_tolerance(mesh) -> float:
    """0.2 % of the mesh's bounding-box diagonal."""
    return 0.002 * float(np.linalg.norm(mesh.extents))


def decompose(
    path: str | Path,
    method: str = "auto",
    tolerance: float | None = None,
    coacd_threshold: float = 0.03,
    coacd_timeout: float = 120.0,
    cache_dir: Path | None = None,
    progress: bool = True,
    conservative: bool = False,
) -> Decomposition:
    """Convex pieces for the mesh at `path`, from the cache when a valid entry exists, else built and cached. A mesh
    with no valid decomposition is cached too: asking again raises the same UserError at once. `conservative`: see
    `choose_method` (a robot's links)."""
    path = Path(path)
    if method not in METHODS:
        raise UserError(f"unknown decomposition method '{method}' (known: {', '.join(METHODS)})")
    digest = file_sha256(check_input(path, "mesh file"))
    params = {
        "method": method,
        "tolerance": tolerance,
        "coacd_threshold": coacd_threshold,
        "version": DECOMPOSER_VERSION,
        "coacd": _coacd_version() if method == "coacd" or (method == "auto" and not conservative) else None,
        "conservative": conservative,
    }
    key = hashlib.sha256((digest + json.dumps(params, sort_keys=True)).encode()).hexdigest()[:32]
    root = (cache_dir or cache_root()) / "meshes"
    entry = root / key
    started = time.perf_counter()
    secret = cache_key()
    found = _read_entry(entry, key, secret)
    if found is not None:
        found.seconds = time.perf_counter() - started
        return found
    if entry.exists():
        if secret is not None:  # (without a key nothing is reused, and cache_key has said so)
            _warn(f"mesh cache entry {entry} is damaged; rebuilding it")
        shutil.rmtree(entry, ignore_errors=True)

    mesh = load_mesh(path)
    tolerance = float(tolerance) if tolerance else default_tolerance(mesh)
    if not tolerance > 0:
        raise UserError("mesh tolerance must be positive")
    facts = classify(mesh)
    manifest = {"key": key, "source": str(path.resolve()), "source_sha256": digest, "params": params}
    try:
        pieces, owner, tried, methods, parts = _decompose_parts(
            mesh, method, tolerance, coacd_threshold, coacd_timeout, progress, path.name, conservative
        )
        if not pieces:
            raise UserError(f"no valid convex decomposition for {path.name}: no piece has any volume")
    except UserError as exc:
        if secret is not None:  # (unsealed, it would never be read back)
            _store(root, entry, {**manifest, "error": str(exc), "files": {}}, lambda staging: None, secret)
        raise
    facts["components"] = len(set(owner)) if owner else 0
    manifest.update(
        tolerance=tolerance,
        method=_method_name(methods),
        methods=methods,
        parts=parts,
        volume=volume_report(mesh, pieces, facts["closed"]),
        tried=tried,
        facts=facts,
        bounds=mesh.bounds.tolist(),
        pieces=[f"pieces/{i:05d}.obj" for i in range(len(pieces))],
    )

    def write(staging: Path) -> None:
        (staging / "pieces").mkdir()
        files = {name: _write_obj(staging / name, p.vertices, p.faces) for name, p in zip(manifest["pieces"], pieces)}
        files["visual.obj"] = _write_obj(staging / "visual.obj", mesh.vertices, mesh.faces)
        manifest.update(files=files, build_seconds=time.perf_counter() - started)

    _store(root, entry, manifest, write, secret)
    result = _read_entry(entry, key, secret, written=manifest)
    if result is None:
        raise UserError(f"cannot write the mesh cache at {entry}")
    result.seconds = time.perf_counter() - started
    result.from_cache = False
    return result


def _store(root: Path, entry: Path, manifest: dict, write, secret: bytes | None) -> None:
    """A cache entry: `write(staging)` fills a staging folder, then manifest.json and its seal manifest.mac (none
    without a key: such an entry is never trusted), then the folder is renamed into place (atomic: a reader sees no
    entry or a whole one)."""
    try:
        root.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{entry.name}-", dir=root))
        write(staging)
        text = json.dumps(manifest, indent=1)
        (staging / "manifest.json").write_text(text)
        if secret is not None:
            (staging / "manifest.mac").write_text(_seal(secret, "mesh-cache-entry", _canonical(json.loads(text))))
        try:
            os.replace(staging, entry)
        except OSError:  # another process won the race; use theirs if it is whole
            shutil.rmtree(staging, ignore_errors=True)
    except OSError as exc:
        raise UserError(
            f"cannot write the mesh cache under {root}: {exc.strerror or exc} (set {CACHE_ENV} to a writable folder)"
        ) from None


def _read_entry(entry: Path, key: str, secret: bytes | None, written: dict | None = None) -> Decomposition | None:
    """The entry if it is one this code made for this key: its manifest parses, its seal (manifest.mac, an HMAC under
    this user's key) matches the manifest, and every file matches its checksum in it; else None. Without a key, only
    the entry just `written` (the same manifest, build time aside) is taken. An entry that records a failed
    decomposition raises its UserError again."""
    try:
        manifest = json.loads((entry / "manifest.json").read_text())
        if secret is not None:
            seal = (entry / "manifest.mac").read_text().strip()
            if not hmac.compare_digest(seal.encode(), _seal(secret, "mesh-cache-entry", _canonical(manifest)).encode()):
                return None
        elif written is None or {**manifest, "build_seconds": 0} != {
            **json.loads(json.dumps(written)),
            "build_seconds": 0,
        }:
            return None
        if manifest.get("key") != key:
            return None
        if "error" in manifest:
            raise UserError(f"{manifest['error']} (cached; delete {entry} to try again)")
        for name, digest in manifest["files"].items():
            if hashlib.sha256((entry / name).read_bytes()).hexdigest() != digest:
                return None
        pieces = [entry / name for name in manifest["pieces"]]
        if not pieces or any(name not in manifest["files"] for name in manifest["pieces"]):
            return None
        return Decomposition(
            directory=entry,
            method=manifest["method"],
            pieces=pieces,
            visual=entry / "visual.obj",
            facts=manifest["facts"],
            validation=manifest["tried"][-1],
            parts=manifest["parts"],
            volume=manifest["volume"],
            from_cache=True,
            bounds=manifest["bounds"],
        )
    except (OSError, ValueError, KeyError, TypeError, IndexError, AttributeError):
        return None


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
    in_pieces = _inside_any(points, pieces, margin=0.0)[0] >= 0
    hull = float(mesh.convex_hull.volume)
    report = {"samples": samples, "pieces": float(in_pieces.mean() * box), "hull": hull}
    if closed:  # (each part apart: overlapping closed shells are common, and one ray-parity test would miscount)
        in_mesh = _inside_solids(points, [mesh.submesh([c], append=True) for c in _components(mesh)])
        report.update(mesh=float(in_mesh.mean() * box), relative_to="mesh")
        report["added"] = float((in_pieces & ~in_mesh).mean() / max(in_mesh.mean(), 1 / samples))
    else:
        report.update(mesh=None, relative_to="hull", added=report["pieces"] / hull - 1 if hull > 0 else 0.0)
    return report


def converted_obj(path: str | Path, cache_dir: Path | None = None) -> Path:
    """A mesh Drake cannot read (.stl, .dae, ...) as an .obj in the cache (keyed by content): the shape unchanged,
    so as a collision shape Drake uses its convex hull (conservative, as usual for robot links). Sealed as decomposition
    entries are (`<key>.obj.mac` beside it: an HMAC of the key and the file's sha256 under this user's key): a
    converted file that does not verify is converted again, since a forged one would be another shape."""
    path = check_input(path, "mesh file")
    key = hashlib.sha256((file_sha256(path) + "convert" + DECOMPOSER_VERSION).encode()).hexdigest()[:32]
    target = (cache_dir or cache_root()) / "converted" / f"{key}.obj"
    seal_file = target.with_name(f"{target.name}.mac")
    secret = cache_key()
    if secret is not None and target.is_file():
        if _converted_seal_holds(secret, key, target, seal_file):
            return target
        _warn(f"mesh cache entry {target} is damaged; rebuilding it")
    mesh = load_mesh(path)
    data = obj_bytes(mesh.vertices, mesh.faces)
    target.parent.mkdir(parents=True, exist_ok=True)
    write_atomically(target, data)
    if secret is not None:
        write_atomically(seal_file, _converted_seal(secret, key, hashlib.sha256(data).hexdigest()))
    return target


def _converted_seal(secret: bytes, key: str, digest: str) -> str:
    return _seal(secret, "converted-obj", f"{key}\0{digest}".encode())


def _converted_seal_holds(secret: bytes, key: str, target: Path, seal_file: Path) -> bool:
    try:
        seal = seal_file.read_text().strip()
        digest = file_sha256(target)
    except (OSError, ValueError):
        return False
    return hmac.compare_digest(seal.encode(), _converted_seal(secret, key, digest).encode())


def _coacd_version() -> str | None:
    try:
        from importlib.metadata import version

        return version("coacd")
    except Exception:
        return None


def load_pieces(decomposition: Decomposition) -> list[Piece]:
    """The pieces back as half-space form (for tests and checks)."""
    out = []
    for p in decomposition.pieces:
        verts = [list(map(float, line.split()[1:4])) for line in p.read_text().splitlines() if line.startswith("v ")]
        out.append(hull_piece(np.array(verts)))
    return out
