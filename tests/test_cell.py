"""The cell roadmap (app.planning.cell): built once, it answers many queries and keeps what they learn; saved, it
loads back only into the cell it was built for and answers as the one in memory does."""

import dataclasses
import json
import re

import numpy as np
import pytest

from app.checking.budget import Budget
from app.errors import NoPath, UserError
from app.planning.cell import BuildSettings, CellRoadmap
from app.planning.roadmap_file import read
from app.planning.settings import PlanSettings
from app.scene.files import SCENES_DIR

SMALL = BuildSettings(nodes=250, seed=0)  # one build round on bar: a few seconds
QUERY = PlanSettings(seed=0, budget=Budget(checks=200_000))


@pytest.fixture(scope="module")
def bar_file(oracles, tmp_path_factory):
    """A small bar roadmap, saved once for the module."""
    path = tmp_path_factory.mktemp("cell") / "bar.npz"
    CellRoadmap.build(oracles("bar"), SMALL).save(path)
    return path


def _pairs(nodes) -> set:
    return {(min(a, b), max(a, b)) for a, b in zip(nodes[:-1], nodes[1:])}


def _queries(oracle, n: int, seed: int) -> list:
    """n pairs of free configurations of the oracle's scene."""
    rng, checker = np.random.default_rng(seed), oracle.context()
    Q = oracle.space.uniform(rng, 40 * n)
    Q = Q[checker.are_free(Q)]
    return [(Q[2 * i], Q[2 * i + 1]) for i in range(n)]


def test_a_loaded_roadmap_answers_as_the_one_in_memory(oracles, tmp_path):
    oracle = oracles("bar")
    kept = CellRoadmap.build(oracle, SMALL)  # never saved before its queries
    kept.save(tmp_path / "bar.npz")
    loaded = CellRoadmap.load(tmp_path / "bar.npz", oracle)
    for start, goal in _queries(oracle, 3, seed=1):
        a, b = kept.solve(start, goal, QUERY), loaded.solve(start, goal, QUERY)
        assert np.array_equal(a.path, b.path) and a.collision_checks == b.collision_checks
    # what the queries learned survives a save and a load too, but for their proofs: a file's are not trusted
    again = tmp_path / "again.npz"
    kept.save(again)
    kept_info, again_info = kept.info(), CellRoadmap.load(again, oracle).info()
    kept_edges, again_edges = dict(kept_info["edges"]), dict(again_info["edges"])
    assert kept_edges.pop("certified") > 0 == again_edges.pop("certified")
    kept_edges["free"] += kept_info["edges"]["certified"]
    assert kept_edges == again_edges and kept_info["nodes"] == again_info["nodes"]


def test_the_same_query_again_costs_fewer_checks_and_decides_no_edge_twice(oracles, bar_file):
    oracle = oracles("bar")
    cell = CellRoadmap.load(bar_file, oracle)
    first = cell.solve(settings=QUERY)
    decided = cell.graph.edges_tried
    second = cell.solve(settings=QUERY)
    assert first.certified and second.certified
    assert second.collision_checks < first.collision_checks
    assert second.stats.rounds == 0  # answered from the roadmap: no sample drawn
    assert cell.graph.edges_tried == decided  # every edge the second query used was decided by the first


def test_a_query_reports_its_own_certificate_time_not_the_cells(oracles, bar_file):
    """The cell's certifier (its cached distances) serves every query on it; each answer's certificate_seconds is
    what its own proofs took, within its certify and timing phases."""
    cell = CellRoadmap.load(bar_file, oracles("bar"))
    for _ in range(3):
        r = cell.solve(settings=QUERY)
        assert 0 < r.stats.certificate_seconds <= r.stats.seconds.certify + r.stats.seconds.timing


