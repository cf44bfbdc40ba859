"""Matplotlib pictures of a scene, read from SceneGraph's collision shapes, so any scene draws without extra code.

2D scenes are drawn as a top view (x-y), 3D scenes on 3D axes. `scene_figure` draws obstacles and the passage
region; `draw_robot` adds the robot at a configuration; `save` writes the PNG atomically; `draw_scene` and
`draw_samples` are the whole pictures of `show` and `sample --png`.

pydrake's geometry types are imported in the functions that use them, as everywhere in the package: importing a
module stays cheap until Drake is needed.
"""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Circle, Polygon, Rectangle  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from app.io import write_atomically  # noqa: E402

_BOX_FACES = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]]


def _geometries(oracle, q, robot: bool):
    """(shape, world pose) of the robot's or the environment's collision geometries at configuration q."""
    from pydrake.geometry import Role

    query = oracle.query_object(q)
    inspector = query.inspector()
    for gid in inspector.GetAllGeometryIds(Role.kProximity):
        if oracle.is_robot_geometry(gid) == robot:
            yield inspector.GetShape(gid), query.GetPoseInWorld(gid)


def _box_corners(shape, pose) -> np.ndarray:
    half = np.array([shape.width(), shape.depth(), shape.height()]) / 2
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    return (pose.rotation().matrix() @ (signs * half).T).T + pose.translation()


def _round_faces(shape, pose, segments: int = 16) -> list[np.ndarray]:
    """Quads approximating a cylinder, sphere or capsule (all round about their z axis) in the world."""
    from pydrake.geometry import Cylinder, Sphere

    r = shape.radius()
    arc = np.linspace(-np.pi / 2, np.pi / 2, 7)
    if isinstance(shape, Cylinder):  # profile (radius, z) from the bottom centre to the top centre
        h = shape.length() / 2
        profile = [(0.0, -h), (r, -h), (r, h), (0.0, h)]
    elif isinstance(shape, Sphere):
        profile = list(zip(r * np.cos(arc), r * np.sin(arc)))
    else:  # capsule: two half spheres joined by a cylinder
        h = shape.length() / 2
        profile = [(r * np.cos(a), -h + r * np.sin(a)) for a in arc[:4]] + [
            (r * np.cos(a), h + r * np.sin(a)) for a in arc[3:]
        ]
    theta = np.linspace(0, 2 * np.pi, segments + 1)
    rings = np.array([[(rho * np.cos(t), rho * np.sin(t), z) for t in theta] for rho, z in profile])
    world = rings @ pose.rotation().matrix().T + pose.translation()
    return [
        np.array([world[i, j], world[i, j + 1], world[i + 1, j + 1], world[i + 1, j]])
        for i in range(len(profile) - 1)
        for j in range(segments)
    ]


def _top_view(ax, points: np.ndarray, **style) -> None:
    """A solid's outline seen from above: the hull of its points in x-y (a line for an upright flat piece)."""
    from scipy.spatial import ConvexHull, QhullError

    xy = points[:, :2]
    try:
        ax.add_patch(Polygon(xy[ConvexHull(xy).vertices], closed=True, **style))
    except QhullError:
        along = (xy - xy.mean(axis=0)) @ np.linalg.svd(xy - xy.mean(axis=0))[2][0]  # position on the line
        ends = xy[[np.argmin(along), np.argmax(along)]]
        ax.plot(*ends.T, color=style.get("edgecolor", "k"))


def _draw_shape(ax, shape, pose, three_d: bool, **style):
    from pydrake.geometry import Box, Capsule, Convex, Cylinder, Mesh, Sphere

    if isinstance(shape, Box):
        corners = _box_corners(shape, pose)
        if three_d:
            ax.add_collection3d(Poly3DCollection([corners[f] for f in _BOX_FACES], **style))
        else:
            _top_view(ax, corners, **style)
    elif isinstance(shape, (Cylinder, Sphere, Capsule)) and not three_d:
        ax.add_patch(Circle(pose.translation()[:2], shape.radius(), **style))
    elif isinstance(shape, (Cylinder, Sphere, Capsule)):
        ax.add_collection3d(Poly3DCollection(_round_faces(shape, pose), **style))
    elif isinstance(shape, (Convex, Mesh)):  # what Drake collides with: the convex hull (custom scenes' pieces)
        hull = shape.GetConvexHull()
        points = np.array([hull.vertex(i) for i in range(hull.num_vertices())])  # scaled already
        world = points @ pose.rotation().matrix().T + pose.translation()
        if three_d:
            faces = [
                world[[face.vertex(j) for j in range(face.num_vertices())]]
                for face in (hull.element(i) for i in range(hull.num_faces()))
            ]
            ax.add_collection3d(Poly3DCollection(faces, **style))
        else:
            _top_view(ax, world, **style)
    elif three_d:
        ax.scatter(*pose.translation(), s=8, color=style.get("facecolor", "k"))


