"""The stages after collision checking on a checker of boxes in the plane (tests/toy_checker.py), without Drake: the
samplers, the lazy roadmap's search, shortcut smoothing and budgets. `make test-fast` runs these (marked `unit`)."""

import numpy as np
import pytest

from app.checking.budget import Budget, BudgetSpent
from app.motion.path import Shortcuts, path_length, shortcut, verify
from app.planning.roadmap import Roadmap
from app.samplers import SAMPLERS, make_sampler
from toy_checker import BLOCK, WALL, ToyOracle, toy_checker

pytestmark = pytest.mark.unit


def _free_at_resolution(checker, P) -> bool:
    """Every point of the polyline P at the checker's resolution free in the toy (its own answer, not the checker's
    edge checks): what a discrete check promises, no more (a corner may slip between checked points)."""
    oracle, resolution = checker.oracle, checker.space.resolution
    for a, b in zip(P[:-1], P[1:]):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / resolution)))
        if oracle.collides(a + np.linspace(0, 1, n + 1)[:, None] * (b - a)).any():
            return False
    return True


@pytest.mark.parametrize("name", list(SAMPLERS))
def test_every_sampler_gives_free_samples_in_bounds_the_same_for_a_seed_and_counts_what_it_asked(name):
    samples = []
    for _ in range(2):
        checker = toy_checker()
        sampler = make_sampler(name, checker, step=6.0)  # a bridge longer than the gap is wide
        samples.append(sampler.sample(20, np.random.default_rng(5)))
        assert checker.checks == checker.oracle.answered > 0  # every configuration handed over is counted
    Q = samples[0]
    assert Q.shape == (20, 2) and np.array_equal(Q, samples[1])
    assert checker.space.within_bounds(Q).all() and not checker.oracle.collides(Q).any()


def test_the_bridge_samplers_find_the_gap_in_the_wall():
    """A bridge's midpoint free between two colliding ends: in this plane, only in the wall's gap (y 48..52)."""
    for name in ("rbbs", "lfbs", "rwbs"):
        Q = make_sampler(name, toy_checker(), step=6.0).sample(10, np.random.default_rng(1))
        assert np.all((Q[:, 1] > 44) & (Q[:, 1] < 56) & (Q[:, 0] > 39) & (Q[:, 0] < 61)), name


def test_a_budget_stops_a_sampler_and_is_never_overrun():
    checker = toy_checker([((0.0, 0.0), (100.0, 99.0))])  # a sliver of free space: samples are dear
    stop = checker.stop(Budget(checks=500))
    with pytest.raises(BudgetSpent) as spent:
        make_sampler("uniform", checker).sample(50, np.random.default_rng(0), stop=stop)
    assert spent.value.reason == "checks" and checker.checks == 500


def test_a_cancelled_stop_ends_an_edge_check_before_it_asks_anything():
    class Cancelled:
        def is_set(self) -> bool:
            return True

    checker = toy_checker()
    with pytest.raises(BudgetSpent, match="cancelled"):
        checker.edges_free(np.array([[10.0, 50.0]]), np.array([[90.0, 50.0]]), stop=checker.stop(cancel=Cancelled()))
    assert checker.checks == 0


def test_edge_checks_are_coarse_to_fine_and_a_colliding_edge_costs_few():
    checker = toy_checker()
    through, free = np.array([[10.0, 30.0], [90.0, 30.0]]), np.array([[10.0, 50.0], [90.0, 50.0]])
    assert not checker.edge_free(*through)
    blocked = checker.checks
    assert checker.edge_free(*free)
    assert blocked < 10 and checker.checks - blocked >= 80 / 0.5  # the free one is checked whole at its resolution


