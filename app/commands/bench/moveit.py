"""`bench moveit [FOLDER]`: MoveIt problems (PlanningScene + MotionPlanRequest YAML pairs) planned by our planner and
by OMPL's RRTConnect through one checker (app.bench.moveit)."""

from pathlib import Path

from app.bench.moveit import EXAMPLES, METHODS, PANDA, Robot, figure, measure, table
from app.commands import custom
from app.commands.bench import results
from app.commands.common import (
    announce,
    answering,
    check_count,
    check_outputs,
    names_from,
    print_json,
    processes,
    repetitions,
)


def register(kinds) -> None:
    p = kinds.add_parser(
        "moveit",
        help="a folder of MoveIt problems (sceneNNNN.yaml + requestNNNN.yaml): ours to a certified, timed "
        "trajectory vs OMPL's RRTConnect solve + simplify + timing, same checker and check budget",
    )
    p.add_argument(
        "folder",
        nargs="?",
        default=str(EXAMPLES.relative_to(EXAMPLES.parents[2])),
        help="problems, one sub-folder per kind (default: the shipped MotionBenchMaker Panda problems, "
        "examples/moveit/mbm-panda)",
    )
    p.add_argument(
        "--robot",
        default=None,
        metavar="URDF",
        help="the problems' robot (default: the shipped Panda, robots/panda/panda.urdf, with its SRDF)",
    )
    p.add_argument("--srdf", default=None, metavar="SRDF", help="its SRDF (needed for a request's group_name)")
    custom.add_package_path_argument(p)
    p.add_argument("--per-kind", type=repetitions, default=10, help="the first N problems of each kind")
    p.add_argument("--seeds", type=repetitions, default=1, help="runs 0..N-1 per problem and method")
    p.add_argument("--checks", type=check_count, default=100_000, help="collision checks per run, either method")
    p.add_argument("--methods", type=names_from(METHODS, "methods"), default=",".join(METHODS), help=", ".join(METHODS))
    p.add_argument(
        "--workers",
        type=processes,
        default=1,
        help="parallel runs (1 keeps timings clean: each run gets the machine and nothing competes)",
    )
    results.add_arguments(p, "out/bench-moveit.sqlite")
    p.add_argument("--png", default=None, metavar="FILE", help="figure: median seconds per kind, and per problem")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    check_outputs(args.png, creating_folders=(args.store,))
    if args.robot is None:
        robot = Robot(PANDA / "panda.urdf", Path(args.srdf) if args.srdf else PANDA / "panda.srdf")
    else:
        robot = Robot(Path(args.robot), Path(args.srdf) if args.srdf else None, tuple(args.package_path))
    report, reuse = measure(
        args.folder,
        robot,
        methods=args.methods,
        per_kind=args.per_kind,
        seeds=args.seeds,
        checks=args.checks,
        store=args.store,
        workers=args.workers,
        fresh=args.fresh,
    )
    results.say_reused(reuse)
    with answering():
        if args.png:
            figure(report, args.png)
            announce(args.png)
        if args.json:
            print_json({**report, "reused": reuse.to_json()})
            return 0
        print(table(report))
        return 0
