"""Continuous collision certification by conservative advancement: a motion is proved free, not only sampled.

A piece of motion is proved by weighing how far its geometries can move along it (app.checking.motion_bound: B_PQ
per pair) against their distances at its ends (app.checking.end_distances: Drake's where it computes them exactly,
lower bounds of our own where it does not, app.checking.shape_gaps). This module cuts the intervals of a curve into
pieces, proves them with the two, and cuts again those that fail.

Certificate. Signed distance changes by at most B_PQ along a piece, so if at the ends a, b of a piece of motion
d_PQ(a) + d_PQ(b) > B_PQ for every pair the scene counts, P and Q never touch in between:
d(t) >= d(a) - B_PQ(a..t) and d(t) >= d(b) - B_PQ(t..b), and the two add up to at most B_PQ. With a clearance c,
d_PQ(a) + d_PQ(b) > B_PQ + 2c leaves d(t) >= c all along the piece, in the same way. An interval starts
as pieces a few resolutions long (a longer piece seldom passes whole, and a round of pieces costs a fixed part
besides its distance queries); a piece that fails is cut into parts (as many as its ends' distances fall short,
2 to 8); one that still fails once its motion is shorter than the floor (in the space's weighted metric) is
reported as colliding. Each interval is cut nearest to contact first, several pieces of every interval at a time
with their ends bounded in one batch (see Certifier).
"""

from __future__ import annotations

import heapq
import itertools
import math
import time
from typing import NamedTuple

import numpy as np

from app.checking.budget import Stop
from app.checking.end_distances import EndDistances
from app.checking.motion_bound import MotionBound, motion_bound
from app.checking.protocol import Checker
from app.errors import UserError

# What a planned motion is proved to keep from everything by default (scene length units: metres for the robots): a
# margin for the proofs that the straight lines a controller draws between its samples, and the path polyline, are
# free too (app.motion.timing), not a safety padding -- a larger one (PlanSettings.clearance) pads the motion, for
# more collision checks, as the planner's own checks do not pad (benchmark pages).
CLEARANCE = 1e-5
# A piece is cut until its motion is shorter than resolution / FLOOR_DIVISOR (weighted metric).
FLOOR_DIVISOR = 256

# The motion bound is named here too: callers take it with the certificate.
__all__ = [
    "CLEARANCE",
    "FLOOR_DIVISOR",
    "Certifier",
    "Motion",
    "MotionBound",
    "certify_curve",
    "certify_path",
    "motion_bound",
    "polyline",
    "straight_edges",
]


