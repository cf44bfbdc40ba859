"""A sweep on a Dask cluster stores the same rows as on the local process pool (timings aside).

The cluster runs in a child process: Dask's event-loop threads may trigger Python's garbage collector, and a
Drake object left over from an earlier test being destroyed off the main thread aborts the whole interpreter.
"""

import os
import subprocess
import sys
import textwrap

import pytest

from app.bench.paper import sampling_specs
from app.bench.runner import run_sweep
from app.bench.store import ResultStore
from app.scene.files import ROOT

distributed = pytest.importorskip("distributed", reason="Dask not installed (pip install '.[cluster]')")

DETERMINISTIC = ("collision_checks", "passage_fraction", "sample_checksum", "censored", "attempts", "gave_up")


def _by_key(store):
    rows = {}
    for r in store.rows("sampling"):
        rows[(r["scene"], r["method"], r["step"], r["seed"])] = {k: r["metrics"].get(k) for k in DETERMINISTIC}
    return rows


def test_dask_cluster_and_local_pool_give_the_same_rows(tmp_path):
    specs = sampling_specs(["bar-3link"], ["lfbs", "gaussian"], [10.0], trials=3, max_checks=50_000)
    local = ResultStore(tmp_path / "local.sqlite")
    assert run_sweep(specs, local, workers=2) == len(specs)

    script = textwrap.dedent(f"""
        import distributed
        from app.bench.paper import sampling_specs
        from app.bench.runner import run_sweep
        from app.bench.store import ResultStore
        if __name__ == "__main__":
            specs = sampling_specs(["bar-3link"], ["lfbs", "gaussian"], [10.0], trials=3, max_checks=50_000)
            cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                               dashboard_address=None)
            try:
                store = ResultStore({str(tmp_path / "dask.sqlite")!r})
                first = run_sweep(specs, store, scheduler=cluster.scheduler_address)
                again = run_sweep(specs, store, scheduler=cluster.scheduler_address)
                print(first, again)
            finally:
                cluster.close()
    """)
    (tmp_path / "dask_sweep.py").write_text(script)
    # The script's own folder comes first on its sys.path: PYTHONPATH makes it (and Dask's workers) import the
    # app under test rather than whichever copy is installed.
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    result = subprocess.run(
        [sys.executable, str(tmp_path / "dask_sweep.py")], capture_output=True, text=True, env=env, timeout=600
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.split() == [str(len(specs)), "0"]  # all ran once; the second sweep resumed to nothing
    remote = ResultStore(tmp_path / "dask.sqlite")

    a, b = _by_key(local), _by_key(remote)
    assert len(a) == len(specs) and a.keys() == b.keys()
    assert a == b
    assert all(row["sample_checksum"] for row in a.values())
    assert len({row["sample_checksum"] for row in a.values()}) == len(specs)  # seeds differ, so samples do
