"""The planner: roadmap metric, budget syntax, collision-free paths under an independent fine check, Toppra timing
within the limits, reproducibility, and the command line's exit codes."""

import dataclasses
import json
import math

import numpy as np
import pytest

from app.checking.budget import Budget
from app.errors import InvalidEndpoint, NoPath, UserError
from app.planning.query import plan
from app.planning.result import PHASES
from app.planning.roadmap import Roadmap
from app.planning.settings import POCKET_ROUNDS, PlanSettings
from independent import fine_points, raw_free

# The bar crossing needs the narrow samples: with 500 uniform samples alone it succeeds in under 10 % of seeds
# (`python -m app bench plan`), with lfbs 200 + uniform 300 in most. Seed 0 is one that succeeds.
BAR = {"sampler": "lfbs", "narrow": 200, "uniform": 300, "seed": 0}
# joint3d's own start and goal need the 10 x 10 hole (see test_workspace.py and the slow test); here a plan on
# the near side of the wall with large turns on all three continuous angles, one of them across the +-pi seam.
JOINT3D = {"sampler": "lfbs", "narrow": 60, "uniform": 90, "seed": 1}
JOINT3D_ENDS = {"start": [20, 25, 75, 0, 0, 0], "goal": [25, 70, 30, 3.0, -1.2, -3.0]}


def same_configuration(oracle, a, b, atol=1e-9):
    d = np.asarray(b, float) - np.asarray(a, float)
    d[..., oracle.space.continuous] = (d[..., oracle.space.continuous] + np.pi) % (2 * np.pi) - np.pi
    return np.allclose(d, 0, atol=atol)


@pytest.fixture(scope="module")
def planned(oracles):
    cache = {}

    def get(name):
        if name not in cache:
            params, ends = (BAR, {}) if name == "bar" else (JOINT3D, JOINT3D_ENDS)
            cache[name] = plan(oracles(name), PlanSettings(**params), **ends)
        return cache[name]

    return get


# ---- budget and metric ---------------------------------------------------------------------------------------------
def test_budget_is_spent_by_either_limit():
    assert str(Budget(seconds=30, checks=200000)) == "30s,200000checks" and str(Budget()) == "none"
    assert Budget(seconds=1).spent(1.0, 0) and not Budget(seconds=1).spent(0.5, 10**9)
    assert Budget(checks=10).spent(0, 10) and not Budget(checks=10).spent(10**6, 9)


def test_a_larger_budget_is_suggested_as_the_command_line_takes_it():
    """Ten times the checks; with a time limit too when that many checks would outlast the budget's (or the command
    line's safety net) at the pace the spent ones took: 200k checks in 52 s, times ten, would take 520 s."""
    assert Budget(seconds=600, checks=200_000).larger(10.0) == "2000kchecks"
    assert Budget(seconds=600, checks=200_000).larger(52.0) == "2000kchecks,800s"
    assert Budget(checks=8000).larger(1.0) == "80kchecks" and Budget(checks=2550).larger(0.1) == "25500checks"
    assert Budget(checks=2500).larger(100.0) == "25kchecks,1500s"
    assert Budget(checks=10**8).larger(60_000.0) == "1000000kchecks,86400s"  # the largest the command line takes


def test_roadmap_neighbours_are_exact_under_the_wrapping_metric(oracles):
    """Exact k nearest under the metric, across the +-pi seam, whether the nodes sit in one k-d tree or in the large
    one and the one over nodes added since (nodes come in batches, asked for neighbours between them)."""
    oracle = oracles("bar")
    rng = np.random.default_rng(3)
    Q = oracle.space.uniform(rng, 600)
    Q[:100, 2:] = rng.choice([-np.pi + 1e-3, np.pi - 1e-3], size=(100, 7))  # crowd the +-pi seam
    Q = Q[rng.permutation(len(Q))]
    roadmap = Roadmap(oracle.context())
    trees = []
    for begin, end in ((0, 300), (300, 400), (400, 480), (480, 600)):
        roadmap.add(Q[begin:end], "uniform", connect=False)
        probes = np.vstack([oracle.space.uniform(rng, 30), Q[:20] * np.r_[1, 1, [-1] * 7]])
        distances, indices = roadmap.neighbours(probes, 10)
        trees.append(len(roadmap._trees()))
        for p, d, i in zip(probes, distances, indices):
            truth = oracle.space.distance(p, Q[:end])
            assert np.allclose(np.sort(truth)[:10], d)
            assert np.allclose(truth[i], d)
    assert trees == [1, 2, 1, 2]  # the large tree rebuilt once the nodes since are more than half of it (480)


