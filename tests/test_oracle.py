"""The collision oracle against an independent SceneGraph reference, and its counters."""

import os
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
    reference = np.array([reference_free(oracle.oracle, q) for q in Q])
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
    assert oracle.diagnostics.clearance(start) > 0
    inside = start.copy()
    inside[0], inside[1] = 50.0, 20.0
    assert oracle.diagnostics.clearance(inside) < 0


def test_contacts_tell_environment_from_self(checkers):
    oracle = checkers("bar")
    folded = oracle.scene.start.copy()
    folded[3] = np.pi  # link 2 folds back onto link 1: self-contact, ignored by the environment-only policy
    assert oracle.diagnostics.contacts(folded) == {"environment": False, "self": True}
    assert oracle.is_free(folded)
    in_wall = oracle.scene.start.copy()
    in_wall[0], in_wall[1] = 50.0, 20.0
    assert oracle.diagnostics.contacts(in_wall)["environment"]


@pytest.mark.parametrize("name", scene_names())
def test_scene_start_goal_free_and_outside_the_passage(checkers, name):
    oracle = checkers(name)
    ends = np.array([oracle.scene.start, oracle.scene.goal])
    assert oracle.are_free(ends).all()
    assert oracle.scene.passage_boxes
    assert not oracle.workspace.in_passage(ends).any()


@pytest.mark.parametrize("name", scene_names())
def test_passage_is_narrow_for_uniform_sampling(checkers, name):
    oracle = checkers(name)
    Q = oracle.space.uniform(np.random.default_rng(11), 6000)
    free = Q[oracle.are_free(Q)]
    assert len(free) > 1000
    assert oracle.workspace.in_passage(free).mean() < 0.02


def test_in_passage_sees_the_frame_in_the_box(checkers):
    oracle = checkers("bar")
    q = oracle.scene.start.copy()
    q[0], q[1], q[2] = 50.0, 50.0, 0.0  # base in the gap, arm pointing along it
    assert oracle.workspace.in_passage(q)[0]
    assert oracle.is_free(q)


def test_every_shipped_scene_is_listed():
    assert set(SAMPLING_SCENES) <= set(scene_names())


def test_every_batch_path_gives_the_same_answers_and_the_cheapest_is_chosen(two_cores):
    from app.checking.oracle import CollisionOracle
    from app.scene.model import Scene

    oracle = CollisionOracle(Scene("bar"), threads=2)
    assert oracle.start_helpers()
    Q = oracle.space.uniform(np.random.default_rng(5), 400)
    choice = oracle.paths_for(len(Q))
    assert set(choice.cost) == {"batch", "raw", "split"}
    answers = {}
    for path in choice.cost:
        choice.cost, choice.tries = dict.fromkeys(choice.cost, 1.0), dict.fromkeys(choice.cost, 2)
        choice.cost[path], choice.tries[path] = None, 0  # not measured yet: this one is taken
        answers[path] = oracle.free_batch(Q)
        assert choice.cost[path] < 1.0  # and measured
    assert 0 < answers["raw"].sum() < len(Q)
    assert np.array_equal(answers["batch"], answers["raw"]) and np.array_equal(answers["split"], answers["raw"])
    choice.tries = dict.fromkeys(choice.cost, 2)  # every path tried: the cheapest is taken
    choice.cost, choice.calls, choice.next_probe = {"batch": 5e-6, "raw": 2e-5, "split": 1e-5}, 1, 16
    assert choice.choose() == "batch"
    choice.cost = {"batch": 9e-5, "raw": 2e-5, "split": 1e-5}
    assert choice.choose() == "split"
    assert oracle.paths_for(8) is not choice and set(oracle.paths_for(8).cost) == {"batch", "raw"}  # too small to split


