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
Intervals: medians get seeded percentile-bootstrap confidence intervals, success rates exact binomial ones (the
tests and intervals: app.bench.statistics).
"""

from collections import defaultdict
from dataclasses import dataclass, field

import numpy as np

from app.bench.statistics import (
    ALPHA,
    BOOTSTRAP_SEED,
    CONFIDENCE,
    N_RESAMPLES,
    Cell,
    fewer,
    greater,
    less_often,
    p_text,
    relative_spread,
    spread_difference,
    success_ci,
)

BRIDGE_WALKERS = ("lfbs", "rwbs")
CHEAP = ("gaussian", "rws", "lfs")
BRIDGES = ("rbbs", "rwbs", "lfbs")


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


def passage_yield(metrics: dict) -> float:
    """Passage samples a sampling trial delivered per K_c requested (censored trials: those drawn in the budget)."""
    k = metrics.get("k", 30)
    drawn = metrics.get("samples_drawn", 0 if metrics.get("censored") else k)
    fraction = metrics.get("passage_fraction")
    return 0.0 if not drawn or fraction is None else float(fraction) * drawn / k


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
            holds, p = greater(mine, rbbs)
            turned, p_back = greater(rbbs, mine)
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
        holds, p = fewer(lfbs, rbbs)
        turned, p_back = fewer(rbbs, lfbs)
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
        p_success = less_often(lfbs_ok, rbbs_ok)
        faster, p_time = greater(rbbs_t, lfbs_t)
        slower, p_slow = greater(lfbs_t, rbbs_t)
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
