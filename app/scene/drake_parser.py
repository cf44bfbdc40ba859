"""Drake's model parser, as every stage of the scene uses it: a RobotDiagramBuilder whose parser knows the shipped
packages and the user's, Drake's known-harmless URDF warnings summarised in one line per file, its refusals as one
line naming the user's file (never a copy in the cache), and what it says about one model file on its own: a URDF
without its geometry (before any mesh work, app.scene.inputs), a model's root bodies (app.scene.emit)."""

import collections
import contextlib
import logging
import re
import warnings
from pathlib import Path

from app.errors import Note, UserError
from app.scene.files import PACKAGES

# pydrake is imported inside the functions that use it, so that importing the package does not load Drake.

# Drake's URDF parser warns about each element it ignores, once per parse. These elements are ROS controller,
# calibration, transmission and friction settings a planner never reads (an xArm7 description drew 70 such warnings).
# A load says in one line per file what it ignored (each element once per process: a custom scene parses its robot
# several times) instead of a warning per element per parse. Each pattern names the element it is about.
HARMLESS_URDF_WARNINGS = (
    r"The tag '(safety_controller|calibration)' found as a child of '\w+' is currently unsupported and will be ignored",
    r"A joint has specified a non-zero value for the '(friction)' attribute of a joint/dynamics tag",
    r"A '\w+' element contains a (mechanicalReduction) element with a value",
    r"A <(transmission)> has a type that isn't 'SimpleTransmission'",
    r"A link has specified the '(group)' attribute on the <collision> tag",
    r"A joint has specified a value for the '(coulomb_window)' attribute",
    r"While re-expressing as central (inertia): .*condition 'mass > 0' failed",  # a massless link's inertia
    r"Drake only supports the (mimic) element for single-dof joints",  # a fixed joint's <mimic>
)
_HARMLESS = re.compile(r"^(.*?):(\d+): warning: (?:" + "|".join(HARMLESS_URDF_WARNINGS) + ")")
_harmless_seen: set[tuple[str, str, str]] = set()  # (file name, line, element) already summarised
_harmless_new: dict[str, collections.Counter] | None = None  # per file name and element, while model_loading runs

# A URDF's geometry and materials, for reading it without them (lines kept).
_GEOMETRY_ELEMENTS = re.compile(
    r"<(collision|visual)\b[^>]*?/>|<(collision|visual)\b.*?</\2\s*>|<material\b[^>]*?/>|<material\b.*?</material\s*>",
    re.S,
)
# An absolute path (or file:// URI) in a message: the user knows their files by name, and the cache's by none.
_ABSOLUTE_PATH = re.compile(r"(?<![\w./])(?:file:)?/+(?:[^\s'\"<>:/]+/)+([^\s'\"<>:/]+)")


def _drop_harmless(record: logging.LogRecord) -> bool:
    found = _HARMLESS.match(record.getMessage())
    if found is None or _harmless_new is None or found.group(1).startswith("<"):  # (a string parsed: no file)
        return True
    # By file name and line: the cached copies of a model (its mesh links rewritten, lines kept) are the same elements.
    name, line = Path(found.group(1)).name, found.group(2)
    element = next(g for g in found.groups()[2:] if g)
    if (name, line, element) not in _harmless_seen:
        _harmless_seen.add((name, line, element))
        _harmless_new.setdefault(name, collections.Counter())[element] += 1
    return False


@contextlib.contextmanager
def model_loading():
    """Drake's known-harmless URDF warnings (HARMLESS_URDF_WARNINGS) kept off stderr while models load, and
    summarised in one line per file at the end of the outermost block (nothing if every one was summarised before):
    `note: arm.urdf: Drake ignored 70 elements it does not use for planning (friction x35, mechanicalReduction x35)`.
    """
    global _harmless_new
    if _harmless_new is not None:  # an enclosing block summarises
        yield
        return
    logger = logging.getLogger("drake")
    _harmless_new = {}
    logger.addFilter(_drop_harmless)
    try:
        yield
    finally:
        logger.removeFilter(_drop_harmless)
        found, _harmless_new = _harmless_new, None
        for name, counts in found.items():
            parts = ", ".join(f"{element} x{count}" for element, count in sorted(counts.items()))
            total = sum(counts.values())
            warnings.warn(
                f"{name}: Drake ignored {total} element{'s' if total > 1 else ''} it does not use for planning "
                f"({parts})",
                Note,
                stacklevel=3,
            )


@contextlib.contextmanager
def drake_quiet_about(marker: str):
    """Drake's log records that contain `marker` dropped while the block runs."""
    logger = logging.getLogger("drake")

    def keep(record: logging.LogRecord) -> bool:
        return marker not in record.getMessage()

    logger.addFilter(keep)
    try:
        yield
    finally:
        logger.removeFilter(keep)


