"""`bench ompl`: our planner beside OMPL's RRTConnect, BIT*, PRM and KPIECE1 on the same oracle and budget
(app.bench.ompl)."""

import argparse

from app.bench.ompl import DEFAULT_METHODS, MORE_METHODS, OURS, figure, measure, parse_method
from app.bench.statistics import shown
from app.commands.bench import results
from app.commands.common import (
    announce,
    answering,
    budget_seconds,
    check_outputs,
    comma_list,
    positive_float,
    print_json,
    processes,
    repetitions,
)
from app.errors import UserError
from app.scene.model import scene_names


def method_names(text: str) -> list[str]:
    """Comma-separated methods of app.bench.ompl.parse_method."""
    names = comma_list(text)
    for name in names:
        try:
            parse_method(name)
        except UserError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    return names


def register(kinds) -> None:
    p = kinds.add_parser(
        "ompl",
        help="our planner vs OMPL's RRTConnect, BIT*, PRM and KPIECE1: same oracle, same "
        "budget; checks to the first solution, smoothing, success",
    )
    p.add_argument(
        "--scenes",
        type=comma_list,
        default=",".join(scene_names()),
        help="comma-separated scenes (shipped scene names or problem files) whose own start-to-goal query each "
        "method plans, once per seed (default: every shipped scene, see `python -m app scenes`)",
    )
    p.add_argument(
        "--methods",
        type=method_names,
        default=",".join(DEFAULT_METHODS),
        help=f"comma-separated; also ours:SAMPLER[:full] and {', '.join(MORE_METHODS)}",
    )
    p.add_argument("--seeds", type=repetitions, default=20, help="runs 0..N-1 per scene and method")
    p.add_argument("--budget", type=budget_seconds, default=10.0, help="seconds per run to the first solution")
    p.add_argument("--step", type=positive_float, default=None, help="sampler step (default: the scene's)")
    p.add_argument(
        "--workers",
        type=processes,
        default=1,
        help="parallel runs (1 keeps timings clean: each run gets a whole core and nothing competes)",
    )
    results.add_arguments(p, "out/bench-ompl.sqlite")
    p.add_argument(
        "--png",
        default=None,
        metavar="FILE",
        help="figure: success rate vs median checks to the first solution, one panel per scene",
    )
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    check_outputs(args.png, creating_folders=(args.store,))
    report, reuse = measure(
        args.scenes,
        args.methods,
        args.seeds,
        args.budget,
        args.step,
        args.store,
        workers=args.workers,
        fresh=args.fresh,
    )
    results.say_reused(reuse, args.store)
    with answering():  # the figure and what is printed are the answer
        if args.png:
            figure(report, args.png)
            announce(args.png)
        if args.json:
            print_json({**report, "reused": reuse.to_json()})
            return 0
        print(
            f"{args.seeds} runs per scene and method, {args.budget:g} s budget each, one Drake oracle counting every "
            f"check. success: a path within the budget, free at 1/4 of the scene's resolution after smoothing (with "
            f"its 95 % binomial interval). Medians over successful runs: checks and seconds to the first solution, "
            f"smoothing checks, path length after smoothing (our metric)"
        )
        for s in report["scenes"]:
            print(f"\n{s['scene']}")
            for m in s["motion_checks"]:
                fractions = m["fractions"]
                told = (
                    f"fraction {fractions[0]:.3g}"
                    if len(fractions) == 1
                    else f"fractions {min(fractions):.3g}-{max(fractions):.3g} over {len(fractions)} subspaces"
                )
                users = ", ".join(u.split(":", 1)[1] for u in m["methods"])
                print(
                    f"  OMPL motion checks, {m['space']} space ({users}): {told}; on {m['edges']} random edges the "
                    f"largest spacing is {m['max_spacing_over_resolution']:.3f} r and OMPL checks "
                    f"{m['checks_over_exact_median']:.2f}x (median; p90 {m['checks_over_exact_p90']:.2f}x) the states "
                    f"of an exact r spacing"
                )
            print(
                f"  {'method':<22} {'success':>7} {'95 % CI':>11} {'checks':>9} {'seconds':>8} {'checks/s':>9} "
                f"{'smoothing':>10} {'length':>9}  notes"
            )
            for r in s["methods"]:
                lo, hi = r["success_ci"]
                notes = []
                if r["failed_fine_check"]:
                    notes.append(
                        f"{r['failed_fine_check']} failed the fine check "
                        f"({r['failed_fine_check_after_smoothing']} only after smoothing)"
                    )
                if r["late"]:
                    notes.append(f"{r['late']} solved after the budget")
                print(
                    f"  {r['method']:<22} {str(r['successes']) + '/' + str(r['runs']):>7} "
                    f"{f'{lo:.0%}-{hi:.0%}':>11} {shown(r['median_checks'], '.0f'):>9} "
                    f"{shown(r['median_seconds'], '.2f'):>8} {shown(r['median_checks_per_second'], '.0f'):>9} "
                    f"{shown(r['median_smoothing_checks'], '.0f'):>10} "
                    f"{shown(r['median_path_length'], '.4g'):>9}  {'; '.join(notes)}"
                )
            c = s["comparison"]
            if c["best_ompl"] is None or not any(r["method"] == OURS for r in s["methods"]):
                continue
            if c["checks_ratio"] is None:
                print(f"  {OURS} / best OMPL ({c['best_ompl']}) median checks: - (one of them never succeeded)")
            else:
                print(
                    f"  {OURS} / best OMPL ({c['best_ompl']}) median checks to the first solution: "
                    f"{c['checks_ratio']:.3g}x  (best: most successes, ties broken by fewer median checks)"
                )
        return 0
