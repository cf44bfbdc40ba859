"""Judges the paper's claims from the results store: reproduced, partly, not reproduced, or no data — with numbers.

Each claim is a set of comparisons (one per scene or per scene x step); the verdict counts them: all hold ->
reproduced, none -> not reproduced, some -> partly. The rules (`RULES`) and their constants are fixed here and
printed in the report: no tuning toward the paper.

Censoring. A sampling trial that spends its collision-check budget is right-censored, never dropped (dropping them
keeps only the lucky trials of a sampler that often runs out, and so favours it):
- its collision checks are "at least what it spent": checks are compared with the log-rank test, which takes
  right-censored values as such (scipy.stats.logrank), and a median that falls on a censored trial is a lower bound;
- its quality counts the samples it drew before the budget ended: quality is the passage yield, the passage samples
  a trial delivered per K_c requested (the passage fraction when the trial finished, less when it ran out).
Intervals: medians get seeded percentile-bootstrap confidence intervals, success rates exact binomial ones.
"""

from collections import defaultdict
from dataclasses import dataclass, field

import numpy as np

ALPHA = 0.01  # one-sided significance level of every test
CONFIDENCE = 0.95  # of every interval
N_RESAMPLES = 2000  # bootstrap resamples per interval
BOOTSTRAP_SEED = 0  # the same store always gives the same intervals
BRIDGE_WALKERS = ("lfbs", "rwbs")
CHEAP = ("gaussian", "rws", "lfs")
BRIDGES = ("rbbs", "rwbs", "lfbs")
RULES = [
    f"C1: per scene, a bridge walker's passage yield (trials pooled over steps) is stochastically greater than "
    f"RBBS's: one-sided Mann-Whitney U, p < {ALPHA:g}, and its median is not smaller.",
    "C2: per scene, the range of LFBS's per-step mean passage yields is smaller than RBBS's.",
    f"C3: per step in bar, LFBS finishes in fewer collision checks than RBBS: one-sided log-rank test on the checks "
    f"(censored trials right-censored at what they spent), p < {ALPHA:g}, LFBS's median below RBBS's and fewer "
    "than half of LFBS's trials censored.",
    f"C4: per PRM cell, LFBS does not succeed less often than RBBS (one-sided Fisher exact test on the success "
    f"counts, p < {ALPHA:g} fails it) and plans faster (one-sided Mann-Whitney U on the plan times, p < {ALPHA:g}, "
    "and a lower median).",
    "C5: per scene, each cheap sampler's median checks are below every bridge sampler's (fewer than half of its "
    "trials censored) and its mean passage yield is below every bridge sampler's.",
    f"Intervals: {CONFIDENCE:.0%} percentile bootstrap of the median ({N_RESAMPLES} resamples, seed "
    f"{BOOTSTRAP_SEED}); success rates: exact (Clopper-Pearson) binomial interval.",
]


@dataclass
class Verdict:
    claim: str
    text: str
    verdict: str
    evidence: list[str] = field(default_factory=list)


def median_ci(values, seed: int = BOOTSTRAP_SEED) -> tuple[float, float, float]:
    """(median, low, high): the median of the finite `values` and its percentile-bootstrap confidence interval."""
    values = np.asarray(values, float)
    values = values[np.isfinite(values)]
    if len(values) == 0:
        return (float("nan"),) * 3
    median = float(np.median(values))
    if np.all(values == values[0]):  # one value, or all alike: nothing to resample
        return median, median, median
    from scipy.stats import bootstrap  # about a second to import: only when statistics are asked for

    ci = bootstrap(
        (values,),
        np.median,
        confidence_level=CONFIDENCE,
        n_resamples=N_RESAMPLES,
        method="percentile",
        rng=np.random.default_rng(seed),
    ).confidence_interval
    return median, float(ci.low), float(ci.high)


def success_ci(successes: int, trials: int) -> tuple[float, float]:
    """Exact binomial confidence interval of a success rate."""
    from scipy.stats import binomtest

    ci = binomtest(int(successes), int(trials)).proportion_ci(confidence_level=CONFIDENCE, method="exact")
    return float(ci.low), float(ci.high)


