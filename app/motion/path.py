"""Paths as polylines in configuration space: length, fine verification, shortcut smoothing.

A path is an (n, dim) array of waypoints; its edges are straight in the scene's metric (the short way round on
continuous angles), exactly as `space.interpolate` walks them. Shortcuts are checked at one resolution (batched,
coarse-to-fine, so colliding ones cost a few checks); the planner smooths at the planning resolution and certifies the
result (app.checking.certify). A shortcut the certificate refuses is banned and smoothing replayed with a `Shortcuts`
memo: every check it made before is remembered, so the replay pays only for what differs (checking every accepted
shortcut at the fine resolution instead doubled the cost of smoothing on the maze). `verify` is the discrete fine
check, for paths no certificate vouches for (OMPL's, in `bench ompl`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from app.checking.budget import BudgetSpent, Stop

# The fine check runs at this fraction of the planning resolution.
FINE = 0.25


def dedupe(P: np.ndarray, tol: float = 1e-12) -> np.ndarray:
    """Drop waypoints equal to their predecessor."""
    P = np.atleast_2d(np.asarray(P, float))
    return P[distinct(P, tol)]


def distinct(P: np.ndarray, tol: float = 1e-12) -> np.ndarray:
    """Indices of the waypoints that differ from their predecessor (the first always)."""
    P = np.atleast_2d(np.asarray(P, float))
    return np.flatnonzero(np.concatenate([[True], np.any(np.abs(np.diff(P, axis=0)) > tol, axis=1)]))


def segment_lengths(checker, P: np.ndarray) -> np.ndarray:
    return checker.space.distance(P[:-1], P[1:]) if len(P) > 1 else np.zeros(0)


def path_length(checker, P: np.ndarray) -> float:
    return float(segment_lengths(checker, P).sum())


def verify(checker, P: np.ndarray, resolution: float | None = None, stop: Stop | None = None) -> np.ndarray:
    """Free flag per edge, checked at `resolution` (default: FINE x the scene's), bounded by `stop`."""
    P = np.atleast_2d(np.asarray(P, float))
    if len(P) < 2:
        return np.ones(0, bool)
    return checker.edges_free(P[:-1], P[1:], resolution or FINE * checker.space.resolution, stop=stop)


@dataclass
class ShortcutStats:
    """What one smoothing pass did: angles turned the short way (`unwind`), waypoints the greedy passes removed,
    random shortcuts taken, shortcut candidates checked, the lengths before and after (weighted metric), the
    resolution its shortcuts were checked at, and whether its budget ran out."""

    unwound: int = 0
    greedy_removed: int = 0
    random_accepted: int = 0
    candidates_checked: int = 0
    length_before: float = 0.0
    length_after: float = 0.0
    resolution: float = 0.0
    stopped: bool = False

    def to_json(self) -> dict:
        return asdict(self)


class Shortcuts:
    """What one smoothing knows about straight edges: the checks made (a replay from the same path and rng state asks
    the checker nothing until it departs from the run before) and the shortcuts banned because the certificate
    refused an edge they carry (a banned shortcut is treated as blocked)."""

    def __init__(self):
        self.known: dict[bytes, bool] = {}
        self.banned: set[bytes] = set()

    @staticmethod
    def _key(a: np.ndarray, b: np.ndarray) -> bytes:
        return np.concatenate([a, b]).tobytes()

    def free(self, checker, a: np.ndarray, b: np.ndarray, resolution: float, stop: Stop | None = None) -> bool:
        """Whether a -> b is free at `resolution`, asking the checker only the first time (the ends lie on a checked
        path, so they are not checked again)."""
        key = self._key(a, b)
        if key in self.banned:
            return False
        if key not in self.known:
            self.known[key] = bool(checker.edges_free(a, b, resolution, ends_free=True, stop=stop)[0])
        return self.known[key]

    def ban_carriers(self, space, P: np.ndarray, edges) -> int:
        """Ban the free shortcuts that carry an edge P[i] -> P[i + 1] (i in `edges`): the edge lies on the shortcut's
        segment. Returns how many were banned; an edge no shortcut carries lies on the path smoothing started from."""
        carriers = {
            key
            for key, free in self.known.items()
            if free
            and key not in self.banned
            and any(on_segment(space, *np.frombuffer(key).reshape(2, -1), P[i : i + 2]) for i in edges)
        }
        self.banned |= carriers
        return len(carriers)


def on_segment(space, a: np.ndarray, b: np.ndarray, Q: np.ndarray, tol: float = 1e-9) -> bool:
    """Whether every configuration of Q lies on the straight edge a -> b (within tol x its length)."""
    d = space.difference(a, b) * space.weights
    dd = float(d @ d)
    if dd == 0:
        return False
    v = space.difference(np.broadcast_to(a, np.shape(Q)), Q) * space.weights
    t = v @ d / dd
    off = v - t[:, None] * d
    return bool(np.all((t > -tol) & (t < 1 + tol)) and np.all(np.einsum("ij,ij->i", off, off) < tol**2 * dd))


def _point_at(checker, P: np.ndarray, cum: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Configurations at arc lengths s along P, and the index of the segment each lies on."""
    seg = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(P) - 2)
    length = cum[seg + 1] - cum[seg]
    t = np.where(length > 0, (s - cum[seg]) / np.where(length > 0, length, 1.0), 0.0)
    d = checker.space.difference(P[seg], P[seg + 1])
    return checker.space.wrap(P[seg] + t[:, None] * d), seg


def shortcut(
    checker,
    P: np.ndarray,
    rng: np.random.Generator,
    rounds: int = 50,
    candidates: int = 8,
    resolution: float | None = None,
    memo: Shortcuts | None = None,
    stop: Stop | None = None,
) -> tuple[np.ndarray, ShortcutStats]:
    """Shorten P with a greedy pass over its waypoints, `rounds` rounds of random shortcuts, a last greedy pass.

    Greedy: from each kept waypoint, jump to the farthest later waypoint it sees directly. Random: each round draws
    `candidates` pairs of points anywhere along the path and takes, of those whose shortcut is free, the one that
    saves most length. Candidates are checked one at a time, best first, and the first free one ends the search:
    a colliding candidate costs a few checks (coarse to fine), so a round costs about one free edge, as OMPL's
    PathSimplifier does. Shortcuts are checked at `resolution` (default: the scene's); the pieces of the edges they
    cut are not checked again: they are parts of checked edges, and the planner certifies the result in the
    continuous sense anyway (and at the same check cap, dropping that re-check shortened the median paths: benchmark
    pages). So every edge of the result lies on an edge of P or on a shortcut
    checked free. A `stop` that runs out (BudgetSpent) ends smoothing with the path as it stands.
    `memo` remembers checks and bans across replays (see Shortcuts). Deterministic for a given rng state and memo.
    """
    resolution = resolution or checker.space.resolution
    memo = memo if memo is not None else Shortcuts()
    P = dedupe(P)
    stats = ShortcutStats(length_before=path_length(checker, P), resolution=resolution)
    try:
        if len(P) > 2:
            P = _greedy(checker, P, resolution, stats, memo, stop)
        for _ in range(rounds):
            if len(P) < 3:
                break
            P = _random_shortcut(checker, P, rng, candidates, resolution, stats, memo, stop)
        if len(P) > 2 and rounds:
            # Random shortcuts leave two new waypoints each; a last greedy pass removes those that became redundant.
            P = _greedy(checker, P, resolution, stats, memo, stop)
        if len(P) > 2:
            P = unwind(checker, P, resolution, stats, memo, stop)
    except BudgetSpent:
        stats.stopped = True
    stats.length_after = path_length(checker, P)
    return P, stats


def unwind(
    checker, P: np.ndarray, resolution: float, stats: ShortcutStats, memo: Shortcuts, stop: Stop | None = None
) -> np.ndarray:
    """Each continuous angle that P turns a whole turn further than the short way between its ends is turned the
    short way instead: spread over P's edges in proportion to their length, the other coordinates as they were
    (OMPL's partial shortcut, on one coordinate), kept if every new edge is free. Each edge takes the short way
    round, but several in a row need not, and a shortcut takes the short way between its ends even where the part of
    the path it replaces turned the other way (a window job's wrist came out a whole turn off home, winding the
    torch's cable, and the shortcuts that would undo it crossed the hatch). Done once the shortcuts are taken (done
    before them too, its checks came out of smoothing's share: benchmark pages); a budget that runs out leaves the
    path as it stands (stats.stopped)."""
    space = checker.space
    try:
        for c in np.flatnonzero(space.continuous):
            U = space.unwrap(P)
            net = U[-1, c] - U[0, c]
            short = (net + np.pi) % (2 * np.pi) - np.pi
            if abs(net - short) < np.pi:  # (they differ by whole turns) the path turns the short way already
                continue
            cum = np.cumsum(np.concatenate([[0.0], segment_lengths(checker, P)]))
            Q = P.copy()
            Q[1:-1, c] = (U[0, c] + short * cum[1:-1] / cum[-1] + np.pi) % (2 * np.pi) - np.pi  # the ends stay exact
            if all(memo.free(checker, a, b, resolution, stop) for a, b in zip(Q[:-1], Q[1:])):
                stats.unwound += 1
                P = Q
    except BudgetSpent:
        stats.stopped = True
    return P


def _random_shortcut(
    checker, P, rng, candidates: int, resolution: float, stats: ShortcutStats, memo: Shortcuts, stop: Stop | None
) -> np.ndarray:
    seg_len = segment_lengths(checker, P)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    total = cum[-1]
    if total <= 0:
        return P
    s = np.sort(rng.uniform(0.0, total, size=(candidates, 2)), axis=1)
    qa, ia = _point_at(checker, P, cum, s[:, 0])
    qb, ib = _point_at(checker, P, cum, s[:, 1])
    gain = (s[:, 1] - s[:, 0]) - checker.space.distance(qa, qb)
    useful = np.flatnonzero((ib > ia) & (gain > 1e-9 * total))
    for c in useful[np.argsort(-gain[useful], kind="stable")]:
        stats.candidates_checked += 1
        if memo.free(checker, qa[c], qb[c], resolution, stop):
            stats.random_accepted += 1
            return dedupe(np.vstack([P[: ia[c] + 1], qa[c], qb[c], P[ib[c] + 1 :]]))
    return P


def _greedy(
    checker, P: np.ndarray, resolution: float, stats: ShortcutStats, memo: Shortcuts, stop: Stop | None
) -> np.ndarray:
    """From each kept waypoint, the farthest later waypoint it sees directly: tried farthest first, one at a time,
    so only the edge taken is checked in full (a blocked one costs a few coarse-to-fine checks)."""
    out, i, n = [P[0]], 0, len(P)
    while i < n - 1:
        nxt = i + 1  # the path's own edge, free already
        for j in range(n - 1, i + 1, -1):
            stats.candidates_checked += 1
            if memo.free(checker, P[i], P[j], resolution, stop):
                nxt = j
                break
        stats.greedy_removed += nxt - i - 1
        out.append(P[nxt])
        i = nxt
    return np.array(out)
