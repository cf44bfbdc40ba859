"""`view` shows a trajectory in Meshcat and/or exports it as a standalone HTML page.

`add_arguments` and `publish_from_args` give any command (plan, run) the same --html / --meshcat / --frame flags.
"""

import sys

from app.commands.common import check_outputs, print_json
from app.custom_scene import load_scene
from app.errors import UserError
from app.trajectory import TrajectoryFile
from app.viewer import ViewData, check_meshcat_allowed, publish


def add_arguments(p) -> None:
    """The viewer flags, for any command that has a scene and a trajectory to show."""
    p.add_argument("--html", metavar="FILE", help="write a standalone Meshcat page (robot animation, samples, path)")
    p.add_argument(
        "--meshcat",
        action="store_true",
        help="serve it on localhost, print the URL, wait for Enter (not when stdin is not a terminal)",
    )
    p.add_argument("--frame", help="robot frame whose positions draw samples and path (default: the passage frame)")
    p.add_argument("--collision", action="store_true", help="also load the collision geometry (hidden at first)")


def check_from_args(args, *outputs: str | None) -> None:
    """Before any work: the command's output files (`outputs` and --html) can be written, and Meshcat, which
    --html and --meshcat need, is allowed."""
    check_outputs(*outputs, args.html)
    if args.html or args.meshcat:
        check_meshcat_allowed()


def publish_from_args(args, scene, data):
    """Show/export `data` (an app.viewer.ViewData) as the flags of `add_arguments` ask; None when none was given.
    With --meshcat the URL goes to stderr (stdout may carry a command's JSON); `wait` then keeps it served."""
    if not args.meshcat and not args.html:
        return None
    viewer = publish(scene, data, html=args.html, frame=args.frame, collision=args.collision)
    if args.meshcat:
        print(f"meshcat: {viewer.url()}", file=sys.stderr, flush=True)
    return viewer


def wait(args) -> None:
    """With --meshcat and a terminal, keep the viewer up until Enter or Ctrl-C; otherwise (CI, pipes) return."""
    if args.meshcat and sys.stdin is not None and sys.stdin.isatty():
        print("press Enter (or Ctrl-C) to quit the viewer", file=sys.stderr, flush=True)
        try:
            sys.stdin.readline()
        except KeyboardInterrupt:
            pass


def register(subparsers) -> None:
    p = subparsers.add_parser("view", help="show a trajectory in Meshcat and/or export a standalone HTML page")
    p.add_argument("scene", help="scene name, problem-file path or custom scene file")
    p.add_argument(
        "--trajectory", required=True, metavar="FILE.json", help="a trajectory file written by plan --out or run --out"
    )
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    add_arguments(p)
    p.set_defaults(func=run_view)


def run_view(args) -> int:
    if not args.html and not args.meshcat:
        raise UserError("view: nothing to do; give --html FILE and/or --meshcat")
    check_outputs(args.html)
    scene = load_scene(args.scene)
    data = ViewData.of(TrajectoryFile.read(args.trajectory, scene.dim))
    check_from_args(args)  # Meshcat allowed? (a bad trajectory file is said first: it is the input)
    viewer = publish_from_args(args, scene, data)
    if args.json:
        print_json({"scene": scene.name, "html": args.html, "meshcat": viewer.url() if args.meshcat else None})
    elif args.html:
        print(args.html)
    wait(args)
    return 0
