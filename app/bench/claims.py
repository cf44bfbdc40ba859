"""Judges the paper's claims from the results store: reproduced, partly, not reproduced, or no data — with numbers.

Each claim is a set of comparisons (one per scene or per scene x step). A comparison holds when the medians point
the claimed way and, where the claim is about distributions, a one-sided Mann-Whitney U test agrees at the 1 %
level. The verdict counts them: all hold -> reproduced, none -> not reproduced, some -> partly. No tuning toward
the paper: the thresholds are fixed here and printed in the report.
"""

from collections import defaultdict
from dataclasses import dataclass, field

import numpy as np

ALPHA = 0.01
BRIDGE_WALKERS = ("lfbs", "rwbs")
CHEAP = ("gaussian", "rws", "lfs")
BRIDGES = ("rbbs", "rwbs", "lfbs")


@dataclass
class Verdict:
    claim: str
    text: str
    verdict: str
    evidence: list[str] = field(default_factory=list)


def _values(rows, experiment, metric):
    """{(scene, method, step): np.array of the metric over seeds}."""
    cells = defaultdict(list)
    for r in rows:
        if r["experiment"] == experiment and r["metrics"].get(metric) is not None:
            cells[(r["scene"], r["method"], r["step"])].append(float(r["metrics"][metric]))
    return {k: np.array(v) for k, v in cells.items()}


def _pooled(cells, scene, method):
    parts = [v for (s, m, _), v in cells.items() if s == scene and m == method]
    return np.concatenate(parts) if parts else np.array([])


def _greater(a, b) -> tuple[bool, float]:
    """a is stochastically greater than b (one-sided Mann-Whitney) and its median is larger."""
    if len(a) < 3 or len(b) < 3:
        return False, float("nan")
    if np.all(a == a[0]) and np.all(b == b[0]):
        return bool(a[0] > b[0]), 0.0 if a[0] > b[0] else 1.0
    from scipy.stats import mannwhitneyu  # about a second to import: only when a claim is judged, not at CLI start

    p = float(mannwhitneyu(a, b, alternative="greater").pvalue)
    return bool(p < ALPHA and np.median(a) >= np.median(b)), p


def _verdict(outcomes: list[bool]) -> str:
    if not outcomes:
        return "no data"
    if all(outcomes):
        return "reproduced"
    return "partly reproduced" if any(outcomes) else "not reproduced"


def _scenes(cells, methods):
    return sorted({s for (s, m, _) in cells if m in methods})


def claim_c1(rows) -> Verdict:
    cells = _values(rows, "sampling", "passage_fraction")
    outcomes, evidence = [], []
    for scene in _scenes(cells, ("rbbs",)):
        rbbs = _pooled(cells, scene, "rbbs")
        for walker in BRIDGE_WALKERS:
            mine = _pooled(cells, scene, walker)
            if len(mine) == 0 or len(rbbs) == 0:
                continue
            holds, p = _greater(mine, rbbs)
            outcomes.append(holds)
            evidence.append(
                f"{scene}: {walker} mean passage fraction {mine.mean():.3f} vs rbbs {rbbs.mean():.3f} "
                f"(p={p:.2g}) -> {'holds' if holds else 'fails'}"
            )
    return Verdict(
        "C1", "Bridge walkers (LFBS, RWBS) put more samples in the passage than RBBS.", _verdict(outcomes), evidence
    )


def claim_c2(rows) -> Verdict:
    """LFBS's passage fraction varies less across steps a than RBBS's (range of per-step means)."""
    cells = _values(rows, "sampling", "passage_fraction")
    outcomes, evidence = [], []
    for scene in _scenes(cells, ("rbbs", "lfbs")):
        spread = {}
        for method in ("lfbs", "rbbs"):
            means = [v.mean() for (s, m, _), v in cells.items() if s == scene and m == method]
            if len(means) >= 2:
                spread[method] = (max(means) - min(means), min(means), max(means))
        if len(spread) < 2:
            continue
        holds = spread["lfbs"][0] < spread["rbbs"][0]
        outcomes.append(holds)
        evidence.append(
            f"{scene}: across steps lfbs passage fraction {spread['lfbs'][1]:.3f}-{spread['lfbs'][2]:.3f} "
            f"(range {spread['lfbs'][0]:.3f}), rbbs {spread['rbbs'][1]:.3f}-{spread['rbbs'][2]:.3f} "
            f"(range {spread['rbbs'][0]:.3f}) -> {'holds' if holds else 'fails'}"
        )
    return Verdict(
        "C2", "LFBS sample quality is insensitive to the step a; RBBS's is not.", _verdict(outcomes), evidence
    )


