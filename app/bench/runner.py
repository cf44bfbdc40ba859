"""Runs a sweep of trials into the results store: on local cores (a process pool) or on a Dask cluster.

A trial is a pure function of its TrialSpec (seeded), so where it runs does not change its row. Each worker
process keeps one oracle per scene (building a Drake diagram per trial would dominate the cost) on one thread:
the parallelism is across processes. With one worker, trials run in this process on all the oracle's threads,
as a plain `plan` would. Only trials the store has no reusable row for are sent (`ResultStore.pending`); rows
are stored as they come back, so a killed sweep resumes where it stopped. Local workers end with the sweep's
process, however it dies (even by SIGKILL): a worker outliving it would wait forever for trials on a queue no one
feeds.
"""

import ctypes
import importlib
import multiprocessing
import os
import signal
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor, as_completed

from tqdm import tqdm

from app.bench.store import ResultStore, Reuse, TrialSpec
from app.checking.oracle import CollisionOracle, default_threads
from app.errors import UserError
from app.scene.model import Scene

# Dask (optional) is imported only for a sweep sent to a scheduler.

# experiment name -> "module:function" taking (oracle, spec) and returning a dict of metrics.
EXPERIMENTS = {
    "sampling": "app.bench.sampling:run_trial_spec",
    "prm": "app.bench.plan:run_trial_spec",
    "ablation": "app.bench.ablation:run_trial_spec",
    "ompl": "app.bench.ompl:run_trial_spec",
    "ur3": "app.bench.jobs:run_trial_spec",
    "audit": "app.bench.audit:run_trial_spec",
    "audit-roadmap": "app.bench.audit:run_roadmap_trial_spec",
    "certify": "app.bench.certification:run_trial_spec",
    "certify-job": "app.bench.certification:run_job_trial_spec",
}

# experiment -> "module:function" taking (spec, threads), for trials whose problem is files of its own rather than a
# shipped scene: such a trial reads them and builds its oracle itself.
OWN_PROBLEM_EXPERIMENTS = {
    "moveit": "app.bench.moveit:run_trial_spec",
}

_oracles = {}


def _oracle(scene: str, threads: int):
    if (scene, threads) not in _oracles:
        _oracles[scene, threads] = CollisionOracle(Scene(scene), threads=threads)
    return _oracles[scene, threads]


def execute(spec: TrialSpec, threads: int = 1) -> tuple[TrialSpec, dict]:
    """Run one trial in this process (top-level, so process pools and Dask can pickle it) on an oracle with
    `threads` collision-checking threads (one per worker when several share the cores)."""
    if spec.experiment in OWN_PROBLEM_EXPERIMENTS:
        module, function = OWN_PROBLEM_EXPERIMENTS[spec.experiment].split(":")
        return spec, getattr(importlib.import_module(module), function)(spec, threads)
    module, function = EXPERIMENTS[spec.experiment].split(":")
    trial = getattr(importlib.import_module(module), function)
    return spec, trial(_oracle(spec.scene, threads), spec)


PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def _exit_with_parent(parent: int) -> None:
    """A local worker's initializer: end this process when `parent` (the sweep's process) dies. On Linux the kernel
    kills it (prctl PR_SET_PDEATHSIG, at once, even in the middle of a Drake call); elsewhere a thread notices the
    worker has been re-parented."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    else:
        threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()
    if os.getppid() != parent:  # it died before the request above was in place
        os._exit(1)


def _watch_parent(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(1.0)
    os._exit(1)


def connect(scheduler):
    """A Dask client for a scheduler address (a client is passed through); one clear line if it is unreachable."""
    try:
        from distributed import Client
    except ImportError:
        raise UserError("--scheduler needs Dask: pip install 'narrow-passage-planner[cluster]'") from None
    if isinstance(scheduler, Client):
        return scheduler
    try:
        return Client(scheduler, timeout="10s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise UserError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None


def run_sweep(
    specs: list[TrialSpec],
    store: ResultStore,
    workers: int = 0,
    scheduler=None,
    desc: str = "trials",
    fresh: bool = False,
) -> int:
    """Run the specs the store has no reusable row for (`ResultStore.pending`: with `fresh`, rows of other code
    versions are not reused); returns how many ran. workers=0: all local cores. `scheduler`: a Dask scheduler
    address or a client from `connect` (connect first to fail before anything is written)."""
    pending = store.pending(specs, fresh=fresh)
    if not pending:
        return 0
    if scheduler is not None:
        scheduler = connect(scheduler)
    progress = tqdm(total=len(pending), desc=desc, unit="trial", dynamic_ncols=True)
    try:
        for spec, metrics in _results(pending, workers or os.cpu_count() or 1, scheduler):
            store.add(spec, metrics)
            progress.update()
    finally:
        progress.close()
    return len(pending)


def sweep(
    specs: list[TrialSpec], store_path, workers: int = 1, desc: str = "trials", fresh: bool = False
) -> tuple[list[dict], Reuse]:
    """A benchmark command's sweep: run what `store_path` has no reusable row for (`run_sweep`); the rows of `specs`
    and what was reused of them."""
    store = ResultStore(store_path)
    try:
        reuse = store.reuse(specs, fresh=fresh)
        run_sweep(specs, store, workers=workers, desc=desc, fresh=fresh)
        return store.rows_for(specs), reuse
    finally:
        store.close()


def _results(pending: list[TrialSpec], workers: int, client):
    if client is not None:
        yield from _dask_results(pending, client)
    elif workers == 1:  # in this process, with all the cores a plain `plan` would use
        for spec in pending:
            yield execute(spec, default_threads())
    else:
        # spawn, not fork: a forked child would inherit Drake's thread pools mid-state.
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(
            max_workers=workers, mp_context=context, initializer=_exit_with_parent, initargs=(os.getpid(),)
        ) as pool:
            futures = [pool.submit(execute, spec) for spec in pending]
            try:
                for future in as_completed(futures):
                    yield future.result()
            except BaseException:
                for future in futures:
                    future.cancel()
                raise


def _dask_results(pending: list[TrialSpec], client):
    from distributed import as_completed as dask_completed

    futures = client.map(execute, pending, pure=False)
    for future in dask_completed(futures):
        yield future.result()
