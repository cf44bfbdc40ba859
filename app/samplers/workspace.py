"""Narrow gaps of the workspace, and configurations that put a piece of the robot in one.

A passage of the configuration space that samples miss nearly always has a narrow gap of the workspace behind it: a
hole in a wall, a hatch, a slot between beams. Such gaps are cheap to find -- a point query against the environment
costs a few microseconds, not a collision check of the whole robot -- and a configuration that puts a piece of the
robot in one lies in the passage far more often than the end of a walk started anywhere on an obstacle (van den Berg
and Overmars, "Using workspace information as a guide to non-uniform sampling in probabilistic roadmap planners",
IJRR 2005). On joint3d's hole placements land far more often than the Lévy bridge walkers' samples, at a fraction
of their checks (benchmark pages, "Tuning notes").

`WorkspaceGaps` finds points in gaps narrower than GAP_WIDTH times the robot's median piece: two obstacles on
opposite sides of the point, closer together than that (`app.checking.workspace.Workspace.environment_gaps`). Half
of its candidate points are uniform in the box the robot's pieces reach, half scattered about gap points already
found, so a gap once hit fills in. `WorkspaceSampler` then draws a uniform configuration, picks one of the robot's
moving pieces and brings its centre to a gap point: by shifting the coordinates that translate the whole robot (a
free-flying body, a mobile base), or, for an arm without such coordinates, by keeping the configuration only if the
piece's centre is already near a gap point. Free placements are its samples.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from app.checking.budget import Stop
from app.checking.protocol import Checker
from app.errors import SamplerBudgetExceeded
from app.samplers.base import Sampler

# A gap is narrow when it is narrower than this many times the diameter of the robot's median moving piece: a gap
# such a piece passes only when turned the right way (why this factor, and the median piece: benchmark pages,
# "Tuning notes").
GAP_WIDTH = 2.5
# Gap points a query looks for; candidate points per search; candidates without a single gap: the scene has none;
# candidates a query asks at most (the search goes on a batch per round while it has fewer than POINTS).
POINTS, BATCH, SEARCH_LIMIT, SEARCH_MAX = 512, 2048, 32768, 131072
# Rounds in a row whose placements all missed the gaps (found in the box the pieces reach, yet out of their reach):
# the sampler gives up (SamplerBudgetExceeded) and the planner leaves the rounds to the walkers.
IDLE_ROUNDS = 16


class WorkspaceGaps:
    """Points in the narrow gaps of a scene's environment, found on demand, and placements of the robot there."""

    def __init__(self, checker: Checker, rng: np.random.Generator):
        self.checker, self.space = checker, checker.space
        Q = self.space.uniform(rng, 64)
        C = checker.workspace.robot_geometry_centres(Q)
        radii = checker.workspace.robot_geometry_radii()
        scale = float(np.max(np.ptp(C.reshape(-1, 3), axis=0))) if C.size else 0.0
        # Pieces that move with the configuration (a cart or base welded to the world does not).
        self.moving = np.flatnonzero(np.ptp(C, axis=0).max(axis=1) > 1e-9 * max(scale, 1.0))
        # A robot with no moving collision geometry has nothing to place: no width, an empty box, `exhausted` at once.
        moving = radii[self.moving] if len(self.moving) else np.zeros(1)
        reach = C[:, self.moving].reshape(-1, 3) if len(self.moving) else np.zeros((1, 3))
        self.width = GAP_WIDTH * 2 * float(np.median(moving))
        # How far a piece's centre may stay from its gap point when nothing can shift it there exactly.
        self.tolerance = self.width / 4
        margin = float(moving.max())
        self.lower, self.upper = reach.min(axis=0) - margin, reach.max(axis=0) + margin
        self.axes, self.directions = self._translations(Q[:4], C[:4])
        self.points = np.empty((0, 3))
        self.searched = 0  # candidate points asked about
        self._tree: cKDTree | None = None

    def _translations(self, Q: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The coordinates that move every piece of the robot by one and the same world vector (a prismatic joint of
        a floating or mobile base), and those vectors per unit of the coordinate, (3, m)."""
        axes, directions = [], []
        if not len(self.moving):
            return np.array([], int), np.empty((3, 0))
        for i in np.flatnonzero(~self.space.angular):
            delta = 1e-3 * float(self.space.upper[i] - self.space.lower[i])
            if not np.isfinite(delta) or delta <= 0:
                continue
            moved = Q.copy()
            moved[:, i] += delta
            D = (self.checker.workspace.robot_geometry_centres(moved) - C)[:, self.moving] / delta
            if np.abs(D - D[0, 0]).max() < 1e-6 and np.linalg.norm(D[0, 0]) > 1e-6:
                axes.append(int(i))
                directions.append(D[0, 0])
        return np.array(axes, int), np.array(directions).T.reshape(3, len(axes))

    @property
    def exhausted(self) -> bool:
        """Searched long enough to say the scene has no narrow gap."""
        return not len(self.points) and (self.searched >= SEARCH_LIMIT or not len(self.moving))

    def search(self, rng: np.random.Generator, n: int = BATCH, stop: Stop | None = None) -> int:
        """Ask n more candidate points (BudgetSpent when `stop` ends it); returns how many gap points were found."""
        if not len(self.moving):
            return 0
        local = n // 2 if len(self.points) else 0
        P = rng.uniform(self.lower, self.upper, size=(n - local, 3))
        if local:
            around = self.points[rng.integers(len(self.points), size=local)]
            P = np.concatenate([P, around + rng.normal(0.0, self.width / 4, size=(local, 3))])
        found = P[self.checker.environment_gaps(P, self.width, stop)]
        self.searched += n
        if len(found):
            self.points = np.concatenate([self.points, found])
            self._tree = None
        return len(found)

    def place(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Up to n in-bounds configurations, each with one moving piece's centre at (or near) a gap point; not
        checked for collision."""
        if not len(self.points):
            return np.empty((0, self.space.dim))
        Q = self.space.uniform(rng, n)
        piece = self.moving[rng.integers(len(self.moving), size=n)]
        x = self.checker.workspace.robot_geometry_centres(Q, piece)
        if len(self.axes):
            p = self.points[rng.integers(len(self.points), size=n)]
            shift = (p - x) @ np.linalg.pinv(self.directions).T
            Q[:, self.axes] += shift
            near = np.linalg.norm(p - x - shift @ self.directions.T, axis=1) <= self.tolerance
        else:
            if self._tree is None:
                self._tree = cKDTree(self.points)
            # Bounded, the tree stops looking past the tolerance (a point beyond it comes back at infinity).
            near = self._tree.query(x, distance_upper_bound=np.nextafter(self.tolerance, np.inf))[0] <= self.tolerance
        Q = Q[near]
        return Q[self.space.within_bounds(Q)]


class WorkspaceSampler(Sampler):
    """Free configurations with a moving piece of the robot in a narrow gap of the workspace (see the module)."""

    name = "workspace"

    def __init__(self, checker, gaps: WorkspaceGaps, **kw):
        super().__init__(checker, **kw)
        self.gaps = gaps
        self._rate = 0.05  # running free fraction of placements
        self._idle = 0  # rounds in a row without a placement

    def _round(self, rng, need, stop):
        gaps = self.gaps
        if len(gaps.points) < POINTS and gaps.searched < SEARCH_MAX:
            gaps.search(rng, stop=stop)
        # Placing costs no check: only the placements made are capped by the call's room.
        n = int(np.clip(np.ceil(1.25 * need / max(self._rate, 1e-3)), 16, 1024))
        Q = gaps.place(rng, n)[: max(1, self._room)]
        self.stats["attempts"] += n
        self._idle = 0 if len(Q) else self._idle + 1
        if self._idle >= IDLE_ROUNDS:
            raise SamplerBudgetExceeded(f"workspace: {IDLE_ROUNDS} rounds of {n} placements, none at a gap")
        if not len(Q):
            return Q, None
        free = self.checker.are_free(Q, stop)
        self._rate = 0.7 * self._rate + 0.3 * max(free.sum() / n, 1e-3)
        return Q[free], None
