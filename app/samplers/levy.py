"""Lévy-stable draws by Mantegna's algorithm (R. N. Mantegna, Phys. Rev. E 49, 4677, 1994), and a tail-index estimate.

Mantegna's draw is X = U / |V|^(1/alpha) with V ~ N(0, 1) and U ~ N(0, sigma_u^2), where

    sigma_u = [ Gamma(1 + alpha) sin(pi alpha / 2) / (Gamma((1 + alpha) / 2) alpha 2^((alpha - 1) / 2)) ]^(1/alpha).

`alpha` is the stability index of the symmetric Lévy-stable law, 0 < alpha <= 2: the tail is P(|X| > x) ~ x^-alpha
(density ~ x^-(1 + alpha)), so alpha is exactly what a Hill estimator of the tail index returns. The paper writes
the density as x^-alpha; we take its alpha = 1.9 / 1.1 to be the stability index, the convention of Mantegna and of
the Lévy-flight literature it cites (Yang's Cuckoo search, Lévy PSO). Mantegna's further nonlinear correction (his
K(alpha) and the averaging of n draws) only reshapes the body of the distribution and is left out, as the
Cuckoo-search code does.
"""

from __future__ import annotations

import functools
import math

import numpy as np

_TINY = float(np.finfo(float).tiny)


@functools.cache
def mantegna_sigma(alpha: float) -> float:
    """sigma_u of Mantegna's numerator, so that X has unit scale."""
    if not 0 < alpha <= 2:
        raise ValueError(f"stability index alpha must be in (0, 2], got {alpha}")
    num = math.gamma(1 + alpha) * math.sin(math.pi * alpha / 2)
    den = math.gamma((1 + alpha) / 2) * alpha * 2 ** ((alpha - 1) / 2)
    return (num / den) ** (1 / alpha)


def levy_stable(rng: np.random.Generator, alpha: float, size) -> np.ndarray:
    """Symmetric heavy-tailed draws with tail index alpha (Mantegna's algorithm), unit scale."""
    return mantegna(rng.standard_normal(size), rng.standard_normal(size), alpha)


def mantegna(u: np.ndarray, v: np.ndarray, alpha: float) -> np.ndarray:
    """Mantegna's draw from standard normals u, v (same shape): sigma_u u / |v|^(1/alpha).

    Lets a caller take all its normals from one generator call (the walkers do, to keep a step cheap)."""
    # V == 0 has probability zero in theory; a float can still produce it, and 0 ** negative is inf.
    v = np.where(v == 0.0, _TINY, v)
    return mantegna_sigma(alpha) * u / np.abs(v) ** (1.0 / alpha)


def hill_tail_index(x: np.ndarray, tail_fraction: float = 0.01) -> float:
    """Hill's estimate of the tail index of |x| from its largest `tail_fraction` of values."""
    a = np.sort(np.abs(np.asarray(x, float).ravel()))[::-1]
    k = max(2, int(len(a) * tail_fraction))
    logs = np.log(a[: k + 1])
    return float(1.0 / np.mean(logs[:k] - logs[k]))
