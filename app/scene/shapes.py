"""Collision shapes as the stages after the scene see them: how near counts as touching, what Drake collides a mesh
as, and the box around a turned shape."""

from __future__ import annotations

import numpy as np

# pydrake is imported inside the functions that use it, so that importing the package does not load Drake.

# Signed distance at or below which two geometries touch: an endpoint there is refused (no motion out of it can be
# proved free).
CONTACT = 1e-9


def hull_vertices(shape) -> np.ndarray:
    """The vertices (n, 3) of a Drake Mesh's or Convex's convex hull, in its frame and scaled: what Drake's
    proximity engine collides with for it."""
    hull = shape.GetConvexHull()
    return np.array([hull.vertex(i) for i in range(hull.num_vertices())], float).reshape(-1, 3)


# The six faces of the box [-1, 1]^3, each a loop of corners around it.
BOX_FACES = (
    [[(s, -1, -1), (s, 1, -1), (s, 1, 1), (s, -1, 1)] for s in (-1, 1)]
    + [[(-1, s, -1), (1, s, -1), (1, s, 1), (-1, s, 1)] for s in (-1, 1)]
    + [[(-1, -1, s), (1, -1, s), (1, 1, s), (-1, 1, s)] for s in (-1, 1)]
)


def half_extent(shape, rotation: np.ndarray) -> np.ndarray:
    """Half the size, along the world axes, of the box around a shape turned by `rotation` (3x3)."""
    from pydrake.geometry import Box, Capsule, Convex, Cylinder, Ellipsoid, Mesh, Sphere

    if isinstance(shape, Box):
        return np.abs(rotation) @ (np.array([shape.width(), shape.depth(), shape.height()]) / 2)
    if isinstance(shape, Sphere):
        return np.full(3, shape.radius())
    if isinstance(shape, (Cylinder, Capsule)):  # round about its z axis: a disc at each end (capsule: a sphere)
        axis = np.abs(rotation[:, 2])
        rim = np.sqrt(np.clip(1 - axis**2, 0, 1)) if isinstance(shape, Cylinder) else np.ones(3)
        return axis * shape.length() / 2 + rim * shape.radius()
    if isinstance(shape, Ellipsoid):
        return np.sqrt(rotation**2 @ np.array([shape.a(), shape.b(), shape.c()]) ** 2)
    if isinstance(shape, (Convex, Mesh)):
        points = hull_vertices(shape) @ rotation.T
        return np.abs(points).max(axis=0)
    return np.zeros(3)
