"""A scene in Drake's Meshcat: the robot animated along a trajectory, narrow-passage samples, the path, the passage
region; and the same as one standalone HTML page (`Meshcat.StaticHtml`, its JavaScript bundled, no CDN).

The oracle's RobotDiagram belongs to its collision checker and is already built, so a MeshcatVisualizer cannot be added
to it: the viewer builds a second diagram from the same scene files (`Scene.add_models`). Both plants load the same
directives in the same order, so a configuration means the same thing to both.

Colours follow the paper's figures: narrow-passage samples yellow, those on the path red. Samples and the path are drawn
at the world position of one robot frame (default: the passage frame, else the tool frame, else the last body).

Meshcat opens a server on localhost even to export HTML. Drake refuses that when DRAKE_ALLOW_NETWORK is set without
"meshcat" in it; the viewer then raises a UserError saying so rather than overriding the user's setting.

pydrake is imported in the functions that use it, so importing this module (as the command line does) stays cheap.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from app.errors import UserError
from app.io import check_output, write_atomically
from app.motion.trajectory import TrajectoryFile
from app.scene.drake_parser import robot_diagram_builder
from app.scene.model import Scene
from app.scene.shapes import half_extent

YELLOW = (1.0, 0.85, 0.0, 1.0)  # narrow-passage samples
RED = (0.9, 0.05, 0.05, 1.0)  # narrow-passage samples on the path
ROBOT_COLOUR = (0.25, 0.55, 0.95, 1.0)  # for robot geometry without its own colour (ours have none)
CAMERA_FOV = 50.0  # degrees, vertical
ENVIRONMENT_COLOUR = (0.72, 0.66, 0.58, 1.0)  # for obstacles without their own (a user's STL): apart from the robot
PATH_COLOUR = (0.55, 0.2, 0.75, 1.0)
PASSAGE_COLOUR = (0.2, 0.8, 0.3, 0.25)
ROADMAP_COLOUR = (0.45, 0.5, 0.55, 0.6)
ILLUSTRATION_PATH = "/drake/illustration"  # where MeshcatVisualizer puts the illustration geometry


@dataclass
class ViewData:
    """What a viewer shows: a sampled trajectory and, optionally, narrow-passage samples and the path's waypoints."""

    times: np.ndarray | None = None  # (N,)
    positions: np.ndarray | None = None  # (N, dim)
    narrow: np.ndarray | None = None  # (M, dim)
    on_path: np.ndarray | None = None  # (M,) bool
    path: np.ndarray | None = None  # (K, dim)

    @classmethod
    def of(cls, file: TrajectoryFile) -> ViewData:
        t = file.trajectory
        return cls(times=t.times, positions=t.positions, narrow=file.narrow, on_path=file.on_path, path=t.waypoints)


def check_meshcat_allowed() -> None:
    """Refuse at once (before a command's work) what Meshcat() would refuse: Drake allows it when
    DRAKE_ALLOW_NETWORK is unset or empty, or lists "meshcat" among its colon-separated components."""
    allowed = os.environ.get("DRAKE_ALLOW_NETWORK", "")
    if allowed and "meshcat" not in allowed.split(":"):
        raise UserError(_meshcat_disabled())


def _meshcat_disabled() -> str:
    return (
        f"Meshcat is disabled by DRAKE_ALLOW_NETWORK={os.environ.get('DRAKE_ALLOW_NETWORK', '')!r}; add 'meshcat' "
        "to it (e.g. DRAKE_ALLOW_NETWORK=meshcat) to view or export HTML"
    )


def start_meshcat(port: int | None = None):
    """A Meshcat server bound to localhost only."""
    from pydrake.geometry import Meshcat, MeshcatParams

    # Drake logs the URL at INFO; callers print it where it belongs. (pydrake mirrors this logger into C++.)
    logging.getLogger("drake").setLevel(logging.WARNING)
    params = MeshcatParams()
    params.host = "localhost"
    if port is not None:
        params.port = port
    try:
        return Meshcat(params)
    except RuntimeError as exc:
        if "DRAKE_ALLOW_NETWORK" in str(exc):
            raise UserError(_meshcat_disabled()) from None
        raise UserError(f"cannot start Meshcat: {' '.join(str(exc).split())[:200]}") from None


