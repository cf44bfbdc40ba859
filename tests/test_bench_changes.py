"""`bench changes` (app.bench.changes): each change of a cell repaired against rebuilt, the queries after it answered
three ways and re-checked; the report says so by its schema."""

import json
from pathlib import Path

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
