"""Judges the paper's claims from the results store: reproduced, partly, not reproduced, reversed, or no data — with
numbers.

Each claim is a set of comparisons (one per scene or per scene x step), each of which holds, fails, or is reversed
(significant the other way, by the same kind of test); the verdict counts them: all hold -> reproduced, all reversed
-> reversed, none holds -> not reproduced (saying how many are reversed), some -> partly. What a verdict leaves out
(cells the check budget decided, scenes no sampler reaches, PRM runs the sampler's own cap ended) is listed with it.
The rules (`RULES`) and their constants are fixed here and printed in the report: no tuning toward the paper.

Censoring. A sampling trial that spends its collision-check budget is right-censored, never dropped (dropping them
keeps only the lucky trials of a sampler that often runs out, and so favours it):
- its collision checks are "at least what it spent": checks are compared with the log-rank test, which takes
  right-censored values as such (scipy.stats.logrank), and a median that falls on a censored trial is a lower bound;
- its quality counts the samples it drew before the budget ended: quality is the passage yield, the passage samples
  a trial delivered per K_c requested (the passage fraction when the trial finished, less when it ran out).
A PRM run whose sampler spent its own per-call cap (`Sampler.max_checks`, SAMPLER_CAP) built no roadmap: it is
censored too, and left out of C4 with its count.
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


def p_text(p: float) -> str:
    """'p=0.0032' as the report writes a p value (two significant digits); below what a double holds, a bound."""
    return "p < 1e-300" if p < 1e-300 else f"p={p:.2g}"


def _sampler_cap() -> int:
    """The collision checks one `Sampler.sample` call may spend before it gives up (its constructor's default)."""
    import inspect

    from app.samplers.base import Sampler

    return int(inspect.signature(Sampler.__init__).parameters["max_checks"].default)


SAMPLER_CAP = _sampler_cap()
# A sampling cell (scene x sampler x step) with at least this share of its trials censored measures the check budget,
# not the sampler: C2 leaves its step out of that scene's comparison for both samplers.
CENSORED_SHARE = 0.5
# A scene where every compared sampler averages fewer passage samples per K_c than this (1.5 of 30) shows whether
# the passage is reached at all, not how well: C1 and C2 leave it out.
FLOOR_YIELD = 0.05
RULES = [
    f"C1: per scene, a bridge walker's passage yield (trials pooled over steps) is stochastically greater than "
    f"RBBS's: one-sided Mann-Whitney U, p < {ALPHA:g}, and its median is not smaller. Reversed: RBBS's is greater "
    f"by the same test. Scenes where every compared sampler's mean yield is below {FLOOR_YIELD:g} are left out.",
    f"C2: per scene, LFBS's relative spread of passage yield across steps (range of the per-step means over their "
    f"mean) is smaller than RBBS's: the {1 - 2 * ALPHA:.0%} stratified bootstrap interval of the difference (LFBS "
    f"minus RBBS, trials resampled within each step) lies below 0 (holds) or above 0 (reversed); bootstrap p is "
    f"the share of resamples on the other side. Steps where either sampler had at least {CENSORED_SHARE:.0%} of its "
    f"trials censored are left out (the budget, not the sampler, set those cells), as are scenes at the floor "
    f"(C1). The absolute spread and a Kruskal-Wallis test of each sampler's yield across steps are reported beside.",
    f"C3: per step in bar, LFBS finishes in fewer collision checks than RBBS: one-sided log-rank test on the checks "
    f"(censored trials right-censored at what they spent), p < {ALPHA:g}, LFBS's median below RBBS's and fewer "
    "than half of LFBS's trials censored.",
    f"C4: per PRM cell, LFBS does not succeed less often than RBBS (one-sided Fisher exact test on the success "
    f"counts, p < {ALPHA:g} reverses it) and plans faster (one-sided Mann-Whitney U on the plan times, p < "
    f"{ALPHA:g}, and a lower median; slower by the same test reverses it). Runs whose sampler gave up at its own "
    f"cap of {SAMPLER_CAP:,} checks per call and built no roadmap are censored: left out, with their count; a "
    "cell with no other run on one side is left out.",
    "C5: per scene, each cheap sampler's median checks are below every bridge sampler's (fewer than half of its "
    "trials censored) and its mean passage yield is below every bridge sampler's.",
    f"Verdicts: every comparison holds -> reproduced; every one reversed -> reversed; none holds -> not reproduced "
    f"(with how many are reversed); some -> partly. Intervals: {CONFIDENCE:.0%} percentile bootstrap of the median "
    f"({N_RESAMPLES} resamples, seed {BOOTSTRAP_SEED}); success rates: exact (Clopper-Pearson) binomial interval.",
]


@dataclass
class Verdict:
    claim: str
    text: str
    verdict: str
    evidence: list[str] = field(default_factory=list)
    reversals: list[str] = field(default_factory=list)  # each comparison that came out the other way, with its test
    excluded: list[str] = field(default_factory=list)  # what was left out of the verdict, and why


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


def _verdict(outcomes: list) -> str:
    """Outcomes are True/"holds", False/"fails" or "reversed" (the comparison came out significantly the other way)."""
    words = ["holds" if o is True else "fails" if o is False else o for o in outcomes]
    if not words:
        return "no data"
    if all(w == "holds" for w in words):
        return "reproduced"
    if all(w == "reversed" for w in words):
        return "reversed"
    turned = sum(w == "reversed" for w in words)
    also = f"; reversed in {turned} of {len(words)}" if turned else ""
    if any(w == "holds" for w in words):
        return f"partly reproduced{also}"
    return f"not reproduced{also}"


def _scenes(cells, methods):
    return sorted({s for (s, m, _) in cells if m in methods})


def _word(holds: bool) -> str:
    return "holds" if holds else "fails"


def at_floor(cells, scene, methods) -> bool:
    """Every one of `methods` averages a passage yield below FLOOR_YIELD in `scene` (pooled over steps)."""
    means = [_pooled(cells, scene, m).values.mean() for m in methods if _pooled(cells, scene, m).n]
    return bool(means) and max(means) < FLOOR_YIELD


def claim_c1(rows) -> Verdict:
    cells = _cells(rows, "sampling", passage_yield)
    outcomes, evidence, reversals, excluded = [], [], [], []
    for scene in _scenes(cells, ("rbbs",)):
        rbbs = _pooled(cells, scene, "rbbs")
        for walker in BRIDGE_WALKERS:
            mine = _pooled(cells, scene, walker)
            if mine.n == 0:
                continue
            if at_floor(cells, scene, (walker, "rbbs")):
                evidence.append(
                    f"{scene}: left out, at the floor: mean passage yield {walker} {mine.values.mean():.3f}, rbbs "
                    f"{rbbs.values.mean():.3f} (both below {FLOOR_YIELD:g})"
                )
                excluded.append(f"{scene} {walker}: at the floor (mean passage yields below {FLOOR_YIELD:g})")
                continue
            holds, p = _greater(mine, rbbs)
            turned, p_back = _greater(rbbs, mine)
            outcome = "holds" if holds else "reversed" if turned else "fails"
            outcomes.append(outcome)
            back = f"; reversed: rbbs greater, one-sided Mann-Whitney {p_text(p_back)}" if turned else ""
            if turned:
                reversals.append(f"{scene} {walker}: rbbs greater, one-sided Mann-Whitney {p_text(p_back)}")
            evidence.append(
                f"{scene}: passage yield {walker} {mine.describe()} vs rbbs {rbbs.describe()} ({p_text(p)}{back}) -> "
                f"{outcome}"
            )
    return Verdict(
        "C1",
        "Bridge walkers (LFBS, RWBS) put more samples in the passage than RBBS.",
        _verdict(outcomes),
        evidence,
        reversals,
        excluded,
    )


def budget_steps(cells, scene, methods) -> dict[float, str]:
    """Steps of `scene` where one of `methods` had at least CENSORED_SHARE of its trials censored: step -> why."""
    out = {}
    for (s, m, step), c in cells.items():
        if s == scene and m in methods and c.n and c.n_censored >= CENSORED_SHARE * c.n:
            out[step] = out.get(step, "") + ("; " if step in out else "") + f"{m} {c.n_censored}/{c.n} censored"
    return out


def relative_spread(means: np.ndarray, axis: int = 0) -> np.ndarray:
    """(max - min) / mean of per-step means along `axis`: how much a sampler's quality moves with the step, as a
    share of its level (a sampler at twice the yield moving by twice as much is as sensitive)."""
    means = np.asarray(means, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        return (means.max(axis=axis) - means.min(axis=axis)) / means.mean(axis=axis)


def spread_difference(lfbs: list[np.ndarray], rbbs: list[np.ndarray], seed: int = BOOTSTRAP_SEED) -> dict:
    """LFBS's relative spread minus RBBS's over the same steps (one array of yields per step each), with its
    (1 - 2 ALPHA) stratified percentile-bootstrap interval (trials resampled within each step) and the one-sided
    bootstrap p for each direction; the absolute spreads' difference likewise."""
    from scipy.stats import bootstrap

    n = len(lfbs)

    def stat(*samples, axis=-1):
        means = np.stack([np.mean(x, axis=axis) for x in samples])
        return np.stack(
            [
                relative_spread(means[:n]) - relative_spread(means[n:]),
                np.ptp(means[:n], axis=0) - np.ptp(means[n:], axis=0),
            ]
        )

    res = bootstrap(
        tuple(lfbs) + tuple(rbbs),
        stat,
        confidence_level=1 - 2 * ALPHA,
        n_resamples=N_RESAMPLES,
        method="percentile",
        vectorized=True,
        rng=np.random.default_rng(seed),
    )
    point = stat(*(np.asarray(x)[None, :] for x in (*lfbs, *rbbs)), axis=-1)[:, 0]
    dist = res.bootstrap_distribution
    out = {}
    for i, name in enumerate(("relative", "absolute")):
        d = dist[i]
        out[name] = {
            "difference": float(point[i]),
            "low": float(res.confidence_interval.low[i]),
            "high": float(res.confidence_interval.high[i]),
            "p_smaller": float((np.sum(d >= 0) + 1) / (len(d) + 1)),  # LFBS's spread smaller
            "p_larger": float((np.sum(d <= 0) + 1) / (len(d) + 1)),  # LFBS's spread larger (the claim reversed)
        }
    return out


def claim_c2(rows) -> Verdict:
    """LFBS's passage yield varies less across steps a than RBBS's, relative to its level (`spread_difference`), on
    the steps where neither sampler's cell is mostly censored."""
    from scipy.stats import kruskal

    cells = _cells(rows, "sampling", passage_yield)
    outcomes, evidence, reversals, excluded = [], [], [], []
    methods = ("lfbs", "rbbs")
    for scene in _scenes(cells, methods):
        if any(_pooled(cells, scene, m).n == 0 for m in methods):
            continue
        if at_floor(cells, scene, methods):
            evidence.append(
                f"{scene}: left out, at the floor: mean passage yield "
                + ", ".join(f"{m} {_pooled(cells, scene, m).values.mean():.3f}" for m in methods)
                + f" (both below {FLOOR_YIELD:g})"
            )
            excluded.append(f"{scene}: at the floor (mean passage yields below {FLOOR_YIELD:g})")
            continue
        dropped = budget_steps(cells, scene, methods)
        excluded += [f"{scene} a={st:g}: budget artefact ({why})" for st, why in sorted(dropped.items())]
        steps = sorted(
            st
            for (s, m, st) in cells
            if s == scene and m == "lfbs" and (scene, "rbbs", st) in cells and st not in dropped
        )
        gone = "; ".join(f"a={st:g} ({why})" for st, why in sorted(dropped.items()))
        if len(steps) < 2:
            evidence.append(
                f"{scene}: left out, fewer than two steps measured by both{' after ' + gone if gone else ''}"
            )
            continue
        lfbs = [cells[(scene, "lfbs", st)].values for st in steps]
        rbbs = [cells[(scene, "rbbs", st)].values for st in steps]
        d = spread_difference(lfbs, rbbs)
        rel, ab = d["relative"], d["absolute"]
        outcome = "holds" if rel["high"] < 0 else "reversed" if rel["low"] > 0 else "fails"
        outcomes.append(outcome)
        means = {m: [v.mean() for v in vals] for m, vals in (("lfbs", lfbs), ("rbbs", rbbs))}
        kw = {
            m: kruskal(*vals).pvalue if len(vals) > 1 else float("nan") for m, vals in (("lfbs", lfbs), ("rbbs", rbbs))
        }
        per_step = "; ".join(
            f"{m} "
            + ", ".join(f"a={st:g} {v:.3f}" for st, v in zip(steps, means[m]))
            + f" (relative spread {relative_spread(means[m]):.2f}, Kruskal-Wallis across a {p_text(kw[m])})"
            for m in methods
        )
        p = rel["p_smaller"] if outcome != "reversed" else rel["p_larger"]
        if outcome == "reversed":
            reversals.append(
                f"{scene}: lfbs's relative spread larger by {rel['difference']:+.2f} [{rel['low']:+.2f}, "
                f"{rel['high']:+.2f}], bootstrap p={p:.2g}"
            )
        evidence.append(
            f"{scene}: mean passage yield per step, {per_step}. Relative spread lfbs - rbbs "
            f"{rel['difference']:+.2f} [{rel['low']:+.2f}, {rel['high']:+.2f}] (bootstrap p={p:.2g}); absolute "
            f"{ab['difference']:+.3f} [{ab['low']:+.3f}, {ab['high']:+.3f}]"
            + (f". Steps left out (budget): {gone}" if gone else "")
            + f" -> {outcome}"
        )
    return Verdict(
        "C2",
        "LFBS sample quality is insensitive to the step a; RBBS's is not.",
        _verdict(outcomes),
        evidence,
        reversals,
        excluded,
    )


def claim_c3(rows, scene="bar") -> Verdict:
    cells = _cells(rows, "sampling", "collision_checks")
    outcomes, evidence, reversals = [], [], []
    for step in sorted({st for (s, m, st) in cells if s == scene and m == "lfbs"}):
        lfbs, rbbs = cells.get((scene, "lfbs", step)), cells.get((scene, "rbbs", step))
        if lfbs is None or rbbs is None:
            continue
        holds, p = _fewer(lfbs, rbbs)
        turned, p_back = _fewer(rbbs, lfbs)
        outcome = "holds" if holds else "reversed" if turned else "fails"
        outcomes.append(outcome)
        if turned:
            reversals.append(f"{scene} a={step:g}: rbbs finishes in fewer checks, log-rank {p_text(p_back)}")
        evidence.append(
            f"{scene} a={step:g}: checks lfbs {lfbs.describe(4)} vs rbbs {rbbs.describe(4)} (log-rank {p_text(p)}) "
            f"-> {outcome}"
        )
    return Verdict(
        "C3", f"LFBS needs fewer collision calls than RBBS in {scene}.", _verdict(outcomes), evidence, reversals
    )


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


def sampler_gave_up(metrics: dict) -> bool:
    """A PRM run whose narrow-passage sampler spent its own check cap (SAMPLER_CAP) and built no roadmap: only start
    and goal were ever nodes. Such a run measures the cap, not the planner."""
    nodes = metrics.get("nodes")
    return not metrics.get("success") and nodes is not None and nodes <= 2


def claim_c4(rows) -> Verdict:
    kept = [r for r in rows if not (r["experiment"] == "prm" and sampler_gave_up(r["metrics"]))]
    gave_up = defaultdict(int)
    for r in rows:
        if r["experiment"] == "prm" and sampler_gave_up(r["metrics"]):
            gave_up[(r["scene"], r["method"], r["step"])] += 1
    success = _cells(kept, "prm", "success")
    seconds = _cells(kept, "prm", "seconds")
    outcomes, evidence, reversals, excluded = [], [], [], []
    cells = sorted({(s, st) for (s, m, st) in list(success) + list(gave_up)})
    for scene, step in cells:
        capped = {m: gave_up[(scene, m, step)] for m in ("lfbs", "rbbs")}
        note = ", ".join(f"{m} {n}" for m, n in capped.items() if n)
        note = f"; censored by the sampler's {SAMPLER_CAP:,}-check cap, no roadmap: {note}" if note else ""
        rbbs_ok, lfbs_ok = success.get((scene, "rbbs", step)), success.get((scene, "lfbs", step))
        lfbs_t, rbbs_t = seconds.get((scene, "lfbs", step)), seconds.get((scene, "rbbs", step))
        if rbbs_ok is None or lfbs_ok is None or lfbs_t is None or rbbs_t is None:
            if note:
                evidence.append(f"{scene} a={step:g}: left out{note}, no other run on that side")
                excluded.append(
                    f"{scene} a={step:g}: " + ", ".join(f"{m} {n}" for m, n in capped.items() if n) + " runs censored "
                    f"by the sampler's {SAMPLER_CAP:,}-check cap (no roadmap)"
                )
            continue
        excluded += [
            f"{scene} a={step:g}: {n} {m} runs censored by the sampler's {SAMPLER_CAP:,}-check cap (no roadmap)"
            for m, n in capped.items()
            if n
        ]
        p_success = _less_often(lfbs_ok, rbbs_ok)
        faster, p_time = _greater(rbbs_t, lfbs_t)
        slower, p_slow = _greater(lfbs_t, rbbs_t)
        faster = faster and lfbs_t.median() < rbbs_t.median()
        if p_success < ALPHA or slower:
            outcome = "reversed"
        else:
            outcome = "holds" if faster else "fails"
        outcomes.append(outcome)
        why = []
        if p_success < ALPHA:
            reversals.append(f"{scene} a={step:g}: lfbs succeeds less often, one-sided Fisher p={p_success:.2g}")
        if slower:
            reversals.append(f"{scene} a={step:g}: lfbs slower, one-sided Mann-Whitney {p_text(p_slow)}")
        if p_success < ALPHA:
            why.append(f"reversed: lfbs succeeds less often, one-sided Fisher p={p_success:.2g}")
        if slower:
            why.append(f"reversed: lfbs slower, one-sided Mann-Whitney {p_text(p_slow)}")
        evidence.append(
            f"{scene} a={step:g}: success lfbs {_rate(lfbs_ok)} vs rbbs {_rate(rbbs_ok)} (Fisher p={p_success:.2g}); "
            f"time s lfbs {lfbs_t.describe()} vs rbbs {rbbs_t.describe()} (Mann-Whitney {p_text(p_time)}){note}"
            + (f" ({'; '.join(why)})" if why else "")
            + f" -> {outcome}"
        )
    return Verdict(
        "C4",
        "LFBS-PRM is faster and succeeds at least as often as RBBS-PRM (maze, tunnel).",
        _verdict(outcomes),
        evidence,
        reversals,
        excluded,
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


def passage_samples(metrics: dict) -> float:
    """Samples a sampling trial delivered in the passage (a censored trial: of those it drew within its budget)."""
    return passage_yield(metrics) * metrics.get("k", 30)


def checks_per_passage_sample(rows) -> dict[tuple, dict]:
    """{(scene, sampler, step): ratio} of the collision checks a cell's trials spent over the passage samples they
    delivered (censored trials count what they spent and what they drew), with the 95 % percentile-bootstrap
    interval of that ratio (trials resampled, checks and samples together). A cell with no passage sample has an
    infinite ratio."""
    from scipy.stats import bootstrap

    checks, found = defaultdict(list), defaultdict(list)
    for r in rows:
        if r["experiment"] == "sampling":
            key = (r["scene"], r["method"], r["step"])
            checks[key].append(float(r["metrics"]["collision_checks"]))
            found[key].append(passage_samples(r["metrics"]))

    def ratio(c, p, axis=-1):
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.sum(c, axis=axis) / np.sum(p, axis=axis)

    out = {}
    for key in checks:
        c, p = np.array(checks[key]), np.array(found[key])
        point = float(ratio(c, p))
        low = high = point
        if np.isfinite(point) and len(c) > 1:
            with np.errstate(invalid="ignore"):  # resamples with no passage sample: infinite ratios
                ci = bootstrap(
                    (c, p),
                    ratio,
                    paired=True,
                    vectorized=True,
                    confidence_level=CONFIDENCE,
                    n_resamples=N_RESAMPLES,
                    method="percentile",
                    rng=np.random.default_rng(BOOTSTRAP_SEED),
                ).confidence_interval
            # All resamples alike: no interval to speak of. A resample with no passage sample: an infinite bound.
            low = point if np.isnan(ci.low) else float(ci.low)
            high = (point if np.isnan(ci.low) else np.inf) if np.isnan(ci.high) else float(ci.high)
        out[key] = {"ratio": point, "low": low, "high": high, "passage": float(p.sum()), "trials": len(c)}
    return out


def trend(x, y) -> dict:
    """How y moves with x: Spearman's rank correlation, its two-sided p, and a word (rises / falls when p < ALPHA,
    else flat). For a handful of published values with no spread to test, the word comes from rho alone (|rho| >=
    0.5)."""
    from scipy.stats import spearmanr

    x, y = np.asarray(x, float), np.asarray(y, float)
    if np.ptp(x) == 0 or np.ptp(y) == 0:  # nothing moves: no correlation to compute
        return {"rho": 0.0, "p": 1.0, "word": "flat", "n": len(x)}
    rho, p = spearmanr(x, y)
    rho, p = float(rho), float(p)
    if len(x) <= 6:
        word = "rises" if rho >= 0.5 else "falls" if rho <= -0.5 else "flat"
    else:
        word = ("rises" if rho > 0 else "falls") if p < ALPHA else "flat"
    return {"rho": rho, "p": p, "word": word, "n": len(x)}
