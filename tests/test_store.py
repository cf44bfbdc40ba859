"""The results store survives a kill: a resumed sweep loses and duplicates nothing; a store of another schema is
refused."""

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
    assert len(sweep(other, path)) == 3
    rows = sweep(toy_specs(4), path)
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
