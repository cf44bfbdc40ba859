"""`bench oracle`: oracle checks/s against a raw HasCollisions loop (app.bench.oracle)."""

from app.bench.oracle import bench_oracle
from app.commands.common import answering, check_count, comma_list, print_json, repetitions, seed


def register(kinds) -> None:
    o = kinds.add_parser("oracle", help="oracle checks/s vs raw HasCollisions on 1 and 2 cores")
    o.add_argument(
        "--scenes",
        type=comma_list,
        default="bar,joint3d",
        help="comma-separated scene names, problem files or custom scene files (robot/env keys)",
    )
    o.add_argument("-n", type=check_count, default=20000, help="configurations per measurement")
    o.add_argument("--repeats", type=repetitions, default=5, help="runs per measurement (the median counts)")
    o.add_argument("--seed", type=seed, default=0)
    o.add_argument("--json", action="store_true")
    o.set_defaults(func=run)


def run(args) -> int:
    rows = bench_oracle(args.scenes, n=args.n, repeats=args.repeats, seed=args.seed)
    with answering():
        if args.json:
            print_json({"oracle": rows})
            return 0
        print(
            f"{'scene':<10} {'raw k/s':>9} {'1 thread k/s':>13} {'ratio':>6} {'2 cores k/s':>12} {'ratio':>6} "
            f"{'us/check (1)':>13} {'in Drake (1)':>13} {'load s (first/cached)':>22}"
        )
        for r in rows:
            print(
                f"{r['scene']:<10} {r['raw_per_s'] / 1e3:>9.1f} {r['oracle_1_per_s'] / 1e3:>13.1f} "
                f"{r['ratio_1']:>6.2f} {r['oracle_2_per_s'] / 1e3:>12.1f} {r['ratio_2']:>6.2f} "
                f"{r['us_per_check_1']:>13.1f} {r['drake_share_1']:>13.0%} "
                f"{r['load_first_s']:>11.2f}/{r['load_cached_s']:.2f}"
            )
        return 0