def robot_diagram_builder():
    """Drake's RobotDiagramBuilder; Drake's refusal to start (e.g. DRAKE_ALLOW_NETWORK forbids fetching the
    drake_models package it registers in every parser) becomes one line for the user."""
    from pydrake.planning import RobotDiagramBuilder

    try:
        return RobotDiagramBuilder(time_step=0.0)
    except RuntimeError as exc:
        reason = " ".join(str(exc).split())
        if "DRAKE_ALLOW_NETWORK" in reason:  # Drake registers drake_models in every parser, used or not
            reason += (
                " (unset DRAKE_ALLOW_NETWORK or add package_map to it: no file of that package is used, so nothing"
                " is fetched)"
            )
        raise UserError(f"Drake cannot start its model parser: {reason}") from None


def add_packages(parser, packages: dict[str, Path]) -> None:
    """`packages` (name -> folder) in the parser's package map, each unless a package of its name is there."""
    for name, directory in packages.items():
        if not parser.package_map().Contains(name):
            parser.package_map().Add(name, str(directory))


def builder_with_packages(packages: dict[str, Path]):
    """A RobotDiagramBuilder whose parser knows the shipped packages and `packages` (the user's win a name)."""
    builder = robot_diagram_builder()
    add_packages(builder.parser(), {**{k: Path(v) for k, v in PACKAGES.items()}, **packages})
    return builder


def user_words(text: str) -> str:
    """`text` with every absolute path cut to its file name (a model copied into the cache keeps its name)."""
    return _ABSOLUTE_PATH.sub(r"\1", text)


def parser_error(exc: Exception, path: Path) -> UserError:
    """Drake's refusal of the model file `path` (the user's: a copy in the cache has the same name) in one line."""
    text = user_words(" ".join(str(exc).split()))
    if "unknown package" in text:
        match = re.search(r"unknown package '([^']+)'", text)
        name = match.group(1) if match else "?"
        return UserError(f"cannot load {path.name}: unknown package '{name}' (add the package path {name}=DIR)")
    return UserError(f"cannot load {path.name}: {text[:300]}")


def probe_model(path: Path, packages: dict[str, Path]) -> dict:
    """Parse a URDF/SDF on its own: the model's name, bodies not attached to the world (floating) and their names."""
    builder = builder_with_packages(packages)
    plant = builder.plant()
    try:
        instances = builder.parser().AddModels(str(path))
        plant.Finalize()
    except Exception as exc:  # pydrake raises RuntimeError (parse errors, unknown packages, bad meshes)
        raise parser_error(exc, path) from None
    if len(instances) != 1:
        raise UserError(f"{path.name}: expected one model, found {len(instances)}")
    floating = sorted(plant.get_body(b).name() for b in plant.GetFloatingBaseBodies())
    return {
        "name": plant.GetModelInstanceName(instances[0]),
        "floating": floating,
        "positions": plant.num_positions(),
        "static": plant.num_bodies() <= 1,
    }


def read_bare_urdf(text: str, path: Path, packages: dict[str, Path]) -> dict:
    """Drake's parser on the URDF without its geometry and materials (lines kept, so its messages point into the
    user's file): its refusal, else the joints it makes (name, type, positions, ephemeral: a joint Drake adds to a
    body attached to nothing) in position order, each position's limits, and the bodies attached to nothing (its
    roots). Its warnings are left to the real load, which summarises them."""
    from pydrake.multibody.tree import JointIndex

    bare = _GEOMETRY_ELEMENTS.sub(lambda m: "\n" * m.group(0).count("\n"), text)
    builder = builder_with_packages(packages)
    plant = builder.plant()
    literal = "<literal-string>.urdf"
    try:
        with drake_quiet_about(literal):
            builder.parser().AddModelsFromString(bare, "urdf")
            plant.Finalize()
    except Exception as exc:  # pydrake raises RuntimeError
        message = " ".join(str(exc).split()).replace(f"{literal}:", "line ").replace(literal, path.name)
        raise parser_error(RuntimeError(message), path) from None
    joints = [plant.get_joint(JointIndex(i)) for i in range(plant.num_joints())]
    joints.sort(key=lambda j: j.position_start())
    moving = [j for j in joints if j.num_positions()]
    return {
        "joints": [(j.name(), j.type_name(), j.num_positions(), j.is_ephemeral()) for j in moving],
        "lower": [float(v) for j in moving if not j.is_ephemeral() for v in j.position_lower_limits()],
        "upper": [float(v) for j in moving if not j.is_ephemeral() for v in j.position_upper_limits()],
        "floating": sorted(plant.get_body(b).name() for b in plant.GetFloatingBaseBodies()),
    }