def test_the_search_graph_kept_between_searches_is_the_graph_of_the_edges_not_known_to_collide(oracles):
    """The kept search graph, with the entries of edges found colliding since it was compacted left at an infinite
    length, is the graph of the edges not known to collide; and the labels that let a search skip start and goal
    apart never part two nodes that edges not known to collide join."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    oracle = oracles("bar")
    rng = np.random.default_rng(6)
    roadmap = Roadmap(oracle.context(), k=8, lazy=True)
    for _ in range(3):  # grow, search (which checks and drops edges), remove some edges, and again
        roadmap.add(oracle.space.uniform(rng, 150), "uniform")
        roadmap.shortest_path(0, len(roadmap) - 1)
        for a, b in roadmap.edges()[rng.choice(len(roadmap.edges()), 20, replace=False)].tolist():
            roadmap.remove_edge(a, b)
        E = roadmap.edges()
        lengths = oracle.space.distance(roadmap.Q[E[:, 0]], roadmap.Q[E[:, 1]])
        fresh = csr_matrix(
            (np.r_[lengths, lengths], (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])), shape=(len(roadmap),) * 2
        )
        fresh.sort_indices()
        kept = roadmap._search_graph().tocoo()
        usable = np.isfinite(kept.data)
        assert (~usable).sum() >= 40  # the removed edges both ways, and those the search found colliding
        found = csr_matrix((kept.data[usable], (kept.row[usable], kept.col[usable])), shape=fresh.shape)
        assert dict(found.todok().items()) == dict(fresh.todok().items())
        compact = roadmap._search_graph(compact=True)
        assert compact.has_sorted_indices and len(E) > 0
        assert np.array_equal(compact.indptr, fresh.indptr) and np.array_equal(compact.indices, fresh.indices)
        assert np.array_equal(compact.data, fresh.data)
        _, components = connected_components(fresh, directed=False)
        same = components[:, None] == components[None, :]
        assert not (same & (roadmap._reach[:, None] != roadmap._reach[None, :])).any()
        assert len(np.unique(roadmap._reach)) > 1  # the labels do part nodes


def test_nodes_kept_are_numbered_again_with_every_verdict_between_them(oracles):
    """keep_nodes drops some nodes and every edge touching one; between the nodes kept, each edge keeps its verdict
    (free, colliding, unchecked) and proof under the new numbering, and a pair once tried is never proposed again."""
    oracle = oracles("bar")
    rng = np.random.default_rng(3)
    roadmap = Roadmap(oracle.context(), k=8, lazy=True)
    roadmap.add(oracle.space.uniform(rng, 200), "uniform")
    roadmap.shortest_path(0, len(roadmap) - 1)  # decides some edges: free ones checked, colliding ones dead
    roadmap.mark_proved([tuple(e) for e in roadmap.edges(checked=True)[:5].tolist()], 1e-3)

    def verdicts(graph, names):
        rows = zip(graph._ends.tolist(), graph._alive.tolist(), graph._checked.tolist())
        return {(names[a], names[b]): (alive, checked) for (a, b), alive, checked in rows}

    before = verdicts(roadmap, range(len(roadmap)))
    keep = rng.random(len(roadmap)) < 0.6
    Q, proved, tried = roadmap.Q.copy(), dict(roadmap.proved), len(roadmap._tried)
    index = roadmap.keep_nodes(keep)
    old = np.flatnonzero(keep)  # the old name of each node kept
    assert np.array_equal(roadmap.Q, Q[keep]) and len(roadmap.kinds) == keep.sum()
    assert np.array_equal(index[old], np.arange(len(old))) and (index[~keep] == -1).all()
    after = verdicts(roadmap, old)
    assert after == {pair: v for pair, v in before.items() if keep[pair[0]] and keep[pair[1]]} and after
    assert {(old[a], old[b]): c for (a, b), c in roadmap.proved.items()} == {
        p: c for p, c in proved.items() if keep[p[0]] and keep[p[1]]
    }
    assert 0 < len(roadmap._tried) < tried
    assert not {tuple(e) for e in roadmap.candidates(np.arange(len(roadmap))).tolist()} & {
        (index[a], index[b]) for a, b in before if keep[a] and keep[b]
    }


# ---- planned paths -------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["bar", "joint3d"])
def test_path_is_collision_free_under_an_independent_fine_check(oracles, planned, name):
    oracle, result = oracles(name), planned(name)
    assert result.certified
    P = result.path
    assert same_configuration(oracle, P[0], result.start) and same_configuration(oracle, P[-1], result.goal)
    points = fine_points(oracle, P, oracle.space.resolution / 8)
    assert oracle.space.within_bounds(points).all()
    assert all(raw_free(oracle, q) for q in points)
    # The sampled trajectory too (it follows the polyline exactly; this checks that claim).
    assert all(raw_free(oracle, q) for q in oracle.space.wrap(result.trajectory.positions))


@pytest.mark.parametrize("name", ["bar", "joint3d"])
def test_trajectory_respects_limits_and_joins_start_to_goal(oracles, planned, name):
    oracle, result = oracles(name), planned(name)
    traj, scene = result.trajectory, oracle.scene
    t, X = traj.times, traj.positions
    assert t[0] == 0 and math.isclose(t[-1], traj.duration) and np.all(np.diff(t) > 0)
    assert np.allclose(X[0], result.start)
    assert same_configuration(oracle, X[-1], result.goal)
    assert np.allclose(X[-1], oracle.space.unwrap(result.path)[-1])  # unwrapped: ends where the path's steps lead
    V = np.diff(X, axis=0) / np.diff(t)[:, None]
    assert np.all(np.abs(V) <= scene.velocity_limits * 1.01 + 1e-9)
    mid = 0.5 * (t[1:] + t[:-1])
    A = np.diff(V, axis=0) / np.diff(mid)[:, None]
    assert np.all(np.abs(A) <= scene.acceleration_limits * 1.05 + 1e-6)
    dt = PlanSettings().dt
    # No 2*pi jumps: consecutive samples are close in every coordinate.
    assert np.all(np.abs(np.diff(X, axis=0)) <= scene.velocity_limits * dt * 1.01 + 1e-9)
    # The velocities and accelerations it reports are within the limits and are the motion's own.
    assert np.all(np.abs(traj.velocities) <= scene.velocity_limits * (1 + 1e-6) + 1e-9)
    assert np.all(np.abs(traj.accelerations) <= scene.acceleration_limits * (1 + 1e-6) + 1e-9)
    assert np.allclose(
        0.5 * (traj.velocities[1:] + traj.velocities[:-1]), V, atol=float(np.max(scene.acceleration_limits)) * dt
    )
    assert np.allclose(traj.velocities[[0, -1]], 0) and traj.joint_names == scene.coordinate_names
    # Corners are blended (velocity never jumps: the acceleration bound above), and the blended curve is proved.
    assert traj.certified and result.stats.distance_queries > 0


def plan_mbm(kind: str, number: int):
    """One of the shipped MotionBenchMaker Panda problems, planned with the default settings."""
    from app.checking.oracle import CollisionOracle
    from app.planning.moveit import goal_configurations
    from app.scene.files import PACKAGES
    from app.scene.moveit import read_problem

    robots = PACKAGES["npp_robots"]
    folder, robot = robots.parent / "examples" / "moveit" / "mbm-panda" / kind, robots / "panda"
    problem = read_problem(
        request=folder / f"request{number:04d}.yaml", scene=folder / f"scene{number:04d}.yaml",
        robot=robot / "panda.urdf", srdf=robot / "panda.srdf",
    )  # fmt: skip
    oracle = CollisionOracle(problem.scene)
    return plan(oracle, PlanSettings(), start=problem.start, goal=goal_configurations(oracle, problem))


def test_a_goal_in_a_pocket_that_uniform_rounds_open_never_pays_for_narrow_passage_samples():
    """The grasp pose in the shelf has no edge after the first round (all its candidate edges collide), and a later
    uniform round opens it: no workspace gaps searched, no walker started."""
    result = plan_mbm("bookshelf_tall", 4)
    stats = result.stats
    assert result.route == "roadmap" and stats.rounds > 1 and stats.narrow_from_round is None
    assert stats.roadmap.narrow_nodes == stats.roadmap.workspace_nodes == 0
    assert not stats.sampler_stats["workspace"] and not stats.sampler_stats["narrow"]  # not a check spent


def test_a_pocket_that_uniform_rounds_leave_shut_brings_in_the_narrow_passage_sources():
    result = plan_mbm("bookshelf_tall", 3)
    stats = result.stats
    assert stats.narrow_from_round == POCKET_ROUNDS + 1 and stats.rounds > POCKET_ROUNDS
    assert stats.roadmap.workspace_nodes > 0 and stats.sampler_stats["narrow"]["checks"] > 0


def test_a_goal_shut_in_a_pocket_grows_out_of_it_by_checked_motions():
    """The grasp pose deep in the thin shelf: its every candidate edge collides and no sample lands near it (without
    the expansion, 100k checks found no path); motions grown from it, each checked, lead it out."""
    result = plan_mbm("bookshelf_thin", 8)
    expansion = result.stats.sampler_stats["expansion"]
    assert 0 < expansion["samples"] <= expansion["tried"] and expansion["checks"] > 0
    assert result.sources_on_path.get("expansion", 0) >= 1 and result.certified
    assert result.collision_checks < 20_000


def test_bar_path_uses_narrow_samples_and_smoothing_shortens_it(planned):
    result = planned("bar")
    assert result.narrow_on_path + result.workspace_on_path >= 1
    assert result.smoothing.length_after <= result.smoothing.raw_length + 1e-9
    assert result.stats.seconds.total >= result.stats.seconds.sampling > 0


def test_a_query_stops_at_the_first_round_that_connects_and_checks_edges_lazily(oracles, planned):
    result = planned("bar")  # 75 uniform samples a round; narrow ones from round 2, 13, 26, 50, 50, ...
    assert result.stats.roadmap.uniform_nodes == 75 * result.stats.rounds
    # bar's gap is not found by 75 uniform samples, which leave both start and goal with edges on their sides of
    # the wall: the uniform rounds have stalled, and the narrow-passage sources join at once
    assert result.stats.narrow_from_round == 2 and result.stats.rounds >= 2
    ramp = [min(50, 13 * 2**k) for k in range(result.stats.rounds - 1)]
    # that share of each round's narrow-passage samples are placements in workspace gaps, the rest the sampler's
    assert result.stats.roadmap.workspace_nodes == sum(round(PlanSettings().workspace * n) for n in ramp)
    assert result.stats.roadmap.narrow_nodes + result.stats.roadmap.workspace_nodes == sum(ramp)
    assert result.narrow_on_path + result.workspace_on_path >= 1
    assert result.stats.rounds < 6 and result.stats.roadmap.lazy
    assert result.stats.roadmap.edges_unchecked > 0  # most candidate edges never lay on a candidate path
    assert result.stats.roadmap.edges_tried < result.stats.roadmap.edges_proposed / 2
    checked = {tuple(edge) for edge in result.graph.edges(checked=True).tolist()}
    assert all((min(u, v), max(u, v)) in checked for u, v in zip(result.path_nodes[:-1], result.path_nodes[1:]))


def test_full_roadmap_builds_every_sample_and_checks_every_edge(oracles):
    result = plan(oracles("bar"), PlanSettings(**BAR, full_roadmap=True, smooth_rounds=0))
    assert result.stats.roadmap.nodes == 502 and result.stats.roadmap.narrow_nodes == 200 and result.stats.rounds == 1
    assert not result.stats.roadmap.lazy and result.stats.roadmap.edges_unchecked == 0
    assert result.stats.roadmap.k == 19  # k-PRM*: e (1 + 1/9) ln 502 = 18.8, for 502 nodes in 9 dimensions


def test_a_path_that_fails_the_fine_recheck_is_replanned_fine_only():
    from app.checking.oracle import CollisionOracle
    from app.scene.model import Scene

    # At a 2 m planning resolution the maze's 0.9 m thick walls (in configuration space) slip between checked
    # points; the fine re-check at 0.5 m does not miss them.
    oracle = CollisionOracle(Scene("maze"))
    oracle.space = dataclasses.replace(oracle.space, resolution=2.0)
    result = plan(oracle, PlanSettings(seed=0, smooth_rounds=10))
    assert result.smoothing.fine_only
    assert all(raw_free(oracle, q) for q in fine_points(oracle, result.path, 0.5))
    assert all(raw_free(oracle, q) for q in fine_points(oracle, result.roadmap_path, 0.5))


def test_a_careful_query_fine_checks_roadmap_paths_once_the_certificate_refused_an_edge(oracles):
    """The fine check filters roadmap edges that slip between checked points; until the certificate has refused one,
    a careful query proves the path's edges directly and the fine check would be work for nothing."""
    from app.planning.query import Query

    query = Query(oracles("bar"), PlanSettings(**BAR))
    query.solve()
    query.refinement.fine_only = True
    before = query.checker.checks
    nodes = query.search(query.stop)
    assert nodes is not None and query.checker.checks == before
    query.refinement.unproved_edges = 1
    assert query.search(query.stop) == nodes and query.checker.checks > before


