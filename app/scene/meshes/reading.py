"""Mesh files: any format trimesh reads (COLLADA via pycollada, in metres), checked before and after trimesh's
processing, and a file's content hash (what the cache is keyed by)."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from app.errors import UserError
from app.io import check_input
from app.scene.files import MAX_COORDINATE, MESH_SUFFIXES

# trimesh (optional, slow to import) is imported inside the functions that use it.


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
