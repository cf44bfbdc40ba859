"""Independent checks for tests: collision answers asked of SceneGraph directly, and points along a polyline
computed here, so a test does not grade the oracle's paths with the oracle's own code."""

import math

import numpy as np

_contexts = {}


def raw_free(oracle, q) -> bool:
    """Free under the scene's policy, asked of SceneGraph directly on a context of our own (not the oracle's paths):
    signed distances on the unfiltered geometry, keeping the pairs the scene counts. q: the plant's positions, which
    are the configuration except in a scene with mimic joints, whose test writes them out itself rather than through
    the scene's position map (it would not be independent then). oracle: a CollisionOracle, or a query's checker
    on one."""
    oracle = _shared(oracle)
    plant, model = oracle.plant, oracle.model
    # Keyed by the model, held with its context so that its id is never reused (a query's contexts come and go).
    if id(model) not in _contexts:
        _contexts[id(model)] = (model.CreateDefaultContext(), model)
    root = _contexts[id(model)][0]
    context = plant.GetMyContextFromRoot(root)
    plant.SetPositions(context, q)
    query = plant.get_geometry_query_input_port().Eval(context)
    for pair in query.ComputeSignedDistancePairwiseClosestPoints(0.0):
        a, b = oracle.is_robot_geometry(pair.id_A), oracle.is_robot_geometry(pair.id_B)
        if ((a != b) or (a and b and oracle.scene.self_collisions)) and pair.distance < 0:
            return False
    return True


def _shared(oracle):
    """The CollisionOracle behind a query's checker (or the oracle itself)."""
    from app.checking.context import QueryContext

    return oracle.oracle if isinstance(oracle, QueryContext) else oracle


def fine_points(oracle, P, resolution):
    """Points along the polyline P, no more than `resolution` apart, computed here (short way on continuous angles)."""
    out = [P[0]]
    for a, b in zip(P[:-1], P[1:]):
        d = np.asarray(b) - np.asarray(a)
        d[oracle.space.continuous] = (d[oracle.space.continuous] + np.pi) % (2 * np.pi) - np.pi
        n = max(1, math.ceil(np.linalg.norm(d * oracle.space.weights) / resolution))
        out.extend(a + t * d for t in np.linspace(0, 1, n + 1)[1:])
    return np.array(out)
