"""A query's own view of the shared collision oracle: its budget, its counters and its cancel flag.

OMPL splits a planner's state the same way: the `SpaceInformation` and its validity checker are shared, while each
`solve()` gets its own `PlannerTerminationCondition`. Here the `CollisionOracle` (one per scene: the Drake model, its
contexts, the measured cost of each batch path) is shared by every query, and a `QueryContext` is made per query:
`checks` (the paper's gamma_c), `distance_queries` and `point_queries` count only what this query asked. What
bounds the work is an argument of every counted call, as OMPL passes its termination condition to `solve(ptc)`: a
`Stop` (app.checking.budget: a Budget running against these counters, plus an optional cancel flag), or None for
none. Two queries on one oracle never mix their counts or budgets.

A context is used from one thread at a time. The oracle behind it may be shared between threads: it serializes its
Drake queries with a lock (see CollisionOracle).

`checks` counts every configuration handed to Drake for a collision answer; an edge check counts the configurations
it looked at. Configurations outside the bounds are rejected before Drake and not counted.
"""

from __future__ import annotations

import time

import numpy as np

from app.checking.budget import Budget, BudgetSpent, Stop

# Most configurations one edge-check call hands Drake at once (a few tenths of a second), so a stop is polled often.
_MAX_BATCH = 4096
# Workspace points asked at once between polls of the stop, at first; then as many as take about _POINT_SECONDS at
# the pace of the batch before, within [_POINT_BATCH, _MAX_BATCH]. Among many environment pieces a point is dear and
# a search of thousands of points must still end when the query must; among a few, each call's fixed cost would
# outweigh the points.
_POINT_BATCH, _POINT_SECONDS = 64, 0.005