def test_samples_a_hard_query_adds_stay_for_the_next(oracles):
    """The samples it joined by free edges stay, with its start and goal; those it never joined leave (the answer's
    nodes are those of the roadmap kept)."""
    from app.planning.roadmap import GOAL, START

    oracle = oracles("bar")
    cell = CellRoadmap.build(oracle, BuildSettings(nodes=20, seed=0))  # far too few to cross the wall
    result = cell.solve(settings=QUERY)
    assert result.certified and result.stats.rounds > 0 and len(cell) > 22
    kinds, joined = np.array(cell.graph.kinds[20:]), cell.graph.joined_nodes()[20:]
    assert {START, GOAL} <= set(kinds) and joined[~np.isin(kinds, [START, GOAL])].all()
    assert result.stats.roadmap.nodes > len(cell)  # some left
    assert np.array_equal(cell.graph.Q[result.path_nodes], result.roadmap_path)
    size = len(cell)
    again = cell.solve(settings=QUERY)
    assert again.stats.rounds == 0 and len(cell) == size and again.collision_checks < result.collision_checks


def test_a_query_on_a_stored_roadmap_draws_what_a_fresh_one_draws_and_adds_no_node_twice(oracles):
    """Its graph is the fresh query's and more in every round: the same samples, on top of the roadmap's, and every
    edge the fresh query's roadmap proposes between them."""
    from app.planning.query import Query

    oracle = oracles("bar")
    cell = CellRoadmap.build(oracle, BuildSettings(nodes=250, seed=1))  # (seed 0's samples would be the query's)
    n, before = len(cell), cell.graph.arrays()
    stored, fresh = Query(oracle, QUERY, roadmap=cell.graph), Query(oracle, QUERY)
    rounds = []
    for _ in range(2):
        stored.grow(5, 30, stored.stop)
        fresh.grow(5, 30, fresh.stop)
        rounds.append(stored.roadmap.Q[n + sum(map(len, rounds)) :])
    assert len(fresh.roadmap) > 40 and np.array_equal(stored.roadmap.Q[n + 2 :], fresh.roadmap.Q[2:])
    # Its start and goal are the fresh query's nodes 0 and 1. Nearest neighbours sought among all nodes alone would
    # crowd out some of the fresh query's edges with the roadmap's nodes.
    theirs = {tuple(e) for e in (fresh.roadmap.arrays()["ends"] + n).tolist()}
    ours = {tuple(e) for e in stored.roadmap.arrays()["ends"].tolist()}
    among_all = {tuple(e) for e in _proposed_among_all(oracle, before, rounds).tolist()}
    assert theirs <= ours and not theirs <= among_all
    # and the pockets it grows out of are the fresh query's
    assert [p.tolist() for p in stored._pockets()] == [p.tolist() for p in fresh._pockets()]
    size = len(cell.graph)
    again = Query(oracle, QUERY, roadmap=cell.graph)  # the same query again: its start, goal and samples are there
    again.grow(5, 30, again.stop)
    assert len(cell.graph) == size


def test_a_query_on_a_stored_roadmap_connects_no_later_than_the_fresh_one_for_no_more_sampling(oracles):
    """The fresh query's roadmap beside it decides when narrow samples join and where pockets grow, and its edges
    are the stored roadmap's: the query takes no more rounds and draws no more. On this maze roadmap of uniform
    samples (none in the window), neighbours sought among all nodes alone took 12 rounds and 15 times the fresh
    query's checks."""
    from app.planning.query import Query

    oracle = oracles("maze")
    cell = CellRoadmap.build(oracle, BuildSettings(nodes=400, narrow=0.0, seed=1))
    stored, fresh = Query(oracle, QUERY, roadmap=cell.graph).solve(), Query(oracle, QUERY).solve()
    assert fresh.stats.rounds >= 2  # not answered by the straight motion or a first round
    assert stored.stats.rounds <= fresh.stats.rounds
    assert stored.stats.checks.sampling <= fresh.stats.checks.sampling
    assert stored.stats.narrow_from_round in (None, fresh.stats.narrow_from_round)
    assert stored.collision_checks <= 1.1 * fresh.collision_checks


def _proposed_among_all(oracle, arrays, rounds):
    """The edges a roadmap (as `arrays`) proposes when each round's nodes (configurations) join it in turn, connected to
    their nearest among all its nodes."""
    from app.planning.roadmap import UNIFORM, Roadmap

    copy = Roadmap.from_arrays(oracle.context(), arrays)
    for Q in rounds:
        copy.connect(copy.add(Q, UNIFORM, connect=False))
    return copy.arrays()["ends"]


