"""Where a roadmap's samples come from (Samples): uniform samples, and the narrow-passage sources -- placements in
narrow workspace gaps and the narrow-passage samplers -- round by round, in a fixed mix or in one learned while the
query runs (Mixture); a query and a cell roadmap's build draw through it alike."""

from __future__ import annotations

import math

import numpy as np

from app.checking.budget import Stop, poll
from app.errors import SamplerBudgetExceeded, UserError

ADAPTIVE = "adaptive"
"""The mixture's name where a sampler's name goes (PlanSettings.sampler, --sampler): every source below, in shares
learned from what each one's samples achieve per check (Mixture)."""
PLACEMENTS = "workspace"
# The narrow-passage sources the adaptive mixture shares a round's narrow checks among: placements, Boor's Gaussian,
# Hsu's bridge builder, and the Lévy and random-walk bridge samplers. Uniform samples are every round's own share,
# not one of them: in a narrow passage's gap they are as rare as the passage is narrow, yet cheap enough that their
# rewards per check outbid the sources that find the passage (with them among the sources, window needed about twice
# the checks: docs/paper.md).
MIXED = (PLACEMENTS, "gaussian", "rbbs", "lfbs", "rwbs")
# The mixture's floor: this share of a round's narrow checks is spread evenly over the sources, so a source that
# did nothing yet can still show what it does in this query's passage (EXP3's exploration; Hybrid PRM's too).
EXPLORE = 0.1
# A source's prior: PRIOR_CHECKS checks at the rate all sources earned together (itself PRIOR_REWARD in PRIOR_CHECKS
# before any reward), so a source is not written off, or trusted, on its first few samples, and one that earns
# nothing in thousands of checks falls to the floor.
PRIOR_REWARD, PRIOR_CHECKS = 1.0, 100.0
# A narrow round's checks per narrow sample it is sized for (Query.round_sizes): about what the fixed default mix
# spends per narrow sample in the UR3 cells, so the mixture's rounds cost what the default's did.
ROUND_CHECKS = 20
# A source is called once its share of the rounds has saved it this many checks: one call draws at least one batch
# of candidates, and a call per source per round would spend the floor many times over.
MIN_CALL = 32


def check_source_name(name: str) -> str:
    """`name` if it names a sampler (app.samplers.SAMPLERS) or the adaptive mixture; else UserError."""
    from app.samplers import SAMPLERS

    if name != ADAPTIVE and name not in SAMPLERS:
        raise UserError(f"unknown sampler '{name}' (known: {ADAPTIVE}, {', '.join(SAMPLERS)})")
    return name


class Mixture:
    """How a round's narrow-passage checks are shared among the sources, learned from reward per check: a
    cost-sensitive bandit in the manner of Hybrid PRM (Hsu, Sánchez-Ante and Sun, ICRA 2005).

    Each source i has earned R_i rewards for C_i checks (Query._reward says what earns one). Its rate is rho_i =
    (R_i + rho PRIOR_CHECKS) / (C_i + PRIOR_CHECKS), shrunk towards rho, the rate of all sources together, and it is
    allotted the share p_i = (1 - EXPLORE) rho_i / sum rho + EXPLORE / K of the round's checks: probability matching
    on reward per check, with EXP3's uniform floor. Allotted checks accumulate as credit (deficit round robin): a
    source draws, until its credit is spent, once it holds MIN_CALL, and what it overspends is owed to later rounds.
    A source draws no more than its share of the round's samples either: placements in the maze cost about a check
    each, and drawn by checks alone they flooded the roadmap with tens of thousands of nodes that every search then
    paid for. Everything is counted, nothing drawn at random, so the mixture adds no randomness of its own. Why not
    EXP3's exponential weights: a query runs tens of rounds, not thousands, and exponential weights on so few, so
    noisy rewards swing to one source and stay there; a ratio of counts settles as fast as the counts do, and the
    floor keeps every source in the running for at most EXPLORE of the narrow checks. How it compares with the fixed
    mixes: `bench ablation` (docs/paper.md)."""

    def __init__(self, names: tuple[str, ...]):
        self.names = names
        self.rewards = dict.fromkeys(names, 0.0)
        self.checks = dict.fromkeys(names, 0)
        self.samples = dict.fromkeys(names, 0)
        self.credit = dict.fromkeys(names, 0.0)

    def shares(self, on: list[str]) -> np.ndarray:
        """The share of a round's checks per source in `on` (those that can still draw)."""
        pooled = (sum(self.rewards[s] for s in on) + PRIOR_REWARD) / (sum(self.checks[s] for s in on) + PRIOR_CHECKS)
        rate = np.array([(self.rewards[s] + pooled * PRIOR_CHECKS) / (self.checks[s] + PRIOR_CHECKS) for s in on])
        return (1 - EXPLORE) * rate / rate.sum() + EXPLORE / len(on)

    def allot(self, samples: int, checks: float, on: list[str]) -> dict[str, tuple[float, int]]:
        """A round's `checks` and `samples` shared among the sources in `on`: of each that may draw now, its credit
        and the most samples it may draw. Credit saved is capped at two rounds' share (a source held back by its
        samples does not bank a flood for later)."""
        out = {}
        for name, share in zip(on, self.shares(on)):
            add = share * checks
            self.credit[name] = min(self.credit[name] + add, 2 * max(add, MIN_CALL))
            if self.credit[name] >= MIN_CALL:
                out[name] = (self.credit[name], math.ceil(share * samples))
        return out

    def per_sample(self, name: str) -> float:
        """The source's checks per sample so far (1 before its first)."""
        return self.checks[name] / self.samples[name] if self.samples[name] else 1.0

    def spent(self, name: str, samples: int, checks: int) -> None:
        self.samples[name] += samples
        self.checks[name] += checks
        self.credit[name] -= checks

    def reward(self, name: str, amount: float) -> None:
        self.rewards[name] += amount


