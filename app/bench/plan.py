"""`bench plan`: PRM success rate and time per narrow-passage sampler, at one fixed roadmap size, over many seeds.

Each trial is one `app.planner.plan` call (up to narrow + uniform samples, no budget; `--full-roadmap` for the
paper's protocol of the whole roadmap first) on a per-process oracle;
rows go to the results store (`experiment` "prm"), so a killed run resumes and the claims report can read them.
`run_trial_spec` also serves other benchmarks: params {"mode": "budget", "budget": seconds} plans in rounds until
connected or out of time (as `plan --budget 30s`).
"""
import time

import numpy as np

from app.bench.store import TrialSpec
from app.cli import non_negative_int, positive_float, positive_int, print_json
from app.planner import PlanSettings

SAMPLERS = ["uniform", "gaussian", "rbbs", "lfbs"]
# What a plain `plan` does: the same roadmap size, k (None: k-PRM*) and smoothing.
SIZE = {"narrow": PlanSettings.narrow, "uniform": PlanSettings.uniform, "k": PlanSettings.k,
        "smooth": PlanSettings.smooth_rounds}


def register(kinds) -> None:
    p = kinds.add_parser("plan", help="PRM success rate and median time per sampler (fixed roadmap size)")
    p.add_argument("--scenes", default="bar,joint3d", help="comma-separated scene names")
    p.add_argument("--samplers", default=",".join(SAMPLERS), help="comma-separated sampler names")
    p.add_argument("--seeds", type=positive_int, default=50, help="seeds 0..N-1 per scene and sampler")
    p.add_argument("--narrow", type=non_negative_int, default=SIZE["narrow"],
                   help="narrow-passage samples per roadmap (uniform: that many more uniform samples)")
    p.add_argument("--uniform", type=non_negative_int, default=SIZE["uniform"], help="uniform samples per roadmap")
    p.add_argument("-k", "--neighbours", type=positive_int, default=SIZE["k"],
                   help="k nearest neighbours (default: k-PRM*'s, as `plan`)")
    p.add_argument("--smooth", type=non_negative_int, default=SIZE["smooth"], help="random shortcut rounds")
    p.add_argument("--step", type=positive_float, default=None, help="sampler step (default: the scene's)")
    p.add_argument("--budget", type=positive_float, default=None, metavar="SECONDS",
                   help="instead of one round, add samples in rounds until connected or this many seconds pass")
    p.add_argument("--roadmap", choices=["query", "full", "both"], default="query",
                   help="query: the planner's default (lazy, a quarter at a time until connected); full: the whole "
                        "roadmap, every edge checked (the paper's protocol); both: side by side")
    p.add_argument("--workers", type=positive_int, default=1,
                   help="parallel processes (1 keeps timings clean and checks on all threads; with more, one thread "
                        "each)")
    p.add_argument("--store", default="out/bench-plan.sqlite", help="results store (resumes a killed run)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def default_step(scene) -> float:
    """The planner's default sampler step for a scene name, Scene or oracle."""
    from app.planner import default_step as step_of

    if isinstance(scene, str):
        from app.scene import Scene

        scene = Scene(scene)
    return step_of(scene)


def run_trial_spec(oracle, spec: TrialSpec) -> dict:
    """One plan: success, seconds (whole pipeline), seconds to a path, checks, roadmap and path facts."""
    from app.budget import Budget
    from app.errors import NoPath
    from app.planner import plan

    p = spec.params
    budget = Budget(seconds=float(p["budget"])) if p.get("mode") == "budget" else None
    narrow = int(p.get("narrow", SIZE["narrow"]))
    uniform = int(p.get("uniform", SIZE["uniform"]))
    if spec.method == "uniform":  # the same roadmap size, all of it uniform
        narrow, uniform = 0, narrow + uniform
    checks0, start = oracle.checks, time.perf_counter()
    try:
        r = plan(oracle, PlanSettings(sampler=spec.method, narrow=narrow, uniform=uniform, step=spec.step,
                                      seed=spec.seed, budget=budget, k=p.get("k", SIZE["k"]),
                                      smooth_rounds=int(p.get("smooth", SIZE["smooth"])),
                                      full_roadmap=bool(p["full_roadmap"])))
    except NoPath as exc:
        d = getattr(exc, "details", {})
        return {"success": 0.0, "seconds": time.perf_counter() - start, "seconds_to_path": None,
                "collision_checks": oracle.checks - checks0, "nodes": d.get("roadmap", {}).get("nodes"),
                "components": d.get("roadmap", {}).get("components"), "rounds": d.get("rounds")}
    s = r.seconds
    return {"success": 1.0, "seconds": s["total"], "seconds_sampling": s["sampling"],
            "seconds_to_path": s["sampling"] + s["roadmap"] + s["search"],
            "collision_checks": r.collision_checks, "nodes": r.roadmap["nodes"],
            "components": r.roadmap["components"], "rounds": r.rounds, "narrow_on_path": r.narrow_on_path,
            "path_length": r.smoothing["length_after"], "duration": r.trajectory.duration}


def specs(scenes, samplers, seeds, params, step) -> list[TrialSpec]:
    out = []
    for scene in scenes:
        a = step or default_step(scene)
        out.extend(TrialSpec("prm", scene, m, a, seed, dict(params)) for m in samplers for seed in range(seeds))
    return out


def summarise(rows) -> list[dict]:
    cells = {}
    for r in rows:
        mode = "full" if r["params"]["full_roadmap"] else "query"
        cells.setdefault((r["scene"], r["method"], mode), []).append(r["metrics"])
    table = []
    for (scene, method, mode), metrics in cells.items():
        ok = np.array([m["success"] for m in metrics], bool)
        seconds = np.array([m["seconds"] for m in metrics])
        checks = np.array([m["collision_checks"] for m in metrics])
        to_path = np.array([m["seconds_to_path"] for m in metrics if m["success"]])
        narrow = np.array([m["narrow_on_path"] for m in metrics if m["success"]])
        table.append({"scene": scene, "sampler": method, "roadmap": mode, "runs": len(metrics),
                      "successes": int(ok.sum()),
                      "success_rate": float(ok.mean()), "median_seconds": float(np.median(seconds)),
                      "median_seconds_to_path": float(np.median(to_path)) if ok.any() else None,
                      "median_checks": float(np.median(checks)),
                      "median_narrow_on_path": float(np.median(narrow)) if ok.any() else None})
    return table


def run(args) -> int:
    from app.bench.runner import sweep
    from app.errors import UserError
    from app.samplers import SAMPLERS as KNOWN

    scenes = [s.strip() for s in args.scenes.split(",") if s.strip()]
    samplers = [s.strip() for s in args.samplers.split(",") if s.strip()]
    unknown = [s for s in samplers if s not in KNOWN]
    if unknown or not samplers or not scenes:
        raise UserError(f"unknown sampler '{unknown[0]}' (known: {', '.join(KNOWN)})" if unknown
                        else "need at least one scene and one sampler")
    params = {"narrow": args.narrow, "uniform": args.uniform, "k": args.neighbours, "smooth": args.smooth}
    if args.budget is not None:
        params.update(mode="budget", budget=args.budget)
    modes = ["query", "full"] if args.roadmap == "both" else [args.roadmap]
    todo = []
    for mode in modes:
        todo += specs(scenes, samplers, args.seeds, {**params, "full_roadmap": mode == "full"}, args.step)
    rows = sweep(todo, args.store, workers=args.workers, desc="bench plan")
    order = {key: i for i, key in enumerate((sc, sa, mode) for sc in scenes for sa in samplers for mode in modes)}
    table = sorted(summarise(rows), key=lambda r: order.get((r["scene"], r["sampler"], r["roadmap"]), 1e9))
    if args.json:
        print_json({"plan": table, "seeds": args.seeds, "params": params})
        return 0
    budget = f"; with a budget, rounds go on until connected or {args.budget:g} s" if args.budget is not None else ""
    print(f"{args.seeds} seeds; up to {args.narrow} narrow + {args.uniform} uniform samples (uniform row: all "
          f"{args.narrow + args.uniform} uniform), k {args.neighbours or 'k-PRM*'}, {args.smooth} shortcut rounds; "
          f"query: lazy edges, a quarter of the samples at a time until connected; full: the whole roadmap, every "
          f"edge checked{budget}")
    print(f"{'scene':<9} {'sampler':<9} {'roadmap':<8} {'success':>8} {'median s':>9} {'s to path':>10} "
          f"{'median checks':>14} {'narrow on path':>15}")
    for r in table:
        to_path = f"{r['median_seconds_to_path']:.2f}" if r["median_seconds_to_path"] is not None else "-"
        narrow = f"{r['median_narrow_on_path']:.0f}" if r["median_narrow_on_path"] is not None else "-"
        print(f"{r['scene']:<9} {r['sampler']:<9} {r['roadmap']:<8} {r['success_rate']:>8.0%} "
              f"{r['median_seconds']:>9.2f} {to_path:>10} {r['median_checks']:>14.0f} {narrow:>15}")
    cells = {(r["scene"], r["sampler"], r["roadmap"]): r for r in table}
    for (scene, sampler, mode), r in cells.items():
        full = cells.get((scene, sampler, "full"))
        if mode == "query" and full:
            print(f"{scene} {sampler}: query/full median time {r['median_seconds'] / full['median_seconds']:.2f}x, "
                  f"checks {r['median_checks'] / full['median_checks']:.2f}x, success {r['success_rate']:.0%} vs "
                  f"{full['success_rate']:.0%}")
    return 0