class Certifier(EndDistances):
    """Certifies pieces of motion on one checker's oracle, the distances at their ends asked for as EndDistances
    (kept across calls, and across queries: a caller may hand it another query's checker).

    Each interval's pieces are cut nearest to contact first: the parts of a piece that failed its test go by the
    distance at its ends, interpolated to each part's middle (the parts beside its nearer end first), the leftmost
    first among equals. Whether an interval is proved does not depend on the order (every piece of its subdivision
    must pass), but a failing interval stops at its first failure, and this order dives to where the motion comes
    nearest an obstacle, where leftmost first would prove everything before it (a factor of several in distance
    queries on a grazing edge: benchmark pages).
    WIDTH pieces of every interval (more where few intervals are left: ROUND_MIN) are taken at a time and their
    ends bounded together: Drake is asked per configuration, but the gaps (numpy) run once over all those
    configurations and pairs, where one configuration at a time spent most of its time in numpy's call overhead."""

    # Pieces taken from each interval at a time: more batches more, but may do more work past a failure.
    WIDTH = 16
    # A failing piece is cut into as many equal parts as its ends' distances fall short of its bound, at least 2 and
    # at most SPLIT_MAX: the parts then pass if the distances in between are like those at its ends, in one round
    # where halving would take several (fewer rounds and fewer queries than halving: benchmark pages).
    SPLIT_MAX = 8
    # Before the first round an interval is cut into pieces of at most FIRST_PIECE x the resolution (weighted
    # metric). A round costs a fixed part besides its distance queries, and a longer piece seldom passes whole: on
    # cell queries this asked 15-20 % more queries in about half the rounds, for a quarter less time (benchmark
    # pages).
    FIRST_PIECE = 4
    # A round takes more than WIDTH pieces of an interval when fewer than ROUND_MIN would be taken in all (a single
    # straight move otherwise needs a round per WIDTH of its pieces), unless a piece of that interval fell short by
    # CLOSING or more in the round before: it may be closing on a contact, and a failing interval stops at its
    # first failure, so it keeps to WIDTH pieces nearest to contact.
    ROUND_MIN = 64
    CLOSING = 4
    # A call that keeps its pieces' margins asks their ends as if each bound were this much larger, so that a pair
    # left unreported at both ends of a piece is a quarter of the piece's largest bound from contact all along it,
    # not barely apart (an end is asked only as far as half the largest bound needs).
    MARGIN_ASK = 1.5

    def __init__(self, checker: Checker, floor: float | None = None):
        clock = time.perf_counter()
        super().__init__(checker)
        self.floor = floor if floor is not None else checker.oracle.space.resolution / FLOOR_DIVISOR
        self.seconds = time.perf_counter() - clock  # all this certifier's work: set-up, then every certify()

    def certify(
        self, curve, intervals, clearance=0.0, floor=None, stop: Stop | None = None, margins: bool = False
    ) -> tuple[bool, dict]:
        """Whether the curve keeps at least `clearance` (0: is free; one for all intervals or one per interval)
        from everything over each interval (s0, s1) of `intervals`: every pair's bound on a piece is taken
        2 x clearance larger, so that d(a) + d(b) > B + 2c leaves d >= c all along (see the module doc). floor: how
        short a failing piece may be cut before its interval fails (one for all or one per interval; default the
        certifier's), for a caller with a cheaper way round a failure than proving it finer. stop: what bounds the
        proof (its time limit and cancel flag: the certificate asks for distances, not checks), polled between its
        batches of distance queries. margins: keep, for every piece that passed, a lower bound on every pair's
        distance all along it (ends asked farther, see MARGIN_ASK), for a caller that proves curves near this one
        from it (app.motion.trajectory_samples).

        The curve (a Motion, or any object with the same methods) gives position(s), and variation(s0, s1), a bound
        on each coordinate's travel between s0 and s1, for s0 < s1 within one interval; and, if it has them,
        derivatives(s0, s1): the velocity dq/ds at s0 and at s1 and a bound on |d2q/ds2| between them, each
        coordinate's (then pieces are also bounded from the motion itself: MotionBound.piece_bounds). All
        take arrays of s, (n,), and give rows, (n, dim): a round asks for all its pieces in one call.
        The curve must stay within the space's bounds between in-bound ends (a straight edge or a blend does).
        stats: failed (indices of intervals not certified), pieces (certified), distance_queries, seconds; with
        margins, margins: (interval, s0, s1, margin) rows of the pieces that passed, (pieces, 4).
        """
        motion = Motion(curve.position, curve.variation, getattr(curve, "derivatives", None))
        clock, queries = time.perf_counter(), self.checker.distance_queries
        intervals = np.array(list(intervals), float).reshape(-1, 2)
        clearances = np.broadcast_to(np.asarray(clearance, float), (len(intervals),))
        floors = np.broadcast_to(np.asarray(self.floor if floor is None else floor, float), (len(intervals),))
        heaps = self._first_pieces(motion.variation, intervals)
        failed, pieces, kept = [], 0, []
        closing: set[int] = set()  # intervals with a piece that fell CLOSING short or more in the last round
        while heaps:
            todo = self._take(heaps, closing)
            judged = self._judge(motion, todo, clearances, stop, margins)
            closing = {i for (i, _), far in zip(todo, judged.closing) if far}
            pieces += self._cut(heaps, todo, judged, floors, failed)
            if margins:
                kept += [(i, a, b, m) for (i, (a, b)), ok, m in zip(todo, judged.passed, judged.margins) if ok]
            heaps = {i: heap for i, heap in heaps.items() if heap}
        stats = {
            "failed": sorted(failed),
            "pieces": pieces,
            "distance_queries": self.checker.distance_queries - queries,
            "seconds": time.perf_counter() - clock,
        }
        if margins:  # of intervals that failed too: each piece that passed is proved
            stats["margins"] = np.array(kept, float).reshape(-1, 4)
        self.seconds += stats["seconds"]
        return not failed, stats

    def _first_pieces(self, variation, intervals: np.ndarray) -> dict:
        """Per interval, a heap of its pieces still to prove, as (distance at the ends of the piece they were cut
        from, start, end): nearest to contact first. At first each interval is cut into pieces of at most
        FIRST_PIECE x the resolution, all at distance 0."""
        heaps = {}
        if len(intervals):
            space = self.checker.space
            length = np.linalg.norm(variation(intervals[:, 0], intervals[:, 1]) * space.weights, axis=1)
            parts = np.ceil(length / (self.FIRST_PIECE * space.resolution)).clip(1, None).astype(int)
            for i, ((a, b), n) in enumerate(zip(intervals.tolist(), parts.tolist())):
                heaps[i] = [(0.0, s0, s1) for s0, s1 in itertools.pairwise(_cuts(a, b, n))]
        return heaps

    def _take(self, heaps: dict, closing: set) -> list:
        """A round's pieces, (interval, (start, end)), off the intervals' heaps, nearest to contact first: WIDTH of
        each interval, more where few intervals are left (ROUND_MIN), but WIDTH of one closing on a contact."""
        wide = max(self.WIDTH, math.ceil(self.ROUND_MIN / len(heaps)))
        return [
            (i, heapq.heappop(heap)[1:])
            for i, heap in heaps.items()
            for _ in range(min(self.WIDTH if i in closing else wide, len(heap)))
        ]

    def _judge(
        self, motion: Motion, todo: list, clearances: np.ndarray, stop: Stop | None, margins: bool = False
    ) -> _Judged:
        """The certificate on a round's pieces (see _take), their ends bounded together; clearances: per interval;
        stop: polled between batches of distance queries; margins: whether to find each piece's margin (see
        certify)."""
        spans = np.array([ab for _, ab in todo])
        variations = motion.variation(spans[:, 0], spans[:, 1]).reshape(len(todo), -1)
        ends = list(dict.fromkeys(s for _, ab in todo for s in ab))
        slot = {s: j for j, s in enumerate(ends)}
        by_end = np.array([slot[s] for _, ab in todo for s in ab])  # piece p's ends are rows 2p and 2p + 1
        Q = motion.position(np.array(ends))
        local = self.bound.local(Q)
        travel = self._travel(local, by_end, spans, variations, motion.derivatives)
        clearance = clearances[[i for i, _ in todo]]
        travel = travel + 2 * clearance[:, None, None]
        found = self.at_ends(Q, ends, by_end, travel, stop, self.MARGIN_ASK if margins else 1.0, local)
        lengths = np.linalg.norm(variations * self.checker.space.weights, axis=1)
        clear, short, slack = _clear([found.get(a) for _, (a, b) in todo], [found.get(b) for _, (a, b) in todo], travel)
        return _Judged(
            passed=clear.tolist(),
            lengths=lengths.tolist(),
            parts=np.clip(np.ceil(short), 2, self.SPLIT_MAX).astype(int).tolist(),
            closing=(short >= self.CLOSING).tolist(),
            ends=found,
            # d(a) + d(b) - B - 2c >= slack for every pair: d >= slack / 2 + c all along the piece.
            margins=(slack / 2 + clearance).tolist(),
        )

    def _travel(self, local, by_end: np.ndarray, spans: np.ndarray, variations: np.ndarray, derivatives):
        """Bounds (pieces, rows, rows) on how much each pair's distance changes along each piece (its ends are rows
        by_end[2p] and by_end[2p + 1] of `local`, the robot's kinematics there (MotionBound.local); from spans[p, 0]
        to spans[p, 1], each coordinate travelling variations[p]): from the rates anywhere in the space, or where
        the robot has them (local is not None), from its lever arms at the piece's ends; and where the curve has
        derivatives, the lesser of that and the bound from the motion itself."""
        if local is None:
            return self.bound.pair_travel(variations)
        if derivatives is not None:  # per unit of tau = (s - s0) / span
            span = (spans[:, 1] - spans[:, 0])[:, None]
            da, db, dd = derivatives(spans[:, 0], spans[:, 1])
            derivatives = (da * span, db * span, dd * span**2)
        return self.bound.piece_bounds(variations, local, by_end[0::2], by_end[1::2], derivatives)[0]

    def _cut(self, heaps: dict, todo: list, judged: _Judged, floors: np.ndarray, failed: list) -> int:
        """After a round (todo, judged): how many of its pieces passed. An interval with a piece that failed at its
        floor, or with an end in collision, goes into `failed` (its heap dropped, its other pieces of the round
        passed over); the other failed pieces are cut into parts, pushed on their intervals' heaps by the distance
        at their ends interpolated to each part's middle (see the class doc)."""
        passed_pieces, ends = 0, judged.ends
        for (i, (a, b)), passed, length, n in zip(todo, judged.passed, judged.lengths, judged.parts):
            if i not in heaps:
                continue
            if passed:
                passed_pieces += 1
            elif length <= floors[i] or ends[a] is None or ends[b] is None:
                failed.append(i)
                del heaps[i]
            else:
                near_a, near_b = ends[a].nearest(), ends[b].nearest()
                for j, (s0, s1) in enumerate(itertools.pairwise(_cuts(a, b, n))):
                    heapq.heappush(heaps[i], (near_a + (near_b - near_a) * (j + 0.5) / n, s0, s1))
        return passed_pieces