def test_an_edge_the_certificate_cannot_prove_is_treated_as_colliding():
    from app.checking.oracle import CollisionOracle
    from app.scene.model import Scene

    # At a 4 m resolution even the fine re-check (1 m) can step over the maze's 0.9 m walls: roadmap edges pass it
    # and then fail the certificate. They must leave the roadmap (not come back as an uncertified path).
    oracle = CollisionOracle(Scene("maze"))
    oracle.space = dataclasses.replace(oracle.space, resolution=4.0)
    result = plan(oracle, PlanSettings(seed=0, smooth_rounds=10))
    # Hundreds of edges step over a wall; after the first refusal the fine check finds most of them first.
    assert 0 < result.certificate.unproved_edges <= 20
    assert result.trajectory.certified
    assert all(raw_free(oracle, q) for q in fine_points(oracle, result.path, 0.05))


def test_once_careful_a_roadmap_path_is_proved_before_smoothing_is_spent_on_it(monkeypatch):
    """Smoothing a candidate the certificate then refuses wastes it: after the first refusal, candidates are proved
    first, so a query smooths at most two roadmap paths (once optimistic, once careful) however many edges it drops."""
    from app.checking.oracle import CollisionOracle
    from app.planning.refine import Refinement
    from app.scene.model import Scene

    oracle = CollisionOracle(Scene("maze"))
    oracle.space = dataclasses.replace(oracle.space, resolution=4.0)  # edges that pass the checks, then fail
    smoothed, smooth = [], Refinement.smooth
    monkeypatch.setattr(
        Refinement,
        "smooth",
        lambda self, nodes, stop, memo=None: smoothed.append(tuple(nodes)) or smooth(self, nodes, stop, memo),
    )
    result = plan(oracle, PlanSettings(seed=0, smooth_rounds=10))
    assert result.certificate.unproved_edges > 0 and result.trajectory.certified
    # Repairs smooth the same roadmap path again; what is limited is the roadmap paths smoothing is spent on.
    assert 1 <= len(set(smoothed)) <= 2 and smoothed[-1] == tuple(result.path_nodes)


class _PredicateOracle:
    """Stands in for a CollisionOracle in a query context: collision answers from `collides(Q)` on configurations
    (n, dim), for the path code, which needs only the metric and the context's checks."""

    def __init__(self, space, collides):
        self.space, self.scene, self.collides = space, None, collides

    def free_batch(self, Q):
        return ~self.collides(np.atleast_2d(Q))

    def first_hits(self, Q, owner, hit, until_one):
        checked = 0
        for i, (q, edge) in enumerate(zip(Q, owner.tolist()), 1):
            if not hit[edge]:
                checked += 1
                if self.collides(q[None])[0]:
                    hit[edge] = True
                    if until_one:
                        return i, checked
        return len(Q), checked


