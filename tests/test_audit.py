"""The audit (app.bench.audit): its re-check counts a trajectory through an obstacle, its densified states follow
the motion, and a short run's table has every field, with no colliding state among the planner's trajectories."""

import json

import numpy as np
import pytest

from app.bench.audit import (
    CHECKS,
    DIVISOR,
    Recheck,
    audit_trajectory,
    bad_input_counts,
    lines,
    measure,
    measure_bad_input,
    measure_roadmaps,
    states,
    summarise,
)
from app.motion.timing import parameterize


def test_a_trajectory_through_an_obstacle_is_counted(oracles):
    """The bar scene's straight motion from start to goal runs through the wall (the oracle agrees); timed rest to
    rest, the re-check finds colliding states and how deep they go; a free start alone has none."""
    oracle = oracles("bar")
    scene = oracle.scene
    start, goal = np.asarray(scene.start, float), np.asarray(scene.goal, float)
    assert not oracle.context().edge_free(start, goal)
    through = parameterize(oracle.plant, np.array([start, goal]), scene.velocity_limits, scene.acceleration_limits)
    recheck = Recheck("bar")
    found = audit_trajectory(recheck, oracle.space, through, start, goal, scene)
    assert found["colliding_states"] > 0 and found["max_penetration"] > 0
    assert found["limit_violations"] == 0 and found["worst_limit_ratio"] <= 1 + 1e-6 and found["endpoints_exact"]
    assert not recheck.check(start)[0][0]
    # The straight line a controller would draw from start to goal is checked finely, and collides.
    line = lines(np.array([start, goal]), oracle.space.weights, oracle.space.resolution / DIVISOR)
    assert len(line) > DIVISOR and recheck.check(line)[0].any()
    # The same trajectory graded against other endpoints is flagged.
    assert not audit_trajectory(recheck, oracle.space, through, start, start, scene)["endpoints_exact"]


def test_the_states_follow_the_motion_finely(oracles):
    """Densified states of a timed motion are no farther apart than asked, and lie on the motion: those at the
    samples of a finer timing of the same path are reproduced by the quintic Hermite between coarser samples."""
    oracle = oracles("maze")
    scene, space = oracle.scene, oracle.space
    W = np.array([[14.5, 2.0, 1.5, 0.0], [16.0, 3.0, 1.8, 0.5]])
    coarse = parameterize(oracle.plant, W, scene.velocity_limits, scene.acceleration_limits, dt=0.05)
    spacing = space.resolution / DIVISOR
    Q = states(coarse, space.weights, spacing)
    assert np.linalg.norm(np.diff(Q, axis=0) * space.weights, axis=1).max() <= spacing
    assert np.array_equal(Q[0], W[0]) and np.array_equal(Q[-1], W[-1])
    fine = parameterize(oracle.plant, W, scene.velocity_limits, scene.acceleration_limits, dt=0.001)
    nearest = np.linalg.norm((fine.positions[:, None] - Q[None]) * space.weights, axis=2).min(axis=1)
    assert nearest.max() <= spacing


def test_a_short_audit_has_every_field_and_no_colliding_state(tmp_path):
    scenes = ["maze", "joint3d"]
    table, _ = measure(scenes, 2, seed=1, checks=CHECKS, store=tmp_path / "audit.sqlite")
    assert [row["scene"] for row in table] == [*scenes, "total"]
    fields = {
        "problems",
        "solved",
        "certified",
        "colliding_trajectories",
        "colliding_states",
        "max_penetration",
        "limit_violations",
        "inexact_endpoints",
        "states_checked",
        "sample_lines_states",
        "colliding_sample_lines_states",
        "polyline_states",
        "colliding_polyline_states",
    }
    assert fields <= set(table[-1])
    assert [row["problems"] for row in table] == [1, 1, 2]
    total = table[-1]
    assert total["solved"] >= 1 and total["states_checked"] > 1000 * total["solved"]
    assert total["colliding_states"] == 0 and total["inexact_endpoints"] == 0
    # What a controller interpolating linearly follows: the lines between 50 Hz samples, and the path polyline.
    assert total["sample_lines_states"] > 100 * total["solved"] and total["polyline_states"] > 100 * total["solved"]
    assert total["colliding_sample_lines_states"] == 0 and total["colliding_polyline_states"] == 0
    # Toppra's limits are checked at its grid points (and app.motion.timing's between them): 1e-4 covers what is left.
    assert 0.5 < total["worst_limit_ratio"] <= 1 + 1e-4


