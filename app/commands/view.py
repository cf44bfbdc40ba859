"""`view` shows a trajectory in Meshcat and/or exports it as a standalone HTML page.

`add_arguments`, `check_from_args`, `write_outputs` and `wait` give any command (plan, run) the same
--html / --bag / --meshcat / --wait / --frame flags.

How long --meshcat serves: `--wait SECONDS` if given (0: not at all); else, with a terminal, until Enter or Ctrl-C;
else (Docker without -t, an IDE, a notebook, a pipe) until Ctrl-C or SIGTERM (`docker stop`). Ending the wait is the
normal end of the command, exit code 0: its work is done and its answer (with --json, its one JSON object) is
already printed. What the wait says goes to stderr.
"""

import contextlib
import os
import signal
import sys
import threading

from app.commands import custom
from app.commands.common import announce, answering, check_outputs, non_negative_float, print_json
from app.errors import NoPath, UserError
from app.io import all_or_nothing, exclusive
from app.motion.rosbag import DEFAULT_DISTRO, DISTROS, read_bag_for, write_bag
from app.motion.trajectory import TrajectoryFile
from app.viewer import ViewData, check_meshcat_allowed, publish


def add_arguments(p) -> None:
    """The viewer flags, for any command that has a scene and a trajectory to show."""
    p.add_argument("--html", metavar="FILE", help="write a standalone Meshcat page (robot animation, samples, path)")
    p.add_argument(
        "--bag",
        metavar="DIR",
        help="write the trajectory as a new ROS 2 bag folder: one trajectory_msgs/msg/JointTrajectory on "
        "/joint_trajectory, its header stamped 0, which ros2_control's joint trajectory controller reads as "
        "'start on arrival' (refused if DIR exists)",
    )
    p.add_argument(
        "--ros-distro",
        choices=list(DISTROS),
        default=None,
        help=f"with --bag: the ROS 2 distribution whose rosbag2 reads the bag (default {DEFAULT_DISTRO}: metadata "
        "version 8, read by Iron and every later distribution); humble: version 5, as Humble's own rosbag2 writes "
        "it; jazzy: version 9, as Jazzy, Kilted and Rolling write it",
    )
    p.add_argument(
        "--meshcat",
        action="store_true",
        help="serve it on localhost and print the URL; then wait for Enter or Ctrl-C on a terminal, else for "
        "Ctrl-C or SIGTERM (see --wait)",
    )
    p.add_argument(
        "--wait",
        type=non_negative_float,
        metavar="SECONDS",
        default=None,
        help="with --meshcat: serve this many seconds, then exit (0: do not wait)",
    )
    p.add_argument("--frame", help="robot frame whose positions draw samples and path (default: the passage frame)")
    p.add_argument("--collision", action="store_true", help="also load the collision geometry (hidden at first)")


def check_from_args(args, *outputs: str | None) -> None:
    """Before any work: the viewer flags agree, the command's output files (`outputs` and --html) can be written,
    and Meshcat, which --html and --meshcat need, is allowed."""
    if args.wait is not None and not args.meshcat:
        raise UserError("--wait needs --meshcat (it says how long the Meshcat server stays up)")
    if args.frame is not None and not (args.html or args.meshcat):
        raise UserError("--frame needs --html or --meshcat (it says which frame draws the samples and path)")
    if args.ros_distro is not None and not args.bag:
        raise UserError("--ros-distro needs --bag (it says which ROS 2 distribution the bag is written for)")
    if args.bag and os.path.lexists(args.bag):  # a bag is a new folder: never merged into or replaced
        raise UserError(f"cannot write {args.bag}: it exists already; give a new folder name")
    check_outputs(*outputs, args.html, args.bag)
    if args.html or args.meshcat:
        check_meshcat_allowed()


def write_outputs(args, scene, file: TrajectoryFile, out: str | None = None, roadmap=None):
    """The trajectory `file` written and shown as the flags ask: `out` (its JSON file), --bag, --html, --meshcat,
    and `roadmap` (a cell roadmap and its path: written back); the files appear together or not at all, each named
    on stderr. Returns the Meshcat viewer (None without --meshcat/--html). The Meshcat URL also goes to stderr
    (stdout may carry a command's JSON); `wait` then keeps it served. A command calls it inside its
    common.answering() block, with the answer it prints."""
    viewer = None
    # The roadmap's lock around the whole block, whose end replaces its file: CellRoadmap.save checks under it that
    # the file is still the revision it loaded. plan --update holds it already (taken before it read the file); a
    # command that did not take it then does not wait here for another process's update, which its save would
    # refuse anyway (and a wait here, where an interrupt waits for the answer, could not be interrupted).
    lock = exclusive(roadmap[1], _refuse_busy(roadmap[1])) if roadmap is not None else contextlib.nullcontext()
    with lock, all_or_nothing():
        if args.meshcat or args.html:
            viewer = publish(scene, ViewData.of(file), html=args.html, frame=args.frame, collision=args.collision)
        if out:
            file.write(out)
        if args.bag:
            write_bag(args.bag, file.trajectory, distro=args.ros_distro or DEFAULT_DISTRO)
        if roadmap is not None:
            roadmap[0].save(roadmap[1])
    announce(out, args.bag, args.html, roadmap and roadmap[1])
    if args.meshcat:
        print(f"meshcat: {viewer.url()}", file=sys.stderr, flush=True)
    return viewer