def _wall_oracle():
    """A 2-D checker with a thin wall between the fine points of the test path's first edge, and a block that leaves
    no direct line from the start to the end."""
    from app.checking.context import QueryContext
    from app.scene.cspace import ConfigurationSpace

    space = ConfigurationSpace(
        lower=np.full(2, -20.0),
        upper=np.full(2, 20.0),
        weights=np.ones(2),
        angular=np.zeros(2, bool),
        continuous=np.zeros(2, bool),
        resolution=1.0,
    )

    def collides(Q):
        x, y = Q.T
        wall = (x >= 4.1) & (x <= 4.15) & (y >= -0.5) & (y <= 0.3)
        block = (x >= 4.5) & (x <= 9.0) & (y >= 0.2) & (y <= 9.0)
        return wall | block

    return QueryContext(_PredicateOracle(space, collides)), np.array([[0.0, 0.0], [9.5, 0.0], [9.5, 10.0]])


def test_every_edge_of_a_shortened_path_lies_on_the_path_or_on_a_shortcut_checked_free():
    """What the certificate and the repair rely on: shortcuts are the only new motion (the pieces of the edges they
    cut are not re-checked: they are parts of checked edges), and each was checked before it was taken."""
    from app.motion.path import Shortcuts, on_segment, shortcut

    oracle, P = _wall_oracle()
    shortened = 0
    for seed in range(50):
        memo = Shortcuts()
        smoothed, stats = shortcut(oracle, P, np.random.default_rng(seed), rounds=10, resolution=0.25, memo=memo)
        free = [np.frombuffer(k).reshape(2, -1) for k, ok in memo.known.items() if ok]
        for u, v in zip(smoothed[:-1], smoothed[1:]):
            carriers = [*zip(P[:-1], P[1:]), *free]
            assert any(on_segment(oracle.space, a, b, np.array([u, v])) for a, b in carriers), seed
        shortened += stats.length_after < stats.length_before
    assert shortened >= 45


def test_a_replay_repeats_the_shortcuts_for_free_and_a_banned_one_is_avoided():
    from app.motion.path import Shortcuts, on_segment, shortcut

    oracle, P = _wall_oracle()
    memo = Shortcuts()
    first, _ = shortcut(oracle, P, np.random.default_rng(3), rounds=10, resolution=0.25, memo=memo)
    checks = oracle.checks
    again, _ = shortcut(oracle, P, np.random.default_rng(3), rounds=10, resolution=0.25, memo=memo)
    assert np.array_equal(first, again) and oracle.checks == checks
    shortcut_edges = [
        i
        for i in range(len(first) - 1)
        if not any(on_segment(oracle.space, *e, first[i : i + 2]) for e in zip(P[:-1], P[1:]))
    ]
    assert shortcut_edges
    assert memo.ban_carriers(oracle.space, first, shortcut_edges[:1]) == 1
    repaired, _ = shortcut(oracle, P, np.random.default_rng(3), rounds=10, resolution=0.25, memo=memo)
    banned = [np.frombuffer(k).reshape(2, -1) for k in memo.banned]
    for u, v in zip(repaired[:-1], repaired[1:]):
        assert not any(on_segment(oracle.space, a, b, np.array([u, v])) for a, b in banned)
    assert memo.ban_carriers(oracle.space, P, [0, 1]) == 0  # the path's own edges have no shortcut carrying them


def test_an_angle_wound_a_whole_turn_along_the_path_is_turned_the_short_way():
    """x linear, theta continuous: the path turns theta by 6 rad (three edges, each the short way) where -0.28 would
    do, and every shortcut between its waypoints that would undo that crosses a block near x = 0. Smoothing (its
    greedy pass alone: random shortcuts may hop round the block) turns theta the short way, spread along the path;
    the ends stay exactly where they were."""
    from app.checking.context import QueryContext
    from app.motion.path import shortcut
    from app.scene.cspace import ConfigurationSpace

    space = ConfigurationSpace(
        lower=np.array([-20.0, -np.pi]),
        upper=np.array([20.0, np.pi]),
        weights=np.ones(2),
        angular=np.array([False, True]),
        continuous=np.array([False, True]),
        resolution=0.05,
    )

    def collides(Q):
        x, theta = Q.T
        return (np.abs(x) <= 1.0) & (theta >= -0.2) & (theta <= -0.1)

    oracle = QueryContext(_PredicateOracle(space, collides))
    P = oracle.space.wrap(np.array([[0.0, 0.0], [10.0, 2.0], [10.0, 4.0], [0.0, 6.0]]))
    assert oracle.edges_free(P[:-1], P[1:]).all()
    assert not oracle.edges_free(P[:1], P[2:3]).any() and not oracle.edges_free(P[1:2], P[3:]).any()
    smoothed, stats = shortcut(oracle, P, np.random.default_rng(0), rounds=0)
    turn = oracle.space.unwrap(smoothed)[:, 1]
    assert stats.unwound == 1 and turn[-1] - turn[0] == pytest.approx(6.0 - 2 * np.pi)
    assert np.array_equal(smoothed[[0, -1]], P[[0, -1]])
    assert oracle.edges_free(smoothed[:-1], smoothed[1:]).all()
    assert stats.length_after < stats.length_before


def test_a_shortcut_the_certificate_refuses_is_undone_and_the_others_kept(monkeypatch):
    """The certificate is made to refuse the first smoothed path's longest shortcut: smoothing is replayed without
    it, the result is proved and still shorter than the roadmap path, and the shortcuts stay within smoothing's cap
    (turning a joint wound a whole turn back the short way is exempt: Refinement.smooth)."""
    from app.checking.oracle import CollisionOracle
    from app.motion.path import on_segment, unwind
    from app.planning import refine
    from app.planning.refine import Refinement
    from app.planning.settings import SMOOTHING_CAP
    from app.scene.model import Scene

    oracle = CollisionOracle(Scene("bar-3link"))
    raw, refused, smooth, certify = [], [], Refinement.smooth, Refinement.certify

    def recording(self, nodes, stop, memo=None):
        raw.append(self.roadmap.Q[nodes])
        return smooth(self, nodes, stop, memo)

    def on_raw(path, i):
        return any(on_segment(oracle.space, a, b, path[i : i + 2]) for a, b in zip(raw[-1][:-1], raw[-1][1:]))

    def refuse(path, edges) -> list[int]:
        """The first smoothed path's longest new edge, refused wherever it appears."""
        new = [i for i in edges if not on_raw(path, i)]
        if raw and not refused and new:
            worst = max(new, key=lambda i: oracle.space.distance(path[i], path[i + 1]))
            refused.append(path[worst : worst + 2].copy())
        return [i for i in edges if refused and np.array_equal(path[i : i + 2], refused[0])]

    def refusing(self, path, stop, edges=None):
        certificate = certify(self, path, stop, edges)
        failed = refuse(path, range(len(path) - 1) if edges is None else edges)
        return dataclasses.replace(certificate, proved=False, failed=failed) if failed else certificate

    unwinding = []

    def counted_unwind(o, path, *args):
        checks = o.checks
        try:
            return unwind(o, path, *args)
        finally:
            unwinding.append(o.checks - checks)

    monkeypatch.setattr(Refinement, "smooth", recording)
    monkeypatch.setattr(Refinement, "certify", refusing)
    monkeypatch.setattr(refine, "unwind", counted_unwind)
    result = plan(oracle, PlanSettings(seed=0))
    assert refused and result.smoothing.repairs == 1 and not result.smoothing.fine_only
    assert result.trajectory.certified
    P = result.path
    assert not any(on_segment(oracle.space, *refused[0], P[i : i + 2]) for i in range(len(P) - 1))
    assert result.smoothing.length_after < result.smoothing.raw_length
    finding = result.collision_checks - result.stats.checks.smoothing - result.stats.checks.timing
    assert result.stats.checks.smoothing - sum(unwinding) <= SMOOTHING_CAP * finding + 1


