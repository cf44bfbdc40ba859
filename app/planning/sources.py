"""Where a roadmap's samples come from (Samples): the narrow-passage sampler, placements in narrow workspace gaps,
and uniform samples, round by round; a query and a cell roadmap's build draw through it alike."""

from __future__ import annotations

import numpy as np

from app.checking.budget import Stop, poll
from app.errors import SamplerBudgetExceeded


class Samples:
    """Where a roadmap's samples come from, in rounds: placements in narrow workspace gaps (a share `workspace` of
    each round's narrow-passage samples, app.samplers.workspace), the narrow-passage sampler's walks, and uniform
    samples. Each source has its own random stream from `seeds` (a spawned SeedSequence list), so one source drawing
    more does not move another's samples; walkers still under way when a round ends go on in the next one. A query
    and a cell roadmap's build draw through this one object."""

    def __init__(self, checker, sampler: str, step: float, seeds, workspace: float, params: dict | None = None):
        from app.samplers import make_sampler

        self.checker, self.step, self.workspace = checker, step, workspace
        self._rngs = {
            "narrow": np.random.default_rng(seeds[0]),
            "uniform": np.random.default_rng(seeds[1]),
            "workspace": np.random.default_rng(seeds[3]),
        }
        self._samplers = {
            "narrow": make_sampler(sampler, checker, step=step, **(params or {})),
            "uniform": make_sampler("uniform", checker, step=step),
        }
        self.stats = {"narrow": {}, "uniform": {}, "workspace": {}}
        self._workspace_on = workspace > 0  # off once no placement can be made

    def draw(self, narrow: int, uniform: int, stop: Stop | None = None) -> list[tuple[str, np.ndarray]]:
        """One round: `narrow` narrow-passage samples (placements first, then walks) and `uniform` uniform ones, as
        (roadmap kind, samples) pairs, bounded by `stop`. SamplerBudgetExceeded when the narrow or uniform sampler
        cannot find its samples within its own check cap."""
        from app.planning.roadmap import NARROW, UNIFORM, WORKSPACE

        W = self._draw("workspace", self._placements(narrow, stop), stop)
        N = self._draw("narrow", narrow - len(W), stop)
        return [(WORKSPACE, W), (NARROW, N), (UNIFORM, self._draw("uniform", uniform, stop))]

    def _draw(self, kind: str, count: int, stop: Stop | None) -> np.ndarray:
        if count <= 0:
            return np.empty((0, self.checker.space.dim))
        sampler = self._samplers[kind]
        try:
            return sampler.sample(count, self._rngs[kind], stop=stop, resume=True)
        except SamplerBudgetExceeded:
            if kind != "workspace":
                raise
            self._workspace_on = False  # no piece of the robot reaches the gaps found: the sampler takes over
            return np.empty((0, self.checker.space.dim))
        finally:
            totals = self.stats[kind]
            for name, value in sampler.stats.items():
                if isinstance(value, (int, float)):
                    totals[name] = totals.get(name, 0) + value

    def _placements(self, narrow: int, stop: Stop | None) -> int:
        """How many of a round's `narrow` samples are placements in workspace gaps. The first time, the gaps are
        searched for (polling the budget) until one is found; a scene with none leaves them all to the sampler."""
        from app.samplers.workspace import WorkspaceGaps, WorkspaceSampler

        if narrow <= 0 or not self._workspace_on:
            return 0
        if "workspace" not in self._samplers:
            rng = self._rngs["workspace"]
            gaps = WorkspaceGaps(self.checker, rng)
            while not len(gaps.points) and not gaps.exhausted:
                poll(stop)
                gaps.search(rng, stop=stop)
            if gaps.exhausted:
                self._workspace_on = False
                return 0
            self._samplers["workspace"] = WorkspaceSampler(self.checker, gaps, step=self.step)
        return round(self.workspace * narrow)
