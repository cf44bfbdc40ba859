"""Scripted arm jobs: a route of named tool poses, each leg planned, all legs joined into one trajectory.

- `welding`: home, the forearm through the access hole into the chassis box section and the torch lined up 4 cm off
  the seam (the scene's first pose), then seam point to seam point along the weld.
- `window`: home, the torch through the enclosure's hatch, the forearm in after it to the part, back out, above the
  side table, home.

Goals are the scene's tool poses solved to collision-free configurations by inverse kinematics (as one chain, so
consecutive seam points get neighbouring arm postures). Each leg is one query: the planner takes the straight
joint-space move where it is proved free (a seam step of a few centimetres needs no roadmap); where that move is
blocked, the tool's straight line between the two poses (app.planning.ik.tool_line: the torch pushed on through the
hatch, the forearm following) if it is proved free; and plans the others. A leg back to where an earlier leg started
(out of the hatch) takes that leg's path reversed: it is proved already.
The robot stops at home and at each pose where the job needs it at rest (a weld point, a grasp, the torch lined up
before it goes in) and nowhere else: legs joined at a pose marked `stop: false` in the scene (the torch in a hatch
on its way through) are timed as one curve, blended and certified there as at any other corner (app.motion.timing).
"""

import time
from dataclasses import dataclass, replace

import numpy as np

from app.errors import NoPath, UserError
from app.motion.path import dedupe
from app.motion.timing import BlendProof, time_path
from app.motion.trajectory import Trajectory, TrajectoryFile
from app.planning.cell import CellRoadmap
from app.planning.ik import solve_poses, tool_line
from app.planning.query import plan
from app.planning.settings import PlanSettings

HOME = "home"
# A leg of a job is short: smaller roadmap rounds and fewer shortcut rounds than a scene's default query.
JOB_SETTINGS = PlanSettings(narrow=40, uniform=40, smooth_rounds=10)
ROUTES = {
    "welding": lambda scene: [HOME] + list(scene.poses),
    "window": lambda scene: [HOME, "window", "reach", "window", "place", HOME],
}


@dataclass
class Leg:
    start: str
    goal: str
    method: str  # "straight", "tool line", "back" (an earlier leg's path reversed) or the sampler's name
    narrow_samples: int
    narrow_on_path: int
    collision_checks: int
    seconds: float
    duration: float  # of this leg within the job's motion (from its start pose to its goal pose)
    path: np.ndarray
    trajectory: Trajectory | None  # None for a leg timed with the next ones, through the pose joining them
    narrow: np.ndarray  # the leg's narrow-passage samples (empty for a straight leg)
    on_path: np.ndarray
    blends: BlendProof | None = None  # what was proved of the path where that is its blended curve (PlanResult)

    def to_json(self) -> dict:
        return {
            "from": self.start,
            "to": self.goal,
            "method": self.method,
            "narrow_samples": self.narrow_samples,
            "narrow_on_path": self.narrow_on_path,
            "collision_checks": self.collision_checks,
            "seconds": self.seconds,
            "duration": self.duration,
            "path": self.path.tolist(),
        }


@dataclass
class RunResult:
    scene: str
    sampler: str
    seed: int
    legs: list
    trajectory: Trajectory
    seconds: dict  # ik, planning, total
    collision_checks: int
    configurations: dict  # pose name -> configuration

    def to_json(self) -> dict:
        return {
            "success": True,
            "scene": self.scene,
            "sampler": self.sampler,
            "seed": self.seed,
            "legs": [leg.to_json() for leg in self.legs],
            "trajectory": self.trajectory.to_json(),
            "seconds": self.seconds,
            "collision_checks": self.collision_checks,
            "configurations": {k: v.tolist() for k, v in self.configurations.items()},
        }

    def trajectory_file(self) -> TrajectoryFile:
        """What `run --out` writes: the joined trajectory with every planned leg's narrow-passage samples."""
        narrow = [leg.narrow for leg in self.legs if len(leg.narrow)]
        on_path = [leg.on_path for leg in self.legs if len(leg.narrow)]
        return TrajectoryFile(
            scene=self.scene,
            trajectory=self.trajectory,
            narrow=np.concatenate(narrow) if narrow else None,
            on_path=np.concatenate(on_path) if on_path else None,
        )