def scene_figure(oracle, title: str | None = None):
    """A figure with the obstacles and the passage region drawn; returns (fig, ax)."""
    scene = oracle.scene
    three_d = scene.problem.view == "3d"
    fig = plt.figure(figsize=(7, 6.5))
    ax = fig.add_subplot(projection="3d") if three_d else fig.add_subplot()
    for shape, pose in _geometries(oracle, scene.start, robot=False):
        style = dict(facecolor=(0.45, 0.45, 0.5, 0.25 if three_d else 1.0), edgecolor=(0.3, 0.3, 0.35, 0.4))
        _draw_shape(ax, shape, pose, three_d, **style)
    for lo, hi in scene.passage_boxes:
        if three_d:
            corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
            ax.add_collection3d(
                Poly3DCollection(
                    [corners[f] for f in _BOX_FACES],
                    facecolor=(1, 0.8, 0, 0.12),
                    edgecolor=(0.9, 0.6, 0, 0.8),
                    linestyle="--",
                )
            )
        else:
            ax.add_patch(
                Rectangle(
                    lo[:2],
                    *(hi - lo)[:2],
                    fill=True,
                    facecolor=(1, 0.85, 0, 0.25),
                    edgecolor=(0.9, 0.6, 0),
                    linestyle="--",
                    linewidth=1.2,
                )
            )
    bounds = _workspace_bounds(oracle)
    if three_d:
        ax.set(xlim=bounds[0], ylim=bounds[1], zlim=bounds[2], xlabel="x", ylabel="y", zlabel="z")
        ax.set_box_aspect([b[1] - b[0] for b in bounds])
    else:
        ax.set(xlim=bounds[0], ylim=bounds[1], xlabel="x", ylabel="y", aspect="equal")
    ax.set_title(title or f"{scene.name}: {scene.problem.description}", fontsize=9, wrap=True)
    return fig, ax


def _workspace_bounds(oracle):
    """The box the obstacles, the robot at start and goal and the robot's translational bounds span."""
    from pydrake.geometry import Box

    points = [np.array(p) for lo, hi in oracle.scene.passage_boxes for p in (lo, hi)]
    for shape, pose in _geometries(oracle, oracle.scene.start, robot=False):
        points.append(pose.translation())
        if isinstance(shape, Box):
            points.extend(_box_corners(shape, pose))
    for q in (oracle.scene.start, oracle.scene.goal):
        for shape, pose in _geometries(oracle, q, robot=True):
            # copy: the pose is a view into SceneGraph's cache, which the next configuration overwrites
            points.extend(_box_corners(shape, pose) if isinstance(shape, Box) else [np.array(pose.translation())])
    translational = ~oracle.scene.angular
    points = np.array(points)
    lo, hi = points.min(axis=0), points.max(axis=0)
    k = min(int(translational.sum()), 3)
    lo[:k] = np.minimum(lo[:k], oracle.space.lower[translational][:k])
    hi[:k] = np.maximum(hi[:k], oracle.space.upper[translational][:k])
    return list(zip(lo, hi))


def draw_robot(ax, oracle, q, color="tab:blue", alpha=0.9):
    three_d = oracle.scene.problem.view == "3d"
    for shape, pose in _geometries(oracle, q, robot=True):
        _draw_shape(ax, shape, pose, three_d, facecolor=color, edgecolor=color, alpha=alpha)


def save(fig, path: str) -> None:
    """Write the figure as a PNG, whole or not at all."""
    try:
        write_atomically(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight"))
    finally:
        plt.close(fig)


def draw_scene(oracle, path: str) -> None:
    """The scene with the robot at start (blue) and goal (green)."""
    fig, ax = scene_figure(oracle)
    draw_robot(ax, oracle, oracle.scene.start, color="tab:blue")
    draw_robot(ax, oracle, oracle.scene.goal, color="tab:green")
    save(fig, path)


def draw_samples(oracle, samples: np.ndarray, path: str, title: str | None = None) -> None:
    """The scene with every sample: faint robots in 2D (like the paper's Fig. 3), frame positions as dots in 3D."""
    fig, ax = scene_figure(oracle, title=title)
    inside = oracle.in_passage(samples)
    if oracle.scene.problem.view == "3d":
        p = oracle.frame_positions(samples) if len(samples) else np.empty((0, 3))
        for q in samples:
            draw_robot(ax, oracle, q, color="tab:blue", alpha=0.06)
        ax.scatter(*p[~inside].T, s=14, color="tab:blue", depthshade=False, label="sample")
        ax.scatter(*p[inside].T, s=18, color="tab:red", depthshade=False, label="sample in passage")
    else:
        for q, hit in zip(samples, inside):
            draw_robot(ax, oracle, q, color="tab:red" if hit else "tab:blue", alpha=0.18)
        p = oracle.frame_positions(samples) if len(samples) else np.empty((0, 3))
        ax.scatter(p[:, 0], p[:, 1], s=10, color="k", zorder=5, label="passage frame")
    ax.legend(loc="upper right", fontsize=7)
    save(fig, path)