def test_a_path_found_dearer_again_is_probed_less_often_and_probes_take_turns():
    from app.checking.batch_paths import BatchPaths

    choice = BatchPaths(("batch", "raw"))
    choice.cost, choice.tries = {"batch": 9e-5, "raw": 2e-5}, {"batch": 2, "raw": 2}
    probes = []
    for _ in range(200):
        path = choice.choose()
        if path == "batch":
            probes.append(choice.calls)
        choice.measured(path, 8e-5 if path == "batch" else 2e-5)  # batch measured dearer again
    assert probes == [16, 48, 112]  # waits of 32, then 64
    choice.cost = {"batch": 9e-5, "raw": 2e-5}
    path = None
    while path != "batch":
        path = choice.choose()
    choice.cost["batch"] = None  # (forget its old cost)
    choice.measured(path, 1e-6)  # the probe finds batch cheaper now: it is chosen, and probing starts over
    assert choice.choose() == "batch"
    assert choice.next_probe == choice.calls - 1 + 16
    three = BatchPaths(("batch", "raw", "split"))
    three.cost, three.tries = {"batch": 9e-5, "raw": 2e-5, "split": 1e-5}, dict.fromkeys(three.cost, 2)
    probed = []
    for _ in range(200):
        path = three.choose()
        if path != "split":
            probed.append(path)
        three.measured(path, three.cost[path])
    assert probed[:2] in (["raw", "batch"], ["batch", "raw"])  # each other path in turn


def test_a_path_slowed_once_while_it_is_tried_is_still_chosen():
    """Each path is tried twice before the cheapest is taken, at the least of its tries: one call slowed by another
    process does not settle the choice on a slower path."""
    from app.checking.batch_paths import BatchPaths

    choice = BatchPaths(("raw", "split"))
    for cost in {"raw": (1e-5, 1e-5), "split": (3e-5, 5e-6)}.values():
        for c in cost:
            choice.measured(choice.choose(), c)
    assert choice.settled and choice.tries == {"raw": 2, "split": 2} and choice.cost["split"] == 5e-6
    assert [choice.choose() for _ in range(5)] == ["split"] * 5


def test_helpers_start_after_half_a_second_of_large_batches_and_a_lost_one_is_answered_for(monkeypatch, two_cores):
    import app.checking.oracle as module
    from app.checking.oracle import CollisionOracle
    from app.scene.model import Scene

    oracle = CollisionOracle(Scene("bar"), threads=2)
    Q = oracle.space.uniform(np.random.default_rng(6), 64)
    truth = oracle.free_batch(Q[:15])
    assert oracle._helpers.state == "idle"  # small batches never start them
    monkeypatch.setattr(module, "_HELPERS_AFTER", 0.0)
    expected = CollisionOracle(Scene("bar"), threads=1).free_batch(Q)
    assert np.array_equal(oracle.free_batch(Q), expected) and np.array_equal(truth, expected[:15])
    assert oracle._helpers.state == "starting"
    oracle._helpers.wait()
    choice = oracle.paths_for(len(Q))
    oracle.free_batch(Q)  # the split path joins the choices once the helpers are ready
    assert "split" in choice.cost
    for process in oracle._helpers._processes:
        process.kill()
        process.wait()
    choice.cost, choice.tries = {"batch": 1.0, "raw": 1.0, "split": None}, {"batch": 2, "raw": 2, "split": 0}
    assert np.array_equal(oracle.free_batch(Q), expected)  # the lost helper's part is answered here
    assert oracle._helpers.state == "failed"
    oracle.free_batch(Q)
    assert "split" not in choice.cost


def test_a_helper_that_cannot_load_the_scene_leaves_the_oracle_answering_alone(tmp_path, two_cores):
    import functools

    from app.checking.oracle import CollisionOracle
    from app.scene.model import Scene

    oracle = CollisionOracle(Scene("bar"), threads=2)
    oracle._helpers._recipe = functools.partial(Scene, str(tmp_path / "gone.yaml"))  # a scene no helper can load
    assert not oracle.start_helpers()
    assert oracle._helpers.state == "failed"
    Q = oracle.space.uniform(np.random.default_rng(7), 64)
    assert "split" not in oracle.paths_for(len(Q)).cost
    assert np.array_equal(oracle.free_batch(Q), CollisionOracle(Scene("bar"), threads=1).free_batch(Q))