def test_a_failed_query_takes_its_samples_away_and_keeps_its_verdicts(oracles):
    """A query that spends its budget without a path leaves the roadmap its nodes and edges as they were, plus the
    verdicts it reached on edges between them; the next query is answered as on a roadmap it never touched."""
    oracle = oracles("bar")
    cell = CellRoadmap.build(oracle, BuildSettings(nodes=20, seed=0))  # far too few to cross the wall
    size, checked = len(cell), len(cell.graph.edges(checked=True))
    with pytest.raises(NoPath):
        cell.solve(settings=dataclasses.replace(QUERY, budget=Budget(checks=1000)))
    assert len(cell) == size and len(cell.graph.Q) == size and len(cell.graph.kinds) == size
    assert (cell.graph.edges() < size).all() and len(cell.graph.edges(checked=True)) >= checked
    untouched = CellRoadmap.build(oracle, BuildSettings(nodes=20, seed=0))
    after, fresh = cell.solve(settings=QUERY), untouched.solve(settings=QUERY)
    assert after.certified and fresh.certified and after.collision_checks <= fresh.collision_checks


def test_an_edge_known_to_collide_is_never_used_or_checked_again(oracles, bar_file):
    oracle = oracles("bar")
    cell = CellRoadmap.load(bar_file, oracle)
    first = cell.solve(settings=QUERY)
    a, b = sorted(first.path_nodes[1:3])  # a roadmap edge the answer used, away from the endpoints
    cell.graph.remove_edge(a, b)  # as if it had been found to collide
    second = cell.solve(settings=QUERY)
    assert (a, b) not in _pairs(second.path_nodes)
    assert (a, b) not in {tuple(e) for e in cell.graph.candidates(np.array([a, b]))}


