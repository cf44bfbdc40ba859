"""The PNG pictures (app.draw): what is in front is drawn in front, and every colour is named in a legend."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from mpl_toolkits.mplot3d import proj3d  # noqa: E402

from app.draw import _BOX_FACES, Faces3D, Picture, draw_samples, draw_scene  # noqa: E402


def box_faces(lo, hi) -> list[np.ndarray]:
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return [corners[f] for f in _BOX_FACES]


def test_a_wall_hides_the_box_behind_it_though_another_part_of_the_box_is_nearer(tmp_path):
    """Seen from +x, an opaque blue wall at x = 1 stands in front of a small red box at the origin; a second red
    box, part of the same solid, stands beside the wall and nearer the camera. Matplotlib orders whole collections
    by their nearest point: with one collection per solid the red one came out on top, the box showing through
    the wall. The pixel where the box projects must be the wall's blue."""
    fig = plt.figure(figsize=(4, 4))
    ax = fig.add_subplot(projection="3d")
    ax.view_init(elev=0, azim=0)
    ax.set(xlim=(-2, 2), ylim=(-2, 2), zlim=(-2, 2))
    faces = Faces3D(tile=0.5, elev=0, azim=0)
    blue, red = (0.0, 0.0, 1.0, 1.0), (1.0, 0.0, 0.0, 1.0)
    for polygon in box_faces((-0.2, -0.2, -0.2), (0.2, 0.2, 0.2)) + box_faces((1.5, 1.4, -0.1), (1.8, 1.7, 0.1)):
        faces.face(polygon, red)
    for polygon in box_faces((0.9, -1.0, -1.0), (1.0, 1.0, 1.0)):
        faces.face(polygon, blue)
    faces.draw(ax)
    png = tmp_path / "depth.png"
    fig.canvas.draw()
    x, y, _ = proj3d.proj_transform(0.0, 0.0, 0.0, ax.get_proj())
    column, row = ax.transData.transform((x, y))
    fig.savefig(png, dpi=fig.dpi)
    plt.close(fig)

    from PIL import Image

    image = np.asarray(Image.open(png).convert("RGB"), float) / 255
    pixel = image[image.shape[0] - int(round(row)), int(round(column))]
    assert pixel[2] > 0.5 and pixel[0] < 0.3, f"at the box's place the picture is {pixel}, not the wall's blue"


def test_points_are_ordered_with_the_faces(tmp_path):
    """A point behind an opaque face is hidden by it; one in front of it shows."""
    fig = plt.figure(figsize=(4, 4))
    ax = fig.add_subplot(projection="3d")
    ax.view_init(elev=0, azim=0)
    ax.set(xlim=(-2, 2), ylim=(-2, 2), zlim=(-2, 2))
    faces = Faces3D(tile=2.0, elev=0, azim=0)
    faces.squares(np.array([[-1.0, -0.8, 0.0], [1.0, 0.8, 0.0]]), (1.0, 0.0, 0.0, 1.0))
    faces.face(np.array([[0.0, -1.5, -1.5], [0.0, 1.5, -1.5], [0.0, 1.5, 1.5], [0.0, -1.5, 1.5]]), (0, 0, 1.0, 1))
    faces.draw(ax)
    fig.canvas.draw()
    pixels = []
    for point in ([-1.0, -0.8, 0.0], [1.0, 0.8, 0.0]):
        x, y, _ = proj3d.proj_transform(*point, ax.get_proj())
        pixels.append(ax.transData.transform((x, y)))
    png = tmp_path / "points.png"
    fig.savefig(png, dpi=fig.dpi)
    plt.close(fig)

    from PIL import Image

    image = np.asarray(Image.open(png).convert("RGB"), float) / 255
    behind, in_front = (image[image.shape[0] - int(round(r)), int(round(c))] for c, r in pixels)
    assert behind[2] > 0.5 and behind[0] < 0.3, behind
    assert in_front[0] > 0.7 and in_front[2] < 0.3, in_front


def legend_labels(png_maker, monkeypatch) -> list[str]:
    """The legend entries of the picture `png_maker` draws (caught as it is saved)."""
    seen = []
    monkeypatch.setattr("app.draw.save", lambda fig, path: seen.append(fig) or plt.close(fig))
    png_maker()
    (fig,) = seen
    legend = fig.axes[0].get_legend()
    return [text.get_text() for text in legend.get_texts()]