def test_the_blends_are_proved_only_on_a_path_whose_polyline_is_proved(monkeypatch):
    """Smoothing's proof takes the polyline first and the blends after it, with every edge known: a path the
    certificate refuses pays for no blends, and the blends' proof does not prove a straight part again."""
    from app.checking.oracle import CollisionOracle
    from app.planning import refine
    from app.planning.refine import Refinement
    from app.scene.model import Scene

    events, certify, prove_blends = [], Refinement.certify, refine.prove_blends

    def certifying(self, path, stop, edges=None):
        certificate = certify(self, path, stop, edges)
        events.append(("polyline", path.tobytes(), certificate.proved))
        return certificate

    def blending(certifier, path, known=(), *args, **kwargs):
        events.append(("blends", path.tobytes(), [int(i) for i in known] == list(range(len(path) - 1))))
        return prove_blends(certifier, path, known, *args, **kwargs)

    monkeypatch.setattr(Refinement, "certify", certifying)
    monkeypatch.setattr(refine, "prove_blends", blending)
    result = plan(CollisionOracle(Scene("bar-3link")), PlanSettings(seed=0))
    blends = [(i, e) for i, e in enumerate(events) if e[0] == "blends"]
    assert blends and all(known for _, (_, _, known) in blends)
    for i, (_, path, _) in blends:
        assert ("polyline", path, True) in events[:i]
    assert result.certificate.blended and result.trajectory.certified


def test_same_seed_same_path(oracles, planned):
    first = planned("joint3d")
    again = plan(oracles("joint3d"), PlanSettings(**JOINT3D), **JOINT3D_ENDS)
    assert np.array_equal(first.path, again.path)
    assert np.array_equal(first.trajectory.positions, again.trajectory.positions)
    assert first.collision_checks == again.collision_checks


def test_endpoint_errors_in_the_api(oracles):
    oracle = oracles("bar")
    with pytest.raises(InvalidEndpoint, match=r"start is in collision: .*obstacles::"):
        plan(oracle, PlanSettings(narrow=0, uniform=1), start=[50, 30, 0, 0, 0, 0, 0, 0, 0])
    with pytest.raises(InvalidEndpoint, match=r"goal is out of bounds: base_x=150"):
        plan(oracle, PlanSettings(narrow=0, uniform=1), goal=[150, 50, 0, 0, 0, 0, 0, 0, 0])
    with pytest.raises(UserError, match="needs 9"):
        plan(oracle, PlanSettings(narrow=0, uniform=1), start=[1, 2, 3])


def test_no_path_says_what_was_tried(oracles):
    with pytest.raises(NoPath, match=r"roadmap of 12 nodes .* start and goal not joined by edges checked free") as info:
        plan(oracles("joint3d"), PlanSettings(sampler="uniform", narrow=0, uniform=10, seed=0, full_roadmap=True))
    assert info.value.details["roadmap"]["nodes"] == 12 and "may not grow further" in str(info.value)


def test_a_free_straight_motion_is_the_answer_after_one_edge_check(oracles):
    oracle = oracles("joint3d")
    start, goal = [20, 25, 75, 0, 0, 0], [30, 25, 75, 0.5, 0, 0]
    result = plan(oracle, PlanSettings(seed=0), start=start, goal=goal)
    assert result.stats.rounds == 0 and len(result.path) == 2 and result.route == "straight"
    inner = len(oracle.space.interpolate(start, goal, oracle.space.resolution)) - 2
    # the endpoints, then every inner point of one edge check; the certificate proves the rest (distance queries)
    assert result.collision_checks == 2 + inner and result.trajectory.certified


def test_a_free_route_through_via_points_is_the_answer_without_a_roadmap(oracles):
    """The caller's easy route (a job's tool line) is taken as the straight motion is: checked, proved, timed, no
    sample drawn. A route that collides is only a first try: with no samples allowed the query then fails."""
    oracle = oracles("bar-3link")
    found = plan(oracle, PlanSettings(seed=0))
    via = found.path[1:-1]
    assert len(via) >= 1 and not oracle.context().edge_free(oracle.scene.start, oracle.scene.goal)
    result = plan(oracle, PlanSettings(seed=1, narrow=0, uniform=0), via=via)
    assert result.stats.rounds == 0 and result.route == "via" and result.via == len(via)
    assert np.array_equal(result.path[1:-1], via) and result.trajectory.certified
    assert np.array_equal(result.roadmap_path, result.path)
    with pytest.raises(NoPath):
        plan(oracle, PlanSettings(seed=1, narrow=0, uniform=0), via=[oracle.scene.start])  # the straight motion again
    with pytest.raises(UserError, match="via point out of bounds"):
        plan(oracle, PlanSettings(seed=1), via=[np.full(oracle.space.dim, 1e6)])


def test_a_plan_without_timing_returns_the_certified_path_alone(oracles):
    """Without timing the polyline itself is the answer, and it is what is proved; with timing, the blended curve
    the trajectory follows is, and the answer says so."""
    from app.checking.certify import certify_path

    oracle = oracles("bar-3link")
    timed, bare = (plan(oracle, PlanSettings(seed=0, timing=t)) for t in (True, False))
    assert bare.trajectory is None and timed.trajectory is not None and bare.stats.seconds.timing == 0
    assert np.array_equal(bare.path, timed.path)
    answer = json.loads(json.dumps(bare.to_json()))
    assert answer["trajectory"] is None and answer["certified"] is True
    assert bare.certificate.blended is False and bare.blends is None
    assert certify_path(oracle.context(), bare.path)[0]
    assert timed.certificate.blended is True and timed.trajectory.certified
    assert np.array_equal(timed.blends.path, timed.path) and not timed.blends.failed


def test_a_check_budget_is_never_overrun(oracles):
    oracle = oracles("joint3d")  # joint3d's hole is beyond 8000 checks of uniform samples
    with pytest.raises(NoPath, match=r"budget of 8000 collision checks spent \(stopped: checks\)") as info:
        plan(oracle, PlanSettings(sampler="uniform", narrow=0, uniform=40, seed=0, budget=Budget(checks=8000)))
    assert 8000 <= info.value.details["collision_checks"] <= 8000 + 2  # + the two endpoint checks before it
    assert info.value.details["rounds"] > 1


