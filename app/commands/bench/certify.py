"""`bench certify`: plan time with and without certification and smooth timing, and smooth vs rest-to-rest
durations, per scene and UR3 job (app.bench.certification)."""

from app.bench.certification import measure
from app.bench.jobs import JOBS
from app.commands.bench import results
from app.commands.common import answering, check_outputs, names_from, print_json, repetitions
from app.scene.model import scene_names


def register(kinds) -> None:
    p = kinds.add_parser(
        "certify", help="what certification and smooth timing add to plan time; smooth vs rest to rest"
    )
    p.add_argument(
        "--scenes",
        type=names_from(scene_names(), "scene"),
        default=",".join(scene_names()),
        help="comma-separated shipped scenes whose own start-to-goal query is planned, once per seed (default: "
        "every shipped scene)",
    )
    p.add_argument("--jobs", type=names_from(JOBS, "job"), default="window", help="comma-separated UR3 jobs")
    p.add_argument("--seeds", type=repetitions, default=5, help="seeds 0..N-1 per scene and job")
    results.add_arguments(p, "out/bench-certify.sqlite")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    check_outputs(creating_folders=(args.store,))
    table, reuse = measure(args.scenes, args.jobs, args.seeds, args.store, args.fresh)
    results.say_reused(reuse, args.store)
    with answering():
        if args.json:
            print_json({"certify": table, "seeds": args.seeds, "reused": reuse.to_json()})
            return 0
        print(
            f"{args.seeds} seeds of each scene's default query (plan SCENE --seed S) and each job; medians. 'without': "
            "the same query with certification and smooth timing replaced by what an uncertified planner does to its "
            "path: a discrete re-check at 1/4 resolution and rest-to-rest timing. Duration ratios are over rest to "
            "rest; 'full-speed bound': no motion along the path within the velocity limits is shorter. 'ms/conf': the "
            "certificate's time (set-up and every proof) per configuration it asked Drake's distance query about, and "
            "that query's own time"
        )
        print(
            f"{'scene/job':<10} {'success':>8} {'plan s':>7} {'without s':>9} {'overhead':>8} {'certify s':>9} "
            f"{'timing s':>8} {'certified':>9} {'duration ratio':>14} {'full-speed bound':>16} {'in Drake':>9} "
            f"{'ms/conf':>8} {'Drake ms/conf':>13}"
        )

        def cell(value, form):
            return "-" if value is None else format(value, form)

        for r in table:
            print(
                f"{r['name']:<10} {r['successes']:>4}/{r['runs']:<3} {cell(r['median_seconds'], '.2f'):>7} "
                f"{cell(r.get('median_seconds_without'), '.2f'):>9} {cell(r.get('overhead'), '+.0%'):>8} "
                f"{cell(r.get('median_seconds_certify'), '.2f'):>9} {cell(r.get('median_seconds_timing'), '.2f'):>8} "
                f"{cell(r.get('certified'), 'd'):>9} {cell(r['median_duration_ratio'], '.2f'):>14} "
                f"{cell(r['median_full_speed_ratio'], '.2f'):>16} {cell(r.get('median_drake_share'), '.0%'):>9} "
                f"{cell(r.get('median_certificate_ms_per_configuration'), '.3f'):>8} "
                f"{cell(r.get('median_drake_ms_per_configuration'), '.3f'):>13}"
            )
        return 0
