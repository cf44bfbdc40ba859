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

from app.bench.store import TrialSpec
from app.cli import non_negative_int, positive_float, positive_int, print_json

JOBS = ["welding", "window"]
MODES = {"query": False, "full": True}  # roadmap mode -> plan(full_roadmap=...)


def register(kinds) -> None:
    p = kinds.add_parser("jobs", help="UR3 welding/window runs timed end to end; query vs full roadmap side by side")
    p.add_argument("--jobs", default=",".join(JOBS), help="comma-separated: welding, window")
    p.add_argument("--samplers", default="lfbs", help="comma-separated sampler names")
    p.add_argument("--seeds", type=positive_int, default=10, help="seeds 0..N-1 per job, sampler and mode")
    p.add_argument("--roadmap", choices=[*MODES, "both"], default="both",
                   help="query: the planner's default; full: the whole roadmap first; both: side by side")
    p.add_argument("--narrow", type=non_negative_int, default=40, help="narrow-passage samples per planned leg")
    p.add_argument("--uniform", type=non_negative_int, default=40, help="uniform samples per planned leg")
    p.add_argument("--budget", type=positive_float, default=30.0, metavar="SECONDS", help="per planned leg")
    p.add_argument("--store", default="out/bench-jobs.sqlite", help="results store (resumes a killed run)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def run_trial_spec(oracle, spec: TrialSpec) -> dict:
    """One scripted UR3 job (experiment "ur3", scene = job): seconds total/ik/planning, checks, success."""
    from app.budget import Budget
    from app.errors import UserError
    from app.runs import JOB_SETTINGS, run_job

    p = spec.params
    oracle.reset()
    start = time.perf_counter()
    try:
        settings = replace(JOB_SETTINGS, sampler=spec.method, seed=spec.seed, narrow=int(p["narrow"]),
                           uniform=int(p["uniform"]), step=spec.step, budget=Budget(seconds=float(p["budget"])),
                           full_roadmap=bool(p["full_roadmap"]))
        r = run_job(oracle, spec.scene, settings)
    except UserError as exc:  # NoPath, or IK finding no collision-free pose
        return {"success": 0.0, "seconds": time.perf_counter() - start, "seconds_ik": None,
                "seconds_planning": None, "collision_checks": oracle.checks, "error": str(exc)[:200]}
    planned = [leg for leg in r.legs if leg.method != "straight"]
    return {"success": 1.0, "seconds": r.seconds["total"], "seconds_ik": r.seconds["ik"],
            "seconds_planning": r.seconds["planning"], "collision_checks": r.collision_checks,
            "legs": len(r.legs), "planned_legs": len(planned), "duration": r.trajectory.duration}


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
        out.append({"job": job, "sampler": sampler, "roadmap": mode, "runs": len(metrics), "successes": len(ok),
                    "median_total": _stat(ok, "seconds"), "min_total": _stat(ok, "seconds", np.min),
                    "max_total": _stat(ok, "seconds", np.max), "median_ik": _stat(ok, "seconds_ik"),
                    "median_planning": _stat(ok, "seconds_planning"),
                    "median_checks": float(np.median([m["collision_checks"] for m in metrics]))})
    return out


def run(args) -> int:
    from app.bench.plan import default_step
    from app.bench.runner import sweep
    from app.errors import UserError
    from app.samplers import SAMPLERS

    jobs = [j.strip() for j in args.jobs.split(",") if j.strip()]
    samplers = [s.strip() for s in args.samplers.split(",") if s.strip()]
    bad = [j for j in jobs if j not in JOBS] or [s for s in samplers if s not in SAMPLERS]
    if bad or not jobs or not samplers:
        raise UserError(f"unknown job or sampler '{bad[0]}' (jobs: {', '.join(JOBS)}; samplers: "
                        f"{', '.join(SAMPLERS)})" if bad else "need at least one job and one sampler")
    modes = list(MODES) if args.roadmap == "both" else [args.roadmap]
    todo = [TrialSpec("ur3", job, sampler, default_step(job), seed,
                      {"narrow": args.narrow, "uniform": args.uniform, "budget": args.budget,
                       "full_roadmap": MODES[mode]})
            for job in jobs for sampler in samplers for mode in modes for seed in range(args.seeds)]
    result = table(sweep(todo, args.store, workers=1, desc="bench jobs"))
    if args.json:
        print_json({"jobs": result, "seeds": args.seeds})
        return 0
    print(f"{args.seeds} seeds; per planned leg up to {args.narrow} narrow + {args.uniform} uniform samples, "
          f"{args.budget:g} s budget; seconds are IK + planning + smoothing + Toppra, medians (min-max) of successes")
    print(f"{'job':<8} {'sampler':<8} {'roadmap':<8} {'success':>8} {'median s':>9} {'min-max s':>12} {'IK s':>6} "
          f"{'checks':>8}")
    cells = {(r["job"], r["sampler"], r["roadmap"]): r for r in result}
    for r in result:
        total = "-" if r["median_total"] is None else f"{r['median_total']:.2f}"
        spread = "-" if r["min_total"] is None else f"{r['min_total']:.2f}-{r['max_total']:.2f}"
        ik = "-" if r["median_ik"] is None else f"{r['median_ik']:.2f}"
        print(f"{r['job']:<8} {r['sampler']:<8} {r['roadmap']:<8} {r['successes']:>4}/{r['runs']:<3} {total:>9} "
              f"{spread:>12} {ik:>6} {r['median_checks']:>8.0f}")
    for (job, sampler, mode), r in cells.items():
        full = cells.get((job, sampler, "full"))
        if mode == "query" and full and r["median_total"] and full["median_total"]:
            print(f"{job} {sampler}: the query mode takes {r['median_total'] / full['median_total']:.2f}x the full "
                  f"roadmap's median time and {r['median_checks'] / full['median_checks']:.2f}x its checks")
    return 0
