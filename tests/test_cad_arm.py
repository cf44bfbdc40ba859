"""A UR-like arm exported the way CAD tools export one (tests/cad_arm.py: STL, unstitched faces, 2-face slivers,
several shells per link) loads with default settings: its links become a few convex hulls that contain the
original mesh and keep a slot open, each link says what was used and the volume it adds, a second load reads the
cache, and (slow) a plan round a post is free against the original meshes, checked with trimesh.

How long the loads take is not asserted here (a busy machine would fail the test, not the code): `bench oracle`
measures it (`python tests/cad_arm.py DIR` prints the command)."""

import json

import numpy as np
import pytest

pytest.importorskip("trimesh")

import trimesh  # noqa: E402
from scipy.spatial import ConvexHull  # noqa: E402

from app.commands.custom import describe  # noqa: E402
from app.errors import UserError  # noqa: E402
from app.scene.custom import CustomSpec, build_scene  # noqa: E402
from app.scene.meshes import cache as mesh_cache  # noqa: E402
from app.scene.meshes import decomposition  # noqa: E402
from app.scene.meshes.merging import MOST_LINK_PIECES  # noqa: E402
from cad_arm import GOAL, LINKS, START, write_arm, write_post  # noqa: E402


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    d = tmp_path_factory.mktemp("cad_arm")
    write_arm(d)
    write_post(d / "post.stl")
    return d


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """One mesh cache for the module: empty for the first test (which loads into it, then from it), warm after it."""
    return tmp_path_factory.mktemp("cad_arm_cache")


def _spec(arm, **keys) -> CustomSpec:
    spec = dict(robot=str(arm / "cad_arm.urdf"), env=[str(arm / "post.stl")], srdf=str(arm / "cad_arm.srdf"))
    return CustomSpec(**{**spec, **keys})


def _outside(points: np.ndarray, pieces: list) -> np.ndarray:
    """Points in no piece: each piece's hull recomputed by scipy from the .obj file Drake reads."""
    out = np.ones(len(points), bool)
    for path in pieces:
        hull = ConvexHull(trimesh.load(path, force="mesh", process=False).vertices)
        out &= (points @ hull.equations[:, :3].T + hull.equations[:, 3]).max(axis=1) > 1e-9
    return out


def test_cad_links_load_with_defaults_and_contain_their_meshes(arm, cache, monkeypatch):
    scene = build_scene(_spec(arm), cache_dir=cache, progress=False)
    links = {d["mesh"]: d for d in scene.info["decompositions"] if d["mesh"] != "post.stl"}
    assert sorted(links) == sorted(f"{name}.stl" for name in LINKS)
    assert not any(d["from_cache"] for d in scene.info["decompositions"])  # built here, into the empty cache
    for name, d in links.items():
        source = trimesh.load(arm / "meshes" / name, force="mesh")
        assert len(source.split(only_watertight=False)) > 90 and not source.is_watertight
        assert d["parts"] == {"split": len(source.split(only_watertight=False))}  # all parts bounded together
        assert d["pieces"] <= MOST_LINK_PIECES  # merged: a few hulls per link, not one per sliver or shell piece
        assert d["volume"]["relative_to"] == "hull" and -0.6 < d["volume"]["added"] < 0.01
        # Conservative: every corner and 3,000 surface points of the original mesh lie in some piece.
        points = np.vstack([source.vertices, trimesh.sample.sample_surface(source, 3000, seed=0)[0]])
        found = mesh_cache.decompose(arm / "meshes" / name, cache_dir=cache, conservative=True, progress=False)
        assert found.from_cache and not _outside(points, found.pieces).any()
    # The closed, non-convex bracket on the upper arm keeps its slot (30 mm wide, 15 deep): a point in it 7.5 mm
    # and more from the mesh is in no piece.
    upper = mesh_cache.decompose(arm / "meshes" / "upper_arm.stl", cache_dir=cache, conservative=True, progress=False)
    assert _outside(np.array([[0.05, 0.0, 0.1225]]), upper.pieces).all()
    lines = describe(scene)
    assert any("upper_arm.stl" in line and "by split" in line and "of the mesh's hull" in line for line in lines)

    # Again: every piece read from the cache, none decomposed anew (how much faster: `bench oracle`, see above).
    monkeypatch.setattr(decomposition, "decompose_parts", None)  # calling it now fails
    again = build_scene(_spec(arm), cache_dir=cache, progress=False)
    assert all(d["from_cache"] for d in again.info["decompositions"])


