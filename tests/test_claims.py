"""The claim judge on small synthetic stores whose answers are known."""

import numpy as np

from app.bench.claims import detectable_drop, judge, median_ci, passage_yield, success_ci
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


def test_prm_success_is_judged_by_a_test_not_by_one_run(tmp_path):
    store = ResultStore(tmp_path / "p.sqlite")
    for step, lfbs_successes in ((0.5, 29), (1.0, 20)):
        fill(
            store, "prm", "maze", "lfbs", step, lambda r: {"success": 1.0, "seconds": 1 + r.random()}, n=lfbs_successes
        )
        for seed in range(lfbs_successes, 30):  # the same seeds, now failed
            store.add(TrialSpec("prm", "maze", "lfbs", step, seed), {"success": 0.0, "seconds": 1.5})
        fill(store, "prm", "maze", "rbbs", step, lambda r: {"success": 1.0, "seconds": 3 + r.random()}, n=30)
    verdict = by_claim(store)["C4"]
    # 29/30 against 30/30 is one run's luck; 20/30 against 30/30 is not
    assert [e.split(":")[0] for e in verdict.evidence] == ["maze a=0.5", "maze a=1"]
    assert verdict.evidence[0].endswith("holds") and verdict.evidence[1].endswith("fails")


def test_detectable_drop_is_the_edge_of_what_the_success_test_flags(tmp_path):
    edge = detectable_drop(30, 30)
    assert 0 < edge < 29
    for lfbs_successes, flagged in ((edge, True), (edge + 1, False)):
        store = ResultStore(tmp_path / f"d{lfbs_successes}.sqlite")
        for seed in range(30):
            ok = float(seed < lfbs_successes)
            store.add(TrialSpec("prm", "maze", "lfbs", 1.0, seed), {"success": ok, "seconds": 1.0 + seed / 100})
            store.add(TrialSpec("prm", "maze", "rbbs", 1.0, seed), {"success": 1.0, "seconds": 5.0 + seed / 100})
        assert by_claim(store)["C4"].evidence[0].endswith("fails" if flagged else "holds")


def censored_cell(store, scene, method, step, finished, censored, budget, fast_checks, quality):
    """`finished` trials with `fast_checks` checks and passage fraction `quality`; `censored` trials that spent
    `budget` checks and drew no sample."""
    for seed in range(finished):
        store.add(
            TrialSpec("sampling", scene, method, step, seed),
            {"collision_checks": fast_checks + seed, "passage_fraction": quality, "censored": False, "k": 30},
        )
    for seed in range(finished, finished + censored):
        store.add(
            TrialSpec("sampling", scene, method, step, seed),
            {
                "collision_checks": budget + seed,
                "passage_fraction": None,
                "samples_drawn": 0,
                "censored": True,
                "k": 30,
            },
        )


def test_a_sampler_that_mostly_spends_its_budget_cannot_win_by_its_few_survivors(tmp_path):
    store = ResultStore(tmp_path / "c.sqlite")
    for step in (2, 10):
        # rbbs: 3 lucky trials, cheap and all in the passage; 17 ran out of budget with nothing
        censored_cell(store, "bar", "rbbs", step, 3, 17, 5000, 100, 1.0)
        censored_cell(store, "bar", "lfbs", step, 20, 0, 5000, 1000, 0.5)
    verdicts = by_claim(store)
    assert verdicts["C1"].verdict == "reproduced"  # lfbs delivers more passage samples per K_c
    assert verdicts["C3"].verdict == "reproduced"  # lfbs finishes in fewer checks
    assert "17 censored" in verdicts["C3"].evidence[0]
    # The same data, roles swapped: the mostly-censored method is lfbs, and it wins nothing.
    swapped = ResultStore(tmp_path / "d.sqlite")
    for step in (2, 10):
        censored_cell(swapped, "bar", "lfbs", step, 3, 17, 5000, 100, 1.0)
        censored_cell(swapped, "bar", "rbbs", step, 20, 0, 5000, 1000, 0.5)
    verdicts = by_claim(swapped)
    assert verdicts["C1"].verdict == "not reproduced"
    assert verdicts["C3"].verdict == "not reproduced"


def test_partial_samples_of_a_censored_trial_count_toward_its_yield():
    assert passage_yield({"passage_fraction": 0.5, "k": 30, "censored": False}) == 0.5
    assert passage_yield({"passage_fraction": 0.5, "samples_drawn": 6, "k": 30, "censored": True}) == 0.1
    assert passage_yield({"passage_fraction": None, "samples_drawn": 0, "k": 30, "censored": True}) == 0.0


def test_median_interval_is_seeded_and_contains_the_median():
    values = np.random.default_rng(3).lognormal(size=40)
    median, lo, hi = median_ci(values)
    assert median == np.median(values)
    assert lo < median < hi
    assert median_ci(values) == (median, lo, hi)
    assert median_ci(values, seed=1) != (median, lo, hi)
    assert median_ci([2.0, 2.0, 2.0]) == (2.0, 2.0, 2.0)
    assert all(np.isnan(median_ci([])))


def test_success_interval_is_the_exact_binomial_one():
    from scipy.stats import binomtest

    ci = binomtest(7, 10).proportion_ci(confidence_level=0.95, method="exact")
    assert success_ci(7, 10) == (ci.low, ci.high)
    lo, hi = success_ci(10, 10)
    assert lo < 1.0 and hi == 1.0
