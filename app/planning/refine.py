"""What a query does with a roadmap path once it has one: smooth it, prove it, and repair what the proof refuses.

Optimistic first: the roadmap path is shortened with shortcuts checked at the planning resolution and the result
proved by the certificate (continuous, app.checking.certify) -- a discrete re-check at a finer resolution would
only repeat part of its work. A shortcut the certificate refuses is banned and smoothing replayed (`smooth_and_prove`:
the replay repeats the other shortcuts for free, up to SMOOTHING_REPAIRS times). If the roadmap path itself is
refused, something grazes an obstacle between checked points, as in a narrow passage: the query turns careful
(`fine_only`). From then on a roadmap path is proved before any smoothing is spent on it (`prove_roadmap_path`); an
edge the certificate cannot prove is treated as colliding and leaves the roadmap, so the search goes on without it.
Paths are never returned unproved: the audit found that such paths can really collide (benchmark pages, "Tuning
notes"). Proofs keep to the query's time limit, not to its check limit (they ask for distances, not checks: the
`proving` stop).
"""

from __future__ import annotations

import dataclasses
import itertools
from typing import NamedTuple

import numpy as np

from app.checking.budget import BudgetSpent, Stop, poll
from app.checking.certify import Certifier, polyline
from app.motion.path import FINE, Shortcuts, ShortcutStats, shortcut, unwind
from app.motion.timing import BlendProof, prove_blends
from app.planning.result import Certificate, Ledger
from app.planning.settings import SMOOTHING_CAP, SMOOTHING_MIN, SMOOTHING_REPAIRS, SMOOTHING_SHARE, PlanSettings


class Refined(NamedTuple):
    """A path found and proved: the roadmap path's nodes, the answer's waypoints, the shortcut pass's record (None:
    not smoothed), the repairs smoothing made, whether the smoothed path was dropped for the roadmap path, and the
    certificate."""

    nodes: list[int]
    path: np.ndarray
    shortcuts: ShortcutStats | None
    repairs: int
    dropped: bool
    certificate: Certificate


