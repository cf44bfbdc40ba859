"""Which of a robot's own link pairs are checked: adjacent links are not, also across a link without collision
geometry between them (as MoveIt's Setup Assistant has it), and a start refused over two links that touch says how
to leave their pair out."""

import pytest

from app.errors import InvalidEndpoint
from app.scene.custom import CustomSpec, build_scene
from app.scene.model import Scene, scene_names

INERTIAL = '<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'


def _link(name: str, box: str = "0.1 0.1 0.5", xyz: str = "0 0 0.25") -> str:
    if box is None:
        return f'  <link name="{name}">{INERTIAL}</link>'
    geometry = f'<collision><origin xyz="{xyz}"/><geometry><box size="{box}"/></geometry></collision>'
    return f'  <link name="{name}">{INERTIAL}{geometry}</link>'


def _joint(name: str, kind: str, parent: str, child: str, xyz: str = "0 0 0.5") -> str:
    limit = '<axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/>' if kind == "revolute" else ""
    return (
        f'  <joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}"/>{limit}</joint>'
    )


def _urdf(path, *elements: str):
    path.write_text("\n".join(['<?xml version="1.0"?>', '<robot name="chain">', *elements, "</robot>", ""]))
    return path


@pytest.fixture(autouse=True)
def _cache(tmp_path, monkeypatch):
    """The scenes' generated files go to the test's own cache, for the commands too."""
    monkeypatch.setenv("NPP_CACHE_DIR", str(tmp_path / "cache"))


def _scene(tmp_path, robot, **keys):
    return build_scene(CustomSpec(robot=str(robot), **keys), cache_dir=tmp_path / "cache", progress=False)


@pytest.fixture
def virtual_link_chain(tmp_path):
    """link_a -> (fixed) virtual_link, which has no collision geometry -> (revolute) link_b: the two boxes meet face
    to face at the joint, in every configuration."""
    return _urdf(
        tmp_path / "chain.urdf",
        _link("link_a"),
        _link("virtual_link", box=None),
        _link("link_b"),
        _joint("a_to_virtual", "fixed", "link_a", "virtual_link"),
        _joint("elbow", "revolute", "virtual_link", "link_b", xyz="0 0 0"),
    )


def test_links_meeting_across_a_link_without_geometry_are_adjacent(tmp_path, virtual_link_chain, cli):
    from app.checking.oracle import CollisionOracle
    from app.planning.query import plan
    from app.planning.settings import PlanSettings

    scene = _scene(tmp_path, virtual_link_chain, start=[0.0], goal=[1.0])
    assert scene.adjacent_pairs == [("link_a", "link_b")]
    oracle = CollisionOracle(scene)
    result = plan(oracle, PlanSettings(seed=0))  # refused as "in collision" when the pair was checked
    assert result.certified
    assert scene.self_collisions
    result = cli("plan", "--robot", virtual_link_chain, "--start", "0", "--goal", "1")
    assert result.returncode == 0, result.stderr
    assert "1 adjacent across links without collision geometry: link_a-link_b" in result.stdout


def test_the_neighbours_of_a_link_without_geometry_are_all_adjacent_and_nothing_else_is(tmp_path):
    """A palm without geometry between an arm and two fingers: arm and fingers, and the fingers with each other, are
    adjacent (MoveIt joins every neighbour of such a link); the tip beyond a finger with geometry is not."""
    from app.scene.build import adjacent_bodies

    robot = _urdf(
        tmp_path / "hand.urdf",
        _link("arm"),
        _link("palm", box=None),
        _link("left", box="0.02 0.02 0.1", xyz="0 0.05 0.05"),
        _link("right", box="0.02 0.02 0.1", xyz="0 -0.05 0.05"),
        _link("tip", box="0.02 0.02 0.05", xyz="0 0.05 0.025"),
        _joint("wrist", "revolute", "arm", "palm"),
        _joint("left_finger", "revolute", "palm", "left", xyz="0 0 0"),
        _joint("right_finger", "revolute", "palm", "right", xyz="0 0 0"),
        _joint("left_tip", "revolute", "left", "tip", xyz="0 0 0.1"),
    )
    scene = _scene(tmp_path, robot, collisions="environment")
    plant = scene.plant
    instances = scene.robot_instances
    pairs = {frozenset((a.name(), b.name())) for a, b in adjacent_bodies(plant, instances)}
    assert pairs == {frozenset(p) for p in [("arm", "left"), ("arm", "right"), ("left", "right"), ("left", "tip")]}


def test_links_that_touch_across_a_link_with_geometry_are_checked_and_the_refusal_says_how_to_leave_them_out(
    tmp_path, cli, one_line_error
):
    """link_a -> (revolute) link_b, whose box is beside the chain -> (fixed) link_c, resting on link_a's top face:
    link_b has geometry, so link_a and link_c are not adjacent and their contact refuses the start."""
    robot = _urdf(
        tmp_path / "rest.urdf",
        _link("link_a"),
        _link("link_b", box="0.1 0.1 0.1", xyz="0.3 0 0"),
        _link("link_c"),
        _joint("elbow", "revolute", "link_a", "link_b"),
        _joint("b_to_c", "fixed", "link_b", "link_c", xyz="0 0 0"),
    )
    assert _scene(tmp_path, robot).adjacent_pairs == []
    line = one_line_error(cli("plan", "--robot", robot, "--start", "0", "--goal", "1"), 3)
    assert "link_a with robot::link_c" in line
    assert '--srdf FILE holding <disable_collisions link1="link_a" link2="link_c"/>' in line
    assert "--no-self-collision" in line

    srdf = tmp_path / "rest.srdf"
    srdf.write_text('<robot name="chain"><disable_collisions link1="link_a" link2="link_c" reason="User"/></robot>\n')
    for flag in (["--srdf", srdf], ["--no-self-collision"]):
        result = cli("plan", "--robot", robot, "--start", "0", "--goal", "1", *flag)
        assert result.returncode == 0, result.stderr


def test_a_start_refused_over_the_environment_names_no_self_collision_flags(tmp_path):
    from app.checking.oracle import CollisionOracle
    from app.planning.query import plan
    from app.planning.settings import PlanSettings

    robot = _urdf(
        tmp_path / "one.urdf", _link("link_a"), _link("link_b"), _joint("elbow", "revolute", "link_a", "link_b")
    )
    post = tmp_path / "post.sdf"
    post.write_text(
        '<?xml version="1.0"?><sdf version="1.7"><model name="post"><static>true</static><link name="post">'
        '<pose>0 0 0.75 0 0 0</pose><collision name="c"><geometry><box><size>0.1 0.1 0.1</size></box></geometry>'
        "</collision></link></model></sdf>\n"
    )
    oracle = CollisionOracle(_scene(tmp_path, robot, env=[str(post)], start=[0.0], goal=[1.0]))
    with pytest.raises(InvalidEndpoint) as refused:
        plan(oracle, PlanSettings(seed=0))
    assert "post" in str(refused.value) and "--srdf" not in str(refused.value)


@pytest.mark.parametrize("name", scene_names())
def test_the_shipped_robots_have_no_pair_adjacent_across_a_link_without_geometry_that_drake_checks(name):
    """The UR3's tool0 sits between wrist_3_link and the torch, all welded: Drake leaves that pair out already. No
    shipped scene checks another pair because of the rule."""
    assert Scene(name).adjacent_pairs == []
