"""app.scene.meshes: conversion, bounds and named methods, validation (it must be able to fail) and the cache."""

import numpy as np
import pytest

pytest.importorskip("trimesh")

import trimesh  # noqa: E402

from app.errors import PlannerWarning, UserError  # noqa: E402
from app.scene.meshes import cache, coacd_process, decomposition, merging, pieces, reading, validation  # noqa: E402
from mesh_shapes import bent_sheet, holed_shell, open_u, u_boxes, u_channel  # noqa: E402


def test_convex_hull_of_a_u_channel_fails_validation():
    mesh = u_channel()
    check = validation.validate(mesh, [pieces.hull_piece(mesh.vertices)], decomposition.default_tolerance(mesh))
    assert not check.ok
    assert check.violations > 100 and check.worst_depth > 0.5  # the hull fills the 2-wide slot


def test_a_dropped_piece_fails_validation():
    mesh = open_u()
    tol = decomposition.default_tolerance(mesh)
    plates = pieces.face_pieces(mesh, slab=tol / 2, thickness=tol / 5, progress=False)
    assert validation.validate(mesh, plates, tol).ok
    check = validation.validate(mesh, plates[1:], tol)
    assert not check.ok and check.uncovered > 0 and check.violations == 0


def test_a_face_with_no_area_makes_no_piece():
    """Collinear corners have no plane: no piece of NaNs (Drake could not read it), the sheet's pieces unchanged."""
    mesh = bent_sheet()
    tol = decomposition.default_tolerance(mesh)
    before = pieces.face_pieces(mesh, slab=tol / 2, thickness=tol / 5, progress=False)
    a, b = mesh.faces[0][:2]
    middle = len(mesh.vertices)
    sliver = trimesh.Trimesh(
        np.vstack([mesh.vertices, (mesh.vertices[a] + mesh.vertices[b]) / 2]),
        np.vstack([mesh.faces, [[a, middle, b]]]),
        process=False,
    )
    after = pieces.face_pieces(sliver, slab=tol / 2, thickness=tol / 5, progress=False)
    assert len(after) == len(before) and all(np.isfinite(p.vertices).all() for p in after)


def test_thick_face_pieces_fail_validation():
    """Pieces thicker than the tolerance reach into free space near the surface: the check sees it."""
    mesh = bent_sheet()
    tol = decomposition.default_tolerance(mesh)
    plates = pieces.face_pieces(mesh, slab=tol / 2, thickness=4 * tol, progress=False)
    check = validation.validate(mesh, plates, tol)
    assert not check.ok and check.violations > 0


def test_open_channel_by_exact_faces_has_coplanar_triangles_merged(tmp_path):
    path = tmp_path / "u.stl"
    open_u().export(path)
    d = cache.decompose(path, method="faces", cache_dir=tmp_path, progress=False)
    assert d.method == "faces" and d.facts["closed"] is False
    assert len(d.pieces) == 8  # 16 triangles: each wall rectangle's two triangles become one piece
    assert d.validation["ok"] and d.validation["violations"] == 0


def test_overlapping_closed_boxes_are_one_piece_each(tmp_path):
    path = tmp_path / "u.stl"
    u_boxes().export(path)  # three boxes in one mesh, touching: not watertight as a whole, each part closed
    d = cache.decompose(path, cache_dir=tmp_path, progress=False)
    assert d.method == "split" and len(d.pieces) == 3 and d.facts["components"] == 3
    assert d.validation["ok"]


def test_bent_sheet_takes_exact_faces_and_validates(tmp_path):
    path = tmp_path / "sheet.obj"
    bent_sheet().export(path)
    d = cache.decompose(path, method="faces", cache_dir=tmp_path, progress=False)
    assert d.method == "faces"
    assert d.validation["ok"] and d.validation["near_surface_points"] > 1000 and d.validation["free_points"] > 1000
    # every piece is thin: within tolerance of the sheet
    for piece in cache.load_pieces(d):
        radial = np.linalg.norm(piece.vertices[:, 1:], axis=1)
        assert np.all(np.abs(radial - 2.0) < d.validation["tolerance"])


