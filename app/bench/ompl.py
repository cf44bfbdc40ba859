"""`bench ompl`: OMPL's PRM on our oracle with OMPL's samplers and ours, beside our own PRM, on one budget.

Every method gets the same wall-clock budget per seed and the same collision oracle, so "checks" means the same
thing everywhere (configurations handed to Drake). OMPL's PRM alternates grow (valid-state sampler) and expand
(uniform bounce walks) phases on its own schedule; all OMPL rows share that schedule, and the sampler is the only
thing that changes between them. Our PRM (`ours:NAME`) runs its own narrow+uniform schedule under the same budget.
"""
import time

import numpy as np

from app.bench.store import TrialSpec
from app.cli import positive_float, positive_int, print_json

OMPL_METHODS = ["ompl-uniform", "ompl-obstacle", "ompl-gaussian", "ompl-bridge", "ompl+lfbs", "ompl+rbbs"]
OURS = ["ours:lfbs", "ours:rbbs", "ours:uniform"]


def register(kinds) -> None:
    p = kinds.add_parser("ompl", help="OMPL's PRM with OMPL's and our samplers vs our PRM, same oracle and budget")
    p.add_argument("--scenes", default="bar,joint3d")
    p.add_argument("--methods", default=",".join(OMPL_METHODS + OURS))
    p.add_argument("--seeds", type=positive_int, default=10)
    p.add_argument("--budget", type=positive_float, default=20.0, help="seconds per run")
    p.add_argument("--step", type=positive_float, default=None, help="sampler step (default: the scene's)")
    p.add_argument("--workers", type=positive_int, default=1,
                   help="parallel runs (1 keeps timings clean: each run gets a whole core and nothing competes)")
    p.add_argument("--store", default="out/bench-ompl.sqlite")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def run_trial_spec(oracle, spec: TrialSpec) -> dict:
    """One OMPL PRM run: success, seconds to the first solution (or the budget), checks."""
    from app.ompl_bridge import OmplProblem

    oracle.reset()
    problem = OmplProblem(oracle, seed=spec.seed)
    name = spec.method
    if name.startswith("ompl+"):
        problem.use_sampler(name[len("ompl+"):], step=spec.step)
    else:
        problem.use_sampler(name)
    start = time.perf_counter()
    success = problem.solve(spec.params["budget"])
    seconds = time.perf_counter() - start
    if success:  # OMPL's path is checked at OMPL's resolution; hold it to ours, as our planner's paths are held
        path = problem.solution_for_oracle()  # OMPL's own motions (it does not wrap angles), not short-way edges
        success = bool(oracle.edges_free(path[:-1], path[1:], oracle.resolution / 4).all())
    return {"success": float(success), "seconds": seconds, "collision_checks": oracle.checks}


def specs(scenes, methods, seeds, budget, step) -> list[TrialSpec]:
    from app.bench.plan import default_step

    out = []
    for scene in scenes:
        a = step or default_step(scene)
        for method in methods:
            experiment = "prm" if method.startswith("ours:") else "ompl"
            name = method.split(":", 1)[1] if experiment == "prm" else method
            params = {"budget": budget}
            if experiment == "prm":
                params.update(mode="budget", full_roadmap=False)  # our planner as `plan` runs it
            out.extend(TrialSpec(experiment, scene, name, a, seed, params) for seed in range(seeds))
    return out


def summarise(rows) -> list[dict]:
    cells = {}
    for r in rows:
        label = r["method"] if r["experiment"] == "ompl" else f"ours:{r['method']}"
        cells.setdefault((r["scene"], label), []).append(r["metrics"])
    table = []
    for (scene, method), metrics in sorted(cells.items()):
        ok = np.array([m["success"] for m in metrics], bool)
        seconds = np.array([m["seconds"] for m in metrics])
        checks = np.array([m["collision_checks"] for m in metrics])
        table.append({"scene": scene, "method": method, "runs": len(metrics), "success_rate": float(ok.mean()),
                      "median_seconds": float(np.median(seconds)),
                      "median_seconds_solved": float(np.median(seconds[ok])) if ok.any() else None,
                      "median_checks": float(np.median(checks))})
    return table


def run(args) -> int:
    from app.bench.runner import sweep
    from app.ompl_bridge import _ompl

    _ompl()  # a missing OMPL is one clear line before anything runs
    scenes = [s.strip() for s in args.scenes.split(",")]
    methods = [m.strip() for m in args.methods.split(",")]
    todo = specs(scenes, methods, args.seeds, args.budget, args.step)
    table = summarise(sweep(todo, args.store, workers=args.workers, desc="bench ompl"))
    if args.json:
        print_json({"ompl": table, "budget_seconds": args.budget, "seeds": args.seeds})
        return 0
    print(f"budget {args.budget:g} s per run, {args.seeds} seeds, same Drake oracle for every method")
    print(f"{'scene':<9} {'method':<15} {'success':>8} {'median s':>9} {'s (solved)':>11} {'median checks':>14}")
    for r in table:
        solved = f"{r['median_seconds_solved']:.2f}" if r["median_seconds_solved"] is not None else "-"
        print(f"{r['scene']:<9} {r['method']:<15} {r['success_rate']:>8.0%} {r['median_seconds']:>9.2f} "
              f"{solved:>11} {r['median_checks']:>14.0f}")
    return 0
