"""A work cell that changes: obstacles added, moved or removed, and objects the robot carries -- as data.

A change (`CellChange`, read from a small YAML file with Drake's typed loader, or built in Python) names objects by
the names their collision geometry has in the cell (`door_south`, `fixture`; `obstacles::fixture` where two models
share a name) and is applied in a fixed order: detach, remove, move, add, attach. A list of changes applies one after
the other. `changed_scene(scene, changes)` is the cell they leave: a Scene of its own, written as files into the cache
(like a custom scene, so that helper processes load the very same cell), named as the scene it came from:

- the environment's model files again, without the collision (and visual) elements of the objects removed or moved;
- one static model, `cell_changes`, holding every object added or moved, each a link of its own at its world pose;
- each payload a model of its own welded to a robot frame, listed among the models that move: it is checked against
  the cell and, where the scene counts self-collisions, against the arm -- except the links it may `touch` (beside
  the body it is welded to, which never counts), which join the scene's SRDF pairs.

Object shapes are boxes, spheres, cylinders, capsules or meshes; Drake checks a mesh as its convex hull, which holds
the mesh, so a mesh object can only make the cell more careful, never let a motion through the real shape.
"""

import dataclasses
import functools
import hashlib
import json
import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.errors import UserError
from app.io import check_input
from app.scene.model import Scene
from app.scene.problem import directives_file, named_file

CHANGES_MODEL = "cell_changes"
CHANGED_COLOUR = "0.6 0.45 0.3 1"  # what a change added, moved or attached, as drawn: brown among grey obstacles
# Where a payload's mass matters to nobody (planning is kinematic), but Drake's parser wants a valid inertia.
_INERTIAL = (
    "<inertial><mass>0.1</mass><inertia><ixx>1e-4</ixx><iyy>1e-4</iyy><izz>1e-4</izz>"
    "<ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia></inertial>"
)


@dataclass
class Placement:
    """A pose: position and roll-pitch-yaw, in the world or in another object's frame.

    Attributes:
        xyz: The position, metres.
        rpy_deg: Roll, pitch and yaw in degrees (R = Rz(yaw) Ry(pitch) Rx(roll)).
        relative_to: The object whose frame the pose is in ("": the world; an attached object's pose is always in
            its link's frame).
    """

    xyz: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    rpy_deg: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    relative_to: str = ""


@dataclass
class Solid:
    """An object's name, shape and pose. Exactly one shape is given.

    Attributes:
        name: The object's name in the cell (a letter, then letters, digits, '_' or '-').
        box: [x, y, z] sizes, metres.
        sphere: [radius].
        cylinder: [radius, length], along the object's z axis.
        capsule: [radius, length], along the object's z axis.
        mesh: A mesh file (relative to the change file); checked as its convex hull, which holds it.
        scale: The mesh's units in metres.
        pose: Where the object is.
        part_of: The object this solid is a part of ("": none), as a MoveIt collision object's primitives are: a
            change that removes, moves or detaches names the object, and a move moves its parts as one.
        object_pose: That object's own pose (as `pose` is given: in the world or relative to another object, or
            in the link's frame): a move places it, and its parts keep their poses relative to it.
    """

    name: str = ""
    box: list[float] = field(default_factory=list)
    sphere: list[float] = field(default_factory=list)
    cylinder: list[float] = field(default_factory=list)
    capsule: list[float] = field(default_factory=list)
    mesh: str = ""
    scale: float = 1.0
    pose: Placement = field(default_factory=Placement)
    part_of: str = ""
    object_pose: Placement = field(default_factory=Placement)


@dataclass
class Move:
    """Move an obstacle.

    Attributes:
        name: The obstacle's name in the cell.
        pose: Where it goes; with `by`, the offset: its translation added in the world, its rotation turning the
            object about its own origin.
        by: Whether `pose` is an offset from where the object is.
    """

    name: str = ""
    pose: Placement = field(default_factory=Placement)
    by: bool = False


