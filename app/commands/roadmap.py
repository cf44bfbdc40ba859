"""`roadmap build SCENE --out FILE` and `roadmap info FILE`: a work cell's roadmap, built once and queried by `plan
--roadmap FILE` and `run JOB --roadmap FILE` (app.planning.cell)."""

import argparse
import contextlib
import sys
import time

from app.checking.oracle import CollisionOracle, default_threads
from app.commands import common, custom, plan
from app.commands.common import (
    answering,
    check_outputs,
    open_cell,
    parse_build_budget,
    print_json,
    processes,
    read_changes,
    share,
    whole_number,
)
from app.commands.view import roadmap_lock
from app.jobs import cover
from app.planning.cell import BuildSettings, CellRoadmap
from app.planning.roadmap_file import read, read_header, summary
from app.scene.custom import load_scene

DEFAULTS = BuildSettings()


def register(subparsers) -> None:
    p = subparsers.add_parser("roadmap", help="build a work cell's roadmap once, then query it with plan/run --roadmap")
    actions = p.add_subparsers(dest="action", required=True, parser_class=type(p))

    b = actions.add_parser("build", help="sample the cell and decide every k-nearest edge; write one roadmap file")
    b.add_argument("scene", nargs="?", help="scene name, problem-file path or custom scene file (or --robot/--env)")
    b.add_argument("--out", required=True, metavar="FILE.npz", help="the roadmap file to write (atomically)")
    b.add_argument(
        "--nodes",
        type=whole_number(2, 1_000_000),
        default=DEFAULTS.nodes,
        help=f"samples the roadmap holds when the build ends (default {DEFAULTS.nodes})",
    )
    b.add_argument(
        "--narrow",
        type=share,
        default=DEFAULTS.narrow,
        help=f"share of the samples from the narrow-passage sampler and workspace gaps (default {DEFAULTS.narrow})",
    )
    plan.add_sampling_arguments(b)
    b.add_argument(
        "--budget",
        type=parse_build_budget,
        default=DEFAULTS.budget,
        help="what the build may spend, looked at between rounds: 60s, 3000kchecks, ... (default "
        f"{DEFAULTS.budget}); no time limit unless given, as the build is bounded by --nodes and ends with the "
        "roadmap it has",
    )
    b.add_argument(
        "--workers",
        type=processes,
        default=1,
        help="processes that check edges (the roadmap is the same for any number)",
    )
    b.add_argument(
        "--cover",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="after the samples, answer the scene's own query and every job its poses allow on the roadmap, which "
        "keeps the samples they join: the cell's hard regions in the roadmap (default on)",
    )
    b.add_argument("--json", action="store_true", help="one JSON object on stdout")
    custom.add_arguments(b)
    b.set_defaults(func=build)

    u = actions.add_parser(
        "update",
        help="repair a roadmap for a changed cell: only the verdicts the change can affect are set back to unknown",
    )
    u.add_argument("file", metavar="FILE.npz", help="the roadmap (`roadmap build`, or one updated before)")
    u.add_argument(
        "--change",
        metavar="CHANGE.yaml",
        action="append",
        required=True,
        help="what changed: obstacles added, moved or removed, objects attached or detached (repeatable, in order): "
        "a change file of ours or a MoveIt PlanningScene diff (is_diff: true)",
    )
    u.add_argument("--out", metavar="FILE.npz", help="write the repaired roadmap here (default: over FILE)")
    u.add_argument("--scene", help="the roadmap's scene, if not the shipped scene its file names")
    u.add_argument("--json", action="store_true", help="one JSON object on stdout")
    u.set_defaults(func=update)

    i = actions.add_parser("info", help="what a roadmap file holds: nodes, edges by verdict, its cell, provenance")
    i.add_argument("file", metavar="FILE.npz")
    i.add_argument("--json", action="store_true", help="one JSON object on stdout")
    i.set_defaults(func=info)


def build(args) -> int:
    settings = BuildSettings(
        nodes=args.nodes,
        narrow=args.narrow,
        sampler=args.sampler,
        step=args.step,
        workspace=args.workspace,
        k=args.neighbours,
        seed=args.seed,
        budget=args.budget,
    )
    check_outputs(args.out)
    oracle = CollisionOracle(custom.scene_from_args(args, args.scene), threads=max(args.workers, default_threads()))
    with _progress(settings.nodes, quiet=args.json) as progress:
        cell = CellRoadmap.build(oracle, settings, workers=args.workers, progress=progress)
    if args.cover:
        cover(cell, seed=settings.seed)
    _save_and_answer(cell, args.out, {"file": args.out, **cell.info()}, args.json)
    return 0


