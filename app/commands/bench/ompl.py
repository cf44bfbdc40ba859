"""`bench ompl`: OMPL's PRM with OMPL's samplers and ours, beside our own PRM, on one budget (app.bench.ompl)."""
from app.bench.ompl import OMPL_METHODS, OURS, measure
from app.commands.common import comma_list, positive_float, positive_int, print_json


def register(kinds) -> None:
    p = kinds.add_parser("ompl", help="OMPL's PRM with OMPL's and our samplers vs our PRM, same oracle and budget")
    p.add_argument("--scenes", type=comma_list, default="bar,joint3d")
    p.add_argument("--methods", type=comma_list, default=",".join(OMPL_METHODS + OURS))
    p.add_argument("--seeds", type=positive_int, default=10)
    p.add_argument("--budget", type=positive_float, default=20.0, help="seconds per run")
    p.add_argument("--step", type=positive_float, default=None, help="sampler step (default: the scene's)")
    p.add_argument("--workers", type=positive_int, default=1,
                   help="parallel runs (1 keeps timings clean: each run gets a whole core and nothing competes)")
    p.add_argument("--store", default="out/bench-ompl.sqlite")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    table = measure(args.scenes, args.methods, args.seeds, args.budget, args.step, args.store, workers=args.workers)
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
