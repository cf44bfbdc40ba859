"""The --robot / --env flags (bring your own robot and environment), for a command that takes a scene: they build
an app.scene.spec.CustomSpec, from which app.scene.custom.build_scene makes the scene."""

import argparse
import math

from app.commands.common import float_list, non_negative_float, positive_float_list
from app.errors import UserError
from app.scene import ompl_app
from app.scene.custom import CustomScene, build_scene, load_scene
from app.scene.files import MESH_METHODS
from app.scene.model import Scene
from app.scene.spec import CustomSpec


def add_package_path_argument(parser) -> None:
    """--package-path NAME=DIR (repeatable), for every command that reads a robot's files."""
    parser.add_argument(
        "--package-path",
        metavar="NAME=DIR",
        action="append",
        default=[],
        help="resolve package://NAME/... in the robot's files to DIR (repeatable)",
    )


def add_arguments(parser) -> None:
    """The --robot/--env flags, as one group of `parser`."""
    group = parser.add_argument_group("bring your own robot and environment (instead of SCENE)")
    group.add_argument("--robot", metavar="FILE", help="robot .urdf/.sdf, or a mesh (a free-flying rigid body)")
    group.add_argument(
        "--ompl-app",
        metavar="PROBLEM.cfg",
        help="an OMPL.app problem file (robot and environment meshes, start, goal, bounds), read with OMPL.app's "
        "frame conventions; the mesh, resolution and limit flags still apply",
    )
    add_package_path_argument(group)
    group.add_argument(
        "--floating",
        action="store_true",
        help="carry a URDF/SDF robot's root in SE(3) (x, y, z, yaw, pitch, roll) instead of welding it",
    )
    group.add_argument(
        "--env",
        metavar="FILE",
        action="append",
        default=[],
        help="obstacle mesh (.obj/.stl/.dae/...) or .sdf/.urdf (repeatable)",
    )
    group.add_argument(
        "--env-pose",
        metavar="X,Y,Z,R,P,Y",
        type=float_list,
        action="append",
        default=[],
        help="place the environment: metres and roll,pitch,yaw in degrees (once, or once per --env)",
    )
    _space_and_collision_arguments(group)


def _space_and_collision_arguments(group) -> None:
    """The flags of the same group that shape the configuration space, the meshes' decomposition and the pairs
    checked."""
    group.add_argument(
        "--bounds",
        metavar="LO..HI,...",
        help="lo..hi per coordinate, or for a floating robot per x,y,z only",
    )
    group.add_argument(
        "--mesh-method",
        choices=MESH_METHODS,
        default="auto",
        help="convex pieces of meshes (default auto: hulls that hold the mesh, within the tolerance of it, 5 mm for "
        "a robot's link; convex: every part's hull; shell, coacd, faces: validated pieces)",
    )
    group.add_argument(
        "--mesh-tolerance",
        type=non_negative_float,
        default=0.0,
        metavar="M",
        help="how far a decomposition may reach beyond the mesh surface, in metres (default: half the "
        "edge-check step for environment meshes, 0.2%% of its size for a robot mesh)",
    )
    group.add_argument(
        "--resolution",
        type=non_negative_float,
        default=0.0,
        metavar="STEP",
        help="edge-check step (default: a quarter of the robot's thickness, the median over its bodies)",
    )
    for kind, unit in (("velocity", "/s"), ("acceleration", "/s^2")):
        group.add_argument(
            f"--{kind}-limits",
            metavar="L,...",
            type=positive_float_list,
            default=[],
            help=f"{kind} limit per coordinate (m{unit} or rad{unit}; default: "
            + ("the model's, 1 where it has none)" if kind == "velocity" else "twice the velocity limits)"),
        )
    group.add_argument(
        "--self-collision",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="count the robot's collisions with itself (default: on; a mesh robot is one body and has none)",
    )
    group.add_argument(
        "--srdf",
        metavar="FILE",
        help="MoveIt SRDF: its <disable_collisions link1= link2=/> pairs are not checked",
    )
    group.add_argument(
        "--hold",
        metavar="JOINT=POSITION",
        type=held_joint,
        action="append",
        default=[],
        help="keep this joint at this position (radians or metres): it is no coordinate, so --start, --goal, "
        "--bounds and the limits name the other joints (repeatable)",
    )


