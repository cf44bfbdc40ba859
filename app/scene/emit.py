"""Stage (c) of a custom scene: the files Drake will parse, written into the cache (each only when it differs, as
other processes may read it meanwhile). Messages name the user's files, never these.

- Model files: a user's URDF/SDF as given, or a copy (`model_copy`) where each <collision> holding a mesh holds its
  validated convex pieces instead (Drake would take the mesh's hull; the pieces stay on the link's body, so they
  are never checked against each other), meshes Drake cannot read point to their .obj, every relative or
  package:// reference is absolute (the copy lives elsewhere) and a URDF's materials are fixed up
  (app.scene.model_files.drake_materials); comments blanked and lines kept, so Drake's messages point into the
  user's file. A mesh robot on the carrier joints (`carrier_urdf`), each environment mesh on the world body
  (`env_urdf`).
- Scene files, in a scene directory named by what defines it: model directives for the robot alone
  (robot.dmd.yaml: its coordinates are the scene's, the environment adds none) and for the scene (scene.dmd.yaml),
  and the problem file (its keys: app.scene.problem.ProblemFile).

Where a model's root bodies are welded (to the world, or to the carrier) is told by Drake's parser on the model file
written here (app.scene.drake_parser.probe_model): an SDF's only from that copy, whose meshes Drake can read.
"""

import hashlib
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

from app.io import write_atomically
from app.scene.drake_parser import probe_model
from app.scene.meshes.cache import Decomposition, writable_folder
from app.scene.model_files import COLLISION_BLOCK, MESH_REFERENCE, is_convertible, is_mesh, reference_parts
from app.scene.prepare_meshes import PreparedEnvironment, PreparedModel, PreparedRobot
from app.scene.spec import CARRIER_JOINTS, SceneInputs, check_environment_roots, check_robot_roots

_INERTIAL = '<inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>'


@dataclass
class SceneFiles:
    """The scene's model directives (@DIR@ stands for the scene directory), the files generated for them, and what
    the robot's part of them is."""

    directives: list[str] = field(default_factory=lambda: ["directives:"])
    files: dict[str, str] = field(default_factory=dict)  # generated file name -> text
    robot_directives: list[str] = field(default_factory=list)
    robot_instances: list[str] = field(default_factory=list)  # the model instances that move
    # (the robot file with decomposed mesh links, the same with Drake's hull per mesh link), if it has mesh links
    hull_robot_file: tuple[Path, Path] | None = None


def write_if_changed(path: Path, text: str) -> None:
    """Write only when different (other processes may read the file meanwhile)."""
    if path.is_file() and path.read_text() == text:
        return
    write_atomically(writable_folder(path.parent) / path.name, text)


# ---- the robot ----------------------------------------------------------------------------------------------------
def emit_robot(files: SceneFiles, inputs: SceneInputs, robot: PreparedRobot, root: Path) -> None:
    """Directives for the robot (a mesh on the carrier joints, or a URDF/SDF welded or carried) and its files."""
    if robot.mesh is not None:
        files.files["robot.urdf"] = carrier_urdf("robot", _mesh_elements_urdf(robot.mesh))
        files.directives += [
            "- add_model:",
            "    name: robot",
            f"    file: {quoted_uri('@DIR@/robot.urdf')}",
            "- add_weld:",
            "    parent: world",
            "    child: robot::origin",
        ]
        files.robot_instances = ["robot"]
    else:
        robot_file = model_copy(robot.model, inputs.packages, root)
        if robot.hulls is not None:  # the same robot with Drake's convex hull per mesh link, to measure the pieces
            files.hull_robot_file = (robot_file, model_copy(robot.hulls, inputs.packages, root))
        roots = probe_model(robot_file, inputs.packages)["floating"]
        files.robot_instances = _robot_directives(files, inputs, robot_file, roots)
    files.robot_directives = list(files.directives)


def _robot_directives(files: SceneFiles, inputs: SceneInputs, robot_file: Path, roots: list[str]) -> list[str]:
    if not inputs.floating:
        files.directives += ["- add_model:", "    name: robot", f"    file: {quoted_uri(robot_file)}"]
        for body in roots:
            files.directives += ["- add_weld:", "    parent: world", f"    child: robot::{body}"]
        return ["robot"]
    check_robot_roots(inputs.robot_path, roots, True)
    # The carrier first, so that its x, y, z, yaw, pitch, roll are the first six coordinates.
    files.files["carrier.urdf"] = carrier_urdf("carrier")
    files.directives += [
        "- add_model:",
        "    name: carrier",
        f"    file: {quoted_uri('@DIR@/carrier.urdf')}",
        "- add_weld:",
        "    parent: world",
        "    child: carrier::origin",
        "- add_model:",
        "    name: robot",
        f"    file: {quoted_uri(robot_file)}",
        "- add_weld:",
        "    parent: carrier::body",
        f"    child: robot::{roots[0]}",
    ]
    return ["carrier", "robot"]