def test_a_spent_check_budget_is_a_planning_failure_that_says_so_and_names_a_larger_budget(oracles):
    """MoveIt's TIMED_OUT is for time: a query its check limit stopped is PLANNING_FAILED, stopped "checks", and its
    message suggests ten times the checks (a time limit beside them only if the checks took long, which this scene's
    do not come near). Its details count what it spent as a success answer counts it."""
    oracle = oracles("joint3d")
    settings = PlanSettings(sampler="uniform", narrow=0, uniform=40, seed=0, budget=Budget(seconds=600, checks=8000))
    with pytest.raises(NoPath, match=r"; budget of 8000 collision checks spent \(stopped: checks\): a larger one may "
                       r"find a path, try --budget 80kchecks") as info:  # fmt: skip
        plan(oracle, settings)
    details = info.value.details
    assert info.value.code == "PLANNING_FAILED" and details["stopped"] == "checks"
    assert details["collision_checks"] == sum(details["checks"].values()) >= 8000
    assert set(details["checks"]) == {"endpoints", *PHASES} and set(details["seconds"]) == {*PHASES, "total"}
    assert details["seconds"]["total"] >= details["seconds"]["sampling"] > 0 and details["rounds"] > 1
    assert details["distance_queries"] == 0 and details["budget"] == "600s,8000checks"


def test_ctrl_c_during_a_query_carries_what_it_spent(oracles, monkeypatch):
    """A KeyboardInterrupt stays one (the command line answers PREEMPTED, exit code 130), with the query's figures
    as its `details`, as a failure's NoPath has them."""
    from app.planning.query import Query

    grow, rounds = Query.grow, []

    def interrupted_in_the_second_round(self, *sizes):
        rounds.append(1)
        if len(rounds) == 2:
            raise KeyboardInterrupt
        return grow(self, *sizes)

    monkeypatch.setattr(Query, "grow", interrupted_in_the_second_round)
    with pytest.raises(KeyboardInterrupt) as info:
        plan(oracles("joint3d"), PlanSettings(sampler="uniform", narrow=0, uniform=40, seed=0))
    details = info.value.details
    assert details["stopped"] == "interrupted" and details["rounds"] == 1  # the first round, done
    assert details["collision_checks"] == sum(details["checks"].values()) > details["checks"]["endpoints"]
    assert set(details["seconds"]) == {*PHASES, "total"}


def test_a_query_cancelled_from_another_thread_stops_with_moveits_preempted(oracles):
    """The stop condition polls the cancel event before every collision batch, as it polls the budget: an event
    that another thread sets after the query has made a few batches ends it there, long before its budget."""
    import threading

    oracle = oracles("joint3d")  # the sampler alone does not solve it within the budget: only the cancel ends it

    class SetAfterPolls:  # a threading.Event that another thread sets once the query has polled it 50 times
        def __init__(self):
            self.polls, self.event = 0, threading.Event()

        def is_set(self) -> bool:
            self.polls += 1
            if self.polls == 50:
                threading.Thread(target=self.event.set).start()
            return self.event.wait(1.0) if self.polls >= 50 else False

    budget = Budget(checks=1_000_000)
    with pytest.raises(NoPath, match=r", cancelled$") as info:
        plan(oracle, PlanSettings(seed=0, budget=budget, workspace=0.0), cancel=SetAfterPolls())
    assert info.value.code == "PREEMPTED" and info.value.details["stopped"] == "cancelled"
    assert info.value.details["collision_checks"] < budget.checks / 10
    assert plan(oracle, PlanSettings(seed=0), start=[20, 25, 75, 0, 0, 0], goal=[30, 25, 75, 0, 0, 0]).certified


def test_proving_a_path_keeps_to_the_time_limit_and_cancel_but_not_the_check_limit(oracles, monkeypatch):
    """The certificate polls the query's stop between its batches of distance queries: a cancel (or a time limit)
    that comes while a found path is being proved ends the query there, and says a path was found; a check limit
    spent by the search does not stop the proof, which asks for no checks."""
    import threading

    from app.checking.certify import Certifier

    oracle = oracles("maze")
    cancel, calls, certify = threading.Event(), [], Certifier.certify

    def certify_then_cancel(self, *args, **kwargs):
        calls.append(1)
        cancel.set()
        return certify(self, *args, **kwargs)

    monkeypatch.setattr(Certifier, "certify", certify_then_cancel)
    with pytest.raises(NoPath, match=r"a path was found on maze but proving and timing it did not finish") as info:
        plan(oracle, PlanSettings(seed=0), cancel=cancel)
    assert info.value.code == "PREEMPTED" and info.value.details["stopped"] == "cancelled" and len(calls) == 1
    monkeypatch.setattr(Certifier, "certify", certify)

    spent = plan(oracle, PlanSettings(seed=0)).collision_checks  # the whole query's checks: search and smoothing
    tight = plan(oracle, PlanSettings(seed=0, budget=Budget(checks=spent)))
    assert tight.trajectory.certified and tight.stats.distance_queries > 0


def test_a_time_budget_ends_sampling_within_a_round(oracles, monkeypatch):
    """rbbs spends most of a round looking for bridges in the maze: the budget stops it inside the sampler, in the
    first round (a round of it takes tens of seconds). The budget's clock is the test's own, 10 ms a look, so the
    budget runs out at its 50th look whatever the machine's speed or load."""
    import types

    import app.checking.budget

    looks = iter(range(10**9))
    monkeypatch.setattr(app.checking.budget, "time", types.SimpleNamespace(perf_counter=lambda: next(looks) / 100))
    oracle = oracles("maze")
    with pytest.raises(NoPath, match=r"time limit of 0.5 s spent \(stopped: time\): try a longer one") as info:
        plan(oracle, PlanSettings(sampler="rbbs", seed=0, step=0.3, budget=Budget(seconds=0.5)))
    assert info.value.details["rounds"] == 1 and info.value.details["stopped"] == "time"
    assert info.value.code == "TIMED_OUT"  # MoveIt's code for time


def test_parameters_that_would_never_end_are_refused(oracles):
    with pytest.raises(UserError, match="longer than the scene's diagonal"):
        plan(oracles("bar-3link"), PlanSettings(step=1e308))
    with pytest.raises(UserError, match="dt must be at least"):
        PlanSettings(dt=1e-7)


def test_budget_adds_rounds_until_spent(oracles):
    with pytest.raises(NoPath, match=r"budget of 8000 collision checks spent") as info:
        plan(
            oracles("joint3d"), PlanSettings(sampler="uniform", narrow=0, uniform=8, seed=0, budget=Budget(checks=8000))
        )
    assert info.value.details["rounds"] > 1
    assert info.value.details["roadmap"]["nodes"] > 10


