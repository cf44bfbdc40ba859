"""Matplotlib pictures of a scene, read from SceneGraph's collision shapes, so any scene draws without extra code.

2D scenes are drawn as a top view (x-y) of patches. 3D scenes are drawn so that what is in front is in front:
matplotlib orders the polygons of one collection by depth, but whole collections only by one depth each (a wall
drawn as one collection covered an arm behind it, or the arm the wall). So a 3D picture gathers every face of every
solid, every edge and every point (a small square facing the camera) first, cut into tiles no larger than a
twenty-fifth of the scene (a large wall's one average depth is wrong for what stands next to it), and draws them as
one collection.

`Picture` is a scene with obstacles and passage region; `add_robot` and `add_points` add to it; `save` writes the
PNG atomically, with a legend naming every colour. `draw_scene` and `draw_samples` are the whole pictures of `show`
and `sample --png`.

pydrake's geometry types are imported in the functions that use them, as everywhere in the package: importing a
module stays cheap until Drake is needed.
"""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import to_rgba  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Circle, Patch, Polygon, Rectangle  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from app.io import write_atomically  # noqa: E402
from app.scene.shapes import hull_vertices  # noqa: E402

OBSTACLE = (0.45, 0.45, 0.5)
OBSTACLE_EDGE = (0.3, 0.3, 0.35)
PASSAGE = (1.0, 0.8, 0.0)
PASSAGE_EDGE = (0.9, 0.6, 0.0)
START, GOAL, SAMPLE, IN_PASSAGE = "tab:blue", "tab:green", "tab:blue", "tab:red"
START_BEHIND_LINES = "tab:orange"  # the arm at the start behind the samples' blue lines
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


def _draw_flat(ax, shape, pose, **style) -> None:
    """A shape seen from above (2D scenes)."""
    from pydrake.geometry import Box, Capsule, Convex, Cylinder, Mesh, Sphere

    if isinstance(shape, Box):
        _top_view(ax, _box_corners(shape, pose), **style)
    elif isinstance(shape, (Cylinder, Sphere, Capsule)):
        ax.add_patch(Circle(pose.translation()[:2], shape.radius(), **style))
    elif isinstance(shape, (Convex, Mesh)):
        _top_view(ax, _hull_points(shape, pose), **style)


def _hull_points(shape, pose) -> np.ndarray:
    """World vertices of what Drake collides with for a mesh: its convex hull (custom scenes' pieces)."""
    return hull_vertices(shape) @ pose.rotation().matrix().T + pose.translation()


def _faces(shape, pose) -> list[np.ndarray] | None:
    """A solid's faces in the world (polygons, (k, 3) each); None for a shape we cannot draw."""
    from pydrake.geometry import Box, Capsule, Convex, Cylinder, Mesh, Sphere

    if isinstance(shape, Box):
        corners = _box_corners(shape, pose)
        return [corners[f] for f in _BOX_FACES]
    if isinstance(shape, (Cylinder, Sphere, Capsule)):
        return _round_faces(shape, pose)
    if isinstance(shape, (Convex, Mesh)):
        hull, world = shape.GetConvexHull(), _hull_points(shape, pose)
        return [
            world[[face.vertex(j) for j in range(face.num_vertices())]]
            for face in (hull.element(i) for i in range(hull.num_faces()))
        ]
    return None


def _tiles(polygon: np.ndarray, size: float) -> list[np.ndarray]:
    """The polygon cut into pieces no wider than `size`: a quadrilateral into a grid of quadrilaterals, anything
    else into fans of triangles cut into grids of triangles."""
    if len(polygon) == 4:
        a, b, c, d = polygon
        n = max(1, int(np.ceil(max(np.linalg.norm(b - a), np.linalg.norm(c - d)) / size)))
        m = max(1, int(np.ceil(max(np.linalg.norm(d - a), np.linalg.norm(c - b)) / size)))
        u, v = np.linspace(0, 1, n + 1)[:, None, None], np.linspace(0, 1, m + 1)[None, :, None]
        grid = (1 - u) * (1 - v) * a + u * (1 - v) * b + u * v * c + (1 - u) * v * d
        return [
            np.array([grid[i, j], grid[i + 1, j], grid[i + 1, j + 1], grid[i, j + 1]])
            for i in range(n)
            for j in range(m)
        ]
    out = []
    a = polygon[0]
    for b, c in zip(polygon[1:-1], polygon[2:]):
        n = max(1, int(np.ceil(max(np.linalg.norm(b - a), np.linalg.norm(c - b), np.linalg.norm(a - c)) / size)))
        steps = np.arange(n + 1)[:, None, None] / n
        grid = a + steps * (b - a) + steps.transpose(1, 0, 2) * (c - a)  # grid[i, j]: i steps along ab, j along ac
        for i in range(n):
            for j in range(n - i):
                out.append(np.array([grid[i, j], grid[i + 1, j], grid[i, j + 1]]))
                if i + j < n - 1:
                    out.append(np.array([grid[i + 1, j], grid[i + 1, j + 1], grid[i, j + 1]]))
    return out


