"""A changing cell (app.scene.changes) and the roadmap repaired for it (app.planning.repair, CellRoadmap.changed):
changes as data put objects where they say; a repair keeps only verdicts the new cell confirms, resets few where
the change is local, and a repaired roadmap saved and loaded belongs to the new cell, not the old."""

import json

import numpy as np
import pytest

from app.checking.budget import Budget
from app.errors import InvalidEndpoint, UserError
from app.planning.cell import BuildSettings, CellRoadmap
from app.planning.settings import PlanSettings
from app.scene.changes import Attachment, CellChange, Move, Placement, Solid, change_from_dict, changed_scene

QUERY = PlanSettings(seed=0, budget=Budget(checks=200_000))
# bar: a wall x in [45, 55] of two boxes, box0 (y 0..46) and box1 (y 54..100), 2 thick in z; the arm's base moves in
# x, y at z = 0.
MOVE_BOX1 = CellChange(move=[Move(name="box1", pose=Placement(xyz=[0.0, 3.0, 0.0]), by=True)])
ADD_POST = CellChange(add=[Solid(name="post", box=[4.0, 4.0, 2.0], pose=Placement(xyz=[25.0, 50.0, 0.0]))])
REMOVE_BOX0 = CellChange(remove=["box0"])
CARRY = CellChange(attach=[Attachment(name="rod", link="link7", box=[6.0, 1.0, 1.0], pose=Placement(xyz=[3, 0, 0]))])


@pytest.fixture(scope="module")
def bar_cell(oracles):
    return CellRoadmap.build(oracles("bar"), BuildSettings(nodes=250, seed=0))


def _free_edges(cell) -> np.ndarray:
    arrays = cell.graph.arrays()
    return arrays["ends"][arrays["alive"] & arrays["checked"]]


def _dead_edges(cell) -> np.ndarray:
    arrays = cell.graph.arrays()
    return arrays["ends"][~arrays["alive"]]


# ---- changes as data ----------------------------------------------------------------------------------------------
def test_objects_are_where_a_change_puts_them(oracles):
    base = oracles("bar")
    q = base.scene.start.copy()
    q[:2] = [50.0, 20.0]  # the base inside box0
    assert not base.free(q)
    removed = base.of_scene(changed_scene(base.scene, [REMOVE_BOX0]))
    assert removed.free(q)
    post = base.scene.start.copy()
    post[:2] = [25.0, 50.0]
    assert base.free(post)
    added = base.of_scene(changed_scene(base.scene, [ADD_POST]))
    assert not added.free(post)
    # a move by 3 in y: the gap's upper edge rises from 54 to 57
    in_gap = base.scene.start.copy()
    in_gap[:3] = [50.0, 55.5, 0.0]  # the arm along x, through the wall
    moved = base.of_scene(changed_scene(base.scene, [MOVE_BOX1]))
    assert not base.free(in_gap) and moved.free(in_gap)
    # the changed cell keeps its scene's name, and changes of a changed cell add to the ones it had
    both = changed_scene(changed_scene(base.scene, [REMOVE_BOX0]), [ADD_POST])
    assert both.name == "bar" and both.changes == [REMOVE_BOX0, ADD_POST]
    assert not base.of_scene(both).free(post) and base.of_scene(both).free(q)


def test_a_change_reads_from_yaml_and_round_trips_as_data(tmp_path):
    from app.scene.changes import read_change

    path = tmp_path / "change.yaml"
    path.write_text(
        "move:\n- {name: fixture, pose: {xyz: [0.05, 0, 0]}, by: true}\n"
        "add:\n- {name: crate, box: [0.1, 0.1, 0.1], pose: {xyz: [0, 0, 0.25], relative_to: side_table}}\n"
        "attach:\n- {name: part, link: tcp, cylinder: [0.02, 0.1], touch: [torch]}\n"
    )
    change = read_change(path)
    assert change.describe() == "move fixture; add crate; attach part"
    assert change_from_dict(json.loads(json.dumps(change.to_dict()))) == change