def route(oracle, job: str) -> list[str]:
    if job not in ROUTES:
        raise UserError(f"unknown job '{job}' (known: {', '.join(ROUTES)})")
    names = ROUTES[job](oracle.scene)
    missing = [n for n in names if n != HOME and n not in oracle.scene.poses]
    if missing:
        raise UserError(f"scene {oracle.scene.name} has no pose named {', '.join(missing)}")
    return names


def run_job(oracle, job: str, settings: PlanSettings = JOB_SETTINGS, cell: CellRoadmap | None = None) -> RunResult:
    """The job's route, leg by leg: a straight move where it is free and proved, else a query with `settings` (leg i
    seeded settings.seed * 1000 + i) on `cell`, the cell's roadmap (default: a new one). Every leg answers on that
    one roadmap, so what one leg sampled and decided serves the next; with settings.full_roadmap (the paper's
    protocol) each leg builds a roadmap of its own instead."""
    seed, sampler = settings.seed, settings.sampler
    names = route(oracle, job)
    cell = cell if cell is not None else CellRoadmap(oracle)
    clock = time.perf_counter()
    checker = oracle.context()  # the job's own checks (straight moves, timing); each leg's plan counts its own
    rng = np.random.default_rng(seed)
    home = oracle.space.wrap(oracle.scene.start)
    poses = list(dict.fromkeys(n for n in names if n != HOME))
    configurations = {HOME: home, **solve_poses(oracle, rng, poses, reference=home)}
    ik_seconds = time.perf_counter() - clock

    last = len(names) - 1
    stops = [k for k, name in enumerate(names) if k in (0, last) or name not in oracle.scene.pass_through]
    # Legs that pass through a pose are timed together (_through): timing each alone would be thrown away.
    joined = {i for a, b in zip(stops[:-1], stops[1:]) if b - a > 1 for i in range(a, b)}
    planner = _LegPlanner(oracle, checker, cell, settings, rng)
    legs: list[Leg] = []
    for i, (a, b) in enumerate(zip(names[:-1], names[1:])):
        back = next((leg for leg in legs if (leg.start, leg.goal) == (b, a)), None)
        timed = i not in joined
        legs.append(planner.back(back, timed) if back else planner.leg(i, a, b, configurations, timed))

    motions = [_through(checker, legs[a:b], settings) for a, b in zip(stops[:-1], stops[1:])]
    planning = time.perf_counter() - clock - ik_seconds
    return RunResult(
        oracle.scene.name,
        sampler,
        seed,
        legs,
        join(motions, oracle),
        {"ik": ik_seconds, "planning": planning, "total": time.perf_counter() - clock},
        checker.checks + planner.planned_checks,
        configurations,
    )