def passage_yield(metrics: dict) -> float:
    """Passage samples a sampling trial delivered per K_c requested (censored trials: those drawn in the budget)."""
    k = metrics.get("k", 30)
    drawn = metrics.get("samples_drawn", 0 if metrics.get("censored") else k)
    fraction = metrics.get("passage_fraction")
    return 0.0 if not drawn or fraction is None else float(fraction) * drawn / k


@dataclass
class Cell:
    """One metric over trials, with which trials were censored and whether their values are then lower bounds (checks
    and time are; a passage yield is what the trial delivered)."""

    values: np.ndarray
    censored: np.ndarray
    bounds: bool = True

    @property
    def n(self) -> int:
        return len(self.values)

    @property
    def n_censored(self) -> int:
        return int(self.censored.sum())

    def median(self) -> float:
        return float(np.median(self.values))

    def describe(self, digits: int = 3) -> str:
        """'median [low, high] (n trials, c censored)', ≥ before the median when it falls on a censored trial."""
        med, lo, hi = median_ci(self.values)
        mark = "≥" if self.median_is_bound() else ""
        interval = f"[{lo:.{digits}g}, {hi:.{digits}g}]"
        return f"{mark}{med:.{digits}g} {interval} ({self.n} trials, {self.n_censored} censored)"

    def median_is_bound(self) -> bool:
        """The median is only a lower bound: some censored value is not above it."""
        return bool(self.bounds and self.n_censored and np.any(self.values[self.censored] <= self.median()))


def _cells(rows, experiment, metric) -> dict[tuple, Cell]:
    """{(scene, method, step): Cell} of `metric` over seeds: a metrics key (a censored trial's value is a lower
    bound), or a function of the metrics (`passage_yield`: a censored trial's value is what it delivered)."""
    read = metric if callable(metric) else (lambda m: m.get(metric))
    values, censored = defaultdict(list), defaultdict(list)
    for r in rows:
        if r["experiment"] != experiment:
            continue
        v = read(r["metrics"])
        if v is not None:
            key = (r["scene"], r["method"], r["step"])
            values[key].append(float(v))
            censored[key].append(bool(r["metrics"].get("censored", False)))
    bounds = not callable(metric)
    return {k: Cell(np.array(values[k]), np.array(censored[k], bool), bounds) for k in values}


def _pooled(cells, scene, method) -> Cell:
    parts = [c for (s, m, _), c in cells.items() if s == scene and m == method]
    if not parts:
        return Cell(np.array([]), np.array([], bool))
    return Cell(np.concatenate([c.values for c in parts]), np.concatenate([c.censored for c in parts]), parts[0].bounds)


def _greater(a: Cell, b: Cell) -> tuple[bool, float]:
    """a is stochastically greater than b (one-sided Mann-Whitney) and its median is not smaller."""
    if a.n < 3 or b.n < 3:
        return False, float("nan")
    x, y = a.values, b.values
    if np.all(x == x[0]) and np.all(y == y[0]):
        return bool(x[0] > y[0]), 0.0 if x[0] > y[0] else 1.0
    from scipy.stats import mannwhitneyu

    p = float(mannwhitneyu(x, y, alternative="greater").pvalue)
    return bool(p < ALPHA and a.median() >= b.median()), p


def _fewer(a: Cell, b: Cell) -> tuple[bool, float]:
    """a finishes in less of the metric than b (one-sided log-rank test, censored values right-censored), with a
    smaller median that is not a censored lower bound."""
    if a.n < 3 or b.n < 3:
        return False, float("nan")
    from scipy.stats import CensoredData, logrank

    def data(c: Cell):
        return CensoredData(uncensored=c.values[~c.censored], right=c.values[c.censored])

    if a.n_censored == a.n and b.n_censored == b.n:  # no trial finished: nothing to compare
        return False, float("nan")
    with np.errstate(invalid="ignore", divide="ignore"):  # no variance (e.g. all values alike): p is NaN, no claim
        p = float(logrank(data(a), data(b), alternative="greater").pvalue)  # "greater": a finishes at a higher rate
    return bool(p < ALPHA and a.median() < b.median() and 2 * a.n_censored < a.n), p