@pytest.mark.parametrize(
    "change, message",
    [
        (CellChange(remove=["nothing"]), r"cannot remove 'nothing': no such object in the cell \(objects: box0, box1"),
        (CellChange(detach=["rod"]), "the robot carries no such object"),
        (CellChange(add=[Solid(name="box0", box=[1, 1, 1])]), "already has something of that name"),
        (CellChange(add=[Solid(name="two", box=[1, 1, 1], sphere=[1])]), "exactly one of box, sphere"),
        (CellChange(add=[Solid(name="flat", box=[1, 0, 1])]), "box needs 3 positive size"),
        (CellChange(add=[Solid(name="x", sphere=[1], pose=Placement(relative_to="ghost"))]), "no such object"),
        (CellChange(attach=[Attachment(name="r", link="wing", sphere=[1])]), "no link or frame 'wing'"),
        (CellChange(attach=[Attachment(name="r", link="link7", sphere=[1], touch=["tail"])]), "no link of the robot"),
    ],
)
def test_a_change_that_cannot_be_applied_is_one_clear_line(oracles, change, message):
    with pytest.raises(UserError, match=message) as refused:
        changed_scene(oracles("bar").scene, [change])
    assert "\n" not in str(refused.value)


# ---- repair -------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("change", [MOVE_BOX1, ADD_POST, REMOVE_BOX0, CARRY], ids=["move", "add", "remove", "attach"])
def test_a_repair_keeps_only_verdicts_the_new_cell_confirms(bar_cell, change):
    repaired = bar_cell.changed([change])
    checker = repaired.oracle.context()
    graph = repaired.graph
    assert checker.are_free(graph.Q).all()  # every node left is free in the new cell
    free, dead = _free_edges(repaired), _dead_edges(repaired)
    assert len(free) and checker.edges_free(graph.Q[free[:, 0]], graph.Q[free[:, 1]], graph.resolution).all()
    if len(dead):  # an edge still known to collide collides in the new cell too
        assert not checker.edges_free(graph.Q[dead[:, 0]], graph.Q[dead[:, 1]], graph.resolution).any()
    record = repaired.provenance["changes"][-1]
    assert record["change"] == [change.to_dict()] and record["described"] == change.describe()
    # A change of one obstacle touches few verdicts; the one before stays as it was.
    before = len(_free_edges(bar_cell))
    if change is not CARRY:
        assert 0 < record["edges_reset"] + record["colliding_reset"] < before / 2
    assert len(_free_edges(bar_cell)) == before and bar_cell.oracle.scene.name == "bar"


@pytest.mark.parametrize("change", [ADD_POST, REMOVE_BOX0, CARRY], ids=["add", "remove", "attach"])
def test_a_repair_asked_in_blocks_over_threads_resets_what_one_block_resets(bar_cell, change, monkeypatch):
    import app.planning.repair as repair

    whole = bar_cell.changed([change]).graph.arrays()
    monkeypatch.setattr(repair, "BLOCK", 7)  # many blocks per round, spread over the oracle's threads
    blocks = bar_cell.changed([change]).graph.arrays()
    assert whole.keys() == blocks.keys() and all(np.array_equal(whole[k], blocks[k]) for k in whole)


def test_a_repaired_roadmap_answers_certified_in_the_new_cell(bar_cell):
    repaired = bar_cell.changed([REMOVE_BOX0])
    result = repaired.solve(settings=QUERY)
    assert result.trajectory.certified
    checker = repaired.oracle.context()
    assert checker.are_free(checker.space.wrap(result.trajectory.positions)).all()