def test_closed_u_channel_is_bounded_and_cached(tmp_path, monkeypatch):
    path = tmp_path / "u.stl"
    u_channel().export(path)
    first = cache.decompose(path, cache_dir=tmp_path, progress=False)
    assert first.facts["closed"] and not first.facts["convex"]
    assert first.method == "split" and first.validation["ok"] and not first.from_cache
    slot = np.array([[0.0, 0.0, 1.0], [0.0, 0.9, 1.5], [1.5, -0.9, 0.7]])  # between the walls, below their tops
    assert (validation.inside_any(slot, cache.load_pieces(first), margin=0.0)[0] < 0).all()
    monkeypatch.setattr(decomposition, "decompose_parts", None)  # calling it now fails: this must read the cache
    again = cache.decompose(path, cache_dir=tmp_path, progress=False)
    assert again.from_cache
    assert [p.read_bytes() for p in again.pieces] == [p.read_bytes() for p in first.pieces]


def test_forced_convex_hull_is_taken_and_the_slot_it_fills_is_stated(tmp_path):
    path = tmp_path / "u.obj"
    u_channel().export(path)
    hull = cache.decompose(path, method="convex", cache_dir=tmp_path, progress=False)
    assert len(hull.pieces) == 1 and hull.parts == {"convex": 1}
    # The U's section is 3 m^2 and its slot 2 x 1.5 = 3 m^2: the hull adds the mesh's own volume again.
    assert hull.volume["relative_to"] == "mesh" and hull.volume["added"] == pytest.approx(1.0, abs=0.05)


def test_a_failed_decomposition_is_cached(tmp_path, monkeypatch):
    path = tmp_path / "open.obj"
    open_u().export(path)
    with pytest.raises(UserError, match="shell needs a closed mesh"):
        cache.decompose(path, method="shell", cache_dir=tmp_path, progress=False)
    # Calling it now fails: the failure must come from the cache
    monkeypatch.setattr(decomposition, "decompose_parts", None)
    with pytest.raises(UserError, match="shell needs a closed mesh.*cached"):
        cache.decompose(path, method="shell", cache_dir=tmp_path, progress=False)


def test_conservative_hulls_merge_slivers_and_keep_an_l_two_hulls():
    """Slivers lying on a box's faces join its hull; a second box at right angles (an L) stays apart."""
    T = trimesh.transformations.translation_matrix
    bar, leg = trimesh.creation.box([1, 0.1, 0.1]), trimesh.creation.box([0.1, 0.1, 1], T([0.45, 0, 0.55]))
    sliver = np.array([[-0.3, -0.05, 0.05], [-0.2, -0.05, 0.05], [-0.2, 0.05, 0.05]])  # on the bar's top face
    hulls, members = pieces.hull_groups([bar.vertices, leg.vertices, sliver, sliver + [0.4, 0, 0]], tolerance=0.002)
    assert sorted(map(sorted, members)) == [[0, 2, 3], [1]]
    merged = hulls[next(k for k, m in enumerate(members) if 2 in m)]
    assert np.all(np.vstack([bar.vertices, sliver]) @ merged.equations[:, :3].T + merged.equations[:, 3] <= 1e-9)


def test_merging_joins_pieces_in_line_and_keeps_an_l_apart():
    """Two boxes end to end merge into one hull that adds nothing; at right angles (an L, 2 cm arms) their hull
    would stand 14 mm off the corner's inside: refused, whatever the cap."""
    T = trimesh.transformations.translation_matrix
    bar = trimesh.creation.box([0.1, 0.02, 0.02])
    line = [bar, trimesh.creation.box([0.1, 0.02, 0.02], T([0.1, 0, 0]))]
    ell = [bar, trimesh.creation.box([0.02, 0.02, 0.1], T([0.04, 0, 0.06]))]
    for boxes, expected in ((line, 1), (ell, 2)):
        surface = merging.Surface(trimesh.util.concatenate(boxes), merging.MERGE_REACH / 8)
        found, members = merging.merged_pieces(
            [pieces.hull_piece(b.vertices) for b in boxes], surface, merging.MERGE_REACH, 1
        )
        assert len(found) == expected and sorted(m for group in members for m in group) == [0, 1]