def test_helpers_that_load_another_scene_are_never_used(tmp_path, two_cores):
    """A helper loads the scene anew from its files: one changed since (here every obstacle moved away) must not
    answer for this oracle."""
    import functools
    import re

    from app.checking.oracle import CollisionOracle
    from app.scene.files import SCENES_DIR
    from app.scene.model import Scene

    def far(match):
        numbers = match.group(1).split()
        return f"<pose>{float(numbers[0]) + 1000} {' '.join(numbers[1:])}</pose>"

    (tmp_path / "obstacles.sdf").write_text(
        re.sub(r"<pose>([^<]+)</pose>", far, (SCENES_DIR / "bar_obstacles.sdf").read_text())
    )
    dmd = (SCENES_DIR / "bar.dmd.yaml").read_text()
    (tmp_path / "bar.dmd.yaml").write_text(
        dmd.replace("package://npp_scenes/bar_obstacles.sdf", f"file://{tmp_path}/obstacles.sdf")
    )
    (tmp_path / "bar.yaml").write_text((SCENES_DIR / "bar.yaml").read_text())
    oracle = CollisionOracle(Scene("bar"), threads=2)
    oracle._helpers._recipe = functools.partial(Scene, str(tmp_path / "bar.yaml"))
    assert not oracle.start_helpers()
    assert oracle._helpers.state == "failed"
    assert "split" not in oracle.paths_for(64).cost


def test_a_forked_copy_of_the_oracle_does_not_talk_to_its_parents_helpers(two_cores):
    from app.checking.oracle import CollisionOracle
    from app.scene.model import Scene

    oracle = CollisionOracle(Scene("bar"), threads=2)
    assert oracle.start_helpers()
    Q = oracle.space.uniform(np.random.default_rng(8), 64)
    choice = oracle.paths_for(len(Q))
    assert "split" in choice.cost
    read, write = os.pipe()
    child = os.fork()
    if child == 0:  # the copy: no split path, and it answers alone
        try:
            oracle._follow_helpers()
            ok = not oracle._helpers.ready() and "split" not in choice.cost
            choice.cost, choice.tries = {"batch": 1.0, "raw": None}, {"batch": 2, "raw": 0}
            ok = ok and np.array_equal(oracle.free_batch(Q), oracle.free_raw(Q))
            os.write(write, b"1" if ok else b"0")
        finally:
            os._exit(0)
    os.close(write)
    assert os.read(read, 1) == b"1"
    os.waitpid(child, 0)
    choice.cost, choice.tries = {"batch": 1.0, "raw": 1.0, "split": None}, {"batch": 2, "raw": 2, "split": 0}
    assert np.array_equal(oracle.free_batch(Q), oracle.free_raw(Q)) and oracle._helpers.ready()  # the parent's work on


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="an oracle starts helpers only on a machine of two cores or more")
def test_helpers_do_not_run_the_users_script_again(tmp_path):
    """A script without a __main__ guard (as most pydrake scripts are) plans with helpers: it runs once."""
    import subprocess
    import sys

    script = tmp_path / "script.py"
    script.write_text(
        "import numpy as np\n"
        "from app.checking.oracle import CollisionOracle\n"
        "from app.scene.model import Scene\n"
        "print('run', flush=True)\n"
        "oracle = CollisionOracle(Scene('bar'), threads=2)\n"
        "print('ready', oracle.start_helpers(), flush=True)\n"
        "print('free', int(oracle.free_batch(oracle.space.uniform(np.random.default_rng(0), 100)).sum()))\n"
    )
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.split("\n")
    assert lines.count("run") == 1 and "ready True" in lines
    assert done.stderr == ""


def test_two_contexts_on_one_oracle_keep_their_own_counts_and_budgets(oracles):
    from app.checking.budget import Budget, BudgetSpent

    oracle = oracles("bar")
    Q = oracle.space.uniform(np.random.default_rng(3), 30)
    bounded, free = oracle.context(), oracle.context()
    stop = bounded.stop(Budget(checks=10))  # a budget runs against the counters of the context it was made on
    free.are_free(Q, stop=free.stop())
    with pytest.raises(BudgetSpent):
        bounded.are_free(Q, stop=stop)
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
