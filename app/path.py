"""Paths as polylines in configuration space: length, fine verification, shortcut smoothing.

A path is an (n, dim) array of waypoints; its edges are straight in the scene's metric (the short way round on
continuous angles), exactly as `oracle.space.interpolate` walks them. Shortcuts are checked at one resolution (batched,
coarse-to-fine, so colliding ones cost a few checks); the planner smooths at the planning resolution, certifies the
result (app.certify), and smooths again at the fine resolution (FINE x that) in the case a shortcut cannot be proved
(checking every accepted shortcut at the fine resolution doubled the cost of smoothing on the maze). `verify` is the
discrete fine check, for paths no certificate vouches for (OMPL's, in `bench ompl`).
"""

from __future__ import annotations

import numpy as np

from app.budget import BudgetSpent

# The fine check runs at this fraction of the planning resolution.
FINE = 0.25


def dedupe(P: np.ndarray, tol: float = 1e-12) -> np.ndarray:
    """Drop waypoints equal to their predecessor."""
    P = np.atleast_2d(np.asarray(P, float))
    if len(P) < 2:
        return P
    keep = np.concatenate([[True], np.any(np.abs(np.diff(P, axis=0)) > tol, axis=1)])
    return P[keep]


def segment_lengths(oracle, P: np.ndarray) -> np.ndarray:
    return oracle.space.distance(P[:-1], P[1:]) if len(P) > 1 else np.zeros(0)


def path_length(oracle, P: np.ndarray) -> float:
    return float(segment_lengths(oracle, P).sum())


def verify(oracle, P: np.ndarray, resolution: float | None = None) -> np.ndarray:
    """Free flag per edge, checked at `resolution` (default: FINE x the scene's)."""
    P = np.atleast_2d(np.asarray(P, float))
    if len(P) < 2:
        return np.ones(0, bool)
    return oracle.edges_free(P[:-1], P[1:], resolution or FINE * oracle.space.resolution)


def _point_at(oracle, P: np.ndarray, cum: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Configurations at arc lengths s along P, and the index of the segment each lies on."""
    seg = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(P) - 2)
    length = cum[seg + 1] - cum[seg]
    t = np.where(length > 0, (s - cum[seg]) / np.where(length > 0, length, 1.0), 0.0)
    d = oracle.space.difference(P[seg], P[seg + 1])
    return oracle.space.wrap(P[seg] + t[:, None] * d), seg


def shortcut(
    oracle,
    P: np.ndarray,
    rng: np.random.Generator,
    rounds: int = 50,
    candidates: int = 8,
    resolution: float | None = None,
) -> tuple[np.ndarray, dict]:
    """Shorten P with a greedy pass over its waypoints, `rounds` rounds of random shortcuts, a last greedy pass.

    Greedy: from each kept waypoint, jump to the farthest later waypoint it sees directly. Random: each round draws
    `candidates` pairs of points anywhere along the path and takes, of those whose shortcut is free, the one that
    saves most length. Candidates are checked one at a time, best first, and the first free one ends the search:
    a colliding candidate costs a few checks (coarse to fine), so a round costs about one free edge, as OMPL's
    PathSimplifier does. Shortcuts are checked at `resolution` (default: the scene's), and so are the pieces of the
    edges they cut: if every edge of P passed a check at `resolution`, every edge of the result has. A budget that
    runs out (BudgetSpent from the oracle) ends smoothing with the path as it stands, which is always checked.
    Deterministic for a given rng state.
    """
    resolution = resolution or oracle.space.resolution
    P = dedupe(P)
    stats = {
        "greedy_removed": 0,
        "random_accepted": 0,
        "candidates_checked": 0,
        "length_before": path_length(oracle, P),
        "resolution": resolution,
        "stopped": False,
    }
    try:
        if len(P) > 2:
            P = _greedy(oracle, P, resolution, stats)
        for _ in range(rounds):
            if len(P) < 3:
                break
            P = _random_shortcut(oracle, P, rng, candidates, resolution, stats)
        if len(P) > 2 and rounds:
            # Random shortcuts leave two new waypoints each; a last greedy pass removes those that became redundant.
            P = _greedy(oracle, P, resolution, stats)
    except BudgetSpent:
        stats["stopped"] = True
    stats["length_after"] = path_length(oracle, P)
    return P, stats


def _random_shortcut(oracle, P, rng, candidates: int, resolution: float, stats: dict) -> np.ndarray:
    seg_len = segment_lengths(oracle, P)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    total = cum[-1]
    if total <= 0:
        return P
    s = np.sort(rng.uniform(0.0, total, size=(candidates, 2)), axis=1)
    qa, ia = _point_at(oracle, P, cum, s[:, 0])
    qb, ib = _point_at(oracle, P, cum, s[:, 1])
    gain = (s[:, 1] - s[:, 0]) - oracle.space.distance(qa, qb)
    useful = np.flatnonzero((ib > ia) & (gain > 1e-9 * total))
    for c in useful[np.argsort(-gain[useful], kind="stable")]:
        stats["candidates_checked"] += 1
        # The shortcut also leaves a piece of each edge it cuts: points along a piece are not points the whole
        # edge was checked at, so the pieces are checked too, and every edge of P stays checked at `resolution`.
        if oracle.edges_free(
            np.array([qa[c], P[ia[c]], qb[c]]), np.array([qb[c], qa[c], P[ib[c] + 1]]), resolution
        ).all():
            stats["random_accepted"] += 1
            return dedupe(np.vstack([P[: ia[c] + 1], qa[c], qb[c], P[ib[c] + 1 :]]))
    return P


def _greedy(oracle, P: np.ndarray, resolution: float, stats: dict) -> np.ndarray:
    """From each kept waypoint, the farthest later waypoint it sees directly: tried farthest first, one at a time,
    so only the edge taken is checked in full (a blocked one costs a few coarse-to-fine checks)."""
    out, i, n = [P[0]], 0, len(P)
    while i < n - 1:
        nxt = i + 1  # the path's own edge, free already
        for j in range(n - 1, i + 1, -1):
            stats["candidates_checked"] += 1
            if oracle.edges_free(P[i], P[j], resolution)[0]:
                nxt = j
                break
        stats["greedy_removed"] += nxt - i - 1
        out.append(P[nxt])
        i = nxt
    return np.array(out)
