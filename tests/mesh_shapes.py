"""Meshes the mesh tests generate (no files shipped): a closed U-shaped channel, the same U as loose boxes, a bent
open sheet. The channel runs along x; its slot is 2 wide (|y| < 1) and open at the top (z > 0.5)."""

import numpy as np
import trimesh

# The U's cross-section in the (y, z) plane, counter-clockwise: floor 0..0.5, walls 0.5 thick up to z = 2.
U_SECTION = np.array(
    [(-1.5, 0.0), (1.5, 0.0), (1.5, 2.0), (1.0, 2.0), (1.0, 0.5), (-1.0, 0.5), (-1.0, 2.0), (-1.5, 2.0)]
)


def _ear_clip(poly: np.ndarray) -> list[tuple[int, int, int]]:
    """Triangles of a simple counter-clockwise polygon."""
    idx = list(range(len(poly)))
    tris = []

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    def inside(p, a, b, c):
        return cross(a, b, p) >= 0 and cross(b, c, p) >= 0 and cross(c, a, p) >= 0

    while len(idx) > 3:
        for k in range(len(idx)):
            i, j, n = idx[k - 1], idx[k], idx[(k + 1) % len(idx)]
            if cross(poly[i], poly[j], poly[n]) <= 0:
                continue
            if any(inside(poly[m], poly[i], poly[j], poly[n]) for m in idx if m not in (i, j, n)):
                continue
            tris.append((i, j, n))
            idx.pop(k)
            break
    tris.append(tuple(idx))
    return tris


def extrude_x(section: np.ndarray, length: float) -> trimesh.Trimesh:
    """A closed prism: the (y, z) polygon swept along x from -length/2 to length/2."""
    m = len(section)
    verts = np.vstack([np.c_[np.full(m, -length / 2), section], np.c_[np.full(m, length / 2), section]])
    faces = []
    for i, j, n in _ear_clip(section):
        faces += [(i, n, j), (m + i, m + j, m + n)]
    for k in range(m):
        a, b = k, (k + 1) % m
        faces += [(a, b, m + b), (a, m + b, m + a)]
    mesh = trimesh.Trimesh(verts, np.array(faces), process=True)
    mesh.fix_normals()
    assert mesh.is_watertight and mesh.volume > 0
    return mesh


def u_channel(length: float = 4.0) -> trimesh.Trimesh:
    return extrude_x(U_SECTION, length)


def u_boxes(length: float = 4.0) -> trimesh.Trimesh:
    """The same U as three overlapping boxes in one mesh: not watertight (a typical export)."""
    T = trimesh.transformations.translation_matrix
    return trimesh.util.concatenate(
        [
            trimesh.creation.box([length, 3, 0.5], T([0, 0, 0.25])),
            trimesh.creation.box([length, 0.5, 2], T([0, -1.25, 1.0])),
            trimesh.creation.box([length, 0.5, 2], T([0, 1.25, 1.0])),
        ]
    )


def bent_sheet(radius: float = 2.0, angle: float = np.pi, width: float = 3.0, n_arc: int = 24) -> trimesh.Trimesh:
    """An open, zero-thickness half-cylinder sheet (axis x, arching over the origin in y-z)."""
    theta = np.linspace(0, angle, n_arc + 1)
    ring = np.c_[radius * np.cos(theta), radius * np.sin(theta)]
    verts = np.vstack([np.c_[np.full(len(ring), -width / 2), ring], np.c_[np.full(len(ring), width / 2), ring]])
    n = len(ring)
    faces = []
    for k in range(n - 1):
        faces += [(k, k + 1, n + k + 1), (k, n + k + 1, n + k)]
    return trimesh.Trimesh(verts, np.array(faces), process=True)


def open_u(length: float = 4.0) -> trimesh.Trimesh:
    """The U channel without its end caps: open (not watertight), walls of zero thickness (a typical export)."""
    mesh = u_channel(length)
    keep = np.abs(mesh.face_normals[:, 0]) < 0.5
    return trimesh.Trimesh(mesh.vertices, mesh.faces[keep], process=True)


def holed_shell(
    outer: float = 1.2, inner: float = 1.0, hole_angle: float = np.radians(24), rings: int = 16, sectors: int = 48
) -> trimesh.Trimesh:
    """A closed, thick spherical shell (a trap) with a round opening about +z: its inner cavity reaches the outside
    only through the hole (radius `inner * sin(hole_angle)` at the inner wall). 2 * (2 rings - 1 + 1) * sectors
    triangles: 3,072 with the defaults."""
    theta = np.linspace(hole_angle, np.pi, rings + 1)[:-1]  # polar angles of the rings; the pole closes each sphere
    phi = np.linspace(0, 2 * np.pi, sectors, endpoint=False)

    def sphere(radius):
        ring = np.stack([np.outer(np.sin(theta), np.cos(phi)), np.outer(np.sin(theta), np.sin(phi))], -1)
        points = np.c_[radius * ring.reshape(-1, 2), radius * np.repeat(np.cos(theta), sectors)]
        return np.vstack([points, [0, 0, -radius]])

    verts = np.vstack([sphere(outer), sphere(inner)])
    per = rings * sectors + 1  # vertices per sphere
    faces = []
    for base, flip in ((0, False), (per, True)):
        for r in range(rings - 1):
            for s in range(sectors):
                a, b = base + r * sectors + s, base + r * sectors + (s + 1) % sectors
                c, d = a + sectors, b + sectors
                faces += [(a, c, b), (b, c, d)] if not flip else [(a, b, c), (b, d, c)]
        pole, last = base + per - 1, base + (rings - 1) * sectors
        for s in range(sectors):
            a, b = last + s, last + (s + 1) % sectors
            faces.append((a, pole, b) if not flip else (a, b, pole))
    for s in range(sectors):  # the rim joining the two spheres round the hole
        a, b = s, (s + 1) % sectors
        faces += [(a, b, per + a), (b, per + b, per + a)]
    mesh = trimesh.Trimesh(verts, np.array(faces), process=True)
    mesh.fix_normals()
    assert mesh.is_watertight and mesh.volume > 0
    return mesh


def loose_walls(jitter: float = 1e-6, seed: int = 0) -> trimesh.Trimesh:
    """Two parallel walls 2 apart (|y| from 1 to 1.2, 4 long, 2 high) and a floor slab beside them, as a scene
    export leaves them: every triangle with corners of its own, moved by up to `jitter`, so that no two share an
    edge (OMPL.app's environments: Maze_planar's 1,892 triangles are 1,884 connected parts)."""
    T = trimesh.transformations.translation_matrix
    boxes = [
        trimesh.creation.box([4, 0.2, 2], T([0, 1.1, 1])),
        trimesh.creation.box([4, 0.2, 2], T([0, -1.1, 1])),
        trimesh.creation.box([3, 3, 0.2], T([5, 0, 0.1])),
    ]
    triangles = np.vstack([b.triangles for b in boxes])
    triangles = triangles + np.random.default_rng(seed).uniform(-jitter, jitter, triangles.shape)
    return trimesh.Trimesh(triangles.reshape(-1, 3), np.arange(3 * len(triangles)).reshape(-1, 3), process=False)
