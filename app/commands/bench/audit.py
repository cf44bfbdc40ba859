"""`bench audit`: random problems in every shipped scene, every returned trajectory re-checked by an independent
Drake checker at 1/64 of the scene's resolution, with its limits and endpoints (app.bench.audit)."""

from app.bench.audit import DIVISOR, measure
from app.commands.bench import results
from app.commands.common import check_outputs, names_from, positive_float, print_json, processes, repetitions, seed
from app.scene.model import scene_names


def register(kinds) -> None:
    p = kinds.add_parser("audit", help="random problems per scene; trajectories re-checked by an independent checker")
    p.add_argument("--problems", type=repetitions, default=200, help="problems in all, shared out over the scenes")
    p.add_argument("--seed", type=seed, default=0, help="seeds the problems' starts and goals")
    p.add_argument(
        "--scenes", type=names_from(scene_names(), "scene"), default=",".join(scene_names()), help="comma-separated"
    )
    p.add_argument("--budget", type=positive_float, default=5.0, metavar="SECONDS", help="planning budget per problem")
    p.add_argument("--workers", type=processes, default=1, help="parallel processes (one thread each when > 1)")
    results.add_arguments(p, "out/bench-audit.sqlite")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    check_outputs(creating_folders=(args.store,))
    table, reuse = measure(
        args.scenes, args.problems, args.seed, args.budget, args.store, workers=args.workers, fresh=args.fresh
    )
    results.say_reused(reuse, args.store)
    if args.json:
        print_json(
            {
                "audit": table,
                "problems": args.problems,
                "seed": args.seed,
                "budget": args.budget,
                "reused": reuse.to_json(),
            }
        )
        return 0
    print(
        f"{args.problems} problems (seed {args.seed}), {args.budget:g} s planning budget each; every solved "
        f"trajectory re-checked at 1/{DIVISOR} of the scene's resolution by a Drake checker of its own"
    )
    print(
        f"{'scene':<10} {'problems':>8} {'solved':>7} {'certified':>9} {'colliding':>9} {'coll. states':>12} "
        f"{'max pen.':>9} {'limit viol.':>11} {'worst v/a':>9} {'bad ends':>8} {'states':>10} {'median s':>8}"
    )
    for r in table:
        seconds = "-" if r["median_seconds"] is None else f"{r['median_seconds']:.2f}"
        worst = "-" if r["worst_limit_ratio"] is None else f"{r['worst_limit_ratio']:.6f}"
        print(
            f"{r['scene']:<10} {r['problems']:>8} {r['solved']:>7} {r['certified']:>9} "
            f"{r['colliding_trajectories']:>9} {r['colliding_states']:>12} {r['max_penetration']:>9.2g} "
            f"{r['limit_violations']:>11} {worst:>9} {r['inexact_endpoints']:>8} "
            f"{r['states_checked']:>10} {seconds:>8}"
        )
    return 0
