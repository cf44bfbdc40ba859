"""Signed distances from many workspace points to spheres, capsules and cylinders, in closed form, in numpy.

The workspace gap search asked SceneGraph for these one point per call; here a batch of points and pieces is
answered at once, with SceneGraph's answers (QueryObject.ComputeSignedDistanceToPoint, as Drake's
distance_to_point_callback computes it), its conventions where the gradient is not unique included:

- a sphere is a capsule of no length, and a capsule's distance is the sphere's about the nearest point of its
  segment; at that point (within Drake's tolerance, 1e-14 times the radius but at least 1e-14) the gradient is
  the piece's own x axis;
- a cylinder is its cross-section through the point and the axis, a rectangle (r, z): outside it the gradient
  leaves the nearest point of the rectangle; within the tolerance of a side (r = radius or |z| = half length) it is
  that side's normal, of both sides at a rim, normalised; inside, it is the normal of the nearest side, the
  barrel's when it is no farther than a cap; on the axis (r below the tolerance) the barrel's normal is the x axis;
  and z = 0 counts as the top's side.
"""

from __future__ import annotations

import numpy as np

from app.checking.polytopes import pairs_near

# Drake's DistanceToPointRelativeTolerance: a size's round-off in a pose, at least 1e-14 m.
_TOLERANCE = 1e-14


class RoundShapes:
    """Spheres, capsules and cylinders fixed in the world, each round about its frame's z axis and given by
    (the frame's rotation (3, 3) and origin (3,) in the world, radius, half length along z (0 for a sphere),
    whether it is a cylinder (else a capsule or a sphere))."""

    def __init__(self, pieces: list[tuple[np.ndarray, np.ndarray, float, float, bool]]):
        self.rotations = np.array([piece[0] for piece in pieces], float).reshape(-1, 3, 3)
        self.origins = np.array([piece[1] for piece in pieces], float).reshape(-1, 3)
        self.radii = np.array([piece[2] for piece in pieces], float)
        self.half_lengths = np.array([piece[3] for piece in pieces], float)
        self.cylinder = np.array([piece[4] for piece in pieces], bool)
        self.count = len(pieces)
        # The sphere about a piece's origin that holds it.
        self.bounds = np.where(self.cylinder, np.hypot(self.radii, self.half_lengths), self.radii + self.half_lengths)

    def near(self, P: np.ndarray, reach: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The points (n, 3) and pieces within `reach` (n,) of each other: (point index, signed distance, unit
        gradient of the distance at the point, (m, 3)), by point; negative inside, as SceneGraph answers."""
        P = np.atleast_2d(np.asarray(P, float))
        if not self.count or not len(P):
            return np.empty(0, int), np.empty(0), np.empty((0, 3))
        points, pieces = pairs_near(P, reach, self.origins, self.bounds)
        ball = np.linalg.norm(P[points] - self.origins[pieces], axis=1) - self.bounds[pieces]
        keep = ball <= reach[points] * (1 + 1e-9)  # a bound: the exact test below decides
        points, pieces = points[keep], pieces[keep]
        R = self.rotations[pieces]
        local = np.einsum("mji,mj->mi", R, P[points] - self.origins[pieces])  # R^T (p - origin)
        distance, gradient = np.empty(len(points)), np.empty((len(points), 3))
        for flat, measure in ((False, _capsules), (True, _cylinders)):
            these = self.cylinder[pieces] == flat
            distance[these], gradient[these] = measure(
                local[these], self.radii[pieces[these]], self.half_lengths[pieces[these]]
            )
        within = distance <= reach[points]
        return points[within], distance[within], np.einsum("mij,mj->mi", R[within], gradient[within])


def _capsules(p: np.ndarray, radius: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed distances and gradients (in the pieces' frames) of points p (m, 3), in their pieces' frames, to
    capsules of these radii and half lengths (spheres where 0)."""
    q = p.copy()
    q[:, 2] -= np.clip(p[:, 2], -half, half)  # from the nearest point of the segment
    length = np.linalg.norm(q, axis=1)
    unique = length > _TOLERANCE * np.maximum(1.0, radius)
    gradient = np.tile([1.0, 0.0, 0.0], (len(p), 1))
    gradient[unique] = q[unique] / length[unique, None]
    # As Drake: (q - N) . gradient, N = radius * gradient, which holds at the centre too.
    return np.einsum("mi,mi->m", q - radius[:, None] * gradient, gradient), gradient


def _cylinders(p: np.ndarray, radius: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed distances and gradients (in the pieces' frames) of points p (m, 3), in their pieces' frames, to
    cylinders of these radii and half lengths: the distance to the rectangle [-radius, radius] x [-half, half] of
    the point's (r, z), mapped back along the point's radial direction."""
    r, z = np.sqrt(p[:, 0] ** 2 + p[:, 1] ** 2), p[:, 2]
    side = np.where(z < 0, -1.0, 1.0)  # z = 0 goes to the top, as Drake's Sign(0) = 1
    tol_r, tol_z = _TOLERANCE * np.maximum(1.0, radius), _TOLERANCE * np.maximum(1.0, half)
    out_r, out_z = r > radius + tol_r, np.abs(z) > half + tol_z
    on_r, on_z = ~out_r & (r >= radius - tol_r), ~out_z & (np.abs(z) >= half - tol_z)
    radial = np.tile([1.0, 0.0], (len(p), 1))  # on the axis (r below the tolerance), the x axis
    off_axis = r >= tol_r
    radial[off_axis] = p[off_axis, :2] / r[off_axis, None]
    # The nearest point (nr, nz): the point clamped onto the rectangle, moved out to a side from inside.
    nr = np.where(out_r | on_r, radius, r)
    nz = np.where(out_z | on_z, side * half, z)
    outside = out_r | out_z
    on = ~outside & (on_r | on_z)
    inside = ~outside & ~on
    gr, gz = np.zeros(len(p)), np.zeros(len(p))
    span = np.hypot(r - nr, z - nz)
    gr[outside], gz[outside] = (r - nr)[outside] / span[outside], (z - nz)[outside] / span[outside]
    both = np.where(on_r & on_z, np.sqrt(0.5), 1.0)  # on a rim: the two sides' normals, normalised
    gr[on], gz[on] = (on_r * both)[on], (on_z * side * both)[on]
    # Inside: the nearest side, the barrel when no farther than a cap (Drake's +r, -r, +z, -z order of ties).
    barrel = inside & (radius - r <= np.minimum(np.abs(half - z), np.abs(-half - z)))
    cap = inside & ~barrel
    gr[barrel], nr[barrel] = 1.0, radius[barrel]
    gz[cap], nz[cap] = side[cap], (side * half)[cap]
    gradient = np.column_stack([gr[:, None] * radial, gz])
    return gr * (r - nr) + gz * (z - nz), gradient
