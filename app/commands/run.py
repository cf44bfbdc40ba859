"""`run welding|window`: the scripted UR3 jobs, planned leg by leg into one trajectory, with a summary table."""

import contextlib
from dataclasses import replace

from app.commands.common import (
    BUDGET_HELP,
    add_change_arguments,
    add_scaling_arguments,
    answering,
    known_sources,
    open_cell,
    parse_budget,
    positive_float,
    print_json,
    progress,
    read_changes,
    sample_count,
    seed,
    source_name,
)
from app.commands.view import add_arguments, check_from_args, kept_on_failure, roadmap_lock, wait, write_outputs
from app.errors import UserError
from app.jobs import JOB_SETTINGS, ROUTES, run_job
from app.scene.changes import read_payload
from app.scene.model import Scene


def register(subparsers) -> None:
    p = subparsers.add_parser("run", help="scripted UR3 jobs: welding (seam point to point), window (reach, place)")
    p.add_argument("job", help="welding or window (the scene of the same name)")
    p.add_argument(
        "--sampler",
        type=source_name,
        default=JOB_SETTINGS.sampler,
        help=f"where narrow-passage samples come from: {known_sources()} (default {JOB_SETTINGS.sampler})",
    )
    p.add_argument("--seed", type=seed, default=0)
    p.add_argument("--narrow", type=sample_count, default=40, help="narrow-passage samples per planned leg")
    p.add_argument("--uniform", type=sample_count, default=40, help="uniform samples per planned leg")
    p.add_argument("--step", type=positive_float, default=None, help="sampler step (default: the scene's)")
    p.add_argument(
        "--budget",
        type=parse_budget,
        default=JOB_SETTINGS.budget,
        help=f"per planned leg: {BUDGET_HELP} (default {JOB_SETTINGS.budget}: checks decide, the seconds are a "
        "safety net)",
    )
    p.add_argument(
        "--full-roadmap",
        action="store_true",
        help="per planned leg, draw every sample and check every edge before the query (as `plan`)",
    )
    p.add_argument(
        "--roadmap",
        metavar="FILE.npz",
        help="plan every leg on this cell roadmap (`roadmap build`); default: one roadmap the legs share, from empty",
    )
    p.add_argument("--update", action="store_true", help="write back to --roadmap what the job's legs learned")
    p.add_argument("--out", metavar="FILE.json", help="write the joined trajectory (not written on failure)")
    p.add_argument("--json", action="store_true")
    add_scaling_arguments(p)
    add_change_arguments(p)
    p.add_argument(
        "--payload",
        metavar="PART.yaml",
        action="append",
        default=[],
        help="the job carries this object (repeatable): a file of one attached object, its shape and pose on a robot "
        "link and the links it may touch (docs/changes.md); applied after --change, the roadmap repaired for it",
    )
    add_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    if args.job not in ROUTES:
        raise UserError(f"unknown job '{args.job}' (known: {', '.join(ROUTES)})")
    settings = replace(
        JOB_SETTINGS,
        sampler=args.sampler,
        seed=args.seed,
        narrow=args.narrow,
        uniform=args.uniform,
        step=args.step,
        budget=args.budget,
        full_roadmap=args.full_roadmap,
        velocity_scale=args.velocity_scale,
        acceleration_scale=args.acceleration_scale,
        clearance=args.clearance,
    )
    if args.update and not args.roadmap:
        raise UserError("--update writes back to a roadmap: give --roadmap FILE")
    if args.roadmap and args.full_roadmap:
        raise UserError("--full-roadmap builds a roadmap per leg: give it or --roadmap, not both")
    check_from_args(args, args.out, args.roadmap if args.update else None)
    changes = read_changes(args.change) + [read_payload(path) for path in args.payload]
    # --update: the roadmap's lock from before the file is read until it is written back, as plan --update takes it.
    with roadmap_lock(args.roadmap) if args.update else contextlib.nullcontext():
        # The cell as it is now: the changes the roadmap was repaired for, then --change (the roadmap repaired).
        oracle, cell = open_cell(args.roadmap, Scene(args.job), changes)
        saved = (cell, args.roadmap) if args.update else None
        with progress(args, oracle, f"run {args.job}"), kept_on_failure(saved):
            result = run_job(oracle, args.job, settings, cell)
        # Files first (all or none), the answer last: a failure writing one leaves no success printed.
        with answering():  # the files and the table are the answer
            viewer = write_outputs(args, oracle.scene, result.trajectory_file(), args.out, saved)
            if args.json:
                print_json(result.to_json())
            else:
                print(f"{result.scene}: {len(result.legs)} legs, sampler {result.sampler}, seed {result.seed}")
                print(
                    f"{'leg':<20} {'method':<9} {'narrow':>7} {'on path':>8} {'checks':>8} {'plan s':>7} {'move s':>7}"
                )
                for leg in result.legs:
                    print(
                        f"{leg.start + ' -> ' + leg.goal:<20} {leg.method:<9} {leg.narrow_samples:>7} "
                        f"{leg.narrow_on_path:>8} {leg.collision_checks:>8} {leg.seconds:>7.2f} {leg.duration:>7.2f}"
                    )
                s = result.seconds
                print(
                    f"{'total':<20} {'':<9} {'':>7} {'':>8} {result.collision_checks:>8} {s['planning']:>7.2f} "
                    f"{result.trajectory.duration:>7.2f}   (IK {s['ik']:.2f} s, wall {s['total']:.2f} s)"
                )
    wait(args, viewer)
    return 0
