"""A robot's or an environment's model file read as data (stage (a)), without Drake: a URDF's or SDF's XML, a URDF's
numbers, joint limits, <mimic> elements, links and materials, every file it references (resolved through the
package paths, meshes checked to exist), and an SRDF's disabled pairs. What Drake's own parser says of a URDF is
added by app.scene.inputs; what the rest of the route does with the text is app.scene.emit's.

What ROS tools accept but Drake refuses only in visuals (a material defined twice, a material used but never
defined) is fixed up in the text given to Drake (`fixed`), with a note saying what was ignored. Comments are blanked
and lines kept throughout, so Drake's messages point into the user's file."""

import collections
import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

from app.errors import UserError
from app.io import check_input
from app.scene.files import CONVERTIBLE_SUFFIXES, MAX_MODEL_NUMBER, MESH_SUFFIXES, PACKAGES

# The numeric attributes of a URDF checked (per element name; each number of a list): finite, within
# MAX_MODEL_NUMBER. Joint limits and speeds are checked apart (`_check_limit`).
_URDF_NUMBERS = {
    "origin": ("xyz",),
    "axis": ("xyz",),
    "box": ("size",),
    "cylinder": ("radius", "length"),
    "sphere": ("radius",),
    "capsule": ("radius", "length"),
    "mesh": ("scale",),
    "mimic": ("multiplier", "offset"),
}
_COMMENT = re.compile(r"<!--.*?-->", re.S)
_MATERIAL = re.compile(r"<material\b(?P<attrs>[^>]*?)(?:/>|>(?P<body>.*?)</material\s*>)", re.S)
_VISUAL = re.compile(r"<visual\b[^>]*?(?<!/)>.*?</visual\s*>", re.S)
# A reference to a file: a URDF's filename="..." or an SDF's <uri>...</uri>.
MESH_REFERENCE = re.compile(r'(filename\s*=\s*")([^"]+)(")|(<uri>\s*)([^<]+?)(\s*</uri>)')
COLLISION_BLOCK = re.compile(r"<collision\b.*?</collision>", re.S)
# A mesh's scale: a URDF's scale="x y z" or an SDF's <scale>x y z</scale>.
MESH_SCALE = re.compile(r'\bscale\s*=\s*"([^"]*)"|<scale>([^<]*)</scale>')