class _LegPlanner:
    """The legs of one job on one cell roadmap (or, full_roadmap, a roadmap each): `back` for a leg back the way an
    earlier one came, `leg` for the others (the easy route first, else a query). Counts the checks the legs' queries
    spent, and the cell's narrow-passage samples before each leg (what a leg drew is the difference)."""

    def __init__(self, oracle, checker, cell: CellRoadmap, settings: PlanSettings, rng: np.random.Generator):
        self.oracle, self.checker, self.cell, self.settings, self.rng = oracle, checker, cell, settings, rng
        self.planned_checks = 0
        self.narrow_seen = self._narrow_in_cell()

    def _narrow_in_cell(self) -> int:
        from app.planning.roadmap import NARROW, WORKSPACE  # (scipy: loaded when a job runs)

        return sum(kind in (NARROW, WORKSPACE) for kind in self.cell.graph.kinds)

    def back(self, earlier: Leg, timed: bool) -> Leg:
        """Back out the way the job came in (out of the hatch after the part): that path is proved already."""
        t, settings = time.perf_counter(), self.settings
        path, proof = earlier.path[::-1], earlier.blends.reversed() if earlier.blends else None
        trajectory = time_path(self.checker, path, settings.dt, **_timing(settings, proof)) if timed else None
        duration = trajectory.duration if trajectory else 0.0
        none, used = np.empty((0, self.oracle.space.dim)), np.zeros(0, bool)
        seconds = time.perf_counter() - t
        return Leg(earlier.goal, earlier.start, "back", 0, 0, 0, seconds, duration, path, trajectory, none, used, proof)

    def leg(self, i: int, a: str, b: str, configurations: dict, timed: bool) -> Leg:
        """Leg i from pose a to pose b, seeded settings.seed * 1000 + i. The planner tries the easy route first: the
        straight joint move (a seam step of a few centimetres needs no roadmap), or where that is blocked the tool's
        straight line (the forearm following the torch into a hatch: the joint move between two such postures swings
        the forearm into the frame)."""
        oracle, checker, settings = self.oracle, self.checker, self.settings
        qa, qb, t, c = configurations[a], configurations[b], time.perf_counter(), checker.checks
        via = None if checker.edges_free(qa, qb, ends_free=True)[0] else tool_line(oracle, qa, qb, self.rng)
        leg_settings = replace(settings, seed=settings.seed * 1000 + i, timing=timed)
        try:
            if settings.full_roadmap:
                result = plan(oracle, leg_settings, start=qa, goal=qb, via=via)
            else:
                result = self.cell.solve(qa, qb, leg_settings, via=via)
        except NoPath as failure:  # the job's checks up to here, for a caller that counts what a failure cost
            details = getattr(failure, "details", {})
            spent = checker.checks + self.planned_checks + details.get("collision_checks", 0)
            failure.details = {**details, "job_checks": spent}
            raise
        self.planned_checks += result.collision_checks
        method = {"straight": "straight", "via": "tool line"}.get(result.route, settings.sampler)
        samples, on_path = result.narrow_samples()
        # The samples this leg drew: the roadmap it answered on (a cell's before the samples it never joined left)
        # against the cell's before it.
        drawn = result.stats.roadmap.narrow_nodes + result.stats.roadmap.workspace_nodes
        drawn -= 0 if settings.full_roadmap else self.narrow_seen
        self.narrow_seen = self._narrow_in_cell()
        used = result.narrow_on_path + result.workspace_on_path
        trajectory = result.trajectory
        return Leg(
            a,
            b,
            method,
            int(drawn),
            int(used),
            checker.checks - c + result.collision_checks,
            time.perf_counter() - t,
            trajectory.duration if trajectory else 0.0,
            result.path,
            trajectory,
            samples,
            on_path,
            result.blends,
        )


def _timing(settings: PlanSettings, proof: BlendProof | None = None, edges_proved: bool = True) -> dict:
    """time_path's keywords for a job's proved paths under `settings`' limit scaling: proved as polylines, or as
    the blended curve `proof`."""
    return {
        "edges_proved": edges_proved and proof is None,
        "proof": proof,
        "velocity_scale": settings.velocity_scale,
        "acceleration_scale": settings.acceleration_scale,
        "clearance": settings.clearance,
    }


