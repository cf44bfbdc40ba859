"""Every command's --json answer, success and failure, against the schemas the docs point to (docs/schemas/):
one JSON object on stdout, whatever happens."""

import json
from pathlib import Path

import pytest

jsonschema = pytest.importorskip("jsonschema")

SCHEMAS = Path(__file__).resolve().parent.parent / "docs" / "schemas"


def schema(name: str) -> dict:
    document = json.loads((SCHEMAS / f"{name}.json").read_text())
    jsonschema.Draft202012Validator.check_schema(document)
    return document


def answer(stdout: str) -> dict:
    """The one JSON object a --json command printed (and nothing else on stdout)."""
    lines = stdout.strip().splitlines()
    assert len(lines) == 1, stdout[:500]
    return json.loads(lines[0])


def check(result, name: str, exit_code: int = 0) -> dict:
    assert result.returncode == exit_code, result.stderr[-2000:]
    obj = answer(result.stdout)
    jsonschema.validate(obj, schema(name if exit_code == 0 else "failure"))
    return obj


def test_the_docs_point_to_every_schema():
    pages = "".join(page.read_text() for page in SCHEMAS.parent.glob("*.md"))
    for path in SCHEMAS.glob("*.json"):
        assert f"(schemas/{path.name})" in pages, path.name


# Cheap arguments: each runs in a few seconds.
CHEAP = [
    ("scenes", ["scenes"]),
    ("show", ["show", "bar", "--png", "{tmp}/bar.png"]),
    ("sample", ["sample", "bar", "--sampler", "lfbs", "-k", "5"]),
    ("bench-oracle", ["bench", "oracle", "--scenes", "bar", "-n", "100", "--repeats", "1"]),
    (
        "bench-sampling",
        [
            "bench",
            "sampling",
            "--scenes",
            "bar",
            "--samplers",
            "uniform,rbbs",
            "--steps",
            "10",
            "--trials",
            "2",
            "-k",
            "3",
        ],
    ),
    (
        "bench-plan",
        ["bench", "plan", "--scenes", "bar", "--samplers", "lfbs", "--seeds", "1", "--store", "{tmp}/plan.sqlite"],
    ),
    (
        "bench-queries",
        [
            "bench",
            "queries",
            "--scenes",
            "bar-3link",
            "--queries",
            "3",
            "--methods",
            "fresh,cell",
            "--build-nodes",
            "60",
            "--store",
            "{tmp}/q.sqlite",
        ],
    ),  # fmt: skip
    (
        "bench-certify",
        ["bench", "certify", "--scenes", "bar-3link", "--jobs", "welding", "--seeds", "1", "--store", "{tmp}/c.sqlite"],
    ),
    (
        "bench-audit",
        [
            "bench",
            "audit",
            "--scenes",
            "bar-3link",
            "--problems",
            "1",
            "--checks",
            "20000",
            "--no-bad-input",
            "--store",
            "{tmp}/a.sqlite",
        ],  # fmt: skip
    ),
    (
        "bench-paper",
        [
            "bench",
            "paper",
            "--out",
            "{tmp}/paper",
            "--parts",
            "sampling",
            "--scenes",
            "bar-3link",
            "--samplers",
            "uniform",
            "--steps",
            "10",
            "--trials",
            "1",
            "--workers",
            "1",
        ],
    ),
    (
        "bench-ablation",
        [
            "bench",
            "ablation",
            "--scenes",
            "bar",
            "--variants",
            "default,lfbs-alone",
            "--seeds",
            "2",
            "--checks",
            "20000",
            "--out",
            "{tmp}/ablation",
            "--store",
            "{tmp}/ablation.sqlite",
        ],
    ),
]
# Minutes rather than seconds (IK, several planned legs, OMPL, the paper's UAV roadmaps).
COSTLY = [
    ("run", ["run", "window", "--narrow", "20", "--uniform", "20"]),
    (
        "bench-jobs",
        ["bench", "jobs", "--jobs", "window", "--seeds", "1", "--roadmap", "query", "--store", "{tmp}/j.sqlite"],
    ),
    (
        "bench-ompl",
        [
            "bench", "ompl", "--scenes", "bar", "--methods", "ours:default,ompl:RRTConnect", "--seeds", "1",
            "--budget", "2", "--store", "{tmp}/o.sqlite",
        ],
    ),
    ("bench-uav", ["bench", "uav", "--seeds", "1", "--store", "{tmp}/u.sqlite"]),
]  # fmt: skip