@pytest.mark.parametrize("closed", [True, False])
def test_a_ring_link_is_bounded_by_hulls_that_hold_it_and_stay_within_the_reach(closed):
    """A ring (radii 4 and 5 cm) as a robot link, closed or with its top cap gone (as CAD exports leave parts): a
    few hulls, which hold every corner and surface point of the ring and whose surfaces (3,000 points each, drawn
    apart from the bounding's own test) lie inside the ring or within MERGE_REACH of it. The ring's hull, which
    fills the hole, is never taken: the centre stays free."""
    ring = trimesh.creation.annulus(r_min=0.04, r_max=0.05, height=0.03, sections=48)
    solid = ring.copy()
    if not closed:
        ring = ring.submesh([np.flatnonzero(ring.face_normals[:, 2] < 0.99)], append=True)
        assert not ring.is_watertight
    args = (ring, "auto", decomposition.default_tolerance(ring), 0.03, 60.0, False, "ring", True)
    bounds, _, tried, methods, _ = decomposition.decompose_parts(*args, merge_reach=merging.MERGE_REACH)
    assert 1 < len(bounds) <= 24 and set(methods) == {"split"} and tried[0]["ok"]
    held = np.vstack([ring.vertices, ring.sample(3000, seed=2)])
    depth, _ = validation.inside_any(np.vstack([held, [[0, 0, 0]]]), bounds, margin=0.0)
    assert (depth[:-1] >= -1e-9).all() and depth[-1] < 0
    for piece in bounds:
        surface = trimesh.Trimesh(piece.vertices, piece.faces).sample(3000, seed=1)
        outside = surface[~solid.contains(surface)]
        gap = np.linalg.norm(trimesh.proximity.closest_point(solid, outside)[0] - outside, axis=1)
        assert gap.max(initial=0.0) <= merging.MERGE_REACH


def test_a_fine_link_mesh_is_split_not_grown_face_by_face(monkeypatch):
    """A link of 20,000 triangles (a finely tessellated ring) is bounded without the shell method, whose patches
    grow a face at a time (minutes on a CAD gripper), and without asking trimesh for exact distances."""
    ring = trimesh.creation.annulus(r_min=0.04, r_max=0.05, height=0.03, sections=48).subdivide().subdivide()
    ring = ring.subdivide().subdivide() if len(ring.faces) < 20_000 else ring
    assert len(ring.faces) >= 20_000
    monkeypatch.setattr(decomposition, "shell_pieces", None)
    monkeypatch.setattr(validation, "within", None)
    args = (ring, "auto", decomposition.default_tolerance(ring), 0.03, 60.0, False, "ring", True)
    bounds = decomposition.decompose_parts(*args, merge_reach=merging.MERGE_REACH)[0]
    assert 1 < len(bounds) <= merging.MOST_LINK_PIECES * 2
    assert (validation.inside_any(ring.vertices, bounds, margin=0.0)[0] >= -1e-9).all()


def said(given) -> list[str]:
    """The PlannerWarnings' messages among warnings recorded by pytest.warns."""
    return [str(w.message) for w in given if issubclass(w.category, PlannerWarning)]


