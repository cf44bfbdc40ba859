"""The seven samplers, registered by name: the CLI, the benchmarks and the planner share this one table.

Every sampler talks only to a Checker (app.checking.protocol: a query's QueryContext).
`make_sampler(name, checker, step=..., **params)` builds one; `sampler.sample(k, rng, stop=...)` returns k free
configurations and leaves its statistics in `sampler.stats`.
"""

from __future__ import annotations

from functools import partial

from app.errors import UserError
from app.samplers.base import Sampler
from app.samplers.bridge import BridgeSampler
from app.samplers.uniform import GaussianSampler, UniformSampler
from app.samplers.walk import Walker

SAMPLERS = {
    "uniform": UniformSampler,
    "gaussian": GaussianSampler,
    "rbbs": BridgeSampler,
    "rws": partial(Walker, step_law="gaussian", bridge=False, name="rws"),
    "lfs": partial(Walker, step_law="levy", bridge=False, name="lfs"),
    "rwbs": partial(Walker, step_law="gaussian", bridge=True, name="rwbs"),
    "lfbs": partial(Walker, step_law="levy", bridge=True, name="lfbs"),
}
"""The seven samplers by name, each called as `SAMPLERS[name](checker, step=...)` (see `make_sampler`): uniform,
gaussian, Hsu's bridge builder (rbbs), and random (Gaussian steps) and Lévy-flight walks without and with the bridge
test (rws, lfs, rwbs, lfbs)."""


def check_name(name: str) -> str:
    """`name` if a sampler is registered under it; else UserError listing the known names."""
    if name not in SAMPLERS:
        raise UserError(f"unknown sampler '{name}' (known: {', '.join(SAMPLERS)})")
    return name


def make_sampler(name: str, checker, **params) -> Sampler:
    """The sampler registered as `name`, built on `checker` with `params` (e.g. step=10)."""
    factory = SAMPLERS[check_name(name)]
    try:
        return factory(checker, **params)
    except TypeError as exc:  # an unknown or misspelt parameter
        raise UserError(f"sampler '{name}': {exc}") from None


__all__ = ["SAMPLERS", "Sampler", "check_name", "make_sampler"]