@dataclass
class ModelFile:
    """A URDF or SDF file, read and checked. `text` is the file with its comments blanked; `fixed` the text Drake is
    given (for a URDF, its materials fixed up: `drake_materials`) and `notes` what that ignored. `targets`: every
    referenced file by its URI (None: a scheme other than package:// or file://). For a URDF, also its links and
    <mimic> elements, and what Drake's parser makes of it without geometry (filled by app.scene.inputs): its joints
    (name, type, positions, ephemeral: a joint Drake adds to a body attached to nothing) in position order, each
    position's limits, and its root bodies (attached to nothing). None of these for an SDF: Drake reads it only
    with its meshes, once they are converted (app.scene.emit)."""

    path: Path
    text: str
    fixed: str
    notes: list[str] = field(default_factory=list)
    targets: dict[str, Path | None] = field(default_factory=dict)
    links: set[str] | None = None
    collision_links: int = 0  # links with a <collision> element
    mimic_elements: list[tuple[str, str, str, str]] = field(default_factory=list)  # joint, follows, multiplier, offset
    joints: list[tuple[str, str, int, bool]] | None = None
    lower: list[float] | None = None
    upper: list[float] | None = None
    roots: list[str] | None = None

    @property
    def urdf(self) -> bool:
        return self.path.suffix.lower() == ".urdf"

    def mimics(self) -> list[dict]:
        """The <mimic> elements of a URDF's joints, as the problem file's `mimic` entries: each such joint follows
        another (multiplier 1 and offset 0 unless given). Drake's URDF parser ignores them in kinematics (a
        continuous plant only records a coupler constraint that no query uses), so they are read here."""
        mimics = []
        for joint, follows, multiplier, offset in self.mimic_elements:
            try:
                values = float(multiplier), float(offset)
            except ValueError:
                raise UserError(f"{self.path.name}: joint '{joint}': <mimic> needs numbers") from None
            mimics.append({"joint": joint, "follows": follows, "multiplier": values[0], "offset": values[1]})
        return mimics

    def uris(self) -> list[str]:
        """The URI of every file reference of `fixed`, in order."""
        return [reference_parts(m)[1] for m in MESH_REFERENCE.finditer(self.fixed)]

    def collision_meshes(self) -> list[tuple[Path, float] | None]:
        """Per <collision> element of `fixed`, in order: the file of its one mesh reference and the largest factor
        of the mesh's scale (1 when it has none); None where it holds none, several, or one by another scheme (such
        a <collision> is left as it is)."""
        found = []
        for block in COLLISION_BLOCK.finditer(self.fixed):
            meshes = [m for m in MESH_REFERENCE.finditer(block.group(0)) if is_mesh(reference_parts(m)[1])]
            target = self.targets[reference_parts(meshes[0])[1]] if len(meshes) == 1 else None
            found.append(None if target is None else (target, self._largest_scale(block.group(0))))
        return found

    def _largest_scale(self, block: str) -> float:
        found = MESH_SCALE.search(block)
        try:
            return max(abs(float(v)) for v in (found.group(1) or found.group(2)).split()) if found else 1.0
        except ValueError:
            raise UserError(f"{self.path.name}: a <collision> mesh's scale must be numbers") from None

    def has_collision_mesh(self) -> bool:
        """Whether any <collision> element references a mesh (so that decomposing has something to do)."""
        return any(
            is_mesh(reference_parts(m)[1])
            for block in COLLISION_BLOCK.finditer(self.fixed)
            for m in MESH_REFERENCE.finditer(block.group(0))
        )

    def kept_uris(self, decomposing: bool) -> list[str]:
        """The URIs of `fixed`'s references that stay in the copy Drake is given: all, but when `decomposing`, each
        <collision>'s one mesh reference (which becomes its pieces')."""
        replaced = set()  # where the replaced references start
        if decomposing and self.has_collision_mesh():
            for block in COLLISION_BLOCK.finditer(self.fixed):
                meshes = [m for m in MESH_REFERENCE.finditer(block.group(0)) if is_mesh(reference_parts(m)[1])]
                if len(meshes) == 1 and self.targets[reference_parts(meshes[0])[1]] is not None:
                    replaced.add(block.start() + meshes[0].start())
        return [reference_parts(m)[1] for m in MESH_REFERENCE.finditer(self.fixed) if m.start() not in replaced]


def read_model_file(path: Path, packages: dict[str, Path]) -> ModelFile:
    """Every refusal a URDF/SDF file can earn before Drake reads it, as one-line UserErrors naming the file: its XML,
    its numbers and <mimic> elements (a URDF's), its references (unknown packages, missing mesh files)."""
    text = blank_comments(path.read_text(errors="replace"))
    root = xml_root_of(text, path)
    urdf = path.suffix.lower() == ".urdf"
    if urdf:
        _check_urdf_numbers(root, path)
        for joint in root.findall("joint"):
            count = len(joint.findall("mimic"))
            if count > 1:
                raise UserError(
                    f"{path.name}: joint '{joint.get('name')}' has {count} <mimic> elements; a joint follows one joint"
                )
    targets = {}
    for m in MESH_REFERENCE.finditer(text):
        uri = reference_parts(m)[1]
        targets[uri] = mesh_target(uri, path, packages)
    if not urdf:
        return ModelFile(path, text, text, targets=targets)
    fixed, notes = drake_materials(text)
    return ModelFile(
        path,
        text,
        fixed,
        notes,
        targets,
        links={link.get("name") for link in root.iter("link")},
        collision_links=sum(1 for link in root.findall("link") if link.find("collision") is not None),
        mimic_elements=_mimic_elements(root),
    )


def _mimic_elements(root) -> list[tuple[str, str, str, str]]:
    found = []
    for joint in root.findall("joint"):  # (a <transmission>'s <joint> children are no joints)
        element = joint.find("mimic")
        # A fixed joint has no position to follow with (Panda URDFs that fix the fingers keep the finger's <mimic>).
        if element is not None and joint.get("type") != "fixed":
            found.append(
                (
                    joint.get("name", ""),
                    element.get("joint", ""),
                    element.get("multiplier", "1.0"),
                    element.get("offset", "0.0"),
                )
            )
    return found