def _run(cli, tmp_path, name, argv):
    if name == "bench-ompl":
        pytest.importorskip("ompl")
    return check(cli(*[a.format(tmp=tmp_path) for a in argv], "--json"), name)


@pytest.mark.parametrize("name, argv", CHEAP, ids=[name for name, _ in CHEAP])
def test_success_answers_follow_their_schema(cli, tmp_path, name, argv):
    obj = _run(cli, tmp_path, name, argv)
    assert obj["success"] is True


@pytest.mark.slow
@pytest.mark.parametrize("name, argv", COSTLY, ids=[name for name, _ in COSTLY])
def test_costly_success_answers_follow_their_schema(cli, tmp_path, name, argv):
    assert _run(cli, tmp_path, name, argv)["success"] is True


def test_plan_and_view_answers_follow_their_schemas(cli, tmp_path, monkeypatch):
    monkeypatch.setenv("DRAKE_ALLOW_NETWORK", "meshcat")  # the viewer's Meshcat needs it, even to export
    trajectory, page = tmp_path / "bar.json", tmp_path / "bar.html"
    planned = check(cli("plan", "bar", "--out", trajectory, "--json"), "plan")
    assert planned["certified"] == planned["trajectory"]["certified"] and trajectory.is_file()
    written = json.loads(trajectory.read_text())
    jsonschema.validate(written, schema("trajectory"))
    # The schema refuses what the reader refuses: a misspelt key, a missing one, a sample of the wrong shape.
    for broken in ({**written, "velocity": []}, {k: v for k, v in written.items() if k != "certified"},
                   {**written, "positions": [[1.0, "x"]]}):  # fmt: skip
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate(broken, schema("trajectory"))
    shown = check(cli("view", "bar", "--trajectory", trajectory, "--html", page, "--json"), "view")
    assert shown["html"] == str(page) and page.is_file() and shown["meshcat"] is None


def test_gui_answer_and_state_file_follow_their_schema(cli, tmp_path, monkeypatch):
    monkeypatch.setenv("DRAKE_ALLOW_NETWORK", "meshcat")
    state, page = tmp_path / "state.json", tmp_path / "panel.html"
    answer = check(cli("gui", "bar-3link", "--wait", "0", "--state", state, "--html", page, "--json"), "gui")
    assert answer["html"] == str(page) and page.is_file() and answer["last"] is None
    kept = json.loads(state.read_text())
    jsonschema.validate(kept, schema("gui"))
    assert kept == {k: v for k, v in answer.items() if k not in ("success", "html")}


def test_roadmap_build_and_info_answer_the_same_object_by_their_schema(cli, tmp_path):
    """`roadmap build --json` answers what it wrote; `roadmap info --json` of that file answers the same object."""
    from app.planning.roadmap_file import FINGERPRINT_PARTS

    file = tmp_path / "bar.npz"
    built = check(cli("roadmap", "build", "bar", "--out", file, "--nodes", "60", "--json"), "roadmap")
    assert file.is_file() and built["file"] == str(file) and built["nodes"] >= 60
    assert sum(built["nodes_by_kind"].values()) == built["nodes"] and sum(built["edges"].values()) > 0
    (record,) = built["provenance"]["builds"]
    assert record["ended"] == "nodes" and record["settings"]["nodes"] == 60 and record["nodes"] == 60
    (covered,) = built["provenance"]["covered"]  # the scene's own query, answered on the roadmap
    assert covered["what"] == "query" and built["provenance"]["queries"] == 1
    assert tuple(built["fingerprint"]) == FINGERPRINT_PARTS
    assert check(cli("roadmap", "info", file, "--json"), "roadmap") == built
    # `roadmap update` answers the repaired file's object, with its repair, which `roadmap info` then lists
    change = tmp_path / "change.yaml"
    change.write_text("remove: [box0]\n")
    updated = check(cli("roadmap", "update", file, "--change", change, "--json"), "roadmap")
    (repair,) = updated["provenance"]["changes"]
    assert updated.pop("repair") == repair and repair["described"] == "remove box0"
    assert check(cli("roadmap", "info", file, "--json"), "roadmap") == updated