class Refinement:
    """The smoothing and proving of one query's roadmap paths (see the module), on its checker, roadmap and ledger.

    certifier: a persistent roadmap's, whose cached distances serve every query on it (None: made when the first
    path is to be proved, in the "certify" phase: it sets up per-geometry bounds)."""

    def __init__(self, checker, roadmap, settings: PlanSettings, ledger: Ledger, seed, certifier=None):
        self.checker, self.roadmap, self.settings, self.ledger = checker, roadmap, settings, ledger
        self.clearance = settings.clearance
        self.fine = FINE * roadmap.resolution
        # Set once an optimistic path has failed the certificate: from then on roadmap paths must pass the fine
        # check and shortcuts are checked at the fine resolution.
        self.fine_only = False
        self.unproved_edges = 0  # roadmap edges fine-checked free that the certificate could not prove
        self.proof_unfinished = False  # the budget ended a proof (or the timing) of a path found
        self.blends: BlendProof | None = None  # the curve of the last path whose blends were proved
        self.certifier = certifier
        if certifier is not None:
            certifier.checker = checker
        self._seed = seed  # the smoothing's random stream (the same shortcuts for the same seed)

    def prove(self, fn, *args, **kwargs):
        """fn(*args, **kwargs), remembering when the budget ended it (for the failure's message)."""
        try:
            return fn(*args, **kwargs)
        except BudgetSpent:
            self.proof_unfinished = True
            raise

    # ---- smoothing --------------------------------------------------------------------------------------------
    def smooth(self, nodes: list[int], stop: Stop, memo: Shortcuts | None = None) -> tuple[np.ndarray, ShortcutStats]:
        """The roadmap path shortened (same seed, same shortcuts), at the fine resolution when fine-only, spending
        at most SMOOTHING_SHARE of the checks that finding it took, SMOOTHING_CAP with the passes before: a path
        is worth shortening, not at any price. `memo`: what an earlier pass on the same path checked and banned."""
        raw, memo = self.roadmap.Q[nodes], memo if memo is not None else Shortcuts()
        resolution = self.fine if self.fine_only else self.checker.space.resolution
        spent = self.ledger.checks.smoothing
        finding = stop.checks() - spent
        share = max(SMOOTHING_MIN, int(SMOOTHING_SHARE * finding))
        within = stop.within(max(0, min(share, int(SMOOTHING_CAP * finding) - spent)))
        rng = np.random.default_rng(self._seed)
        rounds = self.settings.smooth_rounds
        path, stats = self.ledger.run(
            "smoothing", shortcut, self.checker, raw, rng, rounds=rounds, resolution=resolution, memo=memo, stop=within
        )
        # Not held to the cap: a path that winds a joint a whole turn more than it needs is worth a pass of checks.
        if stats.stopped:
            path = self.ledger.run("smoothing", unwind, self.checker, path, resolution, stats, memo, stop)
        return path, stats

    # ---- proving ----------------------------------------------------------------------------------------------
    def certify(self, path: np.ndarray, stop: Stop, edges=None) -> Certificate:
        """Whether every straight edge of `path` (or those of `edges`, indices into it) keeps the clearance in the
        continuous sense (app.checking.certify); `failed` lists the edges that could not be proved. A segment that is
        a roadmap edge proved before with this clearance or more (by this query, or by an earlier one on a
        persistent roadmap, in this process) is not proved again; one proved now is remembered."""
        self._make_certifier()
        pairs = self.roadmap.edge_pairs(path)
        known = self.roadmap.proved_with(pairs, self.clearance)
        edges = [i for i in (range(len(path) - 1) if edges is None else edges) if not known[i]]
        if not edges:
            return Certificate(True, self.clearance)
        curve = polyline(self.checker.space, path)
        intervals = [(i, i + 1) for i in edges]
        proved, stats = self.ledger.run("certify", self.certifier.certify, curve, intervals, self.clearance, stop=stop)
        failed = [edges[k] for k in stats["failed"]]
        self.roadmap.mark_proved([pairs[i] for i in edges if i not in failed], self.clearance)
        return Certificate.of(proved, self.clearance, {**stats, "failed": failed})

    def certify_blends(self, path: np.ndarray, stop: Stop) -> Certificate:
        """The blends timing will cut the corners of `path` with, proved to keep the clearance (a blend that cannot
        be proved tightened, at last a stop; app.motion.timing.prove_blends), for a path to be timed whose edges are
        proved already (so its straight parts and the corners the blends cut off are too); the proof is kept for
        timing."""
        self._make_certifier()
        known = np.arange(len(path) - 1)
        self.blends = self.ledger.run("certify", prove_blends, self.certifier, path, known, self.clearance, stop=stop)
        stats = {**self.blends.cost, "failed": self.blends.failed}
        return Certificate.of(not self.blends.failed, self.clearance, stats, blended=True)

    def _make_certifier(self) -> None:
        if self.certifier is None:
            self.certifier = self.ledger.run("certify", Certifier, self.checker)

    def smooth_and_prove(
        self, nodes: list[int], stop: Stop, proving: Stop, proof: Certificate | None = None
    ) -> tuple[np.ndarray, ShortcutStats, int, Certificate | None]:
        """(smoothed path, its shortcut record, repairs, its certificate or None when it could not be proved;
        `proof`: the roadmap path's, if it has one, so that an unshortened path is not proved twice). A refused edge
        that lies on a shortcut bans that shortcut, and smoothing is replayed from the roadmap path: the replay
        repeats the same shortcuts for free (Shortcuts remembers every check) up to the banned one and then spends
        what is left of the smoothing cap; at most SMOOTHING_REPAIRS times. Undoing one grazing shortcut keeps the
        others, where falling back to the unsmoothed path would lose them all."""
        memo, proved_edges, work = Shortcuts(), set(), {"pieces": 0, "distance_queries": 0, "seconds": 0.0}
        for repairs in itertools.count():
            path, stats = self.smooth(nodes, stop, memo)
            if proof is not None and np.array_equal(path, self.roadmap.Q[nodes]):
                return path, stats, repairs, proof
            # The polyline first, then the blends that cut its corners (tightened where they fail, at last stops):
            # a smoothed path often grazes something, and a proof of the blended curve first spent blends and
            # corners on it before it found the failing edges (benchmark history, "The polyline first again").
            # Edges the replay kept were proved already.
            keys = [path[i : i + 2].tobytes() for i in range(len(path) - 1)]
            todo = [i for i, k in enumerate(keys) if k not in proved_edges]
            certificate = self.prove(self.certify, path, proving, todo)
            proved_edges.update(k for i, k in enumerate(keys) if i not in certificate.failed)
            work = _added(work, certificate)
            if certificate.proved and self.settings.timing:  # its edges proved: only the blends are left
                certificate = self.prove(self.certify_blends, path, proving)
                work = _added(work, certificate)
            if certificate.proved:
                return path, stats, repairs, dataclasses.replace(certificate, **work)
            if repairs == SMOOTHING_REPAIRS or not memo.ban_carriers(self.checker.space, path, certificate.failed):
                return path, stats, repairs, None
        raise AssertionError("unreachable")

    def prove_roadmap_path(self, nodes: list[int], stop: Stop, proving: Stop) -> Certificate | None:
        """The certificate of the roadmap path through `nodes` (its edges not proved before), or None when it cannot
        be proved; then its unprovable edges have left the roadmap."""
        edges = [(min(a, b), max(a, b)) for a, b in itertools.pairwise(nodes)]
        certificate = self.prove(self.certify, self.roadmap.Q[nodes], proving)
        if certificate.proved:
            return certificate
        for i in certificate.failed:
            self.roadmap.remove_edge(*edges[i])
        self.unproved_edges += len(certificate.failed)
        poll(stop)  # certificates ask no collision checks, so the budget is polled here
        return None


def _added(work: dict, certificate: Certificate) -> dict:
    return {
        "pieces": work["pieces"] + certificate.pieces,
        "distance_queries": work["distance_queries"] + certificate.distance_queries,
        "seconds": work["seconds"] + certificate.seconds,
    }