class Samples:
    """Where a roadmap's samples come from, in rounds: `uniform` uniform samples, and `narrow` narrow-passage ones.

    A named sampler makes a fixed mix: a share `workspace` of the narrow samples are placements in narrow workspace
    gaps (app.samplers.workspace), the rest the sampler's. ADAPTIVE deals them out among the sources in MIXED by a
    Mixture, which the query teaches after each round (`reward`). Each source has its own random stream from
    `seeds` (a spawned SeedSequence list), so one source drawing more does not move another's samples; walkers
    still under way when a round ends go on in the next one. A query and a cell roadmap's build draw through this
    one object."""

    def __init__(self, checker, sampler: str, step: float, seeds, workspace: float, params: dict | None = None):
        from app.samplers import make_sampler

        self.checker, self.step, self.workspace, self.sampler = checker, step, workspace, sampler
        self._rngs = {"uniform": np.random.default_rng(seeds[1]), PLACEMENTS: np.random.default_rng(seeds[3])}
        self._samplers = {"uniform": make_sampler("uniform", checker, step=step)}
        if sampler == ADAPTIVE:
            walkers = [s for s in MIXED if s != PLACEMENTS]
            for name, stream in zip(walkers, seeds[0].spawn(len(walkers))):
                self._rngs[name] = np.random.default_rng(stream)
                self._samplers[name] = make_sampler(name, checker, step=step)
            names = MIXED if workspace > 0 else MIXED[1:]
            self.mixture: Mixture | None = Mixture(names)
            self.stats: dict[str, dict] = {name: {} for name in ("uniform", *self.mixture.names)}
        else:
            self._rngs["narrow"] = np.random.default_rng(seeds[0])
            self._samplers["narrow"] = make_sampler(sampler, checker, step=step, **(params or {}))
            self.mixture = None
            self.stats = {"narrow": {}, "uniform": {}, PLACEMENTS: {}}
        self._workspace_on = workspace > 0  # off once no placement can be made
        self._off: set[str] = set()  # mixed sources that can find no more samples

    def draw(self, narrow: int, uniform: int, stop: Stop | None = None) -> list[tuple[str, str, np.ndarray]]:
        """One round: `narrow` narrow-passage samples and `uniform` uniform ones, as (roadmap kind, source,
        samples) triples, bounded by `stop`. SamplerBudgetExceeded when a named sampler, the uniform one or (in the
        mixture) every narrow source cannot find its samples within its own check cap."""
        from app.planning.roadmap import NARROW, UNIFORM, WORKSPACE

        if self.mixture is None:
            W = self._draw(PLACEMENTS, self._placements(narrow, stop), stop)
            N = self._draw("narrow", narrow - len(W), stop)
            U = self._draw("uniform", uniform, stop)
            return [(WORKSPACE, PLACEMENTS, W), (NARROW, self.sampler, N), (UNIFORM, "uniform", U)]
        out, mixture = [], self.mixture
        if narrow > 0 and PLACEMENTS in mixture.names and PLACEMENTS not in self._off:
            self._placements(narrow, stop)  # finds the gaps the first time
            if not self._workspace_on:
                self._off.add(PLACEMENTS)
        on = [s for s in mixture.names if s not in self._off]
        if narrow > 0 and not on:
            raise SamplerBudgetExceeded("every narrow-passage source gave up")
        allotted = mixture.allot(narrow, narrow * ROUND_CHECKS, on) if narrow > 0 else {}
        for name in mixture.names:
            if name in allotted:  # as many samples as the credit buys at the source's cost so far, within its share
                credit, most = allotted[name]
                count = min(most, max(1, int(credit / mixture.per_sample(name))))
                kind = WORKSPACE if name == PLACEMENTS else NARROW
                out.append((kind, name, self._draw(name, count, stop, credit)))
        return [*out, (UNIFORM, "uniform", self._draw("uniform", uniform, stop))]

    def record(self) -> dict[str, dict]:
        """Each source's counters (its sampler's, summed over the rounds); in the mixture also the samples it drew,
        the rewards they earned and its share of the next round's narrow checks."""
        out = {name: dict(totals) for name, totals in self.stats.items()}
        if self.mixture is not None:
            m = self.mixture
            on = [s for s in m.names if s not in self._off]
            shares = dict(zip(on, m.shares(on).tolist())) if on else {}
            for name in m.names:
                out[name].update(samples=m.samples[name], rewards=m.rewards[name], share=shares.get(name, 0.0))
        return out

    def reward(self, rewards: dict[str, float]) -> None:
        """What each source's samples achieved in the round just searched (app.planning.query), for the mixture."""
        if self.mixture is not None:
            for name, amount in rewards.items():
                if name in self.mixture.rewards:  # (uniform samples are not the mixture's)
                    self.mixture.reward(name, amount)

    def _draw(self, kind: str, count: int, stop: Stop | None, cap: float | None = None) -> np.ndarray:
        """`count` samples of a source; in the mixture, those its `cap` of checks finds (fewer, if it runs out)."""
        drawn = np.empty((0, self.checker.space.dim))
        if count <= 0 or kind not in self._samplers:  # (placements before their gaps are found: none)
            return drawn
        sampler, before = self._samplers[kind], self.checker.checks
        guard = sampler.max_checks
        if cap is not None:
            sampler.max_checks = min(guard, int(cap))
        try:
            drawn = sampler.sample(count, self._rngs[kind], stop=stop, resume=True)
        except SamplerBudgetExceeded as exc:
            # Its share spent (the sampler's own cap, not a give-up): the samples found, and the rest next time.
            if cap is not None and sampler.stats.get("checks", 0) > sampler.max_checks:
                drawn = drawn if exc.samples is None else exc.samples
            elif kind == PLACEMENTS:  # no piece of the robot reaches the gaps found: the other sources take over
                self._workspace_on = False
                self._off.add(kind)
            elif self.mixture is None or kind == "uniform":
                raise
            else:
                self._off.add(kind)
        finally:
            sampler.max_checks = guard
            totals = self.stats[kind]
            for name, value in sampler.stats.items():
                if isinstance(value, (int, float)):
                    totals[name] = totals.get(name, 0) + value
            if self.mixture is not None and kind in self.mixture.checks:
                self.mixture.spent(kind, len(drawn), self.checker.checks - before)
        return drawn

    def _placements(self, narrow: int, stop: Stop | None) -> int:
        """How many of a round's `narrow` samples are placements in workspace gaps (fixed mix). The first time, the
        gaps are searched for (polling the budget) until one is found; a scene with none leaves them all to the
        sampler."""
        from app.samplers.workspace import WorkspaceGaps, WorkspaceSampler

        if narrow <= 0 or not self._workspace_on:
            return 0
        if PLACEMENTS not in self._samplers:
            rng, before = self._rngs[PLACEMENTS], self.checker.checks
            gaps = WorkspaceGaps(self.checker, rng)
            while not len(gaps.points) and not gaps.exhausted:
                poll(stop)
                gaps.search(rng, stop=stop)
            if self.mixture is not None:
                self.mixture.spent(PLACEMENTS, 0, self.checker.checks - before)
            if gaps.exhausted:
                self._workspace_on = False
                return 0
            self._samplers[PLACEMENTS] = WorkspaceSampler(self.checker, gaps, step=self.step)
        return round(self.workspace * narrow) if self.mixture is None else 0
