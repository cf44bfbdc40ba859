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