@dataclass
class Attachment(Solid):
    """An object the robot carries: a Solid welded to a robot link, its pose in that link's frame.

    Attributes:
        name: As a Solid's.
        box: As a Solid's.
        sphere: As a Solid's.
        cylinder: As a Solid's.
        capsule: As a Solid's.
        mesh: As a Solid's.
        scale: As a Solid's.
        pose: Where it is held, in the frame of `link`.
        part_of: As a Solid's.
        object_pose: As a Solid's (in the frame of `link`).
        link: The robot link or frame it is welded to.
        touch: Robot links it may touch (the body it is welded to always may).
    """

    link: str = ""
    touch: list[str] = field(default_factory=list)


@dataclass
class CellChange:
    """One change of a cell, applied in this order: detach, remove, move, add, attach (by name).

    Attributes:
        detach: Carried objects put down (they leave the cell).
        remove: Obstacles taken away.
        move: Obstacles moved.
        add: Obstacles added.
        attach: Objects the robot takes and carries.
    """

    detach: list[str] = field(default_factory=list)
    remove: list[str] = field(default_factory=list)
    move: list[Move] = field(default_factory=list)
    add: list[Solid] = field(default_factory=list)
    attach: list[Attachment] = field(default_factory=list)

    def to_dict(self) -> dict:
        """The change as plain data (what a roadmap's provenance records; `change_from_dict` reads it back)."""
        return dataclasses.asdict(self)

    def describe(self) -> str:
        """One line: what the change does."""
        parts = [f"{verb} {', '.join(names)}" for verb, names in self._names().items() if names]
        return "; ".join(parts) or "nothing"

    def _names(self) -> dict[str, list[str]]:
        return {
            "detach": list(self.detach),
            "remove": list(self.remove),
            "move": [m.name for m in self.move],
            "add": list(dict.fromkeys(s.part_of or s.name for s in self.add)),
            "attach": list(dict.fromkeys(a.part_of or a.name for a in self.attach)),
        }


def read_change(path) -> CellChange:
    """The change in YAML file `path` (the keys of CellChange); a mesh's file relative to it, made absolute."""
    return _read_typed(path, CellChange, "change file")


def read_payload(path) -> CellChange:
    """The change a payload file makes: the robot takes the one object it holds (the keys of Attachment: a Solid, the
    `link` it is held by and the links it may `touch`) and carries it."""
    return CellChange(attach=[_read_typed(path, Attachment, "payload file")])


def _read_typed(path, schema, what: str):
    """A `schema` from YAML file `path` (one UserError if it is not one), its mesh files made absolute."""
    from pydrake.common.yaml import yaml_load_typed

    path = check_input(Path(path), what)
    try:
        read = yaml_load_typed(schema=schema, filename=str(path))
    except Exception as exc:  # the loader raises RuntimeError, ValueError or yaml errors; all mean a bad file
        raise UserError(f"bad {what} {path.name}: {' '.join(str(exc).split())[:300]}") from None
    for solid in [*read.add, *read.attach] if isinstance(read, CellChange) else [read]:
        if solid.mesh:
            solid.mesh = str((path.parent / solid.mesh).resolve())
    return read


def change_from_dict(data: dict) -> CellChange:
    """A change from `CellChange.to_dict`'s plain data (UserError if it is not one)."""
    from pydrake.common.yaml import yaml_load_typed

    try:
        return yaml_load_typed(schema=CellChange, data=json.dumps(data))
    except Exception as exc:
        raise UserError(f"not a cell change: {' '.join(str(exc).split())[:300]}") from None


# ---- the objects of a cell ----------------------------------------------------------------------------------------
@dataclass
class _Object:
    shape: object  # a pydrake.geometry Shape
    pose: object  # RigidTransform: in the world (an obstacle), or in its link's frame (a payload)
    model: str = ""  # the environment model it came from ("" once added or moved)
    link: str = ""  # a payload's robot frame (scoped name)
    touch: tuple[str, ...] = ()
    part_of: str = ""  # the object it is a part of (Solid.part_of)
    origin: object = None  # that object's pose (RigidTransform), as `pose` is


