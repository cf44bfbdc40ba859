"""What a query answers: the path and its motion (PlanResult), and typed records of what it cost (PlanStats) and what
was proved of it (Certificate); its JSON form is `PlanResult.to_json()` (docs/schemas/plan.json)."""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, fields
from typing import TYPE_CHECKING

import numpy as np

from app.motion.path import ShortcutStats
from app.motion.timing import BlendProof
from app.motion.trajectory import Trajectory, TrajectoryFile

if TYPE_CHECKING:  # the roadmap pulls in scipy: imported when planning, not when the CLI starts
    from app.planning.roadmap import Roadmap, RoadmapStats

# How a query found its path: the straight motion, the caller's `via` polyline, or a roadmap search.
ROUTES = ("straight", "via", "roadmap")


@dataclass
class PhaseChecks:
    """Collision checks per phase of a query: its endpoints, then the phases in order."""

    endpoints: int = 0
    sampling: int = 0
    roadmap: int = 0
    search: int = 0
    smoothing: int = 0
    certify: int = 0
    timing: int = 0


@dataclass
class PhaseSeconds:
    """Seconds per phase of a query, and in all (its whole time, endpoints and bookkeeping included)."""

    sampling: float = 0.0
    roadmap: float = 0.0
    search: float = 0.0
    smoothing: float = 0.0
    certify: float = 0.0
    timing: float = 0.0
    total: float = 0.0


# The phases of a query, in order (after its endpoints are checked).
PHASES = tuple(f.name for f in fields(PhaseSeconds) if f.name != "total")


class Ledger:
    """A query's checks and seconds per phase, as they are spent (`run`)."""

    def __init__(self, checker):
        self.checker = checker
        self.checks, self.seconds = PhaseChecks(), PhaseSeconds()
        self._clock0, self._checks0 = time.perf_counter(), checker.checks

    def run(self, phase: str, fn, *args, **kwargs):
        """fn(*args, **kwargs), its seconds and collision checks added to `phase`'s."""
        t, c = time.perf_counter(), self.checker.checks
        try:
            return fn(*args, **kwargs)
        finally:
            setattr(self.seconds, phase, getattr(self.seconds, phase) + time.perf_counter() - t)
            setattr(self.checks, phase, getattr(self.checks, phase) + self.checker.checks - c)

    def elapsed(self) -> tuple[float, int]:
        """Seconds and collision checks spent since the ledger was opened."""
        return time.perf_counter() - self._clock0, self.checker.checks - self._checks0


@dataclass
class PlanStats:
    """What a query spent, a success's or a failure's alike (`PlanResult.stats`).

    Attributes:
        collision_checks: Collision checks in all.
        distance_queries: The certificate's signed-distance queries.
        point_queries: Workspace points asked for their distances to the environment.
        checks: Collision checks per phase.
        seconds: Seconds per phase and in all.
        certificate_seconds: The certificate's own seconds (set-up and every proof, Drake's queries included).
        rounds: Rounds of samples drawn.
        narrow_from_round: The first round with narrow-passage samples (None: never needed).
        roadmap: The roadmap's sizes and counters (app.planning.roadmap.RoadmapStats).
        sampler_stats: Each sample source's counters, by name.
        budget: The query's budget, as `--budget` writes it.
        stopped: Why the work stopped early: "time", "checks", "cancelled" or "interrupted"; None when it did not.
    """

    collision_checks: int
    distance_queries: int
    point_queries: int
    checks: PhaseChecks
    seconds: PhaseSeconds
    certificate_seconds: float
    rounds: int
    narrow_from_round: int | None
    roadmap: RoadmapStats
    sampler_stats: dict[str, dict[str, float]]
    budget: str
    stopped: str | None = None

    def to_json(self) -> dict:
        """Its part of a `plan --json` answer (docs/schemas/plan.json)."""
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        out.update(checks=asdict(self.checks), seconds=asdict(self.seconds), roadmap=self.roadmap.to_json())
        return out


@dataclass
class Certificate:
    """What was proved of an answer (app.checking.certify), and what proving it cost (`PlanResult.certificate`).

    Attributes:
        proved: Every edge of the path (or, `blended`, the curve its trajectory follows: blends, the straight parts
            between them and the corners they cut off) keeps `clearance` from everything.
        clearance: The distance proved (scene length units).
        blended: Whether the trajectory's curve, not the polyline, was proved.
        pieces: Pieces the proof cut the motion into.
        distance_queries: The proof's signed-distance queries.
        seconds: The proof's seconds.
        failed: The path's edges that could not be proved (none when proved).
        unproved_edges: Roadmap edges checked free that no proof could hold, dropped from the roadmap on the way.
    """

    proved: bool
    clearance: float
    blended: bool = False
    pieces: int = 0
    distance_queries: int = 0
    seconds: float = 0.0
    failed: list[int] = field(default_factory=list)
    unproved_edges: int = 0

    @classmethod
    def of(cls, proved: bool, clearance: float, stats: dict, blended: bool = False) -> Certificate:
        """The record of a certifier's answer (its stats: pieces, distance_queries, seconds, failed)."""
        return cls(
            proved,
            clearance,
            blended,
            int(stats.get("pieces", 0)),
            int(stats.get("distance_queries", 0)),
            float(stats.get("seconds", 0.0)),
            list(stats.get("failed", [])),
        )

    def to_json(self) -> dict:
        return asdict(self)


