"""The workspace as the samplers see it: where the robot's pieces and its passage frame are at a configuration, and
where the environment leaves narrow gaps (workspace points and their distances to obstacles). Measurements on the
oracle's model, not collision answers: a query's context counts the points it asks (`point_queries`)."""

from __future__ import annotations

import functools
import time

import numpy as np

from app.checking.polytopes import Polytopes, gaps
from app.checking.round_shapes import RoundShapes
from app.scene.shapes import BOX_FACES, half_extent, hull_vertices

# pydrake is imported inside the methods that use it, so that importing the package does not load Drake.


class Workspace:
    """Workspace queries on an oracle's model (its lock and its policy context)."""

    def __init__(self, oracle):
        self._oracle = oracle
        plant, scene = oracle.plant, oracle.scene
        self._inspector = oracle.model.scene_graph().model_inspector()
        self._passage_frame = (
            plant.GetFrameByName(scene.passage_frame.name(), scene.passage_frame.model_instance())
            if scene.passage_frame is not None
            else None
        )
        # What `frame_positions` tracks: the passage frame, or without one (a custom scene) the robot's last body.
        last_body = plant.GetBodyIndices(scene.robot_instances[-1])[-1]
        self._tracked_frame = self._passage_frame or plant.get_body(last_body).body_frame()

    def frame_positions(self, Q: np.ndarray) -> np.ndarray:
        """World position of the passage frame's origin (no passage declared: the robot's last body's) for each
        configuration, (n, 3)."""
        Q = np.atleast_2d(np.asarray(Q, float))
        out = np.empty((len(Q), 3))
        with self._oracle.lock:
            for i, q in enumerate(Q):
                out[i] = self._tracked_frame.CalcPoseInWorld(self._oracle.plant_context(q)).translation()
        return out

    def in_passage(self, Q: np.ndarray) -> np.ndarray:
        """Whether each configuration puts the scene's passage frame inside a passage box."""
        Q = np.atleast_2d(np.asarray(Q, float))
        if self._passage_frame is None or not self._oracle.scene.passage_boxes or len(Q) == 0:
            return np.zeros(len(Q), bool)
        p = self.frame_positions(Q)
        return np.any([np.all((p >= lo) & (p <= hi), axis=1) for lo, hi in self._oracle.scene.passage_boxes], axis=0)

    @functools.cached_property
    def robot_shapes(self) -> list:
        """(body, pose of the geometry in the body, geometry id) of each robot collision geometry, in a fixed order."""
        return [
            (self._oracle.plant.GetBodyFromFrameId(self._inspector.GetFrameId(g)), self._inspector.GetPoseInFrame(g), g)
            for g in sorted(self._oracle.robot_geometries, key=lambda g: g.get_value())
        ]

    @functools.cached_property
    def robot_kinematics(self):
        """Numpy forward kinematics of the robot's collision geometries, in `robot_shapes` order
        (app.checking.kinematics), or None when a joint is not revolute, prismatic or weld."""
        from app.checking.kinematics import TreeKinematics

        return TreeKinematics.of(
            self._oracle.plant, [(body, X_BG) for body, X_BG, _ in self.robot_shapes], self._oracle.scene.position_map
        )

    def robot_geometry_centres(self, Q: np.ndarray, pieces: np.ndarray | None = None) -> np.ndarray:
        """World position of the centre of each robot collision geometry for each configuration, (n, G, 3); with
        `pieces` (n indices into that order), of that one piece of each configuration, (n, 3)."""
        Q = np.atleast_2d(np.asarray(Q, float))
        if self.robot_kinematics is not None:
            if pieces is None:
                return self.robot_kinematics.frame_origins(Q)
            return self.robot_kinematics.origins(Q, np.asarray(pieces, int))
        shapes = self.robot_shapes
        every = np.arange(len(shapes))
        out = np.empty((len(Q), len(shapes), 3))
        with self._oracle.lock:
            for i, q in enumerate(Q):
                context = self._oracle.plant_context(q)
                for j in every if pieces is None else (int(pieces[i]),):
                    body, X_BG, _ = shapes[j]
                    out[i, j] = self._oracle.plant.EvalBodyPoseInWorld(context, body).multiply(X_BG.translation())
        return out if pieces is None else out[np.arange(len(Q)), np.asarray(pieces, int)]

    def robot_geometry_radii(self) -> np.ndarray:
        """Radius of the sphere about its centre that holds each robot collision geometry, (G,)."""
        return np.array(
            [np.linalg.norm(half_extent(self._inspector.GetShape(g), np.eye(3))) for _, _, g in self.robot_shapes]
        )

    @functools.cached_property
    def _environment(self) -> tuple[Polytopes, RoundShapes, list, np.ndarray, np.ndarray]:
        """The environment, which does not move with the robot: its boxes and convex hulls as world-frame
        polytopes, its spheres, capsules and cylinders as round shapes, and its other pieces (ellipsoids,
        half-spaces) as geometry ids with the bounding spheres about their frames' origins, centres (k, 3) and
        radii (k,)."""
        from pydrake.geometry import Box, Capsule, Convex, Cylinder, Mesh, Role, Sphere

        faces, round_shapes, others = [], [], []
        with self._oracle.lock:
            query = self._oracle.query_object(self._oracle.scene.start)
            for g in self._inspector.GetAllGeometryIds(Role.kProximity):
                if g in self._oracle.robot_geometries:
                    continue
                shape, X = self._inspector.GetShape(g), query.GetPoseInWorld(g)
                R, t = X.rotation().matrix(), X.translation()
                if isinstance(shape, Box):
                    loops = [
                        np.array(face) * (np.array([shape.width(), shape.depth(), shape.height()]) / 2)
                        for face in BOX_FACES
                    ]
                elif isinstance(shape, (Convex, Mesh)):  # Drake's proximity engine uses a mesh's convex hull
                    vertices, data = hull_vertices(shape), shape.GetConvexHull().face_data()
                    loops, i = [], 0
                    while i < len(data):  # each face: its vertex count, then its vertices' indices
                        loops.append(vertices[np.asarray(data[i + 1 : i + 1 + data[i]], int)])
                        i += 1 + data[i]
                elif isinstance(shape, (Sphere, Capsule, Cylinder)):
                    half = 0.0 if isinstance(shape, Sphere) else shape.length() / 2
                    round_shapes.append((R, t, shape.radius(), half, isinstance(shape, Cylinder)))
                    continue
                else:
                    others.append((g, t, np.linalg.norm(half_extent(shape, np.eye(3)))))
                    continue
                faces.append([loop @ R.T + t for loop in loops])
        centres = np.array([c for _, c, _ in others]).reshape(-1, 3)
        return (
            Polytopes(faces),
            RoundShapes(round_shapes),
            [g for g, _, _ in others],
            centres,
            np.array([r for _, _, r in others]),
        )

    def _point_distances(self, P: np.ndarray, reach: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The points (n, 3) and environment pieces within `reach` (n,) of each other: (point index, signed
        distance, unit gradient at the point), by point. Boxes, hulls, spheres, capsules and cylinders in numpy,
        the same answers as SceneGraph's point queries at a fraction of their cost; other shapes by those queries,
        for the points their bounding spheres reach."""
        polytopes, round_shapes, others, centres, radii = self._environment
        found = [polytopes.near(P, reach), round_shapes.near(P, reach)]
        if others:
            found.append(self._asked(P, reach, others, centres, radii))
        points = np.concatenate([f[0] for f in found]).astype(int)
        order = np.argsort(points, kind="stable")
        distance = np.concatenate([f[1] for f in found])
        gradient = np.concatenate([f[2].reshape(-1, 3) for f in found])
        return points[order], distance[order], gradient[order]

    def _asked(
        self, P: np.ndarray, reach: np.ndarray, others: list, centres: np.ndarray, radii: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """SceneGraph's answers for the `others` pieces (geometry ids; bounding spheres: centres, radii) within
        `reach` of the points, asking only for the points those spheres reach; as `_point_distances` returns them."""
        ball = np.linalg.norm(P[:, None, :] - centres[None], axis=2) - radii
        asked = np.flatnonzero(np.any(ball <= reach[:, None] * (1 + 1e-9), axis=1))
        rows = []
        with self._oracle.lock:
            query = self._oracle.query_object(self._oracle.scene.start)
            for i in asked.tolist():
                try:
                    answers = query.ComputeSignedDistanceToPoint(P[i], reach[i])
                except RuntimeError:
                    # Drake refuses a point query near some sliver hulls of decomposed meshes ("very sharp edge"):
                    # the other shapes near such a point go unseen; the gap search is a sampling heuristic.
                    continue
                rows += [(i, r.distance, r.grad_W) for r in answers if r.id_G in others]
        return (
            np.array([i for i, _, _ in rows], int),
            np.array([d for _, d, _ in rows], float),
            np.array([g for _, _, g in rows], float).reshape(-1, 3),
        )

    def environment_gaps(self, P: np.ndarray, width: float) -> np.ndarray:
        """Whether each workspace point (n, 3) lies free in a gap of the environment narrower than `width`: two
        obstacles on roughly opposite sides of it (their distance gradients more than 120 degrees apart) whose
        distances add up to less than `width` (`polytopes.gaps`).

        One of a gap's two obstacles lies within width/2 of the point, so the pieces within width/2 are found first;
        then, for a point free with one so near, those within `width` less the nearest distance (the farthest the
        other obstacle may be): the fewer pieces a point reaches, the less it costs."""
        P = np.atleast_2d(np.asarray(P, float))
        start = time.perf_counter()
        points, distance, _ = self._point_distances(P, np.full(len(P), width / 2))
        nearest = np.full(len(P), np.inf)
        np.minimum.at(nearest, points, distance)
        free = np.flatnonzero(np.isfinite(nearest) & (nearest > 0))
        points, distance, gradient = self._point_distances(P[free], width - nearest[free])
        gap = np.zeros(len(P), bool)
        gap[free] = gaps(points, distance, gradient, len(free), width)
        self._oracle.seconds["points"] += time.perf_counter() - start
        return gap