def test_the_lazy_roadmap_finds_a_free_path_through_the_gap_and_drops_colliding_edges():
    checker = toy_checker(WALL + BLOCK)
    roadmap = Roadmap(checker, k=10, lazy=True)
    start, goal = roadmap.node(checker.scene.start, "start"), roadmap.node(checker.scene.goal, "goal")
    rng = np.random.default_rng(2)
    Q = make_sampler("uniform", checker).sample(300, rng)
    gap = np.column_stack([rng.uniform(46, 54, 20), rng.uniform(49, 51, 20)])  # a few nodes in the gap
    roadmap.add(np.vstack([Q, gap]), "uniform", connect=False)
    roadmap.connect(np.arange(len(roadmap)))
    nodes = roadmap.shortest_path(start, goal)
    assert nodes is not None and nodes[0] == start and nodes[-1] == goal
    assert _free_at_resolution(checker, roadmap.Q[nodes])
    stats = roadmap.stats()
    assert 0 < stats.edges_tried < stats.edges_proposed  # lazy: only the edges candidate paths used were checked
    assert roadmap.shortest_path(start, goal) == nodes  # decided edges are not checked again
    assert checker.checks == checker.oracle.answered


def test_edges_and_verdicts_handed_from_one_roadmap_to_another_are_not_checked_again():
    """What a query on a stored roadmap does with the fresh query's roadmap beside it (app.planning.query)."""
    checker = toy_checker(WALL + BLOCK)
    rng = np.random.default_rng(2)
    Q = np.vstack(
        [
            make_sampler("uniform", checker).sample(300, rng),
            np.column_stack([rng.uniform(46, 54, 20), 50 + rng.uniform(-1, 1, 20)]),
        ]
    )

    def roadmap(connect: bool) -> Roadmap:
        r = Roadmap(checker, k=10, lazy=True)
        r.node(checker.scene.start, "start"), r.node(checker.scene.goal, "goal")
        r.add(Q, "uniform", connect=False)
        if connect:
            r.connect(np.arange(len(r)))
        return r

    fresh = roadmap(connect=True)
    before = checker.checks
    path = fresh.shortest_path(0, 1)
    spent = checker.checks - before
    assert path is not None and spent > 0
    stored = roadmap(connect=False)
    stored.propose(fresh.pairs())
    stored.propose(fresh.pairs())  # proposed once
    assert sorted(map(tuple, stored.pairs().tolist())) == sorted(map(tuple, fresh.pairs().tolist()))
    decided, free = fresh.verdicts()
    stored.learn(fresh.pairs()[decided], free[decided])
    before = checker.checks
    assert stored.shortest_path(0, 1) == path and checker.checks == before  # nothing checked again
    # a roadmap taking only the free verdicts from elsewhere finds its own collisions, and checks no free edge again
    again = roadmap(connect=True)
    again.free_elsewhere = lambda P: np.logical_and(*fresh.known(P))
    before = checker.checks
    assert again.shortest_path(0, 1) == path and 0 < checker.checks - before < spent
    assert _free_at_resolution(checker, again.Q[path])


def test_smoothing_keeps_the_path_free_shortens_it_and_a_replay_asks_nothing_new():
    checker = toy_checker(WALL + BLOCK)
    P = np.array([[10.0, 50.0], [15.0, 90.0], [40.0, 90.0], [40.0, 50.0], [60.0, 50.0], [70.0, 80.0], [90.0, 50.0]])
    assert verify(checker, P, 0.1).all()
    memo = Shortcuts()
    smoothed, stats = shortcut(checker, P, np.random.default_rng(0), rounds=20, memo=memo)
    assert _free_at_resolution(checker, smoothed) and np.array_equal(smoothed[[0, -1]], P[[0, -1]])
    assert stats.length_after < stats.length_before == pytest.approx(path_length(checker, P))
    before = checker.checks
    again, _ = shortcut(checker, P, np.random.default_rng(0), rounds=20, memo=memo)
    assert np.array_equal(again, smoothed) and checker.checks == before


def test_smoothing_within_a_budget_stops_and_keeps_the_path_as_it_stands():
    checker = toy_checker(WALL + BLOCK)
    P = np.array([[10.0, 50.0], [15.0, 90.0], [40.0, 90.0], [40.0, 50.0], [60.0, 50.0], [70.0, 80.0], [90.0, 50.0]])
    stop = checker.stop(Budget(checks=30))
    smoothed, stats = shortcut(checker, P, np.random.default_rng(0), rounds=20, stop=stop)
    assert stats.stopped and checker.checks <= 30 and _free_at_resolution(checker, smoothed)


def test_the_toy_oracle_answers_like_its_boxes():
    oracle = ToyOracle()
    assert not oracle.free(np.array([50.0, 10.0])) and oracle.free(np.array([50.0, 50.0]))
