"""Uniform sampling, and Boor's Gaussian sampler (V. Boor, M. Overmars, A. van der Stappen, ICRA 1999)."""

from __future__ import annotations

import numpy as np

from app.errors import UserError
from app.samplers.base import Sampler


class UniformSampler(Sampler):
    """Free configurations uniform in the bounds: draw a batch, keep the free ones. `step` is ignored. `batch`:
    candidates per round, fixed (default None: sized from the free fraction seen so far)."""

    name = "uniform"

    def __init__(self, checker, step: float = 10.0, batch: int | None = None, **kw):
        super().__init__(checker, step=step, **kw)
        if batch is not None and (isinstance(batch, bool) or not isinstance(batch, (int, np.integer)) or batch < 1):
            raise UserError(f"batch must be a whole number of at least 1, got {batch!r}")
        self.batch = None if batch is None else int(batch)

    def _begin(self, rng):
        self._rate = 0.5  # running estimate of the free fraction, to size batches

    def _round(self, rng, need, stop):
        n = self.batch or self._batch_size(need, self._rate)
        Q = self.space.uniform(rng, n)
        free = self.checker.are_free(Q, stop)
        self.stats["attempts"] += n
        self._rate = max(free.mean(), 0.01) if n else self._rate
        return Q[free], None


class GaussianSampler(Sampler):
    """q1 uniform, q2 ~ N(q1, sigma) (weighted rms distance sigma, default the step); keep the free one when exactly
    one of the two is free. Both of a batch's configurations go to the checker in one call."""

    name = "gaussian"

    def __init__(self, checker, step: float = 10.0, sigma: float | None = None, **kw):
        super().__init__(checker, step=step, **kw)
        self.sigma = float(sigma) if sigma is not None else self.step

    def _begin(self, rng):
        self._rate = 0.05

    def _round(self, rng, need, stop):
        n = self._batch_size(need, self._rate, low=32, high=512)
        Q1 = self.space.uniform(rng, n)
        Q2, ok = self._propose(rng, Q1, lambda r, m: self._offsets(r, m, self.sigma, exact=False))
        Q1, Q2 = Q1[ok], Q2[ok]  # a pair whose second point left the bounds is dropped (bounds are no obstacle)
        free = self.checker.are_free(np.concatenate([Q1, Q2]), stop)
        f1, f2 = free[: len(Q1)], free[len(Q1) :]
        self.stats["attempts"] += n
        keep = f1 != f2
        self._rate = max(keep.mean() if len(keep) else 0.0, 0.005)
        return np.where(f1[:, None], Q1, Q2)[keep], None
