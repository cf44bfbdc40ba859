"""`bench audit`: the soak. Random problems in every shipped scene, each planned under a budget of collision checks,
every returned trajectory re-checked by an independent Drake checker at 1/64 of the scene's resolution, with its
limits and endpoints, the straight lines between its 50 Hz samples and its path polyline; the same on cell roadmaps
saved and read back, and tampered with; and the bad-input table, each case run as its own process
(app.bench.audit)."""

import argparse

from app.bench.audit import (
    ANSWER_SECONDS,
    CHECKS,
    DIVISOR,
    ROADMAP_NODES,
    bad_input_counts,
    measure,
    measure_bad_input,
    measure_roadmaps,
)
from app.commands.bench import results
from app.commands.common import (
    answering,
    check_count,
    check_outputs,
    names_from,
    print_json,
    processes,
    repetitions,
    seed,
    whole_number,
)
from app.scene.model import scene_names


def register(kinds) -> None:
    p = kinds.add_parser(
        "audit", help="the soak: random problems re-checked by an independent checker, and the bad-input table"
    )
    p.add_argument(
        "--problems", type=repetitions, default=2000, help="problems in all, shared out over the scenes (default 2000)"
    )
    p.add_argument("--seed", type=seed, default=0, help="seeds the problems' starts and goals")
    p.add_argument(
        "--scenes",
        type=names_from(scene_names(), "scene"),
        default=",".join(scene_names()),
        help="comma-separated shipped scenes the random problems are drawn in (default: every shipped scene)",
    )
    p.add_argument(
        "--checks",
        type=check_count,
        default=CHECKS,
        help=f"collision checks each problem may spend planning (default {CHECKS}); checks, not seconds, so the "
        "answers do not depend on the machine or its load",
    )
    p.add_argument(
        "--roadmap-problems",
        type=whole_number(0, 10_000),
        default=200,
        help="problems planned on stored cell roadmaps (one per scene, saved and read back as it is, or with every "
        "colliding edge rewritten as free and proved), shared out over scenes and the two (default 200; 0: none)",
    )
    p.add_argument(
        "--roadmap-nodes",
        type=repetitions,
        default=ROADMAP_NODES,
        help=f"nodes of each scene's stored roadmap (default {ROADMAP_NODES})",
    )
    p.add_argument("--workers", type=processes, default=1, help="parallel processes (one thread each when > 1)")
    p.add_argument(
        "--bad-input",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="also run the bad-input table, each case as its own process (default: yes)",
    )
    results.add_arguments(p, "out/bench-audit.sqlite")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    check_outputs(creating_folders=(args.store,))
    table, reuse = measure(
        args.scenes, args.problems, args.seed, args.checks, args.store, workers=args.workers, fresh=args.fresh
    )
    results.say_reused(reuse, args.store)
    stored = None
    if args.roadmap_problems:
        stored, stored_reuse = measure_roadmaps(
            args.scenes,
            args.roadmap_problems,
            args.seed,
            args.checks,
            args.store,
            nodes=args.roadmap_nodes,
            workers=args.workers,
            fresh=args.fresh,
        )
        results.say_reused(stored_reuse)
    cases = None
    if args.bad_input:
        cases, case_reuse = measure_bad_input(args.store, workers=args.workers, fresh=args.fresh)
        results.say_reused(case_reuse)
    with answering():
        if args.json:
            print_json(
                {
                    "audit": table,
                    "stored_roadmaps": stored,
                    "problems": args.problems,
                    "roadmap_problems": args.roadmap_problems,
                    "seed": args.seed,
                    "checks": args.checks,
                    "reused": reuse.to_json(),
                    "bad_input": cases,
                    "bad_input_counts": None if cases is None else bad_input_counts(cases),
                }
            )
            return 0
        print(
            f"{args.problems} problems (seed {args.seed}), at most {args.checks} collision checks each; every solved "
            f"trajectory re-checked at 1/{DIVISOR} of the scene's resolution by a Drake checker of its own: its "
            "curve, the straight lines between its 50 Hz samples, and its path polyline"
        )
        _table(table, "scene")
        if stored is not None:
            print(
                f"\n{args.roadmap_problems} problems on stored cell roadmaps of {args.roadmap_nodes} nodes, read back "
                "as saved, or tampered (every colliding edge rewritten as free and proved); re-checked the same way"
            )
            _table(stored, "roadmap")
        if cases is not None:
            counts = bad_input_counts(cases)
            print(
                f"\nbad input: {counts['behaved']} of {counts['cases']} cases behaved (expected exit code, one line on "
                f"stderr, answered within {ANSWER_SECONDS:g} s, nothing written); {counts['tracebacks']} tracebacks, "
                f"{counts['hangs']} hangs, {counts['slow']} slow, {counts['wrong_exit_code']} wrong exit codes, "
                f"{counts['wrote_files']} wrote files"
            )
            print(f"{'ok':<3} {'exit':>4} {'s':>5}  command  ->  first stderr line [files written]")
            for c in cases:
                code = "hung" if c["exit_code"] is None else c["exit_code"]
                written = f" [{', '.join(c['written'])}]" if c["written"] else ""
                print(
                    f"{'ok' if c['behaved'] else 'BAD':<3} {code:>4} {c['seconds']:>5.1f}  {c['command']}  ->  "
                    f"{c['first_line']}{written}"
                )
        return 0


def _table(rows: list[dict], first: str) -> None:
    wide = max(10, *(len(r["scene"]) for r in rows))
    print(
        f"{first:<{wide}} {'problems':>8} {'solved':>7} {'certified':>9} {'colliding':>9} {'coll. states':>12} "
        f"{'lines':>6} {'polyline':>8} {'max pen.':>9} {'limit viol.':>11} {'worst v/a':>9} {'bad ends':>8} "
        f"{'states':>10} {'median s':>8}" + (f" {'forged on path':>14}" if "forged_edges_on_paths" in rows[-1] else "")
    )
    for r in rows:
        seconds = "-" if r["median_seconds"] is None else f"{r['median_seconds']:.2f}"
        worst = "-" if r["worst_limit_ratio"] is None else f"{r['worst_limit_ratio']:.6f}"
        lines, polyline = (
            "-" if r[key] is None else r[key] for key in ("colliding_sample_lines_states", "colliding_polyline_states")
        )
        forged = f" {r['forged_edges_on_paths']:>14}" if "forged_edges_on_paths" in r else ""
        print(
            f"{r['scene']:<{wide}} {r['problems']:>8} {r['solved']:>7} {r['certified']:>9} "
            f"{r['colliding_trajectories']:>9} {r['colliding_states']:>12} {lines:>6} {polyline:>8} "
            f"{r['max_penetration']:>9.2g} {r['limit_violations']:>11} {worst:>9} {r['inexact_endpoints']:>8} "
            f"{r['states_checked']:>10} {seconds:>8}{forged}"
        )
