"""What every sampler shares: the sampling loop with its budget and statistics, and bounded random steps.

A sampler is built with a checker and its parameters and answers `sample(k, rng, stop=...)` with k free, in-bounds
configurations. It works in rounds: each round makes a vectorised batch of candidates and asks the checker about
all of them in as few `are_free` calls as possible, and the loop stops as soon as k samples exist, or when the stop
says so (BudgetSpent). Work done on candidates that are then not needed is still counted (gamma_c is honest).

Steps are measured in the space's weighted metric: a coordinate's weight is the lever arm it swings, so a
displacement of `s` workspace units along an angle is s / weight radians.
"""

from __future__ import annotations

import numpy as np

from app.checking.budget import Stop, poll
from app.checking.protocol import Checker
from app.errors import SamplerBudgetExceeded, UserError


def unit_directions(rng: np.random.Generator, n: int, dim: int) -> np.ndarray:
    """n directions uniform on the unit sphere of R^dim."""
    g = rng.normal(size=(n, dim))
    norm = np.sqrt(np.einsum("ij,ij->i", g, g))[:, None]
    return g / np.where(norm > 0, norm, 1.0)


class Sampler:
    """Base class. Subclasses implement `_round(rng, need, stop) -> (samples, bridges or None)`.

    Attributes:
        name: The name it is registered under in SAMPLERS.
        step: The base step a in the weighted metric.
        max_checks: A guard on one `sample` call that finds nothing, not a budget (that is its `stop`).
        stats: Its counters (collision checks, rounds, ...).
        bridges: (k, 2, dim) the colliding bridge endpoints of the last samples (bridge samplers; else None).
    """

    name = ""

    def __init__(
        self,
        checker: Checker,
        step: float = 10.0,
        max_checks: int = 2_000_000,
        max_rounds: int = 100_000,
        redraws: int = 20,
    ):
        if not np.isfinite(step) or step <= 0:
            raise UserError(f"step must be a positive finite number, got {step}")
        self.checker = checker
        self.space = checker.space
        self.step = float(step)
        # A guard on one sample() call, not a budget (that is its stop): a sampler that finds nothing stops here.
        self.max_checks = int(max_checks)
        self.max_rounds = int(max_rounds)  # rounds one sample() call may run (guards rounds that check nothing)
        self.redraws = int(redraws)  # how often an out-of-bounds step is redrawn before that proposal is dropped
        self.stats: dict = {}
        self._begun = False  # _begin has run: there is state to resume from
        # Checks the current call may still spend before `max_checks`: a round's batch is no larger (a caller that
        # caps a call tightly, as the adaptive mixture does, is not overrun by a batch sized for thousands).
        self._room = self.max_checks
        self.bridges: np.ndarray | None = None  # (k, 2, dim) colliding bridge endpoints of the last samples

    # ---- the loop ------------------------------------------------------------------------------------------
    def sample(self, k: int, rng: np.random.Generator, *, stop: Stop | None = None, resume: bool = False) -> np.ndarray:
        """k free, in-bounds configurations (continuous angles wrapped), shape (k, dim); BudgetSpent when `stop`
        ends it first.

        resume: carry on from the previous call (running yield estimates, walkers still under way) instead of
        starting afresh, so drawing a roadmap's samples in batches wastes no work between batches. `stats` always
        covers this call alone.
        """
        k = int(k)
        if k <= 0:
            raise UserError(f"k must be positive, got {k}")
        checker = self.checker
        self.stats = {"attempts": 0, "gave_up": 0, "rounds": 0, "checks": 0}
        if not (resume and self._begun):
            self._begin(rng)
            self._begun = True
        samples, bridges, have = [], [], 0
        start = checker.checks
        while have < k:
            spent = checker.checks - start
            if spent > self.max_checks or self.stats["rounds"] >= self.max_rounds:
                self.stats["checks"] = spent
                raise SamplerBudgetExceeded(
                    f"{self.name}: gave up after {spent} collision checks and {self.stats['rounds']} rounds "
                    f"with {have} of {k} samples (its limits per call: {self.max_checks} checks, "
                    f"{self.max_rounds} rounds; another step may need fewer)",
                    samples=np.concatenate(samples) if samples else np.empty((0, self.space.dim)),
                )
            self.stats["rounds"] += 1
            self._room = self.max_checks - spent
            poll(stop)  # a round may ask nothing (every proposal out of bounds)
            got, ends = self._round(rng, k - have, stop)
            if len(got):
                got = got[: k - have]
                samples.append(got)
                if ends is not None:
                    bridges.append(ends[: len(got)])
                have += len(got)
        self.stats["checks"] = checker.checks - start
        out = np.concatenate(samples)
        self.bridges = np.concatenate(bridges) if bridges else None
        return out

    def _begin(self, rng: np.random.Generator) -> None:
        """Reset per-call state (so the same seed gives the same samples whatever ran before)."""

    def _round(self, rng: np.random.Generator, need: int, stop: Stop | None):
        raise NotImplementedError

    # ---- helpers -------------------------------------------------------------------------------------------
    def _batch_size(self, need: int, rate: float, low: int = 16, high: int = 1024) -> int:
        """Candidates for one round: enough to give `need` samples at the observed yield `rate`, within limits."""
        return max(1, min(int(np.clip(np.ceil(1.25 * need / max(rate, 1e-3)), low, high)), self._room))

    def _offsets(self, rng: np.random.Generator, n: int, length: float, exact: bool) -> np.ndarray:
        """n configuration-space offsets of weighted length `length` (exact) or Gaussian with that rms length."""
        dim = self.space.dim
        if exact:
            w = unit_directions(rng, n, dim) * length
        else:
            w = rng.normal(0.0, length / np.sqrt(dim), size=(n, dim))
        return w / self.space.weights

    def _propose(self, rng: np.random.Generator, Q: np.ndarray, draw, spare: int = 4):
        """Q + draw(rng, n), wrapped; a proposal that leaves the bounds is redrawn, up to `redraws` times.

        After a first try of one candidate per row, each redraw draws `spare` candidates per remaining row in one
        call and keeps the first in bounds (fewer numpy calls than redrawing row by row). Returns the proposals
        and a mask of those in bounds; each row still out of bounds after all redraws counts one gave_up.
        """
        space = self.space
        n, dim = Q.shape
        P = space.wrap(Q + draw(rng, n))  # first try: one candidate per row (most steps stay in bounds)
        ok = space.within_bounds(P) if n else np.zeros(0, bool)
        todo = np.flatnonzero(~ok)
        for _ in range(-(-self.redraws // spare)):
            if not len(todo):
                break
            C = space.wrap(Q[todo, None, :] + draw(rng, len(todo) * spare).reshape(len(todo), spare, dim))
            good = space.within_bounds(C.reshape(-1, dim)).reshape(len(todo), spare)
            found = good.any(axis=1)
            first = good.argmax(axis=1)
            hit = todo[found]
            P[hit] = C[found, first[found]]
            ok[hit] = True
            todo = todo[~found]
        P[todo] = Q[todo]
        self.stats["gave_up"] += len(todo)
        return P, ok

    def _collides(self, Q: np.ndarray, stop: Stop | None) -> np.ndarray:
        """In bounds and in collision (one batched call). Out of bounds is not a collision: no obstacle there."""
        inside = self.space.within_bounds(Q) if len(Q) else np.zeros(0, bool)
        hit = np.zeros(len(Q), bool)
        if inside.any():
            hit[inside] = ~self.checker.are_free(Q[inside], stop)
        return hit
