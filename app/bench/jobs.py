"""`bench jobs`: the scripted UR3 jobs (`run welding|window`), timed end to end over seeds -- IK, planning,
smoothing and Toppra -- with the planner's query mode (lazy, a quarter of the samples at a time, stopping when
connected) side by side with the full roadmap (every sample drawn and every edge checked first, the paper's
protocol) in one run.

Trials are experiment "ur3" in the results store (`bench paper` times the paper's UR3 set-up with the same trial),
so a killed run resumes.
"""

import time
from dataclasses import replace

import numpy as np

from app.bench.plan import MODES
from app.bench.runner import sweep
from app.bench.store import Reuse, TrialSpec
from app.checking.budget import Budget
from app.errors import UserError
from app.jobs import JOB_SETTINGS, ROUTES, run_job
from app.planning.settings import default_step
from app.scene.model import Scene

JOBS = list(ROUTES)  # the scripted jobs: welding, window


def run_trial_spec(oracle, spec: TrialSpec) -> dict:
    """One scripted UR3 job (experiment "ur3", scene = job): seconds total/ik/planning, checks, success."""
    p = spec.params
    start = time.perf_counter()
    try:
        settings = replace(
            JOB_SETTINGS,
            sampler=spec.method,
            seed=spec.seed,
            narrow=int(p["narrow"]),
            uniform=int(p["uniform"]),
            step=spec.step,
            budget=Budget(seconds=float(p["budget"])),
            full_roadmap=bool(p["full_roadmap"]),
        )
        r = run_job(oracle, spec.scene, settings)
    except UserError as exc:  # NoPath, or IK finding no collision-free pose
        return {
            "success": 0.0,
            "seconds": time.perf_counter() - start,
            "seconds_ik": None,
            "seconds_planning": None,
            "collision_checks": getattr(exc, "details", {}).get("job_checks"),
            "error": str(exc)[:200],
        }
    planned = [leg for leg in r.legs if leg.method != "straight"]
    return {
        "success": 1.0,
        "seconds": r.seconds["total"],
        "seconds_ik": r.seconds["ik"],
        "seconds_planning": r.seconds["planning"],
        "collision_checks": r.collision_checks,
        "legs": len(r.legs),
        "planned_legs": len(planned),
        "duration": r.trajectory.duration,
    }


def _stat(metrics: list[dict], key: str, fn=np.median) -> float | None:
    """`fn` of the values of `key` the metrics hold (a failed step leaves None), or None without any."""
    values = [m[key] for m in metrics if m.get(key) is not None]
    return float(fn(values)) if values else None


def table(rows) -> list[dict]:
    """Medians per (job, sampler, roadmap mode) over successful runs; checks over all runs."""
    cells = {}
    for r in rows:
        if r["experiment"] == "ur3":
            mode = "full" if r["params"]["full_roadmap"] else "query"
            cells.setdefault((r["scene"], r["method"], mode), []).append(r["metrics"])
    out = []
    for (job, sampler, mode), metrics in sorted(cells.items()):
        ok = [m for m in metrics if m["success"]]
        out.append(
            {
                "job": job,
                "sampler": sampler,
                "roadmap": mode,
                "runs": len(metrics),
                "successes": len(ok),
                "median_total": _stat(ok, "seconds"),
                "min_total": _stat(ok, "seconds", np.min),
                "max_total": _stat(ok, "seconds", np.max),
                "median_ik": _stat(ok, "seconds_ik"),
                "median_planning": _stat(ok, "seconds_planning"),
                "median_checks": float(np.median([m["collision_checks"] for m in metrics])),
            }
        )
    return out


def measure(
    jobs: list[str],
    samplers: list[str],
    seeds: int,
    modes: list[str],
    narrow: int,
    uniform: int,
    budget: float,
    store,
    fresh: bool = False,
) -> tuple[list[dict], Reuse]:
    """Every job x sampler x roadmap mode (`MODES`) for seeds 0..seeds-1, in this process (trials `store` has no
    reusable row for are run; `runner.sweep`), as `table` rows; and what was reused. budget: seconds per planned
    leg."""
    steps = {job: default_step(Scene(job)) for job in jobs}
    todo = [
        TrialSpec(
            "ur3",
            job,
            sampler,
            steps[job],
            seed,
            {"narrow": narrow, "uniform": uniform, "budget": budget, "full_roadmap": MODES[mode]},
        )
        for job in jobs
        for sampler in samplers
        for mode in modes
        for seed in range(seeds)
    ]
    rows, reuse = sweep(todo, store, workers=1, desc="bench jobs", fresh=fresh)
    return table(rows), reuse