@dataclass
class Smoothing:
    """What became of the roadmap path (`PlanResult.smoothing`).

    Attributes:
        raw_length: The roadmap path's length (weighted metric).
        length_after: The answer's length.
        shortcuts: The shortcut pass's record (app.motion.path.ShortcutStats; None for the easy route, which is not
            smoothed).
        repairs: Smoothed paths the certificate refused and smoothing redid.
        fine_only: Whether the query had turned careful (shortcuts checked at the fine resolution).
        dropped: Whether the smoothed path was dropped for the roadmap path, which could be proved where it could
            not.
    """

    raw_length: float
    length_after: float
    shortcuts: ShortcutStats | None = None
    repairs: int = 0
    fine_only: bool = False
    dropped: bool = False

    def to_json(self) -> dict:
        """Its part of a `plan --json` answer (docs/schemas/plan.json)."""
        out = asdict(self)
        out["shortcuts"] = self.shortcuts.to_json() if self.shortcuts else None
        return out


@dataclass
class PlanResult:
    """A query's answer (`app.plan`, `CellRoadmap.solve`): the path and its motion, what it cost, what was proved.

    Attributes:
        scene: The scene's name.
        sampler: The narrow-passage sampler's name.
        seed: The query's seed.
        step: The sampler's base step used.
        start: (dim,) the start.
        goal: (dim,) the goal reached (one of several, when several were given).
        path: (n, dim) the smoothed path: wrapped waypoints, every edge proved.
        roadmap_path: (m, dim) the roadmap's path before smoothing.
        trajectory: The timed motion (None when PlanSettings.timing is off).
        route: How the path was found: "straight", "via" (the caller's polyline) or "roadmap".
        via: How many via points the caller gave (0: none).
        stats: What the query spent.
        smoothing: What became of the roadmap path.
        certificate: What was proved of the path, and what proving it cost.
        narrow_on_path: Nodes of the roadmap path from the narrow-passage sampler.
        workspace_on_path: Nodes of the roadmap path from workspace-gap placements.
        sources_on_path: Nodes of the roadmap path by the source that drew them ("workspace", "uniform", or a
            sampler's name); nodes the query did not draw (its endpoints, a stored roadmap's) are not counted.
        graph: The roadmap itself (nodes `Q`, their `kinds`, `edges()`), for viewers; not part of the JSON.
        path_nodes: The roadmap path's node indices in `graph`.
        blends: The certified curve of the trajectory where that, and not the polyline `path`, is what was proved
            (certificate.blended); for timing the path again the same way.
    """

    scene: str
    sampler: str
    seed: int
    step: float
    start: np.ndarray
    goal: np.ndarray
    path: np.ndarray
    roadmap_path: np.ndarray
    trajectory: Trajectory | None
    route: str
    via: int
    stats: PlanStats
    smoothing: Smoothing
    certificate: Certificate
    narrow_on_path: int
    workspace_on_path: int
    sources_on_path: dict[str, int] = field(default_factory=dict)
    graph: Roadmap | None = field(default=None, repr=False)
    path_nodes: list = field(default_factory=list, repr=False)
    blends: BlendProof | None = field(default=None, repr=False)

    @property
    def collision_checks(self) -> int:
        """Collision checks the query spent in all (`stats.collision_checks`)."""
        return self.stats.collision_checks

    @property
    def certified(self) -> bool:
        """Whether the motion returned (the timed trajectory, or without timing the path) was proved free."""
        return self.trajectory.certified if self.trajectory else self.certificate.proved

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
        """The `plan --json` answer's fields (docs/schemas/plan.json)."""
        stats = self.stats.to_json()
        stats.pop("stopped")
        return {
            "scene": self.scene,
            "sampler": self.sampler,
            "seed": self.seed,
            "step": self.step,
            "start": self.start.tolist(),
            "goal": self.goal.tolist(),
            "path": self.path.tolist(),
            "roadmap_path": self.roadmap_path.tolist(),
            "path_length": self.smoothing.length_after,
            "roadmap_path_length": self.smoothing.raw_length,
            "trajectory": self.trajectory.to_json() if self.trajectory else None,
            "route": self.route,
            "via": self.via,
            **stats,
            "narrow_on_path": self.narrow_on_path,
            "workspace_on_path": self.workspace_on_path,
            "sources_on_path": self.sources_on_path,
            "smoothing": self.smoothing.to_json(),
            "certificate": self.certificate.to_json(),
            "certified": self.certified,
            "clearance": self.certificate.clearance if self.certified else None,
        }