def _rgba(colour):
    from pydrake.geometry import Rgba

    return Rgba(*colour)


class Viewer:
    """A scene in Meshcat. Keep the Viewer (it holds the Meshcat server) for as long as the page should be served."""

    def __init__(
        self,
        scene: Scene | str,
        *,
        frame: str | None = None,
        collision: bool = False,
        meshcat=None,
        marker_size: float | None = None,
        obstacle_opacity: float | None = None,
    ):
        from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams, Role

        self.scene = scene if isinstance(scene, Scene) else Scene(scene)
        self.meshcat = meshcat if meshcat is not None else start_meshcat()

        # Same directives, same order: model instance indices and position coordinates match the scene's plant.
        builder = robot_diagram_builder()
        self.scene.add_models(builder.parser())
        builder.plant().Finalize()
        self._colour_environment(builder.plant(), builder.scene_graph())
        params = MeshcatVisualizerParams(
            role=Role.kIllustration, prefix="illustration", default_color=_rgba(ROBOT_COLOUR)
        )
        self._period = params.publish_period  # also the recording's 1/fps
        self._visualizer = MeshcatVisualizer.AddToBuilder(
            builder.builder(), builder.scene_graph(), self.meshcat, params
        )
        if collision:  # hidden at first; the Meshcat controls toggle it
            MeshcatVisualizer.AddToBuilder(
                builder.builder(),
                builder.scene_graph(),
                self.meshcat,
                MeshcatVisualizerParams(
                    role=Role.kProximity,
                    prefix="collision",
                    visible_by_default=False,
                    default_color=_rgba((0.9, 0.3, 0.9, 0.4)),
                ),
            )
        self.diagram = builder.Build()
        self.plant = self.diagram.plant()
        self.dim = self.scene.dim
        self._context = self.diagram.CreateDefaultContext()
        self._plant_context = self.plant.GetMyContextFromRoot(self._context)
        self.frame = self._find_frame(frame)
        self.frames_recorded = 0
        self._copy_contexts, self._copy_colours = {}, {}  # show_robot_copy's, by name

        self.plant.SetPositions(self._plant_context, self.scene.positions(self.scene.start))
        self.diagram.ForcedPublish(self._context)  # sends the geometry and poses the robot at the start
        self._centre, self._radius = self._extent()
        self.marker_size = marker_size or 0.02 * self._radius
        self._set_stage()
        # In 3D, walls hide the robot behind them: see-through obstacles by default.
        if obstacle_opacity is None:
            obstacle_opacity = 0.4 if self.scene.problem.view == "3d" else 1.0
        if obstacle_opacity < 1.0:
            self._set_obstacle_opacity(obstacle_opacity)
        self.show_passage()

    # ---- set-up ----------------------------------------------------------------------------------------------
    def _colour_environment(self, plant, scene_graph) -> None:
        """Obstacles that bring no colour of their own (a mesh has none) in ENVIRONMENT_COLOUR: MeshcatVisualizer's
        default colour is the robot's, and a robot among obstacles of its own colour is hard to see."""
        from pydrake.geometry import IllustrationProperties, Role, RoleAssign

        inspector = scene_graph.model_inspector()
        robot_frames = {
            plant.GetBodyFrameIdOrThrow(b) for i in self.scene.robot_instances for b in plant.GetBodyIndices(i)
        }
        # Drake warns on every replaced illustration role that a visualizer made before would miss it; none is made
        # yet (the visualizer is added after this), so the warnings are kept quiet.
        drake_log = logging.getLogger("drake")
        level = drake_log.level
        drake_log.setLevel(logging.ERROR)
        try:
            for gid in inspector.GetAllGeometryIds(Role.kIllustration):
                properties = inspector.GetIllustrationProperties(gid)
                if inspector.GetFrameId(gid) in robot_frames or properties.HasProperty("phong", "diffuse"):
                    continue
                coloured = IllustrationProperties(properties)
                coloured.AddProperty("phong", "diffuse", _rgba(ENVIRONMENT_COLOUR))
                scene_graph.AssignRole(plant.get_source_id(), gid, coloured, RoleAssign.kReplace)
        finally:
            drake_log.setLevel(level)

    @property
    def radius(self) -> float:
        """The radius of a sphere holding the scene (its illustration geometry and passage region) at the start."""
        return self._radius

    def _find_frame(self, name: str | None):
        plant, robots = self.plant, self.scene.robot_instances
        name = name or self.scene.problem.passage.frame or getattr(self.scene.problem, "tool_frame", "")
        if not name:  # the robot's last body: an arm's tool, a mobile robot's base
            return plant.get_body(plant.GetBodyIndices(robots[-1])[-1]).body_frame()
        for instance in robots:
            if plant.HasFrameNamed(name, instance):
                return plant.GetFrameByName(name, instance)
        if plant.HasFrameNamed(name):
            return plant.GetFrameByName(name)
        raise UserError(f"no frame named '{name}' in scene {self.scene.name}")

    def _extent(self) -> tuple[np.ndarray, float]:
        """Centre and radius of a sphere holding the scene's illustration geometry and passage region at the start."""
        lo, hi = self._bounds(robot=None)
        for box_lo, box_hi in self.scene.passage_boxes:
            lo, hi = np.minimum(lo, box_lo), np.maximum(hi, box_hi)
        if not np.all(np.isfinite(lo)):
            return np.zeros(3), 1.0
        return (lo + hi) / 2, max(float(np.linalg.norm(hi - lo)) / 2, 1e-3)

    def _bounds(self, robot: bool | None) -> tuple[np.ndarray, np.ndarray]:
        """World box around the illustration geometry at the current configuration: the robot's (robot=True), the
        environment's (False) or all of it (None). Infinite where there is none."""
        from pydrake.geometry import Role

        query = self.plant.get_geometry_query_input_port().Eval(self._plant_context)
        inspector = query.inspector()
        robot_frames = self._robot_frame_ids()
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        for gid in inspector.GetAllGeometryIds(Role.kIllustration):
            if robot is not None and (inspector.GetFrameId(gid) in robot_frames) != robot:
                continue
            pose = query.GetPoseInWorld(gid)
            half = half_extent(inspector.GetShape(gid), pose.rotation().matrix())
            lo, hi = np.minimum(lo, pose.translation() - half), np.maximum(hi, pose.translation() + half)
        return lo, hi

    def _robot_frame_ids(self) -> set:
        return {
            self.plant.GetBodyFrameIdOrThrow(b)
            for i in self.scene.robot_instances
            for b in self.plant.GetBodyIndices(i)
        }

    def _set_obstacle_opacity(self, opacity: float) -> None:
        """Fade the environment's illustration geometry (MeshcatVisualizer's paths: prefix/frame/geometry)."""
        from pydrake.geometry import Role

        inspector = self.diagram.scene_graph().model_inspector()
        robot_frames = self._robot_frame_ids()
        for gid in inspector.GetAllGeometryIds(Role.kIllustration):
            frame = inspector.GetFrameId(gid)
            if frame in robot_frames:
                continue
            frame_path = (
                "" if frame == inspector.world_frame_id() else "/" + inspector.GetName(frame).replace("::", "/")
            )
            path = f"{ILLUSTRATION_PATH}{frame_path}/{inspector.GetName(gid).replace('::', '/')}"
            self.meshcat.SetProperty(path, "modulated_opacity", float(opacity))

    def _set_stage(self) -> None:
        """Camera framing the scene, brighter light (Meshcat's lights suit a 1 m scene), no grid at large scale."""
        from pydrake.geometry import Meshcat

        self.meshcat.SetProperty("/Lights/AmbientLight/<object>", "intensity", 0.8)
        self.meshcat.SetProperty("/Lights/FillLight/<object>", "intensity", 0.8)
        if self._radius > 5.0:  # Meshcat's grid and axes are metre-sized: specks in a 100-unit scene
            self.meshcat.SetProperty("/Grid", "visible", False)
            self.meshcat.SetProperty("/Axes", "visible", False)
        r = self._radius
        camera = Meshcat.PerspectiveCamera(fov=CAMERA_FOV, aspect=1.0, near=0.01 * r, far=20.0 * r)
        self.meshcat.SetCamera(camera)
        target, position = self._camera_pose()
        self.meshcat.SetCameraPose(position, target)

    def frame_motion(self, positions) -> None:
        """Point the camera so that the whole motion through `positions` (configurations) stays in view."""
        target, position = self._camera_pose(positions)
        self.meshcat.SetCameraPose(position, target)

    def _camera_pose(self, motion=None) -> tuple[np.ndarray, np.ndarray]:
        """(target, position) of the camera.

        A robot at least a twentieth of the scene's size: the whole scene, a 2D scene from above (tilted a little to
        show depth), a 3D scene from an oblique corner. A smaller one (a quadrotor in a 20 m maze would be a few
        pixels) with a `motion` (configurations): the box its frame sweeps, grown by the robot's size, from above
        and tilted, just far enough for the camera's field of view to hold it (a view from the start would lose the
        robot as it flies off). Without a motion: a view over its shoulder at the start, from behind and above as
        seen from the scene's centre, ten robot radii away (the robot a fifth of the picture's height); the camera
        stays inside the box its body can reach, so the walls around that box (a tunnel's) do not hide it.
        """
        lo, hi = self._bounds(robot=True)
        robot_radius = float(np.linalg.norm(hi - lo)) / 2 if np.all(np.isfinite(lo)) else self._radius
        if robot_radius >= 0.05 * self._radius:
            direction = np.array([0.0, -0.35, 1.0]) if self.scene.problem.view == "2d" else np.array([-1.0, -1.3, 0.9])
            return self._centre, self._centre + 1.8 * self._radius * direction / np.linalg.norm(direction)
        if motion is not None and len(motion):
            P = self.frame_positions(motion)
            swept_lo, swept_hi = P.min(axis=0) - robot_radius, P.max(axis=0) + robot_radius
            centre, half = (swept_lo + swept_hi) / 2, float(np.linalg.norm(swept_hi - swept_lo)) / 2
            direction = np.array([0.0, -0.6, 1.0])
            distance = half / np.sin(np.radians(CAMERA_FOV / 2))
            return centre, centre + distance * direction / np.linalg.norm(direction)
        robot = (lo + hi) / 2
        behind = robot - self._centre
        behind[2] = 0.0
        behind = behind / np.linalg.norm(behind) if np.linalg.norm(behind) > 1e-9 else np.array([-1.0, 0.0, 0.0])
        direction = behind + np.array([0.0, 0.0, 0.8])
        position = robot + 10 * robot_radius * direction / np.linalg.norm(direction)
        reach_lo, reach_hi = self._reachable_box()
        return robot, np.clip(position, reach_lo, reach_hi)

    def _reachable_box(self) -> tuple[np.ndarray, np.ndarray]:
        """World box between the tracked frame's positions with every coordinate at its lower and at its upper
        bound: for a free flyer, the box its body can reach."""
        P = self.frame_positions(np.array([self.scene.lower, self.scene.upper]))
        return P.min(axis=0), P.max(axis=0)

    # ---- drawing ---------------------------------------------------------------------------------------------
    def _configurations(self, Q, what: str) -> np.ndarray:
        Q = np.asarray(Q, float)
        if Q.ndim == 1 and Q.size == 0:
            Q = Q.reshape(0, self.dim)
        if Q.ndim != 2 or Q.shape[1] != self.dim or not np.all(np.isfinite(Q)):
            raise UserError(f"{what} must be rows of {self.dim} finite numbers for scene {self.scene.name}")
        return Q

    def frame_positions(self, Q) -> np.ndarray:
        """World position of the viewer's frame for each configuration, (n, 3)."""
        Q = self._configurations(Q, "configurations")
        out = np.empty((len(Q), 3))
        context = self.plant.CreateDefaultContext()
        for i, q in enumerate(Q):
            self.plant.SetPositions(context, self.scene.positions(q))
            out[i] = self.frame.CalcPoseInWorld(context).translation()
        return out

    def _points(self, path: str, P: np.ndarray, colour) -> None:
        from pydrake.perception import BaseField, Fields, PointCloud

        cloud = PointCloud(len(P), Fields(BaseField.kXYZs))
        cloud.mutable_xyzs()[:] = P.T
        self.meshcat.SetObject(path, cloud, point_size=self.marker_size, rgba=_rgba(colour))

    def show_samples(self, narrow_Q, on_path_mask=None) -> None:
        """Narrow-passage samples: yellow, and red where `on_path_mask` is true."""
        P = self.frame_positions(self._configurations(narrow_Q, "narrow samples"))
        mask = np.zeros(len(P), bool) if on_path_mask is None else np.asarray(on_path_mask, bool).reshape(-1)
        if mask.shape != (len(P),):
            raise UserError(f"{mask.size} on-path flags for {len(P)} narrow samples")
        self.meshcat.Delete("/samples")
        if np.any(~mask):
            self._points("/samples/narrow", P[~mask], YELLOW)
        if np.any(mask):
            self._points("/samples/on_path", P[mask], RED)

    def show_path(self, Q, name: str = "path", colour=PATH_COLOUR) -> None:
        """A polyline through the frame's positions at the configurations Q."""
        P = self.frame_positions(self._configurations(Q, "path"))
        if len(P) >= 2:
            self.meshcat.SetLine(f"/{name}", np.asfortranarray(P.T), line_width=3.0, rgba=_rgba(colour))

    def show_passage(self) -> None:
        """The scene's passage region as translucent boxes."""
        from pydrake.geometry import Box
        from pydrake.math import RigidTransform

        for i, (lo, hi) in enumerate(self.scene.passage_boxes):
            size = np.maximum(hi - lo, 1e-6)
            self.meshcat.SetObject(f"/passage/box{i}", Box(*size), _rgba(PASSAGE_COLOUR))
            self.meshcat.SetTransform(f"/passage/box{i}", RigidTransform((lo + hi) / 2))

    def show_roadmap(self, Q, edges, name: str = "roadmap", colour=ROADMAP_COLOUR) -> None:
        """The roadmap's edges (pairs of row indices into Q) as straight segments between the frame's positions."""
        edges = np.asarray(edges, int).reshape(-1, 2)
        self.meshcat.Delete(f"/{name}")
        if len(edges):
            P = self.frame_positions(Q)
            self.meshcat.SetLineSegments(
                f"/{name}",
                np.asfortranarray(P[edges[:, 0]].T),
                np.asfortranarray(P[edges[:, 1]].T),
                line_width=1.0,
                rgba=_rgba(colour),
            )

    def show_robot_copy(self, name: str, q, colour) -> None:
        """A copy of the robot's illustration geometry at configuration q, all in `colour`, under /{name} (the
        animated robot stays where it is): e.g. a start or goal drawn beside it. The shapes are sent again only when
        the colour changes; moving the copy only sends poses."""
        from pydrake.geometry import Role

        q = self._configurations(np.atleast_2d(q), "configuration")[0]
        if name not in self._copy_contexts:
            self._copy_contexts[name] = self.plant.CreateDefaultContext()
        context = self._copy_contexts[name]
        self.plant.SetPositions(context, self.scene.positions(q))
        inspector = self.diagram.scene_graph().model_inspector()
        redraw = self._copy_colours.get(name) != tuple(colour)
        self._copy_colours[name] = tuple(colour)
        for instance in self.scene.robot_instances:
            for index in self.plant.GetBodyIndices(instance):
                body = self.plant.get_body(index)
                frame_id = self.plant.GetBodyFrameIdIfExists(index)
                if frame_id is None:
                    continue
                X_WB = self.plant.EvalBodyPoseInWorld(context, body)
                for i, gid in enumerate(inspector.GetGeometries(frame_id, Role.kIllustration)):
                    path = f"/{name}/{body.name()}/{i}"
                    if redraw:
                        self.meshcat.SetObject(path, inspector.GetShape(gid), _rgba(colour))
                    self.meshcat.SetTransform(path, X_WB @ inspector.GetPoseInFrame(gid))

    def set_configuration(self, q) -> None:
        """Pose the robot (live, not recorded)."""
        q = self._configurations(np.atleast_2d(q), "configuration")[0]
        self.plant.SetPositions(self._plant_context, self.scene.positions(q))
        self.diagram.ForcedPublish(self._context)

    def animate(self, times, positions) -> int:
        """Record the robot along (times (N,), positions (N, dim)) as Meshcat's animation; returns the frame count.

        Times are shifted to start at 0. The recording has one frame per publish period of the visualizer (1/64 s);
        samples closer than that share a frame, the last one winning.
        """
        positions = self._configurations(positions, "positions")
        times = np.asarray(times, float).reshape(-1)
        if times.shape != (len(positions),) or len(times) == 0:
            raise UserError(f"{times.size} times for {len(positions)} positions")
        if not np.all(np.isfinite(times)) or np.any(np.diff(times) < 0):
            raise UserError("times must be finite and non-decreasing")
        times = times - times[0]
        self._visualizer.DeleteRecording()
        self._visualizer.StartRecording(set_transforms_while_recording=False)
        try:
            for t, q in zip(times, positions):
                self._context.SetTime(float(t))
                self.plant.SetPositions(self._plant_context, self.scene.positions(q))
                self.diagram.ForcedPublish(self._context)
        finally:
            self._visualizer.StopRecording()
        self._visualizer.PublishRecording()
        self.frames_recorded = int(round(times[-1] / self._period)) + 1
        return self.frames_recorded

    # ---- output ----------------------------------------------------------------------------------------------
    def html(self) -> str:
        return self.meshcat.StaticHtml()

    def write_html(self, path: str | os.PathLike) -> Path:
        """The standalone page, written atomically."""
        return write_atomically(path, self.html())

    def url(self) -> str:
        return self.meshcat.web_url()


def show(
    scene: Scene | str, data: ViewData, *, frame: str | None = None, collision: bool = False, meshcat=None
) -> Viewer:
    """A Viewer with everything in `data` drawn and the trajectory (if any) recorded."""
    viewer = Viewer(scene, frame=frame, collision=collision, meshcat=meshcat)
    if data.narrow is not None and len(data.narrow):
        viewer.show_samples(data.narrow, data.on_path)
    if data.path is not None:
        viewer.show_path(data.path)
    elif data.positions is not None:
        viewer.show_path(data.positions)
    if data.positions is not None:
        viewer.set_configuration(data.positions[0])
        viewer.animate(data.times, data.positions)
        viewer.frame_motion(data.positions)
    return viewer


def publish(
    scene: Scene | str, data: ViewData, *, html: str | None = None, frame: str | None = None, collision: bool = False
) -> Viewer:
    """What `--meshcat` / `--html FILE` do for any command: `data` shown in a Meshcat served on localhost
    (`viewer.url()`), and the standalone page written to `html` when given (checked before the viewer is built)."""
    if html:
        check_output(html)
    viewer = show(scene, data, frame=frame, collision=collision)
    if html:
        viewer.write_html(html)
    return viewer
