"""The planner: a query on a lazy PRM whose key samples come from a narrow-passage sampler.

    endpoints checked -> narrow + uniform samples, in rounds until start and goal connect -> roadmap (k-nearest;
    lazy edge checks for a single query) -> shortest path -> shortcut smoothing -> the result re-checked at 1/4
    resolution -> Toppra per segment

`plan(oracle, PlanSettings(...))` runs one `Query` through those phases and returns a PlanResult.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from app.budget import Budget
from app.errors import InvalidEndpoint, NoPath, SamplerBudgetExceeded, UserError
from app.path import FINE, path_length, shortcut, verify
from app.timing import parameterize
from app.trajectory import Trajectory, TrajectoryFile

if TYPE_CHECKING:  # the roadmap pulls in scipy and networkx: imported when planning, not when the CLI starts
    from app.roadmap import Roadmap

PHASES = ("sampling", "roadmap", "search", "smoothing", "timing")


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

    sampler: the narrow-passage sampler's registered name; narrow / uniform: how many samples of each (per round
    a quarter, unless full_roadmap); step: the sampler's base step a (None: the scene's default); budget: keep
    adding rounds past those counts until connected or spent; k: neighbours per node (None: k-PRM*'s);
    smooth_rounds: random shortcut rounds; dt: trajectory sample period (s); sampler_params: extra keyword
    arguments of the sampler (e.g. alpha_angle); skip_connected: Kavraki's rule for a full roadmap;
    full_roadmap: the paper's protocol (every sample drawn, every edge checked, then the query)."""

    sampler: str = "lfbs"
    narrow: int = 200
    uniform: int = 300
    step: float | None = None
    seed: int = 0
    budget: Budget | None = None
    k: int | None = None
    smooth_rounds: int = 50
    dt: float = 0.02
    sampler_params: dict = field(default_factory=dict)
    skip_connected: bool = True
    full_roadmap: bool = False

    def __post_init__(self):
        from app.samplers import check_name

        check_name(self.sampler)
        for name in ("narrow", "uniform", "smooth_rounds", "seed"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise UserError(f"{name} must be a non-negative whole number, got {value!r}")
        if self.k is not None and (isinstance(self.k, bool) or not isinstance(self.k, (int, np.integer))
                                   or self.k < 1):
            raise UserError(f"k must be a positive whole number, got {self.k!r}")
        for name in ("dt", "step"):
            value = getattr(self, name)
            if value is None and name == "step":
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) \
                    or not math.isfinite(value) or value <= 0:
                raise UserError(f"{name} must be a positive finite number, got {value!r}")
        if self.budget is not None and not isinstance(self.budget, Budget):
            raise UserError(f"budget must be a Budget, got {self.budget!r}")


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
    trajectory: Trajectory
    collision_checks: int
    checks: dict  # per phase
    seconds: dict  # per phase and total
    roadmap: dict
    narrow_on_path: int
    rounds: int
    budget: str
    smoothing: dict = field(default_factory=dict)
    sampler_stats: dict = field(default_factory=dict)
    # The roadmap itself (nodes `Q`, provenance `kinds`, networkx `graph`) and the roadmap path's node indices,
    # for viewers; not part of the JSON.
    graph: "Roadmap | None" = field(default=None, repr=False)
    path_nodes: list = field(default_factory=list, repr=False)

    def narrow_samples(self) -> tuple[np.ndarray, np.ndarray]:
        """The narrow-passage samples in the roadmap (M, dim), and which of them the roadmap path used (M,)."""
        from app.roadmap import NARROW

        if self.graph is None:
            return np.empty((0, len(self.start))), np.zeros(0, bool)
        narrow = [i for i, kind in enumerate(self.graph.kinds) if kind == NARROW]
        used = set(self.path_nodes)
        return self.graph.Q[narrow].reshape(-1, len(self.start)), np.array([i in used for i in narrow], bool)

    def trajectory_file(self) -> TrajectoryFile:
        """What `plan --out` writes: the trajectory with the narrow-passage samples."""
        narrow, on_path = self.narrow_samples()
        return TrajectoryFile(scene=self.scene, trajectory=self.trajectory, narrow=narrow, on_path=on_path)

    def to_json(self) -> dict:
        return {
            "success": self.success, "scene": self.scene, "sampler": self.sampler, "seed": self.seed,
            "step": self.step, "start": self.start.tolist(), "goal": self.goal.tolist(),
            "path": self.path.tolist(), "roadmap_path": self.roadmap_path.tolist(),
            "path_length": self.smoothing.get("length_after"), "roadmap_path_length": self.smoothing.get("raw_length"),
            "trajectory": self.trajectory.to_json(), "collision_checks": self.collision_checks,
            "checks": self.checks, "seconds": self.seconds, "roadmap": self.roadmap,
            "narrow_on_path": self.narrow_on_path, "rounds": self.rounds, "budget": self.budget,
            "smoothing": self.smoothing, "sampler_stats": self.sampler_stats,
        }