# ---- the environment ----------------------------------------------------------------------------------------------
def emit_environment(files: SceneFiles, inputs: SceneInputs, env: PreparedEnvironment, root: Path) -> None:
    """Directives for the environment models (static, or one rigid body welded at its pose) and their files."""
    for i, (path, entry, pose) in enumerate(zip(inputs.env_paths, env.entries, inputs.env_poses)):
        name = f"env{i}"
        if isinstance(entry, Decomposition):
            files.files[f"{name}.urdf"] = env_urdf(name, entry, pose)
            files.directives += ["- add_model:", f"    name: {name}", f"    file: {quoted_uri(f'@DIR@/{name}.urdf')}"]
            continue
        model_file = model_copy(entry, inputs.packages, root)
        roots = probe_model(model_file, inputs.packages)["floating"]
        files.directives += ["- add_model:", f"    name: {name}", f"    file: {quoted_uri(model_file)}"]
        check_environment_roots(path, roots, pose)
        if roots:
            files.directives += [
                "- add_weld:",
                "    parent: world",
                f"    child: {name}::{roots[0]}",
                _pose_yaml(pose).rstrip("\n"),
            ]


# ---- model files --------------------------------------------------------------------------------------------------
def model_copy(prepared: PreparedModel, packages: dict[str, Path], root: Path) -> Path:
    """The model file Drake is given: the user's own when nothing needs changing, else a copy in the cache (see the
    module's docstring), named by its content."""
    model = prepared.model
    decompose_here = prepared.decompositions is not None and model.has_collision_mesh()
    refit = model.urdf and model.fixed != model.text  # (materials fixed up)
    if not decompose_here and not refit and not any(is_convertible(uri) for uri in model.uris()):
        return model.path

    def absolute(m):
        head, uri, tail = reference_parts(m)
        if uri not in model.targets:  # a piece's absolute .obj path, just written in: as it is
            return m.group(0)
        target = model.targets[uri]
        if target is None:  # (another scheme)
            return m.group(0)
        if is_convertible(uri):
            target = prepared.converted[target]
        return f"{head}{target if m.group(2) else f'file://{target}'}{tail}"

    text = model.fixed
    if decompose_here:
        pieces = iter(prepared.decompositions)
        text = COLLISION_BLOCK.sub(lambda block: _split_collision(block.group(0), model.targets, pieces), text)
    rewritten = MESH_REFERENCE.sub(absolute, text)
    key = hashlib.sha256(rewritten.encode()).hexdigest()[:24]
    out = root / "models" / key / model.path.name
    write_if_changed(out, rewritten)
    return out


def _split_collision(block: str, targets: dict, decompositions) -> str:
    """A <collision> holding one mesh as one <collision> per piece of its decomposition (the next of
    `decompositions`), all on the block's own lines; any other <collision> as it is."""
    found = [m for m in MESH_REFERENCE.finditer(block) if is_mesh(reference_parts(m)[1])]
    if len(found) != 1:
        return block
    m = found[0]
    if targets[reference_parts(m)[1]] is None:
        return block
    copies = []
    for k, piece in enumerate(next(decompositions).pieces):
        head, _, tail = reference_parts(m)
        uri = str(piece) if m.group(2) else f"file://{piece}"
        copy = block[: m.start()] + f"{head}{uri}{tail}" + block[m.end() :]
        copy = re.sub(r'(<collision\b[^>]*\bname\s*=\s*")([^"]*)(")', rf"\g<1>\g<2>_piece{k}\g<3>", copy, count=1)
        copies.append(copy if not copies else copy.replace("\n", " "))
    return "".join(copies)


def carrier_urdf(name: str, body_xml: str = "") -> str:
    """Prismatic x, y, z then revolute yaw, pitch, roll (no limits: the problem file's bounds rule), ending in a link
    `body` holding `body_xml` (collision/visual elements)."""
    links = ["origin", "px", "py", "pz", "yawed", "pitched", "body"]
    axes = ["1 0 0", "0 1 0", "0 0 1", "0 0 1", "0 1 0", "1 0 0"]
    out = [
        f'<?xml version="1.0"?>\n<robot name="{name}" xmlns:drake="http://drake.mit.edu">',
        '  <link name="origin"/>',
    ]
    for link in links[1:-1]:
        out.append(f'  <link name="{link}">{_INERTIAL}</link>')
    out.append(f'  <link name="body">{_INERTIAL}\n{body_xml}  </link>')
    for k, joint in enumerate(CARRIER_JOINTS):
        kind = "prismatic" if k < 3 else "continuous"
        limit = (
            '<limit lower="-1e4" upper="1e4" effort="1" velocity="10"/>'
            if k < 3
            else '<limit effort="1" velocity="10"/>'
        )
        out.append(
            f'  <joint name="{joint}" type="{kind}"><parent link="{links[k]}"/><child link="{links[k + 1]}"/>'
            f'<axis xyz="{axes[k]}"/>{limit}</joint>'
        )
    out.append("</robot>\n")
    return "\n".join(out)


