"""app.from_checker: the planner on a user's own Drake SceneGraphCollisionChecker, its filters as they are."""

from pathlib import Path

import numpy as np
import pytest

import app

ROOT = Path(__file__).resolve().parent.parent
START, GOAL = [20, 80, -1.5708, 0, 0], [80, 80, -1.5708, 0, 0]


def own_checker(filter_link: str | None = None):
    """The bar scene's 3-link arm built the way a pydrake user would, self-collision on (Drake's default), and
    optionally one link's collisions filtered with every body."""
    from pydrake.multibody.parsing import LoadModelDirectives, ProcessModelDirectives
    from pydrake.planning import RobotDiagramBuilder, SceneGraphCollisionChecker

    builder = RobotDiagramBuilder()
    parser = builder.parser()
    parser.package_map().Add("npp_robots", str(ROOT / "robots"))
    parser.package_map().Add("npp_scenes", str(ROOT / "scenes"))
    ProcessModelDirectives(LoadModelDirectives(str(ROOT / "scenes" / "bar-3link.dmd.yaml")), parser)
    plant = builder.plant()
    plant.Finalize()
    robot = plant.GetModelInstanceByName("arm")
    checker = SceneGraphCollisionChecker(
        model=builder.Build(), robot_model_instances=[robot], edge_step_size=0.5, env_collision_padding=0.0
    )
    if filter_link:
        checker.SetCollisionFilteredWithAllBodies(plant.GetBodyByName(filter_link, robot).index())
    return checker


@pytest.mark.parametrize("filter_link", [None, "link3"])
def test_answers_are_the_checkers_own(filter_link):
    checker = own_checker(filter_link)
    oracle = app.from_checker(checker, start=START, goal=GOAL, resolution=0.5)
    scene = oracle.scene
    assert scene.dim == 5 and scene.self_collisions  # every plant position a coordinate; self-contact counted
    Q = np.random.default_rng(0).uniform(scene.lower, scene.upper, (400, scene.dim))
    free = oracle.context().are_free(Q)
    assert 0.2 < free.mean() < 0.9  # both verdicts occur, so the comparison below can fail
    assert free.tolist() == [checker.CheckConfigCollisionFree(q) for q in Q]


def test_a_filtered_link_may_pass_through_what_it_would_hit():
    plain, filtered = (app.from_checker(own_checker(f), start=START, goal=GOAL) for f in (None, "link3"))
    Q = np.random.default_rng(1).uniform(plain.scene.lower, plain.scene.upper, (400, 5))
    only_filtered = filtered.context().are_free(Q) & ~plain.context().are_free(Q)
    assert only_filtered.any()  # configurations where link3 alone touches something: free once it is filtered
    # The certificate's distance queries honour the same filter: a pose where link3 overlaps an obstacle is proved
    q = Q[only_filtered][0]
    assert app.certify_path(filtered.context(), [q, q])[0]
    assert not app.certify_path(plain.context(), [q, q])[0]


def test_a_planned_motion_is_certified_and_free_by_the_users_checker():
    checker = own_checker()
    oracle = app.from_checker(checker, start=START, goal=GOAL, resolution=0.5, weights=[1, 1, 12, 8, 4])
    result = app.plan(oracle, app.PlanSettings(seed=0))
    assert result.certificate.proved
    path = np.asarray(result.path)
    assert np.allclose(path[0], START) and np.allclose(path[-1], GOAL)
    dense = np.vstack([oracle.space.interpolate(a, b, resolution=0.01) for a, b in zip(path[:-1], path[1:])])
    assert all(checker.CheckConfigCollisionFree(q) for q in dense)
