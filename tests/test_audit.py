"""The audit (app.bench.audit): its re-check counts a trajectory through an obstacle, its densified states follow
the motion, and a short run's table has every field, with no colliding state among the planner's trajectories."""

import numpy as np

from app.bench.audit import DIVISOR, Recheck, audit_trajectory, measure, states
from app.motion.timing import parameterize


def test_a_trajectory_through_an_obstacle_is_counted(oracles):
    """The bar scene's straight motion from start to goal runs through the wall (the oracle agrees); timed rest to
    rest, the re-check finds colliding states and how deep they go; a free start alone has none."""
    oracle = oracles("bar")
    scene = oracle.scene
    start, goal = np.asarray(scene.start, float), np.asarray(scene.goal, float)
    assert not oracle.context().edge_free(start, goal)
    through = parameterize(oracle.plant, np.array([start, goal]), scene.velocity_limits, scene.acceleration_limits)
    recheck = Recheck("bar")
    found = audit_trajectory(recheck, oracle.space, through, start, goal, scene)
    assert found["colliding_states"] > 0 and found["max_penetration"] > 0
    assert found["limit_violations"] == 0 and found["worst_limit_ratio"] <= 1 + 1e-6 and found["endpoints_exact"]
    assert not recheck.check(start)[0][0]
    # The same trajectory graded against other endpoints is flagged.
    assert not audit_trajectory(recheck, oracle.space, through, start, start, scene)["endpoints_exact"]


def test_the_states_follow_the_motion_finely(oracles):
    """Densified states of a timed motion are no farther apart than asked, and lie on the motion: those at the
    samples of a finer timing of the same path are reproduced by the quintic Hermite between coarser samples."""
    oracle = oracles("maze")
    scene, space = oracle.scene, oracle.space
    W = np.array([[14.5, 2.0, 1.5, 0.0], [16.0, 3.0, 1.8, 0.5]])
    coarse = parameterize(oracle.plant, W, scene.velocity_limits, scene.acceleration_limits, dt=0.05)
    spacing = space.resolution / DIVISOR
    Q = states(coarse, space.weights, spacing)
    assert np.linalg.norm(np.diff(Q, axis=0) * space.weights, axis=1).max() <= spacing
    assert np.array_equal(Q[0], W[0]) and np.array_equal(Q[-1], W[-1])
    fine = parameterize(oracle.plant, W, scene.velocity_limits, scene.acceleration_limits, dt=0.001)
    nearest = np.linalg.norm((fine.positions[:, None] - Q[None]) * space.weights, axis=2).min(axis=1)
    assert nearest.max() <= spacing


def test_a_short_audit_has_every_field_and_no_colliding_state(tmp_path):
    scenes = ["maze", "joint3d"]
    table, _ = measure(scenes, 2, seed=1, budget=5.0, store=tmp_path / "audit.sqlite")
    assert [row["scene"] for row in table] == [*scenes, "total"]
    fields = {
        "problems",
        "solved",
        "certified",
        "colliding_trajectories",
        "colliding_states",
        "max_penetration",
        "limit_violations",
        "inexact_endpoints",
        "states_checked",
    }
    assert fields <= set(table[-1])
    assert [row["problems"] for row in table] == [1, 1, 2]
    total = table[-1]
    assert total["solved"] >= 1 and total["states_checked"] > 1000 * total["solved"]
    assert total["colliding_states"] == 0 and total["inexact_endpoints"] == 0
    # Toppra's limits are checked at its grid points (and app.motion.timing's between them): 1e-4 covers what is left.
    assert 0.5 < total["worst_limit_ratio"] <= 1 + 1e-4
