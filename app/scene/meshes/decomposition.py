"""A mesh's convex pieces (`decompose_parts`): by default hulls that hold it and stay near it (`_bounds`); a method
asked for by name built per connected part and the whole validated."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from app.errors import UserError
from app.scene.files import MESH_METHODS
from app.scene.meshes import coacd_process
from app.scene.meshes.merging import MOST_LINK_PIECES, Enclosure, Surface, merged_pieces, split_hulls
from app.scene.meshes.pieces import Piece, face_pieces, faces_instead, hull_groups, hull_piece, shell_pieces
from app.scene.meshes.validation import Validation, components, validate

# Distances to a mesh's surface are bounded to within reach / _SPACING (see merging.Surface), with at most about
# _MOST_SURFACE_POINTS points (a UR5's upper arm would take 1.8 million at 5 mm / 8; laying out and asking 4 million
# took most of a minute on a scene export, for the same hulls).
_SPACING = 8
_MOST_SURFACE_POINTS = 1_000_000
# A part with fewer faces is no closed mesh (a closed part has at least 4): no per-part mesh and facts for it.
_OPEN_FACTS = {"faces": 0, "closed": False, "volume": 0.0, "hull_volume": 0.0, "convex": False}


def default_tolerance(mesh) -> float:
    """0.2 % of the mesh's bounding-box diagonal."""
    return 0.002 * float(np.linalg.norm(mesh.extents))


def classify(mesh) -> dict:
    """Facts the method choice rests on."""
    closed = bool(mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0)
    volume = float(mesh.volume) if closed else 0.0
    hull_volume = float(mesh.convex_hull.volume) if closed else 0.0  # only a closed mesh can be its own hull
    return {
        "faces": int(len(mesh.faces)),
        "closed": closed,
        "volume": volume,
        "hull_volume": hull_volume,
        "convex": closed and hull_volume <= volume * (1 + 1e-6) + 1e-12,
    }


def method_name(methods: dict) -> str:
    """The method that made the pieces (`decompose_parts` uses one)."""
    return next(m for m, n in methods.items() if n)


def decompose_parts(
    mesh,
    method: str,
    tolerance: float,
    coacd_threshold: float,
    coacd_timeout: float,
    progress: bool,
    label: str,
    conservative: bool = False,
    merge_reach: float | None = None,
):
    """A mesh's convex pieces. Method "auto" bounds it (`_bounds`): a robot's link (`conservative`) within
    `merge_reach` of its mesh, towards MOST_LINK_PIECES hulls; any other mesh (an obstacle, a mesh robot) within
    `tolerance`, its hulls merged as far as that allows. A method asked for by name is built per connected part and
    validated: shell pieces that hold free points become face pieces once, and pieces that still fail are a
    UserError. Method "convex" takes the parts' hulls as bounds, merged by `hull_groups` and exempt from the
    free-space test (they are larger than their parts by design). With `merge_reach` (in the mesh's units), the
    validated pieces are then merged (`merged_pieces`) while every merged hull's surface stays within `merge_reach`
    of the mesh: within `merge_reach - tolerance` of the validated pieces, which hold no free point farther than the
    tolerance from it. Returns (pieces, the number of parts with pieces,
    the validation rounds, pieces per method before merging, parts per method)."""
    if method == "auto":
        if conservative and merge_reach:
            return _bounds(mesh, tolerance / 5, merge_reach, MOST_LINK_PIECES)
        return _bounds(mesh, tolerance / 5, tolerance, 1)
    parts = _Parts(mesh, method, tolerance, label, progress, coacd_threshold, coacd_timeout)
    while True:
        parts.build()
        pieces, owner = parts.assembled()
        check, methods = parts.validated(pieces, owner)
        if check.ok:
            break
        parts.mend(check, owner)
    if merge_reach is not None and merge_reach > tolerance:
        reach = merge_reach - tolerance
        pieces = merged_pieces(pieces, _surface(mesh, reach), reach)[0]
    return pieces, len(set(owner)), parts.tried, methods, {method: len(parts.parts)}


def _bounds(mesh, thickness: float, reach: float, most: int):
    """Method "auto": hulls split top down, then merged towards `most`, each within `reach` of the mesh or inside
    its parts (`split_hulls`, `merged_pieces`; flat groups thickened by `thickness`), in seconds even on a CAD mesh
    of tens of thousands of triangles. The same return as `decompose_parts`; the one round of "validation" records
    the rule."""
    if mesh.is_watertight and mesh.is_convex:  # (its own hull: exact, with no surface points to lay out)
        pieces, hulls, parts = [hull_piece(mesh.vertices)], 1, 1
        rule = "a closed convex mesh: its own hull"
    else:
        surface = _surface(mesh, reach)
        enclosure = Enclosure(mesh)
        split = split_hulls(mesh, surface, reach, thickness, enclosure)
        pieces = merged_pieces(split, surface, reach, most, inside_is_near=False, enclosure=enclosure)[0]
        hulls, parts = len(split), enclosure.parts
        rule = f"hulls of the faces, split and merged while every hull's surface stays within {reach:.3g} of the mesh"
    record = asdict(Validation(ok=True, tolerance=reach, message=rule))
    record.pop("bad_pieces"), record.pop("uncovered_faces")
    tried = [{"methods": {"split": hulls}, "pieces": len(pieces), "notes": [], **record}]
    return pieces, parts, tried, {"split": hulls}, {"split": parts}


