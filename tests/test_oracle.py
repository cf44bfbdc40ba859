"""The collision oracle against an independent SceneGraph reference, and its counters."""

import time

import numpy as np
import pytest

from app.scene.model import scene_names

SAMPLING_SCENES = ["bar", "bar-3link", "bar-5link", "joint", "joint3d", "teeth3d"]


def reference_free(oracle, q) -> bool:
    """Free under the scene's policy, computed another way: signed distances on the *unfiltered* context, keeping
    robot-environment pairs (and robot-robot pairs only if the scene counts self-collision)."""
    plant = oracle.plant
    context = plant.GetMyContextFromRoot(oracle.model.CreateDefaultContext())
    plant.SetPositions(context, q)
    query = plant.get_geometry_query_input_port().Eval(context)
    for pair in query.ComputeSignedDistancePairwiseClosestPoints(0.0):
        a, b = oracle.is_robot_geometry(pair.id_A), oracle.is_robot_geometry(pair.id_B)
        counts = (a != b) or (a and b and oracle.scene.self_collisions)
        if counts and pair.distance < 0:
            return False
    return True


@pytest.mark.parametrize("name", SAMPLING_SCENES)
def test_oracle_agrees_with_scenegraph_on_1000_configurations(checkers, name):
    oracle = checkers(name)
    Q = oracle.space.uniform(np.random.default_rng(7), 1000)
    batch = oracle.are_free(Q)
    single = np.array([oracle.is_free(q) for q in Q])
    reference = np.array([reference_free(oracle, q) for q in Q])
    assert np.array_equal(batch, reference)
    assert np.array_equal(single, reference)
    # Both answers occur, so agreement means something.
    assert 0.05 < reference.mean() < 0.95


def test_counters_are_exact(checkers):
    oracle = checkers("bar")
    rng = np.random.default_rng(1)
    Q = oracle.space.uniform(rng, 50)
    oracle = oracle.oracle.context()
    assert oracle.checks == 0
    oracle.is_free(Q[0])
    assert oracle.checks == 1
    oracle.are_free(Q)
    assert oracle.checks == 51
    outside = Q[:5].copy()
    outside[:, 0] = oracle.space.upper[0] + 1.0  # out of bounds: rejected before Drake, not counted
    assert not oracle.are_free(outside).any()
    assert not oracle.is_free(outside[0])
    assert oracle.checks == 51
    oracle = oracle.oracle.context()
    assert oracle.checks == 0


def test_edge_check_counts_the_configurations_it_looked_at(checkers):
    oracle = checkers("bar")
    start = oracle.scene.start
    free_end = start.copy()
    free_end[1] += 10.0  # slide the arm sideways in open space
    oracle = oracle.oracle.context()
    assert oracle.edge_free(start, free_end)
    assert oracle.checks == len(oracle.space.interpolate(start, free_end))

    through_wall = start.copy()
    through_wall[0] = 50.0
    through_wall[1] = 20.0  # the base inside the lower bar
    oracle = oracle.oracle.context()
    assert not oracle.edge_free(start, through_wall)
    assert 0 < oracle.checks < len(oracle.space.interpolate(start, through_wall))


def test_the_points_of_an_undecided_edge_found_free_are_not_checked_again(checkers):
    """A long free edge checked beside one that collides at once: the check ends early, the free edge undecided
    with some of its points found free; checking it again with that progress asks only the rest."""
    oracle = checkers("bar")
    start = oracle.scene.start
    free_end, through_wall = start.copy(), start.copy()
    free_end[1] += 10.0  # slide the arm sideways in open space
    through_wall[:2] = [50.0, 20.0]  # the base inside the lower bar
    inner = len(oracle.space.interpolate(start, free_end)) - 2  # its points, ends aside
    context = oracle.oracle.context()
    progress = np.zeros(2, np.int64)
    Q1, Q2 = np.array([start, start]), np.array([free_end, through_wall])
    free, decided = context.edges_status(Q1, Q2, ends_free=True, until_one_collides=True, progress=progress)
    assert not free[1] and decided[1] and free[0] and not decided[0]
    found = int(progress[0])
    assert 0 < found < inner
    again, rest = oracle.oracle.context(), progress[:1].copy()
    free, decided = again.edges_status(Q1[:1], Q2[:1], ends_free=True, progress=rest)
    assert free[0] and decided[0]
    assert again.checks == inner - found and rest[0] == inner