class _Cell:
    """The objects of a scene as its changes leave them: obstacles by name, payloads by name."""

    def __init__(self, scene):
        from pydrake.geometry import Role

        self.scene = scene
        inspector = scene.diagram.scene_graph().model_inspector()
        query = _query_object(scene)
        robot = set(scene.robot_instances)
        self.obstacles: dict[str, _Object] = {}
        self.payloads: dict[str, _Object] = {}
        self._full: dict[str, str] = {}  # "model::name" -> name, for names two models share
        shared = set()
        for g in inspector.GetAllGeometryIds(Role.kProximity):
            if scene.plant.GetBodyFromFrameId(inspector.GetFrameId(g)).model_instance() in robot:
                continue
            model, _, name = inspector.GetName(g).rpartition("::")
            shared |= {name} if name in self.obstacles else set()
            found = _Object(inspector.GetShape(g), query.GetPoseInWorld(g), model)  # one object, known by both names
            self.obstacles.setdefault(name, found)
            self.obstacles[f"{model}::{name}"] = found
            self._full[f"{model}::{name}"] = name
        for name in shared:  # a name two models share is only known with its model's
            del self.obstacles[name]
        self.removed: set[tuple[str, str]] = set()  # (model, collision name) of the original obstacles gone

    def names(self) -> list[str]:
        """Each obstacle's name, sorted: its own, or `model::name` where two models share it."""
        return sorted(n for n in self.obstacles if "::" not in n or _bare(n) not in self.obstacles)

    def obstacle(self, name: str, verb: str) -> _Object:
        found = self.obstacles.get(name)
        if found is None:
            known = ", ".join(self.names())
            raise UserError(f"cannot {verb} '{name}': no such object in the cell (objects: {known})")
        return found

    def take(self, name: str, verb: str) -> _Object:
        """Object `name` out of the cell."""
        found = self.obstacle(name, verb)
        for key in [k for k, o in self.obstacles.items() if o is found]:
            del self.obstacles[key]
        if found.model:
            self.removed.add((found.model, self._full.get(name, name) if "::" in name else name))
        return found

    def world_pose(self, placement: Placement, what: str):
        """`placement` as a pose in the world."""
        pose = _transform(placement, what)
        if placement.relative_to:
            pose = self.pose_of(placement.relative_to, f"place '{what}' relative to").multiply(pose)
        return pose

    def pose_of(self, name: str, verb: str):
        """The world pose of obstacle `name`: an object of parts' own pose (Solid.object_pose), else its geometry's."""
        parts = self.parts(self.obstacles, name)
        return self.obstacles[parts[0]].origin if parts else self.obstacle(name, verb).pose

    @staticmethod
    def parts(objects: dict, name: str) -> list[str]:
        """The keys of the parts of object `name` (Solid.part_of) in `objects`: none where it has no parts."""
        return [key for key, o in objects.items() if o.part_of == name]

    def apply(self, change: CellChange) -> None:
        for name in change.detach:
            keys = self.parts(self.payloads, name) or ([name] if name in self.payloads else [])
            if not keys:
                raise UserError(f"cannot detach '{name}': the robot carries no such object")
            for key in keys:
                del self.payloads[key]
        for name in change.remove:
            for key in self.parts(self.obstacles, name) or [name]:
                self.take(key, "remove")
        for move in change.move:
            if move.by and move.pose.relative_to:
                raise UserError(f"cannot move '{move.name}' by a pose relative to another object: give it in the world")
            old = self.pose_of(move.name, "move")
            if move.by:
                offset = _transform(move.pose, move.name)
                new = _rigid(offset.rotation().multiply(old.rotation()), old.translation() + offset.translation())
            else:
                new = self.world_pose(move.pose, move.name)
            parts = self.parts(self.obstacles, move.name)
            carry = new.multiply(old.inverse())  # each part keeps its pose relative to the object's
            for key in parts or [move.name]:
                moved = self.take(key, "move")
                pose = carry.multiply(moved.pose) if parts else new
                origin = new if parts else moved.origin  # (one part moved alone leaves its object where it was)
                self.obstacles[_bare(key)] = _Object(moved.shape, pose, part_of=moved.part_of, origin=origin)
        objects = self.objects()
        object_poses: dict[str, Placement] = {}
        for solid in [*change.add, *change.attach]:
            if object_poses.setdefault(solid.part_of, solid.object_pose) != solid.object_pose and solid.part_of:
                raise UserError(f"the parts of '{solid.part_of}' give it different poses (object_pose): give one")
        for solid in change.add:
            self._new_name(solid, objects, "add")
            self.obstacles[solid.name] = _Object(
                _shape(solid),
                self.world_pose(solid.pose, solid.name),
                part_of=solid.part_of,
                origin=self.world_pose(solid.object_pose, solid.part_of) if solid.part_of else None,
            )
        for attachment in change.attach:
            self._new_name(attachment, objects, "attach")
            if attachment.pose.relative_to or attachment.object_pose.relative_to:
                raise UserError(f"cannot attach '{attachment.name}': its pose is in its link's frame (no relative_to)")
            link = _robot_frame(self.scene, attachment.link, attachment.name)
            touch = tuple(_robot_body(self.scene, name, attachment.name) for name in attachment.touch)
            shape = _shape(attachment)
            self.payloads[attachment.name] = _Object(
                shape,
                _transform(attachment.pose, attachment.name),
                "",
                link,
                touch,
                attachment.part_of,
                _transform(attachment.object_pose, attachment.part_of) if attachment.part_of else None,
            )

    def added_obstacles(self) -> list[tuple[str, object, object]]:
        """(name, shape, world pose) of each obstacle added or moved: the changes model's links."""
        return [(name, o.shape, o.pose) for name, o in self.obstacles.items() if not o.model]

    def _new_name(self, solid: Solid, before: set[str], verb: str) -> None:
        """Refuses a solid whose name, or whose object's (Solid.part_of), is no name or is taken: by anything in the
        cell, or, for its object, by an object of parts the cell had before this change."""
        from pydrake.multibody.tree import ModelInstanceIndex

        plant = self.scene.plant
        instances = {plant.GetModelInstanceName(ModelInstanceIndex(i)) for i in range(plant.num_model_instances())}
        taken = {*self.obstacles, *self.payloads, *instances, CHANGES_MODEL}
        objects = self.objects()
        for name in (solid.name, *([solid.part_of] if solid.part_of else [])):
            if not name or not name.replace("_", "").replace("-", "").isalnum() or not name[0].isalpha():
                raise UserError(f"cannot {verb} '{name}': a name is a letter, then letters, digits, '_' or '-'")
        if solid.part_of and solid.part_of in before | taken:
            raise UserError(f"cannot {verb} '{solid.part_of}': the cell already has something of that name")
        if solid.name in taken or solid.name in objects - {solid.part_of}:
            raise UserError(f"cannot {verb} '{solid.name}': the cell already has something of that name")

    def objects(self) -> set[str]:
        """The names of the objects of parts in the cell (Solid.part_of)."""
        return {o.part_of for o in [*self.obstacles.values(), *self.payloads.values()]} - {""}


