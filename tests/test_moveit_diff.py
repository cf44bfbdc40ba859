"""A MoveIt planning-scene diff as a change of the cell (app.scene.moveit_diff): its objects are where MoveIt puts
them, a MOVE moves an object's parts as one, an attached object is the payload our own change makes, a roadmap is
repaired for a diff on the command line, and what a diff asks that the cell cannot honour is one line."""

import json

import numpy as np
import pytest

from app.errors import UserError
from app.planning.cell import BuildSettings, CellRoadmap
from app.scene.changes import Attachment, CellChange, Placement, changed_scene
from app.scene.moveit_diff import read_change_file

# bar: a wall x in [45, 55] of two boxes, box0 (y 0..46) and box1 (y 54..100); the arm's base moves in x, y at z = 0.
# `post`: two 4 x 4 boxes 10 either side of its origin along its y axis, the object turned 90 degrees about z, so the
# boxes stand 10 either side along x: at (15, 50) and (35, 50), none at (25, 60) or (25, 40).
ADD_POST = """
is_diff: true
world:
  collision_objects:
  - id: post
    header: {frame_id: world}
    pose:
      position: {x: 25.0, y: 50.0, z: 0.0}
      orientation: {x: 0.0, y: 0.0, z: 0.7071067811865476, w: 0.7071067811865476}
    primitives:
    - {type: 1, dimensions: [4.0, 4.0, 2.0]}
    - {type: 1, dimensions: [4.0, 4.0, 2.0]}
    primitive_poses:
    - {position: {x: 0.0, y: 10.0, z: 0.0}}
    - {position: {x: 0.0, y: -10.0, z: 0.0}}
    operation: 0
"""
# Robowflex's form (positions as lists): post's origin to (25, 80), unturned: its boxes at (25, 90) and (25, 70).
MOVE_POST = """
is_diff: true
world:
  collision_objects:
  - {id: post, header: {frame_id: ''}, pose: {position: [25.0, 80.0, 0.0], orientation: [0, 0, 0, 1]}, operation: 3}
"""
ATTACH_ROD = """
is_diff: true
robot_state:
  is_diff: true
  attached_collision_objects:
  - link_name: link7
    touch_links: [link6]
    object:
      id: rod
      header: {frame_id: link7}
      pose: {position: {x: 1.0, y: 0.0, z: 0.0}}
      primitives: [{type: BOX, dimensions: [6.0, 1.0, 1.0]}]
      primitive_poses: [{position: {x: 2.0, y: 0.0, z: 0.0}}]
      operation: 0
"""
DETACH_ROD = """
is_diff: true
robot_state:
  attached_collision_objects:
  - {link_name: link7, object: {id: rod, operation: 1}}
world:
  collision_objects:
  - {id: rod, operation: 1}
"""


