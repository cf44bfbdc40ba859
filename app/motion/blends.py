"""The curve a timed path follows: its corners rounded by parabolic blends, and the proof that the curve is free
(app.checking.certify), blends tightened where it is not.

The corner problem: on a piecewise-linear path Toppra sees zero curvature at the corners and does not slow down, so
the joint velocity would jump there. Stopping at every corner (rest to rest per segment) avoids that but makes the
robot stop at each waypoint. Here each corner is rounded instead by a parabolic blend -- a quadratic Bezier curve
from a point `radius` before the corner, through the corner as control point, to the point `radius` after it -- so
the path is C1 and Toppra slows down just as much as its curvature needs. A blend leaves the checked polyline, so
the whole curve is certified (app.checking.certify); a blend that cannot be certified is halved, and after TIGHTEN
halvings the corner becomes a stop (the path is cut there into legs, each timed from rest to rest), or sooner where
the corner's own distances cannot prove even the last halving's blend clear (STOP_TEST). What is proved
is that curve and the corners the blends cut off, so the returned polyline is proved too (a controller may follow
either): where the polyline's edges are proved already only the blends are; otherwise (`prove_blends`, what the
planner asks first) the straight parts between the blends and the cut-off corners are.

The path parameter s is arc length in the space's weighted metric along the polyline, and a blend of radius r
spans s in [corner - r, corner + r], so straight parts keep their s whatever the blends: a straight piece that was
certified stays certified when a neighbouring blend shrinks.
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass

import numpy as np

# pydrake is imported inside the functions that use it, so that importing the package does not load Drake.
from app.checking.budget import Stop
from app.checking.certify import CLEARANCE, Certifier, straight_edges
from app.motion.path import distinct

# A blend's first radius: this fraction of the shorter of its two segments (at most 1/2, so blends never overlap).
BLEND = 0.5
# Halvings of a blend that fails certification before its corner becomes a stop.
TIGHTEN = 8
# A blend that fails this many times becomes a stop at once where its corner's own distances cannot prove even the
# last halving's blend clear: the corner lies that near something, a stop there costs the motion no more than so tight
# a blend, and the halvings in between cost a certifier call each (the welding cell's queries: benchmark pages).
STOP_TEST = 2
# A straight line the certificate cannot prove in this many parts is cheaper to change than to prove finer: a line
# between two samples gets a sample between (app.motion.trajectory_samples), a blend whose cut-off corner fails is
# tightened.
LINE_CUTS = 8
# Piece derivatives are linear in s up to rounding of their cubic Hermite form: a little slack on the bounds taken
# from them (the travel within a piece, the distance of a line between two samples from the curve).
CURVE_SLACK = 1 + 1e-9


@dataclass
class Leg:
    """A stretch of the path timed from rest to rest: waypoints first..last, blended at the corners in between."""

    first: int
    last: int
    offset: float  # global s of the leg's start; its Drake path runs over s - offset
    path: object  # PiecewisePolynomial, C1, pieces of degree <= 2
    pieces: list  # (s0, s1, corner or None), global s


def _leg(W: np.ndarray, tangent: np.ndarray, arc: np.ndarray, radii: np.ndarray, first: int, last: int) -> Leg:
    from pydrake.trajectories import PiecewisePolynomial

    tiny = 1e-12 * max(arc[-1], 1.0)
    breaks, values, slopes, pieces = [arc[first]], [W[first]], [tangent[first]], []
    for i in range(first + 1, last + 1):
        r = radii[i] if i < last else 0.0
        if arc[i] - r > breaks[-1] + tiny:  # the straight piece of segment i-1 up to the blend (or the leg's end)
            pieces.append((breaks[-1], arc[i] - r, None))
            breaks.append(arc[i] - r)
            values.append(W[i] - r * tangent[i - 1])
            slopes.append(tangent[i - 1])
        if i < last:
            pieces.append((breaks[-1], arc[i] + r, i))
            breaks.append(arc[i] + r)
            values.append(W[i] + r * tangent[i])
            slopes.append(tangent[i])
    path = PiecewisePolynomial.CubicHermite(np.array(breaks) - arc[first], np.array(values).T, np.array(slopes).T)
    return Leg(first, last, arc[first], path, pieces)


def legs_between_stops(W, tangent, arc, radii) -> list[Leg]:
    """The legs between stops: the ends and every corner whose radius is 0."""
    stops = [0] + [i for i in range(1, len(W) - 1) if radii[i] == 0] + [len(W) - 1]
    return [_leg(W, tangent, arc, radii, a, b) for a, b in itertools.pairwise(stops)]


class _Curve:
    """position(s), variation(s0, s1) and derivatives(s0, s1) over the global s of all legs, for the certifier: each
    for arrays of s, with one Drake call per leg they fall on."""

    def __init__(self, legs: list[Leg]):
        self.legs = legs
        self.starts = np.array([leg.offset for leg in legs])
        self.rates = [leg.path.MakeDerivative(1) for leg in legs]
        self._last = None  # see _end_rates

    def _leg_of(self, s: np.ndarray) -> np.ndarray:
        return np.maximum(np.searchsorted(self.starts, s, side="right") - 1, 0)

    def _values(self, paths: list, s: np.ndarray, leg_of: np.ndarray) -> np.ndarray:
        """paths[leg_of[i]] at s[i] (global s), rows of the result."""
        out = np.empty((len(s), self.legs[0].path.rows()))
        for k in np.unique(leg_of).tolist():
            rows = np.flatnonzero(leg_of == k)
            out[rows] = paths[k].vector_values(s[rows] - self.legs[k].offset).T
        return out

    def position(self, s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, float)
        return self._values([leg.path for leg in self.legs], s, self._leg_of(s))

    def variation(self, s0: np.ndarray, s1: np.ndarray) -> np.ndarray:
        # Within a piece the derivative is linear in s, so each coordinate's travel, the integral of its magnitude,
        # is in closed form: the mean of the two ends' magnitudes, or where it changes sign, the two triangles
        # either side of its zero, (d0^2 + d1^2) / (2 (|d0| + |d1|)).
        s0, s1, d0, d1 = self._end_rates(s0, s1)
        a, b = np.abs(d0), np.abs(d1)
        mean = np.where(d0 * d1 >= 0, 0.5 * (a + b), (a * a + b * b) / (2 * np.maximum(a + b, 1e-300)))
        return mean * (s1 - s0)[:, None] * CURVE_SLACK

    def derivatives(self, s0: np.ndarray, s1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        # Within a piece the derivative is linear in s: the second derivative is its change over the span.
        s0, s1, d0, d1 = self._end_rates(s0, s1)
        return d0, d1, np.abs(d1 - d0) / np.maximum(s1 - s0, 1e-300)[:, None] * CURVE_SLACK

    def _end_rates(self, s0, s1) -> tuple[np.ndarray, ...]:
        """(s0, s1, dq/ds at s0, at s1) of pieces within one leg piece each. The certifier asks variation and
        derivatives of the same pieces in each round: the last answer is kept, so Drake evaluates them once."""
        s0, s1 = np.asarray(s0, float), np.asarray(s1, float)
        key = (s0.tobytes(), s1.tobytes())
        if self._last is None or self._last[0] != key:
            leg = self._leg_of(0.5 * (s0 + s1))
            self._last = key, (s0, s1, self._values(self.rates, s0, leg), self._values(self.rates, s1, leg))
        return self._last[1]


class Margins:
    """What the proof of a curve found besides that it is free: pieces of the curve (global s), each with a lower
    bound on every pair's distance all along it, its margin (Certifier.certify's margins). The straight parts' pieces
    hold whatever the blends become; a blend's hold while its corner keeps the radius it was proved at (`on`).
    The lines between a trajectory's samples are proved from them (app.motion.trajectory_samples). Pieces cover a
    span only where they meet exactly: their ends are the same numbers (the certificate cuts an interval at shared
    points, and a blend and the straight parts beside it end at the same arc lengths). The polyline's corners the
    blends cut off are pieces of the polyline, not of the curve: kept apart (`polyline_least`)."""

    def __init__(self):
        self._line: list = []  # (s0, s1, margin)
        self._blends: dict = {}  # blend piece (s0, s1, corner) -> [(s0, s1, margin)]
        self._corners: list = []  # (s0, s1, margin) on the polyline

    def add_line(self, rows: np.ndarray) -> None:
        self._line += [tuple(row) for row in rows.tolist()]

    def add_blend(self, piece: tuple, rows: np.ndarray) -> None:
        self._blends.setdefault(piece, []).extend(tuple(row) for row in rows.tolist())

    def add_corners(self, rows: np.ndarray) -> None:
        self._corners += [tuple(row) for row in rows.tolist()]

    def polyline_least(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Per span [a[i], b[i]] of the polyline, the least margin of its pieces proved (straight parts and the
        corners the blends cut off) over it, or -inf where they leave part of it uncovered."""
        return self.least(np.array(sorted(self._line + self._corners), float).reshape(-1, 3), a, b)

    def on(self, legs: list[Leg]) -> np.ndarray:
        """The pieces that hold on the curve of these legs, (s0, s1, margin) rows sorted by s0."""
        rows = list(self._line)
        for leg in legs:
            for piece in leg.pieces:
                if piece[2] is not None:
                    rows += self._blends.get(piece, [])
        return np.array(sorted(rows), float).reshape(-1, 3)

    def least(self, rows: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Per span [a[i], b[i]] of the curve, the least margin of the pieces `rows` (see `on`) over it, or -inf
        where they leave part of it uncovered."""
        out = np.full(len(a), -np.inf)
        if not len(rows) or not len(a):
            return out
        s0, s1, margin = rows.T
        # Runs of pieces that meet or overlap: a span is covered when one run holds it.
        first = np.flatnonzero(np.concatenate([[True], s0[1:] > np.maximum.accumulate(s1)[:-1]]))
        starts, ends = s0[first], np.maximum.reduceat(s1, first)
        run = np.searchsorted(starts, a, side="right") - 1
        covered = (run >= 0) & (ends[run.clip(0)] >= b)
        overlap = (s0[None, :] < b[:, None]) & (s1[None, :] > a[:, None])
        least = np.where(overlap, margin[None, :], np.inf).min(axis=1)
        return np.where(covered, least, out)


def certified_radii(
    certifier: Certifier,
    W,
    tangent,
    arc,
    radii,
    tighten: int,
    known: np.ndarray,
    clearance: float,
    give_up: bool = False,
    stop: Stop | None = None,
) -> tuple[np.ndarray, list[int], dict]:
    """Blend radii tightened until every blend keeps `clearance` and the corner of the polyline it cuts off is
    free (a corner that never is becomes a stop), the segments whose straight part failed (indices into W's
    segments; none: the whole curve, and the polyline, are certified), and the cost.

    A segment's straight part runs between its corners' blends. As a blend shrinks, the straight parts beside it
    grow and keep their s, so only what they gain is proved. The polyline's corner a blend cuts off is within
    radius / 4 x the change of tangent of the blend, coordinate by coordinate (at the blend's middle), so where
    that moves no pair more than clearance / 2 the blend's proof covers it; otherwise it is proved itself, to keep
    clearance / 2 (the path polyline is part of the answer: a controller may follow it). Each round proves the
    blends, corners and straight parts it has in one certifier call, and keeps the margins of the curve's pieces
    (Margins; the last value returned). known: per segment, whether it is certified
    already (then so is its straight part, and its half of each corner). give_up: a straight part that fails ends
    the proof (for a caller that will prove the path another way or change it, rather than time it uncertified).
    stop: what bounds the proofs (Certifier.certify)."""
    rounds = _BlendRounds(certifier, W, tangent, arc, known, clearance, stop)
    radii, halvings = radii.copy(), np.zeros(len(W), int)
    while True:
        corners = rounds.prove(radii)
        if not corners or rounds.refused and give_up:
            return radii, sorted(rounds.refused), rounds.cost, rounds.margins
        for i in corners:
            halvings[i] += 1
            radii[i] /= 2
            smallest = radii[i] / 2.0 ** (tighten - halvings[i])
            if halvings[i] > tighten or halvings[i] == STOP_TEST and rounds.safe_radius(i, radii[i]) < smallest:
                radii[i] = 0.0


class _BlendRounds:
    """What certified_radii has proved so far, round by round, and what its rounds cost: per segment the span of
    its straight part proved, the segments whose straight part failed (`refused`), per corner the radius up to which
    the polyline it cuts off is proved, and the blends proved (as pieces of the curve: a blend of another radius is
    another piece)."""

    def __init__(self, certifier: Certifier, W, tangent, arc, known: np.ndarray, clearance: float, stop: Stop | None):
        self.certifier, self.W, self.tangent, self.arc = certifier, W, tangent, arc
        self.known, self.clearance, self.stop = known, clearance, stop
        self.line, self.tiny = straight_edges(W, arc), 1e-12 * max(arc[-1], 1.0)
        self.weights = certifier.checker.space.weights
        self.proved = np.tile([np.inf, -np.inf], (len(W) - 1, 1))  # per segment, the span of its straight part proved
        self.cornered = np.zeros(len(W))  # per corner, the radius up to which the polyline it cuts off is proved
        turn = np.abs(np.diff(tangent[: len(W) - 1], axis=0, prepend=tangent[:1]))  # per corner i, |t_i - t_i-1|
        self.covered = certifier.bound.pair_travel(turn / 4).max(axis=(-2, -1))  # per corner, per unit of radius
        self.done: set = set()  # blend pieces proved
        self.refused: set[int] = set()
        self.margins = Margins()
        self.cost = {"pieces": 0, "distance_queries": 0, "seconds": 0.0, "rounds": 0}

    def prove(self, radii: np.ndarray) -> set[int]:
        """A round at these radii: what the straight parts have gained, the blends not proved yet and the corners
        of the polyline their proofs do not cover, proved in one certifier call; the corners whose blend or cut-off
        failed."""
        straight = self._straight_gains(radii)
        curve = _Curve(legs_between_stops(self.W, self.tangent, self.arc, radii))
        blends = [p for leg in curve.legs for p in leg.pieces if p[2] is not None and p not in self.done]
        near, corners = self._uncovered_corners(radii)
        intervals = (
            [(s0, s1) for _, s0, s1 in straight]
            + [(-s1, -s0) for s0, s1, _ in blends]
            + [(s0, s1) for _, s0, s1 in corners]
        )
        margins = [self.clearance] * (len(straight) + len(blends)) + [self.clearance / 2] * len(corners)
        # A corner that fails once cut in LINE_CUTS is cheaper to tighten (halving its blend) than to prove finer.
        floor, variation = self.certifier.floor, self.line.variation
        floors = [floor] * (len(straight) + len(blends)) + [
            max(floor, np.linalg.norm(variation(np.array([s0]), np.array([s1]))[0] * self.weights) / LINE_CUTS)
            for _, s0, s1 in corners
        ]
        both = _Both(self.line, curve, self.W.shape[1])
        failed = _certify(self.certifier, both, intervals, margins, floors, self.stop)
        for key in ("pieces", "distance_queries", "seconds"):
            self.cost[key] += failed[key]
        return self._record(radii, straight, blends, near, corners, failed)

    def safe_radius(self, i: int, radius: float) -> float:
        """The largest radius up to `radius` whose blend at corner i, and the polyline it cuts off, the distances at
        the corner alone prove keep twice the clearance: both lie within radius x the larger of the corner's two
        tangents, coordinate by coordinate, of the corner (the blend is a Bezier curve of its ends and the corner),
        and moved that far a pair's distance changes by at most the motion bound's pair travel."""
        bound, c = self.certifier.bound, self.clearance
        unit = bound.pair_travel(np.maximum(np.abs(self.tangent[i - 1]), np.abs(self.tangent[i])))
        found = self.certifier.distances(self.W[i], float(unit.max() * radius + 2 * c) * (1 + 1e-9))
        if found is None:
            return 0.0
        safe = radius
        for pair, d in found.items():
            a, b = (bound.row(g) for g in pair)
            if unit[a, b] > 0:
                safe = min(safe, (d - 2 * c) / unit[a, b])
        return max(safe, 0.0)

    def _straight_gains(self, radii: np.ndarray) -> list:
        """(segment, s0, s1): what each straight part not known nor refused has gained since the last round."""
        arc, straight = self.arc, []
        for j in np.flatnonzero(~self.known):
            s0, s1, (lo, hi) = arc[j] + radii[j], arc[j + 1] - radii[j + 1], self.proved[j]
            if j in self.refused or s1 - s0 <= self.tiny:
                continue
            gained = [(s0, s1)] if lo > hi else [(a, b) for a, b in ((s0, lo), (hi, s1)) if b - a > self.tiny]
            straight += [(int(j), *span) for span in gained]
        return straight

    def _uncovered_corners(self, radii: np.ndarray) -> tuple[list, list]:
        """The corners whose cut-off the blend's proof does not cover and that are not proved at this radius
        (those it covers are marked proved), and the halves of their polyline to prove, (corner, s0, s1): each half
        apart (the polyline's variation holds within one segment); a known segment's half is proved already."""
        arc, inside = self.arc, np.arange(1, len(self.W) - 1)
        small = self.covered[inside] * radii[inside] <= self.clearance / 2
        self.cornered[inside[small]] = np.maximum(self.cornered[inside[small]], radii[inside[small]])
        near = inside[~small & (radii[inside] > self.cornered[inside])].tolist()
        corners = [
            (i, s0, s1)
            for i in near
            for j, s0, s1 in ((i - 1, arc[i] - radii[i], arc[i]), (i, arc[i], arc[i] + radii[i]))
            if not self.known[j]
        ]
        return near, corners

    def _record(self, radii, straight: list, blends: list, near: list, corners: list, stats: dict) -> set[int]:
        """What a round proved, from the certifier's stats on its intervals (straight parts, then blends, then
        corners): the indices of those that failed and the margins of the pieces that passed; the corners whose blend
        or cut-off failed."""
        failed, first_blend, first_corner = stats["failed"], len(straight), len(straight) + len(blends)
        interval = stats["margins"][:, 0].astype(int)
        self.margins.add_line(stats["margins"][interval < first_blend, 1:])
        self.margins.add_corners(stats["margins"][interval >= first_corner, 1:])
        for k, piece in enumerate(blends):  # a blend's pieces at -s: the curve's at s
            rows = stats["margins"][interval == first_blend + k]
            self.margins.add_blend(piece, np.column_stack([-rows[:, 2], -rows[:, 1], rows[:, 3]]))
        failed_straight = {k for k in failed if k < first_blend}
        failed_blends = {k - first_blend for k in failed if first_blend <= k < first_corner}
        failed_corners = {corners[k - first_corner][0] for k in failed if k >= first_corner}
        for i in near:
            if i not in failed_corners:
                self.cornered[i] = radii[i]
        self.cost["rounds"] += 1
        for k, (j, s0, s1) in enumerate(straight):
            if k in failed_straight:
                self.refused.add(j)
            else:
                self.proved[j] = min(self.proved[j, 0], s0), max(self.proved[j, 1], s1)
        self.done.update(p for k, p in enumerate(blends) if k not in failed_blends)
        return {blends[k][2] for k in failed_blends} | failed_corners


def _certify(certifier: Certifier, curve, intervals: list, clearances: list, floors: list, stop: Stop | None) -> dict:
    """The certifier's stats on the intervals of `curve`, each to keep its clearance, cut no finer than its floor
    (none asked for: no cost), with the margins of the pieces that passed."""
    if not intervals:
        return {"failed": [], "pieces": 0, "distance_queries": 0, "seconds": 0.0, "margins": np.zeros((0, 4))}
    clearances, floors = np.array(clearances, float), np.array(floors, float)
    return certifier.certify(curve, intervals, clearances, floors, stop, margins=True)[1]


class _Both:
    """The polyline (`line`: position, variation) at s >= 0 and the blended curve at -s, so that one certifier call
    proves pieces of both (its rounds batch their distance queries together); negating s is exact, and both curves
    are W[0] at s = 0."""

    def __init__(self, line: tuple, curve: _Curve, dim: int):
        self.line, self.curve, self.dim = line, curve, dim

    def position(self, s: np.ndarray) -> np.ndarray:
        out, curved = np.empty((len(s), self.dim)), s < 0
        out[~curved] = self.line.position(s[~curved])
        out[curved] = self.curve.position(-s[curved])
        return out

    def variation(self, s0: np.ndarray, s1: np.ndarray) -> np.ndarray:
        out, curved = np.empty((len(s0), self.dim)), s0 + s1 < 0
        out[~curved] = self.line.variation(s0[~curved], s1[~curved])
        out[curved] = self.curve.variation(-s1[curved], -s0[curved])
        return out

    def derivatives(self, s0: np.ndarray, s1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        # On the curve, q(s) = curve(-s): the velocities change sign, and s0 is the curve's later end.
        out = [np.empty((len(s0), self.dim)) for _ in range(3)]
        curved = s0 + s1 < 0
        for o, x in zip(out, self.line.derivatives(s0[~curved], s1[~curved])):
            o[~curved] = x
        at_1, at_0, dd = self.curve.derivatives(-s1[curved], -s0[curved])
        out[0][curved], out[1][curved], out[2][curved] = -at_0, -at_1, dd
        return tuple(out)


def first_radii(lengths: np.ndarray) -> np.ndarray:
    """Each corner's first blend radius: at most half of each segment it touches, or all of the first or last
    segment (the path's ends have no blend to share it with), so that blends never overlap."""
    share = np.full(len(lengths), BLEND)
    share[[0, -1]] = 2 * BLEND
    radii = np.zeros(len(lengths) + 1)
    radii[1:-1] = np.minimum(share[:-1] * lengths[:-1], share[1:] * lengths[1:])
    return radii


def path_geometry(waypoints, weights):
    """Waypoints without repeats, unit tangents, arc lengths in the weighted metric, and which waypoints were kept."""
    P = np.atleast_2d(np.asarray(waypoints, float))
    kept = distinct(P)
    W = P[kept]
    steps = np.diff(W, axis=0)
    lengths = np.linalg.norm(steps * weights, axis=1)
    tangent = steps / lengths[:, None] if len(W) > 1 else np.zeros((0, W.shape[1]))
    arc = np.concatenate([[0.0], np.cumsum(lengths)])
    return W, np.vstack([tangent, tangent[-1:]]) if len(W) > 1 else tangent, arc, kept


@dataclass(frozen=True)
class BlendProof:
    """The curve a path's trajectory follows, certified ahead of its timing (prove_blends) to keep `clearance`: its
    blend radii, the path's edges whose straight part could not be proved (none: the whole curve is certified), the
    margins its proof found (None: not known), and the path's edges its pieces cover whole with that clearance (as
    proved as if the polyline had been certified: a persistent roadmap keeps them proved for later queries)."""

    path: np.ndarray
    radii: np.ndarray
    failed: list[int]
    cost: dict
    clearance: float
    margins: Margins | None = None
    whole: tuple[int, ...] = ()

    def reversed(self) -> BlendProof:
        """The proof of the same curve run backwards (a blend is symmetric about its corner). Its margins are left
        out: they are placed by arc length, which the reversed path adds up anew (not to the same last digit)."""
        failed = sorted(len(self.path) - 2 - i for i in self.failed)
        whole = tuple(sorted(len(self.path) - 2 - i for i in self.whole))
        return dataclasses.replace(
            self, path=self.path[::-1].copy(), radii=self.radii[::-1].copy(), failed=failed, margins=None, whole=whole
        )


def prove_blends(
    certifier: Certifier,
    path: np.ndarray,
    known=(),
    clearance: float = CLEARANCE,
    tighten: int = TIGHTEN,
    stop: Stop | None = None,
) -> BlendProof:
    """The curve time_path makes of `path` (a path of the certifier's checker, wrapped) certified to keep
    `clearance`: its blends, the straight parts of its edges between them, and the corners the blends cut off (to
    keep half of it, see certified_radii). Stops at the first straight part that fails. known: indices of the
    path's edges certified already (to keep `clearance`), whose straight parts are not proved again. stop: what
    bounds the proofs."""
    space = certifier.checker.space
    W, tangent, arc, kept = path_geometry(space.unwrap(path), space.weights)
    edge = kept[1:] - 1  # each of W's segments as an edge of the path (repeated waypoints are skipped)
    if len(W) < 2:
        cost = {"pieces": 0, "distance_queries": 0, "seconds": 0.0, "rounds": 0}
        return BlendProof(path.copy(), np.zeros(len(W)), [], cost, clearance)
    known = np.isin(edge, list(known))
    radii, failed, cost, margins = certified_radii(
        certifier, W, tangent, arc, first_radii(np.diff(arc)), tighten, known, clearance, give_up=True, stop=stop
    )
    whole = tuple(edge[~known & (margins.polyline_least(arc[:-1], arc[1:]) >= clearance)].tolist())
    return BlendProof(path.copy(), radii, [int(edge[j]) for j in failed], cost, clearance, margins, whole)