@pytest.mark.slow
def test_joint3d_through_the_hole_with_the_sampler_alone(oracles):
    # Without workspace-gap placements seed 0 connects after about 414k checks (1.5-2 min): a check budget, so the
    # machine's load cannot fail it.
    oracle = oracles("joint3d")
    settings = PlanSettings(sampler="lfbs", seed=0, budget=Budget(checks=600_000), workspace=0.0)
    result = plan(oracle, settings)
    points = fine_points(oracle, result.path, oracle.space.resolution / 8)
    assert all(raw_free(oracle, q) for q in points)
    assert oracle.workspace.in_passage(points).any()


# ---- the command line ----------------------------------------------------------------------------------------------
def test_cli_plan_json_and_out(tmp_path, cli):
    out = tmp_path / "traj.json"
    start, goal = ",".join(map(str, JOINT3D_ENDS["start"])), ",".join(map(str, JOINT3D_ENDS["goal"]))
    result = cli(
        "plan",
        "joint3d",
        "--narrow",
        "60",
        "--uniform",
        "90",
        "--seed",
        "1",
        "--start",
        start,
        "--goal",
        goal,
        "--json",
        "--out",
        out,
    )
    assert result.returncode == 0, result.stderr
    doc = json.loads(result.stdout)
    for key in [
        "success",
        "scene",
        "sampler",
        "seed",
        "path",
        "trajectory",
        "collision_checks",
        "seconds",
        "roadmap",
        "narrow_on_path",
    ]:
        assert key in doc
    assert doc["success"] is True and doc["sampler"] == "lfbs"
    assert set(doc["roadmap"]) >= {"nodes", "edges", "components"}
    assert set(doc["trajectory"]) >= {"joint_names", "time_from_start", "positions", "velocities", "accelerations"}
    written = json.loads(out.read_text())
    assert written["positions"] == doc["trajectory"]["positions"] and written["waypoints"] == doc["path"]
    assert len(written["narrow_samples"]) == doc["roadmap"]["narrow_nodes"] == 15 * doc["rounds"]
    assert sum(written["narrow_on_path"]) == doc["narrow_on_path"]
    from app.motion.trajectory import TrajectoryFile  # the file is what the viewer reads

    TrajectoryFile.from_json(written, 6)
    assert [p.name for p in tmp_path.iterdir()] == ["traj.json"]  # no temp file left behind


