"""Randomised bridge builder, RBBS (D. Hsu, T. Jiang, J. Reif, Z. Sun, ICRA 2003): two colliding endpoints a bridge
length `a` apart (weighted metric, uniform direction) whose midpoint is free."""

from __future__ import annotations

import numpy as np

from app.samplers.base import Sampler


class BridgeSampler(Sampler):
    name = "rbbs"

    def _begin(self, rng):
        self._rate = 0.01

    def _round(self, rng, need, stop):
        space = self.space
        n = self._batch_size(need, self._rate, low=64, high=1024)
        self.stats["attempts"] += n
        A = space.uniform(rng, n)
        A = A[self._collides(A, stop)]
        B, ok = self._propose(rng, A, lambda r, m: self._offsets(r, m, self.step, exact=True))
        A, B = A[ok], B[ok]
        hit = self._collides(B, stop)
        A, B = A[hit], B[hit]
        M = space.wrap(A + 0.5 * space.difference(A, B))
        free = self.checker.are_free(M, stop)
        self._rate = max(free.sum() / n, 0.002)
        return M[free], np.stack([A[free], B[free]], axis=1)
