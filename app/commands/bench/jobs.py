"""`bench jobs`: the UR3 welding and window runs timed end to end, query mode vs full roadmap (app.bench.jobs)."""

from app.bench.jobs import JOBS, measure
from app.bench.plan import MODES
from app.commands.bench import results
from app.commands.common import (
    answering,
    budget_seconds,
    check_outputs,
    known_samplers,
    names_from,
    print_json,
    repetitions,
    sample_count,
    sampler_names,
)


def register(kinds) -> None:
    p = kinds.add_parser("jobs", help="UR3 welding/window runs timed end to end; query vs full roadmap side by side")
    p.add_argument(
        "--jobs", type=names_from(JOBS, "job"), default=",".join(JOBS), help="comma-separated: welding, window"
    )
    p.add_argument(
        "--samplers", type=sampler_names, default="lfbs", help=f"comma-separated sampler names, of {known_samplers()}"
    )
    p.add_argument("--seeds", type=repetitions, default=10, help="seeds 0..N-1 per job, sampler and mode")
    p.add_argument(
        "--roadmap",
        choices=[*MODES, "both"],
        default="both",
        help="query: the planner's default; full: the whole roadmap first; both: side by side",
    )
    p.add_argument("--narrow", type=sample_count, default=40, help="narrow-passage samples per planned leg")
    p.add_argument("--uniform", type=sample_count, default=40, help="uniform samples per planned leg")
    p.add_argument("--budget", type=budget_seconds, default=30.0, metavar="SECONDS", help="per planned leg")
    results.add_arguments(p, "out/bench-jobs.sqlite")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    check_outputs(creating_folders=(args.store,))
    modes = list(MODES) if args.roadmap == "both" else [args.roadmap]
    result, reuse = measure(
        args.jobs, args.samplers, args.seeds, modes, args.narrow, args.uniform, args.budget, args.store, args.fresh
    )
    results.say_reused(reuse, args.store)
    with answering():
        if args.json:
            print_json({"jobs": result, "seeds": args.seeds, "reused": reuse.to_json()})
            return 0
        print(
            f"{args.seeds} seeds; per planned leg up to {args.narrow} narrow + {args.uniform} uniform samples, "
            f"{args.budget:g} s budget; seconds are IK + planning + smoothing + Toppra, medians (min-max) of successes"
        )
        print(
            f"{'job':<8} {'sampler':<8} {'roadmap':<8} {'success':>8} {'median s':>9} {'min-max s':>12} {'IK s':>6} "
            f"{'checks':>8}"
        )
        cells = {(r["job"], r["sampler"], r["roadmap"]): r for r in result}
        for r in result:
            total = "-" if r["median_total"] is None else f"{r['median_total']:.2f}"
            spread = "-" if r["min_total"] is None else f"{r['min_total']:.2f}-{r['max_total']:.2f}"
            ik = "-" if r["median_ik"] is None else f"{r['median_ik']:.2f}"
            print(
                f"{r['job']:<8} {r['sampler']:<8} {r['roadmap']:<8} {r['successes']:>4}/{r['runs']:<3} {total:>9} "
                f"{spread:>12} {ik:>6} {r['median_checks']:>8.0f}"
            )
        for (job, sampler, mode), r in cells.items():
            full = cells.get((job, sampler, "full"))
            if mode == "query" and full and r["median_total"] and full["median_total"]:
                print(
                    f"{job} {sampler}: the query mode takes {r['median_total'] / full['median_total']:.2f}x the full "
                    f"roadmap's median time and {r['median_checks'] / full['median_checks']:.2f}x its checks"
                )
        return 0