def _surface(mesh, reach: float) -> Surface:
    """The mesh's surface points for tests within `reach`: reach / _SPACING apart, or farther where that would make
    more than about _MOST_SURFACE_POINTS (a mesh far larger than the reach, e.g. one in millimetres read as metres:
    then fewer hulls pass and more are kept, in bounded memory)."""
    return Surface(mesh, max(reach / _SPACING, np.sqrt(float(mesh.area) / _MOST_SURFACE_POINTS)))


class _Parts:
    """A mesh's connected parts for a method asked for by name, the pieces built for each so far, and what every
    round of validation found (`tried`)."""

    def __init__(self, mesh, method, tolerance, label, progress, coacd_threshold, coacd_timeout):
        self.mesh, self.method, self.tolerance, self.label, self.progress = mesh, method, tolerance, label, progress
        self.coacd_threshold, self.coacd_timeout = coacd_threshold, coacd_timeout
        self.groups = components(mesh)
        self.part_of_face = np.empty(len(mesh.faces), int)
        for i, g in enumerate(self.groups):
            self.part_of_face[g] = i
        self.parts = [mesh.submesh([g], append=True) if len(g) >= 4 else None for g in self.groups]
        self.facts = [classify(p) if p is not None else _OPEN_FACTS for p in self.parts]
        self.solids = [p for p, f in zip(self.parts, self.facts) if f["closed"]]
        self.built: dict[int, list[Piece]] = {}
        self.shell_groups: dict[int, list] = {}  # a shell part's face groups, piece by piece
        self.mended: set[int] = set()
        self.notes: list[str] = []
        self.tried: list[dict] = []
        if method in ("shell", "coacd") and not all(f["closed"] for f in self.facts):
            raise UserError(f"no valid convex decomposition for {label}: {method} needs a closed mesh")

    def build(self) -> None:
        """Build the parts without pieces: convex hulls, shell pieces, CoACD in one child, or faces merged."""
        todo = [i for i in range(len(self.parts)) if i not in self.built]
        if self.method == "convex":
            self._build_hulls(todo)
        elif self.method == "shell":
            for i in todo:
                self.built[i], self.shell_groups[i] = shell_pieces(
                    self.parts[i], self.tolerance, progress=self.progress
                )
        elif self.method == "coacd":
            self._build_coacd(todo)
        else:
            self._build_faces(todo)

    def _build_hulls(self, hull_parts: list[int]) -> None:
        points = [self.mesh.vertices[np.unique(self.mesh.faces[self.groups[i]])] for i in hull_parts]
        hulls, members = hull_groups(points, self.tolerance)
        self.built.update({i: [] for i in hull_parts})
        for piece, group in zip(hulls, members):
            self.built[hull_parts[group[0]]].append(piece)

    def _build_coacd(self, coacd_parts: list[int]) -> None:
        try:
            found = coacd_process.coacd_pieces(
                [self.parts[i] for i in coacd_parts], self.coacd_threshold, self.coacd_timeout, self.progress
            )
        except coacd_process.MethodFailed as exc:
            raise UserError(f"no valid convex decomposition for {self.label}: {exc}") from None
        self.built.update(zip(coacd_parts, found))

    def _build_faces(self, face_parts: list[int]) -> None:
        if not face_parts:
            return
        face_ids = np.concatenate([self.groups[i] for i in face_parts])
        joined = self.mesh.submesh([face_ids], append=True)
        joined_owner = self.part_of_face[face_ids]
        pieces, seeds = face_pieces(
            joined, slab=self.tolerance / 2, thickness=self.tolerance / 5, progress=self.progress, with_seeds=True
        )
        for i in face_parts:
            self.built[i] = []
        for piece, seed in zip(pieces, seeds):
            self.built[joined_owner[seed]].append(piece)

    def assembled(self) -> tuple[list[Piece], list[int]]:
        """Every part's pieces in part order, and the part each piece belongs to."""
        pieces, owner = [], []
        for i in range(len(self.parts)):
            pieces += self.built[i]
            owner += [i] * len(self.built[i])
        return pieces, owner

    def validated(self, pieces: list[Piece], owner: list[int]) -> tuple[Validation, dict]:
        """The pieces validated against the mesh (hulls standing for their parts as bounds, not tested), recorded
        in `tried`; and the pieces per method."""
        methods = {m: len(pieces) if m == self.method else 0 for m in MESH_METHODS[1:]}
        if self.method == "convex":
            check = Validation(ok=True, tolerance=self.tolerance, message="convex hulls only: they contain their parts")
        else:
            check = validate(self.mesh, pieces, self.tolerance, solids=self.solids, progress=self.progress)
        record = asdict(check)
        record.pop("bad_pieces"), record.pop("uncovered_faces")
        self.tried.append({"methods": methods, "pieces": len(pieces), "notes": list(self.notes), **record})
        return check, methods

    def mend(self, check: Validation, owner: list[int]) -> None:
        """After a failed validation: a shell part's few bad pieces become face pieces (once); UserError when a part
        has none to mend."""
        uncovered = {int(self.part_of_face[f]) for f in check.uncovered_faces}
        blamed = {owner[k] for k in check.bad_pieces} | uncovered
        mend = {i for i in blamed if self.method == "shell" and i not in self.mended} - uncovered
        if not mend or blamed - mend:
            raise UserError(f"no valid convex decomposition for {self.label}: {check.message}")
        for i in mend:
            first = owner.index(i)
            bad = [k - first for k in check.bad_pieces if owner[k] == i]
            self.built[i], self.shell_groups[i] = faces_instead(
                self.parts[i], self.built[i], self.shell_groups[i], bad, self.tolerance
            )
            self.notes.append(f"part {i}: {len(bad)} shell piece(s) held free points and became face pieces")
            self.mended.add(i)
