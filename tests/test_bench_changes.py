"""`bench changes` (app.bench.changes): each change of a cell repaired against rebuilt, the queries after it answered
three ways (four with OMPL's PRM, its graph re-checked in the new cell) and re-checked; the report says so by its
schema."""

import json
from pathlib import Path

import numpy as np
import pytest

from app.bench.changes import CHANGES, summarise
from app.scene.changes import changed_scene

SCHEMAS = Path(__file__).resolve().parent.parent / "docs" / "schemas"


def test_every_shipped_change_applies_to_its_cell_and_leaves_the_start_free(oracles):
    for cell, changes in CHANGES.items():
        oracle = oracles(cell)
        names = [label for label, _ in changes]
        assert len(names) == len(set(names)) == 6
        for label, change in changes:
            changed = oracle.of_scene(changed_scene(oracle.scene, [change]))
            assert changed.free(changed.scene.start), (cell, label)


def test_a_changes_row_sets_repair_against_rebuild():
    def trial(prepare, seconds, ok):
        answers = [
            {"success": o, "certified": o, "checks": 10, "seconds": s, "colliding_states": 0}
            for s, o in zip(seconds, ok)
        ]
        return {"prepare": prepare, "answers": answers}

    row = summarise(
        "move",
        {
            "repair": trial({"seconds": 1.0, "checks": 3}, [0.01, 0.03, 0.02], [True, True, False]),
            "rebuild": trial({"seconds": 20.0, "checks": 300}, [0.02, 0.02, 0.02], [True, True, True]),
        },
    )
    assert row["repair_over_rebuild"] == {"checks": 0.01, "seconds": 0.05}
    assert row["methods"]["repair"]["successes"] == 2 and row["methods"]["repair"]["median_seconds"] == 0.02


@pytest.mark.slow
def test_bench_changes_answers_by_its_schema(tmp_path, run_app):
    result = run_app(
        "bench", "changes", "--scenes", "window", "--queries", "2", "--build-nodes", "100",
        "--methods", "repair,rebuild,fresh,ompl-prm", "--ompl-seconds", "2",
        "--store", tmp_path / "c.sqlite", "--json", timeout=1800,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr[-2000:]
    answer = json.loads(result.stdout)
    jsonschema = pytest.importorskip("jsonschema")
    jsonschema.validate(answer, json.loads((SCHEMAS / "bench-changes.json").read_text()))
    (scene,) = answer["scenes"]
    assert [r["change"] for r in scene["changes"]] == [label for label, _ in CHANGES["window"]]
    for row in scene["changes"]:
        assert row["repair_over_rebuild"]["checks"] < 0.1
        assert all(m["colliding_states"] == 0 for m in row["methods"].values())
        prm = row["methods"]["ompl-prm"]["prepare"]  # its whole graph checked again, where a repair checks few
        assert (
            prm["nodes"] <= prm["grown"]["nodes"] and prm["checks"] > 10 * row["methods"]["repair"]["prepare"]["checks"]
        )


def _prm_graph(problem):
    """OMPL's PRM graph as (vertices (n, dim), edges (m, 2))."""
    data = problem.ob.PlannerData(problem.si)
    problem.planner.getPlannerData(data)
    Q = np.array([problem.to_q(data.getVertex(i).getState()) for i in range(data.numVertices())])
    edges = np.array([(i, j) for i in range(data.numVertices()) for j in data.getEdges(i) if i < j]).reshape(-1, 2)
    return Q, edges


def test_ompl_prms_graph_is_grown_again_in_a_changed_cell_every_vertex_and_edge_checked(oracles):
    pytest.importorskip("ompl")
    from app.ompl_bridge import OmplProblem
    from app.scene.changes import CellChange, Placement, Solid

    base = oracles("bar")
    grown = OmplProblem(base, planner="PRM")
    grown.use_milestones()
    grown.grow(600, checks=20_000)  # (the checks end it)
    milestones = grown.milestones
    assert grown.planner.milestoneCount() == len(milestones) > 5
    same = OmplProblem(base, planner="PRM")
    same.regrow(milestones)  # in the cell it grew in: the same graph
    assert (same.planner.milestoneCount(), same.planner.edgeCount()) == (len(milestones), grown.planner.edgeCount())
    # a post on the first milestone's base: it and what else the post holds leave the graph, every edge left is free
    x, y = milestones[0][:2]
    post = CellChange(add=[Solid(name="post", box=[4.0, 4.0, 2.0], pose=Placement(xyz=[float(x), float(y), 0.0]))])
    changed = base.of_scene(changed_scene(base.scene, [post]))
    checker = changed.context()
    free = checker.are_free(np.array(milestones))
    assert not free[0]
    problem = OmplProblem(changed, planner="PRM")
    problem.regrow(milestones)
    Q, edges = _prm_graph(problem)
    assert len(Q) == problem.planner.milestoneCount() == free.sum()
    assert checker.are_free(Q).all() and len(edges)
    assert checker.edges_free(Q[edges[:, 0]], Q[edges[:, 1]], changed.space.resolution).all()
    assert problem.checker.checks >= len(milestones) + len(edges)  # each milestone and edge, re-checked
