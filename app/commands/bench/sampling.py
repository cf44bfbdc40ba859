"""`bench sampling`: t_eps, gamma_c and passage fraction of the samplers vs step (app.bench.sampling)."""

from app.bench.sampling import STEPS, figure, measure, summarise
from app.commands.common import (
    announce,
    answering,
    check_count,
    check_outputs,
    comma_list,
    known_samplers,
    positive_float,
    positive_float_list,
    print_json,
    processes,
    repetitions,
    sampler_names,
    samples_wanted,
)
from app.samplers import SAMPLERS


def register(kinds) -> None:
    p = kinds.add_parser("sampling", help="t_eps, gamma_c and passage fraction of the seven samplers vs step")
    p.add_argument(
        "--scenes",
        type=comma_list,
        default="bar,teeth3d",
        help="comma-separated scenes (shipped scene names or problem files) each sampler draws samples in "
        "(default bar,teeth3d)",
    )
    p.add_argument(
        "--samplers",
        type=sampler_names,
        default=",".join(SAMPLERS),
        help=f"comma-separated sampler names, of {known_samplers()}",
    )
    p.add_argument(
        "--steps", type=positive_float_list, default=STEPS, help="comma-separated steps a (default 2,5,10,15,20)"
    )
    p.add_argument("--trials", type=repetitions, default=10, help="trials (seeds 0..N-1) per cell")
    p.add_argument("-k", type=samples_wanted, default=30, help="samples per trial (the paper's K_c = 30)")
    p.add_argument(
        "--margin",
        type=positive_float,
        default=None,
        help="contact margin for 'sits between' (default: twice the scene's resolution)",
    )
    p.add_argument(
        "--max-checks",
        type=check_count,
        default=200_000,
        help="collision-check budget per trial; a trial that spends it is reported as censored",
    )
    p.add_argument("--threads", type=processes, default=None, help="oracle threads (default: up to 2)")
    p.add_argument("--png", help="figure: one panel per metric vs step, one line per sampler, a row per scene")
    p.add_argument("--json", action="store_true", help="rows and summary as one JSON object on stdout")
    p.set_defaults(func=run)


def run(args) -> int:
    check_outputs(args.png)
    rows = measure(
        args.scenes,
        args.samplers,
        args.steps,
        args.trials,
        k=args.k,
        margin=args.margin,
        max_checks=args.max_checks,
        threads=args.threads,
    )
    summary = summarise(rows)
    with answering():  # the figure and what is printed are the answer
        if args.png:
            figure(summary, args.png)
            announce(args.png)
        if args.json:
            print_json({"rows": rows, "summary": summary})
        else:
            print_table(summary)
        return 0


def print_table(summary: list[dict]) -> None:
    print(
        f"{'scene':<9} {'sampler':<8} {'step':>5} {'t_eps s (median, 95% CI)':>26} {'gamma_c (median, 95% CI)':>28} "
        f"{'passage (95% CI)':>20} {'env':>5} {'self':>5} {'both':>5} {'none':>5}"
    )
    for s in summary:
        t, c, p = s["seconds"], s["collision_checks"], s["passage_fraction"]
        mark = "≥" if s["censored"] else " "
        near = " ".join(
            f"{s.get(k, float('nan')):>5.2f}" for k in ("near_environment", "near_self", "near_both", "near_neither")
        )
        print(
            f"{s['scene']:<9} {s['sampler']:<8} {s['step']:>5g} "
            f"{mark}{t['median']:>7.3f} ({t['lo']:>7.3f}-{t['hi']:>7.3f}) "
            f"{mark}{c['median']:>8.0f} ({c['lo']:>8.0f}-{c['hi']:>8.0f}) "
            f"{p['median']:>6.2f} ({p['lo']:.2f}-{p['hi']:.2f}) {near}"
            + (f"  [{s['censored']}/{s['trials']} over budget]" if s["censored"] else "")
        )