def _through(oracle, legs: list[Leg], settings: PlanSettings) -> Trajectory:
    """The motion from rest to rest along legs that pass through the poses joining them: one curve timed over all
    their waypoints (a single leg keeps its own trajectory). Sets each leg's `duration` to its share of it."""
    if len(legs) == 1:
        return legs[0].trajectory
    paths = [dedupe(leg.path) for leg in legs]
    # Every path a query returns is certified: where as a polyline, only the blends need proving.
    try:
        W = np.vstack([paths[0]] + [p[1:] for p in paths[1:]])
        proved = all(leg.blends is None for leg in legs)
        trajectory = time_path(oracle, W, settings.dt, **_timing(settings, edges_proved=proved))
    except RuntimeError:  # Toppra found no timing of the joined curve: stop at the poses after all
        for leg in legs:
            try:
                leg.trajectory = time_path(oracle, leg.path, settings.dt, **_timing(settings, leg.blends))
            except RuntimeError as exc:
                raise NoPath(f"leg {leg.start} -> {leg.goal} found but not time-parameterized: {exc}") from None
            leg.duration = leg.trajectory.duration
        return join([leg.trajectory for leg in legs], oracle)
    ends = np.cumsum([len(p) - 1 for p in paths])  # each leg's goal among the joined waypoints
    times = trajectory.waypoint_times[np.concatenate([[0], ends])]
    for leg, duration in zip(legs, np.diff(times)):
        leg.duration = float(duration)
    return trajectory


def join(trajectories: list[Trajectory], oracle) -> Trajectory:
    """One trajectory from legs that each start where the previous one stopped, at rest (continuous angles may
    differ by whole turns between a leg's end and the next leg's start: they are shifted to continue without a
    jump)."""
    parts = {key: [] for key in ("times", "positions", "velocities", "accelerations", "waypoints", "waypoint_times")}
    offset, end = 0.0, None
    for k, leg in enumerate(trajectories):
        shift = np.zeros(oracle.space.dim)
        if end is not None:
            shift = np.where(oracle.space.continuous, np.round((end - leg.positions[0]) / (2 * np.pi)) * 2 * np.pi, 0.0)
        skip = 1 if k else 0  # the joint instant appears once
        parts["times"].append(leg.times[skip:] + offset)
        parts["positions"].append(leg.positions[skip:] + shift)
        parts["velocities"].append(leg.velocities[skip:])
        parts["accelerations"].append(leg.accelerations[skip:])
        parts["waypoints"].append(leg.waypoints[skip:] + shift)
        parts["waypoint_times"].append(leg.waypoint_times[skip:] + offset)
        offset += leg.duration
        end = leg.positions[-1] + shift
    certified = all(t.certified for t in trajectories)
    return Trajectory(
        joint_names=trajectories[0].joint_names,
        certified=certified,
        clearance=min(t.clearance for t in trajectories) if certified else None,
        position_map=trajectories[0].position_map,
        **{key: np.concatenate(value) for key, value in parts.items()},
    )


def cover(cell: CellRoadmap, seed: int = 0) -> list[dict]:
    """Join the cell's named hard regions to its roadmap: its scene's own query and every job its poses allow, each
    answered on the roadmap, which keeps the samples each joined (CellRoadmap.solve). A build's samples are spread
    over the free space and few land in a hatch; a query that must cross it then draws its own thousands, and on a
    stored roadmap paid more than with none. Returns what each cost, as the roadmap's provenance records it."""
    oracle, done = cell.oracle, []
    tasks = [("query", None)] + [(f"job {job}", job) for job in ROUTES if _has_route(oracle, job)]
    for what, job in tasks:
        try:
            if job is None:
                spent = cell.solve(settings=PlanSettings(seed=seed, timing=False)).collision_checks
            else:
                spent = run_job(oracle, job, replace(JOB_SETTINGS, seed=seed), cell).collision_checks
            solved = True
        except NoPath as failure:
            details = getattr(failure, "details", {})
            spent, solved = details.get("job_checks", details.get("collision_checks", 0)), False
        done.append({"what": what, "solved": solved, "collision_checks": int(spent)})
    cell.provenance.setdefault("covered", []).extend(done)
    return done


def _has_route(oracle, job: str) -> bool:
    """Whether the scene names the poses of the job's route, and it has a leg."""
    try:
        return len(route(oracle, job)) > 1
    except UserError:
        return False