def test_cli_human_summary(cli):
    result = cli(
        "plan",
        "joint3d",
        "--narrow",
        "20",
        "--uniform",
        "30",
        "--seed",
        "1",
        "--start",
        "20,25,75,0,0,0",
        "--goal",
        "30,25,75,0,0,0",
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("plan joint3d: path found") and "collision checks" in result.stdout


@pytest.mark.parametrize(
    "args, code, words",
    [
        (["bar", "--start", "50,30,0,0,0,0,0,0,0"], 3, ["start", "collision", "obstacles::obstacles"]),
        (["bar", "--goal", "150,50,0,0,0,0,0,0,0"], 3, ["goal", "out of bounds"]),
        (
            ["joint3d", "--sampler", "uniform", "--narrow", "0", "--uniform", "10", "--budget", "1checks"],
            1,
            ["no path", "not joined", "budget of 1 collision check spent", "try --budget 10checks"],
        ),
        (["bar", "--sampler", "magic"], 2, ["unknown sampler", "lfbs"]),
        (["atlantis"], 2, ["unknown scene"]),
        (["bar", "--narrow", "-1"], 2, ["--narrow"]),
        (["bar", "--uniform", "many"], 2, ["--uniform"]),
        (["bar", "--step", "nan"], 2, ["--step"]),
        (["bar", "--budget", "forever"], 2, ["budget"]),
        (["bar", "--start", "1,2,3"], 2, ["start", "9"]),
        (["bar", "--goal", "1,2,nan,4,5,6,7,8,9"], 2, ["--goal"]),
    ],
)
def test_cli_errors_are_one_line_with_the_agreed_code(tmp_path, cli, one_line_error, args, code, words):
    out = tmp_path / "traj.json"
    result = cli("plan", *args, "--out", out)
    one_line_error(result, code)
    for word in words:
        assert word in result.stderr, result.stderr
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_cli_out_into_a_missing_folder_is_exit_2(tmp_path, cli, one_line_error):
    result = cli("plan", "bar", "--out", tmp_path / "missing" / "traj.json")
    one_line_error(result, 2)


def test_cli_plan_html_shows_the_trajectory(tmp_path, cli, monkeypatch):
    page = tmp_path / "plan.html"
    monkeypatch.setenv("DRAKE_ALLOW_NETWORK", "meshcat")  # the viewer's Meshcat needs it, even to export
    result = cli(
        "plan",
        "joint3d",
        "--narrow",
        "20",
        "--uniform",
        "30",
        "--seed",
        "1",
        "--start",
        "20,25,75,0,0,0",
        "--goal",
        "30,25,75,0,0,1",
        "--html",
        page,
    )
    assert result.returncode == 0, result.stderr
    assert page.read_text().lstrip().lower().startswith("<!doctype html")


def test_bench_plan_runs_and_resumes_from_its_store(tmp_path, cli, one_line_error):
    store = tmp_path / "bench.sqlite"
    args = [
        "bench",
        "plan",
        "--seeds",
        "2",
        "--scenes",
        "joint3d",
        "--samplers",
        "uniform,lfbs",
        "--narrow",
        "10",
        "--uniform",
        "10",
        "--smooth",
        "0",
        "--roadmap",
        "both",
        "--budget",  # the uniform samples never cross joint3d's hole: a query of them ends on its budget
        "3",
        "--store",
        str(store),
        "--json",
    ]
    result = cli(*args)
    assert result.returncode == 0, result.stderr
    table = {(row["sampler"], row["roadmap"]): row for row in json.loads(result.stdout)["plan"]}
    assert set(table) == {(s, m) for s in ("uniform", "lfbs") for m in ("query", "full")}
    assert all(row["runs"] == 2 for row in table.values())
    again = cli(*args)  # everything is in the store already: same table, nothing re-run
    first, second = json.loads(result.stdout), json.loads(again.stdout)
    assert (first.pop("reused")["reused"], second.pop("reused")["reused"]) == (0, 8)
    assert again.returncode == 0 and second == first
    one_line_error(cli("bench", "plan", "--samplers", "magic", "--store", store), 2)


def test_bench_plan_can_leave_the_workspace_placements_out(tmp_path, cli, one_line_error):
    """--workspace 0 measures the narrow-passage sampler alone; without the flag, the trials' params (their store
    keys) are what they were before the flag existed."""
    args = ["bench", "plan", "--scenes", "bar", "--samplers", "lfbs", "--seeds", "3", "--json"]
    default = json.loads(cli(*args, "--store", tmp_path / "default.sqlite").stdout)
    alone = json.loads(cli(*args, "--workspace", "0", "--store", tmp_path / "alone.sqlite").stdout)
    assert "workspace" not in default["params"] and alone["params"]["workspace"] == 0
    (with_placements,), (without,) = default["plan"], alone["plan"]
    assert with_placements["successes"] == without["successes"] == 3
    assert with_placements["median_workspace_on_path"] > 0 and without["median_workspace_on_path"] == 0
    # checks per second everything included, over a raw HasCollisions loop's beside it: at most the two cores' worth
    assert all(0 < row["median_of_raw"] <= 2 for row in (with_placements, without))
    one_line_error(cli(*args, "--workspace", "1.5", "--store", tmp_path / "bad.sqlite"), 2)


def test_bench_jobs_times_query_and_full_roadmap_side_by_side(tmp_path, cli, one_line_error):
    args = ["bench", "jobs", "--jobs", "welding", "--seeds", "1", "--store", str(tmp_path / "jobs.sqlite")]
    result = cli(*args)
    assert result.returncode == 0, result.stderr
    rows = [line.split() for line in result.stdout.splitlines() if line.startswith("welding  ")]
    assert [row[2] for row in rows] == ["full", "query"] and rows[1][3] == "1/1"
    # A full roadmap of the job's 80 samples rarely gets through the slot into the chassis: the ratio of the two
    # modes' times is printed only when both have a time.
    assert rows[0][3] in ("0/1", "1/1")
    assert ("welding lfbs: the query mode takes" in result.stdout) == (rows[0][3] == "1/1")
    one_line_error(cli("bench", "jobs", "--jobs", "parking", "--store", tmp_path / "x.sqlite"), 2)
    assert not (tmp_path / "x.sqlite").exists()


def test_plan_scales_the_limits_it_times_with(cli, tmp_path, oracles):
    full, slow = tmp_path / "full.json", tmp_path / "slow.json"
    assert cli("plan", "bar", "--out", full).returncode == 0
    assert cli("plan", "bar", "--out", slow, "--velocity-scale", "0.5", "--acceleration-scale", "0.25").returncode == 0
    full, slow = (json.loads(f.read_text()) for f in (full, slow))
    assert slow["waypoints"] == full["waypoints"]  # the same path (the same seed), timed more slowly
    scene = oracles("bar").scene
    assert np.all(np.abs(slow["velocities"]) <= 0.5 * scene.velocity_limits * (1 + 1e-6) + 1e-9)
    assert np.all(np.abs(slow["accelerations"]) <= 0.25 * scene.acceleration_limits * (1 + 1e-6) + 1e-9)
    assert slow["time_from_start"][-1] == pytest.approx(2 * full["time_from_start"][-1], rel=0.05)


@pytest.mark.parametrize("flag, value", [("--velocity-scale", "0"), ("--acceleration-scale", "1.5")])
def test_a_scale_outside_zero_to_one_is_bad_input(cli, one_line_error, flag, value):
    assert "must be a fraction in (0, 1]" in one_line_error(cli("plan", "bar", flag, value), 2)


@pytest.mark.parametrize("flag", ["--velocity-scale", "--acceleration-scale"])
def test_a_scale_that_would_make_the_motion_last_days_is_refused_before_planning(cli, one_line_error, flag):
    """Limits scaled by 1e-300 made Drake's own checks fail in C++ after planning, with nothing on stdout."""
    out = cli("plan", "bar", flag, "1e-300", "--json")
    assert "more than a day" in one_line_error(out, 2)
    answer = json.loads(out.stdout)
    assert answer["success"] is False and answer["error"]["code"] == "INVALID_INPUT"


def test_a_start_touching_an_obstacle_is_refused_naming_the_bodies(oracles):
    """maze's x bound 0.35 puts the hull against the outer wall (signed distance 0): the collision check calls that
    free, but no motion out of it can be certified, so it is refused at once instead of spending the budget."""
    oracle = oracles("maze")
    touching = oracle.scene.start.copy()
    touching[0] = oracle.space.lower[0]
    assert oracle.context().is_free(touching)
    with pytest.raises(InvalidEndpoint, match="start touches .*quadrotor::body") as refused:
        plan(oracle, PlanSettings(seed=0), start=touching)
    assert refused.value.code == "START_STATE_IN_COLLISION"
    clear = touching.copy()
    clear[0] += 0.01
    assert plan(oracle, PlanSettings(seed=0, budget=Budget(checks=200_000)), start=clear).trajectory.certified


def test_the_answer_keeps_the_clearance_it_states_and_an_end_nearer_is_refused(oracles, cli):
    """The maze's start is 1 cm from the outer wall once moved there: with a clearance of 2 cm it is refused, saying
    why; with 5 mm the answer is certified and states the clearance, as does the command line's answer, which the
    samples keep (Drake's own distances)."""
    oracle = oracles("maze")
    near = oracle.scene.start.copy()
    near[0] = oracle.space.lower[0] + 0.01
    with pytest.raises(InvalidEndpoint, match="start is nearer than the clearance 0.02") as refused:
        plan(oracle, PlanSettings(seed=0, clearance=0.02), start=near)
    assert refused.value.code == "START_STATE_IN_COLLISION"
    result = plan(oracle, PlanSettings(seed=0, clearance=0.005), start=near)
    assert result.certified and result.trajectory.clearance == result.to_json()["clearance"] == 0.005
    assert min(oracle.diagnostics.clearance(q, 1.0) for q in oracle.space.wrap(result.trajectory.positions)) >= 0.005
    answer = json.loads(cli("plan", "maze", "--json", "--clearance", "0.004").stdout)
    assert answer["certified"] and answer["clearance"] == answer["trajectory"]["clearance"] == 0.004
    assert "clearance must be" in str(pytest.raises(UserError, PlanSettings, clearance=0).value)


def test_an_edge_proved_to_keep_a_smaller_clearance_is_proved_again_for_a_larger_one(oracles):
    roadmap = Roadmap(oracles("bar").context(), k=8, lazy=True)
    roadmap.mark_proved([(0, 1), None, (2, 3)], 1e-3)
    roadmap.mark_proved([(2, 3)], 1e-5)  # the larger proof stands
    assert roadmap.proved_with([(0, 1), (1, 2), None, (2, 3)], 1e-3).tolist() == [True, False, False, True]
    assert not roadmap.proved_with([(0, 1), (2, 3)], 1e-2).any()


def test_the_default_budget_is_counted_in_checks_so_answers_do_not_depend_on_the_machine():
    from app.planning.settings import DEFAULT_BUDGET

    assert PlanSettings().budget == DEFAULT_BUDGET and DEFAULT_BUDGET.checks is not None
    # its seconds are a safety net far beyond what the checks take on this project's 2-core machines
    assert DEFAULT_BUDGET.seconds is None or DEFAULT_BUDGET.seconds >= DEFAULT_BUDGET.checks / 1000