def claim_c3(rows, scene="bar") -> Verdict:
    cells = _values(rows, "sampling", "collision_checks")
    outcomes, evidence = [], []
    for step in sorted({st for (s, m, st) in cells if s == scene and m == "lfbs"}):
        lfbs, rbbs = cells.get((scene, "lfbs", step)), cells.get((scene, "rbbs", step))
        if lfbs is None or rbbs is None:
            continue
        holds, p = _greater(rbbs, lfbs)
        outcomes.append(holds)
        evidence.append(
            f"{scene} a={step:g}: median checks lfbs {np.median(lfbs):.0f} vs rbbs {np.median(rbbs):.0f} "
            f"(p={p:.2g}) -> {'holds' if holds else 'fails'}"
        )
    return Verdict("C3", f"LFBS needs fewer collision calls than RBBS in {scene}.", _verdict(outcomes), evidence)


def claim_c4(rows) -> Verdict:
    success = _values(rows, "prm", "success")
    seconds = _values(rows, "prm", "seconds")
    outcomes, evidence = [], []
    for scene, method, step in sorted(k for k in success if k[1] == "lfbs"):
        rbbs_ok, lfbs_ok = success.get((scene, "rbbs", step)), success[(scene, method, step)]
        if rbbs_ok is None:
            continue
        lfbs_t, rbbs_t = seconds.get((scene, "lfbs", step)), seconds.get((scene, "rbbs", step))
        faster = lfbs_t is not None and rbbs_t is not None and np.median(lfbs_t) < np.median(rbbs_t)
        holds = bool(lfbs_ok.mean() >= rbbs_ok.mean() and faster)
        outcomes.append(holds)
        evidence.append(
            f"{scene} a={step:g}: success lfbs {lfbs_ok.mean():.0%} vs rbbs {rbbs_ok.mean():.0%}; "
            f"median time lfbs {np.median(lfbs_t):.2f}s vs rbbs {np.median(rbbs_t):.2f}s "
            f"-> {'holds' if holds else 'fails'}"
        )
    return Verdict(
        "C4",
        "LFBS-PRM is faster and succeeds at least as often as RBBS-PRM (maze, tunnel).",
        _verdict(outcomes),
        evidence,
    )


def claim_c5(rows) -> Verdict:
    checks = _values(rows, "sampling", "collision_checks")
    quality = _values(rows, "sampling", "passage_fraction")
    outcomes, evidence = [], []
    for scene in _scenes(checks, CHEAP):
        bridges = [b for b in BRIDGES if len(_pooled(checks, scene, b))]
        for cheap in CHEAP:
            c, q = _pooled(checks, scene, cheap), _pooled(quality, scene, cheap)
            if len(c) == 0 or not bridges:
                continue
            cheaper = all(np.median(c) < np.median(_pooled(checks, scene, b)) for b in bridges)
            poorer = all(q.mean() < _pooled(quality, scene, b).mean() for b in bridges)
            outcomes.append(cheaper and poorer)
            best = max(bridges, key=lambda b: _pooled(quality, scene, b).mean())
            evidence.append(
                f"{scene}: {cheap} median checks {np.median(c):.0f} (bridges ≥ "
                f"{min(np.median(_pooled(checks, scene, b)) for b in bridges):.0f}), passage fraction "
                f"{q.mean():.3f} (best bridge {best} {_pooled(quality, scene, best).mean():.3f}) -> "
                f"{'holds' if cheaper and poorer else 'fails'}"
            )
    return Verdict(
        "C5",
        "Gaussian, RWS and LFS are cheap but poor: fewer checks, fewer passage samples than the bridge samplers.",
        _verdict(outcomes),
        evidence,
    )


def judge(rows) -> list[Verdict]:
    return [claim_c1(rows), claim_c2(rows), claim_c3(rows), claim_c4(rows), claim_c5(rows)]
