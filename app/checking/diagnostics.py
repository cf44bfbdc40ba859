"""What a configuration touches, for messages and checks of a start or goal: the oracle's diagnostics, not counted
as collision answers (a query's context counts those)."""

from __future__ import annotations

import numpy as np

from app.scene.shapes import CONTACT


class Diagnostics:
    """Named contacts and clearances at a configuration, on an oracle's model (its lock, its policy's query object,
    and a context of its own that sees every pair, for `contacts`)."""

    def __init__(self, oracle):
        self._oracle = oracle
        self._inspector = oracle.model.scene_graph().model_inspector()
        self._port = oracle.plant.get_geometry_query_input_port()
        # Unfiltered: says *what* a configuration touches (environment, self) whatever pairs the scene counts.
        self._root = oracle.model.CreateDefaultContext()
        self._context = oracle.plant.GetMyContextFromRoot(self._root)

    def clearance(self, q: np.ndarray, max_distance: float = 10.0) -> float:
        """Signed distance from the robot to whatever counts under the scene's policy (negative: penetration).

        Pairs farther apart than `max_distance` are not computed, so the answer is capped there.
        """
        with self._oracle.lock:
            pairs = self._oracle.query_object(q).ComputeSignedDistancePairwiseClosestPoints(max_distance)
        return min((p.distance for p in pairs), default=float(max_distance))

    def contacts(self, q: np.ndarray, margin: float = 0.0) -> dict[str, bool]:
        """What the robot touches (or comes within `margin` of) at q, environment and self, whether or not the scene
        counts self-collision (pairs Drake or the SRDF filter are never reported)."""
        with self._oracle.lock:
            self._oracle.plant.SetPositions(self._context, self._oracle.positions(np.asarray(q, float)))
            pairs = self._port.Eval(self._context).ComputeSignedDistancePairwiseClosestPoints(max(margin, 1e-9))
        touched = {"environment": False, "self": False}
        for p in pairs:
            if p.distance > margin:
                continue
            a, b = p.id_A in self._oracle.robot_geometries, p.id_B in self._oracle.robot_geometries
            if a and b:
                touched["self"] = True
            elif a or b:
                touched["environment"] = True
        return touched

    def colliding_bodies(self, q: np.ndarray) -> list[tuple[str, str]]:
        """The body pairs (scoped names, sorted) in collision at q under the scene's policy; for error messages.
        Geometry anchored to the world (a custom scene's environment pieces) is named itself, not "world"."""
        with self._oracle.lock:
            query = self._oracle.query_object(q)
            try:
                pairs = [(p.id_A, p.id_B) for p in query.ComputePointPairPenetration()]
            except RuntimeError:  # a shape pair without penetration support: fall back to signed distances
                distances = query.ComputeSignedDistancePairwiseClosestPoints(0.0)
                pairs = [(p.id_A, p.id_B) for p in distances if p.distance < 0]
        return sorted({tuple(sorted((self.body_name(a), self.body_name(b)))) for a, b in pairs})

    def touching(self, q: np.ndarray, margin: float = CONTACT) -> list[tuple[str, str, float]]:
        """The body pairs under the scene's policy no farther apart than `margin` at q, as (name, name, signed
        distance), nearest first: a configuration whose geometry touches (distance 0, which HasCollisions calls
        free) can be left by no motion the certificate proves."""
        pairs = self._oracle.signed_distance_pairs(q, margin)
        named = {}
        for p in pairs:
            key = tuple(sorted((self.body_name(p.id_A), self.body_name(p.id_B))))
            named[key] = min(named.get(key, np.inf), p.distance)
        return sorted(((a, b, d) for (a, b), d in named.items() if d <= margin), key=lambda t: t[2])

    def body_name(self, g) -> str:
        """A geometry's body, by scoped name; geometry anchored to the world (a custom scene's environment pieces)
        by its own name, not "world"."""
        frame = self._inspector.GetFrameId(g)
        if frame == self._inspector.world_frame_id():
            return self._inspector.GetName(g)
        return self._oracle.plant.GetBodyFromFrameId(frame).scoped_name().to_string()