def _verdict(outcomes: list[bool]) -> str:
    if not outcomes:
        return "no data"
    if all(outcomes):
        return "reproduced"
    return "partly reproduced" if any(outcomes) else "not reproduced"


def _scenes(cells, methods):
    return sorted({s for (s, m, _) in cells if m in methods})


def _word(holds: bool) -> str:
    return "holds" if holds else "fails"


def claim_c1(rows) -> Verdict:
    cells = _cells(rows, "sampling", passage_yield)
    outcomes, evidence = [], []
    for scene in _scenes(cells, ("rbbs",)):
        rbbs = _pooled(cells, scene, "rbbs")
        for walker in BRIDGE_WALKERS:
            mine = _pooled(cells, scene, walker)
            if mine.n == 0:
                continue
            holds, p = _greater(mine, rbbs)
            outcomes.append(holds)
            evidence.append(
                f"{scene}: passage yield {walker} {mine.describe()} vs rbbs {rbbs.describe()} (p={p:.2g}) -> "
                f"{_word(holds)}"
            )
    return Verdict(
        "C1", "Bridge walkers (LFBS, RWBS) put more samples in the passage than RBBS.", _verdict(outcomes), evidence
    )


def claim_c2(rows) -> Verdict:
    """LFBS's passage yield varies less across steps a than RBBS's (range of per-step means)."""
    cells = _cells(rows, "sampling", passage_yield)
    outcomes, evidence = [], []
    for scene in _scenes(cells, ("rbbs", "lfbs")):
        spread, text = {}, {}
        for method in ("lfbs", "rbbs"):
            steps = sorted((st, c) for (s, m, st), c in cells.items() if s == scene and m == method)
            if len(steps) >= 2:
                means = [c.values.mean() for _, c in steps]
                spread[method] = max(means) - min(means)
                text[method] = ", ".join(
                    f"a={st:g} {c.values.mean():.3f} ({c.n_censored}/{c.n} censored)" for st, c in steps
                )
        if len(spread) < 2:
            continue
        holds = spread["lfbs"] < spread["rbbs"]
        outcomes.append(holds)
        evidence.append(
            f"{scene}: mean passage yield per step, lfbs {text['lfbs']} (range {spread['lfbs']:.3f}); rbbs "
            f"{text['rbbs']} (range {spread['rbbs']:.3f}) -> {_word(holds)}"
        )
    return Verdict(
        "C2", "LFBS sample quality is insensitive to the step a; RBBS's is not.", _verdict(outcomes), evidence
    )


def claim_c3(rows, scene="bar") -> Verdict:
    cells = _cells(rows, "sampling", "collision_checks")
    outcomes, evidence = [], []
    for step in sorted({st for (s, m, st) in cells if s == scene and m == "lfbs"}):
        lfbs, rbbs = cells.get((scene, "lfbs", step)), cells.get((scene, "rbbs", step))
        if lfbs is None or rbbs is None:
            continue
        holds, p = _fewer(lfbs, rbbs)
        outcomes.append(holds)
        evidence.append(
            f"{scene} a={step:g}: checks lfbs {lfbs.describe(4)} vs rbbs {rbbs.describe(4)} (log-rank p={p:.2g}) "
            f"-> {_word(holds)}"
        )
    return Verdict("C3", f"LFBS needs fewer collision calls than RBBS in {scene}.", _verdict(outcomes), evidence)


def _rate(cell: Cell) -> str:
    ok = int(cell.values.sum())
    lo, hi = success_ci(ok, cell.n)
    return f"{ok}/{cell.n} [{lo:.0%}, {hi:.0%}]"


