"""The results store survives a kill: a resumed sweep loses and duplicates nothing; a store of another schema is
refused."""

import json
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time

import pytest

from app.bench.runner import EXPERIMENTS, run_sweep
from app.bench.store import SCHEMA_VERSION, ResultStore, TrialSpec
from app.errors import UserError

TESTS = os.path.dirname(__file__)


def toy_specs(n, sleep=0.0):
    return [TrialSpec("toy", "bar-3link", "uniform", 1.0, seed, {"n": 20, "sleep": sleep}) for seed in range(n)]


def test_keys_depend_on_everything_that_defines_a_trial():
    a = TrialSpec("sampling", "bar", "lfbs", 10, 3, {"k": 30})
    assert a.key == TrialSpec("sampling", "bar", "lfbs", 10.0, 3, {"k": 30}).key
    for other in (
        TrialSpec("sampling", "bar", "lfbs", 10, 4, {"k": 30}),
        TrialSpec("sampling", "bar", "rbbs", 10, 3, {"k": 30}),
        TrialSpec("sampling", "bar", "lfbs", 10, 3, {"k": 31}),
        TrialSpec("prm", "bar", "lfbs", 10, 3, {"k": 30}),
    ):
        assert other.key != a.key


def test_sweep_stores_each_trial_once(tmp_path, monkeypatch):
    monkeypatch.setitem(EXPERIMENTS, "toy", "toy_trials:run")
    store = ResultStore(tmp_path / "r.sqlite")
    assert run_sweep(toy_specs(6), store, workers=1) == 6
    assert run_sweep(toy_specs(8), store, workers=1) == 2  # only the new ones run
    rows = store.rows("toy")
    assert sorted(r["seed"] for r in rows) == list(range(8))
    assert all(r["metrics"]["collision_checks"] == 20 for r in rows)
    assert rows[0]["code_version"]


def test_a_reopened_store_resumes(tmp_path, monkeypatch):
    monkeypatch.setitem(EXPERIMENTS, "toy", "toy_trials:run")
    path = tmp_path / "r.sqlite"
    store = ResultStore(path)
    assert run_sweep(toy_specs(3), store, workers=1) == 3
    store.close()
    store = ResultStore(path)
    assert run_sweep(toy_specs(5), store, workers=1) == 2
    assert store.count() == 5


@pytest.mark.parametrize("user_version, schema", [(0, 1), (SCHEMA_VERSION + 1, SCHEMA_VERSION + 1)])
def test_a_store_of_another_schema_is_refused(tmp_path, user_version, schema):
    """A store written before the version was recorded (user_version 0: schema 1) or by newer code is not read."""
    path = tmp_path / "old.sqlite"
    db = sqlite3.connect(path)
    db.executescript(f"""
        CREATE TABLE trials (key TEXT PRIMARY KEY, experiment TEXT NOT NULL, scene TEXT NOT NULL,
            method TEXT NOT NULL, step REAL NOT NULL, seed INTEGER NOT NULL, params TEXT NOT NULL,
            metrics TEXT NOT NULL, code_version TEXT NOT NULL, finished REAL NOT NULL);
        INSERT INTO trials VALUES ('k', 'prm', 'bar', 'lfbs', 10.0, 0, '{{}}', '{{"success": 1.0}}', 'abc', 0);
        PRAGMA user_version = {user_version};
    """)
    db.close()
    with pytest.raises(UserError) as caught:
        ResultStore(path)
    message = str(caught.value)
    assert message == (
        f"results store {path} has schema {schema}, this code writes {SCHEMA_VERSION}: move it away and run again"
    )
    db = sqlite3.connect(path)  # untouched
    assert db.execute("SELECT COUNT(*), (SELECT user_version FROM pragma_user_version) FROM trials").fetchone() == (
        1,
        user_version,
    )
    db.close()


def test_a_command_sweep_returns_only_its_own_rows(tmp_path, monkeypatch):
    from app.bench.runner import sweep

    monkeypatch.setitem(EXPERIMENTS, "toy", "toy_trials:run")
    path = tmp_path / "new" / "r.sqlite"  # the folder is made
    other = [TrialSpec("toy", "bar-3link", "uniform", 1.0, seed, {"n": 5, "sleep": 0.0}) for seed in range(3)]
    assert len(sweep(other, path)[0]) == 3
    rows, reuse = sweep(toy_specs(4), path)
    assert (reuse.reused, reuse.trials) == (0, 4)
    assert sorted(r["seed"] for r in rows) == [0, 1, 2, 3] and all(r["params"]["n"] == 20 for r in rows)
    assert len(ResultStore(path).rows("toy")) == 7


