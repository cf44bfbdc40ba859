"""A planning panel in the browser (`python -m app gui SCENE`): Drake's Meshcat with sliders for the start and goal,
buttons to choose the sampler, plan, replay and show or hide the samples and the roadmap, in the manner of MoveIt's
MotionPlanning panel in RViz.

Threads. Drake's Meshcat is driven from the thread that made it: `Panel.step` (called by `serve` about POLL_HZ times
a second) reads the sliders and button clicks, redraws and plays the motion. Planning is `app.plan` -- the planner of
`plan`, with its settings -- run on one worker thread, so the page stays live while it runs. Both threads share the
scene's one collision oracle (it serializes their Drake queries; each query counts and bounds its own checks): the
worker plans and solves IK on it, the main thread colours the start and goal robots red in collision.

The cell can change under the panel, as a work cell does: "Obstacle: NAME" picks one of the scene's obstacles, the
"obstacle x/y/z" sliders say where it goes (an offset from where the scene has it), and "Move obstacle" moves it
there. The move is a cell change (app.scene.changes): on the worker thread the panel's roadmap is repaired for it
(CellRoadmap.changed: only the verdicts the move can reach are reset), and the panel then draws, checks and plans in
the changed cell; the last plan's path, made in the old cell, is taken away. `state()["changes"]` lists what each
repair did.

A Plan press takes the sliders' start and goal and the sampler shown at that moment, and plans on the panel's one
roadmap (app.planning.cell), which keeps the samples and edge verdicts of every earlier press: the second query in the
same cell is cheaper than the first. A press while a query runs cancels it (`cancel=`: the query's stop condition
polls the event before every collision batch) and the latest press is planned: a new Plan always replaces the old
result.

What the page shows of the last plan (success, collision checks, seconds) is the label of a button at the bottom of
the controls: Meshcat has no text element. The same figures, the slider values as the server read them and what is
drawn are in `state()`, which `serve` writes after every change to `state_path` (JSON, atomically) for scripts and
tests.
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import gc
import json
import threading
import time

import numpy as np

from app.errors import UserError
from app.io import write_atomically
from app.planning.cell import CellRoadmap
from app.planning.ik import pose_goal, robot_frame
from app.planning.query import plan
from app.planning.settings import PlanSettings
from app.samplers import SAMPLERS
from app.scene.changes import CellChange, Move, Placement, obstacle_names
from app.viewer import ILLUSTRATION_PATH, PATH_COLOUR, Viewer, start_meshcat

POLL_HZ = 25
START_COLOUR = (0.2, 0.75, 0.3, 0.5)  # the start robot (translucent green)
GOAL_COLOUR = (1.0, 0.55, 0.1, 0.5)  # the goal robot (translucent orange)
COLLIDING_COLOUR = (0.9, 0.05, 0.05, 0.6)  # either, while in collision
SLIDER_STEPS = 10_000  # slider resolution: a coordinate's range over this
POSE_LABELS = ("x", "y", "z", "roll", "pitch", "yaw")  # metres and degrees, as `plan --goal-pose`

# Button labels that never change; the others carry their state (sampler, shown/hidden, an IK failure, the result).
PLAN, PLAY, GOAL_FROM_POSE, MOVE_OBSTACLE = "Plan", "Play", "Goal from pose (IK)", "Move obstacle"
OBSTACLE_AXES = ("x", "y", "z")  # the obstacle sliders: an offset in the world from where the scene has it
# Made once, before the sliders, so that they head the controls (a 1280 x 800 window shows them without scrolling).
FIXED_BUTTONS = (PLAN, PLAY)


def is_arm(scene) -> bool:
    """A 3D robot whose coordinates are all joint angles: its goal can also be set as a tool pose."""
    return scene.problem.view == "3d" and bool(np.all(scene.angular))


class Panel:
    """The panel's state and its Meshcat, over one scene's shared collision oracle."""

    def __init__(
        self,
        oracle,
        settings: PlanSettings,
        *,
        port: int | None = None,
        frame: str | None = None,
        state_path=None,
    ):
        _collect_meshcats()
        self.oracle, self.settings = oracle, settings
        self.cell = CellRoadmap(oracle)  # grows with every Plan press; used on the worker thread only
        self.preview = oracle.context()  # the main thread's checks of the sliders' start and goal
        self.scene = oracle.scene
        self.viewer = Viewer(self.scene, meshcat=start_meshcat(port), frame=frame)
        self.meshcat = self.viewer.meshcat
        self.state_path = state_path
        self.sampler = settings.sampler
        self.samples_visible, self.roadmap_visible = True, False
        self.result = None  # the last PlanResult shown
        self.last: dict | None = None  # its figures, or the last Plan press's error
        self.ik: dict | None = None  # the last "Goal from pose" press's goal, or its error
        self.plans = self.dropped = 0  # results shown; answers dropped because a newer press replaced them
        self._worker = concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="panel-planner")
        self._running = None  # (kind, future, cancel event or None) on the worker
        self._pending: dict = {}  # kind -> job, waiting for the worker (a newer press of a kind replaces the older)
        self._play_from: float | None = None  # clock time the motion started playing at
        self._written = None

        for label in FIXED_BUTTONS:
            self.meshcat.AddButton(label)
        self._clicks: dict[str, int] = dict.fromkeys(FIXED_BUTTONS, 0)
        names = self.scene.coordinate_names
        lower, upper = self.scene.lower, self.scene.upper
        self._sliders = {end: [f"{end} {name}" for name in names] for end in ("start", "goal")}
        for end, q in (("start", self.scene.start), ("goal", self.scene.goal)):
            for name, lo, hi, value in zip(self._sliders[end], lower, upper, q):
                self.meshcat.AddSlider(name, float(lo), float(hi), float(hi - lo) / SLIDER_STEPS, float(value))
        self._pose_sliders = self._add_pose_sliders() if is_arm(self.scene) else []
        # The obstacles a move may pick, and how far each stands from where the scene has it.
        self._obstacles = obstacle_names(self.scene)
        self.obstacle = self._obstacles[0] if self._obstacles else None
        self._moved = {name: np.zeros(3) for name in self._obstacles}
        self.changes: list[dict] = []  # what each move's repair did, or its error
        self._obstacle_sliders = [f"obstacle {axis}" for axis in OBSTACLE_AXES] if self._obstacles else []
        reach = 0.5 * self.viewer.radius
        for name in self._obstacle_sliders:
            self.meshcat.AddSlider(name, -reach, reach, reach / SLIDER_STEPS, 0.0)
        self._frame = frame
        self._labels: list[str] = []  # the buttons after the sliders
        self._set_buttons()
        self._q = {end: None for end in ("start", "goal")}
        self._free = {end: True for end in ("start", "goal")}
        self._refresh_ends()
        self.viewer.set_configuration(self._q["start"])

    # ---- controls ----------------------------------------------------------------------------------------------------
    def _add_pose_sliders(self) -> list[str]:
        """x, y, z, roll, pitch, yaw of the tool frame, first at its pose in the scene's goal; positions within the
        arm's reach of its base."""
        from pydrake.math import RollPitchYaw

        plant = self.oracle.plant
        context = plant.CreateDefaultContext()
        plant.SetPositions(context, self.scene.positions(self.scene.goal))
        pose = robot_frame(self.oracle).CalcPoseInWorld(context)
        base = plant.get_body(plant.GetBodyIndices(self.scene.robot_instances[0])[0])
        reach = np.linalg.norm(pose.translation() - plant.EvalBodyPoseInWorld(context, base).translation())
        values = [*pose.translation(), *np.degrees(RollPitchYaw(pose.rotation()).vector())]
        names = [f"goal pose {label}" for label in POSE_LABELS]
        for i, (name, value) in enumerate(zip(names, values)):
            lo, hi = (value - reach, value + reach) if i < 3 else (-180.0, 180.0)
            self.meshcat.AddSlider(name, float(lo), float(hi), float(hi - lo) / SLIDER_STEPS, float(value))
        return names

    def _button_labels(self) -> list[str]:
        labels = [
            f"Sampler: {self.sampler}",
            f"Samples: {'shown' if self.samples_visible else 'hidden'}",
            f"Roadmap: {'shown' if self.roadmap_visible else 'hidden'}",
        ]
        if self._pose_sliders:
            failed = self.ik is not None and not self.ik["success"]
            labels.append(f"{GOAL_FROM_POSE}: {self.ik['error']['code']}" if failed else GOAL_FROM_POSE)
        if self._obstacles:
            failed = self.changes and not self.changes[-1]["success"]
            labels += [
                f"Obstacle: {self.obstacle}",
                f"{MOVE_OBSTACLE}: {self.changes[-1]['error']['code']}" if failed else MOVE_OBSTACLE,
            ]
        return [*labels, self._summary()]

    def _set_buttons(self) -> None:
        """(Re)make the buttons after the sliders when a label changes. Meshcat appends a button at the end of the
        controls and a label cannot be edited, so all of these are made again, in their order."""
        labels = self._button_labels()
        if labels == self._labels:
            return
        for label in self._labels:
            self.meshcat.DeleteButton(label, strict=False)
        for label in labels:
            self.meshcat.AddButton(label)
        fixed = {label: self._clicks[label] for label in FIXED_BUTTONS}
        self._labels, self._clicks = labels, {**fixed, **dict.fromkeys(labels, 0)}

    def _pressed(self) -> list[str]:
        """The buttons clicked since the last look (each once, however often it was clicked)."""
        pressed = []
        for label in [*FIXED_BUTTONS, *self._labels]:
            clicks = self.meshcat.GetButtonClicks(label)
            if clicks > self._clicks[label]:
                self._clicks[label] = clicks
                pressed.append(label)
        return pressed

    def _summary(self) -> str:
        """The last plan in a few words (Meshcat's controls are 245 pixels wide)."""
        if self.planning():
            return "Planning ..."
        if self.last is None:
            return "No plan yet"
        if not self.last["success"]:
            return f"Failed: {self.last['error']['code']}"
        return f"Found: {self.last['collision_checks']} checks, {self.last['seconds']:.2f} s, {self.last['sampler']}"

    # ---- the loop ----------------------------------------------------------------------------------------------------
    def serve(self, seconds: float | None = None) -> None:
        """Run the panel for `seconds` (None: until interrupted; KeyboardInterrupt propagates). It steps at least
        once, so the state file is written even for 0 seconds."""
        end = None if seconds is None else time.monotonic() + seconds
        period = 1.0 / POLL_HZ
        while True:
            tick = time.monotonic()
            self.step()
            if end is not None and tick >= end:
                return
            time.sleep(max(0.0, period - (time.monotonic() - tick)))

    def step(self) -> None:
        """One look at the page: sliders, buttons, the worker's answer, the motion being played; the state file."""
        self._refresh_ends()
        for label in self._pressed():
            self.press(label)
        self._collect()
        self._play()
        self._set_buttons()
        self._write_state()

    def planning(self) -> bool:
        """A Plan press not answered yet."""
        return self._running is not None and self._running[0] == "plan" or "plan" in self._pending

    def busy(self) -> bool:
        """Work on the worker thread or waiting for it."""
        return self._running is not None or bool(self._pending)

    def press(self, label: str) -> None:
        """What a click on the button labelled `label` does (`step` calls it for the page's clicks)."""
        if label == PLAN:
            start, goal = self._q["start"].copy(), self._q["goal"].copy()
            settings = dataclasses.replace(self.settings, sampler=self.sampler)
            cancel = threading.Event()
            self._request("plan", lambda: self._plan(settings, start, goal, cancel), cancel)
        elif label == PLAY:
            self._play_from = time.monotonic() if self.result is not None else None
        elif label.startswith(GOAL_FROM_POSE):
            pose = [self.meshcat.GetSliderValue(name) for name in self._pose_sliders]
            start, seed = self._q["start"].copy(), self.settings.seed
            self._request("ik", lambda: pose_goal(self.oracle, pose, reference=start, seed=seed))
        elif label.startswith("Obstacle:"):
            self.obstacle = self._obstacles[(self._obstacles.index(self.obstacle) + 1) % len(self._obstacles)]
            for name, value in zip(self._obstacle_sliders, self._moved[self.obstacle]):
                self.meshcat.SetSliderValue(name, float(value))
        elif label.startswith(MOVE_OBSTACLE):
            name = self.obstacle
            to = np.array([self.meshcat.GetSliderValue(s) for s in self._obstacle_sliders])
            by = to - self._moved[name]
            change = CellChange(move=[Move(name=name, pose=Placement(xyz=by.tolist()), by=True)])
            self._request("change", lambda: (name, to, self.cell.changed([change])))
        elif label.startswith("Sampler:"):
            names = list(SAMPLERS)
            self.sampler = names[(names.index(self.sampler) + 1) % len(names)]
        elif label.startswith("Samples:"):
            self.samples_visible = not self.samples_visible
            self.meshcat.SetProperty("/samples", "visible", self.samples_visible)
        elif label.startswith("Roadmap:"):
            self.roadmap_visible = not self.roadmap_visible
            self.meshcat.SetProperty("/roadmap", "visible", self.roadmap_visible)

    def _plan(self, settings, start, goal, cancel):
        """One Plan press's query, on the worker thread: on the panel's roadmap, which keeps what every earlier
        press sampled and decided (unless each press must build a roadmap of its own, the paper's protocol)."""
        if settings.full_roadmap:
            return plan(self.oracle, settings, start=start, goal=goal, cancel=cancel)
        return self.cell.solve(start, goal, settings, cancel=cancel)

    def _request(self, kind: str, job, cancel: threading.Event | None = None) -> None:
        """Queue a job for the worker; one of the same kind under way is cancelled if it can be (`cancel`)."""
        self._pending.pop(kind, None)
        self._pending[kind] = (job, cancel)
        if self._running is not None and self._running[0] == kind and self._running[2] is not None:
            self._running[2].set()
        self._submit()

    def _submit(self) -> None:
        if self._running is None and self._pending:
            kind = next(iter(self._pending))
            job, cancel = self._pending.pop(kind)
            self._running = (kind, self._worker.submit(job), cancel)

    def _collect(self) -> None:
        """Take the worker's answer when it is ready: shown, unless a newer press of its kind is waiting."""
        if self._running is None or not self._running[1].done():
            return
        (kind, future, _), self._running = self._running, None
        if kind in self._pending:
            self.dropped += 1
        else:
            try:
                answer = future.result()
            except UserError as exc:
                answer = exc
            if kind == "plan":
                self._show_plan(answer)
            elif kind == "change":
                self._changed(answer)
            elif isinstance(answer, UserError):
                self.ik = _error(answer)
            else:  # the goal sliders take the IK solution
                for name, value in zip(self._sliders["goal"], answer):
                    self.meshcat.SetSliderValue(name, float(value))
                self.ik = {"success": True, "goal": answer.tolist()}
        self._submit()

    def _show_plan(self, answer) -> None:
        for path in ("/path", "/samples", "/roadmap"):
            self.meshcat.Delete(path)
        self.plans += 1
        if isinstance(answer, UserError):
            self.result, self.last, self._play_from = None, _error(answer), None
            return
        result = self.result = answer
        positions = result.trajectory.positions
        self.viewer.show_path(positions, colour=PATH_COLOUR)
        narrow, on_path = result.narrow_samples()
        if len(narrow):
            self.viewer.show_samples(narrow, on_path)
            self.meshcat.SetProperty("/samples", "visible", self.samples_visible)
        edges = result.graph.edges().tolist() if result.graph is not None else []
        if edges:
            self.viewer.show_roadmap(result.graph.Q, edges)
            self.meshcat.SetProperty("/roadmap", "visible", self.roadmap_visible)
        self.last = {
            "success": True,
            "sampler": result.sampler,
            "collision_checks": result.collision_checks,
            "seconds": result.stats.seconds.total,
            "path_length": result.smoothing.length_after,
            "waypoints": len(result.path),
            "duration": result.trajectory.duration,
            "certified": result.trajectory.certified,
            "start": result.start.tolist(),
            "goal": result.goal.tolist(),
            "drawn": {"path_points": len(positions), "narrow_samples": len(narrow), "roadmap_edges": len(edges)},
        }
        self._play_from = time.monotonic()  # a new result plays once; Play replays it

    def _changed(self, answer) -> None:
        """A move's answer: the repaired roadmap and its cell, drawn and planned in from now on (or its error)."""
        if isinstance(answer, UserError):
            self.changes.append(_error(answer))
            return
        name, to, cell = answer
        self._moved[name] = to
        self.cell, self.oracle = cell, cell.oracle
        self.scene, self.preview = cell.oracle.scene, cell.oracle.context()
        self.meshcat.Delete(ILLUSTRATION_PATH)  # the old cell's geometry (the new viewer draws the new one)
        self.viewer = Viewer(self.scene, meshcat=self.meshcat, frame=self._frame)
        for path in ("/path", "/samples", "/roadmap"):  # the last plan's: made in the old cell
            self.meshcat.Delete(path)
        self.result, self._play_from = None, None
        self._q = {end: None for end in ("start", "goal")}
        self._refresh_ends()  # the start and goal drawn and checked again, in the new cell
        self.changes.append({"success": True, **cell.provenance["changes"][-1]})

    def _refresh_ends(self) -> None:
        """Start and goal from the sliders; their robots drawn there, red while in collision."""
        for end, colour in (("start", START_COLOUR), ("goal", GOAL_COLOUR)):
            q = np.array([self.meshcat.GetSliderValue(name) for name in self._sliders[end]])
            if self._q[end] is not None and np.array_equal(q, self._q[end]):
                continue
            self._q[end] = q
            self._free[end] = self.preview.is_free(q)
            self.viewer.show_robot_copy(end, q, colour if self._free[end] else COLLIDING_COLOUR)

    def _play(self) -> None:
        if self._play_from is None or self.result is None:
            return
        trajectory = self.result.trajectory
        elapsed = time.monotonic() - self._play_from
        i = min(int(np.searchsorted(trajectory.times, elapsed)), len(trajectory.times) - 1)
        self.viewer.set_configuration(trajectory.positions[i])
        if elapsed >= trajectory.times[-1]:
            self._play_from = None

    # ---- what the panel holds ----------------------------------------------------------------------------------------
    def state(self) -> dict:
        sliders = [name for names in self._sliders.values() for name in names]
        sliders += self._pose_sliders + self._obstacle_sliders
        return {
            "scene": self.scene.name,
            "meshcat": self.viewer.url(),
            "sampler": self.sampler,
            "planning": self.planning(),
            "plans": self.plans,
            "dropped": self.dropped,
            "sliders": {name: self.meshcat.GetSliderValue(name) for name in sliders},
            "start": self._q["start"].tolist(),
            "goal": self._q["goal"].tolist(),
            "start_free": self._free["start"],
            "goal_free": self._free["goal"],
            "samples_visible": self.samples_visible,
            "roadmap_visible": self.roadmap_visible,
            "playing": self._play_from is not None,
            "last": self.last,
            "ik": self.ik,
            "obstacle": self.obstacle,
            "changes": self.changes,
        }

    def _write_state(self) -> None:
        if self.state_path is None:
            return
        state = self.state()
        if state != self._written:
            write_atomically(self.state_path, json.dumps(state) + "\n")
            self._written = state

    def export_html(self, path) -> None:
        """The last motion recorded as Meshcat's animation, and the page written to `path` (standalone)."""
        if self.result is not None:
            self.viewer.animate(self.result.trajectory.times, self.result.trajectory.positions)
        self.viewer.write_html(path)

    def close(self) -> None:
        """Stop serving: waiting jobs dropped, a query under way cancelled, and the Meshcat server closed now, on this
        thread (see _collect_meshcats)."""
        if self._running is not None and self._running[2] is not None:
            self._running[2].set()
        self._worker.shutdown(wait=False, cancel_futures=True)
        self.viewer = self.meshcat = None
        _collect_meshcats()


def _collect_meshcats() -> None:
    """Run Python's cycle collector here. Drake aborts the process when a Meshcat is destroyed on another thread than
    the one that made it, and a Meshcat no longer used is only freed by the cycle collector (pybind keeps it in a
    cycle with its visualizer), which runs on whichever thread happens to allocate: with a worker thread planning,
    often that one. So the panel collects on the main thread when it starts (earlier viewers') and when it closes."""
    gc.collect()


def _error(exc: UserError) -> dict:
    return {"success": False, "error": {"code": exc.code, "message": str(exc)}}
