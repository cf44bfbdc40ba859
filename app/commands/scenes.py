"""`scenes` lists the shipped scenes; `show` draws one to a PNG."""

from app.checking.oracle import CollisionOracle
from app.commands import custom
from app.commands.common import announce, answering, check_outputs, print_json
from app.scene.model import Scene, scene_names


def register(subparsers) -> None:
    p = subparsers.add_parser("scenes", help="list the shipped scenes")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.set_defaults(func=run_scenes)

    p = subparsers.add_parser("show", help="draw a scene (obstacles, passage region, robot at start and goal)")
    p.add_argument(
        "scene", nargs="?", help="scene name, problem-file path or custom scene file (or --robot/--env instead)"
    )
    p.add_argument("--png", required=True, help="output PNG file")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    custom.add_arguments(p)  # --robot / --package-path / --env ...
    p.set_defaults(func=run_show)


def run_scenes(args) -> int:
    scenes = [Scene(name).summary() for name in scene_names()]
    with answering():
        if args.json:
            print_json({"scenes": scenes})
        else:
            width = max(len(s["name"]) for s in scenes)
            for s in scenes:
                print(f"{s['name']:<{width}}  {s['dof']} DOF  {s['description']}")
    return 0


def run_show(args) -> int:
    from app.draw import draw_scene  # loads matplotlib: only when a picture is drawn

    check_outputs(args.png)
    oracle = CollisionOracle(custom.scene_from_args(args, args.scene))
    with answering():  # the picture is the answer
        draw_scene(oracle, args.png)
        announce(args.png)
        if args.json:
            print_json({"scene": oracle.scene.name, "png": args.png})
    return 0
