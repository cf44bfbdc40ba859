"""`bench changes`: a work cell changes; its stored roadmap repaired against one built again, and the queries after
each change (app.bench.changes)."""

from app.bench.changes import CHANGES, DEFAULT_METHODS, GOALS, METHODS, check_methods, figure, measure
from app.bench.queries import Settings
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


def register(kinds) -> None:
    p = kinds.add_parser(
        "changes",
        help="a work cell changes (a fixture moved 1, 5, 20 cm, a box added, one removed, a part attached): the "
        "stored roadmap repaired vs built again, and queries after each change (repair, rebuild, fresh; ompl-prm on "
        "request)",
    )
    p.add_argument(
        "--scenes",
        type=names_from(sorted(CHANGES), "cell"),
        default=",".join(CHANGES),
        help=f"comma-separated shipped scenes that are work cells, each with its sequence of changes (default "
        f"{','.join(CHANGES)})",
    )
    p.add_argument("--queries", type=repetitions, default=100, help="queries after each change")
    p.add_argument("--seed", type=seed, default=0, help="of the query sets, the builds and every planner")
    p.add_argument(
        "--methods",
        type=names_from(METHODS, "methods"),
        default=",".join(DEFAULT_METHODS),
        help=f"comma-separated, of {', '.join(METHODS)} (default {','.join(DEFAULT_METHODS)}; ompl-prm re-checks "
        "OMPL's whole PRM graph after each change and stops on time only: slow)",
    )
    p.add_argument(
        "--ompl-seconds",
        type=positive_float,
        default=10.0,
        metavar="S",
        help="ompl-prm: OMPL's seconds per query (OMPL stops on time, not on checks; default 10)",
    )
    p.add_argument("--budget", type=parse_budget, default="200kchecks", help=f"each query: {BUDGET_HELP}")
    p.add_argument("--build-nodes", type=whole_number(2, 10**7), default=1500, help="the roadmaps' nodes")
    p.add_argument("--build-budget", type=parse_build_budget, default="3Mchecks", help="what a build may spend")
    p.add_argument("--workers", type=processes, default=1, help="processes building a roadmap")
    results.add_arguments(p, "out/bench-changes.sqlite")
    p.add_argument("--png", default=None, metavar="FILE", help="figure: repair vs rebuild, and query seconds")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    methods = check_methods(args.methods)
    check_outputs(args.png, creating_folders=(args.store,))
    settings = Settings(
        queries=args.queries,
        seed=args.seed,
        budget=args.budget,
        build_nodes=args.build_nodes,
        build_budget=args.build_budget,
        workers=args.workers,
        ompl_seconds=args.ompl_seconds,
    )
    report, reuse = measure(args.scenes, methods, settings, args.store, fresh=args.fresh)
    results.say_reused(reuse)
    with answering():
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
    """Per cell, a markdown row per change: repair and rebuild (checks, seconds, their ratio), what the repair
    reset, and per method the queries' success, certified answers, median seconds and colliding states."""
    lines = [
        f"{report['queries']} queries after each change (seed {report['seed']}), {report['budget']} each; roadmaps "
        f"of {report['build_nodes']} nodes. Goals: repair <= {GOALS['repair over rebuild']:g} x rebuild in checks "
        f"and seconds; median query <= {GOALS['median query seconds'] * 1000:g} ms; 0 colliding states (independent "
        "re-check at 1/64 of the resolution)."
    ]
    versions = sorted({v for s in report["scenes"] for r in s["changes"] for v in r["code_versions"].values()})
    lines.append(
        f"Code version(s) of the trials: {', '.join(f'`{v}`' for v in versions)}"
        + (" (mixed: per change and method below)" if len(versions) > 1 else "")
    )
    methods = ", ".join(report["methods"])
    prm = "ompl-prm" in report["methods"]
    if "ompl-prm" in report["methods"]:
        lines.append(
            f"ompl-prm: OMPL's PRM grown for the cell build's seconds, its graph re-checked after each change (its "
            f"preparation), then {report['ompl_seconds']:g} s per query, smoothed, never certified."
        )
    for s in report["scenes"]:
        lines += [
            "",
            f"### {s['scene']}",
            "",
            "| change | repair checks | repair s | rebuild checks | rebuild s | ratio checks | ratio s | reset "
            f"free/colliding | nodes checked/dropped | solved: {methods} | median ms: {methods} | certified "
            "| colliding states |" + (" PRM re-checked: checks | s |" if prm else ""),
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|" + ("---:|---:|" if prm else ""),
        ]
        for r in s["changes"]:
            m = r["methods"]
            repair, rebuild = (m.get(k, {}).get("prepare") or {} for k in ("repair", "rebuild"))
            record = repair.get("record", {})
            prepared = m.get("ompl-prm", {}).get("prepare") or {}
            ratio = r.get("repair_over_rebuild", {})
            solved = ", ".join(f"{m[k]['successes']}/{m[k]['queries']}" if k in m else "-" for k in report["methods"])
            ms = ", ".join(
                shown(None if k not in m or m[k]["median_seconds"] is None else 1000 * m[k]["median_seconds"], ".0f")
                for k in report["methods"]
            )
            won = sum(v["successes"] for v in m.values())
            lines.append(
                "| "
                + " | ".join(
                    [
                        r["change"],
                        shown(repair.get("checks"), ",d"),
                        shown(repair.get("seconds"), ".2f"),
                        shown(rebuild.get("checks"), ",d"),
                        shown(rebuild.get("seconds"), ".1f"),
                        shown(ratio.get("checks"), ".4f"),
                        shown(ratio.get("seconds"), ".3f"),
                        f"{record.get('edges_reset', '-')}/{record.get('colliding_reset', '-')}",
                        f"{record.get('nodes_checked', '-')}/{record.get('nodes_dropped', '-')}",
                        solved,
                        ms,
                        f"{sum(v['certified'] for v in m.values())}/{won}",
                        str(sum(v["colliding_states"] for v in m.values())),
                        *([shown(prepared.get("checks"), ",d"), shown(prepared.get("seconds"), ".1f")] if prm else []),
                    ]
                )
                + " |"
            )
        if len(versions) > 1:
            lines.append("")
            for r in s["changes"]:
                spelled = ", ".join(f"{m} `{v}`" for m, v in r["code_versions"].items())
                lines.append(f"- {r['change']}: {spelled}")
    return "\n".join(lines)