def test_a_killed_sweep_resumes_without_loss_or_duplicates(tmp_path):
    db = tmp_path / "r.sqlite"
    script = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {TESTS!r})
        from app.bench.runner import EXPERIMENTS, run_sweep
        from app.bench.store import ResultStore, TrialSpec
        EXPERIMENTS["toy"] = "toy_trials:run"
        specs = [TrialSpec("toy", "bar-3link", "uniform", 1.0, s, {{"n": 20, "sleep": 0.05}}) for s in range(40)]
        run_sweep(specs, ResultStore({str(db)!r}), workers=1)
    """)
    child = subprocess.Popen(
        [sys.executable, "-c", script], env=os.environ.copy(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    deadline = time.time() + 120
    while time.time() < deadline:  # kill it in the middle of the sweep
        if db.exists() and 5 <= ResultStore(db).count() < 40:
            break
        time.sleep(0.05)
    child.send_signal(signal.SIGKILL)
    child.wait()
    partial = ResultStore(db).count()
    assert 5 <= partial < 40

    subprocess.run([sys.executable, "-c", script], env=os.environ.copy(), check=True, capture_output=True)
    store = ResultStore(db)
    seeds = [r["seed"] for r in store.rows("toy")]
    assert sorted(seeds) == list(range(40))


def _rewrite_version(path, version, seeds):
    """As if older code had written these seeds' rows."""
    db = sqlite3.connect(path)
    with db:
        db.executemany("UPDATE trials SET code_version = ? WHERE seed = ?", [(version, s) for s in seeds])
    db.close()


def test_a_sweep_says_what_it_reuses_and_from_which_code_version(tmp_path, monkeypatch):
    monkeypatch.setitem(EXPERIMENTS, "toy", "toy_trials:run")
    store = ResultStore(tmp_path / "r.sqlite")
    assert store.reuse(toy_specs(5)).reused == 0
    run_sweep(toy_specs(3), store, workers=1)
    reuse = store.reuse(toy_specs(5))
    assert (reuse.reused, reuse.trials, reuse.versions) == (3, 5, (store.version,))
    assert reuse.message() == f"reused 3 of 5 trials from {store.path.resolve()} (code version {store.version})"
    assert reuse.warning() is None


def test_rows_of_other_code_are_reused_with_a_warning_and_fresh_runs_them_again(tmp_path, monkeypatch):
    monkeypatch.setitem(EXPERIMENTS, "toy", "toy_trials:run")
    path = tmp_path / "r.sqlite"
    store = ResultStore(path)
    run_sweep(toy_specs(4), store, workers=1)
    _rewrite_version(path, "0ld0ld0ld0ld", [0, 1])

    reuse = store.reuse(toy_specs(4))
    assert reuse.reused == 4 and reuse.versions == tuple(sorted(["0ld0ld0ld0ld", store.version]))
    assert "0ld0ld0ld0ld" in reuse.message() and "0ld0ld0ld0ld" in reuse.warning()
    assert run_sweep(toy_specs(4), store, workers=1) == 0  # without --fresh: reused as they are

    fresh = store.reuse(toy_specs(4), fresh=True)
    assert (fresh.reused, fresh.versions, fresh.warning()) == (2, (store.version,), None)
    assert run_sweep(toy_specs(4), store, workers=1, fresh=True) == 2  # only the other version's trials run again
    rows = store.rows("toy")
    assert sorted(r["seed"] for r in rows) == [0, 1, 2, 3]  # replaced, not duplicated
    assert {r["code_version"] for r in rows} == {store.version}
    assert run_sweep(toy_specs(4), store, workers=1, fresh=True) == 0  # a fresh run started again resumes


def test_the_code_version_tells_uncommitted_changes_apart(tmp_path, monkeypatch):
    from app.bench import store as store_module

    def git(*args):
        return subprocess.run(
            ["git", "-c", "user.name=t", "-c", "user.email=t@t", *args],
            cwd=tmp_path,
            check=True,
            capture_output=True,
            text=True,
        ).stdout.strip()

    git("init", "-q")
    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "report.md").write_text("60 trials\n")
    git("add", ".")
    git("commit", "-qm", "one")
    monkeypatch.setattr(store_module, "ROOT", tmp_path)
    commit = git("rev-parse", "--short=12", "HEAD")
    assert store_module.code_version() == commit
    # What the benches write is not code: a resumed `bench paper` rewrites the committed report.
    (tmp_path / "results" / "report.md").write_text("120 trials\n")
    assert store_module.code_version() == commit
    (tmp_path / "a.py").write_text("x = 2\n")
    first = store_module.code_version()
    (tmp_path / "a.py").write_text("x = 3\n")
    second = store_module.code_version()
    assert first.startswith(commit + "+dirty.") and second.startswith(commit + "+dirty.") and first != second


def test_bench_plan_says_what_it_reused_and_fresh_runs_other_versions_again(tmp_path, cli):
    path = tmp_path / "plan.sqlite"
    command = ["bench", "plan", "--scenes", "bar-3link", "--samplers", "uniform", "--seeds", "2", "--narrow", "5"]
    command += ["--uniform", "20", "--smooth", "0", "--store", path, "--json"]
    first = cli(*command)
    assert first.returncode == 0, first.stderr
    assert json.loads(first.stdout)["reused"]["reused"] == 0 and "reused" not in first.stderr

    _rewrite_version(path, "0ld0ld0ld0ld", [0])
    again = cli(*command)
    reused = json.loads(again.stdout)["reused"]
    assert reused["reused"] == 2 and "0ld0ld0ld0ld" in reused["versions"] and reused["warning"]
    assert f"reused 2 of 2 trials from {path.resolve()} (code version " in again.stderr
    assert "warning: " in again.stderr and "--fresh" in again.stderr

    fresh = cli(*command, "--fresh")
    reused = json.loads(fresh.stdout)["reused"]
    assert (reused["reused"], reused["warning"]) == (1, None)
    assert {r["code_version"] for r in ResultStore(path).rows("prm")} == {reused["current"]}
