"""A scene's problem file, read as data (stage (a) of a shipped scene): which models move, which collisions count,
bounds, start and goal, metric, passage, tool poses, mimic joints.

The problem file is loaded with Drake's typed YAML loader, so an unknown or misspelt key is an error rather than a
silently ignored setting. What the keys mean for the configuration space is derived later
(`app.scene.coordinates`), once the Drake diagram they describe is built (`app.scene.build`).
"""

from dataclasses import dataclass, field
from pathlib import Path

from app.errors import UserError
from app.io import check_input
from app.scene.files import PACKAGES

# pydrake is imported inside the functions that use it, so that importing the package (as the command line does)
# does not load Drake.


@dataclass
class Box:
    """An axis-aligned workspace box (world frame)."""

    lo: list[float] = field(default_factory=list)
    hi: list[float] = field(default_factory=list)


@dataclass
class PassageSpec:
    """A sample counts as "in the passage" when the origin of `frame` lies in one of `boxes`."""

    frame: str = ""
    boxes: list[Box] = field(default_factory=list)


@dataclass
class ToolPose:
    """A named pose of the scene's tool frame in the world: position (m) and roll-pitch-yaw (degrees, Drake's
    convention R = Rz(yaw) Ry(pitch) Rx(roll)). Goals of arm scenes are reached from these by inverse kinematics.
    `stop`: a job's robot comes to rest here (a weld point, a grasp); false: it passes through (an approach)."""

    name: str = ""
    xyz: list[float] = field(default_factory=list)
    rpy_deg: list[float] = field(default_factory=list)
    stop: bool = True


@dataclass
class Mimic:
    """A joint that follows another (URDF <mimic>): position = multiplier * the followed joint's + offset. It is no
    coordinate of the configuration space (see app.scene.cspace.PositionMap)."""

    joint: str = ""
    follows: str = ""
    multiplier: float = 1.0
    offset: float = 0.0


@dataclass
class ProblemFile:
    description: str = ""
    directives: str = ""  # a *.dmd.yaml file beside the problem file
    robot: list[str] = field(default_factory=list)  # model instances that move; everything else is environment
    # Which collisions count: "environment" (robot vs. obstacles) or "all" (also robot vs. itself).
    collisions: str = "environment"
    collisions_why: str = ""
    # An SRDF (MoveIt's format; a path relative to the problem file, or package://npp_robots/...) whose
    # <disable_collisions link1= link2=/> robot body pairs are never checked (adjacent links never are: see
    # app.scene.build.exclude_adjacent_bodies).
    srdf: str = ""
    lower: list[float] = field(default_factory=list)  # default: the model's joint limits
    upper: list[float] = field(default_factory=list)
    start: list[float] = field(default_factory=list)
    goal: list[float] = field(default_factory=list)
    # Metric weight per coordinate, so that metres and radians compare (an angle's weight is the lever arm it swings).
    weights: list[float] = field(default_factory=list)
    resolution: float = 0.5  # edge-check step in the weighted metric
    step: float = 0.0  # default sampler step a for this scene (0: a tenth of its largest linear extent)
    passage: PassageSpec = field(default_factory=PassageSpec)
    velocity_limits: list[float] = field(default_factory=list)  # default: the model's
    acceleration_limits: list[float] = field(default_factory=list)  # default: 2x the velocity limits
    view: str = "2d"  # how `show` draws it: "2d" top view or "3d"
    tool_frame: str = ""  # the frame `poses` are poses of (arm scenes); required when poses are given
    poses: list[ToolPose] = field(default_factory=list)  # named tool poses, in file order (e.g. a weld seam)
    mimic: list[Mimic] = field(default_factory=list)  # joints that follow others: not planned coordinates
    hold: dict[str, float] = field(default_factory=dict)  # joints that stay at these positions: no coordinates either
    # Body pairs never checked against each other: robot links, or an environment model's bodies (by their names).
    allowed_collisions: list[list[str]] = field(default_factory=list)


def read_problem(path: Path) -> ProblemFile:
    from pydrake.common.yaml import yaml_load_typed

    check_input(path, "scene file")
    try:
        problem = yaml_load_typed(schema=ProblemFile, filename=str(path))
    except Exception as exc:  # the loader raises RuntimeError, ValueError or yaml errors; all mean a bad file
        detail = " ".join(str(exc).split())
        raise UserError(f"bad scene file {path.name}: {detail[:300]}") from None
    if problem.collisions not in ("environment", "all"):
        raise UserError(f"bad scene file {path.name}: collisions must be 'environment' or 'all'")
    if problem.view not in ("2d", "3d"):
        raise UserError(f"bad scene file {path.name}: view must be '2d' or '3d'")
    if not problem.directives or not problem.robot:
        raise UserError(f"bad scene file {path.name}: 'directives' and 'robot' are required")
    return problem


def named_file(problem_path: Path, uri: str) -> Path:
    """A file named in the problem file: package://NAME/rest of a shipped package, else relative to the file."""
    if uri.startswith("package://"):
        name, _, rest = uri[len("package://") :].partition("/")
        if name not in PACKAGES:
            raise UserError(f"bad scene file {problem_path.name}: unknown package '{name}' in {uri}")
        return PACKAGES[name] / rest
    return problem_path.parent / uri


def directives_file(problem_path: Path, problem: ProblemFile) -> Path:
    """The problem file's model directives: a file beside it, within the size every input file is held to."""
    path = problem_path.parent / problem.directives
    if not path.is_file():
        raise UserError(f"bad scene file {problem_path.name}: directives file not found: {problem.directives}")
    return check_input(path, "model directives")