def _less_often(a: Cell, b: Cell) -> float:
    """p of a one-sided Fisher exact test that successes `a` (0/1 values) come less often than successes `b`."""
    from scipy.stats import fisher_exact

    ok_a, ok_b = int(a.values.sum()), int(b.values.sum())
    return float(fisher_exact([[ok_a, a.n - ok_a], [ok_b, b.n - ok_b]], alternative="less").pvalue)


def detectable_drop(runs: int, successes: int) -> int:
    """The most successes out of `runs` that the C4 success test flags as fewer than `successes` out of `runs`:
    what a cell of this many runs can tell apart."""
    from scipy.stats import fisher_exact

    flagged = [
        k
        for k in range(successes + 1)
        if fisher_exact([[k, runs - k], [successes, runs - successes]], alternative="less").pvalue < ALPHA
    ]
    return max(flagged, default=-1)


def claim_c4(rows) -> Verdict:
    success = _cells(rows, "prm", "success")
    seconds = _cells(rows, "prm", "seconds")
    outcomes, evidence = [], []
    for scene, method, step in sorted(k for k in success if k[1] == "lfbs"):
        rbbs_ok, lfbs_ok = success.get((scene, "rbbs", step)), success[(scene, method, step)]
        lfbs_t, rbbs_t = seconds.get((scene, "lfbs", step)), seconds.get((scene, "rbbs", step))
        if rbbs_ok is None or lfbs_t is None or rbbs_t is None:
            continue
        p_success = _less_often(lfbs_ok, rbbs_ok)
        faster, p_time = _greater(rbbs_t, lfbs_t)
        faster = faster and lfbs_t.median() < rbbs_t.median()
        holds = bool(p_success >= ALPHA and faster)
        outcomes.append(holds)
        evidence.append(
            f"{scene} a={step:g}: success lfbs {_rate(lfbs_ok)} vs rbbs {_rate(rbbs_ok)} (Fisher p={p_success:.2g}); "
            f"time s lfbs {lfbs_t.describe()} vs rbbs {rbbs_t.describe()} (Mann-Whitney p={p_time:.2g}) -> "
            f"{_word(holds)}"
        )
    return Verdict(
        "C4",
        "LFBS-PRM is faster and succeeds at least as often as RBBS-PRM (maze, tunnel).",
        _verdict(outcomes),
        evidence,
    )


def claim_c5(rows) -> Verdict:
    checks = _cells(rows, "sampling", "collision_checks")
    quality = _cells(rows, "sampling", passage_yield)
    outcomes, evidence = [], []
    for scene in _scenes(checks, CHEAP):
        bridges = {b: (_pooled(checks, scene, b), _pooled(quality, scene, b)) for b in BRIDGES}
        bridges = {b: cq for b, cq in bridges.items() if cq[0].n}
        for cheap in CHEAP:
            c, q = _pooled(checks, scene, cheap), _pooled(quality, scene, cheap)
            if c.n == 0 or not bridges:
                continue
            cheaper = 2 * c.n_censored < c.n and all(c.median() < bc.median() for bc, _ in bridges.values())
            poorer = all(q.values.mean() < bq.values.mean() for _, bq in bridges.values())
            outcomes.append(cheaper and poorer)
            best = max(bridges, key=lambda b: bridges[b][1].values.mean())
            least = min(bridges, key=lambda b: bridges[b][0].median())
            evidence.append(
                f"{scene}: {cheap} checks {c.describe(4)} (cheapest bridge {least} {bridges[least][0].describe(4)}), "
                f"mean passage yield {q.values.mean():.3f} (best bridge {best} {bridges[best][1].values.mean():.3f}) "
                f"-> {_word(cheaper and poorer)}"
            )
    return Verdict(
        "C5",
        "Gaussian, RWS and LFS are cheap but poor: fewer checks, fewer passage samples than the bridge samplers.",
        _verdict(outcomes),
        evidence,
    )


def judge(rows) -> list[Verdict]:
    return [claim_c1(rows), claim_c2(rows), claim_c3(rows), claim_c4(rows), claim_c5(rows)]