def test_damaged_cache_entry_is_rebuilt(tmp_path):
    path = tmp_path / "u.stl"
    open_u().export(path)
    first = cache.decompose(path, cache_dir=tmp_path, progress=False)
    good = first.pieces[3].read_bytes()
    first.pieces[3].write_bytes(good[: len(good) // 2])  # truncated
    with pytest.warns(PlannerWarning, match="damaged"):
        rebuilt = cache.decompose(path, cache_dir=tmp_path, progress=False)
    assert not rebuilt.from_cache and rebuilt.pieces[3].read_bytes() == good
    (rebuilt.directory / "manifest.json").write_text("{not json")
    with pytest.warns(PlannerWarning, match="damaged"):
        assert not cache.decompose(path, cache_dir=tmp_path, progress=False).from_cache


def test_a_forged_cache_entry_with_matching_checksums_is_rebuilt(tmp_path):
    """Checksums in the manifest catch accidents only: a piece replaced by a smaller one, with the manifest's checksum
    updated to match, would leave part of the mesh outside every piece. The manifest's seal (an HMAC under this
    user's key, which is not in the cache) no longer matches: the entry is rebuilt."""
    import hashlib
    import json

    path = tmp_path / "u.stl"
    open_u().export(path)
    first = cache.decompose(path, cache_dir=tmp_path, progress=False)
    good = first.pieces[0].read_bytes()
    forged = b"v 0 0 0\nv 1e-3 0 0\nv 0 1e-3 0\nv 0 0 1e-3\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"
    first.pieces[0].write_bytes(forged)
    manifest_file = first.directory / "manifest.json"
    manifest = json.loads(manifest_file.read_text())
    manifest["files"][manifest["pieces"][0]] = hashlib.sha256(forged).hexdigest()
    manifest_file.write_text(json.dumps(manifest, indent=1))
    with pytest.warns(PlannerWarning) as given:
        rebuilt = cache.decompose(path, cache_dir=tmp_path, progress=False)
    assert not rebuilt.from_cache and rebuilt.pieces[0].read_bytes() == good
    assert said(given) == [f"mesh cache entry {first.directory} is damaged; rebuilding it"]
    assert cache.decompose(path, cache_dir=tmp_path, progress=False).from_cache  # sealed again, with this key
    (rebuilt.directory / "manifest.mac").unlink()  # no seal at all: damaged too
    with pytest.warns(PlannerWarning, match="damaged"):
        assert not cache.decompose(path, cache_dir=tmp_path, progress=False).from_cache


def test_a_cache_made_with_another_key_is_rebuilt(tmp_path, monkeypatch):
    """Another user's cache folder (or one handed over) is sealed under their key, not this user's."""
    path = tmp_path / "u.stl"
    open_u().export(path)
    monkeypatch.setenv(cache.KEY_ENV, str(tmp_path / "theirs.key"))
    theirs = cache.decompose(path, cache_dir=tmp_path, progress=False)
    assert cache.decompose(path, cache_dir=tmp_path, progress=False).from_cache
    monkeypatch.setenv(cache.KEY_ENV, str(tmp_path / "mine.key"))
    with pytest.warns(PlannerWarning, match="is damaged; rebuilding it"):
        mine = cache.decompose(path, cache_dir=tmp_path, progress=False)
    assert mine.directory == theirs.directory and not mine.from_cache


def test_a_converted_obj_is_sealed_and_a_forged_one_is_converted_again(tmp_path, monkeypatch):
    path = tmp_path / "u.stl"
    u_boxes().export(path)
    converted = cache.converted_obj(path, cache_dir=tmp_path)
    good = converted.read_bytes()
    assert converted.with_name(converted.name + ".mac").is_file()
    assert cache.converted_obj(path, cache_dir=tmp_path).read_bytes() == good
    converted.write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")  # another shape under the same name
    with pytest.warns(PlannerWarning, match="is damaged; rebuilding it"):
        assert cache.converted_obj(path, cache_dir=tmp_path).read_bytes() == good
    # The same file and seal made under another key: converted again.
    monkeypatch.setenv(cache.KEY_ENV, str(tmp_path / "other.key"))
    seal = converted.with_name(converted.name + ".mac").read_text()
    with pytest.warns(PlannerWarning, match="is damaged; rebuilding it"):
        cache.converted_obj(path, cache_dir=tmp_path)
    assert converted.with_name(converted.name + ".mac").read_text() != seal


def test_the_key_is_made_private_and_a_key_that_cannot_be_made_means_no_reuse(tmp_path, monkeypatch):
    monkeypatch.setenv(cache.KEY_ENV, str(tmp_path / "config" / "npp" / "cache.key"))
    key = cache.cache_key()
    stat = (tmp_path / "config" / "npp" / "cache.key").stat()
    assert len(key) == 32 and stat.st_mode & 0o777 == 0o600 and cache.cache_key() == key
    path = tmp_path / "u.stl"
    open_u().export(path)
    cache.decompose(path, cache_dir=tmp_path, progress=False)
    # A key that cannot be made (its folder would be inside a file, as under a read-only home): said once, and
    # nothing cached is reused, not even what this process writes.
    (tmp_path / "file").write_text("x")
    monkeypatch.setenv(cache.KEY_ENV, str(tmp_path / "file" / "cache.key"))
    with pytest.warns(PlannerWarning) as given:
        assert not cache.decompose(path, cache_dir=tmp_path, progress=False).from_cache
        assert not cache.decompose(path, cache_dir=tmp_path, progress=False).from_cache
    err = said(given)
    assert len(err) == 1 and err[0].startswith(f"cannot use the mesh cache key {tmp_path / 'file'}")
    assert "cached meshes are not reused" in err[0]
    # A key file others may read is no secret: refused the same way.
    loose = tmp_path / "loose.key"
    loose.write_bytes(b"k" * 32)
    loose.chmod(0o644)
    monkeypatch.setenv(cache.KEY_ENV, str(loose))
    with pytest.warns(PlannerWarning, match="chmod 600 it"):
        assert cache.cache_key() is None


def test_a_changed_mesh_is_a_new_entry(tmp_path):
    path = tmp_path / "m.stl"
    u_boxes().export(path)
    a = cache.decompose(path, cache_dir=tmp_path, progress=False)
    u_boxes(length=5.0).export(path)
    b = cache.decompose(path, cache_dir=tmp_path, progress=False)
    assert a.directory != b.directory and not b.from_cache


def test_collada_is_read(tmp_path):
    path = tmp_path / "u.dae"
    u_boxes().export(path)
    mesh = reading.load_mesh(path)
    assert len(mesh.faces) == 36


@pytest.mark.parametrize(
    "content, suffix, message",
    [
        (None, ".stl", "not found"),
        (b"this is not a mesh at all\n", ".stl", "cannot read mesh"),
        (b"<COLLADA><broken", ".dae", "cannot read mesh"),
        (b"solid x\nendsolid x\n", ".stl", "cannot read mesh"),
        (b"v 0 0 0\n", ".xyz", "unsupported mesh format"),
    ],
)
def test_bad_meshes_are_one_line_user_errors(tmp_path, content, suffix, message):
    path = tmp_path / f"bad{suffix}"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(UserError, match=message) as info:
        cache.decompose(path, cache_dir=tmp_path, progress=False) if suffix != ".xyz" else reading.load_mesh(path)
    assert "\n" not in str(info.value)


def test_coacd_pieces_that_fill_free_space_are_refused_and_the_refusal_cached(tmp_path, monkeypatch):
    """As measured on thin-walled scenes: CoACD's pieces put free space in collision -> validation rejects them."""

    def hull_instead(parts, *args, **kwargs):
        return [[pieces.hull_piece(p.vertices)] for p in parts]

    monkeypatch.setattr(coacd_process, "coacd_pieces", hull_instead)
    path = tmp_path / "u.stl"
    u_channel().export(path)
    with pytest.raises(UserError, match="no valid convex decomposition for u.stl") as info:
        cache.decompose(path, method="coacd", cache_dir=tmp_path, progress=False)
    assert "\n" not in str(info.value)
    monkeypatch.setattr(coacd_process, "coacd_pieces", None)  # asking again reads the refusal
    with pytest.raises(UserError, match="cached"):
        cache.decompose(path, method="coacd", cache_dir=tmp_path, progress=False)


def test_a_crashing_coacd_is_one_line(tmp_path, monkeypatch):
    def crash(*args, **kwargs):
        raise coacd_process.MethodFailed("CoACD failed (exit code -11)")

    monkeypatch.setattr(coacd_process, "coacd_pieces", crash)
    path = tmp_path / "u.stl"
    u_channel().export(path)
    with pytest.raises(UserError, match="exit code -11"):
        cache.decompose(path, method="coacd", cache_dir=tmp_path, progress=False)


def test_a_thick_shell_becomes_shell_pieces_far_fewer_than_face_plates(tmp_path):
    """The trap (3,072 triangles, walls 0.2 thick): pieces reaching into the wall cover its outer side in large
    caps; they keep the cavity and the opening free, checked on points the validation did not draw."""
    path = tmp_path / "trap.obj"
    holed_shell().export(path)
    tol = 0.025
    shell = cache.decompose(path, method="shell", tolerance=tol, cache_dir=tmp_path, progress=False)
    plates = cache.decompose(path, method="faces", tolerance=tol, cache_dir=tmp_path, progress=False)
    assert shell.method == "shell" and shell.validation["ok"]
    assert len(shell.pieces) < 0.5 * len(plates.pieces)
    rng = np.random.default_rng(7)
    points = rng.uniform(-1.5, 1.5, (40_000, 3))
    radius = np.linalg.norm(points, axis=1)
    free = (radius < 1.0 - tol) | (radius > 1.2 + tol)
    depth, _ = validation.inside_any(points[free], cache.load_pieces(shell), margin=0.0)
    assert free.sum() > 20_000 and not (depth > 1e-9).any()
    wall = (radius > 1.0 + tol) & (radius < 1.2 - tol) & (points[:, 2] < 0)  # away from the opening
    depth, _ = validation.inside_any(points[wall], cache.load_pieces(shell), margin=0.0)
    assert wall.sum() > 1000 and (depth > 0).mean() > 0.5  # the pieces fill much of the wall, not just its skin


def test_shell_pieces_that_fill_free_space_become_face_pieces(tmp_path):
    """The hull of a U-shaped end face fills the U's slot between sparse probes: validation finds those pieces and
    only they are replaced."""
    path = tmp_path / "u.obj"
    u_channel().export(path)
    d = cache.decompose(path, method="shell", cache_dir=tmp_path, progress=False)
    manifest = __import__("json").loads((d.directory / "manifest.json").read_text())
    assert [t["ok"] for t in manifest["tried"]] == [False, True]
    assert manifest["tried"][0]["violations"] > 0 and "became face pieces" in " ".join(d.validation["notes"])
    assert d.method == "shell" and len(d.pieces) > manifest["tried"][0]["pieces"]


def test_collada_units_are_applied(tmp_path):
    path = tmp_path / "mm.dae"
    u_boxes().export(path)
    text = path.read_text()
    path.write_text(text.replace("<asset>", '<asset><unit meter="0.001" name="millimeter"/>', 1))
    mesh = reading.load_mesh(path)
    assert np.allclose(mesh.extents, [0.004, 0.003, 0.002])


@pytest.mark.slow
def test_a_2700_face_scene_builds_few_pieces_once(tmp_path, monkeypatch):
    """A generated COLLADA scene: 110 thin walls (closed boxes) + a finely curved open sheet."""
    import trimesh

    rng = np.random.default_rng(0)
    parts = []
    for _ in range(110):
        T = trimesh.transformations.translation_matrix(rng.uniform(-10, 10, 3))
        R = trimesh.transformations.rotation_matrix(rng.uniform(0, np.pi), [0, 0, 1])
        parts.append(trimesh.creation.box([rng.uniform(1, 4), 0.1, 3], T @ R))
    sheet = bent_sheet(radius=3, n_arc=700, width=6)
    sheet.apply_translation([0, 0, 12])
    path = tmp_path / "scene.dae"
    trimesh.util.concatenate(parts + [sheet]).export(path)
    first = cache.decompose(path, cache_dir=tmp_path, progress=False)
    assert first.validation["ok"] and len(first.pieces) < 200
    monkeypatch.setattr(decomposition, "decompose_parts", None)  # calling it now fails: this must read the cache
    again = cache.decompose(path, cache_dir=tmp_path, progress=False)
    assert again.from_cache


def test_two_uncached_link_meshes_are_built_one_here_one_in_a_child(tmp_path, monkeypatch):
    """A robot's uncached link meshes are built two at a time: this process builds one (the larger), a child
    interpreter the other; both come back as built (not from the cache), and asking again reads both from it."""
    from app.scene.prepare_meshes import MeshOptions

    paths = [tmp_path / "big.stl", tmp_path / "small.stl"]
    trimesh.creation.annulus(r_min=0.04, r_max=0.05, height=0.03, sections=64).export(paths[0])
    trimesh.creation.annulus(r_min=0.02, r_max=0.03, height=0.02, sections=32).export(paths[1])
    here = []
    build = decomposition.decompose_parts
    monkeypatch.setattr(decomposition, "decompose_parts", lambda *a, **k: here.append(a[6]) or build(*a, **k))
    options = MeshOptions(method="auto", tolerance=None, cache_dir=tmp_path / "cache", progress=False)
    requests = [(path, True, 1.0) for path in paths]
    built = options.built(requests)
    assert here == ["big.stl"] and set(built) == set(requests)  # (the label: the file's name)
    assert not any(d.from_cache for d in built.values())
    assert options.built(requests) == {} and all(options.decompose(*r).from_cache for r in requests)
    assert len(here) == 1


def test_loose_triangles_of_an_obstacle_are_bounded_by_a_hull_a_wall(tmp_path):
    """An obstacle exported as loose triangles (36 connected parts) becomes one hull a wall and one for the slab:
    each hull holds its triangles, stays within the tolerance of them (points on its surface, drawn apart from the
    bounding's own test), and the corridor between the walls stays free."""
    from mesh_shapes import loose_walls

    mesh = loose_walls()
    path = tmp_path / "walls.obj"
    mesh.export(path)
    d = cache.decompose(path, tolerance=0.02, cache_dir=tmp_path, progress=False)
    assert d.method == "split" and d.facts["components"] == 36 and len(d.pieces) == 3
    bounds = cache.load_pieces(d)
    assert (validation.inside_any(mesh.vertices, bounds, margin=1e-9)[0] >= 0).all()
    solid = trimesh.util.concatenate(
        [trimesh.convex.convex_hull(mesh.vertices[k * 36 : (k + 1) * 36]) for k in range(3)]
    )
    for piece in bounds:
        surface = trimesh.Trimesh(piece.vertices, piece.faces).sample(2000, seed=1)
        gap = np.abs(trimesh.proximity.signed_distance(solid, surface))
        assert gap.max() <= 0.02
    corridor = np.array([[0, 0, 1.0], [1.9, 0.95, 1.9], [-1.9, -0.95, 0.05], [5, 0, 0.25]])
    assert (validation.inside_any(corridor, bounds, margin=0.0)[0] < 0).all()