def obstacle_names(scene) -> list[str]:
    """The names a change may give the scene's obstacles, sorted (`model::name` only where two models share one)."""
    return _Cell(scene).names()


def _bare(name: str) -> str:
    return name.rpartition("::")[2]


# ---- the changed scene --------------------------------------------------------------------------------------------
def changed_scene(scene, changes: list[CellChange], cache_dir: Path | None = None):
    """The cell `scene` becomes after `changes` (in order): a Scene of its own, named as `scene`, loaded from files
    written into the cache (app.scene.meshes.cache.cache_root, or `cache_dir`). No changes: `scene` itself.
    UserError (one line) for a change that cannot be applied: an unknown object or link, a name taken, a bad shape."""
    if not changes:
        return scene
    if isinstance(scene, ChangedScene) and scene.base is not None:
        # A changed cell changes again: all its changes, from the scene they started from.
        return changed_scene(scene.base, [*scene.changes, *changes], cache_dir)
    from app.scene.meshes.cache import cache_root

    cell = _Cell(scene)
    for change in changes:
        cell.apply(change)
    files = _cell_files(scene, cell)
    key = hashlib.sha256(json.dumps(files, sort_keys=True).encode()).hexdigest()[:24]
    folder = (Path(cache_dir).absolute() if cache_dir else cache_root()) / "cells" / key
    from app.scene.emit import write_if_changed

    for name, text in files.items():
        write_if_changed(folder / name, text.replace("@DIR@", str(folder)))
    changed = ChangedScene(folder / f"{scene.name}.yaml", scene.packages(), scene.name)
    changed.base, changed.changes = scene, list(changes)
    return changed


