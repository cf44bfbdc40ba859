"""`gui SCENE`: the planning panel (app.panel) served by Meshcat on localhost.

The URL goes to stderr when the panel is up. It serves until Ctrl-C or SIGTERM, or for `--wait SECONDS`; stopping
it is the command's normal end (exit 0). Then `--html FILE` is written (the last planned motion, animated) and, with
`--json`, the one answer: the panel's state at exit (URL, slider values, the last plan's figures; Panel.state,
docs/schemas/gui.json). `--state FILE` holds the same state, rewritten (atomically) after every change the panel sees.
"""

import signal
import sys

from app.checking.oracle import CollisionOracle
from app.commands import custom, plan
from app.commands.common import announce, answering, check_outputs, non_negative_float, print_json, whole_number
from app.panel import Panel
from app.viewer import check_meshcat_allowed


def register(subparsers) -> None:
    p = subparsers.add_parser("gui", help="a planning panel in the browser: set start and goal, plan, watch (Meshcat)")
    p.add_argument(
        "scene", nargs="?", help="scene name, problem-file path or custom scene file (or --robot/--env instead)"
    )
    plan.add_settings_arguments(p)  # the planner's settings, as for `plan`; the sampler can be changed on the page
    p.add_argument("--port", type=whole_number(1, 65535), default=None, help="Meshcat's port (default: 7000 or next)")
    p.add_argument(
        "--wait",
        type=non_negative_float,
        metavar="SECONDS",
        default=None,
        help="serve this many seconds, then exit (default: until Ctrl-C or SIGTERM)",
    )
    p.add_argument("--state", metavar="FILE", help="keep the panel's state here as JSON (rewritten on every change)")
    p.add_argument("--html", metavar="FILE", help="on exit, write a standalone page of the last planned motion")
    p.add_argument("--frame", help="robot frame whose positions draw samples and path (default: the passage frame)")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout, on exit")
    custom.add_arguments(p)  # --robot / --package-path / --env ...
    p.set_defaults(func=run)


def run(args) -> int:
    settings = plan.settings_from_args(args)
    check_outputs(args.state, args.html)
    scene = custom.scene_from_args(args, args.scene)
    check_meshcat_allowed()
    panel = Panel(CollisionOracle(scene), settings, port=args.port, frame=args.frame, state_path=args.state)
    print(f"meshcat: {panel.viewer.url()}", file=sys.stderr, flush=True)
    how = f"for {args.wait:g} s" if args.wait is not None else "until Ctrl-C (or SIGTERM)"
    print(f"gui: serving the planning panel {how}", file=sys.stderr, flush=True)
    previous = signal.signal(signal.SIGTERM, signal.default_int_handler)  # SIGTERM stops it as Ctrl-C does
    try:
        panel.serve(args.wait)
    except KeyboardInterrupt:
        pass
    except BaseException:
        panel.close()
        raise
    finally:
        signal.signal(signal.SIGTERM, previous)
    with answering():  # stopping the panel ends its work: from here on its answer is written whole
        try:
            if args.html:
                panel.export_html(args.html)
            answer = {"html": args.html, **panel.state()}
        finally:
            panel.close()
        announce(args.state, args.html)
        if args.json:
            print_json(answer)
    return 0