def check_endpoint(oracle, q, what: str) -> np.ndarray:
    """A start or goal as a vector; wrong length or non-finite -> UserError, out of bounds or colliding ->
    InvalidEndpoint naming the coordinate or the touching bodies."""
    q = oracle.space.check_configuration(q, what)
    bad = oracle.space.out_of_bounds(q)
    if bad:
        raise InvalidEndpoint(f"{what} is out of bounds: {'; '.join(bad)}")
    if not oracle.is_free(q):
        pairs = oracle.colliding_bodies(q)
        touching = ", ".join(f"{a} with {b}" for a, b in pairs[:4]) + (" ..." if len(pairs) > 4 else "")
        raise InvalidEndpoint(f"{what} is in collision: {touching or 'contact reported by the checker'}")
    return oracle.space.wrap(q)


def plan(oracle, settings: PlanSettings | None = None, *, start=None, goal=None) -> PlanResult:
    """Plan from start to goal (default: the scene's) with `settings` (default: PlanSettings()).

    Returns a PlanResult; raises InvalidEndpoint for a bad start or goal, NoPath (with `.details`) when the
    samples or the budget run out before start and goal connect, UserError for bad parameters."""
    return Query(oracle, settings or PlanSettings(), start=start, goal=goal).solve()


class Query:
    """One planning query in explicit phases, as OMPL splits its PRM (setup / grow / solve):

    setup (the constructor): endpoints checked, samplers made, start and goal put in the roadmap;
    `grow()`: one round of narrow and uniform samples, added and connected to their k nearest neighbours;
    `search()`: the shortest roadmap path whose edges are free, or None while start and goal are apart;
    `smooth(nodes)`: shortcuts of that path, checked at the planning resolution (fine-only: the fine one);
    `recheck(path)`: the smoothed path checked again at FINE x the resolution;
    `time(path)`: Toppra under the scene's limits; `solve()`: the loop that runs them and returns the result.

    Rounds are a quarter of `narrow` and `uniform` each, and the loop stops at the first round after which start
    and goal connect: a single query needs no more roadmap than that. With `full_roadmap` the first round is the
    whole `narrow` + `uniform` (the paper's protocol). With a budget, quarter rounds go on past those counts until
    start and goal connect or the budget is spent."""

    def __init__(self, oracle, settings: PlanSettings, *, start=None, goal=None):
        # The roadmap and samplers pull in scipy and networkx: imported when a query is made, not at CLI start-up.
        from app.roadmap import GOAL, START, Roadmap
        from app.samplers import make_sampler

        self.oracle, self.settings = oracle, settings
        self.step = default_step(oracle.scene) if settings.step is None else float(settings.step)
        self._clock0, self._checks0 = time.perf_counter(), oracle.checks
        self.seconds = dict.fromkeys(PHASES, 0.0)
        self.checks = dict.fromkeys(("endpoints",) + PHASES, 0)

        self.start = check_endpoint(oracle, oracle.scene.start if start is None else start, "start")
        self.goal = check_endpoint(oracle, oracle.scene.goal if goal is None else goal, "goal")
        self.checks["endpoints"] = oracle.checks - self._checks0

        seeds = np.random.SeedSequence(settings.seed).spawn(3)
        self._rngs = {"narrow": np.random.default_rng(seeds[0]), "uniform": np.random.default_rng(seeds[1])}
        self._smoothing_seed = seeds[2]
        self._samplers = {"narrow": make_sampler(settings.sampler, oracle, step=self.step, **settings.sampler_params),
                          "uniform": make_sampler("uniform", oracle, step=self.step)}
        self.sampler_stats = {"narrow": {}, "uniform": {}}
        self.drawn = {"narrow": 0, "uniform": 0}
        self.rounds = 0
        # A single query checks only the edges its candidate paths use; a full roadmap is checked whole.
        self.roadmap = Roadmap(oracle, k=settings.k, skip_connected=settings.skip_connected,
                               lazy=not settings.full_roadmap)
        self.start_node = int(self.roadmap.add(self.start, START, connect=False)[0])
        self.goal_node = int(self.roadmap.add(self.goal, GOAL, connect=False)[0])
        self.fine = FINE * self.roadmap.resolution
        # Set once an optimistic path has failed the fine re-check: from then on roadmap paths must pass the fine
        # check and shortcuts are checked at the fine resolution.
        self.fine_only = False

    # ---- bookkeeping ----------------------------------------------------------------------------------------------
    def _timed(self, phase: str, fn, *args, **kwargs):
        t, c = time.perf_counter(), self.oracle.checks
        out = fn(*args, **kwargs)
        self.seconds[phase] += time.perf_counter() - t
        self.checks[phase] += self.oracle.checks - c
        return out

    def elapsed(self) -> tuple[float, int]:
        """Seconds and collision checks spent since the query was made."""
        return time.perf_counter() - self._clock0, self.oracle.checks - self._checks0

    # ---- grow -------------------------------------------------------------------------------------------------------
    def round_sizes(self) -> tuple[int, int] | None:
        """How many narrow and uniform samples the next round draws, or None when the query may draw no more."""
        s = self.settings
        if self.rounds == 0 and s.full_roadmap:
            return s.narrow, s.uniform
        quarter = math.ceil(s.narrow / 4), math.ceil(s.uniform / 4)
        if self.rounds == 0:
            return quarter
        if s.narrow == 0 and s.uniform == 0:
            return None
        if s.budget is None:
            if self.drawn["narrow"] >= s.narrow and self.drawn["uniform"] >= s.uniform:
                return None
            return min(quarter[0], s.narrow - self.drawn["narrow"]), min(quarter[1], s.uniform - self.drawn["uniform"])
        return None if s.budget.spent(*self.elapsed()) else quarter

    def _draw(self, kind: str, count: int) -> np.ndarray:
        """`count` samples from the narrow or uniform sampler, resuming its walkers; a sampler that cannot find
        them within its check cap (or the budget's) makes the query fail."""
        if count <= 0:
            return np.empty((0, self.oracle.space.dim))
        sampler, budget = self._samplers[kind], self.settings.budget
        if budget is not None and budget.checks is not None:  # a sampler may not overrun a check budget
            sampler.max_checks = min(sampler.max_checks, max(1, budget.checks - self.elapsed()[1]))
        try:  # resume: walkers still under way when a round ends go on in the next one
            return sampler.sample(count, self._rngs[kind], resume=True)
        except SamplerBudgetExceeded as exc:
            raise self._failure(f"no path on {self.oracle.scene.name}: {exc}", sampler=str(exc)) from None
        finally:
            totals = self.sampler_stats[kind]
            for name, value in sampler.stats.items():
                if isinstance(value, (int, float)):
                    totals[name] = totals.get(name, 0) + value

    def grow(self, narrow: int, uniform: int) -> np.ndarray:
        """One round: draw the samples, add them as nodes (the first round also connects start and goal) and
        connect the new nodes to their neighbours. Returns the new nodes."""
        from app.roadmap import NARROW, UNIFORM

        self.rounds += 1
        N = self._timed("sampling", self._draw, "narrow", narrow)
        U = self._timed("sampling", self._draw, "uniform", uniform)
        self.drawn["narrow"] += len(N)
        self.drawn["uniform"] += len(U)
        new = np.concatenate([self.roadmap.add(N, NARROW, connect=False), self.roadmap.add(U, UNIFORM, connect=False)])
        if self.rounds == 1:
            new = np.concatenate([[self.start_node, self.goal_node], new])
        self._timed("roadmap", self.roadmap.connect, new)
        return new

    # ---- solve ------------------------------------------------------------------------------------------------------
    def search(self) -> list[int] | None:
        """Node indices of the shortest start-goal path whose edges are checked free (fine-only: at the fine
        resolution too; edges failing it are dropped), or None while start and goal are apart."""
        roadmap = self.roadmap
        while True:
            nodes = self._timed("search", roadmap.shortest_path, self.start_node, self.goal_node)
            if nodes is None or not self.fine_only:
                return nodes
            ok = self._timed("search", verify, self.oracle, roadmap.Q[nodes], self.fine)
            if ok.all():
                return nodes
            for i in np.flatnonzero(~ok):
                roadmap.remove_edge(nodes[i], nodes[i + 1])

    def smooth(self, nodes: list[int]) -> tuple[np.ndarray, dict]:
        """The roadmap path shortened (same seed, same shortcuts), at the fine resolution when fine-only."""
        path, stats = self._timed("smoothing", shortcut, self.oracle, self.roadmap.Q[nodes],
                                  np.random.default_rng(self._smoothing_seed), rounds=self.settings.smooth_rounds,
                                  resolution=self.fine if self.fine_only else None)
        stats["fine_only"] = self.fine_only
        return path, stats

    def recheck(self, path: np.ndarray) -> bool:
        """Whether every edge of `path` passes the fine check (an edge may graze an obstacle between the points
        the planning resolution looked at)."""
        return bool(self._timed("smoothing", verify, self.oracle, path, self.fine).all())

    def connect_and_smooth(self) -> tuple[list[int], np.ndarray, dict] | None:
        """(roadmap path, smoothed path, smoothing stats) once start and goal connect, else None.

        Optimistic first (planning resolution, then the fine re-check); if the re-check fails the query turns
        fine-only and tries again, so every returned edge has passed the fine check."""
        while True:
            nodes = self.search()
            if nodes is None:
                return None
            path, stats = self.smooth(nodes)
            if self.fine_only or self.recheck(path):
                return nodes, path, stats
            self.fine_only = True

    def time(self, path: np.ndarray) -> Trajectory:
        scene = self.oracle.scene
        try:
            return self._timed("timing", parameterize, self.oracle.plant, self.oracle.space.unwrap(path),
                               scene.velocity_limits, scene.acceleration_limits, self.settings.dt,
                               self.oracle.space.names)
        except (RuntimeError, ValueError) as exc:  # Toppra infeasible, or limits that are not positive
            raise NoPath(f"path found on {scene.name} but not time-parameterized: "
                         f"{' '.join(str(exc).split())}") from None

    def solve(self) -> PlanResult:
        """Grow round by round until start and goal connect, then smooth, re-check and time the path."""
        sizes = self.round_sizes()
        found = None
        while sizes is not None:
            self.grow(*sizes)
            found = self.connect_and_smooth()
            if found is not None:
                break
            sizes = self.round_sizes()
        if found is None:
            raise self._not_connected()
        return self._result(*found)

    # ---- answers ----------------------------------------------------------------------------------------------------
    def _failure(self, message: str, **details) -> NoPath:
        seconds, spent = self.elapsed()
        error = NoPath(message)
        error.details = {"roadmap": self.roadmap.stats(), "rounds": self.rounds, "collision_checks": spent,
                         "seconds": seconds, **details}
        return error

    def _not_connected(self) -> NoPath:
        stats, s = self.roadmap.stats(), self.settings
        sizes = self.roadmap.component_sizes(self.start_node, self.goal_node)
        seconds, spent = self.elapsed()
        return self._failure(
            f"no path from start to goal on {self.oracle.scene.name}: roadmap of {stats['nodes']} nodes "
            f"({stats['narrow_nodes']} narrow-passage samples from {s.sampler}, {stats['uniform_nodes']} uniform) in "
            f"{stats['components']} components, start and goal in different ones (sizes {sizes[0]} and {sizes[1]}); "
            f"{stats['edges_tried']} edges tried, {spent} collision checks, {seconds:.1f} s, {self.rounds} round(s)"
            + (f", budget {s.budget} spent" if s.budget is not None else "; no budget for more rounds"),
            components_of_start_goal=sizes)

    def _result(self, nodes: list[int], path: np.ndarray, stats: dict) -> PlanResult:
        from app.roadmap import NARROW

        roadmap, s = self.roadmap, self.settings
        raw = roadmap.Q[nodes]
        stats["raw_length"] = path_length(self.oracle, raw)
        stats["length_after"] = path_length(self.oracle, path)
        trajectory = self.time(path)
        self.seconds["total"] = self.elapsed()[0]
        return PlanResult(
            success=True, scene=self.oracle.scene.name, sampler=s.sampler, seed=int(s.seed), step=self.step,
            start=self.start, goal=self.goal, path=path, roadmap_path=raw, trajectory=trajectory,
            collision_checks=self.elapsed()[1], checks=self.checks, seconds=self.seconds, roadmap=roadmap.stats(),
            narrow_on_path=int(sum(roadmap.kinds[i] == NARROW for i in nodes)), rounds=self.rounds,
            budget=str(s.budget) if s.budget is not None else "none", smoothing=stats,
            sampler_stats=self.sampler_stats, graph=roadmap, path_nodes=list(nodes))