def _mesh_elements_urdf(decomposition: Decomposition) -> str:
    lines = [
        f'    <collision name="piece{i}"><geometry><mesh filename={quoteattr(str(p))}><drake:declare_convex/></mesh>'
        f"</geometry></collision>"
        for i, p in enumerate(decomposition.pieces)
    ]
    lines.append(f"    <visual><geometry><mesh filename={quoteattr(str(decomposition.visual))}/></geometry></visual>")
    return "\n".join(lines) + "\n"


def env_urdf(name: str, decomposition: Decomposition, pose: list[float]) -> str:
    """The pieces as convex collision shapes and the original mesh as the visual, all on the URDF link named `world`
    (which Drake takes as the world body itself), placed at pose. On the world body SceneGraph registers them as
    *anchored* geometry: its broad phase keeps them in a tree built once, whereas geometry on a body (even one welded
    to the world, as in a static SDF model) is dynamic: re-posed and re-sorted on every query, which makes a check
    among many pieces far dearer (docs/benchmarks-history.md, "Mesh scenes")."""
    x, y, z, r, p, w = pose
    origin = f'<origin xyz="{x!r} {y!r} {z!r}" rpy="' + " ".join(f"{math.radians(a)!r}" for a in (r, p, w)) + '"/>'
    lines = [
        '<?xml version="1.0"?>',
        f'<robot name="{name}" xmlns:drake="http://drake.mit.edu">',
        '  <link name="world">',
    ]
    # Geometry names are unique per frame, and every environment shares the world's: so they carry the model's name.
    for i, piece in enumerate(decomposition.pieces):
        lines.append(
            f'    <collision name="{name}_piece{i}">{origin}<geometry><mesh filename={quoteattr(str(piece))}>'
            f"<drake:declare_convex/></mesh></geometry></collision>"
        )
    lines.append(
        f'    <visual name="{name}_mesh">{origin}<geometry><mesh filename={quoteattr(str(decomposition.visual))}/>'
        "</geometry></visual>"
    )
    lines += ["  </link>", "</robot>", ""]
    return "\n".join(lines)


# ---- scene files --------------------------------------------------------------------------------------------------
def quoted_uri(path: Path | str) -> str:
    # A JSON string is a YAML double-quoted scalar: '#', ': ' and quotes in a path stay part of it.
    return json.dumps(f"file://{path}")


def _pose_yaml(pose: list[float]) -> str:
    x, y, z, r, p, w = pose
    return (
        f"    X_PC:\n      translation: [{x!r}, {y!r}, {z!r}]\n      rotation: !Rpy {{ deg: [{r!r}, {p!r}, {w!r}] }}\n"
    )


def write_scene_dir(files: SceneFiles, packages: dict[str, Path], root: Path) -> Path:
    """The scene directory, named by a hash of what defines it: the generated files, robot.dmd.yaml (the robot
    alone, whose coordinates are the scene's: the environment adds none) and scene.dmd.yaml."""
    key_text = "\n".join(files.directives) + "".join(files.files.values()) + repr(sorted(packages.items()))
    scene_dir = root / "scenes" / hashlib.sha256(key_text.encode()).hexdigest()[:24]
    for name, text in files.files.items():
        write_if_changed(scene_dir / name, text)
    # @DIR@ only stands inside quoted URIs (quoted_uri), so it is replaced by the folder escaped as in one.
    folder = json.dumps(str(scene_dir))[1:-1]
    write_if_changed(scene_dir / "robot.dmd.yaml", "\n".join(files.robot_directives).replace("@DIR@", folder) + "\n")
    write_if_changed(scene_dir / "scene.dmd.yaml", "\n".join(files.directives).replace("@DIR@", folder) + "\n")
    return scene_dir


def write_problem(scene_dir: Path, problem: dict) -> Path:
    """The problem file (JSON is YAML), named by its content."""
    text = json.dumps(problem, indent=1) + "\n"
    problem_path = scene_dir / f"problem-{hashlib.sha256(text.encode()).hexdigest()[:16]}.yaml"
    write_if_changed(problem_path, text)
    return problem_path


def write_hull_directives(scene_dir: Path, pieces_file: Path, hull_file: Path) -> Path:
    """robot-hulls.dmd.yaml: the robot alone with Drake's hull per mesh link instead of its pieces."""
    hulls = scene_dir / "robot-hulls.dmd.yaml"
    write_if_changed(hulls, (scene_dir / "robot.dmd.yaml").read_text().replace(str(pieces_file), str(hull_file)))
    return hulls