class ChangedScene(Scene):
    """A scene after changes (`changed_scene`), loaded from its generated files: named as the scene it came from,
    with that scene's packages. `base` is that scene, `changes` the changes, in order."""

    def __init__(self, problem_path: Path, packages: dict[str, Path], name: str):
        self._packages = dict(packages)
        super().__init__(str(problem_path))
        self.name = name
        # (another process loads the very same files; `base` and `changes` stay with the one that made them)
        self.recipe = functools.partial(ChangedScene, problem_path, self._packages, name)
        self.base, self.changes = None, []

    def packages(self) -> dict[str, Path]:
        return dict(self._packages)


def _cell_files(scene, cell: _Cell) -> dict[str, str]:
    """File name -> text (@DIR@: the folder they are written to) of the changed cell: its problem file, directives,
    environment models, changes model, payload models and SRDF."""
    from pydrake.multibody.parsing import LoadModelDirectives

    problem_path = Path(scene.path)
    directives_path = directives_file(problem_path, scene.problem)
    text = directives_path.read_text()
    files: dict[str, str] = {}
    edited = {model for model, _ in cell.removed}
    for directive in LoadModelDirectives(str(directives_path)).directives:
        model = directive.add_model
        if model is None or model.name not in edited:
            continue
        source = _resolve(model.file, scene.packages(), directives_path)
        name = f"env-{model.name}{source.suffix}"
        files[name] = _without(source, {n for m, n in cell.removed if m == model.name})
        text = text.replace(model.file, json.dumps(f"file://@DIR@/{name}"))
    # Relative references of the directives now live elsewhere: their package:// and file:// forms are untouched.
    lines = [text.rstrip("\n")]
    if cell.added_obstacles():
        files[f"{CHANGES_MODEL}.sdf"] = _changes_sdf(cell)
        lines.append(_add_model(CHANGES_MODEL, f"{CHANGES_MODEL}.sdf"))
    robot = list(scene.problem.robot)
    pairs = list(scene.disabled_pairs)
    for name, payload in cell.payloads.items():
        files[f"payload-{name}.sdf"] = _sdf_model(name, [(name, payload.shape, None)], static=False)
        lines.append(_add_model(name, f"payload-{name}.sdf"))
        lines.append(_weld(payload.link, f"{name}::{name}", payload.pose))
        robot.append(name)
        pairs += [(name, body) for body in payload.touch]
    files[f"{scene.name}.dmd.yaml"] = "\n".join(lines) + "\n"
    problem = _problem_data(scene)
    problem.update(directives=f"{scene.name}.dmd.yaml", robot=robot)
    if pairs != list(scene.disabled_pairs):
        files["cell.srdf"] = _srdf(pairs)
        problem["srdf"] = "cell.srdf"
    elif scene.problem.srdf:
        problem["srdf"] = str(named_file(problem_path, scene.problem.srdf))
    files[f"{scene.name}.yaml"] = json.dumps(problem, indent=1) + "\n"
    return files


def _problem_data(scene) -> dict:
    """The scene's problem file as plain data (JSON is YAML), every key as the typed loader read it."""
    return json.loads(json.dumps(dataclasses.asdict(scene.problem)))


