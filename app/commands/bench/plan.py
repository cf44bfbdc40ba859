"""`bench plan`: PRM success rate and median time per sampler at one roadmap size (app.bench.plan)."""

from app.bench.plan import COMPARED_SAMPLERS, MODES, SIZE, measure, trial_params
from app.commands.bench import results
from app.commands.common import (
    answering,
    budget_seconds,
    check_outputs,
    comma_list,
    known_samplers,
    neighbours,
    positive_float,
    print_json,
    processes,
    repetitions,
    sample_count,
    sampler_names,
    share,
    shortcut_rounds,
)


def register(kinds) -> None:
    p = kinds.add_parser("plan", help="PRM success rate and median time per sampler (fixed roadmap size)")
    p.add_argument(
        "--scenes",
        type=comma_list,
        default="bar,joint3d",
        help="comma-separated scenes (shipped scene names or problem files) whose own start-to-goal query each "
        "sampler plans, once per seed (default bar,joint3d)",
    )
    p.add_argument(
        "--samplers",
        type=sampler_names,
        default=",".join(COMPARED_SAMPLERS),
        help=f"comma-separated sampler names, of {known_samplers()}",
    )
    p.add_argument("--seeds", type=repetitions, default=50, help="seeds 0..N-1 per scene and sampler")
    p.add_argument(
        "--narrow",
        type=sample_count,
        default=SIZE["narrow"],
        help="narrow-passage samples per roadmap (uniform: that many more uniform samples)",
    )
    p.add_argument("--uniform", type=sample_count, default=SIZE["uniform"], help="uniform samples per roadmap")
    p.add_argument(
        "-k",
        "--neighbours",
        type=neighbours,
        default=SIZE["k"],
        help="k nearest neighbours (default: k-PRM*'s, as `plan`)",
    )
    p.add_argument("--smooth", type=shortcut_rounds, default=SIZE["smooth"], help="random shortcut rounds")
    p.add_argument("--step", type=positive_float, default=None, help="sampler step (default: the scene's)")
    p.add_argument(
        "--budget",
        type=budget_seconds,
        default=None,
        metavar="SECONDS",
        help="instead of one round, add samples in rounds until connected or this many seconds pass",
    )
    p.add_argument(
        "--workspace",
        type=share,
        default=None,
        help="share of the narrow-passage samples placed with a piece of the robot in a narrow gap of the "
        "workspace, on a query roadmap (0: the sampler alone; default: the planner's, as `plan`)",
    )
    p.add_argument(
        "--roadmap",
        choices=[*MODES, "both"],
        default="query",
        help="query: the planner's default (lazy, a quarter at a time until connected); full: the whole "
        "roadmap, every edge checked (the paper's protocol); both: side by side",
    )
    p.add_argument(
        "--workers",
        type=processes,
        default=1,
        help="parallel processes (1 keeps timings clean and checks on all threads; with more, one thread each)",
    )
    results.add_arguments(p, "out/bench-plan.sqlite")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    check_outputs(creating_folders=(args.store,))
    params = trial_params(
        args.narrow, args.uniform, args.neighbours, args.smooth, budget=args.budget, workspace=args.workspace
    )
    modes = list(MODES) if args.roadmap == "both" else [args.roadmap]
    table, reuse = measure(
        args.scenes,
        args.samplers,
        args.seeds,
        params,
        args.store,
        modes=modes,
        step=args.step,
        workers=args.workers,
        fresh=args.fresh,
    )
    results.say_reused(reuse, args.store)
    with answering():
        if args.json:
            print_json({"plan": table, "seeds": args.seeds, "params": params, "reused": reuse.to_json()})
            return 0
        settings = ""
        if args.budget is not None:
            settings = f"; with a budget, rounds go on until connected or {args.budget:g} s"
        if args.workspace is not None:
            settings += f"; {args.workspace:g} of the narrow samples placed in workspace gaps"
        print(
            f"{args.seeds} seeds; up to {args.narrow} narrow + {args.uniform} uniform samples (uniform row: all "
            f"{args.narrow + args.uniform} uniform), k {args.neighbours or 'k-PRM*'}, {args.smooth} shortcut rounds; "
            f"query: lazy edges, a quarter of the samples at a time until connected; full: the whole roadmap, every "
            f"edge checked{settings}"
        )
        print(
            f"{'scene':<9} {'sampler':<9} {'roadmap':<8} {'success':>8} {'median s':>9} {'s to path':>10} "
            f"{'median checks':>14} {'narrow on path':>15} {'checks/s':>9} {'in Drake':>9} {'of raw':>7}"
        )
        for r in table:
            to_path = f"{r['median_seconds_to_path']:.2f}" if r["median_seconds_to_path"] is not None else "-"
            narrow = f"{r['median_narrow_on_path']:.0f}" if r["median_narrow_on_path"] is not None else "-"
            drake = f"{r['median_drake_share']:.0%}" if r["median_drake_share"] is not None else "-"
            of_raw = f"{r['median_of_raw']:.2f}" if r.get("median_of_raw") is not None else "-"
            print(
                f"{r['scene']:<9} {r['sampler']:<9} {r['roadmap']:<8} {r['success_rate']:>8.0%} "
                f"{r['median_seconds']:>9.2f} {to_path:>10} {r['median_checks']:>14.0f} {narrow:>15} "
                f"{r['median_checks_per_second']:>9.0f} {drake:>9} {of_raw:>7}"
            )
        cells = {(r["scene"], r["sampler"], r["roadmap"]): r for r in table}
        for (scene, sampler, mode), r in cells.items():
            full = cells.get((scene, sampler, "full"))
            if mode == "query" and full:
                print(
                    f"{scene} {sampler}: query/full median time {r['median_seconds'] / full['median_seconds']:.2f}x, "
                    f"checks {r['median_checks'] / full['median_checks']:.2f}x, success {r['success_rate']:.0%} vs "
                    f"{full['success_rate']:.0%}"
                )
        return 0