def test_a_repaired_roadmap_refuses_the_old_cell_and_opens_in_the_new(bar_cell, oracles, tmp_path):
    path = tmp_path / "bar.npz"
    repaired = bar_cell.changed([MOVE_BOX1]).changed([ADD_POST])
    repaired.save(path)
    base = oracles("bar")
    with pytest.raises(UserError, match="its environment.* differ.*roadmap update --change"):
        CellRoadmap.load(path, base)
    opened = CellRoadmap.open(path, base)  # the base cell, with the changes the file records
    assert opened.oracle.scene.changes == [MOVE_BOX1, ADD_POST]
    assert opened.info()["edges"] == repaired.info()["edges"]
    # a change on top repairs again from the cell the file was last repaired for
    again = CellRoadmap.open(path, base, [REMOVE_BOX0])
    assert again.oracle.scene.changes == [MOVE_BOX1, ADD_POST, REMOVE_BOX0]
    assert [r["described"] for r in again.provenance["changes"]] == ["move box1", "add post", "remove box0"]


def test_a_change_that_puts_something_where_the_robot_starts_is_refused(bar_cell):
    start = bar_cell.oracle.scene.start
    over = CellChange(add=[Solid(name="lid", box=[6.0, 6.0, 2.0], pose=Placement(xyz=[*start[:2], 0.0]))])
    with pytest.raises(InvalidEndpoint, match="start is in collision") as refused:
        bar_cell.changed([over])
    assert refused.value.code == "START_STATE_IN_COLLISION"


def test_a_payload_is_checked_against_the_cell_and_the_arm_but_not_the_links_it_may_touch(oracles):
    """On the UR3 (self-collision counts): a rod held at the tool meets the enclosure and, at some postures, the
    cart and the arm; allowed to touch those links, it meets only the enclosure."""
    window = oracles("window")
    rng = np.random.default_rng(0)
    Q = window.space.uniform(rng, 400)
    Q = Q[window.context().are_free(Q)]

    def held(touch):
        rod = Attachment(name="rod", link="tcp", cylinder=[0.02, 0.4], pose=Placement(xyz=[0, 0, 0.1]), touch=touch)
        oracle = window.of_scene(changed_scene(window.scene, [CellChange(attach=[rod])]))
        free = oracle.context().are_free(Q)
        return free, {pair for q in Q[~free] for pair in oracle.diagnostics.colliding_bodies(q)}

    free, pairs = held([])
    assert {("obstacles::obstacles", "rod::rod"), ("rod::rod", "ur3::cart")} <= pairs
    touching, pairs = held(["cart", "upper_arm_link"])
    assert pairs == {("obstacles::obstacles", "rod::rod")} and touching.sum() > free.sum() and (touching >= free).all()


# ---- the command line ---------------------------------------------------------------------------------------------
def test_roadmap_update_info_and_plan_on_the_repaired_roadmap(cli, tmp_path, bar_cell):
    path, out, change = tmp_path / "bar.npz", tmp_path / "repaired.npz", tmp_path / "change.yaml"
    bar_cell.save(path)
    change.write_text("remove: [box0]\n")
    updated = cli("roadmap", "update", path, "--change", change, "--out", out, "--json")
    assert updated.returncode == 0, updated.stderr
    answer = json.loads(updated.stdout)
    assert answer["repair"]["described"] == "remove box0" and answer["repair"]["colliding_reset"] > 0
    assert "changed   remove box0:" in cli("roadmap", "info", out).stdout
    planned = cli("plan", "bar", "--roadmap", out, "--json")
    assert planned.returncode == 0, planned.stderr and json.loads(planned.stdout)["certified"]
    assert json.loads(planned.stdout)["changes"] == [REMOVE_BOX0.to_dict()]
    post = tmp_path / "post.yaml"
    post.write_text("add:\n- {name: post, box: [4.0, 4.0, 2.0], pose: {xyz: [25.0, 50.0, 0.0]}}\n")
    said = cli("plan", "bar", "--roadmap", out, "--change", post)
    assert said.returncode == 0, said.stderr
    assert "\n  changed   remove box0; add post\n" in said.stdout + "\n"  # the file's change, then --change
    # the repaired file refuses the old cell given as a scene file (its environment differs) -- and planning on the
    # old file with --change repairs it in memory
    assert cli("plan", "bar", "--roadmap", path, "--change", change, "--json").returncode == 0
    fresh = cli("plan", "bar", "--change", change, "--json")
    assert fresh.returncode == 0 and json.loads(fresh.stdout)["certified"]


