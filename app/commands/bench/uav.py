"""`bench uav`: the paper's maze and tunnel PRM tables, LFBS vs RBBS (app.bench.uav)."""

from app.bench.uav import PAPER_SECONDS, measure
from app.commands.bench import results
from app.commands.common import answering, check_outputs, print_json, processes, repetitions


def register(kinds) -> None:
    p = kinds.add_parser("uav", help="the paper's maze/tunnel PRM tables: LFBS vs RBBS, t_eps, T_PRM, success")
    p.add_argument("--seeds", type=repetitions, default=30)
    p.add_argument("--workers", type=processes, default=1, help="parallel processes (1 keeps timings clean)")
    results.add_arguments(p, "out/bench-uav.sqlite")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    check_outputs(creating_folders=(args.store,))
    result, reuse = measure(args.seeds, args.store, workers=args.workers, fresh=args.fresh)
    results.say_reused(reuse, args.store)
    with answering():
        if args.json:
            print_json({"uav": result, "seeds": args.seeds, "reused": reuse.to_json()})
            return 0
        print(
            f"{args.seeds} seeds per cell; whole roadmap, every edge checked, k 10 (maze 200 + 300, tunnel 100 + 200 "
            "samples); t_eps = narrow+uniform sampling time of successful runs, T_PRM = whole plan; "
            "paper's seconds in brackets; gave up: runs whose sampler spent its own cap of checks and built no roadmap "
            "(censored, not PRM failures)"
        )
        print(
            f"{'scene':<7} {'step':>5} {'sampler':<8} {'success':>8} {'gave up':>8} {'t_eps s':>9} {'T_PRM s':>9} "
            f"{'checks':>9} {'paper t_eps':>12} {'paper T_PRM':>12}"
        )
        for r in result:
            paper = PAPER_SECONDS.get((r["scene"], r["step"]))
            t_eps, t_prm = (
                (paper[0], paper[1])
                if paper and r["sampler"] == "lfbs"
                else (paper[2], paper[3])
                if paper
                else (None, None)
            )
            eps = f"{r['median_t_eps']:.2f}" if r["median_t_eps"] is not None else "-"
            print(
                f"{r['scene']:<7} {r['step']:>5g} {r['sampler']:<8} {r['success_rate']:>8.0%} "
                f"{r['sampler_gave_up']:>8} {eps:>9} "
                f"{r['median_t_prm']:>9.2f} {r['median_checks']:>9.0f} {t_eps!s:>12} {t_prm!s:>12}"
            )
        return 0