def test_forced_hulls_take_every_part_as_a_hull(arm, tmp_path):
    forced = mesh_cache.decompose(arm / "meshes" / "upper_arm.stl", "convex", cache_dir=tmp_path, progress=False)
    assert forced.parts == {"convex": len(trimesh.load(arm / "meshes" / "upper_arm.stl").split(only_watertight=False))}
    assert forced.method == "convex" and forced.volume["added"] > -0.6


def test_an_unknown_srdf_link_is_reported_before_any_mesh_work(arm, tmp_path, monkeypatch):
    (tmp_path / "typo.srdf").write_text('<robot name="cad_arm"><disable_collisions link1="base" link2="elbw"/></robot>')
    monkeypatch.setattr(mesh_cache, "decompose", None)  # calling it now fails: the SRDF must be refused first
    with pytest.raises(UserError, match="unknown link.*elbw"):
        build_scene(_spec(arm, srdf=str(tmp_path / "typo.srdf")), cache_dir=tmp_path, progress=False)


def test_a_wrong_start_is_reported_before_the_environment_is_decomposed(arm, tmp_path, cache, monkeypatch):
    (tmp_path / "box.stl").write_bytes(trimesh.creation.box([0.1, 0.1, 0.1]).export(file_type="stl"))
    build_scene(_spec(arm, env=[]), cache_dir=cache, progress=False)  # the links cached (by the first test already)
    # Decomposing the box now fails: start must be refused first
    monkeypatch.setattr(decomposition, "decompose_parts", None)
    with pytest.raises(UserError, match="start needs 6 numbers"):
        build_scene(_spec(arm, env=[str(tmp_path / "box.stl")], start=[0.0, 0.0]), cache_dir=cache, progress=False)


@pytest.mark.slow
def test_a_plan_round_the_post_is_free_against_the_original_meshes(arm, tmp_path, cli, monkeypatch):
    from app.checking.oracle import CollisionOracle
    from independent import fine_points

    monkeypatch.setenv("NPP_CACHE_DIR", str(tmp_path))
    flags = ["--robot", arm / "cad_arm.urdf", "--srdf", arm / "cad_arm.srdf", "--env", arm / "post.stl"]
    result = cli("plan", *flags, f"--start={','.join(map(str, START))}", f"--goal={','.join(map(str, GOAL))}", "--json")
    assert result.returncode == 0, result.stderr
    answer = json.loads(result.stdout)
    assert answer["success"] and {d["mesh"] for d in answer["meshes"]} >= {f"{n}.stl" for n in LINKS}

    # Independently: the original link meshes (every corner, 2,000 surface points each) posed by forward kinematics
    # at every state and along the path at half the edge-check step, against the original obstacle mesh (trimesh).
    oracle = CollisionOracle(build_scene(_spec(arm), cache_dir=tmp_path, progress=False))
    plant = oracle.plant
    context = plant.CreateDefaultContext()
    obstacle = trimesh.load(arm / "post.stl", force="mesh")
    posts = obstacle.split()
    clouds = {}
    for name in LINKS:
        source = trimesh.load(arm / "meshes" / f"{name}.stl", force="mesh")
        clouds[name] = np.vstack([source.vertices, trimesh.sample.sample_surface(source, 2000, seed=0)[0]])
    states = np.vstack([answer["trajectory"]["positions"], fine_points(oracle, np.array(answer["path"]), 0.01)])
    for q in states:
        plant.SetPositions(context, q)
        for name, cloud in clouds.items():
            X = plant.GetBodyByName(name).EvalPoseInWorld(context)
            world = cloud @ X.rotation().matrix().T + X.translation()
            assert not any(part.contains(world).any() for part in posts), (name, q)
