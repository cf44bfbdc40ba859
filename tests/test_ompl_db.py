"""The results store written as OMPL's benchmark database: OMPL's tables and columns, one run per trial."""

import sqlite3

import pytest

from app.bench import ompl_db
from app.bench.store import ResultStore, TrialSpec

# The tables and runs columns that OMPL's ompl_benchmark_statistics.py creates and Planner Arena reads.
OMPL_TABLES = {"experiments", "plannerConfigs", "enums", "runs", "progress"}
OMPL_EXPERIMENT_COLUMNS = [
    *("id", "name", "totaltime", "timelimit", "memorylimit", "runcount", "version", "hostname", "cpuinfo", "date"),
    *("seed", "setup"),
]


def tiny_store(tmp_path):
    store = ResultStore(tmp_path / "results.sqlite")
    params = {"k": 30, "max_checks": 5000}
    for seed in range(3):
        store.add(
            TrialSpec("sampling", "bar", "lfbs", 10.0, seed, params),
            {
                "seconds": 0.1 * (seed + 1),
                "collision_checks": 1000 + seed,
                "passage_fraction": 0.5,
                "k": 30,
                "censored": False,
                "sample_checksum": "abc",
            },
        )
    store.add(
        TrialSpec("sampling", "bar", "rbbs", 10.0, 0, params),
        {
            "seconds": 2.0,
            "collision_checks": 5003,
            "passage_fraction": 1.0,
            "samples_drawn": 3,
            "k": 30,
            "censored": True,
            "sample_checksum": "def",
        },
    )
    store.add(TrialSpec("prm", "maze", "lfbs", 0.5, 0, {"narrow": 200}), {"success": 0.0, "seconds": 4.0})
    return store


def test_the_database_has_ompl_layout_and_one_run_per_trial(tmp_path):
    store = tiny_store(tmp_path)
    path = ompl_db.write(store.rows(), tmp_path / "benchmark.db")
    db = sqlite3.connect(path)
    tables = {name for (name,) in db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    assert OMPL_TABLES <= tables
    assert [c[1] for c in db.execute("PRAGMA table_info(experiments)")] == OMPL_EXPERIMENT_COLUMNS
    assert [c[1] for c in db.execute("PRAGMA table_info(plannerConfigs)")] == ["id", "name", "settings"]
    runs = {c[1]: c[2] for c in db.execute("PRAGMA table_info(runs)")}
    assert {"id": "INTEGER", "experimentid": "INTEGER", "plannerid": "INTEGER", "time": "REAL"}.items() <= runs.items()
    assert runs["solved"] == "BOOLEAN" and runs["status"] == "ENUM" and runs["collision_checks"] == "INTEGER"
    assert "sample_checksum" not in runs  # not a number: not a run property
    status = dict(db.execute("SELECT value, description FROM enums WHERE name = 'status'"))
    assert status[ompl_db.EXACT_SOLUTION] == "Exact solution" and status[ompl_db.TIMEOUT] == "Timeout"

    experiments = dict(db.execute("SELECT name, runcount FROM experiments"))
    assert experiments == {"sampling bar a=10": 3, "prm maze a=0.5": 1}
    got = db.execute(
        "SELECT e.name, p.name, r.seed, r.time, r.solved, r.status, r.collision_checks, r.passage_yield "
        "FROM runs r JOIN experiments e ON e.id = r.experimentid JOIN plannerConfigs p ON p.id = r.plannerid "
        "ORDER BY e.name, p.name, r.seed"
    ).fetchall()
    assert len(got) == store.count()
    exact, timeout = ompl_db.EXACT_SOLUTION, ompl_db.TIMEOUT
    assert got == [
        ("prm maze a=0.5", "lfbs", 0, 4.0, 0, timeout, None, None),
        ("sampling bar a=10", "lfbs", 0, pytest.approx(0.1), 1, exact, 1000, 0.5),
        ("sampling bar a=10", "lfbs", 1, pytest.approx(0.2), 1, exact, 1001, 0.5),
        ("sampling bar a=10", "lfbs", 2, pytest.approx(0.3), 1, exact, 1002, 0.5),
        ("sampling bar a=10", "rbbs", 0, 2.0, 0, timeout, 5003, 0.1),  # censored: 3 of 30 samples, all in passage
    ]


def test_ompl_computes_its_views_on_the_database(tmp_path):
    statistics = pytest.importorskip("ompl._benchmark_statistics")
    path = ompl_db.write(tiny_store(tmp_path).rows(), tmp_path / "benchmark.db")
    statistics.computeViews(str(path), False)
    db = sqlite3.connect(path)
    best = db.execute("SELECT experimentid, avg_solved FROM bestPlannerConfigsPerExperiment").fetchall()
    assert sorted(solved for _, solved in best) == [0.0, 0.0, 1.0]  # prm lfbs; sampling rbbs, lfbs
