"""Our forward kinematics (app.checking.kinematics) against Drake's own: the same geometry poses, many configurations
at once; a plant with a joint it does not handle has none, and its callers ask Drake."""

import numpy as np
import pytest

from app.checking.kinematics import TreeKinematics


@pytest.mark.parametrize("name", ["welding", "bar", "joint3d", "tunnel"])
def test_geometry_poses_are_drakes(oracles, name):
    oracle = oracles(name)
    shapes = oracle.workspace.robot_shapes
    kinematics = TreeKinematics.of(oracle.plant, [(body, X_BG) for body, X_BG, _ in shapes])
    Q = oracle.space.uniform(np.random.default_rng(3), 20)
    R, p = kinematics.poses(Q)
    for q, R_q, p_q in zip(Q, R, p):
        query = oracle.query_object(q)
        for (_, _, geometry), R_g, p_g in zip(shapes, R_q, p_q):
            X = query.GetPoseInWorld(geometry)
            assert np.allclose(R_g, X.rotation().matrix(), rtol=0, atol=1e-12)
            assert np.allclose(p_g, X.translation(), rtol=0, atol=1e-12)
    pieces = np.random.default_rng(4).integers(len(shapes), size=len(Q))
    assert np.allclose(kinematics.origins(Q, pieces), p[np.arange(len(Q)), pieces], rtol=0, atol=1e-15)


def test_a_floating_body_has_no_tree_kinematics():
    from pydrake.math import RigidTransform
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.multibody.tree import SpatialInertia

    plant = MultibodyPlant(0.0)
    body = plant.AddRigidBody("free", SpatialInertia.SolidSphereWithMass(1.0, 0.1))
    plant.Finalize()  # the body gets a quaternion floating joint
    assert TreeKinematics.of(plant, [(body, RigidTransform())]) is None


@pytest.mark.parametrize("name", ["welding", "maze"])
def test_the_oracle_and_the_certificate_answer_the_same_with_drakes_poses(oracles, name):
    """What our kinematics feed -- workspace piece centres, the certificate's gap bounds -- is what Drake's
    poses give, to rounding."""
    from app.checking.certify import Certifier

    oracle = oracles(name)
    rng = np.random.default_rng(8)
    Q = oracle.space.uniform(rng, 40)
    pieces = rng.integers(len(oracle.workspace.robot_shapes), size=len(Q))
    numpy_centres = oracle.workspace.robot_geometry_centres(Q), oracle.workspace.robot_geometry_centres(Q, pieces)
    saved, oracle.workspace.robot_kinematics = oracle.workspace.robot_kinematics, None
    try:
        drake_centres = oracle.workspace.robot_geometry_centres(Q), oracle.workspace.robot_geometry_centres(Q, pieces)
    finally:
        oracle.workspace.robot_kinematics = saved
    for a, b in zip(numpy_centres, drake_centres):
        assert np.allclose(a, b, rtol=0, atol=1e-12)

    limit = 20 * oracle.space.resolution
    ours, drakes = Certifier(oracle.context()), Certifier(oracle.context())
    assert ours._kinematics is not None
    drakes._kinematics = None
    ends = ours._distances(list(Q), [limit] * len(Q)), drakes._distances(list(Q), [limit] * len(Q))
    assert sum(end is not None and len(end.keys) > 0 for end in ends[0]) >= 3
    for a, b in zip(*ends):
        assert (a is None) == (b is None)
        if a is not None:
            assert np.array_equal(a.keys, b.keys)
            assert np.allclose(a.distance, b.distance, rtol=0, atol=1e-12)