@contextlib.contextmanager
def kept_on_failure(roadmap):
    """With --update (`roadmap`: a cell roadmap and its path, else None), a query that finds no path still writes
    back what it learned: its verdicts on the roadmap's edges (CellRoadmap.solve keeps them and takes its samples
    away), which the next query need not check again. Not when it was stopped from outside (PREEMPTED): an interrupt
    writes nothing."""
    try:
        yield
    except NoPath as failure:
        if roadmap is not None and failure.code != "PREEMPTED":
            with answering(final=False), exclusive(roadmap[1], _refuse_busy(roadmap[1])):
                roadmap[0].save(roadmap[1])
            announce(roadmap[1])
        raise


def roadmap_lock(path):
    """The lock of a roadmap file that is read, added to and written back (app.io.exclusive): taken before it is
    read and held until it is written, so that two processes updating one roadmap take turns and the second adds
    to the first one's update instead of writing over it. Says so once on stderr when it has to wait."""

    def waiting() -> None:
        print(f"waiting for roadmap {path}: another process is updating it", file=sys.stderr, flush=True)

    return exclusive(path, waiting)


def _refuse_busy(path):
    def refuse() -> None:
        raise UserError(
            f"roadmap {path} is being updated by another process: not written over (that update would be lost)"
        )

    return refuse


def wait(args, viewer) -> None:
    """Keep the --meshcat `viewer` served as the module docstring says; return when the wait ends. (The viewer is
    passed so that it stays referenced while it serves: a Meshcat no longer referenced stops its server.)"""
    if not args.meshcat or args.wait == 0:
        return
    terminal = args.wait is None and sys.stdin is not None and sys.stdin.isatty()
    if args.wait is not None:
        how = f"serving for {args.wait:g} s; Ctrl-C stops it sooner"
    elif terminal:
        how = "press Enter or Ctrl-C to stop serving"
    else:
        how = "serving until Ctrl-C (or SIGTERM)"
    print(f"meshcat: {how}", file=sys.stderr, flush=True)
    previous = signal.signal(signal.SIGTERM, signal.default_int_handler)  # SIGTERM ends the wait as Ctrl-C does
    try:
        if terminal:
            sys.stdin.readline()
        else:
            threading.Event().wait(args.wait)  # None: until a signal interrupts it
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGTERM, previous)


def register(subparsers) -> None:
    p = subparsers.add_parser("view", help="show a trajectory in Meshcat and/or export a standalone HTML page")
    p.add_argument(
        "scene", nargs="?", help="scene name, problem-file path or custom scene file (or --robot/--env instead)"
    )
    p.add_argument(
        "--trajectory",
        required=True,
        metavar="FILE.json|BAG",
        help="a trajectory file written by plan --out or run --out, or a ROS 2 bag folder holding a "
        "trajectory_msgs/msg/JointTrajectory (plan --bag writes one; its first is shown, not certified)",
    )
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    add_arguments(p)
    custom.add_arguments(p)  # --robot / --package-path / --env ...: the scene the trajectory was planned in
    p.set_defaults(func=run_view)


def run_view(args) -> int:
    if not args.html and not args.meshcat and not args.bag:
        raise UserError("view: nothing to do; give --html FILE, --bag DIR and/or --meshcat")
    check_outputs(args.html)
    scene = custom.scene_from_args(args, args.scene)
    read = read_bag_for if os.path.isdir(args.trajectory) else TrajectoryFile.read_for  # (False for a bad name)
    file = read(args.trajectory, scene)
    check_from_args(args)  # Meshcat allowed? (a bad trajectory file is said first: it is the input)
    with answering():
        viewer = write_outputs(args, scene, file)
        if args.json:
            print_json(
                {
                    "scene": scene.name,
                    "html": args.html,
                    "bag": args.bag,
                    "meshcat": viewer.url() if args.meshcat else None,
                }
            )
    wait(args, viewer)
    return 0