def test_answers_on_a_stored_and_a_tampered_roadmap_are_clean(tmp_path):
    """Problems planned on a cell roadmap saved and read back, and on the same file with every colliding edge
    rewritten as free and proved: every answer certified and clean, and no forged edge on any roadmap path."""
    table, _ = measure_roadmaps(["bar-3link"], 4, seed=0, checks=CHECKS, store=tmp_path / "audit.sqlite", nodes=200)
    assert [row["scene"] for row in table] == ["bar-3link saved", "bar-3link tampered", "total"]
    assert [row["problems"] for row in table] == [2, 2, 4]
    total = table[-1]
    assert table[0]["forged_edges"] == 0 and table[1]["forged_edges"] > 100  # every colliding edge of the build
    assert total["solved"] == total["certified"] >= 3 and total["forged_edges_on_paths"] == 0
    colliding = ("colliding_states", "colliding_sample_lines_states", "colliding_polyline_states")
    assert [total[key] for key in colliding] == [0, 0, 0]


def test_a_soak_run_again_reuses_its_problems(cli, tmp_path):
    """Problems are rows of the store: the same soak again plans nothing and answers the same table."""
    argv = ["bench", "audit", "--scenes", "bar-3link,maze", "--problems", "2", "--roadmap-problems", "0"]
    argv += ["--no-bad-input", "--json"]
    argv += ["--store", tmp_path / "audit.sqlite"]
    first = json.loads(cli(*argv).stdout)
    assert first["checks"] == CHECKS and first["bad_input"] is None and first["stored_roadmaps"] is None
    assert [row["problems"] for row in first["audit"]] == [1, 1, 2] and first["reused"]["reused"] == 0
    again = json.loads(cli(*argv).stdout)
    assert again["reused"]["reused"] == 2 and again["audit"] == first["audit"]


def test_the_bad_input_audit_tells_a_behaved_case_from_one_that_wrote_a_file(tmp_path):
    """Each case runs as its own process; one that succeeds and writes a picture where a refusal was expected is
    counted as such, and a second audit reuses the stored cases."""
    rows = [
        (["plan", "bar", "--step", "1e308"], 2, "longer than the scene's diagonal"),
        (["show", "bar", "--png", "{out}/bar.png"], 2, "a refusal that does not come"),
    ]
    table, reuse = measure_bad_input(tmp_path / "audit.sqlite", rows=rows)
    assert reuse.reused == 0
    refused, drawn = table
    assert refused["exit_code"] == 2 and refused["stderr_lines"] == 1 and "diagonal" in refused["first_line"]
    assert refused["written"] == [] and not refused["traceback"]  # (behaved also asks for an answer within 10 s)
    assert drawn["exit_code"] == 0 and drawn["written"] == ["out/bar.png"] and not drawn["behaved"]
    counts = bad_input_counts(table)
    assert (counts["cases"], counts["wrong_exit_code"], counts["wrote_files"]) == (2, 1, 1)
    assert counts["tracebacks"] == counts["hangs"] == 0
    again, reuse = measure_bad_input(tmp_path / "audit.sqlite", rows=rows)
    assert reuse.reused == 2 and again == table


@pytest.mark.slow
def test_every_bad_input_case_behaves_as_its_own_process(tmp_path):
    """The whole table as `bench audit` runs it: every case answered in one line, with its exit code, nothing
    written, no traceback, no hang. `behaved` also asks for an answer within ANSWER_SECONDS, which measures the
    machine and its load as much as the code: `bench audit` reports it; the test asks for everything else."""
    from app.bench import bad_input
    from app.bench.audit import behaved

    table, _ = measure_bad_input(tmp_path / "audit.sqlite", workers=2)
    expected = [{"exit_code": code, "fragment": fragment} for _, code, fragment in bad_input.ROWS]
    assert len(table) == len(expected) and not [case["command"] for case in table if case["exit_code"] is None]
    assert [c["command"] for c, e in zip(table, expected) if not behaved({**c, "seconds": 0.0}, e)] == []


def test_the_total_row_counts_each_roadmap_files_forged_edges_once():
    """Every problem on one file sees all its forged edges; the total adds the files' counts, not the problems'."""

    def row(scene, variant, forged):
        metrics = {
            "drawn": True, "solved": True, "certified": True, "colliding_states": 0, "max_penetration": 0.0,
            "limit_violations": 0, "endpoints_exact": True, "states": 1, "seconds": 0.1,
            "forged_edges": forged, "forged_edges_on_path": 0,
        }  # fmt: skip
        return {"scene": scene, "method": variant, "metrics": metrics}

    rows = [row("bar", "tampered", 10), row("bar", "tampered", 10), row("maze", "tampered", 25), row("bar", "saved", 0)]
    labels = ["bar saved", "bar tampered", "maze tampered"]
    table = summarise(rows, labels, label=lambda r: f"{r['scene']} {r['method']}")
    assert [r["forged_edges"] for r in table] == [0, 10, 25, 35]