# One failure per command (most refused before any work), and the planner's own failures.
FAILURES = [
    (["scenes", "--verbose"], 2, "INVALID_INPUT"),
    (["show", "nowhere", "--png", "{tmp}/x.png"], 2, "INVALID_INPUT"),
    (["sample", "bar", "--sampler", "lfbs", "-k", "0"], 2, "INVALID_INPUT"),
    (["plan", "bar", "--start", "50,30,0,0,0,0,0,0,0"], 3, "START_STATE_IN_COLLISION"),
    (["plan", "joint3d", "--sampler", "uniform", "--narrow", "0", "--budget", "2000checks"], 1, "PLANNING_FAILED"),
    (["run", "painting"], 2, "INVALID_INPUT"),
    (["view", "bar", "--trajectory", "{tmp}/missing.json", "--html", "{tmp}/x.html"], 2, "INVALID_INPUT"),
    (["gui", "nowhere"], 2, "INVALID_INPUT"),
    (["gui", "bar", "--sampler", "nope"], 2, "INVALID_INPUT"),
    (["roadmap", "build", "nowhere", "--out", "{tmp}/r.npz"], 2, "INVALID_INPUT"),
    (["roadmap", "info", "{tmp}/missing.npz"], 2, "INVALID_INPUT"),
    (["roadmap", "update", "{tmp}/missing.npz", "--change", "{tmp}/missing.yaml"], 2, "INVALID_INPUT"),
    (["roadmap"], 2, "INVALID_INPUT"),
    (["bench", "oracle", "-n", "0"], 2, "INVALID_INPUT"),
    (["bench", "sampling", "--png", "{tmp}"], 2, "INVALID_INPUT"),
    (["bench", "plan", "--store", "{tmp}"], 2, "INVALID_INPUT"),
    (["bench", "uav", "--workers", "0"], 2, "INVALID_INPUT"),
    (["bench", "jobs", "--jobs", "painting"], 2, "INVALID_INPUT"),
    (["bench", "ompl", "--seeds", "0"], 2, "INVALID_INPUT"),
    (["bench", "paper", "--out", "/proc/paper"], 2, "INVALID_INPUT"),
    (["bench", "paper", "--out", "{tmp}/paper", "--ompl-db", "{tmp}"], 2, "INVALID_INPUT"),
    (["bench", "certify", "--seeds", "0"], 2, "INVALID_INPUT"),
    (["bench", "audit", "--store", "{tmp}"], 2, "INVALID_INPUT"),
    (["bench", "queries", "--methods", "fresh,ompl-prm"], 2, "INVALID_INPUT"),
    (["bench", "queries", "--budget", "0checks"], 2, "INVALID_INPUT"),
    (["bench", "ablation", "--variants", "default,nope"], 2, "INVALID_INPUT"),
    (["bench", "ablation", "--store", "{tmp}"], 2, "INVALID_INPUT"),
    (["bench"], 2, "INVALID_INPUT"),
    (["no-such-command"], 2, "INVALID_INPUT"),
]


@pytest.mark.parametrize("argv, exit_code, code", FAILURES, ids=[" ".join(argv[:2]) for argv, _, _ in FAILURES])
def test_failure_answers_follow_the_failure_schema(cli, tmp_path, argv, exit_code, code):
    result = cli(*[a.format(tmp=tmp_path) for a in argv], "--json")
    obj = check(result, "failure", exit_code)
    assert obj["error"]["code"] == code and obj["exit_code"] == exit_code
    assert result.stderr == f"error: {obj['error']['message']}\n"


def test_an_internal_error_still_answers_one_object(capsys, monkeypatch):
    """A bug is not bad input: its traceback stays, and a --json reader still gets its one answer."""
    import app.commands.scenes
    from app.cli import main

    def broken(name):
        raise RuntimeError("boom")

    monkeypatch.setattr(app.commands.scenes, "Scene", broken)
    capsys.readouterr()
    with pytest.raises(RuntimeError, match="boom"):
        main(["scenes", "--json"])
    obj = answer(capsys.readouterr().out)
    jsonschema.validate(obj, schema("failure"))
    assert obj["error"] == {"code": "FAILURE", "message": "internal error: RuntimeError: boom"}