def test_edges_free_matches_pointwise_checks(checkers):
    oracle = checkers("joint3d")
    rng = np.random.default_rng(3)
    A, B = oracle.space.uniform(rng, 40), oracle.space.uniform(rng, 40)
    B = A + 0.1 * (B - A)  # short edges: a mix of free and colliding
    flags = oracle.edges_free(A, B)
    expected = np.array([oracle.are_free(oracle.space.interpolate(a, b)).all() for a, b in zip(A, B)])
    assert np.array_equal(flags, expected)
    assert 0 < flags.sum() < len(flags)


def test_known_free_ends_are_skipped_and_a_path_check_ends_at_its_first_collision(checkers):
    oracle = checkers("joint3d")
    rng = np.random.default_rng(3)
    A, B = oracle.space.uniform(rng, 60), oracle.space.uniform(rng, 60)
    keep = oracle.are_free(A) & oracle.are_free(B)  # endpoints free, as roadmap nodes are
    A, B = A[keep], B[keep]
    full = oracle.edges_free(A, B)
    assert full.any() and not full.all()
    oracle = oracle.oracle.context()
    assert np.array_equal(oracle.edges_free(A, B, ends_free=True), full)
    expected = sum(len(oracle.space.interpolate(a, b)) - 2 for a, b in zip(A[full], B[full]))
    assert oracle.checks >= expected  # every free edge's inner points, not its ends
    everything = oracle.checks
    oracle = oracle.oracle.context()
    free, decided = oracle.edges_status(A, B, ends_free=True, until_one_collides=True)
    assert oracle.checks < everything / 4  # stopped early: the round of the first collision ends it
    assert np.array_equal(free[decided], full[decided])  # what it decided is right
    assert (~free[decided]).any() and not decided.all()  # at least one collision found, some edges left open
    assert np.all(free[~decided])  # an undecided edge has not been seen to collide


def test_distance_takes_the_short_way_round_on_continuous_angles(checkers):
    oracle = checkers("bar")
    q1 = oracle.scene.start.copy()
    q2 = q1.copy()
    q1[2], q2[2] = np.pi - 0.1, -np.pi + 0.1
    assert oracle.space.distance(q1, q2) == pytest.approx(0.2 * oracle.space.weights[2])
    path = oracle.space.interpolate(q1, q2)
    assert np.all(np.abs(path[:, 2]) > np.pi - 0.11)  # never swings through zero


def test_clearance_is_signed(checkers):
    oracle = checkers("bar")
    start = oracle.scene.start
    assert oracle.clearance(start) > 0
    inside = start.copy()
    inside[0], inside[1] = 50.0, 20.0
    assert oracle.clearance(inside) < 0


def test_contacts_tell_environment_from_self(checkers):
    oracle = checkers("bar")
    folded = oracle.scene.start.copy()
    folded[3] = np.pi  # link 2 folds back onto link 1: self-contact, ignored by the environment-only policy
    assert oracle.contacts(folded) == {"environment": False, "self": True}
    assert oracle.is_free(folded)
    in_wall = oracle.scene.start.copy()
    in_wall[0], in_wall[1] = 50.0, 20.0
    assert oracle.contacts(in_wall)["environment"]


@pytest.mark.parametrize("name", scene_names())
def test_scene_start_goal_free_and_outside_the_passage(checkers, name):
    oracle = checkers(name)
    ends = np.array([oracle.scene.start, oracle.scene.goal])
    assert oracle.are_free(ends).all()
    assert oracle.scene.passage_boxes
    assert not oracle.in_passage(ends).any()


@pytest.mark.parametrize("name", scene_names())
def test_passage_is_narrow_for_uniform_sampling(checkers, name):
    oracle = checkers(name)
    Q = oracle.space.uniform(np.random.default_rng(11), 6000)
    free = Q[oracle.are_free(Q)]
    assert len(free) > 1000
    assert oracle.in_passage(free).mean() < 0.02


def test_in_passage_sees_the_frame_in_the_box(checkers):
    oracle = checkers("bar")
    q = oracle.scene.start.copy()
    q[0], q[1], q[2] = 50.0, 50.0, 0.0  # base in the gap, arm pointing along it
    assert oracle.in_passage(q)[0]
    assert oracle.is_free(q)


def test_every_shipped_scene_is_listed():
    assert set(SAMPLING_SCENES) <= set(scene_names())