def _resolve(uri: str, packages: dict, directives_path: Path) -> Path:
    if uri.startswith("package://"):
        name, _, rest = uri[len("package://") :].partition("/")
        if name in packages:
            return Path(packages[name]) / rest
    elif uri.startswith("file://"):
        return Path(uri[len("file://") :])
    else:
        return directives_path.parent / uri
    raise UserError(f"cannot change the cell: its model file {uri} is not found")


def _without(path: Path, names: set[str]) -> str:
    """Model file `path`'s text without the <collision> and <visual> elements named in `names`."""
    text = path.read_text()
    for prefix, uri in re.findall(r'xmlns:([A-Za-z_][\w.-]*)\s*=\s*"([^"]*)"', text):
        ET.register_namespace(prefix, uri)  # written back under their own prefixes, which Drake's parser reads
    tree = ET.ElementTree(ET.fromstring(text))
    found = set()
    for parent in tree.getroot().iter():
        for child in list(parent):
            if child.tag in ("collision", "visual") and child.get("name") in names:
                parent.remove(child)
                found.add(child.get("name"))
    if names - found:
        missing = ", ".join(sorted(names - found))
        raise UserError(f"cannot change the cell: {missing} not found by name in its model file {path.name}")
    return ET.tostring(tree.getroot(), encoding="unicode") + "\n"


def _add_model(name: str, file: str) -> str:
    return f"- add_model:\n    name: {name}\n    file: {json.dumps('file://@DIR@/' + file)}"


def _weld(parent: str, child: str, pose) -> str:
    x, y, z = map(float, pose.translation())
    r, p, w = map(float, np.degrees(_rpy(pose)))
    return (
        f"- add_weld:\n    parent: {json.dumps(parent)}\n    child: {json.dumps(child)}\n    X_PC:\n"
        f"      translation: [{x!r}, {y!r}, {z!r}]\n      rotation: !Rpy {{ deg: [{r!r}, {p!r}, {w!r}] }}"
    )


def _srdf(pairs: list[tuple[str, str]]) -> str:
    rows = "".join(f'  <disable_collisions link1="{a}" link2="{b}" reason="Allowed"/>\n' for a, b in pairs)
    return f'<?xml version="1.0"?>\n<robot name="cell">\n{rows}</robot>\n'


def _changes_sdf(cell: _Cell) -> str:
    return _sdf_model(CHANGES_MODEL, cell.added_obstacles(), static=True)


def _sdf_model(model: str, links: list, static: bool) -> str:
    """An SDF model of one link per (name, shape, world pose or None) entry, collision and visual alike."""
    body = []
    for name, shape, pose in links:
        geometry = _geometry_xml(shape)
        placed = "" if pose is None else f"<pose>{' '.join(repr(float(v)) for v in _pose_numbers(pose))}</pose>"
        body.append(
            f'  <link name="{name}">{placed}{"" if static else _INERTIAL}'
            f'<collision name="{name}"><geometry>{geometry}</geometry></collision>'
            f'<visual name="{name}"><geometry>{geometry}</geometry>'
            f"<material><diffuse>{CHANGED_COLOUR}</diffuse></material></visual></link>"
        )
    return (
        '<?xml version="1.0"?>\n<sdf version="1.9" xmlns:drake="http://drake.mit.edu">\n'
        f'<model name="{model}"><static>{"true" if static else "false"}</static>\n'
        + "\n".join(body)
        + "\n</model>\n</sdf>\n"
    )