@pytest.mark.parametrize("scene", ["bar", "joint3d"])
def test_scene_pictures_name_every_colour(scene, oracles, monkeypatch):
    oracle = oracles(scene)
    labels = legend_labels(lambda: draw_scene(oracle, "unused.png"), monkeypatch)
    assert labels == ["obstacle", "passage region", "robot at start", "robot at goal"]


@pytest.mark.parametrize(
    "scene, points", [("bar", ["tracked frame"]), ("joint3d", ["sample (tracked frame)", "sample in passage"])]
)
def test_sample_pictures_name_every_colour(scene, points, oracles, monkeypatch):
    """Uniform samples and, in 3D, one with the tracked frame in the passage (the start moved into it)."""
    oracle = oracles(scene)
    samples = oracle.space.uniform(np.random.default_rng(0), 6)
    if oracle.scene.problem.view == "3d":
        lo, hi = oracle.scene.passage_boxes[0]
        through = oracle.scene.start.copy()
        through[:3] += (lo + hi) / 2 - oracle.workspace.frame_positions(through)[0]  # joint3d: x, y, z come first
        assert oracle.workspace.in_passage(through)[0]
        samples = np.vstack([samples, through])
    labels = legend_labels(lambda: draw_samples(oracle, samples, "unused.png"), monkeypatch)
    assert labels[:3] == ["obstacle", "passage region", "robot at a sample"]
    assert [label for label in labels[3:] if label != "robot at a sample in passage"] == points


def test_a_robot_part_that_does_not_move_is_drawn_once(oracles):
    """The window scene's cart stays put between start and goal: drawn twice in one place it was a checkerboard."""
    oracle = oracles("window")
    picture = Picture(oracle)
    picture.add_robot(oracle.scene.start, "tab:blue", 0.9, "robot at start")
    at_start = picture.solids.count("robot at start")
    picture.add_robot(oracle.scene.goal, "tab:green", 0.9, "robot at goal", unmoved_from=oracle.scene.start)
    at_goal = picture.solids.count("robot at goal")
    assert 0 < at_goal < at_start
    plt.close(picture.fig)


def test_an_arms_samples_are_lines_from_its_base_to_its_tool(oracles, monkeypatch):
    """Thirty faint copies of an arm were one blob: each sample is a line through its links' origins instead, from
    the arm's base (not the cart under it) to the tracked frame, over one arm at the start."""
    oracle = oracles("window")
    samples = oracle.space.uniform(np.random.default_rng(0), 5)
    lines = []
    monkeypatch.setattr(Picture, "add_line", lambda self, P, colour, label, width=1.5: lines.append(P))
    labels = legend_labels(lambda: draw_samples(oracle, samples, "unused.png"), monkeypatch)
    assert "robot at a sample" not in labels and "robot at start" in labels
    assert len(lines) == len(samples)
    base = lines[0][0]
    for P, q in zip(lines, samples):
        assert np.allclose(P[0], base)  # every line starts where the arm stands
        assert np.allclose(P[-1], oracle.workspace.frame_positions(q)[0])
        assert len(P) >= 6 and len({tuple(np.round(p, 6)) for p in P}) >= 4  # through the links, not a point


def test_a_flat_scenes_axis_labels_do_not_overlap(oracles):
    """The maze is 20 x 20 x 3 m: its short z axis once carried seven labels on top of each other. Consecutive z
    labels are now further apart on the picture than a label is high."""
    picture = Picture(oracles("maze"))
    ax = picture.ax
    picture.fig.canvas.draw()
    lo, hi = ax.get_zlim()
    ticks = [z for z in ax.get_zticks() if lo - 1e-9 <= z <= hi + 1e-9]
    corner = np.full(len(ticks), ax.get_xlim()[0]), np.full(len(ticks), ax.get_ylim()[0])
    x, y, _ = proj3d.proj_transform(*corner, np.array(ticks), ax.get_proj())
    gaps = np.linalg.norm(np.diff(ax.transData.transform(np.c_[x, y]), axis=0), axis=1)
    label_height = ax.zaxis.get_ticklabels()[0].get_fontsize() * picture.fig.dpi / 72
    assert len(ticks) >= 2 and gaps.min() > 1.2 * label_height, (ticks, gaps, label_height)
    plt.close(picture.fig)


