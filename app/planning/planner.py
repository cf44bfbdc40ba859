"""The planner: a query on a lazy PRM whose key samples come from a narrow-passage sampler.

    endpoints checked -> the straight motion -> uniform, then narrow-passage samples (the sampler's walks and
    placements in workspace gaps), in rounds until start and goal connect -> roadmap (k-nearest; lazy edge checks
    for a single query) -> shortest path -> shortcut smoothing -> the result certified free between its checked
    points -> Toppra along a blended curve

`plan(oracle, PlanSettings(...))` runs one `Query` through those phases and returns a PlanResult.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from app.checking.budget import MAX_SECONDS, SAFETY_NET_SECONDS, Budget, BudgetSpent, Stop, spell_checks
from app.checking.certify import CLEARANCE
from app.errors import InvalidEndpoint, NoPath, SamplerBudgetExceeded, UserError
from app.motion.path import FINE, Shortcuts, path_length, shortcut, unwind, verify
from app.motion.timing import BlendProof, check_duration, prove_blends, scaled_limits, time_path
from app.motion.trajectory import Trajectory, TrajectoryFile
from app.scene.shapes import CONTACT

if TYPE_CHECKING:  # the roadmap pulls in scipy: imported when planning, not when the CLI starts
    from app.planning.roadmap import Roadmap

PHASES = ("sampling", "roadmap", "search", "smoothing", "certify", "timing")
# What a query may spend unless told otherwise: every query ends, and says so when this is why. Collision checks
# decide, so the same seed gives the same answer on any machine at any load; the seconds are a safety net for a
# machine so slow that the checks would take hours, and a query they stop says that its answer depends on the machine.
DEFAULT_BUDGET = Budget(seconds=SAFETY_NET_SECONDS, checks=200_000)
# Smoothing may spend this share of the checks that finding the path took (at least SMOOTHING_MIN), and all its passes
# together (a path the certificate refused is shortened again, fine-only) SMOOTHING_CAP.
SMOOTHING_SHARE, SMOOTHING_CAP, SMOOTHING_MIN = 0.2, 0.3, 200
# How many times a smoothed path the certificate refused is smoothed again without the shortcuts that carried the
# refused edges, before the query goes careful: each repair costs a certificate, and a refused edge is bisected deep
# (the measurements behind one are on the benchmark pages, "Tuning notes").
SMOOTHING_REPAIRS = 4
# The shortest trajectory sample period: a 1 kHz controller; finer would only make files of gigabytes.
MIN_DT = 1e-3
# The smallest clearance a query may ask for (PlanSettings.clearance, CLEARANCE by default): the samples a controller
# needs for the straight lines between them to keep half of it grow as 1/sqrt(clearance).
MIN_CLEARANCE = 1e-6
# Narrow-passage samples per round once they are on: narrow/NARROW_RAMP at first, doubling every round up to
# narrow/4 -- few while a few may do, and never more than twice what the query needed.
NARROW_RAMP = 16


def default_step(scene) -> float:
    """A scene's default sampler step: its file's `step` if set; else a tenth of its largest linear extent (10 for
    the 100-unit scenes); with no linear coordinate, a tenth of the weighted diagonal of the bounds."""
    if scene.step:
        return scene.step
    extent = np.asarray(scene.upper) - np.asarray(scene.lower)
    linear = ~np.asarray(scene.angular)
    if linear.any():
        return 0.1 * float(np.max(extent[linear]))
    return 0.1 * float(np.linalg.norm(extent * scene.weights))


@dataclass(frozen=True)
class PlanSettings:
    """Everything a query may be told, validated once when built (a bad value raises UserError).

    sampler: the narrow-passage sampler's registered name; narrow / uniform: the sample counts that size a
    query's rounds (see Query) or, with full_roadmap, the whole roadmap; step: the sampler's base step a (None:
    the scene's default); budget: what the search for a path may spend (seconds and/or collision checks; Budget()
    has no limit; the default, DEFAULT_BUDGET, stops on checks, with SAFETY_NET_SECONDS as a safety net: a budget
    built here as Budget(checks=N) has no time limit unless it says seconds=..., where the command line's
    `--budget Nchecks` keeps the safety net). Its time limit bounds the whole query, the proof
    (the certificate) and timing of the path found included; its check limit bounds the search and smoothing, as
    proving and timing ask for distances, not checks; k: neighbours per node (None: k-PRM*'s);
    smooth_rounds: random shortcut rounds; dt: trajectory sample period (s); sampler_params: extra keyword
    arguments of the sampler (e.g. alpha_angle); skip_connected: Kavraki's rule for a full roadmap;
    full_roadmap: the paper's protocol (every sample drawn, every edge checked, then the query); workspace: the
    share of a query's narrow-passage samples placed in narrow gaps of the workspace (app.samplers.workspace; 0: the
    sampler alone; a full roadmap draws none); timing: time the path with Toppra (False: the result's trajectory is
    None, for a caller that times several paths as one motion, as a job does through its pass-through poses).
    velocity_scale, acceleration_scale: fractions in (0, 1] of the scene's velocity and acceleration limits that the
    trajectory keeps to (MoveIt's scaling factors); clearance: the distance (scene length units) the certified
    motion keeps from everything the scene counts (CLEARANCE; at least MIN_CLEARANCE), of which the straight lines
    between its samples and the path polyline keep at least half: start and goal must be that far off too."""

    sampler: str = "lfbs"
    narrow: int = 200
    uniform: int = 300
    step: float | None = None
    seed: int = 0
    budget: Budget = DEFAULT_BUDGET
    k: int | None = None
    smooth_rounds: int = 50
    dt: float = 0.02
    sampler_params: dict = field(default_factory=dict)
    skip_connected: bool = True
    full_roadmap: bool = False
    workspace: float = 0.75
    timing: bool = True
    velocity_scale: float = 1.0
    acceleration_scale: float = 1.0
    clearance: float = CLEARANCE

    def __post_init__(self):
        from app.samplers import check_name

        check_name(self.sampler)
        for name in ("narrow", "uniform", "smooth_rounds", "seed"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise UserError(f"{name} must be a non-negative whole number, got {value!r}")
        if self.k is not None and (isinstance(self.k, bool) or not isinstance(self.k, (int, np.integer)) or self.k < 1):
            raise UserError(f"k must be a positive whole number, got {self.k!r}")
        if isinstance(self.dt, (int, float)) and self.dt < MIN_DT:
            raise UserError(f"dt must be at least {MIN_DT:g} s (a {1 / MIN_DT:g} Hz controller), got {self.dt!r}")
        for name in ("dt", "step"):
            value = getattr(self, name)
            if value is None and name == "step":
                continue
            if (
                isinstance(value, bool)
                or not isinstance(value, (int, float, np.floating, np.integer))
                or not math.isfinite(value)
                or value <= 0
            ):
                raise UserError(f"{name} must be a positive finite number, got {value!r}")
        share = self.workspace
        if isinstance(share, bool) or not isinstance(share, (int, float)) or not 0 <= share <= 1:
            raise UserError(f"workspace must be a share from 0 to 1, got {self.workspace!r}")
        if not isinstance(self.budget, Budget):
            raise UserError(f"budget must be a Budget, got {self.budget!r}")
        for name in ("velocity_scale", "acceleration_scale"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value <= 1:
                raise UserError(f"{name} must be a fraction in (0, 1], got {value!r}")
        c = self.clearance
        if isinstance(c, bool) or not isinstance(c, (int, float)) or not MIN_CLEARANCE <= c < math.inf:
            raise UserError(f"clearance must be a finite distance of at least {MIN_CLEARANCE:g}, got {c!r}")


@dataclass
class PlanResult:
    success: bool
    scene: str
    sampler: str
    seed: int
    step: float
    start: np.ndarray
    goal: np.ndarray
    path: np.ndarray  # smoothed waypoints, wrapped (every edge fine-checked)
    roadmap_path: np.ndarray  # the roadmap's shortest path before smoothing
    trajectory: Trajectory | None  # None when PlanSettings.timing is off
    collision_checks: int
    checks: dict  # per phase
    seconds: dict  # per phase and total
    roadmap: dict
    narrow_on_path: int  # roadmap path nodes from the narrow-passage sampler
    rounds: int
    budget: str
    smoothing: dict = field(default_factory=dict)
    sampler_stats: dict = field(default_factory=dict)
    narrow_from_round: int | None = None  # the first round with narrow-passage samples (None: never needed)
    distance_queries: int = 0  # signed-distance queries of the certificates (apart from collision_checks)
    workspace_on_path: int = 0  # roadmap path nodes placed in workspace gaps
    point_queries: int = 0  # workspace points asked for their distances to obstacles, finding gaps
    certificate_seconds: float = 0.0  # the certificates' own time (set-up and every proof), Drake's queries included
    clearance: float = 0.0  # what the certificate proved the motion keeps from everything (see PlanSettings)
    # The roadmap itself (nodes `Q`, provenance `kinds`, `edges()`) and the roadmap path's node indices,
    # for viewers; not part of the JSON.
    graph: Roadmap | None = field(default=None, repr=False)
    path_nodes: list = field(default_factory=list, repr=False)
    # The certified curve of the trajectory where that, and not the polyline `path`, is what was proved
    # (smoothing["certificate"]["blended"]); for timing the path again the same way.
    blends: BlendProof | None = field(default=None, repr=False)

    def narrow_samples(self) -> tuple[np.ndarray, np.ndarray]:
        """The narrow-passage samples in the roadmap (M, dim), and which of them the roadmap path used (M,)."""
        from app.planning.roadmap import NARROW, WORKSPACE

        if self.graph is None:
            return np.empty((0, len(self.start))), np.zeros(0, bool)
        narrow = [i for i, kind in enumerate(self.graph.kinds) if kind in (NARROW, WORKSPACE)]
        used = set(self.path_nodes)
        return self.graph.Q[narrow].reshape(-1, len(self.start)), np.array([i in used for i in narrow], bool)

    def trajectory_file(self) -> TrajectoryFile:
        """What `plan --out` writes: the trajectory with the narrow-passage samples."""
        narrow, on_path = self.narrow_samples()
        return TrajectoryFile(scene=self.scene, trajectory=self.trajectory, narrow=narrow, on_path=on_path)

    def to_json(self) -> dict:
        return {
            "success": self.success,
            "scene": self.scene,
            "sampler": self.sampler,
            "seed": self.seed,
            "step": self.step,
            "start": self.start.tolist(),
            "goal": self.goal.tolist(),
            "path": self.path.tolist(),
            "roadmap_path": self.roadmap_path.tolist(),
            "path_length": self.smoothing.get("length_after"),
            "roadmap_path_length": self.smoothing.get("raw_length"),
            "trajectory": self.trajectory.to_json() if self.trajectory else None,
            "collision_checks": self.collision_checks,
            "checks": self.checks,
            "seconds": self.seconds,
            "roadmap": self.roadmap,
            "narrow_on_path": self.narrow_on_path,
            "rounds": self.rounds,
            "budget": self.budget,
            "smoothing": self.smoothing,
            "sampler_stats": self.sampler_stats,
            "narrow_from_round": self.narrow_from_round,
            "distance_queries": self.distance_queries,
            "workspace_on_path": self.workspace_on_path,
            "point_queries": self.point_queries,
            "certificate_seconds": self.certificate_seconds,
            "certified": self.certified,
            "clearance": self.clearance if self.certified else None,
        }

    @property
    def certified(self) -> bool:
        """Whether the motion returned (the timed trajectory, or without timing the path) was proved free."""
        return self.trajectory.certified if self.trajectory else bool(self.smoothing["certificate"]["proved"])


def check_endpoint(checker, q, what: str, clearance: float = CONTACT) -> np.ndarray:
    """A start or goal as a vector; wrong length or non-finite -> UserError, out of bounds, colliding or nearer
    than `clearance` to anything -> InvalidEndpoint naming the coordinate or the bodies.

    Touching (signed distance 0: a maze hull on the outer wall at its bound), or nearer than the clearance the
    motion must keep, is refused too, although the collision check calls it free: no motion out of it can be
    certified, and a query from it would spend its whole budget before failing. Refused rather than moved off,
    because which way is "off" is the user's call (a tool on a part means to touch it); the message says how close
    the bodies are, so a nudge is easy."""
    q = checker.space.check_configuration(q, what)
    bad = checker.space.out_of_bounds(q)
    code = "START_STATE_IN_COLLISION" if what == "start" else "GOAL_IN_COLLISION"
    if bad:
        raise InvalidEndpoint(
            f"{what} is out of bounds: {'; '.join(bad)}",
            "START_STATE_INVALID" if what == "start" else "GOAL_STATE_INVALID",
        )
    if not checker.is_free(q):
        pairs = checker.diagnostics.colliding_bodies(q)
        if not pairs:  # faces that touch exactly: a collision to the check, no penetration to name; name the contact
            pairs = [(a, b) for a, b, _ in checker.diagnostics.touching(q)]
        touching = ", ".join(f"{a} with {b}" for a, b in pairs[:4]) + (" ..." if len(pairs) > 4 else "")
        raise InvalidEndpoint(
            f"{what} is in collision: {touching or 'contact reported by the checker'}{_own_links(checker, pairs)}",
            code,
        )
    contacts = checker.diagnostics.touching(q, max(clearance, CONTACT))
    if contacts:
        named = ", ".join(f"{a} with {b} at {d:.2g}" for a, b, d in contacts[:4]) + (
            " ..." if len(contacts) > 4 else ""
        )
        own = _own_links(checker, contacts)
        if contacts[0][2] <= CONTACT:
            raise InvalidEndpoint(
                f"{what} touches (signed distance <= {CONTACT:g}): {named}; move it off the contact{own}", code
            )
        raise InvalidEndpoint(
            f"{what} is nearer than the clearance {clearance:g} the motion must keep: {named}; move it off, or "
            f"plan with a smaller clearance (--clearance){own}",
            code,
        )
    return checker.space.wrap(q)


def _own_links(checker, pairs) -> str:
    """For an endpoint refused over body pairs (scoped names first in each item): if two links of the robot are one
    of them, the end of the message saying how to stop checking that pair, which no move of the endpoint can help
    when the links touch by design (at a joint); else nothing."""
    links = getattr(checker.scene, "robot_links", {})
    own = [(links[a], links[b]) for a, b, *_ in pairs if a in links and b in links]
    if not own:
        return ""
    a, b = own[0]
    return (
        f"; {a} and {b} are links of the robot: if that is by design, leave the pair out with an SRDF (--srdf FILE "
        f'holding <disable_collisions link1="{a}" link2="{b}"/>; srdf: in a scene file) or do not check '
        "self-collision (--no-self-collision; collisions: environment)"
    )


def check_goals(checker, goal, clearance: float = CONTACT) -> np.ndarray:
    """One goal, or several (k, dim) of which the query may reach any (every IK solution of a tool pose), as rows.
    A single bad goal is refused as check_endpoint refuses it; among several, those that are out of bounds or collide
    are left out, and only when none is left is the first one's fault raised."""
    try:
        several = np.ndim(np.asarray(goal, float)) == 2
    except (TypeError, ValueError):  # ragged or not numbers: check_endpoint says what is wrong
        several = False
    if not several:
        return check_endpoint(checker, goal, "goal", clearance)[None, :]
    kept, faults = [], []
    for q in goal:
        try:
            kept.append(check_endpoint(checker, q, "goal", clearance))
        except InvalidEndpoint as fault:
            faults.append(fault)
    if not kept:
        if len(faults) == 1:
            raise faults[0]
        raise InvalidEndpoint(f"none of {len(faults)} goals is valid; the first: {faults[0]}", faults[0].code)
    return np.array(kept)


def plan(oracle, settings: PlanSettings | None = None, *, start=None, goal=None, via=None, cancel=None) -> PlanResult:
    """Plan from start to goal (default: the scene's) with `settings` (default: PlanSettings()); `via`: waypoints
    of the easy route to try instead of the straight motion (an arm's tool line, app.planning.ik.tool_line).

    Returns a PlanResult; raises InvalidEndpoint for a bad start or goal, NoPath (with `.details`, Query.figures)
    when the samples or the budget run out before start and goal connect (code PREEMPTED when `cancel`, a
    threading.Event, was set from another thread; TIMED_OUT when the time limit ran out), UserError for bad
    parameters. A KeyboardInterrupt (Ctrl-C) while the query runs leaves it with the same `.details`."""
    return Query(oracle, settings or PlanSettings(), start=start, goal=goal, via=via, cancel=cancel).solve()


class Samples:
    """Where a roadmap's samples come from, in rounds: placements in narrow workspace gaps (a share `workspace` of
    each round's narrow-passage samples, app.samplers.workspace), the narrow-passage sampler's walks, and uniform
    samples. Each source has its own random stream from `seeds` (a spawned SeedSequence list), so one source drawing
    more does not move another's samples; walkers still under way when a round ends go on in the next one. A query
    and a cell roadmap's build draw through this one object."""

    def __init__(self, checker, sampler: str, step: float, seeds, workspace: float, params: dict | None = None):
        from app.samplers import make_sampler

        self.checker, self.step, self.workspace = checker, step, workspace
        self._rngs = {
            "narrow": np.random.default_rng(seeds[0]),
            "uniform": np.random.default_rng(seeds[1]),
            "workspace": np.random.default_rng(seeds[3]),
        }
        self._samplers = {
            "narrow": make_sampler(sampler, checker, step=step, **(params or {})),
            "uniform": make_sampler("uniform", checker, step=step),
        }
        self.stats = {"narrow": {}, "uniform": {}, "workspace": {}}
        self._workspace_on = workspace > 0  # off once no placement can be made

    def draw(self, narrow: int, uniform: int) -> list[tuple[str, np.ndarray]]:
        """One round: `narrow` narrow-passage samples (placements first, then walks) and `uniform` uniform ones, as
        (roadmap kind, samples) pairs. SamplerBudgetExceeded when the narrow or uniform sampler cannot find its
        samples within its own check cap."""
        from app.planning.roadmap import NARROW, UNIFORM, WORKSPACE

        W = self._draw("workspace", self._placements(narrow))
        N = self._draw("narrow", narrow - len(W))
        return [(WORKSPACE, W), (NARROW, N), (UNIFORM, self._draw("uniform", uniform))]

    def _draw(self, kind: str, count: int) -> np.ndarray:
        if count <= 0:
            return np.empty((0, self.checker.space.dim))
        sampler = self._samplers[kind]
        try:
            return sampler.sample(count, self._rngs[kind], resume=True)
        except SamplerBudgetExceeded:
            if kind != "workspace":
                raise
            self._workspace_on = False  # no piece of the robot reaches the gaps found: the sampler takes over
            return np.empty((0, self.checker.space.dim))
        finally:
            totals = self.stats[kind]
            for name, value in sampler.stats.items():
                if isinstance(value, (int, float)):
                    totals[name] = totals.get(name, 0) + value

    def _placements(self, narrow: int) -> int:
        """How many of a round's `narrow` samples are placements in workspace gaps. The first time, the gaps are
        searched for (polling the budget) until one is found; a scene with none leaves them all to the sampler."""
        from app.samplers.workspace import WorkspaceGaps, WorkspaceSampler

        if narrow <= 0 or not self._workspace_on:
            return 0
        if "workspace" not in self._samplers:
            rng = self._rngs["workspace"]
            gaps = WorkspaceGaps(self.checker, rng)
            while not len(gaps.points) and not gaps.exhausted:
                self.checker.poll()
                gaps.search(rng)
            if gaps.exhausted:
                self._workspace_on = False
                return 0
            self._samplers["workspace"] = WorkspaceSampler(self.checker, gaps, step=self.step)
        return round(self.workspace * narrow)


class Query:
    """One planning query in explicit phases, as OMPL splits its PRM (setup / grow / solve):

    setup (the constructor): endpoints checked, samplers made, start and goal put in the roadmap;
    `straight()`: the easy route first -- the straight motion from start to goal (or the polyline through the
    caller's `via` points), checked at the resolution;
    `grow(narrow, uniform)`: one round of samples, added and connected to their k nearest neighbours;
    `search()`: the shortest roadmap path whose edges are free, or None while start and goal are apart;
    `smooth(nodes)`: shortcuts of that path; `certify(path)`: the result proved free between its checked points;
    `time(path)`: Toppra under the scene's limits; `solve()`: the loop that runs them and returns the result.

    How much narrow-passage effort a query spends is decided from what the roadmap shows. The straight motion is
    tried first. Then one round of cheap uniform samples with lazy edges (nothing is checked until a candidate path
    uses it): that alone solves the open queries (the UR3's, most of the tunnel's) for a few hundred checks. If
    start and goal are still apart after it, a passage uniform samples rarely hit is in the way, and the
    narrow-passage sampler joins every later round: narrow/NARROW_RAMP samples at first, doubling each round up to
    narrow/4, so a query that needs few pays for few and one that needs many spends at most twice what it needed.
    (The alternatives measured against this schedule are on the benchmark pages, "Tuning notes".)

    Three quarters of every narrow round (`workspace`) are placed rather than walked to: configurations with a piece
    of the robot in a narrow gap of the workspace (app.samplers.workspace), found by point queries against the
    obstacles. The walkers find a passage wherever obstacles leave one, but in a passage narrow in many dimensions they
    end on the obstacles' faces; placements go straight to the gap, for a tenth of a walk's checks, and the walkers
    still cover passages with no workspace gap behind them (the maze's window). Why three quarters, and what each
    source adds: the benchmark pages ("Workspace-gap placements: what share") and the ablation
    (`bench ablation`, docs/paper.md). A scene whose workspace has no narrow
    gap leaves the whole round to the sampler after a bounded search (SEARCH_LIMIT points, a few tenths of a
    second). Every collision answer polls the query's budget (`Stop`), so sampling, edge checks and smoothing all
    end when it is spent.

    `full_roadmap` is the paper's protocol instead: one round of all `narrow` + `uniform` samples, every edge
    checked, then the query."""

    def __init__(
        self,
        oracle,
        settings: PlanSettings,
        *,
        start=None,
        goal=None,
        via=None,
        cancel=None,
        roadmap=None,
        certifier=None,
    ):
        # The roadmap and samplers pull in scipy: imported when a query is made, not at CLI start-up.
        from app.planning.roadmap import GOAL, START, Roadmap

        # The query's own counters and budget on the shared oracle (its stop is set when solve() runs).
        self.oracle, self.settings = oracle, settings
        self.checker = checker = oracle.context()
        # Made now, so the budget counts the whole query, endpoint checks included; it bounds from solve() on.
        self._stop = Stop(settings.budget, checker, cancel)
        self.step = oracle.space.check_step(default_step(oracle.scene) if settings.step is None else settings.step)
        self._clock0, self._checks0 = time.perf_counter(), checker.checks
        self.seconds = dict.fromkeys(PHASES, 0.0)
        self.checks = dict.fromkeys(("endpoints",) + PHASES, 0)

        self.clearance = settings.clearance
        self.start = check_endpoint(checker, oracle.scene.start if start is None else start, "start", self.clearance)
        self.goals = check_goals(checker, oracle.scene.goal if goal is None else goal, self.clearance)
        self.goal = self.goals[0]  # until the query has reached one of them
        self.checks["endpoints"] = checker.checks - self._checks0
        if settings.timing:  # limits scaled so far down that even the straight motion would take days: refused now
            limits = scaled_limits(oracle.scene, settings.velocity_scale, settings.acceleration_scale)
            nearest = self.goals[np.argmin(oracle.space.distance(self.start, self.goals))]
            check_duration(oracle.space.unwrap(np.array([self.start, nearest])), *limits)
        # The easy route: the straight motion, or the polyline through `via`.
        via = [] if via is None or len(via) == 0 else np.atleast_2d(np.asarray(via, float))
        via = [oracle.space.check_configuration(q, "via point") for q in via]
        outside = [fault for q in via for fault in oracle.space.out_of_bounds(q)]
        if outside:
            raise UserError(f"via point out of bounds: {outside[0]}")
        self.via = via
        self.route = np.vstack([self.start, *via, self.goal])

        # A roadmap that already holds samples gets a seed of its own per size, so that its next query does not draw
        # the same samples again.
        given = roadmap is not None and len(roadmap) > 0
        seeds = np.random.SeedSequence(settings.seed, spawn_key=(len(roadmap),) if given else ()).spawn(4)
        self._smoothing_seed = seeds[2]
        workspace = 0.0 if settings.full_roadmap else settings.workspace  # a full roadmap places none
        self.samples = Samples(checker, settings.sampler, self.step, seeds, workspace, settings.sampler_params)
        self.rounds = 0
        # Narrow-passage samples from the round after the first one that left start and goal apart.
        self.narrow_from_round: int | None = 1 if settings.full_roadmap else None
        # A single query checks only the edges its candidate paths use; a full roadmap is checked whole. A persistent
        # roadmap (app.planning.cell) is handed in with every verdict it holds, and answers this query's checker.
        if roadmap is None:
            roadmap = Roadmap(
                checker, k=settings.k, skip_connected=settings.skip_connected, lazy=not settings.full_roadmap
            )
        roadmap.checker = checker
        self.roadmap = roadmap
        before = len(roadmap)
        self.start_node = roadmap.node(self.start, START)
        self.goal_nodes = [roadmap.node(g, GOAL) for g in self.goals]
        # Endpoints are connected with the first round's samples, or at once where the roadmap has nodes already.
        self._unconnected = list(dict.fromkeys([self.start_node, *self.goal_nodes]))
        self._searchable = before > 0
        self.fine = FINE * self.roadmap.resolution
        # Set once an optimistic path has failed the certificate: from then on roadmap paths must pass the fine
        # check and shortcuts are checked at the fine resolution.
        self.fine_only = False
        self.stopped: str | None = None  # why the query's work ended early: "time", "checks" or "cancelled"
        # Made when the first path is to be proved (it sets up per-geometry bounds), or a persistent roadmap's, whose
        # cached distances serve every query on it.
        self.certifier = certifier
        if certifier is not None:
            certifier.checker = checker
        # What the shared certifier had spent before this query: the answer reports only this query's share.
        self._certificate_before = certifier.seconds if certifier is not None else 0.0
        self.unproved_edges = 0  # roadmap edges fine-checked free that the certificate could not prove
        self.proof_unfinished = False  # the budget ended the proof or timing of a path found
        self.blends: BlendProof | None = None  # the curve of the last path whose blends were proved (certify_blends)

    # ---- bookkeeping ----------------------------------------------------------------------------------------------
    def _timed(self, phase: str, fn, *args, **kwargs):
        t, c = time.perf_counter(), self.checker.checks
        try:
            return fn(*args, **kwargs)
        finally:
            self.seconds[phase] += time.perf_counter() - t
            self.checks[phase] += self.checker.checks - c

    def elapsed(self) -> tuple[float, int]:
        """Seconds and collision checks spent since the query was made."""
        return time.perf_counter() - self._clock0, self.checker.checks - self._checks0

    # ---- the easy route -----------------------------------------------------------------------------------------
    def straight(self) -> bool:
        """Whether an easy route (the straight motion from start to a goal, or the polyline through `via`; the
        nearest goal first) is free at the resolution (one batched edge check each; the certificate then proves it
        between the checked points); it is then `route`, and its goal `goal`. Via points are checked too: only the
        endpoints are known free."""
        resolution = self.roadmap.resolution
        for g in self.goals[np.argsort(self.checker.space.distance(self.start, self.goals), kind="stable")]:
            R = np.vstack([self.start, *self.via, g])
            free = self._timed("search", self.checker.edges_free, R[:-1], R[1:], resolution, ends_free=len(R) == 2)
            if free.all():
                self.route, self.goal = R, g
                return True
        return False

    # ---- grow -------------------------------------------------------------------------------------------------------
    def round_sizes(self) -> tuple[int, int] | None:
        """How many narrow and uniform samples the next round draws, or None when the query may draw no more."""
        s = self.settings
        if s.full_roadmap:
            return (s.narrow, s.uniform) if self.rounds == 0 else None
        if s.narrow == 0 and s.uniform == 0:
            return None
        if self.narrow_from_round is None or self.rounds + 1 < self.narrow_from_round:
            return 0, math.ceil(s.uniform / 4)
        k = self.rounds + 1 - self.narrow_from_round
        return min(math.ceil(s.narrow / 4), math.ceil(s.narrow / NARROW_RAMP) * 2**k), math.ceil(s.uniform / 4)

    def grow(self, narrow: int, uniform: int) -> np.ndarray:
        """One round: draw the samples, add them as nodes (the first round also connects start and goal) and
        connect the new nodes to their neighbours. Returns the new nodes."""

        self.rounds += 1
        try:
            drawn = self._timed("sampling", self.samples.draw, narrow, uniform)
        except SamplerBudgetExceeded as exc:
            raise self._failure(f"no path on {self.checker.scene.name}: {exc}", sampler=str(exc)) from None
        new = np.concatenate([self.roadmap.add(Q, kind, connect=False) for kind, Q in drawn])
        new = np.concatenate([np.array(self._unconnected, int), new])
        self._unconnected = []
        self._timed("roadmap", self.roadmap.connect, new)
        return new

    # ---- solve ------------------------------------------------------------------------------------------------------
    def search(self) -> list[int] | None:
        """Node indices of the shortest start-goal path whose edges are checked free, or None while start and goal
        are apart. Once the certificate has refused a roadmap edge of a careful (fine-only) query, the path's edges
        are checked at the fine resolution too and those failing it are dropped: a cheap filter where many edges
        slip between checked points, work for nothing where the certificate proves them all (benchmark pages)."""
        roadmap = self.roadmap
        while True:
            nodes = self._timed("search", roadmap.shortest_path, self.start_node, self.goal_nodes)
            if nodes is None or not (self.fine_only and self.unproved_edges):
                return nodes
            ok = self._timed("search", verify, self.checker, roadmap.Q[nodes], self.fine)
            if ok.all():
                return nodes
            for i in np.flatnonzero(~ok):
                roadmap.remove_edge(nodes[i], nodes[i + 1])

    def smooth(self, nodes: list[int], memo: Shortcuts | None = None) -> tuple[np.ndarray, dict]:
        """The roadmap path shortened (same seed, same shortcuts), at the fine resolution when fine-only, spending
        at most SMOOTHING_SHARE of the checks that finding it took, SMOOTHING_CAP with the passes before: a path
        is worth shortening, not at any price. `memo`: what an earlier pass on the same path checked and banned."""
        outer, raw = self.checker.stop, self.roadmap.Q[nodes]
        memo = memo if memo is not None else Shortcuts()
        resolution = self.fine if self.fine_only else self.checker.space.resolution
        if outer is not None:
            spent = self.checks["smoothing"]
            finding = self.elapsed()[1] - spent
            share = max(SMOOTHING_MIN, int(SMOOTHING_SHARE * finding))
            self.checker.stop = outer.within(max(0, min(share, int(SMOOTHING_CAP * finding) - spent)))
        try:
            path, stats = self._timed(
                "smoothing",
                shortcut,
                self.checker,
                raw,
                np.random.default_rng(self._smoothing_seed),
                rounds=self.settings.smooth_rounds,
                resolution=resolution,
                memo=memo,
            )
        finally:
            self.checker.stop = outer
        # Not held to the cap: a path that winds a joint a whole turn more than it needs is worth a pass of checks.
        if stats["stopped"]:
            path = self._timed("smoothing", unwind, self.checker, path, resolution, stats, memo)
        stats["fine_only"] = self.fine_only
        return path, stats

    def certify(self, path: np.ndarray, edges=None) -> tuple[bool, dict]:
        """Whether every straight edge of `path` (or those of `edges`, indices into it) is free in the continuous
        sense (app.checking.certify: signed distances at the ends exceed how far any point of the robot can travel
        along the edge, bisected where they do not); stats["failed"] lists the edges that could not be proved."""
        from app.checking.certify import polyline

        self._make_certifier()
        # A segment that is a roadmap edge proved before with this clearance or more (by this query, or by an
        # earlier one on a persistent roadmap, in this process) is not proved again; one proved now is remembered.
        pairs = self.roadmap.edge_pairs(path)
        known = self.roadmap.proved_with(pairs, self.clearance)
        edges = [i for i in (range(len(path) - 1) if edges is None else edges) if not known[i]]
        if not edges:
            return True, {"failed": [], "pieces": 0, "distance_queries": 0, "seconds": 0.0, "blended": False}
        curve = polyline(self.checker.space, path)
        proved, stats = self._timed(
            "certify", self.certifier.certify, curve, [(i, i + 1) for i in edges], self.clearance
        )
        failed = [edges[k] for k in stats["failed"]]
        self.roadmap.mark_proved([pairs[i] for i in edges if i not in failed], self.clearance)
        return proved, {**stats, "failed": failed, "blended": False}

    def certify_blends(self, path: np.ndarray) -> tuple[bool, dict]:
        """Whether the curve the robot will follow along `path` is free in the continuous sense: its corners blended
        as timing blends them (a blend that cannot be proved tightened, at last a stop), the straight parts between
        them proved, the corners the blends cut off not (app.motion.timing.prove_blends). stats["failed"] lists the
        edges whose straight part could not be proved; the proof is kept for `time`. For a path that is timed:
        without timing the polyline itself is the answer, and `certify` proves it."""
        self._make_certifier()
        known = np.flatnonzero(self.roadmap.proved_with(self.roadmap.edge_pairs(path), self.clearance))
        self.blends = self._timed("certify", prove_blends, self.certifier, path, known, self.clearance)
        return not self.blends.failed, {**self.blends.cost, "failed": self.blends.failed, "blended": True}

    def _make_certifier(self) -> None:
        """The query's certifier, made when the first path is to be proved (it sets up per-geometry bounds: time of
        the "certify" phase)."""
        from app.checking.certify import Certifier

        if self.certifier is None:
            self.certifier = self._timed("certify", Certifier, self.checker)

    def smooth_and_prove(self, nodes: list[int], proof: dict | None = None) -> tuple[np.ndarray, dict, dict | None]:
        """(smoothed path, smoothing stats, its certificate or None when it could not be proved; `proof`: the roadmap
        path's, if it has one, so that an unshortened path is not proved twice). A refused edge
        that lies on a shortcut bans that shortcut, and smoothing is replayed from the roadmap path: the replay repeats
        the same shortcuts for free (Shortcuts remembers every check) up to the banned one and then spends what is
        left of the smoothing cap; at most SMOOTHING_REPAIRS times. Undoing one grazing shortcut keeps the others,
        where falling back to the unsmoothed path would lose them all."""
        memo, proved_edges, work = Shortcuts(), set(), {"pieces": 0, "distance_queries": 0, "seconds": 0.0}
        for repairs in itertools.count():
            path, stats = self.smooth(nodes, memo)
            stats["repairs"] = repairs
            if proof is not None and np.array_equal(path, self.roadmap.Q[nodes]):
                return path, stats, proof
            with self._proving():
                # The curve the robot follows first. A path it refuses grazes something: from then on the
                # polyline, which a blended proof spends blends on before it finds the failing edges (single
                # queries: benchmark pages); where it passes, timing proves the blends, or makes stops of them.
                proved = False
                if self.settings.timing and repairs == 0 and not self.fine_only:
                    proved, certificate = self.certify_blends(path)
                    work = {k: work[k] + certificate[k] for k in work}
                if not proved:  # edges the replay kept were proved already
                    keys = [path[i : i + 2].tobytes() for i in range(len(path) - 1)]
                    proved, certificate = self.certify(path, [i for i, k in enumerate(keys) if k not in proved_edges])
                    proved_edges.update(k for i, k in enumerate(keys) if i not in certificate["failed"])
                    work = {k: work[k] + certificate[k] for k in work}
            if proved:
                return path, stats, {**certificate, **work}
            if repairs == SMOOTHING_REPAIRS or not memo.ban_carriers(self.checker.space, path, certificate["failed"]):
                return path, stats, None

    def connect_and_smooth(self) -> tuple[list[int], np.ndarray, dict] | None:
        """(roadmap path, smoothed path, smoothing stats) once start and goal connect, else None.

        Optimistic first: the roadmap path is shortened with shortcuts checked at the planning resolution, and the
        result proved by the certificate (continuous, app.checking.certify) -- a discrete re-check at a finer
        resolution would only repeat part of its work. If the certificate refuses it, something grazes an obstacle
        between checked points, as in a narrow passage: the query turns careful (fine-only). From then on a roadmap
        path is proved before any smoothing is spent on it (and fine-checked first once an edge has been refused:
        `search`); an edge the certificate cannot prove is treated as colliding, leaves the roadmap, and the search
        goes on (more rounds if need be). Proved edges are remembered, so the next candidate pays only for its new
        ones. The proved path is then shortened with shortcuts checked at the fine resolution, and if that cannot be
        proved either, the roadmap path is the answer.
        Paths are never returned unproved: the audit found that such paths can really collide (benchmark pages,
        "Tuning notes"). Certificates keep to the query's time limit, not to its check limit (`_proving`)."""
        while True:
            nodes = self.search()
            if nodes is None:
                return None
            if not self.fine_only:
                path, stats, certificate = self.smooth_and_prove(nodes)
                if certificate is not None:
                    break
                self.fine_only = True
                continue
            raw_proof = self._prove_roadmap_path(nodes)
            if raw_proof is None:
                continue
            path, stats, certificate = self.smooth_and_prove(nodes, raw_proof)
            if certificate is None:
                path, stats, certificate = self.roadmap.Q[nodes], {**stats, "smoothing_dropped": True}, raw_proof
            break
        proof = {**certificate, "proved": True, "unproved_edges_dropped": self.unproved_edges}
        return nodes, path, {**stats, "certificate": proof}

    def _prove_roadmap_path(self, nodes: list[int]) -> dict | None:
        """The certificate of the roadmap path through `nodes` (its edges not proved before), or None when it cannot
        be proved; then its unprovable edges have left the roadmap."""
        edges = [(min(a, b), max(a, b)) for a, b in itertools.pairwise(nodes)]
        with self._proving():
            proved, certificate = self.certify(self.roadmap.Q[nodes])
        if proved:
            return certificate
        for i in certificate["failed"]:
            self.roadmap.remove_edge(*edges[i])
        self.unproved_edges += len(certificate["failed"])
        if self.checker.stop is not None:  # certificates ask no collision checks, so the budget is polled here
            self.checker.stop.allow(0)
        return None

    def time(self, path: np.ndarray, proved: bool = False) -> Trajectory:
        """Toppra along the path with its corners blended where the blends can be proved free (app.motion.timing);
        proved: the path's edges are certified already (by this query's certifier), so only the blends need to be,
        unless its blended curve is (certify_blends), whose radii are then used."""
        blends = self.blends
        if blends is None or blends.failed or not np.array_equal(blends.path, path):
            blends = None
        try:
            return self._timed(
                "timing",
                time_path,
                self.checker,
                path,
                self.settings.dt,
                certifier=self.certifier,
                edges_proved=proved and blends is None,
                proof=blends,
                clearance=self.clearance,
                velocity_scale=self.settings.velocity_scale,
                acceleration_scale=self.settings.acceleration_scale,
            )
        except (RuntimeError, ValueError) as exc:  # Toppra infeasible, or limits that are not positive
            raise self._failure(
                f"path found on {self.checker.scene.name} but not time-parameterized: {' '.join(str(exc).split())}"
            ) from None

    def solve(self) -> PlanResult:
        """The easy route (straight, or through `via`) if it is free and proved; else grow round by round until start
        and goal connect, then smooth, certify and time the path. A time limit bounds all of it; a check limit
        bounds the search and smoothing, not the proof and timing (they ask for distances, not checks)."""
        self.checker.stop = self._stop
        try:
            found = self._find()
            if found is not None:
                with self._proving():
                    return self._result(*found)
        except BudgetSpent as spent:
            self.stopped = spent.reason
        except KeyboardInterrupt as interrupt:
            # Ctrl-C stays an interrupt (the command line answers PREEMPTED, exit code 130), carrying what the query
            # had spent, as a failure's NoPath.details does.
            interrupt.details = self.figures("interrupted")
            raise
        finally:
            self.checker.stop = None
        if self.proof_unfinished:
            raise self._failure(
                f"a path was found on {self.checker.scene.name} but proving and timing it did not finish within the "
                f"budget {self.settings.budget} ({self.stopped}): a larger time budget lets it finish"
            )
        raise self._not_connected()

    def _find(self) -> tuple | None:
        """The arguments of `_result` for the easy route or a smoothed roadmap path (proved), or None when the
        samples run out first; BudgetSpent when the budget does."""
        if self.straight():
            path = self.route
            with self._proving():
                proved, certificate = self.certify(path)
            if proved:  # else the roadmap may find a route it can prove
                nodes = [self.start_node, self.goal_nodes[self._goal_index(self.goal)]]
                return (
                    nodes,
                    path,
                    {"straight": True, "via": len(path) - 2, "certificate": {**certificate, "proved": True}},
                    path,
                )
        found = None
        if self._searchable:  # a persistent roadmap: search what it holds before drawing any sample
            self._timed("roadmap", self.roadmap.connect, np.array(self._unconnected, int))
            self._unconnected = []
            found = self.connect_and_smooth()
        sizes = None if found is not None else self.round_sizes()
        while sizes is not None:
            self.grow(*sizes)
            found = self.connect_and_smooth()
            if found is not None:
                break
            if self.narrow_from_round is None:  # uniform samples alone did not do it: a passage in the way
                self.narrow_from_round = self.rounds + 1
            sizes = self.round_sizes()
        return found

    @contextlib.contextmanager
    def _proving(self):
        """Proving or timing a path found: past the check limit (what it asks of Drake are distances, not the checks
        a budget counts) but within the time limit and the cancel flag, so a timed query's answer keeps to its
        time. Remembers when the budget ended a proof, for the failure's message."""
        saved = self.checker.stop
        self.checker.stop = None if saved is None else saved.without_check_limit()
        try:
            yield
        except BudgetSpent:
            self.proof_unfinished = True
            raise
        finally:
            self.checker.stop = saved

    def _goal_index(self, q: np.ndarray) -> int:
        return int(np.argmin(self.checker.space.distance(q, self.goals)))

    # ---- answers ----------------------------------------------------------------------------------------------------
    def figures(self, stopped: str | None = None) -> dict:
        """What the query has spent so far, counted as a success answer counts it (PlanResult): collision checks in
        all and per phase, distance and point queries, seconds per phase and in total, rounds, the roadmap, the
        budget, and why it stopped (`stopped`, else the budget's reason: "time", "checks", "cancelled", or None)."""
        seconds, spent = self.elapsed()
        return {
            "collision_checks": spent,
            "checks": dict(self.checks),
            "distance_queries": self.checker.distance_queries,
            "point_queries": self.checker.point_queries,
            "certificate_seconds": 0.0 if self.certifier is None else self.certifier.seconds - self._certificate_before,
            "seconds": {**self.seconds, "total": seconds},
            "rounds": self.rounds,
            "roadmap": self.roadmap.stats(),
            "budget": str(self.settings.budget),
            "stopped": stopped or self.stopped,
        }

    def _failure(self, message: str, **details) -> NoPath:
        """NoPath with the query's figures in `details`. Its code says why: PREEMPTED when cancelled, TIMED_OUT when
        the time limit ended it (MoveIt's code for time), else PLANNING_FAILED -- a spent check limit too, whose
        details say stopped: "checks"."""
        code = {"cancelled": "PREEMPTED", "time": "TIMED_OUT"}.get(self.stopped)
        error = NoPath(message, code)
        error.details = {**self.figures(), **details}
        return error

    def _not_connected(self) -> NoPath:
        stats, s = self.roadmap.stats(), self.settings
        sizes = self.roadmap.component_sizes(self.start_node, *self.goal_nodes)
        seconds, spent = self.elapsed()
        if self.stopped == "cancelled":
            ending = ", cancelled"
        elif self.stopped == "checks":
            ending = (
                f"; budget of {s.budget.checks} collision check{'s' if s.budget.checks != 1 else ''} spent (stopped: "
                f"checks): a larger one may find a path, try --budget {s.budget.larger(seconds)}"
            )
        elif self.stopped == "time" and s.budget.checks is not None:
            ending = (
                f", stopped by the budget's {s.budget.seconds:g} s before its {s.budget.checks} checks were spent: "
                "on a faster or less loaded machine the same seed may get further; --budget "
                f"{spell_checks(s.budget.checks)},nolimit lets the checks alone decide"
            )
        elif self.stopped == "time":
            ending = (
                f"; time limit of {s.budget.seconds:g} s spent (stopped: time): try a longer one, e.g. --budget "
                f"{min(MAX_SECONDS, 10 * s.budget.seconds):g}s"
            )
        else:
            ending = "; the roadmap may not grow further"
        if self.unproved_edges:
            ending += f"; {self.unproved_edges} edge(s) checked free but not provably free were dropped"
        return self._failure(
            f"no path from start to goal on {self.checker.scene.name}: roadmap of {stats['nodes']} nodes "
            f"({stats['narrow_nodes']} narrow-passage samples from {s.sampler}, {stats['uniform_nodes']} uniform), "
            f"start and goal not joined by edges checked free; {stats['edges_tried']} edges decided, {spent} "
            f"collision checks, {seconds:.1f} s, {self.rounds} round(s)" + ending,
            components_of_start_goal=sizes,
            unproved_edges=self.unproved_edges,
        )

    def _result(self, nodes: list[int], path: np.ndarray, stats: dict, raw: np.ndarray | None = None) -> PlanResult:
        """raw: the path before smoothing (default: the roadmap's through `nodes`)."""
        from app.planning.roadmap import NARROW, WORKSPACE

        roadmap, s = self.roadmap, self.settings
        raw = roadmap.Q[nodes] if raw is None else raw
        self.goal = self.goals[self._goal_index(raw[-1])]
        stats["raw_length"] = path_length(self.checker, raw)
        stats["length_after"] = path_length(self.checker, path)
        trajectory = self.time(path, stats["certificate"]["proved"]) if s.timing else None
        self.seconds["total"] = self.elapsed()[0]
        return PlanResult(
            success=True,
            scene=self.checker.scene.name,
            sampler=s.sampler,
            seed=int(s.seed),
            step=self.step,
            start=self.start,
            goal=self.goal,
            path=path,
            roadmap_path=raw,
            trajectory=trajectory,
            collision_checks=self.elapsed()[1],
            checks=self.checks,
            seconds=self.seconds,
            roadmap=roadmap.stats(),
            narrow_on_path=int(sum(roadmap.kinds[i] == NARROW for i in nodes)),
            rounds=self.rounds,
            budget=str(s.budget),
            smoothing=stats,
            sampler_stats=self.samples.stats,
            narrow_from_round=self.narrow_from_round,
            graph=roadmap,
            path_nodes=list(nodes),
            distance_queries=self.checker.distance_queries,
            workspace_on_path=int(sum(roadmap.kinds[i] == WORKSPACE for i in nodes)),
            point_queries=self.checker.point_queries,
            certificate_seconds=0.0 if self.certifier is None else self.certifier.seconds - self._certificate_before,
            clearance=self.clearance,
            blends=self.blends if stats["certificate"].get("blended") else None,
        )