def _geometry_xml(shape) -> str:
    from pydrake.geometry import Box, Capsule, Convex, Cylinder, Ellipsoid, Mesh, Sphere

    if isinstance(shape, Box):
        return f"<box><size>{shape.width()!r} {shape.depth()!r} {shape.height()!r}</size></box>"
    if isinstance(shape, Sphere):
        return f"<sphere><radius>{shape.radius()!r}</radius></sphere>"
    if isinstance(shape, Cylinder):
        return f"<cylinder><radius>{shape.radius()!r}</radius><length>{shape.length()!r}</length></cylinder>"
    if isinstance(shape, Capsule):
        size = f"<drake:radius>{shape.radius()!r}</drake:radius><drake:length>{shape.length()!r}</drake:length>"
        return f"<drake:capsule>{size}</drake:capsule>"
    if isinstance(shape, Ellipsoid):
        size = "".join(
            f"<drake:{axis}>{value!r}</drake:{axis}>" for axis, value in zip("abc", (shape.a(), shape.b(), shape.c()))
        )
        return f"<drake:ellipsoid>{size}</drake:ellipsoid>"
    if isinstance(shape, (Mesh, Convex)):
        uri = f"file://{shape.source().path()}"
        hull = "<drake:declare_convex/>" if isinstance(shape, Convex) else ""
        return f"<mesh><uri>{uri}</uri><scale>{' '.join(repr(float(v)) for v in shape.scale3())}</scale>{hull}</mesh>"
    raise UserError(f"cannot move an object of shape {type(shape).__name__}")


def _shape(solid: Solid):
    """The Drake shape of `solid`: exactly one of its shape keys, with sizes a shape can have."""
    from pydrake.geometry import Box, Capsule, Cylinder, Mesh, Sphere

    given = {
        key: getattr(solid, key) for key in ("box", "sphere", "cylinder", "capsule", "mesh") if getattr(solid, key)
    }
    if len(given) != 1:
        raise UserError(f"object '{solid.name}' needs exactly one of box, sphere, cylinder, capsule or mesh")
    ((kind, size),) = given.items()
    if kind == "mesh":
        path = check_input(Path(size), "mesh file")
        if not (math.isfinite(solid.scale) and solid.scale > 0):
            raise UserError(f"object '{solid.name}': scale must be a positive number, got {solid.scale!r}")
        return Mesh(str(path), solid.scale)
    counts = {"box": 3, "sphere": 1, "cylinder": 2, "capsule": 2}
    if len(size) != counts[kind] or not all(math.isfinite(v) and v > 0 for v in size):
        raise UserError(f"object '{solid.name}': {kind} needs {counts[kind]} positive size(s) in metres, got {size}")
    return {"box": Box, "sphere": Sphere, "cylinder": Cylinder, "capsule": Capsule}[kind](*size)


def _transform(placement: Placement, what: str):
    values = [*placement.xyz, *placement.rpy_deg]
    if len(placement.xyz) != 3 or len(placement.rpy_deg) != 3 or not all(math.isfinite(v) for v in values):
        raise UserError(f"the pose of '{what}' needs xyz and rpy_deg, 3 finite numbers each")
    from pydrake.math import RollPitchYaw

    return _rigid(RollPitchYaw(np.radians(placement.rpy_deg)).ToRotationMatrix(), np.asarray(placement.xyz, float))


def _rigid(rotation, translation):
    from pydrake.math import RigidTransform

    return RigidTransform(rotation, np.asarray(translation, float))


def _rpy(pose) -> np.ndarray:
    from pydrake.math import RollPitchYaw

    return RollPitchYaw(pose.rotation()).vector()


def _pose_numbers(pose) -> list[float]:
    return [*pose.translation(), *_rpy(pose)]


def _query_object(scene):
    """The scene graph's query object at the default context (obstacles do not depend on the robot's pose)."""
    context = scene.diagram.CreateDefaultContext()
    scene_graph = scene.diagram.scene_graph()
    return scene_graph.get_query_output_port().Eval(scene_graph.GetMyContextFromRoot(context))


def _robot_frame(scene, name: str, what: str) -> str:
    """The scoped name of robot frame `name` (a link or another frame of a model that moves)."""
    plant = scene.plant
    for instance in scene.robot_instances:
        if plant.HasFrameNamed(name, instance):
            return plant.GetFrameByName(name, instance).scoped_name().to_string()
    raise UserError(f"cannot attach '{what}': the robot has no link or frame '{name}'")


def _robot_body(scene, name: str, what: str) -> str:
    plant = scene.plant
    if any(plant.HasBodyNamed(name, instance) for instance in scene.robot_instances):
        return name
    raise UserError(f"cannot attach '{what}': it may touch '{name}', which is no link of the robot")
