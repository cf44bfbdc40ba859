"""The --robot / --env flags (bring your own robot and environment), for a command that takes a scene: they build
an app.custom_scene.CustomSpec, from which app.custom_scene.build_scene makes the scene."""

from app import meshes
from app.commands.common import float_list, non_negative_float
from app.custom_scene import CustomSpec, build_scene, load_scene
from app.errors import UserError
from app.scene import Scene


def add_arguments(parser) -> None:
    """The --robot/--env flags, as one group of `parser`."""
    group = parser.add_argument_group("bring your own robot and environment (instead of SCENE)")
    group.add_argument("--robot", metavar="FILE", help="robot .urdf/.sdf, or a mesh (a free-flying rigid body)")
    group.add_argument(
        "--package-path",
        metavar="NAME=DIR",
        action="append",
        default=[],
        help="resolve package://NAME/... in the robot's files to DIR (repeatable)",
    )
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
    group.add_argument(
        "--bounds",
        metavar="LO..HI,...",
        help="lo..hi per coordinate, or for a floating robot per x,y,z only",
    )
    group.add_argument(
        "--mesh-method",
        choices=meshes.METHODS,
        default="auto",
        help="convex decomposition of meshes (default auto: per mesh, validated)",
    )
    group.add_argument(
        "--mesh-tolerance",
        type=non_negative_float,
        default=0.0,
        metavar="M",
        help="how far a decomposition may reach beyond the mesh surface (default 0.2%% of its size)",
    )
    group.add_argument(
        "--resolution",
        type=non_negative_float,
        default=0.0,
        metavar="STEP",
        help="edge-check step (default: a quarter of the robot's smallest extent)",
    )
    group.add_argument(
        "--self-collision",
        action="store_true",
        help="count the robot's collisions with itself too (default: only with the environment)",
    )


def spec_from_args(args) -> CustomSpec | None:
    """A CustomSpec from parsed flags, or None when no --robot was given. `args.start`/`args.goal` are lists."""
    if not args.robot:
        if args.env:
            raise UserError("--env needs --robot")
        return None
    return CustomSpec(
        robot=args.robot,
        package_path=list(args.package_path),
        floating=args.floating,
        env=list(args.env),
        env_pose=[v for pose in args.env_pose for v in pose],
        start=list(args.start or []),
        goal=list(args.goal or []),
        bounds=[args.bounds] if args.bounds else [],
        collisions="all" if args.self_collision else "environment",
        resolution=args.resolution,
        mesh_method=args.mesh_method,
        mesh_tolerance=args.mesh_tolerance,
    )


def scene_from_args(args, scene: str | None = None) -> Scene:
    """The scene a command works on: --robot/--env when given, else SCENE (a name or a scene file)."""
    spec = spec_from_args(args)
    if spec is not None:
        if scene:
            raise UserError("give either SCENE or --robot/--env, not both")
        return build_scene(spec)
    if not scene:
        raise UserError("a SCENE (name or file) or --robot is required")
    return load_scene(scene)
