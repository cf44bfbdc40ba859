"""The planning pipeline, as one function the CLI, the viewer and the benchmarks share:

    endpoints checked -> narrow + uniform samples, in rounds until start and goal connect -> roadmap (k-nearest;
    lazy edge checks for a single query) -> shortest path -> shortcut smoothing -> the result re-checked at 1/4
    resolution -> Toppra per segment

`plan(...)` returns a PlanResult on success and raises InvalidEndpoint (exit 3) for a bad start or goal, NoPath
(exit 1, with `.details`) when the budget runs out unconnected, UserError (exit 2) for bad parameters.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from app.budget import Budget
from app.errors import InvalidEndpoint, NoPath, SamplerBudgetExceeded, UserError
from app.path import FINE, path_length, shortcut, unwrap, verify
from app.timing import Trajectory, parameterize

if TYPE_CHECKING:  # the roadmap pulls in scipy and networkx: imported when planning, not when the CLI starts
    from app.roadmap import Roadmap

PHASES = ("sampling", "roadmap", "search", "smoothing", "timing")


def default_step(oracle) -> float:
    """The scene file's `step` if it sets one; else a tenth of the scene's largest linear extent (10 for the 100-unit
    scenes); with no linear coordinate, a tenth of the weighted diagonal of the bounds."""
    scene = getattr(oracle, "scene", oracle)
    if getattr(scene, "step", None):
        return scene.step
    linear = ~np.asarray(oracle.angular)
    if linear.any():
        return 0.1 * float(np.max((oracle.upper - oracle.lower)[linear]))
    return 0.1 * float(np.linalg.norm((oracle.upper - oracle.lower) * oracle.weights))


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

    def view_json(self) -> dict:
        """The trajectory file `python -m app view --trajectory` reads: times, positions (unwrapped), the smoothed
        path, the narrow-passage samples and which of them the roadmap path used."""
        out = {"times": self.trajectory.times.tolist(), "positions": self.trajectory.positions.tolist(),
               "path": self.path.tolist()}
        if self.graph is not None:
            samples, on_path = self.narrow_samples()
            out["narrow"] = samples.tolist()
            out["on_path"] = on_path.tolist()
        return out

    def narrow_samples(self) -> tuple[np.ndarray, np.ndarray]:
        """The roadmap's narrow-passage samples (n, dim) and whether the roadmap path used each (n,) bool; empty
        without a roadmap."""
        if self.graph is None:
            return np.empty((0, len(self.start))), np.zeros(0, bool)
        from app.roadmap import NARROW

        narrow = [i for i, kind in enumerate(self.graph.kinds) if kind == NARROW]
        used = set(self.path_nodes)
        return self.graph.Q[narrow], np.array([i in used for i in narrow], bool)

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
    q = oracle.check_configuration(q, what)
    if not oracle.within_bounds(q)[0]:
        names = oracle.scene.coordinate_names
        bad = [f"{names[i]}={q[i]:g} not in [{oracle.lower[i]:g}, {oracle.upper[i]:g}]"
               for i in range(oracle.dim) if not (oracle._lo[i] <= q[i] <= oracle._hi[i])]
        raise InvalidEndpoint(f"{what} is out of bounds: {'; '.join(bad)}")
    if not oracle.is_free(q):
        pairs = oracle.colliding_bodies(q)
        touching = ", ".join(f"{a} with {b}" for a, b in pairs[:4]) + (" ..." if len(pairs) > 4 else "")
        raise InvalidEndpoint(f"{what} is in collision: {touching or 'contact reported by the checker'}")
    return oracle.wrap(q)


def plan(oracle, settings: PlanSettings | None = None, *, start=None, goal=None) -> PlanResult:
    """Plan from start to goal (default: the scene's) on a PRM of up to `settings.narrow` samples from
    `settings.sampler` plus `settings.uniform` uniform free samples.

    Samples are added in rounds of a quarter of each count, and planning stops at the first round after which start
    and goal connect (a single query needs no more roadmap than that). With `full_roadmap` the first round is the
    whole `narrow` + `uniform` (the paper's protocol: a roadmap of fixed size, then the query). With a budget,
    quarter rounds go on past those counts until start and goal connect or the budget is spent."""
    from app.roadmap import GOAL, NARROW, START, UNIFORM, Roadmap
    from app.samplers import make_sampler

    s = settings or PlanSettings()
    sampler, narrow, uniform, seed, budget = s.sampler, s.narrow, s.uniform, s.seed, s.budget
    k, smooth_rounds, dt, sampler_params = s.k, s.smooth_rounds, s.dt, s.sampler_params
    skip_connected, full_roadmap = s.skip_connected, s.full_roadmap
    step = default_step(oracle) if s.step is None else float(s.step)

    clock0, checks0 = time.perf_counter(), oracle.checks
    seconds = dict.fromkeys(PHASES, 0.0)
    checks = dict.fromkeys(("endpoints",) + PHASES, 0)

    def timed(phase, fn, *args, **kwargs):
        t, c = time.perf_counter(), oracle.checks
        out = fn(*args, **kwargs)
        seconds[phase] += time.perf_counter() - t
        checks[phase] += oracle.checks - c
        return out

    q_start = check_endpoint(oracle, oracle.scene.start if start is None else start, "start")
    q_goal = check_endpoint(oracle, oracle.scene.goal if goal is None else goal, "goal")
    checks["endpoints"] = oracle.checks - checks0

    seeds = np.random.SeedSequence(seed).spawn(3)
    rng_narrow, rng_uniform = (np.random.default_rng(s) for s in seeds[:2])
    narrow_sampler = make_sampler(sampler, oracle, step=step, **(sampler_params or {}))
    uniform_sampler = make_sampler("uniform", oracle, step=step)
    sampler_stats = {"narrow": {}, "uniform": {}}

    def draw(kind_sampler, count, rng, key):
        if count <= 0:
            return np.empty((0, oracle.dim))
        if budget is not None and budget.checks is not None:  # a sampler may not overrun a check budget
            kind_sampler.max_checks = min(kind_sampler.max_checks, max(1, budget.checks - (oracle.checks - checks0)))
        try:  # resume: walkers still under way when a round ends go on in the next one
            out = kind_sampler.sample(count, rng, resume=True)
        except SamplerBudgetExceeded as exc:  # a sampler that cannot find its samples is a planning failure
            error = NoPath(f"no path on {oracle.scene.name}: {exc}")
            error.details = {"roadmap": roadmap.stats(), "sampler": str(exc), "rounds": rounds,
                             "collision_checks": oracle.checks - checks0}
            raise error from None
        finally:
            for name, value in kind_sampler.stats.items():
                if isinstance(value, (int, float)):
                    sampler_stats[key][name] = sampler_stats[key].get(name, 0) + value
        return out

    # A single query checks only the edges its candidate paths use; a full roadmap is checked whole (multi-query).
    roadmap = Roadmap(oracle, k=k, skip_connected=skip_connected, lazy=not full_roadmap)
    s_node = int(roadmap.add(q_start, START, connect=False)[0])
    g_node = int(roadmap.add(q_goal, GOAL, connect=False)[0])
    fine = FINE * roadmap.resolution
    fine_only = False  # set once an optimistic path has failed the fine re-check

    def solve():
        """(roadmap path, smoothed path, smoothing stats), or None while start and goal are not connected.

        Optimistic first: the roadmap path and its shortcuts are checked at the planning resolution, and the
        smoothed path is then re-checked at FINE x it. Should that fail (an edge that grazes an obstacle between
        checked points), the planner goes on fine-only: roadmap paths must pass the fine check (more rounds if
        none does yet) and shortcuts are checked at the fine resolution. Either way every returned edge has passed
        the fine check."""
        nonlocal fine_only
        nodes = (timed("search", _search_fine, oracle, roadmap, s_node, g_node) if fine_only
                 else timed("search", roadmap.shortest_path, s_node, g_node))
        if nodes is None:
            return None
        smoothed, stats = timed("smoothing", shortcut, oracle, roadmap.Q[nodes], np.random.default_rng(seeds[2]),
                                rounds=smooth_rounds, resolution=fine if fine_only else None)
        stats["fine_only"] = fine_only
        if fine_only or timed("smoothing", verify, oracle, smoothed, fine).all():
            return nodes, smoothed, stats
        fine_only = True
        return solve()

    rounds, found = 0, None
    quarter_narrow, quarter_uniform = math.ceil(narrow / 4), math.ceil(uniform / 4)
    round_narrow, round_uniform = (narrow, uniform) if full_roadmap else (quarter_narrow, quarter_uniform)
    drawn_narrow = drawn_uniform = 0
    while True:
        rounds += 1
        N = timed("sampling", draw, narrow_sampler, round_narrow, rng_narrow, "narrow")
        U = timed("sampling", draw, uniform_sampler, round_uniform, rng_uniform, "uniform")
        drawn_narrow, drawn_uniform = drawn_narrow + len(N), drawn_uniform + len(U)
        new = np.concatenate([roadmap.add(N, NARROW, connect=False), roadmap.add(U, UNIFORM, connect=False)])
        if rounds == 1:
            new = np.concatenate([[s_node, g_node], new])
        timed("roadmap", roadmap.connect, new)
        found = solve()
        if found is not None:
            break
        elapsed, spent = time.perf_counter() - clock0, oracle.checks - checks0
        if narrow == 0 and uniform == 0:
            break
        if budget is None:
            if drawn_narrow >= narrow and drawn_uniform >= uniform:
                break
            round_narrow, round_uniform = min(quarter_narrow, narrow - drawn_narrow), \
                min(quarter_uniform, uniform - drawn_uniform)
        elif budget.spent(elapsed, spent):
            break
        else:
            round_narrow, round_uniform = quarter_narrow, quarter_uniform

    if found is None:
        stats = roadmap.stats()
        sizes = roadmap.component_sizes(s_node, g_node)
        elapsed, spent = time.perf_counter() - clock0, oracle.checks - checks0
        error = NoPath(
            f"no path from start to goal on {oracle.scene.name}: roadmap of {stats['nodes']} nodes "
            f"({stats['narrow_nodes']} narrow-passage samples from {sampler}, {stats['uniform_nodes']} uniform) in "
            f"{stats['components']} "
            f"components, start and goal in different ones (sizes {sizes[0]} and {sizes[1]}); "
            f"{stats['edges_tried']} edges tried, {spent} collision checks, {elapsed:.1f} s, {rounds} round(s)"
            + (f", budget {budget} spent" if budget is not None else "; no budget for more rounds"))
        error.details = {"roadmap": stats, "components_of_start_goal": sizes, "collision_checks": spent,
                         "seconds": elapsed, "rounds": rounds}
        raise error

    path_nodes, smoothed, smooth_stats = found
    raw = roadmap.Q[path_nodes]
    narrow_on_path = sum(roadmap.kinds[i] == NARROW for i in path_nodes)
    smooth_stats["raw_length"] = path_length(oracle, raw)
    smooth_stats["length_after"] = path_length(oracle, smoothed)

    scene = oracle.scene
    try:
        trajectory = timed("timing", parameterize, oracle.plant, unwrap(oracle, smoothed), scene.velocity_limits,
                           scene.acceleration_limits, dt)
    except (RuntimeError, ValueError) as exc:  # Toppra infeasible, or limits that are not positive
        raise NoPath(f"path found on {scene.name} but not time-parameterized: {' '.join(str(exc).split())}") from None
    seconds["total"] = time.perf_counter() - clock0
    return PlanResult(
        success=True, scene=scene.name, sampler=sampler, seed=int(seed), step=step, start=q_start, goal=q_goal,
        path=smoothed, roadmap_path=raw, trajectory=trajectory, collision_checks=oracle.checks - checks0,
        checks=checks, seconds=seconds, roadmap=roadmap.stats(), narrow_on_path=int(narrow_on_path),
        rounds=rounds, budget=str(budget) if budget is not None else "none", smoothing=smooth_stats,
        sampler_stats=sampler_stats, graph=roadmap, path_nodes=list(path_nodes))


def _search_fine(oracle, roadmap: Roadmap, a: int, b: int) -> list[int] | None:
    """Shortest roadmap path whose every edge also passes the fine check; edges that fail it are dropped."""
    while True:
        nodes = roadmap.shortest_path(a, b)
        if nodes is None:
            return None
        ok = verify(oracle, roadmap.Q[nodes], FINE * roadmap.resolution)
        if ok.all():
            return nodes
        for i in np.flatnonzero(~ok):
            roadmap.remove_edge(nodes[i], nodes[i + 1])