def _shaded(colour, polygon: np.ndarray, light: np.ndarray):
    """The face's colour darkened as it turns away from the light (either side lit: faces have no outside here)."""
    normal = np.cross(polygon[1] - polygon[0], polygon[2] - polygon[0])
    length = np.linalg.norm(normal)
    lit = abs(normal @ light) / length if length > 0 else 1.0
    r, g, b, alpha = colour
    return (*(np.array([r, g, b]) * (0.55 + 0.45 * lit)), alpha)


class Faces3D:
    """Faces, edges and points for one 3D picture, drawn as one collection so matplotlib orders all of them by
    depth together, each face cut into tiles of at most `tile` so that one face's average depth is right for
    whatever stands beside it. `elev` and `azim` (degrees) are the view's, for shading and for squares that face
    the camera."""

    def __init__(self, tile: float, elev: float, azim: float):
        self.tile = tile
        e, a = np.radians([elev, azim])
        self.eye = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
        light = self.eye + np.array([0.0, 0.0, 1.0])
        self.light = light / np.linalg.norm(light)
        self.polygons, self.facecolours, self.edgecolours, self.widths = [], [], [], []

    def face(self, polygon: np.ndarray, face, edge=None) -> None:
        """One face, as tiles, and its outline (when `edge` is a colour) as short segments sorted with them."""
        shaded, none = _shaded(face, polygon, self.light), (0.0, 0.0, 0.0, 0.0)
        for tile in _tiles(polygon, self.tile):
            self._add(tile, shaded, none, 0.0)
        if edge is None:
            return
        for a, b in zip(polygon, np.roll(polygon, -1, axis=0)):
            n = max(1, int(np.ceil(np.linalg.norm(b - a) / self.tile)))
            ends = a + np.linspace(0, 1, n + 1)[:, None] * (b - a)
            for p, q in zip(ends[:-1], ends[1:]):
                self._add(np.array([p, q]), none, edge, 0.6)

    def line(self, P: np.ndarray, colour, width: float) -> None:
        """A polyline through the points P, as short segments sorted with the faces."""
        none = (0.0, 0.0, 0.0, 0.0)
        for a, b in zip(P[:-1], P[1:]):
            n = max(1, int(np.ceil(np.linalg.norm(b - a) / self.tile)))
            ends = a + np.linspace(0, 1, n + 1)[:, None] * (b - a)
            for p, q in zip(ends[:-1], ends[1:]):
                self._add(np.array([p, q]), none, colour, width)

    def squares(self, P: np.ndarray, colour) -> None:
        """Points as small squares facing the camera."""
        u = np.cross([0.0, 0.0, 1.0], self.eye)
        u = u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-9 else np.array([1.0, 0.0, 0.0])
        v = np.cross(self.eye, u)
        corners = self.tile / 8 * np.array([-u - v, u - v, u + v, -u + v])
        for p in P:
            self._add(p + corners, colour, (0.0, 0.0, 0.0, 0.0), 0.0)

    def _add(self, polygon, face, edge, width) -> None:
        self.polygons.append(polygon)
        self.facecolours.append(face)
        self.edgecolours.append(edge)
        self.widths.append(width)

    def draw(self, ax) -> None:
        if self.polygons:
            ax.add_collection3d(
                _DepthSorted(
                    self.polygons,
                    facecolors=self.facecolours,
                    edgecolors=self.edgecolours,
                    linewidths=self.widths,
                    zsort="average",
                )
            )