def blank_comments(text: str) -> str:
    """`text` with its XML comments blanked out (each character a space, lines kept): a commented-out element is
    none, and Drake's line numbers still point into the user's file."""
    return _COMMENT.sub(lambda m: re.sub(r"[^\n]", " ", m.group(0)), text)


def xml_root_of(text: str, path: Path):
    """The root element of a model file's text, or one line: "cannot load NAME: the XML error". A prefix used but
    never declared (`<drake:...>` without xmlns:drake, which Drake's own parser takes) is declared for the reading."""
    try:
        return ET.fromstring(text)
    except ET.ParseError as exc:
        if "unbound prefix" not in str(exc):
            raise UserError(f"cannot load {path.name}: {exc}") from None
    prefixes = set(re.findall(r"</?([A-Za-z_][\w.-]*):[A-Za-z_]", text)) - {"xml"}
    declared = set(re.findall(r"xmlns:([A-Za-z_][\w.-]*)\s*=", text))
    extra = "".join(f' xmlns:{p}="urn:undeclared:{p}"' for p in sorted(prefixes - declared))
    head = re.search(r"<(?![?!])[A-Za-z_][\w.:-]*", text)
    try:
        return ET.fromstring(text[: head.end()] + extra + text[head.end() :] if head else text)
    except ET.ParseError as exc:
        raise UserError(f"cannot load {path.name}: {exc}") from None


def _local(tag) -> str:
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""


def _check_urdf_numbers(root, path: Path) -> None:
    """A URDF's joint limits and speeds, mimic factors, offsets and sizes: finite and within MAX_MODEL_NUMBER, and a
    joint's lower limit not above its upper one (Drake's parser takes +-1e300; the planner then overflows, and an
    inverted limit or a negative speed stops the process inside Drake). Text that is no number is Drake's to refuse."""
    for kind in ("link", "joint"):
        for owner in root.findall(kind):
            where = f"{path.name}: {kind} '{owner.get('name')}'"
            for element in owner.iter():
                for attribute in _URDF_NUMBERS.get(_local(element.tag), ()):
                    raw = element.get(attribute)
                    try:
                        values = [float(v) for v in raw.split()] if raw is not None else []
                    except ValueError:
                        continue
                    if not all(math.isfinite(v) and abs(v) <= MAX_MODEL_NUMBER for v in values):
                        raise UserError(
                            f'{where}: <{_local(element.tag)} {attribute}="{raw.strip()}"> is out of range (numbers '
                            f"here must be finite and within +-{MAX_MODEL_NUMBER:g})"
                        )
            if kind == "joint":
                _check_limit(owner, where)


def _check_limit(joint, where: str) -> None:
    limit = joint.find("limit")
    if limit is None:
        return
    # A continuous (or fixed, floating, planar) joint's lower and upper are not limits: Drake reads them for
    # revolute and prismatic joints only.
    names = ("lower", "upper", "velocity") if joint.get("type") in ("revolute", "prismatic") else ("velocity",)
    values = {}
    for name in names:
        raw = limit.get(name)
        try:
            value = float(raw) if raw is not None else None
        except ValueError:
            continue  # (Drake's parser says what it expected)
        what = "velocity limit" if name == "velocity" else f"{name} limit"
        if value is not None and not math.isfinite(value):
            raise UserError(f"{where}: {what} {raw.strip()} is not a finite number")
        if value is not None and abs(value) > MAX_MODEL_NUMBER:
            raise UserError(
                f"{where}: {what} {raw.strip()} is out of range (limits must be within +-{MAX_MODEL_NUMBER:g} m or rad)"
            )
        values[name] = value
    if values.get("velocity") is not None and values["velocity"] < 0:
        raise UserError(f"{where}: velocity limit {limit.get('velocity').strip()} is negative")
    lower, upper = values.get("lower"), values.get("upper")
    if lower is not None and upper is not None and lower > upper:
        raise UserError(f"{where}: lower limit {limit.get('lower').strip()} is above upper limit {upper:g}")