def test_a_bad_change_file_is_one_line_and_writes_nothing(cli, one_line_error, tmp_path, bar_cell):
    path, out, change = tmp_path / "bar.npz", tmp_path / "repaired.npz", tmp_path / "change.yaml"
    bar_cell.save(path)
    change.write_text("remove: [box7]\n")
    assert "cannot remove 'box7'" in one_line_error(cli("roadmap", "update", path, "--change", change, "--out", out), 2)
    change.write_text("shift: [box0]\n")
    assert "bad change file" in one_line_error(cli("roadmap", "update", path, "--change", change, "--out", out), 2)
    start = bar_cell.oracle.scene.start
    change.write_text(f"add:\n- {{name: lid, box: [6, 6, 2], pose: {{xyz: [{start[0]}, {start[1]}, 0]}}}}\n")
    assert "start is in collision" in one_line_error(
        cli("roadmap", "update", path, "--change", change, "--out", out), 3
    )
    assert not out.exists()


def test_the_example_changes_apply_and_a_job_carries_its_part(cli, oracles):
    from app.scene.changes import read_change
    from app.scene.files import ROOT

    examples = sorted(p for p in (ROOT / "examples" / "changes").glob("*.yaml") if not p.stem.endswith("-payload"))
    assert examples
    window = oracles("window")
    for path in examples:
        changed = window.of_scene(changed_scene(window.scene, [read_change(path)]))
        assert changed.free(changed.scene.start)
    ran = cli("run", "window", "--change", ROOT / "examples" / "changes" / "window-part.yaml", "--json")
    assert ran.returncode == 0, ran.stderr
    assert len(json.loads(ran.stdout)["legs"]) == 5


def test_a_job_carries_its_payload_file_and_one_it_cannot_carry_is_one_line(cli, one_line_error, tmp_path):
    from app.scene.changes import read_payload
    from app.scene.files import ROOT

    torch = ROOT / "examples" / "changes" / "welding-torch-payload.yaml"
    cup = Attachment(name="gas_cup", link="torch", cylinder=[0.016, 0.035], pose=Placement(xyz=[0, 0, 0.14]))
    assert read_payload(torch) == CellChange(attach=[cup])
    ran = cli("run", "welding", "--payload", torch, "--json")
    assert ran.returncode == 0, ran.stderr
    assert len(json.loads(ran.stdout)["legs"]) == 5
    # the payload is in the job's cell: with a 30 cm ball on the wire tip no pose of the job is free
    ball = tmp_path / "ball.yaml"
    ball.write_text("{name: ball, link: tcp, sphere: [0.3]}\n")
    assert "cannot be reached collision-free" in one_line_error(cli("run", "welding", "--payload", ball), 3)
    ball.write_text("attach:\n- {name: ball, link: tcp, sphere: [0.3]}\n")  # a change file is no payload file
    assert "bad payload file" in one_line_error(cli("run", "welding", "--payload", ball), 2)


def test_an_object_moved_is_gone_by_either_of_its_names_and_a_move_says_where_it_is(oracles):
    from app.scene.changes import obstacle_names

    base = oracles("window")
    moved = changed_scene(
        base.scene, [CellChange(move=[Move(name="fixture", pose=Placement(xyz=[0, 0.05, 0]), by=True)])]
    )
    assert "fixture" in obstacle_names(moved) and "obstacles::fixture" not in obstacle_names(moved)
    with pytest.raises(UserError, match="cannot remove 'obstacles::fixture'"):
        changed_scene(moved, [CellChange(remove=["obstacles::fixture"])])
    with pytest.raises(UserError, match="give it in the world"):
        changed_scene(
            base.scene, [CellChange(move=[Move(name="fixture", by=True, pose=Placement(relative_to="side_table"))])]
        )
    with pytest.raises(UserError, match="in its link's frame"):
        changed_scene(
            base.scene,
            [
                CellChange(
                    attach=[Attachment(name="p", link="tcp", sphere=[0.01], pose=Placement(relative_to="fixture"))]
                )
            ],
        )