# ---- what a failed or interrupted query spent --------------------------------------------------------------------
PHASES = {"sampling", "roadmap", "search", "smoothing", "certify", "timing"}


def _spent(details: dict, stopped: str) -> None:
    """`details` count what the query spent as a success answer counts it, and say why it stopped."""
    assert details["stopped"] == stopped and details["rounds"] >= 1
    assert details["collision_checks"] == sum(details["checks"].values()) > details["checks"]["endpoints"]
    assert set(details["checks"]) == {"endpoints", *PHASES} and set(details["seconds"]) == {*PHASES, "total"}
    assert details["distance_queries"] >= 0 and details["roadmap"]["nodes"] >= 2


def test_a_spent_check_budget_answers_planning_failed_with_what_it_spent(cli):
    """Not TIMED_OUT, which is MoveIt's code for time: the check limit ran out, the details say so (stopped:
    "checks"), and the message names a larger budget."""
    argv = ["plan", "joint3d", "--sampler", "uniform", "--narrow", "0", "--budget", "2000checks", "--json"]
    failed = check(cli(*argv), "failure", 1)
    assert failed["error"]["code"] == "PLANNING_FAILED"
    assert "budget of 2000 collision checks spent (stopped: checks)" in failed["error"]["message"]
    assert "try --budget 20kchecks" in failed["error"]["message"]
    _spent(failed["details"], "checks")
    assert failed["details"]["collision_checks"] >= 2000 and failed["details"]["budget"] == "600s,2000checks"


def test_ctrl_c_during_plan_answers_preempted_with_what_the_query_spent(cli, monkeypatch):
    """Ctrl-C after the query's first round: exit code 130 and PREEMPTED, with the query's figures. The interrupt is
    sent by the process to itself from inside the query, so where it lands does not depend on timing."""
    import os
    import signal

    from app.planning.query import Query

    grow = Query.grow

    def grow_then_ctrl_c(self, *sizes):
        new = grow(self, *sizes)
        os.kill(os.getpid(), signal.SIGINT)
        return new

    monkeypatch.setattr(Query, "grow", grow_then_ctrl_c)
    result = cli("plan", "joint3d", "--sampler", "uniform", "--narrow", "0", "--json")
    interrupted = check(result, "failure", 130)
    assert interrupted["error"] == {"code": "PREEMPTED", "message": "interrupted"}
    assert result.stderr == "error: interrupted\n"
    _spent(interrupted["details"], "interrupted")
    assert interrupted["details"]["rounds"] == 1


def test_a_custom_scene_answers_its_meshes_and_load_time_on_failure_as_on_success(cli, tmp_path, monkeypatch):
    """plan --robot/--env: the answer names each mesh's decomposition and what loading the scene took, whether the
    query found its path or spent its budget (1 check: spent before the first edge)."""
    trimesh = pytest.importorskip("trimesh")
    monkeypatch.setenv("NPP_CACHE_DIR", str(tmp_path / "cache"))
    trimesh.creation.box([0.6, 0.6, 0.6]).export(tmp_path / "cube.obj")
    trimesh.creation.box([1.0, 1.0, 1.0]).export(tmp_path / "block.stl")
    argv = ["plan", "--robot", tmp_path / "cube.obj", "--env", tmp_path / "block.stl", "--bounds=-3..3,-2..2,-2..3"]
    argv += ["--start=-2.5,1.5,2.1,0,0,0", "--goal=2.5,-1.5,0.9,0,0,0", "--json"]
    planned = check(cli(*argv), "plan")
    failed = check(cli(*argv, "--budget", "1checks"), "failure", 1)
    assert failed["error"]["code"] == "PLANNING_FAILED" and failed["details"]["stopped"] == "checks"
    for answer in (planned, failed["details"]):
        assert sorted(Path(mesh["mesh"]).name for mesh in answer["meshes"]) == ["block.stl", "cube.obj"]
        assert set(answer["scene_seconds"]) == {"prepare", "drake_load"}
        assert all(seconds > 0 for seconds in answer["scene_seconds"].values())