class QueryContext:
    """What one query (or one script) asks of a shared `CollisionOracle`, counted; each counted call bounded by the
    `stop` it is given (`Stop(budget, context, cancel)`; None: no limit).

    Attributes:
        oracle: The shared oracle: the Drake model and uncounted distances.
        space: The oracle's configuration space.
        scene: The oracle's scene.
        checks: Collision checks asked through this context.
        distance_queries: Signed-distance queries (continuous certification), apart from `checks`.
        point_queries: Workspace points asked for their distances to the environment.
    """

    def __init__(self, oracle):
        self.oracle = oracle  # (protocol.DistanceSource)
        self.space = oracle.space
        self.scene = oracle.scene
        self.checks = 0
        self.distance_queries = 0
        self.point_queries = 0

    def stop(self, budget: Budget | None = None, cancel=None) -> Stop:
        """A Stop running from now against this context's counters (and the clock): `budget` (None: no limit) and
        `cancel` (a threading.Event, or anything with `is_set()`, that stops it from another thread)."""
        return Stop(budget or Budget(), self, cancel)

    @property
    def threads(self) -> int:
        """The cores the shared oracle may use (a large k-nearest query is spread over them)."""
        return self.oracle.threads

    @property
    def workspace(self):
        """Where the robot's pieces and passage frame are, and the environment's gaps (app.checking.workspace):
        uncounted, but for `environment_gaps` here."""
        return self.oracle.workspace

    @property
    def diagnostics(self):
        """What a configuration touches, named (app.checking.diagnostics): uncounted."""
        return self.oracle.diagnostics

    # ---- collision answers (counted, each bounded by its stop) --------------------------------------------------
    def is_free(self, q: np.ndarray, stop: Stop | None = None) -> bool:
        """Whether configuration `q` is within bounds and collision-free (one check; none when out of bounds)."""
        q = np.asarray(q, float)
        if not self.space.within_bounds(q)[0]:
            return False
        if stop is not None:
            stop.allow(1)
        self.checks += 1
        return self.oracle.free(q)

    def are_free(self, Q: np.ndarray, stop: Stop | None = None) -> np.ndarray:
        """Free flags for a batch (n, dim), spread over the oracle's threads. Under a `stop`, a batch the check
        limit cannot hold is checked as far as it goes, then BudgetSpent is raised."""
        Q = np.atleast_2d(np.asarray(Q, float))
        free = self.space.within_bounds(Q)
        inside = np.flatnonzero(free)
        if stop is not None and len(inside):
            allowed = stop.allow(len(inside))
            if allowed < len(inside):
                self.checks += allowed
                free[inside[:allowed]] = self.oracle.free_batch(Q[inside[:allowed]])
                raise BudgetSpent("checks")
        self.checks += len(inside)
        free[inside] = self.oracle.free_batch(Q[inside])
        return free

    def edges_free(
        self,
        Q1: np.ndarray,
        Q2: np.ndarray,
        resolution: float | None = None,
        ends_free: bool = False,
        stop: Stop | None = None,
    ) -> np.ndarray:
        """Free flags for the straight edges Q1[i] -> Q2[i], checked at `resolution` (default: the scene's).

        Points go to Drake in coarse-to-fine rounds across all edges at once, and an edge stops being checked at
        its first collision, so colliding edges cost few checks; they are made and asked a slice at a time (at most
        _MAX_BATCH), and the stop is polled before each.
        ends_free: the endpoints are known to be free (roadmap nodes) and are not checked again.
        """
        return self.edges_status(Q1, Q2, resolution, ends_free, stop=stop)[0]

    def edges_status(
        self,
        Q1: np.ndarray,
        Q2: np.ndarray,
        resolution: float | None = None,
        ends_free: bool = False,
        until_one_collides: bool = False,
        progress: np.ndarray | None = None,
        stop: Stop | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(free, decided) flags for the edges, checked as `edges_free` does. With `until_one_collides` the check
        ends with the coarse-to-fine round of the first collision (the edges of one candidate path: one collision
        condemns the path, and finishing its free edges would be wasted); edges not finished by then are not decided.
        progress: per edge, how many of its points (in coarse-to-fine order) an earlier check found free: they are
        not checked again, and the array is updated with what this check found (a lazy roadmap keeps it per
        undecided edge)."""
        from app.checking import kernels

        Q1 = np.atleast_2d(np.ascontiguousarray(Q1, float))
        Q2 = np.atleast_2d(np.ascontiguousarray(Q2, float))
        # Every edge's points in coarse-to-fine order, in the order they are asked: round by round (an edge's first
        # point, then its next 2, 4, 8...), edge by edge within a round, so every edge is looked at coarsely before
        # any is finished. Drake answers them in that order in one loop that skips the points of an edge already
        # hit (a round trip per round cost more than its checks on short edges). Made in one compiled call: in
        # numpy, making them cost more than a short edge's checks.
        done = np.zeros(len(Q1), np.int64) if progress is None else progress
        points, owner, inside, last, round_end, outside, opening = kernels.edge_points(
            Q1, Q2, resolution or self.space.resolution, 2 if ends_free else 0, done, *self.space.edge_table
        )
        hit = [False] * len(Q1)
        # Points are asked a slice at a time, the first up to each edge's 7th point (rounds 0-2), then twice as many
        # each time, so that the stop is polled between slices.
        passed, end, size = 0, len(owner), opening
        stop_at_hit = until_one_collides
        while passed < end:
            more = min(end - passed, size, _MAX_BATCH)
            allowed = stop.allow(more) if stop is not None else more
            part = slice(passed, passed + allowed)
            if passed + allowed > outside:  # out of bounds: collides, unasked (edges leave the bounds only at an end)
                for edge in owner[part][~inside[part]].tolist():
                    hit[edge] = True
                if until_one_collides:
                    break
            reached, asked = self.oracle.first_hits(points[part], owner[part], hit, stop_at_hit)
            self.checks += asked
            passed += reached
            if stop_at_hit and any(hit):
                # The check ends with the round of this collision: the other edges' points in that round are still
                # asked, so that whatever else of the path collides as early is found in the same call (deciding
                # fewer edges per call made the search try many more candidate paths).
                stop_at_hit, end = False, int(round_end[passed - 1])
                size = end - passed
                continue
            if allowed < more:
                if progress is not None:
                    progress += np.bincount(owner[:passed], minlength=len(Q1))
                raise BudgetSpent("checks")
            size *= 2
        if progress is not None:  # an edge's points passed were found free, unless the edge was hit
            progress += np.bincount(owner[:passed], minlength=len(Q1))
        free = np.logical_not(hit)
        # an edge is decided when hit or when every point of it was passed
        return free, ~free | (last < passed)

    def edge_free(
        self, q1: np.ndarray, q2: np.ndarray, resolution: float | None = None, stop: Stop | None = None
    ) -> bool:
        """Whether the straight edge from `q1` to `q2` is free at `resolution` (default: the scene's), as
        `edges_free` checks it."""
        return bool(self.edges_free(q1, q2, resolution, stop=stop)[0])

    # ---- measurements (counted apart from collision checks) -----------------------------------------------------
    def signed_distances(self, q: np.ndarray, max_distance: float) -> list:
        """SceneGraph's SignedDistancePairs at q of the pairs the scene's policy counts that lie within
        `max_distance`; counted in `distance_queries`, not in `checks`."""
        self.distance_queries += 1
        return self.oracle.signed_distance_pairs(q, max_distance)

    def in_contact(self, q: np.ndarray) -> bool:
        """Whether a pair the scene's policy counts penetrates at q (CollisionOracle.in_contact); the certificate's
        question about a configuration it bounds itself, counted there (count_bounded), not in `checks`."""
        return self.oracle.in_contact(q)

    def pair_distances(self, q: np.ndarray, pairs: list) -> list:
        """SceneGraph's SignedDistancePair at q of each given pair (CollisionOracle.pair_distances): the
        certificate's question about a configuration it bounds itself, counted there (count_bounded)."""
        return self.oracle.pair_distances(q, pairs)

    def count_bounded(self, n: int) -> None:
        """The certificate bounded the distances at n configurations itself (asking Drake per pair where it needed
        a direction, and in_contact where a bound came out at or below 0): counted as n `distance_queries`, one a
        configuration, as signed_distances counts."""
        self.distance_queries += n

    def environment_gaps(self, P: np.ndarray, width: float, stop: Stop | None = None) -> np.ndarray:
        """Whether each workspace point (n, 3) lies free in a gap of the environment narrower than `width`
        (app.checking.workspace); counted in `point_queries`. Asked in batches, polling the stop before
        each, so BudgetSpent may end it part way."""
        P = np.atleast_2d(np.asarray(P, float))
        gap = np.zeros(len(P), bool)
        b, size = 0, _POINT_BATCH
        while b < len(P):
            if stop is not None:
                stop.allow(0)
            batch = P[b : b + size]
            self.point_queries += len(batch)
            clock = time.perf_counter()
            gap[b : b + len(batch)] = self.workspace.environment_gaps(batch, width)
            pace = (time.perf_counter() - clock) / len(batch)
            b, size = b + len(batch), int(np.clip(_POINT_SECONDS / max(pace, 1e-9), _POINT_BATCH, _MAX_BATCH))
        return gap