def test_a_lines_width_stays_with_it_when_the_faces_are_sorted_by_depth():
    """Matplotlib sorts a collection's polygons by depth and reorders their colours, not their line widths: a
    segment then drew with a face's width 0 (gone) or an outline's. Each drawn segment keeps its own width."""
    fig = plt.figure(figsize=(4, 4))
    ax = fig.add_subplot(projection="3d")
    ax.view_init(elev=0, azim=0)
    ax.set(xlim=(-2, 2), ylim=(-2, 2), zlim=(-2, 2))
    faces = Faces3D(tile=0.5, elev=0, azim=0)
    faces.face(np.array([[0.0, -1.5, -1.5], [0.0, 1.5, -1.5], [0.0, 1.5, 1.5], [0.0, -1.5, 1.5]]), (0, 0, 1.0, 1))
    faces.line(np.array([[1.0, -1.0, 0.5], [-1.0, 1.0, 0.5]]), (1.0, 0.0, 0.0, 1.0), 2.5)  # through the face
    faces.draw(ax)
    fig.canvas.draw()
    (collection,) = ax.collections
    edges, widths = collection.get_edgecolor(), collection.get_linewidth()
    plt.close(fig)
    red = edges[:, 0] > 0.5
    assert red.sum() > 1 and np.all(widths[red] == 2.5) and np.all(widths[~red] == 0.0)


def test_a_custom_scenes_picture_holds_every_shape_whole(tmp_path):
    """A fixed arm with a 1 m cylinder link along x and a sphere of radius 0.3 centred at y = 1: the axes once held
    where each shape's frame was, cropping the arm to its link's middle and the sphere to its centre."""
    from app.checking.oracle import CollisionOracle
    from app.scene.custom import CustomSpec, build_scene

    inertial = '<inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>'
    (tmp_path / "arm.urdf").write_text(
        f'<robot name="arm"><link name="base">{inertial}</link><link name="arm">{inertial}<collision>'
        '<origin xyz="0.5 0 0" rpy="0 1.5707963 0"/><geometry><cylinder radius="0.05" length="1"/></geometry>'
        '</collision></link><joint name="j" type="revolute"><parent link="base"/><child link="arm"/>'
        '<axis xyz="0 0 1"/><limit lower="-0.1" upper="0.1" effort="1" velocity="1"/></joint></robot>\n'
    )
    (tmp_path / "ball.sdf").write_text(
        '<?xml version="1.0"?><sdf version="1.7"><model name="ball"><static>true</static><link name="ball">'
        '<pose>0 1 0 0 0 0</pose><collision name="c"><geometry><sphere><radius>0.3</radius></sphere></geometry>'
        "</collision></link></model></sdf>\n"
    )
    spec = CustomSpec(robot=str(tmp_path / "arm.urdf"), env=[str(tmp_path / "ball.sdf")], start=[0.0], goal=[0.0])
    picture = Picture(CollisionOracle(build_scene(spec, cache_dir=tmp_path / "cache", progress=False)))
    (x0, x1), (y0, y1), (z0, z1) = picture.ax.get_xlim(), picture.ax.get_ylim(), picture.ax.get_zlim()
    plt.close(picture.fig)
    assert x1 >= 1.0 - 1e-6 and y1 >= 1.3 - 1e-6 and z0 <= -0.3 + 1e-6 and z1 >= 0.3 - 1e-6
    assert x0 <= -0.3 + 1e-6 and y0 <= -0.05 + 1e-6  # the sphere's side, the cylinder's


def test_a_sample_picture_holds_every_sample_and_draws_the_obstacles_faintly(oracles, monkeypatch):
    """The window's enclosure, drawn as a grey cloud, covered the samples among it, and samples beyond the scene's
    box fell outside the axes: the obstacles are outlines over a faint fill, and the axes hold every sample."""
    oracle = oracles("window")
    samples = oracle.space.uniform(np.random.default_rng(0), 10)
    seen = []
    monkeypatch.setattr("app.draw.save", lambda fig, path: seen.append(fig))
    draw_samples(oracle, samples, "unused.png")
    (fig,) = seen
    ax = fig.axes[0]
    limits = np.array([ax.get_xlim(), ax.get_ylim(), ax.get_zlim()])
    for p in oracle.workspace.frame_positions(samples):
        assert np.all(limits[:, 0] <= p + 1e-9) and np.all(p <= limits[:, 1] + 1e-9), (p, limits)
    fig.canvas.draw()
    (collection,) = ax.collections
    alphas = collection.get_facecolor()[:, 3]
    plt.close(fig)
    assert np.isclose(alphas, 0.05).any() and not np.isclose(alphas, 0.25).any()  # a scene picture's obstacles: 0.25