def _diff(tmp_path, text: str, name: str = "diff.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _free_at(oracle, *xys) -> list[bool]:
    out = []
    for xy in xys:
        q = oracle.scene.start.copy()
        q[:2] = xy
        out.append(bool(oracle.free(q)))
    return out


def test_a_diff_puts_objects_where_moveit_does_and_a_move_carries_an_objects_parts(oracles, tmp_path):
    base = oracles("bar")
    add = read_change_file(_diff(tmp_path, ADD_POST))
    assert add.describe() == "add post" and [s.name for s in add.add] == ["post_0", "post_1"]
    spots = [(15, 50), (35, 50), (25, 60), (25, 40), (25, 90), (25, 70)]
    assert _free_at(base, *spots) == [True] * 6
    added = changed_scene(base.scene, [add])
    assert _free_at(base.of_scene(added), *spots) == [False, False, True, True, True, True]
    # MOVE places the object's own pose: both boxes follow it (its turn undone too), as MoveIt moves them
    moved = changed_scene(added, [read_change_file(_diff(tmp_path, MOVE_POST))])
    assert _free_at(base.of_scene(moved), *spots) == [True, True, True, True, False, False]
    gone = changed_scene(moved, [read_change_file(_diff(tmp_path, ADD_POST.replace("operation: 0", "operation: 1")))])
    assert _free_at(base.of_scene(gone), *spots) == [True] * 6


def test_a_moveit_attach_is_the_payload_our_change_makes_and_a_detach_puts_it_down(oracles, tmp_path):
    base = oracles("bar")
    attach = read_change_file(_diff(tmp_path, ATTACH_ROD))
    ours = CellChange(
        attach=[
            Attachment(name="rod", link="link7", box=[6.0, 1.0, 1.0], pose=Placement(xyz=[3, 0, 0]), touch=["link6"])
        ]
    )
    samples = base.space.uniform(np.random.default_rng(0), 300)
    by_diff = base.of_scene(changed_scene(base.scene, [attach]))
    by_ours = base.of_scene(changed_scene(base.scene, [ours]))
    carried, plain = by_diff.context().are_free(samples), base.context().are_free(samples)
    assert (carried == by_ours.context().are_free(samples)).all()
    assert (plain & ~carried).any()  # the rod collides where the bare arm does not
    detach = read_change_file(_diff(tmp_path, DETACH_ROD))
    assert detach == CellChange(detach=["rod"])  # put down and taken away: it leaves the cell
    put_down = base.of_scene(changed_scene(base.scene, [attach, detach]))
    assert (put_down.context().are_free(samples) == plain).all()


def test_our_change_files_still_read_as_ours(tmp_path):
    path = _diff(tmp_path, "remove: [box0]\n", "change.yaml")
    assert read_change_file(path) == CellChange(remove=["box0"])


@pytest.mark.parametrize(
    "text, message",
    [
        (ADD_POST.replace("is_diff: true", "is_diff: false"), "a full planning scene"),
        ("is_diff: true\nworld: {octomap: {octomap: {data: [1, 2]}}}\n", "octomaps are not supported"),
        ("is_diff: true\nallowed_collision_matrix: {entry_names: [a]}\n", "allowed-collision matrix"),
        (ADD_POST.replace("    operation: 0", "    meshes: [{}]\n    operation: 0"), "meshes are not supported"),
        (ADD_POST.replace("operation: 0", "operation: 2"), "APPEND"),
        (MOVE_POST.replace("operation: 3", "operation: 3, primitives: [{type: 2, dimensions: [1]}]"), "MOVE gives"),
        (
            ADD_POST.replace("type: 1, dimensions: [4.0, 4.0, 2.0]}\n    - ", "type: 4, dimensions: [1, 1]}\n    - "),
            "type 4",
        ),
        (ADD_POST.replace("[4.0, 4.0, 2.0]}\n    primitive_poses", "[4.0]}\n    primitive_poses"), "needs 3 dim"),
        (ADD_POST + MOVE_POST.split("collision_objects:")[1], "named twice"),
        (ATTACH_ROD.replace("frame_id: link7", "frame_id: world"), "give its pose in the frame of its link"),
        (ATTACH_ROD.replace("primitives: [{type: BOX", "meshless: [{type: BOX"), "attaching a world object by id"),
        (DETACH_ROD.split("world:")[0], "leaves a detached object in the world"),
    ],
)
def test_what_a_diff_asks_that_the_cell_cannot_honour_is_one_line(tmp_path, text, message):
    with pytest.raises(UserError, match=message) as refused:
        read_change_file(_diff(tmp_path, text))
    assert "\n" not in str(refused.value)


def test_roadmap_update_repairs_for_a_diff_and_a_bad_one_writes_nothing(cli, one_line_error, oracles, tmp_path):
    path, out = tmp_path / "bar.npz", tmp_path / "repaired.npz"
    CellRoadmap.build(oracles("bar"), BuildSettings(nodes=150, seed=0)).save(path)
    updated = cli("roadmap", "update", path, "--change", _diff(tmp_path, ADD_POST), "--out", out, "--json")
    assert updated.returncode == 0, updated.stderr
    repair = json.loads(updated.stdout)["repair"]
    assert repair["described"] == "add post" and repair["edges_reset"] > 0
    again = cli("roadmap", "update", out, "--change", _diff(tmp_path, MOVE_POST, "move.yaml"), "--json")
    assert again.returncode == 0 and json.loads(again.stdout)["repair"]["described"] == "move post"
    bad = tmp_path / "bad.npz"
    moved_ghost = MOVE_POST.replace("id: post", "id: ghost")
    error = one_line_error(cli("roadmap", "update", path, "--change", _diff(tmp_path, moved_ghost), "--out", bad), 2)
    assert "cannot move 'ghost'" in error and not bad.exists()