def test_components_counted_again_after_an_edge_leaves_are_those_the_free_edges_make(oracles, bar_file):
    """The skip-connected rule's components, rebuilt in one pass after an edge leaves, partition the nodes as joining
    the remaining free edges one by one does; and later joins keep working on them."""
    from app.planning.graph import joined_labels

    cell = CellRoadmap.load(bar_file, oracles("bar"))
    graph, edges = cell.graph, cell.graph.edges(checked=True)
    a, b = edges[len(edges) // 2]
    graph.remove_edge(a, b)
    joined = np.arange(len(graph.Q))
    for u, v in graph.edges(checked=True).tolist():
        joined = joined_labels(joined, np.array([[u, v]]))
    recounted = graph._free
    partition = {}
    for node in range(len(graph.Q)):
        partition.setdefault(recounted[node], set()).add(joined[node])
    assert all(len(roots) == 1 for roots in partition.values())
    assert len(partition) == len(set(joined.tolist())) > 1
    later = joined_labels(recounted, np.array([[a, b]]))
    assert later[a] == later[b]


def test_any_of_several_goals_may_be_reached_and_bad_ones_are_left_out(oracles, bar_file):
    oracle = oracles("bar")
    cell = CellRoadmap.load(bar_file, oracle)
    scene = oracle.scene
    inside_wall = scene.goal.copy()
    inside_wall[:2] = [50.0, 20.0]  # the base in the wall
    far = _queries(oracle, 1, seed=5)[0][0]
    result = cell.solve(scene.start, [inside_wall, far, scene.goal], QUERY)
    assert any(np.allclose(result.goal, g) for g in (far, scene.goal))
    assert np.allclose(oracle.space.difference(result.path[-1], result.goal), 0)


def test_a_roadmap_is_the_same_built_on_one_process_or_two(monkeypatch, two_cores):
    import app.checking.helpers as module
    from app.checking.oracle import CollisionOracle
    from app.scene.model import Scene

    oracle = CollisionOracle(Scene("bar"), threads=2)
    one = CellRoadmap.build(oracle, SMALL, workers=1)
    shared = []  # the helper's share of each round's edges: (edges, checks)
    spread = module.Helpers.edges_free

    def counted(self, Q1, Q2, resolution, here):
        mine = []
        free, checks = spread(self, Q1, Q2, resolution, lambda A, B: mine.append(len(A)) or here(A, B))
        shared.append((len(Q1) - sum(mine), checks))
        return free, checks

    monkeypatch.setattr(module.Helpers, "edges_free", counted)
    nothing = np.empty((0, oracle.space.dim))
    assert oracle.spread_edges(oracle.context(), nothing, nothing, oracle.space.resolution).shape == (0,)  # a round
    two = CellRoadmap.build(oracle, SMALL, workers=2)
    assert sum(edges for edges, _ in shared) > 0 and sum(checks for _, checks in shared) > 0  # the helper took part
    assert two.provenance["builds"][-1]["collision_checks"] == one.provenance["builds"][-1]["collision_checks"]
    one, two = one.graph.arrays(), two.graph.arrays()
    for key in one:
        assert np.array_equal(one[key], two[key]), key


def test_a_roadmap_of_another_scene_is_refused(oracles, bar_file):
    with pytest.raises(UserError, match="built for another cell .* robot"):
        CellRoadmap.load(bar_file, oracles("bar-3link"))


def _bar_copy(folder, obstacles: str):
    """bar's scene files in `folder`, with the obstacles file's text `obstacles`."""
    (folder / "obstacles.sdf").write_text(obstacles)
    dmd = (SCENES_DIR / "bar.dmd.yaml").read_text()
    (folder / "bar.dmd.yaml").write_text(
        dmd.replace("package://npp_scenes/bar_obstacles.sdf", f"file://{folder}/obstacles.sdf")
    )
    (folder / "bar.yaml").write_text((SCENES_DIR / "bar.yaml").read_text())
    return folder / "bar.yaml"


def test_a_moved_obstacle_makes_the_roadmap_stale_and_an_unchanged_copy_does_not(bar_file, tmp_path):
    from app.checking.oracle import CollisionOracle
    from app.scene.model import Scene

    text = (SCENES_DIR / "bar_obstacles.sdf").read_text()
    same = tmp_path / "same"
    same.mkdir()
    assert len(CellRoadmap.load(bar_file, CollisionOracle(Scene(str(_bar_copy(same, text)))))) > 0
    moved = tmp_path / "moved"
    moved.mkdir()
    pose = re.search(r"<pose>([^<]+)</pose>", text)
    numbers = pose.group(1).split()
    numbers[0] = str(float(numbers[0]) + 0.01)  # one obstacle 1 cm along x
    changed = text[: pose.start(1)] + " ".join(numbers) + text[pose.end(1) :]
    with pytest.raises(UserError, match="environment differs"):
        CellRoadmap.load(bar_file, CollisionOracle(Scene(str(_bar_copy(moved, changed)))))


def test_a_changed_srdf_makes_the_roadmap_stale(oracles, tmp_path):
    from app.checking.oracle import CollisionOracle
    from app.scene.model import Scene

    path = tmp_path / "window.npz"
    CellRoadmap.build(oracles("window"), BuildSettings(nodes=10, narrow=0.0)).save(path)
    (tmp_path / "window.dmd.yaml").write_text((SCENES_DIR / "window.dmd.yaml").read_text())
    (tmp_path / "window.yaml").write_text(re.sub(r"srdf: .*\n", "", (SCENES_DIR / "window.yaml").read_text()))
    with pytest.raises(UserError, match="collision pairs differs"):
        CellRoadmap.load(path, CollisionOracle(Scene(str(tmp_path / "window.yaml"))))


def test_a_truncated_or_damaged_file_is_refused(oracles, bar_file, tmp_path):
    data = bar_file.read_bytes()
    truncated, damaged, other = tmp_path / "truncated.npz", tmp_path / "damaged.npz", tmp_path / "other.npz"
    truncated.write_bytes(data[: len(data) // 2])
    flipped = bytearray(data)
    flipped[len(data) // 3] ^= 0xFF
    damaged.write_bytes(bytes(flipped))
    np.savez(other, Q=np.zeros((3, 9)))
    headless = tmp_path / "headless.npz"
    header, arrays = read(bar_file)
    np.savez(
        headless, header=np.array(json.dumps({"format": header["format"], "version": header["version"]})), **arrays
    )
    with pytest.raises(UserError, match="lacks its fingerprint"):
        read(headless)
    for path in (truncated, damaged):
        with pytest.raises(UserError, match="not a whole roadmap file"):
            CellRoadmap.load(path, oracles("bar"))
    with pytest.raises(UserError, match="lacks|not a roadmap file"):
        read(other)


# ---- the command line ---------------------------------------------------------------------------------------------
def test_build_info_plan_and_update_from_the_command_line(cli, tmp_path):
    import json

    path = tmp_path / "bar.npz"
    built = cli("roadmap", "build", "bar", "--out", path, "--nodes", 250, "--json")
    assert built.returncode == 0, built.stderr
    answer = json.loads(built.stdout)
    assert answer["nodes"] >= 250 and answer["edges"]["free"] > 0 and f"wrote {path}" in built.stderr
    # The build answered the scene's own query on the roadmap (bar has no job), which kept what it joined.
    assert answer["provenance"]["covered"] == [
        {"what": "query", "solved": True, "collision_checks": answer["provenance"]["covered"][0]["collision_checks"]}
    ]
    assert answer["provenance"]["queries"] == 1
    planned = cli("plan", "bar", "--roadmap", path, "--update", "--json")
    assert planned.returncode == 0, planned.stderr
    assert json.loads(planned.stdout)["certified"]
    info = json.loads(cli("roadmap", "info", path, "--json").stdout)
    assert info["provenance"]["queries"] == 2 and info["nodes"] >= answer["nodes"]  # the query was written back
    assert "covered   query: joined" in cli("roadmap", "info", path).stdout
    bare = cli("roadmap", "build", "bar", "--out", tmp_path / "bare.npz", "--nodes", 250, "--no-cover", "--json")
    assert json.loads(bare.stdout)["nodes"] == 250 and "covered" not in json.loads(bare.stdout)["provenance"]
    assert info["fingerprint"] == answer["fingerprint"]


def test_a_failed_plan_update_writes_back_what_it_decided(cli, tmp_path):
    """The query finds no path within its budget: exit 1 with the failure's one JSON object, and the file is
    written back with the query counted and every verdict kept (the query's own samples leave, as in memory)."""
    import json

    path = tmp_path / "bar.npz"
    # too few to cross the wall, and not covered (the build would answer the scene's own query)
    assert cli("roadmap", "build", "bar", "--out", path, "--nodes", 20, "--no-cover").returncode == 0
    before = json.loads(cli("roadmap", "info", path, "--json").stdout)
    failed = cli("plan", "bar", "--roadmap", path, "--update", "--budget", "1000checks", "--json")
    assert failed.returncode == 1 and json.loads(failed.stdout)["error"]["code"] == "PLANNING_FAILED"
    assert f"wrote {path}" in failed.stderr.splitlines()
    after = json.loads(cli("roadmap", "info", path, "--json").stdout)
    assert after["provenance"]["queries"] == before["provenance"]["queries"] + 1
    assert after["nodes"] == before["nodes"]
    for verdict in ("free", "colliding_or_unprovable"):
        assert after["edges"][verdict] >= before["edges"][verdict]


def test_a_query_stopped_from_outside_writes_nothing_back(tmp_path):
    """kept_on_failure saves on a failure to find a path, never on PREEMPTED (an interrupt or a cancel)."""
    from app.commands.view import kept_on_failure

    class Cell:
        saved: list = []

        def save(self, path):
            self.saved.append(path)

    cell, path = Cell(), tmp_path / "cell.npz"
    for code, saved in (("PREEMPTED", []), (None, [path])):
        Cell.saved = []
        with pytest.raises(NoPath), kept_on_failure((cell, path)):
            raise NoPath("no path", code)
        assert Cell.saved == saved
    with pytest.raises(NoPath), kept_on_failure(None):  # no --update: nothing to write
        raise NoPath("no path")


@pytest.mark.parametrize(
    "args",
    [
        ["plan", "bar-3link", "--roadmap", "{bar}"],  # built for another cell
        ["plan", "bar", "--roadmap", "{truncated}"],
        ["plan", "bar", "--update"],  # nothing to write back to
        ["plan", "bar", "--roadmap", "{bar}", "--full-roadmap"],
        ["roadmap", "info", "{missing}"],
        ["roadmap", "build", "bar", "--out", "{bar}", "--nodes", "1"],
        ["roadmap", "build", "bar", "--out", "{bar}", "--workers", "0"],
    ],
)
def test_bad_roadmap_input_fails_in_one_line_and_writes_nothing(cli, one_line_error, bar_file, tmp_path, args):
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(bar_file.read_bytes()[:1000])
    before = bar_file.read_bytes()
    names = {"bar": bar_file, "truncated": truncated, "missing": tmp_path / "missing.npz"}
    result = cli(*[a.format(**names) for a in args])
    one_line_error(result, 2)
    assert bar_file.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["truncated.npz"]


def test_a_job_runs_its_legs_on_one_roadmap_and_a_saved_one_makes_it_cheaper(oracles, tmp_path):
    from app.jobs import JOB_SETTINGS, run_job

    oracle = oracles("window")
    cell = CellRoadmap(oracle)
    first = run_job(oracle, "window", JOB_SETTINGS, cell)
    planned = [leg for leg in first.legs if leg.method == JOB_SETTINGS.sampler]
    assert len(planned) >= 2 and cell.provenance["queries"] >= len(planned)
    # A later leg found samples the earlier ones left: it added fewer than the first planned leg did (and a leg's
    # count is of what it drew, whatever left the cell after the leg before).
    assert 0 <= planned[-1].narrow_samples < planned[0].narrow_samples
    assert all(leg.narrow_samples >= 0 for leg in first.legs)
    cell.save(tmp_path / "window.npz")
    again = run_job(oracle, "window", JOB_SETTINGS, CellRoadmap.load(tmp_path / "window.npz", oracle))
    assert again.collision_checks < first.collision_checks


def test_a_covered_roadmap_answers_its_scenes_query_from_what_it_holds(oracles):
    from app.jobs import cover
    from app.planning.query import plan

    oracle = oracles("bar")
    fresh = plan(oracle, PlanSettings(seed=5))
    cell = CellRoadmap.build(oracle, BuildSettings(nodes=60, seed=0))  # too few to cross the wall on their own
    bare = CellRoadmap.build(oracle, BuildSettings(nodes=60, seed=0))
    covered = cover(cell)
    assert covered == cell.provenance["covered"] and [c["what"] for c in covered] == ["query"] and covered[0]["solved"]
    assert len(cell) > len(bare)  # the query's joined samples stayed
    answer = cell.solve(settings=PlanSettings(seed=5))
    assert answer.certified and answer.stats.checks.sampling == 0
    assert answer.collision_checks < fresh.collision_checks / 4
    assert bare.solve(settings=PlanSettings(seed=5)).stats.checks.sampling > 0


def test_a_build_reports_progress_as_each_rounds_edges_are_decided(oracles, monkeypatch):
    """A build of one round (its first 250 nodes took most of a 103 s build) reported once, at its end: a bar went
    from 0 to 83 % of 300 nodes at once. It reports after each part of a round's edges now (parts of about
    PART_SECONDS; here of FIRST_PART edges each), rising to the nodes it holds, and builds the same roadmap."""
    from app.planning import cell as cells

    whole = CellRoadmap.build(oracles("bar"), BuildSettings(nodes=40, seed=0))
    monkeypatch.setattr(cells, "PART_SECONDS", 0.0)
    monkeypatch.setattr(cells, "FIRST_PART", 8)
    reports = []
    cell = CellRoadmap.build(oracles("bar"), BuildSettings(nodes=40, seed=0), progress=lambda *r: reports.append(r))
    nodes = [n for n, _, _ in reports]
    assert len(reports) > 4 and nodes == sorted(nodes) and nodes[-1] == len(cell) == 40
    assert len(set(nodes)) > 4 and nodes[0] < 40 / 4  # through the round, not at its end
    for key, array in whole.graph.arrays().items():
        assert np.array_equal(array, cell.graph.arrays()[key]), key
    assert all(target == 40 for _, target, _ in reports)
    checks = [c for _, _, c in reports]
    assert checks == sorted(checks) and checks[-1] == cell.provenance["builds"][-1]["collision_checks"]