def _cuts(a: float, b: float, n: int) -> list[float]:
    """a, b and the points that cut [a, b] into n equal parts, in order."""
    return [a, *(a + (b - a) * j / n for j in range(1, n)), b]


class _Judged(NamedTuple):
    """A round's pieces as the certificate found them, an entry a piece: whether it passed, its length (weighted
    metric), into how many parts it is cut if it failed, whether it fell CLOSING short or more, a lower bound on every
    pair's distance all along it (meaningful where it passed); and the distances at the ends asked, {s: PairDistances or
    None}."""

    passed: list
    lengths: list
    parts: list
    closing: list
    ends: dict
    margins: list


def _clear(ends_a: list, ends_b: list, pair_travel: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The certificate for pieces (ends a[p], b[p], pair bounds pair_travel[p]), all at once: whether every pair
    reported at either end of a piece is farther apart, summed over the two ends, than its distance can change (a pair
    an end does not report is at least that end's limit apart; False where an end is None: it collides), by what
    factor the worst pair's bound exceeds its two distances (1 where none does, or an end collides), and the least
    of every pair's two distances less its bound (-inf where an end collides; a pair neither end reports counts both
    limits less the largest bound)."""
    ok = np.array([a is not None and b is not None for a, b in zip(ends_a, ends_b)], bool)
    short, slack = np.ones(len(ok)), np.full(len(ok), -np.inf)
    if not ok.any():
        return ok, short, slack
    # The distinct ends, and per piece which of them it joins.
    slots, table = {}, []
    for end in itertools.chain(ends_a, ends_b):
        if end is not None and id(end) not in slots:
            slots[id(end)] = len(table)
            table.append(end)
    pieces = np.flatnonzero(ok)
    a = np.array([slots[id(ends_a[p])] for p in pieces.tolist()], np.int64)
    b = np.array([slots[id(ends_b[p])] for p in pieces.tolist()], np.int64)
    counts = np.array([len(end.keys) for end in table], np.int64)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    keys, distance, row_a, row_b = (np.concatenate([getattr(end, field) for end in table]) for field in _END_FIELDS)
    limit = np.array([end.limit for end in table])
    from app.checking import kernels  # loads numba on first use (see there)

    ok[pieces], short[pieces], slack[pieces] = kernels.clear_pieces(
        pieces, a, b, first, counts, keys, distance, row_a, row_b, limit, pair_travel
    )
    return ok, short, slack


# A PairDistances' arrays, a row per pair, for the test's kernel.
_END_FIELDS = ("keys", "distance", "row_a", "row_b")


class Motion(NamedTuple):
    """A curve for Certifier.certify: position(s), variation(s0, s1) and derivatives(s0, s1) (see there)."""

    position: object
    variation: object
    derivatives: object = None


def certify_curve(oracle, curve, knots, floor: float | None = None, clearance: float = 0.0) -> tuple[bool, dict]:
    """Certify the curve (see Certifier.certify) over [knots[0], knots[-1]], its variation and derivatives holding
    between two consecutive knots. stats["failed"]: indices of the knot intervals that failed."""
    knots = np.asarray(knots, float)
    return Certifier(oracle, floor).certify(curve, itertools.pairwise(knots), clearance)


def polyline(space, P: np.ndarray) -> Motion:
    """The polyline P (straight edges, the short way) with parameter s = i + t on edge i."""
    return straight_edges(space.unwrap(P), np.arange(len(P), dtype=float))


def straight_edges(W: np.ndarray, knots: np.ndarray) -> Motion:
    """The polyline W (unwrapped: straight from each waypoint to the next) with edge i running from s = knots[i] to
    knots[i + 1] (increasing)."""
    rate = np.diff(W, axis=0) / np.diff(knots)[:, None]

    def edge(s: np.ndarray) -> np.ndarray:
        return np.clip(np.searchsorted(knots, s, side="right") - 1, 0, len(rate) - 1)

    def position(s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, float)
        i = edge(s)
        return W[i] + (s - knots[i])[:, None] * rate[i]

    def variation(s0: np.ndarray, s1: np.ndarray) -> np.ndarray:
        s0, s1 = np.asarray(s0, float), np.asarray(s1, float)
        return np.abs(rate[edge(0.5 * (s0 + s1))]) * (s1 - s0)[:, None]

    def derivatives(s0: np.ndarray, s1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        velocity = rate[edge(0.5 * (np.asarray(s0, float) + np.asarray(s1, float)))]
        return velocity, velocity, np.zeros_like(velocity)

    return Motion(position, variation, derivatives)


def certify_path(oracle, P: np.ndarray, floor: float | None = None, clearance: float = 0.0) -> tuple[bool, dict]:
    """Certify that every straight edge of the polyline P (in oracle.space) keeps at least `clearance` from
    everything (0: is free). stats["failed"]: the edges that failed."""
    P = np.atleast_2d(np.asarray(P, float))
    dim = oracle.space.dim
    if P.ndim != 2 or P.shape[1] != dim or not len(P) or not np.isfinite(P).all():
        raise UserError(f"certify_path: P must be finite configurations of {dim} coordinates, shape (n, {dim})")
    if len(P) < 2:
        P = np.vstack([P, P])
    return certify_curve(oracle, polyline(oracle.space, P), np.arange(len(P)), floor, clearance)
