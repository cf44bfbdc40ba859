"""`bench queries`: many queries in one cell, answered by fresh single queries, one persistent cell roadmap, OMPL's
multi-query PRM and OMPL's RRTConnect (app.bench.queries)."""

from app.bench.queries import GOALS, METHODS, MIXES, Settings, check_methods, figure, measure, per_query_words
from app.bench.statistics import shown
from app.commands.bench import results
from app.commands.common import (
    BUDGET_HELP,
    answering,
    check_outputs,
    names_from,
    parse_budget,
    parse_build_budget,
    positive_float,
    print_json,
    processes,
    repetitions,
    seed,
    whole_number,
)
from app.scene.model import scene_names


def register(kinds) -> None:
    p = kinds.add_parser(
        "queries",
        help="many queries in one cell: fresh single queries vs one persistent roadmap vs OMPL's PRM (graph kept) "
        "and RRTConnect, through one oracle; build, per-query checks and time, success, certified share",
    )
    p.add_argument(
        "--scenes",
        type=names_from(scene_names(), "scene"),
        default="window,welding",
        help="comma-separated shipped scenes, each a cell in which --queries queries are made and answered (default "
        "window,welding)",
    )
    p.add_argument("--queries", type=repetitions, default=100, help="queries per scene")
    p.add_argument("--seed", type=seed, default=0, help="of the query set and every planner")
    p.add_argument("--methods", type=names_from(METHODS, "methods"), default=",".join(METHODS), help=", ".join(METHODS))
    p.add_argument(
        "--budget",
        type=parse_budget,
        default="200kchecks",
        help="each of our queries (fresh, cell): checks decide, so results do not depend on the machine; as plan's "
        f"--budget: {BUDGET_HELP}",
    )
    p.add_argument(
        "--ompl-seconds",
        type=positive_float,
        default=10.0,
        help="each OMPL query's seconds (OMPL's planners stop on time, not on checks)",
    )
    p.add_argument("--build-nodes", type=whole_number(2, 10**7), default=1500, help="the cell roadmap's nodes")
    p.add_argument("--build-budget", type=parse_build_budget, default="3Mchecks", help="what the cell build may spend")
    p.add_argument("--workers", type=processes, default=1, help="processes building the cell roadmap")
    p.add_argument(
        "--mix",
        choices=MIXES,
        default="own",
        help="the UR3 cells' queries: own (a work cell's sequence of tool poses, chained) or held-out (each from its "
        "own start, a random free configuration or a hard posture, to a moved named pose: queries unlike those "
        "the build's cover answers)",
    )
    results.add_arguments(p, "out/bench-queries.sqlite")
    p.add_argument("--png", default=None, metavar="FILE", help="figure: per-query seconds per method (log scale)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    methods = check_methods(args.methods)
    check_outputs(args.png, creating_folders=(args.store,))
    settings = Settings(
        queries=args.queries,
        seed=args.seed,
        budget=args.budget,
        ompl_seconds=args.ompl_seconds,
        build_nodes=args.build_nodes,
        build_budget=args.build_budget,
        workers=args.workers,
        mix=args.mix,
    )
    report, reuse = measure(args.scenes, methods, settings, args.store, fresh=args.fresh)
    results.say_reused(reuse)
    with answering():  # the figure and what is printed are the answer
        if args.png:
            figure(report, args.png)
        if args.json:
            print_json({**report, "reused": reuse.to_json()})
            return 0
        print(table(report))
        if args.png:
            print(f"\nfigure: {args.png}")
        return 0


def table(report: dict) -> str:
    """The report as a markdown table per scene (checks first, then seconds) and the ratios the issue's goals name."""
    lines = [
        f"{report['queries']} queries per scene (seed {report['seed']}); ours (fresh, cell) {report['budget']} per "
        f"query, answers smoothed, certified and time-parameterised; OMPL {report['ompl_seconds']:g} s per query, "
        f"answers smoothed, neither certified nor time-parameterised. Medians and p95 over all queries (a failure "
        f"counts what it spent); build: cell {report['build_nodes']} nodes within {report['build_budget']}, "
        f"ompl-prm growRoadmap for the cell build's seconds."
    ]
    for s in report["scenes"]:
        qs = s["query_set"]
        lines += [
            "",
            f"### {s['scene']}: {qs['count']} queries ({qs['hard']} in the hard region), set {qs['digest']}",
            f"{qs['kind']}",
            "",
            "| method | build s | build checks | nodes/edges | checks median | checks p95 | s median "
            "| (certify+timing) | s p95 | success | certified | total checks | total s |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        ]
        notes = []
        for r in s["methods"]:
            b = r["build"]
            build = [f"{b['seconds']:.1f}", f"{b['checks']}", f"{b['nodes']}/{b['edges']}"] if b else ["-", "-", "-"]
            lines.append(
                "| "
                + " | ".join(
                    [r["method"], *build]
                    + [
                        shown(r["median_checks"], ".0f"),
                        shown(r["p95_checks"], ".0f"),
                        shown(r["median_seconds"], ".3f"),
                        shown(r["median_certify_timing_seconds"], ".3f"),
                        shown(r["p95_seconds"], ".3f"),
                        f"{r['successes']}/{r['queries']}",
                        shown(r["certified_share"], ".0%"),
                        f"{r['total_checks']}",
                        f"{r['total_seconds']:.1f}",
                    ]
                )
                + " |"
            )
            if r["failed_fine_check"]:
                notes.append(
                    f"{r['method']}: {r['failed_fine_check']} of its answers not free at our fine step "
                    f"(1/4 of the resolution; checked apart)"
                )
        lines += [f"\n{note}" for note in notes]
        for q in s["ratios"]:
            lines.append(
                f"\n{q['of']} / {q['over']} total: checks {shown(q['checks'], '.3g')}x, seconds "
                f"{shown(q['seconds'], '.3g')}x (goal <= {q['goal_seconds']:g}x); with the builds: checks "
                f"{shown(q['checks_with_builds'], '.3g')}x, seconds {shown(q['seconds_with_builds'], '.3g')}x; over "
                f"the {q['both_answered']} queries both answered: checks {shown(q['checks_both_answered'], '.3g')}x, "
                f"seconds {shown(q['seconds_both_answered'], '.3g')}x"
            )
            if q["per_query"] is not None:
                lines.append(f"\nqueries over {GOALS['query vs fresh']:g}x fresh: {per_query_words(q['per_query'])}")
    return "\n".join(lines)
