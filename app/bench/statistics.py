"""The statistics `bench paper` judges and reports with: one-sided tests of two cells of trials (Mann-Whitney, log-rank
with right-censored values, Fisher's exact test), percentile-bootstrap and exact binomial intervals, the relative
spread of a quality across steps, and Spearman trends. Seeded: the same trials always give the same numbers. The
claims' rules that use them are app.bench.claims'.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

ALPHA = 0.01  # one-sided significance level of every test
CONFIDENCE = 0.95  # of every interval
N_RESAMPLES = 2000  # bootstrap resamples per interval
BOOTSTRAP_SEED = 0  # the same store always gives the same intervals


def median_or_none(values) -> float | None:
    """The median of the values that are not None; None when none are (a method that never succeeded)."""
    values = [v for v in values if v is not None]
    return float(np.median(values)) if values else None


def shown(value, spec: str) -> str:
    """A table cell: `value` formatted by `spec`, or "-" for None."""
    return "-" if value is None else format(value, spec)


def p_text(p: float) -> str:
    """'p=0.0032' as the report writes a p value (two significant digits); below what a double holds, a bound."""
    return "p < 1e-300" if p < 1e-300 else f"p={p:.2g}"


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


def greater(a: Cell, b: Cell) -> tuple[bool, float]:
    """a is stochastically greater than b (one-sided Mann-Whitney) and its median is not smaller."""
    if a.n < 3 or b.n < 3:
        return False, float("nan")
    x, y = a.values, b.values
    if np.all(x == x[0]) and np.all(y == y[0]):
        return bool(x[0] > y[0]), 0.0 if x[0] > y[0] else 1.0
    from scipy.stats import mannwhitneyu

    p = float(mannwhitneyu(x, y, alternative="greater").pvalue)
    return bool(p < ALPHA and a.median() >= b.median()), p


def fewer(a: Cell, b: Cell) -> tuple[bool, float]:
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


def less_often(a: Cell, b: Cell) -> float:
    """p of a one-sided Fisher exact test that successes `a` (0/1 values) come less often than successes `b`."""
    from scipy.stats import fisher_exact

    ok_a, ok_b = int(a.values.sum()), int(b.values.sum())
    return float(fisher_exact([[ok_a, a.n - ok_a], [ok_b, b.n - ok_b]], alternative="less").pvalue)


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


def trend(x, y) -> dict:
    """How y moves with x: Spearman's rank correlation, its two-sided p, and a word (rises / falls when p < ALPHA,
    else flat). A trend that is not monotone is named by its moves instead (e.g. "falls, then rises"): where y
    moves significantly both ways between neighbouring values of x (Mann-Whitney, two-sided, Bonferroni over the
    neighbouring pairs), a rank correlation over all of them would name only the larger move. For a handful of
    published values with no spread to test, the word comes from rho alone (|rho| >= 0.5)."""
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
        moves = _moves_between_neighbours(x, y)
        if {"rises", "falls"} <= set(moves):
            word = ", then ".join(m for i, m in enumerate(moves) if i == 0 or m != moves[i - 1])
    return {"rho": rho, "p": p, "word": word, "n": len(x)}


def _moves_between_neighbours(x: np.ndarray, y: np.ndarray) -> list[str]:
    """'rises' or 'falls' for each pair of neighbouring x values whose y differ significantly (Mann-Whitney,
    two-sided, p < ALPHA / the number of pairs), in order of x."""
    from scipy.stats import mannwhitneyu

    levels = np.unique(x)
    pairs = list(zip(levels[:-1], levels[1:]))
    moves = []
    for a, b in pairs:
        ya, yb = y[x == a], y[x == b]
        if len(ya) > 1 and len(yb) > 1 and mannwhitneyu(ya, yb).pvalue < ALPHA / len(pairs):
            moves.append("rises" if np.median(yb) > np.median(ya) else "falls")
    return moves


def holm(pvalues: list[float | None]) -> list[float | None]:
    """Holm's step-down adjustment of a family of p-values (None: no test, kept None): each adjusted p is compared
    with the family's level as it is, every comparison corrected alike; it holds the family-wise error rate as
    Bonferroni's does and rejects at least what Bonferroni's rejects."""
    tested = sorted((p, i) for i, p in enumerate(pvalues) if p is not None)
    out: list[float | None] = [None] * len(pvalues)
    running = 0.0
    for rank, (p, i) in enumerate(tested):
        running = max(running, min(1.0, (len(tested) - rank) * p))
        out[i] = running
    return out


def paired_tests(a_success, a_checks, b_success, b_checks) -> dict:
    """Two planners on the same seeds (pairs in order): an exact McNemar test of success (a two-sided binomial test
    of the discordant pairs), and a Wilcoxon signed-rank test of checks to the first solution with an unsolved run
    counted at its budget (a censored value no solved run exceeds); how many pairs a needs fewer and more checks."""
    from scipy.stats import binomtest, wilcoxon

    a_success, b_success = np.asarray(a_success, bool), np.asarray(b_success, bool)
    a_checks, b_checks = np.asarray(a_checks, float), np.asarray(b_checks, float)
    only_a, only_b = int(np.sum(a_success & ~b_success)), int(np.sum(b_success & ~a_success))
    success_p = float(binomtest(only_a, only_a + only_b).pvalue) if only_a + only_b else 1.0
    differ = a_checks != b_checks
    checks_p = float(wilcoxon(a_checks[differ], b_checks[differ]).pvalue) if differ.sum() >= 1 else 1.0
    return {
        "pairs": len(a_checks),
        "success_mcnemar_p": success_p,
        "checks_wilcoxon_p": checks_p,
        "fewer_checks": int(np.sum(a_checks < b_checks)),
        "more_checks": int(np.sum(a_checks > b_checks)),
    }
