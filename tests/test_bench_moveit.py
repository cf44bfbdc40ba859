"""`bench moveit` (app.bench.moveit): MoveIt problem folders found by pairs, both methods through one checker under
one check budget, paired medians, and the report by its schema."""

import json
import shutil
from pathlib import Path

import pytest

from app.bench.moveit import EXAMPLES, PANDA, RRT, Robot, _problem, find_problems, specs, summarise
from app.errors import UserError
from app.planning.moveit import goal_configurations

SCHEMAS = Path(__file__).resolve().parent.parent / "docs" / "schemas"
ROBOT = Robot(PANDA / "panda.urdf", PANDA / "panda.srdf")


def copy_problem(kind: str, number: str, folder: Path) -> None:
    (folder / kind).mkdir(parents=True, exist_ok=True)
    for part in ("scene", "request"):
        shutil.copy(EXAMPLES / kind / f"{part}{number}.yaml", folder / kind)


def test_problems_are_pairs_by_kind_and_number(tmp_path):
    copy_problem("box", "0002", tmp_path)
    copy_problem("box", "0001", tmp_path)
    copy_problem("cage", "0001", tmp_path)
    (tmp_path / "cage" / "request0009.yaml").write_text("{}")  # no scene beside it: not a problem
    found = find_problems(tmp_path)
    assert [p.name for p in found] == ["box/0001", "box/0002", "cage/0001"]
    assert [p.name for p in find_problems(tmp_path, per_kind=1)] == ["box/0001", "cage/0001"]
    assert len(find_problems(EXAMPLES)) == 70
    with pytest.raises(UserError, match="no folder"):
        find_problems(tmp_path / "none")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(UserError, match="no MoveIt problems"):
        find_problems(empty)


def test_a_changed_problem_file_is_another_trial(tmp_path):
    copy_problem("box", "0001", tmp_path)
    before = specs(find_problems(tmp_path), ROBOT, ["ours"], 1, 1000)[0].key
    request = tmp_path / "box" / "request0001.yaml"
    request.write_text(request.read_text().replace("allowed_planning_time: 60", "allowed_planning_time: 30"))
    assert specs(find_problems(tmp_path), ROBOT, ["ours"], 1, 1000)[0].key != before


def test_medians_are_paired_over_the_problems_both_methods_solved():
    def row(name, method, solved, checks, seconds, colliding=0.0):
        metrics = {"solved": solved, "checks": checks, "seconds": seconds, "colliding": colliding}
        return {"scene": name, "method": method, "metrics": metrics, "code_version": "v"}

    rows = [
        row("a/1", "ours", 1.0, 100, 1.0),
        row("a/1", RRT, 1.0, 400, 2.0, colliding=1.0),
        row("a/2", "ours", 1.0, 300, 3.0),
        row("a/2", RRT, 0.0, 1000, 9.0),  # not solved by both: out of the medians
        row("b/1", "ours", 1.0, 200, 1.0),
        row("b/1", RRT, 1.0, 200, 4.0),
    ]
    kinds = {k["kind"]: k for k in summarise(rows, ["ours", RRT])["kinds"]}
    every = kinds["all"]
    assert every["both_solved"] == 2 and every["ours"]["solved"] == 3 and every[RRT]["solved"] == 2
    assert every["ours"]["median_checks"] == 150 and every[RRT]["median_checks"] == 300
    assert every["ratio"]["checks"] == 0.5 and every["ratio"]["seconds"] == 1.0 / 3.0
    assert every[RRT]["colliding"] == 1 and kinds["b"][RRT]["colliding"] == 0
    assert kinds["a"]["both_solved"] == 1 and kinds["a"]["ours"]["median_seconds"] == 1.0


def test_rrt_connect_stops_at_its_check_budget():
    from app.ompl_bridge import OmplProblem

    (spec,) = specs(find_problems(EXAMPLES / "cage", per_kind=1), ROBOT, [RRT], 1, 300)
    problem, oracle = _problem(spec.params, 1)
    ompl = OmplProblem(oracle, seed=0, planner="RRTConnect")
    ompl.set_query(problem.start, goal_configurations(oracle, problem))
    assert not ompl.solve(600.0, checks=300)  # the cage is not solved in 300 checks
    assert 300 <= ompl.checker.checks <= 400


def test_bench_moveit_answers_by_its_schema_and_reuses_its_trials(tmp_path, run_app):
    folder = tmp_path / "problems"
    copy_problem("table_pick", "0001", folder)
    copy_problem("bookshelf_thin", "0001", folder)
    args = ["bench", "moveit", folder, "--checks", "50000", "--store", tmp_path / "m.sqlite", "--json"]
    first = run_app(*args, "--png", tmp_path / "m.png")
    assert first.returncode == 0, first.stderr[-2000:]
    answer = json.loads(first.stdout)
    jsonschema = pytest.importorskip("jsonschema")
    jsonschema.validate(answer, json.loads((SCHEMAS / "bench-moveit.json").read_text()))
    every = answer["kinds"][0]
    assert every["kind"] == "all" and every["problems"] == 2
    assert every["ours"]["solved"] == every["ours"]["certified"] == 2 and every["ours"]["colliding"] == 0
    assert all(t["checks"] <= 50_000 + 100 for t in answer["trials"] if t["method"] == RRT)
    assert (tmp_path / "m.png").stat().st_size > 0
    again = run_app(*args)
    assert again.returncode == 0, again.stderr[-2000:]
    reused = json.loads(again.stdout)
    assert reused["reused"]["reused"] == 4
    assert reused["trials"] == answer["trials"]


def test_a_method_that_crashes_is_a_named_failure_the_table_counts(tmp_path, monkeypatch):
    """An unexpected error inside one method's run (as Drake's Toppra once raised on one problem) is that trial's
    failure, with the error named, and the run goes on; the table says how many crashed."""
    from app.bench import moveit

    def crash(*args):
        raise RuntimeError("Failure at toppra.cc:85 in\nthe grid's last point")

    monkeypatch.setattr(moveit, "_ours", crash)
    copy_problem("box", "0001", tmp_path)
    spec = specs(find_problems(tmp_path), ROBOT, ["ours"], 1, 1000)[0]
    metrics = moveit.run_trial_spec(spec)
    assert (
        metrics["solved"] == 0.0
        and metrics["crashed"] == "RuntimeError: Failure at toppra.cc:85 in the grid's last point"
    )
    rows = [{"scene": "box/0001", "method": m, "metrics": metrics if m == "ours" else {"solved": 1.0, "checks": 9,
             "seconds": 1.0}, "code_version": "v"} for m in ("ours", RRT)]  # fmt: skip
    report = summarise(rows, ["ours", RRT])
    assert report["kinds"][0]["ours"]["crashed"] == 1 and report["kinds"][0][RRT]["crashed"] == 0
    text = moveit.table({**report, "methods": ["ours", RRT], "problems": 1, "folder": "f", "seeds": 1, "checks": 1000})
    assert "| 0 (1 crashed), 1 |" in text
