"""`bench ablation`: our planner with each source of narrow-passage samples removed or swapped, on a check budget
(app.bench.ablation)."""

from pathlib import Path

from app.bench.ablation import DEFAULT_CHECKS, VARIANTS, figure, markdown, measure
from app.commands.bench import results
from app.commands.common import answering, check_count, check_outputs, comma_list, print_json, processes, repetitions
from app.io import write_atomically
from app.scene.model import scene_names


def register(kinds) -> None:
    p = kinds.add_parser(
        "ablation",
        help="the planner with workspace placements, the Lévy walkers or both swapped out: success and checks to "
        "the first solution on a check budget, and which source supplied the path's narrow nodes",
    )
    p.add_argument(
        "--scenes",
        type=comma_list,
        default=",".join(scene_names()),
        help="comma-separated scenes (shipped scene names or problem files) whose own start-to-goal query each "
        "variant plans, once per seed (default: every shipped scene, see `python -m app scenes`)",
    )
    p.add_argument("--variants", type=comma_list, default=",".join(VARIANTS), help=f"of {', '.join(VARIANTS)}")
    p.add_argument("--seeds", type=repetitions, default=20, help="seeds 0..N-1 per scene and variant")
    p.add_argument("--checks", type=check_count, default=DEFAULT_CHECKS, help="collision-check budget per query")
    p.add_argument("--workers", type=processes, default=1, help="parallel processes")
    p.add_argument("--out", default="results/ablation", metavar="DIR", help="where table.md and ablation.png go")
    p.add_argument(
        "--report-only", action="store_true", help="rebuild the table and figure from the store; run no trial"
    )
    results.add_arguments(p, "results/ablation/trials.sqlite")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    from app.errors import UserError

    unknown = [v for v in args.variants if v not in VARIANTS]
    if unknown:
        raise UserError(f"unknown variant {', '.join(unknown)} (known: {', '.join(VARIANTS)})")
    out = Path(args.out)
    table_path, png_path = out / "table.md", out / "ablation.png"
    check_outputs(creating_folders=(args.store, str(table_path), str(png_path)))
    table, reuse, held, versions = measure(
        args.scenes,
        args.variants,
        args.seeds,
        args.checks,
        args.store,
        workers=args.workers,
        run=not args.report_only,
        fresh=args.fresh,
    )
    results.say_reused(reuse)
    planned = len(args.scenes) * len(args.variants) * args.seeds
    text = markdown(table, held, planned, args.checks, args.seeds, versions)
    with answering():  # the table, the figure and what is printed are the answer
        out.mkdir(parents=True, exist_ok=True)
        if table:
            figure(table, str(png_path), args.checks)
        write_atomically(table_path, text)
        if args.json:
            print_json({"ablation": table, "trials": held, "planned": planned, "reused": reuse.to_json()})
        else:
            print(text)
        return 0