def test_both_batch_paths_give_the_same_answers_and_the_cheaper_is_chosen():
    from app.checking.oracle import CollisionOracle
    from app.scene.model import Scene

    oracle = CollisionOracle(Scene("bar"), threads=2)
    Q = oracle.space.uniform(np.random.default_rng(5), 400)
    answers = {}
    for path in ("batch", "raw"):
        oracle._cost = {"batch": None, "raw": None}
        oracle._cost["raw" if path == "batch" else "batch"] = 1.0  # the other path looks dear: this one is taken
        answers[path] = oracle.free_batch(Q)
    assert np.array_equal(answers["batch"], answers["raw"])
    oracle._cost = {"batch": 5e-6, "raw": 2e-5}
    oracle._batch_calls, oracle._next_probe, oracle._probe_wait = 1, 16, 16
    assert oracle._choose_path() == "batch"
    oracle._cost = {"batch": 9e-5, "raw": 2e-5}
    assert oracle._choose_path() == "raw"


def test_a_path_found_dearer_again_is_probed_less_often():
    from app.checking.oracle import CollisionOracle
    from app.scene.model import Scene

    oracle = CollisionOracle(Scene("bar"), threads=2)
    oracle._cost = {"batch": 9e-5, "raw": 2e-5}
    probes = []
    for _ in range(200):
        path = oracle._choose_path()
        if path == "batch":
            probes.append(oracle._batch_calls)
            oracle._cost["batch"] = 8e-5  # measured dearer again
        if oracle._batch_calls == oracle._next_probe:
            oracle._settle_probe(path)
    assert probes == [16, 48, 112]  # waits of 32, then 64
    oracle._cost = {"batch": 9e-5, "raw": 2e-5}
    path = None
    while path != "batch":
        path = oracle._choose_path()
    oracle._cost["batch"] = 1e-5  # the probe finds batch cheaper now: it is chosen, and probing starts over
    oracle._settle_probe(path)
    assert oracle._choose_path() == "batch"
    assert oracle._next_probe == oracle._batch_calls - 1 + 16


def test_two_contexts_on_one_oracle_keep_their_own_counts_and_budgets(oracles):
    from app.checking.budget import Budget, BudgetSpent

    oracle = oracles("bar")
    Q = oracle.space.uniform(np.random.default_rng(3), 30)
    bounded, free = oracle.context(Budget(checks=10)), oracle.context()
    free.are_free(Q)
    with pytest.raises(BudgetSpent):
        bounded.are_free(Q)
    assert bounded.checks == 10  # checked as far as its own limit allowed, then stopped
    free.are_free(Q)  # the other context is not bound by it, and counts only its own
    assert free.checks == 60
    assert bounded.checks == 10


def test_queries_from_two_threads_on_one_oracle_get_the_answers_of_one(oracles):
    import threading

    oracle = oracles("joint3d")
    Q = oracle.space.uniform(np.random.default_rng(11), 600)
    expected = oracle.context().are_free(Q)
    answers, errors = {}, []

    def work(name, rows):
        try:
            checker = oracle.context()
            answers[name] = (rows, [checker.is_free(q) for q in Q[rows]], checker.checks)
        except Exception as exc:  # a failure in the thread must fail the test
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(k, np.arange(k, 600, 2))) for k in (0, 1)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    for rows, flags, checks in answers.values():
        assert np.array_equal(flags, expected[rows])
        assert checks == len(rows)


def test_the_seconds_in_drake_grow_with_each_kind_of_answer_and_stay_within_the_call(oracles):
    oracle = oracles("joint3d")
    Q = oracle.space.uniform(np.random.default_rng(2), 200)
    context = oracle.context()
    for kind, ask in [
        ("checks", lambda: context.are_free(Q)),
        ("distances", lambda: context.signed_distances(Q[0], 5.0)),
        ("distances", lambda: context.in_contact(Q[0])),
        ("points", lambda: context.environment_gaps(np.array([[50.0, 50, 50]]), 20.0)),
    ]:
        before = dict(oracle.seconds)
        clock = time.perf_counter()
        ask()
        elapsed = time.perf_counter() - clock
        grown = {k: oracle.seconds[k] - before[k] for k in before}
        assert 0 < grown[kind] <= elapsed, kind
        assert all(grown[k] == 0 for k in grown if k != kind), kind