def update(args) -> int:
    changes = read_changes(args.change)
    out = args.out or args.file
    check_outputs(out)
    # Written in place: the file's lock from before it is read until it is written, as `plan --update` holds it.
    with roadmap_lock(args.file) if out == args.file else contextlib.nullcontext():
        scene = load_scene(args.scene or read_header(args.file)["scene"])
        _, cell = open_cell(args.file, scene, changes)
        _save_and_answer(cell, out, {"file": out, "repair": cell.provenance["changes"][-1], **cell.info()}, args.json)
    return 0


def _save_and_answer(cell, path: str, answer: dict, as_json: bool) -> None:
    """The roadmap written to `path`, then what it holds: the file and the answer are written whole or not at all."""
    with answering():
        cell.save(path)
        print(f"roadmap: wrote {path}", file=sys.stderr)
        if as_json:
            print_json(answer)
        else:
            print(_describe(answer))


def info(args) -> int:
    header, arrays = read(args.file)
    answer = {"file": args.file, **summary(arrays, header)}
    with answering():
        if args.json:
            print_json(answer)
        else:
            print(_describe(answer))
    return 0


def _describe(answer: dict) -> str:
    edges, kinds = answer["edges"], answer["nodes_by_kind"]
    builds = answer["provenance"]["builds"]
    lines = [
        f"roadmap {answer['file']}: cell {answer['scene']}, {answer['nodes']} nodes of {answer['dimension']} "
        f"coordinates ({', '.join(f'{n} {kind}' for kind, n in kinds.items())})",
        f"  edges     {edges['certified']} certified, {edges['free']} free at the resolution, {edges['unchecked']} "
        f"not yet checked, {edges['colliding_or_unprovable']} known to collide or unprovable",
    ]
    for record in builds:
        lines.append(
            f"  built     {record['nodes']} nodes, {record['collision_checks']} collision checks, "
            f"{record['seconds']:.1f} s on {record['workers']} process(es), ended by {record['ended']}"
        )
    for record in answer["provenance"].get("covered", []):
        outcome = "joined" if record["solved"] else "not answered"
        lines.append(f"  covered   {record['what']}: {outcome}, {record['collision_checks']} collision checks")
    for record in answer["provenance"].get("changes", []):
        lines.append(
            f"  changed   {record['described']}: {record['edges_reset']} free and {record['colliding_reset']} "
            f"colliding edge verdicts set back to unknown, {record['nodes_checked']} nodes checked again "
            f"({record['nodes_dropped']} dropped), {record['collision_checks']} collision checks, "
            f"{record['seconds']:.2f} s"
        )
    lines.append(f"  queries   {answer['provenance']['queries']} made on it and written back (answered or not)")
    return "\n".join(lines)


class _progress:
    """The build's progress on stderr: a bar on a terminal; where stderr is no terminal (a log), a plain line at most
    every common.PROGRESS_LOG_EVERY s, and none with --json (`quiet`). The build reports as each round's edges are
    decided (CellRoadmap.grow), so both advance within a round."""

    def __init__(self, total: int, quiet: bool = False):
        self.total, self.quiet, self.bar = total, quiet, None

    def __enter__(self):
        if not sys.stderr.isatty():
            return None if self.quiet else self._log()
        from tqdm import tqdm

        self.bar = tqdm(total=self.total, desc="roadmap build", unit="node", file=sys.stderr)

        def update(nodes: int, target: int, checks: int) -> None:
            self.bar.n = nodes
            self.bar.set_postfix_str(f"{checks / 1000:.0f}k checks", refresh=True)

        return update

    def _log(self):
        started = last = time.monotonic()

        def update(nodes: int, target: int, checks: int) -> None:
            nonlocal last
            now = time.monotonic()
            if now - last >= common.PROGRESS_LOG_EVERY:
                last = now
                print(
                    f"roadmap build: {nodes}/{target} nodes, {checks:,} collision checks, {now - started:.0f} s",
                    file=sys.stderr,
                    flush=True,
                )

        return update

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()