def drake_materials(text: str) -> tuple[str, list[str]]:
    """A URDF's text with the materials Drake refuses and ROS tools (urdfdom, RViz) take fixed up, and what was done.
    Drake reads the robot's own <material> elements, then each visual's, and refuses a name defined twice (an inline
    repeat of the same colour aside) and a name used before any definition; here the first definition of a name is
    kept (a later top-level one dropped, a later inline one reduced to a reference to it), and a reference to a name
    defined nowhere before it is dropped (that visual keeps Drake's default colour). Lines are kept."""
    visuals = [m.span() for m in _VISUAL.finditer(text)]
    found = []
    for m in _MATERIAL.finditer(text):
        name = re.search(r"\bname\s*=\s*([\"'])(.*?)\1", m.group("attrs"))
        if name is None:  # (Gazebo's <material>Gazebo/Grey</material>: not Drake's)
            continue
        inline = any(a <= m.start() < b for a, b in visuals)
        found.append((m, name.group(2), inline, _material_definition(m.group("body") or "")))
    defined_somewhere = collections.Counter(name for _, name, _, definition in found if definition is not None)
    defined: dict[str, tuple] = {}
    edits, notes = [], []
    for m, name, inline, definition in [f for f in found if not f[2]] + [f for f in found if f[2]]:
        if definition is None:
            if name not in defined:
                edits.append((m.span(), ""))
                notes.append(
                    f"material '{name}' is used before it is defined (that visual's colour left default)"
                    if name in defined_somewhere
                    else f"material '{name}' is used but never defined (visual colour left default)"
                )
        elif name not in defined:
            defined[name] = definition
        elif not (inline and definition == defined[name]):
            edits.append((m.span(), f"<material name={quoteattr(name)}/>" if inline else ""))
            times = "twice" if defined_somewhere[name] == 2 else f"{defined_somewhere[name]} times"
            notes.append(f"material '{name}' is defined {times} (the first definition is used)")
    for (start, end), replacement in sorted(edits, reverse=True):
        text = text[:start] + replacement + "\n" * text[start:end].count("\n") + text[end:]
    return text, list(dict.fromkeys(notes))


def _material_definition(body: str) -> tuple | None:
    """A material's colour and texture as Drake compares them; None when it has neither (a reference by name)."""
    rgba = re.search(r"<color\b[^>]*\brgba\s*=\s*([\"'])(.*?)\1", body)
    texture = re.search(r"<texture\b[^>]*\bfilename\s*=\s*([\"'])(.*?)\1", body)
    if rgba is None and texture is None:
        return None
    try:
        colour = tuple(float(v) for v in rgba.group(2).split()) if rgba else None
    except ValueError:
        colour = rgba.group(2)
    return colour, texture.group(2) if texture else None


# ---- references ---------------------------------------------------------------------------------------------------
def resolve_uri(uri: str, relative_to: Path, packages: dict[str, Path]) -> Path | None:
    """package://NAME/rest, file:///abs, an absolute or a relative path -> a Path; None for other schemes."""
    if uri.startswith("package://"):
        name, _, rest = uri[len("package://") :].partition("/")
        known = {**{k: Path(v) for k, v in PACKAGES.items()}, **packages}
        if name not in known:
            raise UserError(
                f"cannot load {relative_to.name}: unknown package '{name}' (add the package path {name}=DIR)"
            )
        return known[name] / rest
    if uri.startswith("file://"):
        return Path(uri[len("file://") :])
    if "://" in uri:
        return None
    path = Path(uri)
    return path if path.is_absolute() else relative_to.parent / path


def reference_parts(m) -> tuple[str, str, str]:
    """A MESH_REFERENCE match as (what precedes the URI, the URI, what follows it)."""
    return (m.group(1), m.group(2), m.group(3)) if m.group(2) else (m.group(4), m.group(5), m.group(6))


def is_mesh(uri: str) -> bool:
    return Path(uri.split("?")[0]).suffix.lower() in MESH_SUFFIXES


def is_convertible(uri: str) -> bool:
    """A mesh Drake cannot read (converted to .obj for it)."""
    return Path(uri.split("?")[0]).suffix.lower() in CONVERTIBLE_SUFFIXES


