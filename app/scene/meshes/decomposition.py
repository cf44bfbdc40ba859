"""A mesh's convex decomposition, part by part: a method chosen per connected part (`choose_method`), the parts built,
the whole validated, and a part whose pieces fail moved on to its next method (`decompose_parts`)."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from app.errors import UserError
from app.scene.files import MESH_METHODS
from app.scene.meshes import coacd_process
from app.scene.meshes.merging import Enclosure, Surface, merged_pieces, split_hulls
from app.scene.meshes.pieces import Piece, face_pieces, faces_instead, hull_groups, hull_piece, shell_pieces
from app.scene.meshes.validation import Validation, components, validate

# Distances to a mesh's surface are bounded to within reach / _SPACING (see merging.Surface), with at most about
# _MOST_SURFACE_POINTS points (a UR5's upper arm takes 1.8 million at 5 mm / 8).
_SPACING = 8
_MOST_SURFACE_POINTS = 4_000_000
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


def choose_method(facts: dict) -> list[str]:
    """Methods to try in order: closed and convex -> one piece; closed -> shell pieces (seconds), then CoACD
    (minutes), then exact faces; else exact faces. (A robot's links take `_link_bounds` instead.)"""
    if facts["convex"]:
        return ["convex", "faces"]
    if facts["closed"]:
        return ["shell", "coacd", "faces"]
    return ["faces"]


def method_name(methods: dict) -> str:
    """The one method that made pieces, or "mixed"."""
    used = [m for m, n in methods.items() if n]
    return used[0] if len(used) == 1 else "mixed"


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
    """Choose a method per connected part, build, validate the whole; a part whose pieces fail moves on to its next
    method. A robot's link (`conservative`, method "auto") is bounded by `_link_bounds` instead. With
    `conservative` and method "convex", hulls stand for their parts as bounds, merged by `hull_groups` and exempt
    from the free-space test (they are larger than their parts by design). With `merge_reach` (in the mesh's
    units), the validated pieces are then merged (`merged_pieces`) while every merged hull's surface stays within
    `merge_reach` of the mesh: within `merge_reach - tolerance` of the validated pieces, which hold no free point
    farther than the tolerance from it. Returns (pieces, the number of parts with pieces, the validation
    rounds, pieces per method before merging, parts per method)."""
    if conservative and method == "auto":
        return _link_bounds(mesh, tolerance, merge_reach)
    parts = _Parts(mesh, method, tolerance, conservative, label, progress, coacd_threshold, coacd_timeout)
    while True:
        if not parts.build():
            continue  # CoACD failed: its parts moved on to their next method
        pieces, owner = parts.assembled()
        check, methods = parts.validated(pieces, owner)
        if check.ok:
            break
        parts.mend_or_move_on(check, owner)
    if merge_reach is not None and merge_reach > tolerance:
        reach = merge_reach - tolerance
        pieces = merged_pieces(pieces, Surface(mesh, reach / _SPACING), reach)[0]
    final = parts.final_methods()
    return pieces, len(set(owner)), parts.tried, methods, {m: final.count(m) for m in MESH_METHODS[1:] if m in final}


def _link_bounds(mesh, tolerance: float, reach: float):
    """A robot link's pieces (`conservative`, method "auto"): hulls split top down, then merged, each within `reach`
    of the mesh or inside its parts (`split_hulls`, `merged_pieces`), in seconds even on a CAD mesh of tens of
    thousands of triangles. The same return as `decompose_parts`; the one round of "validation" records the rule."""
    # (A link far larger than the reach, e.g. a mesh in millimetres read as metres, gets fewer, coarser points:
    # then fewer hulls pass and more are kept, in bounded memory.)
    surface = Surface(mesh, max(reach / _SPACING, np.sqrt(float(mesh.area) / _MOST_SURFACE_POINTS)))
    enclosure = Enclosure(mesh)
    hulls = split_hulls(mesh, surface, reach, tolerance / 5, enclosure)
    pieces = merged_pieces(hulls, surface, reach, inside_is_near=False, enclosure=enclosure)[0]
    rule = f"hulls of the faces, split and merged while every hull's surface stays within {reach:.3g} of the mesh"
    record = asdict(Validation(ok=True, tolerance=reach, message=rule))
    record.pop("bad_pieces"), record.pop("uncovered_faces")
    tried = [{"methods": {"split": len(hulls)}, "pieces": len(pieces), "notes": [], **record}]
    return pieces, enclosure.parts, tried, {"split": len(hulls)}, {"split": enclosure.parts}


class _Parts:
    """A mesh's connected parts, each with the methods to try in order (`level`: the one now), the pieces built for
    each so far, and what every round of validation found (`tried`)."""

    def __init__(self, mesh, method, tolerance, conservative, label, progress, coacd_threshold, coacd_timeout):
        self.mesh, self.tolerance, self.label, self.progress = mesh, tolerance, label, progress
        self.coacd_threshold, self.coacd_timeout = coacd_threshold, coacd_timeout
        self.groups = components(mesh)
        self.part_of_face = np.empty(len(mesh.faces), int)
        for i, g in enumerate(self.groups):
            self.part_of_face[g] = i
        self.parts = [mesh.submesh([g], append=True) if len(g) >= 4 else None for g in self.groups]
        self.facts = [classify(p) if p is not None else _OPEN_FACTS for p in self.parts]
        self.solids = [p for p, f in zip(self.parts, self.facts) if f["closed"]]
        self.bounding = conservative or method == "convex"
        self.orders = [[method] if method != "auto" else choose_method(f) for f in self.facts]
        self.level = [0] * len(self.parts)
        self.built: dict[int, list[Piece]] = {}
        self.shell_groups: dict[int, list] = {}  # a shell part's face groups, piece by piece
        self.mended: set[int] = set()
        self.notes: list[str] = []
        self.tried: list[dict] = []

    def method(self, i: int) -> str:
        return self.orders[i][self.level[i]]

    def final_methods(self) -> list[str]:
        return [self.method(i) for i in range(len(self.parts))]

    def _last_method(self, i: int) -> bool:
        return self.level[i] + 1 >= len(self.orders[i])

    def build(self) -> bool:
        """(Re)build the parts without pieces at their current method: convex hulls, shell pieces, CoACD in one
        child, faces merged. False when CoACD failed (its parts then moved on, nothing built by faces yet)."""
        todo = [i for i in range(len(self.parts)) if i not in self.built]
        for i in todo:
            self._skip_methods_needing_a_closed_part(i)
        self._build_hulls([i for i in todo if self.method(i) == "convex"])
        for i in todo:
            if self.method(i) == "shell":
                self.built[i], self.shell_groups[i] = shell_pieces(
                    self.parts[i], self.tolerance, progress=self.progress
                )
        if not self._build_coacd([i for i in todo if self.method(i) == "coacd"]):
            return False
        self._build_faces([i for i in todo if self.method(i) == "faces"])
        return True

    def _skip_methods_needing_a_closed_part(self, i: int) -> None:
        while self.method(i) in ("shell", "coacd") and not self.facts[i]["closed"]:
            self.notes.append(f"part {i}: {self.method(i)} needs a closed mesh")
            if self._last_method(i):
                raise UserError(f"no valid convex decomposition for {self.label}: {self.method(i)} needs a closed mesh")
            self.level[i] += 1

    def _build_hulls(self, hull_parts: list[int]) -> None:
        if self.bounding and hull_parts:
            points = [self.mesh.vertices[np.unique(self.mesh.faces[self.groups[i]])] for i in hull_parts]
            hulls, members = hull_groups(points, self.tolerance)
            self.built.update({i: [] for i in hull_parts})
            for piece, group in zip(hulls, members):
                self.built[hull_parts[group[0]]].append(piece)
        else:
            self.built.update({i: [hull_piece(self.parts[i].vertices)] for i in hull_parts})

    def _build_coacd(self, coacd_parts: list[int]) -> bool:
        if not coacd_parts:
            return True
        try:
            found = coacd_process.coacd_pieces(
                [self.parts[i] for i in coacd_parts], self.coacd_threshold, self.coacd_timeout, self.progress
            )
            for i, pieces in zip(coacd_parts, found):
                self.built[i] = pieces
        except coacd_process.MethodFailed as exc:
            self.notes.append(str(exc))
            for i in coacd_parts:
                if self._last_method(i):
                    raise UserError(f"no valid convex decomposition for {self.label}: {exc}") from None
                self.level[i] += 1
            return False
        return True

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
        final = self.final_methods()
        methods = {
            m: sum(len(self.built[i]) for i in range(len(self.parts)) if final[i] == m) for m in MESH_METHODS[1:]
        }
        exempt = [self.bounding and final[i] == "convex" for i in owner]
        checked = [k for k in range(len(pieces)) if not exempt[k]]
        bounds = [pieces[k] for k in range(len(pieces)) if exempt[k]]
        if checked:
            check = validate(
                self.mesh,
                [pieces[k] for k in checked],
                self.tolerance,
                solids=self.solids,
                progress=self.progress,
                bounds=bounds,
            )
            check.bad_pieces = [checked[k] for k in check.bad_pieces]
        else:
            check = Validation(ok=True, tolerance=self.tolerance, message="convex hulls only: they contain their parts")
        record = asdict(check)
        record.pop("bad_pieces"), record.pop("uncovered_faces")
        self.tried.append({"methods": methods, "pieces": len(pieces), "notes": list(self.notes), **record})
        return check, methods

    def mend_or_move_on(self, check: Validation, owner: list[int]) -> None:
        """After a failed validation: a shell part's few bad pieces become face pieces (once) before the part moves
        on to its next method; every other part blamed moves on; UserError when one has no method left."""
        uncovered = {int(self.part_of_face[f]) for f in check.uncovered_faces}
        blamed = {owner[k] for k in check.bad_pieces} | uncovered
        mend = {i for i in blamed if self.method(i) == "shell" and i not in self.mended}
        mend -= uncovered
        for i in mend:
            first = owner.index(i)
            bad = [k - first for k in check.bad_pieces if owner[k] == i]
            self.built[i], self.shell_groups[i] = faces_instead(
                self.parts[i], self.built[i], self.shell_groups[i], bad, self.tolerance
            )
            self.notes.append(f"part {i}: {len(bad)} shell piece(s) held free points and became face pieces")
            self.mended.add(i)
        blamed -= mend
        if mend and not blamed:
            return
        stuck = [i for i in blamed if self._last_method(i)]
        if stuck or not blamed:
            raise UserError(
                f"no valid convex decomposition for {self.label}: {check.message}"
                + (f" ({len(stuck)} part(s) have no other method)" if stuck else "")
            )
        for i in blamed:
            self.level[i] += 1
            del self.built[i]