class _DepthSorted(Poly3DCollection):
    """A Poly3DCollection whose line widths stay with their polygons when it sorts them by depth. Matplotlib reorders
    the face and edge colours only, so a line segment got the width of whatever came to stand at its place in the
    order: a face's 0 (the segment vanished) or an outline's 0.6 (a sample's arm drawn as broken hairlines). The
    order is read back from the edge colours, which carry each polygon's index while matplotlib sorts them."""

    def __init__(self, polygons, linewidths, **style):
        super().__init__(polygons, linewidths=linewidths, **style)
        self._widths_in_order = np.asarray(linewidths, float)

    def do_3d_projection(self):
        colours = self._edgecolor3d
        tags = np.zeros((len(colours), 4))
        tags[:, 0] = np.arange(len(colours))
        self._edgecolor3d = tags
        try:
            # (Polygons of 2, 3 and 4 corners: matplotlib pads the shorter ones with uninitialised numbers it masks,
            # whose projection may overflow: a warning about numbers never drawn.)
            with np.errstate(over="ignore"):
                depth = super().do_3d_projection()
            order = np.asarray(self._edgecolors2d)[:, 0].round().astype(int)
        finally:
            self._edgecolor3d = colours
        self._edgecolors2d = colours[order]
        self._linewidths = self._widths_in_order[order]
        return depth