def held_joint(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    try:
        position = float(value)
    except ValueError:
        position = math.nan
    if not sep or not name.strip() or not math.isfinite(position):
        raise argparse.ArgumentTypeError(f"needs JOINT=POSITION with a finite position, got {text!r}")
    return name.strip(), position


# The flags that describe a robot or environment of one's own: dest -> the flag as a user types it.
ROBOT_ONLY = {
    "package_path": "--package-path",
    "floating": "--floating",
    "env": "--env",
    "env_pose": "--env-pose",
    "bounds": "--bounds",
    "mesh_method": "--mesh-method",
    "mesh_tolerance": "--mesh-tolerance",
    "resolution": "--resolution",
    "self_collision": "--no-self-collision",
    "srdf": "--srdf",
    "hold": "--hold",
    "velocity_limits": "--velocity-limits",
    "acceleration_limits": "--acceleration-limits",
}


def _defaults() -> argparse.Namespace:
    parser = argparse.ArgumentParser(add_help=False)
    add_arguments(parser)
    return parser.parse_args([])


def spec_from_args(args) -> CustomSpec | None:
    """A CustomSpec from parsed flags, or None when no --robot was given. `args.start`/`args.goal` are lists, where
    the command has them (gui has not: its start and goal are set on the page, from the robot's home)."""
    if not args.robot:
        # A flag of a shipped scene's own (its resolution, its collisions) must not be silently ignored.
        defaults = vars(_defaults())
        given = [flag for dest, flag in ROBOT_ONLY.items() if getattr(args, dest) != defaults[dest]]
        if given:
            verb = "needs" if len(given) == 1 else "need"
            raise UserError(f"{', '.join(given)} {verb} --robot (for a scene, its file sets them)")
        return None
    return CustomSpec(
        robot=args.robot,
        package_path=list(args.package_path),
        floating=args.floating,
        env=list(args.env),
        env_pose=[v for pose in args.env_pose for v in pose],
        start=list(getattr(args, "start", None) or []),
        goal=list(getattr(args, "goal", None) or []),
        bounds=[args.bounds] if args.bounds else [],
        collisions="all" if args.self_collision else "environment",
        srdf=args.srdf or "",
        resolution=args.resolution,
        mesh_method=args.mesh_method,
        mesh_tolerance=args.mesh_tolerance,
        velocity_limits=list(args.velocity_limits),
        acceleration_limits=list(args.acceleration_limits),
        hold=dict(args.hold),
    )


# The flags that still apply to an OMPL.app problem (the file sets the rest).
OMPL_APP_OPTIONS = ("mesh_method", "mesh_tolerance", "resolution", "velocity_limits", "acceleration_limits")


def ompl_app_scene(args, scene: str | None) -> Scene:
    """The scene of --ompl-app PROBLEM.cfg; refused beside SCENE or a flag the problem file sets."""
    defaults = vars(_defaults())
    given = [
        flag
        for dest, flag in {"robot": "--robot", **ROBOT_ONLY}.items()
        if dest not in OMPL_APP_OPTIONS and getattr(args, dest) != defaults[dest]
    ]
    if scene or given:
        raise UserError(
            f"--ompl-app sets the robot, environment and bounds: give it without {', '.join(given) or 'SCENE'}"
        )
    return ompl_app.build_scene(args.ompl_app, **{dest: getattr(args, dest) for dest in OMPL_APP_OPTIONS})


def scene_from_args(args, scene: str | None = None) -> Scene:
    """The scene a command works on: --ompl-app or --robot/--env when given, else SCENE (a name or a scene file)."""
    if args.ompl_app:
        return ompl_app_scene(args, scene)
    spec = spec_from_args(args)
    if spec is not None:
        if scene:
            raise UserError("give either SCENE or --robot/--env, not both")
        return build_scene(spec)
    if not scene:
        raise UserError("a SCENE (name or file) or --robot is required")
    return load_scene(scene)


def describe(scene: Scene) -> list[str]:
    """For a custom scene, one line per mesh decomposition (method, pieces, connected parts per method, the volume the
    pieces add, tolerance, time, cached or not) and one for the edge-check step and Drake's load; nothing for another
    scene."""
    if not isinstance(scene, CustomScene):
        return []
    lines = []
    found = scene.info.get("ompl_app")
    if found:
        lines.append(
            f"OMPL.app problem {found['problem']}: {found['motion']}; COLLADA up axis, turned to y up as assimp "
            f"does: robot {found['up_axis']['robot'] or 'none'}, world {found['up_axis']['world'] or 'none'}; robot "
            f"re-centred on its mean vertex ({', '.join(f'{c:.4g}' for c in found['robot_centre'])})"
        )
    for d in scene.info["decompositions"]:
        how = f"from the cache in {d['seconds']:.2f} s" if d["from_cache"] else f"built in {d['seconds']:.1f} s"
        parts = ", ".join(f"{n} by {m}" for m, n in d["parts"].items())
        volume = d["volume"]
        if volume["relative_to"] == "mesh":
            added = f"{volume['added']:+.1%} volume outside the mesh"
        elif volume["hull"] > 0:
            added = f"{volume['pieces'] / volume['hull']:.0%} of the mesh's hull (the mesh is open)"
        else:  # a flat mesh (a planar problem's outline): its pieces have the volume their thickness gives them
            added = f"{volume['pieces']:.3g} cubic units of pieces round a flat mesh"
        lines.append(
            f"mesh {d['mesh']}: {d['pieces']} convex piece(s) by {d['method']} (parts: {parts}), {added}, "
            f"tolerance {d['validation']['tolerance']:.3g} m, {how}"
        )
    lines.append(
        f"scene {scene.name}: edge-check step {scene.resolution:.3g}, "
        f"Drake load {scene.info['drake_load_seconds']:.1f} s"
    )
    return lines