def mesh_target(uri: str, path: Path, packages: dict[str, Path]) -> Path | None:
    """The file a reference in the model file `path` names (None for another URI scheme); an unknown package, or a
    mesh file that is not there, is a UserError naming `path`."""
    target = resolve_uri(uri, path, packages)
    if target is not None and is_mesh(uri) and not target.is_file():
        raise UserError(f"cannot load {path.name}: mesh file not found: {uri}")
    return target


# ---- SRDF ---------------------------------------------------------------------------------------------------------
def xml_root(path: Path, failure: str):
    """The root element of an XML file (a URDF, an SRDF), or one line: `failure`, the file's name and the error."""
    try:
        return ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise UserError(f"{failure} {path.name}: {exc}") from None


def read_srdf(path: Path) -> list[tuple[str, str]]:
    """The (link1, link2) pairs of an SRDF's <disable_collisions> elements."""
    check_input(path, "SRDF file")
    root = xml_root(path, "bad SRDF")
    pairs = []
    for element in root.iter("disable_collisions"):
        a, b = element.get("link1"), element.get("link2")
        if not a or not b:
            raise UserError(f"bad SRDF {path.name}: <disable_collisions> needs link1 and link2")
        pairs.append((a, b))
    return pairs


@dataclass
class SrdfGroup:
    """An SRDF <group>: the joints, chains (base link, tip link), links and subgroups it names."""

    joints: list[str] = field(default_factory=list)
    chains: list[tuple[str, str]] = field(default_factory=list)
    links: list[str] = field(default_factory=list)
    subgroups: list[str] = field(default_factory=list)


def read_srdf_groups(path: Path) -> dict[str, SrdfGroup]:
    """An SRDF's <group> elements by name (MoveIt's planning groups), as they are written: app.scene.moveit resolves
    them to joints."""
    check_input(path, "SRDF file")
    groups = {}
    for element in xml_root(path, "bad SRDF").iter("group"):
        name = element.get("name")
        if not name:
            raise UserError(f"bad SRDF {path.name}: a <group> needs a name")
        group = groups.setdefault(name, SrdfGroup())
        for child in element:
            if child.tag == "chain":
                if not child.get("base_link") or not child.get("tip_link"):
                    raise UserError(f"bad SRDF {path.name}: group '{name}': <chain> needs base_link and tip_link")
                group.chains.append((child.get("base_link"), child.get("tip_link")))
            elif child.tag in ("joint", "link", "group"):
                if not child.get("name"):
                    raise UserError(f"bad SRDF {path.name}: group '{name}': <{child.tag}> needs a name")
                {"joint": group.joints, "link": group.links, "group": group.subgroups}[child.tag].append(
                    child.get("name")
                )
    return groups


@dataclass
class UrdfJoint:
    """A URDF <joint> as data: its type, parent and child links, and its <origin> (xyz in m, rpy in radians)."""

    name: str
    kind: str
    parent: str
    child: str
    xyz: list[float]
    rpy: list[float]


def urdf_joints(model: ModelFile) -> dict[str, UrdfJoint]:
    """A URDF's joints by name (its numbers are checked when the file is read: read_model_file)."""
    root = xml_root_of(model.text, model.path)
    joints = {}
    for joint in root.findall("joint"):
        parent, child, origin = joint.find("parent"), joint.find("child"), joint.find("origin")
        joints[joint.get("name")] = UrdfJoint(
            joint.get("name"),
            joint.get("type", ""),
            "" if parent is None else parent.get("link", ""),
            "" if child is None else child.get("link", ""),
            [float(v) for v in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()],
            [float(v) for v in (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()],
        )
    return joints


def read_srdf_fixed_frames(path: Path) -> list[str]:
    """The parent frames of an SRDF's fixed <virtual_joint>s: names of the frame the robot's root is fixed in
    (MoveIt's planning frame, "world" as a rule)."""
    root = xml_root(check_input(path, "SRDF file"), "bad SRDF")
    return [
        v.get("parent_frame") for v in root.iter("virtual_joint") if v.get("type") == "fixed" and v.get("parent_frame")
    ]