class Picture:
    """A scene's picture: obstacles and the passage region drawn; `add_robot` and `add_points` add to it, `save`
    writes it with a legend of every colour used."""

    def __init__(self, oracle, title: str | None = None, also: np.ndarray | None = None, faint: bool = False):
        """`also`: world points (n, 3) the axes must hold too (samples); `faint`: obstacles as outlines over a
        faint fill (3D), so that what is drawn among them (samples) stands out."""
        scene = oracle.scene
        self.oracle = oracle
        self.three_d = scene.problem.view == "3d"
        self.fig = plt.figure(figsize=(7, 6.5))
        self.ax = self.fig.add_subplot(projection="3d") if self.three_d else self.fig.add_subplot()
        self.solids: list[str] = []  # the label of every solid drawn
        self._legend: dict[str, object] = {}  # label -> legend handle, in the order first drawn
        bounds = _workspace_bounds(oracle, also)
        lo, hi = np.array(bounds).T
        if self.three_d:
            # Seen from the robot's side of the scene, turned 30 degrees to show depth.
            toward = np.mean([pose.translation() for _, pose in _geometries(oracle, scene.start, robot=True)], axis=0)
            azim = np.degrees(np.arctan2(*(toward - (lo + hi) / 2)[1::-1])) - 30
            self.ax.view_init(elev=25, azim=azim)
            self._faces = Faces3D(float(np.linalg.norm(hi - lo)) / 25, 25, azim)
        alpha, edge = (0.05, 0.3) if faint and self.three_d else (0.25, 0.4) if self.three_d else (1.0, 0.4)
        for shape, pose in _geometries(oracle, scene.start, robot=False):
            self._solid(shape, pose, (*OBSTACLE, alpha), (*OBSTACLE_EDGE, edge), "obstacle")
        for box_lo, box_hi in scene.passage_boxes:
            self._passage_box(box_lo, box_hi)
        if self.three_d:
            self.ax.set(xlim=bounds[0], ylim=bounds[1], zlim=bounds[2], xlabel="x", ylabel="y", zlabel="z")
            self.ax.set_box_aspect(hi - lo)
            # Ticks in proportion to each axis's drawn length: a flat scene's short z axis holds two or three
            # labels, not six on top of each other (the maze's 3 m beside its 20 m).
            for axis, extent in zip((self.ax.xaxis, self.ax.yaxis, self.ax.zaxis), hi - lo):
                axis.set_major_locator(MaxNLocator(nbins=max(2, round(6 * extent / max(hi - lo)))))
        else:
            self.ax.set(xlim=bounds[0], ylim=bounds[1], xlabel="x", ylabel="y", aspect="equal")
        self.ax.set_title(title or f"{scene.name}: {scene.problem.description}", fontsize=9, wrap=True)

    def _passage_box(self, lo, hi) -> None:
        face, edge = (*PASSAGE, 0.12 if self.three_d else 0.25), (*PASSAGE_EDGE, 0.8)
        self._legend.setdefault(
            "passage region", Patch(facecolor=face, edgecolor=edge, linestyle="--", label="passage region")
        )
        if self.three_d:
            corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
            for f in _BOX_FACES:
                self._faces.face(corners[f], face, edge)
        else:
            self.ax.add_patch(
                Rectangle(lo[:2], *(hi - lo)[:2], facecolor=face, edgecolor=edge, linestyle="--", linewidth=1.2)
            )

    def _solid(self, shape, pose, face, edge, label: str) -> None:
        self.solids.append(label)
        shown = (*face[:3], max(face[3], 0.3))  # a faint colour (one of thirty overlaid robots) is lost in a legend
        self._legend.setdefault(label, Patch(facecolor=shown, edgecolor=edge if edge else shown, label=label))
        if not self.three_d:
            _draw_flat(self.ax, shape, pose, facecolor=face, edgecolor=edge if edge else face)
            return
        polygons = _faces(shape, pose)
        if polygons is None:  # a shape we cannot draw: its origin
            self._faces.squares(np.array([pose.translation()]), face)
        for polygon in polygons or []:
            self._faces.face(polygon, face, edge)

    def add_robot(self, q, colour, alpha: float, label: str, unmoved_from=None) -> None:
        """The robot at configuration q; with `unmoved_from` (a configuration), only its parts that q moves (a cart
        that stays put, drawn twice in one place, would be a checkerboard of the two colours)."""
        face = to_rgba(colour, alpha)
        drawn = (
            []
            if unmoved_from is None
            else [p.GetAsMatrix4() for _, p in _geometries(self.oracle, unmoved_from, robot=True)]
        )
        for i, (shape, pose) in enumerate(_geometries(self.oracle, q, robot=True)):
            if drawn and np.allclose(drawn[i], pose.GetAsMatrix4(), atol=1e-9):
                continue
            self._solid(shape, pose, face, None if self.three_d else face, label)

    def add_points(self, P: np.ndarray, colour, label: str, size: float = 12) -> None:
        """Points in the world, (n, 3)."""
        if not len(P):
            return
        self._legend.setdefault(
            label, Line2D([], [], marker="s" if self.three_d else "o", linestyle="", color=colour, label=label)
        )
        if self.three_d:
            self._faces.squares(P, to_rgba(colour))
        else:
            self.ax.scatter(P[:, 0], P[:, 1], s=size, color=colour, zorder=5)

    def add_line(self, P: np.ndarray, colour, label: str, width: float = 1.5) -> None:
        """A polyline through world points, (n, 3)."""
        self._legend.setdefault(label, Line2D([], [], color=colour, linewidth=width, label=label))
        if self.three_d:
            self._faces.line(P, to_rgba(colour), width)
        else:
            self.ax.plot(P[:, 0], P[:, 1], color=colour, linewidth=width, zorder=4)

    def save(self, path: str) -> None:
        """Write the PNG, whole or not at all."""
        if self.three_d:
            self._faces.draw(self.ax)
        self.ax.legend(handles=list(self._legend.values()), loc="upper left", fontsize=7, framealpha=0.85)
        save(self.fig, path)


def _articulated(oracle) -> bool:
    """Whether the robot's parts move against each other between start and goal (an arm), not as one body."""
    ends = [
        [p.GetAsMatrix4() for _, p in _geometries(oracle, q, robot=True)]
        for q in (oracle.scene.start, oracle.scene.goal)
    ]
    relative = [[np.linalg.inv(poses[0]) @ pose for pose in poses] for poses in ends]
    return not np.allclose(relative[0], relative[1], atol=1e-9)


def _skeleton(oracle, q) -> np.ndarray:
    """World positions of the robot's body origins at q, in the plant's order (a serial arm's: base to tool), and of
    the tracked frame: the arm drawn as one line, from the last body whose origin stays where it is at the start
    (the arm's base, not the cart it stands on)."""
    plant = oracle.plant
    bodies = [plant.get_body(b) for i in oracle.scene.robot_instances for b in plant.GetBodyIndices(i)]
    context = plant.CreateDefaultContext()
    origins = []
    for configuration in (oracle.scene.start, q):
        plant.SetPositions(context, oracle.scene.positions(configuration))
        origins.append(np.array([plant.EvalBodyPoseInWorld(context, body).translation() for body in bodies]))
    moved = np.flatnonzero(np.linalg.norm(origins[1] - origins[0], axis=1) > 1e-9)
    first = max(int(moved[0]) - 1, 0) if len(moved) else 0
    return np.vstack([origins[1][first:], oracle.workspace.frame_positions(np.array([q]))])


