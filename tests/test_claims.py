"""The claim judge on small synthetic stores whose answers are known."""

import numpy as np

from app.bench.claims import judge
from app.bench.store import ResultStore, TrialSpec


def fill(store, experiment, scene, method, step, metric_fn, n=20):
    rng = np.random.default_rng(hash((scene, method, step)) % 2**32)
    for seed in range(n):
        store.add(TrialSpec(experiment, scene, method, step, seed), metric_fn(rng))


def sampling_store(tmp_path, lfbs_quality, rbbs_quality_by_step, lfbs_checks, rbbs_checks):
    store = ResultStore(tmp_path / "s.sqlite")
    for step in (2, 10, 20):
        fill(
            store,
            "sampling",
            "bar",
            "lfbs",
            step,
            lambda r: {
                "passage_fraction": lfbs_quality + 0.02 * r.standard_normal(),
                "collision_checks": lfbs_checks + r.integers(50),
            },
        )
        fill(
            store,
            "sampling",
            "bar",
            "rbbs",
            step,
            lambda r, quality=rbbs_quality_by_step[step]: {
                "passage_fraction": quality + 0.02 * r.standard_normal(),
                "collision_checks": rbbs_checks + r.integers(50),
            },
        )
        fill(
            store,
            "sampling",
            "bar",
            "rwbs",
            step,
            lambda r: {"passage_fraction": lfbs_quality + 0.02 * r.standard_normal(), "collision_checks": lfbs_checks},
        )
        fill(
            store,
            "sampling",
            "bar",
            "gaussian",
            step,
            lambda r: {"passage_fraction": 0.01 + 0.005 * r.random(), "collision_checks": 100 + r.integers(10)},
        )
    return store


def by_claim(store):
    return {v.claim: v for v in judge(store.rows())}


def test_claims_reproduced_when_the_data_says_so(tmp_path):
    store = sampling_store(tmp_path, 0.6, {2: 0.1, 10: 0.3, 20: 0.5}, 1000, 5000)
    verdicts = by_claim(store)
    assert verdicts["C1"].verdict == "reproduced"
    assert verdicts["C2"].verdict == "reproduced"
    assert verdicts["C3"].verdict == "reproduced"
    assert verdicts["C5"].verdict == "reproduced"
    assert verdicts["C4"].verdict == "no data"
    assert all(v.evidence for k, v in verdicts.items() if k != "C4")


def test_claims_not_reproduced_when_the_data_says_otherwise(tmp_path):
    store = sampling_store(tmp_path, 0.2, {2: 0.5, 10: 0.5, 20: 0.5}, 9000, 1000)
    verdicts = by_claim(store)
    assert verdicts["C1"].verdict == "not reproduced"
    assert verdicts["C3"].verdict == "not reproduced"


def test_prm_claim_counts_success_and_time(tmp_path):
    store = ResultStore(tmp_path / "p.sqlite")
    for scene in ("maze", "tunnel"):
        fill(store, "prm", scene, "lfbs", 0.5, lambda r: {"success": 1.0, "seconds": 1 + r.random()})
        fill(
            store, "prm", scene, "rbbs", 0.5, lambda r: {"success": float(r.random() < 0.5), "seconds": 3 + r.random()}
        )
    fill(store, "prm", "tunnel", "lfbs", 1.0, lambda r: {"success": 0.0, "seconds": 5.0})
    fill(store, "prm", "tunnel", "rbbs", 1.0, lambda r: {"success": 1.0, "seconds": 1.0})
    verdict = by_claim(store)["C4"]
    assert verdict.verdict == "partly reproduced"
    assert len(verdict.evidence) == 3