def _workspace_bounds(oracle, also: np.ndarray | None = None):
    """The box the obstacles, the robot at start and goal, the robot's translational bounds and the points `also`
    span: every shape whole (a mesh piece by its hull's vertices, a cylinder by its rims), not only where its frame
    is."""
    points = [np.array(p) for lo, hi in oracle.scene.passage_boxes for p in (lo, hi)]
    points.extend(np.empty((0, 3)) if also is None else also)
    for q, robot in ((oracle.scene.start, False), (oracle.scene.start, True), (oracle.scene.goal, True)):
        for shape, pose in _geometries(oracle, q, robot=robot):
            # copies: the pose is a view into SceneGraph's cache, which the next configuration overwrites
            polygons = _faces(shape, pose)
            points.extend(np.vstack(polygons) if polygons else [np.array(pose.translation())])
    translational = ~oracle.scene.angular
    points = np.array(points)
    lo, hi = points.min(axis=0), points.max(axis=0)
    k = min(int(translational.sum()), 3)
    lo[:k] = np.minimum(lo[:k], oracle.space.lower[translational][:k])
    hi[:k] = np.maximum(hi[:k], oracle.space.upper[translational][:k])
    return list(zip(lo, hi))


def save(fig, path: str) -> None:
    """Write the figure as a PNG, whole or not at all."""
    try:
        write_atomically(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight"))
    finally:
        plt.close(fig)


def draw_scene(oracle, path: str) -> None:
    """The scene with the robot at start and at goal."""
    picture = Picture(oracle)
    picture.add_robot(oracle.scene.start, START, 0.9, "robot at start")
    picture.add_robot(oracle.scene.goal, GOAL, 0.9, "robot at goal", unmoved_from=oracle.scene.start)
    picture.save(path)


def draw_samples(oracle, samples: np.ndarray, path: str, title: str | None = None) -> None:
    """The scene with every sample: faint robots in 2D (like the paper's Fig. 3), frame positions as dots in 3D; an
    arm in 3D as a line through its links' origins per sample (thirty faint overlaid arms are one blue blob) over the
    arm at the start."""
    inside = oracle.workspace.in_passage(samples)
    p = oracle.workspace.frame_positions(samples) if len(samples) else np.empty((0, 3))
    arm = oracle.scene.problem.view == "3d" and _articulated(oracle)
    skeletons = [_skeleton(oracle, q) for q in samples] if arm else []
    # The axes hold every sample; the obstacles (an enclosure's walls in front of the samples) are outlines.
    picture = Picture(oracle, title=title, also=np.vstack([p, *skeletons]), faint=True)
    if arm:
        picture.add_robot(oracle.scene.start, START_BEHIND_LINES, 0.15, "robot at start")
        for skeleton, hit in zip(skeletons, inside):
            picture.add_line(skeleton, IN_PASSAGE if hit else SAMPLE, "arm at a sample (link origins)")
        picture.add_points(p[~inside], SAMPLE, "sample (tracked frame)")
        picture.add_points(p[inside], IN_PASSAGE, "sample in passage")
    elif picture.three_d:
        for q in samples:  # parts no sample moves (a cart) are left out: thirty faint copies would be opaque
            picture.add_robot(q, SAMPLE, 0.06, "robot at a sample", unmoved_from=oracle.scene.start)
        picture.add_points(p[~inside], SAMPLE, "sample (tracked frame)")
        picture.add_points(p[inside], IN_PASSAGE, "sample in passage")
    else:
        for q, hit in zip(samples, inside):
            picture.add_robot(
                q, IN_PASSAGE if hit else SAMPLE, 0.18, "robot at a sample in passage" if hit else "robot at a sample"
            )
        picture.add_points(p, "k", "tracked frame", size=10)
    picture.save(path)
