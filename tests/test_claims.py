"""The claim judge on small synthetic stores whose answers are known."""

import numpy as np
import pytest

from app.bench.claims import SAMPLER_CAP, checks_per_passage_sample, judge, passage_yield
from app.bench.statistics import detectable_drop, holm, median_ci, paired_tests, spread_difference, success_ci, trend
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
    # RBBS puts significantly more in the passage and finishes in fewer checks everywhere: said as reversals
    assert verdicts["C1"].verdict == "reversed"
    assert verdicts["C3"].verdict == "reversed"
    assert len(verdicts["C1"].reversals) == 2 and "Mann-Whitney p" in verdicts["C1"].reversals[0]
    assert all("log-rank p" in r for r in verdicts["C3"].reversals)


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
    assert verdict.verdict == "partly reproduced; reversed in 1 of 3"  # tunnel a=1: 0/20 against 20/20, slower
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
    assert verdict.evidence[0].endswith("holds") and verdict.evidence[1].endswith("reversed")


def test_detectable_drop_is_the_edge_of_what_the_success_test_flags(tmp_path):
    edge = detectable_drop(30, 30)
    assert 0 < edge < 29
    for lfbs_successes, flagged in ((edge, True), (edge + 1, False)):
        store = ResultStore(tmp_path / f"d{lfbs_successes}.sqlite")
        for seed in range(30):
            ok = float(seed < lfbs_successes)
            store.add(TrialSpec("prm", "maze", "lfbs", 1.0, seed), {"success": ok, "seconds": 1.0 + seed / 100})
            store.add(TrialSpec("prm", "maze", "rbbs", 1.0, seed), {"success": 1.0, "seconds": 5.0 + seed / 100})
        assert by_claim(store)["C4"].evidence[0].endswith("reversed" if flagged else "holds")


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
    assert verdicts["C1"].verdict == "reversed"
    assert verdicts["C3"].verdict == "reversed"


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


def quality_store(tmp_path, lfbs_by_step, rbbs_by_step, rbbs_censored_at=(), n=60):
    """LFBS and RBBS sampling cells in bar whose passage yields (k = 30) are drawn around the given per-step levels;
    RBBS's cells at `rbbs_censored_at` have every trial spend the budget with two passage samples of three drawn."""
    store = ResultStore(tmp_path / "q.sqlite")
    rng = np.random.default_rng(5)
    for method, levels in (("lfbs", lfbs_by_step), ("rbbs", rbbs_by_step)):
        for step, level in levels.items():
            for seed in range(n):
                if method == "rbbs" and step in rbbs_censored_at:
                    m = {"passage_fraction": 2 / 3, "samples_drawn": 3, "censored": True, "collision_checks": 9e5}
                else:
                    m = {"passage_fraction": rng.binomial(30, level) / 30, "censored": False, "collision_checks": 1e3}
                store.add(TrialSpec("sampling", "bar", method, step, seed), {**m, "k": 30})
    return store


def test_c2_holds_when_only_rbbs_moves_with_the_step(tmp_path):
    store = quality_store(tmp_path, {5: 0.3, 10: 0.3, 20: 0.3}, {5: 0.1, 10: 0.3, 20: 0.5})
    verdict = by_claim(store)["C2"]
    assert verdict.verdict == "reproduced"
    assert verdict.reversals == [] and verdict.excluded == []


def test_c2_is_reversed_when_lfbs_moves_more_for_its_level(tmp_path):
    store = quality_store(tmp_path, {5: 0.1, 10: 0.2, 20: 0.3}, {5: 0.5, 10: 0.5, 20: 0.5})
    verdict = by_claim(store)["C2"]
    assert verdict.verdict == "reversed"
    assert "bootstrap p=" in verdict.reversals[0]


def test_c2_leaves_out_a_step_the_budget_decided_and_says_so(tmp_path):
    # RBBS is flat where it finishes; at a=2 every trial spent the budget and delivered 2 of 30: a huge "spread"
    # that is the budget's. LFBS is as flat: without the a=2 cell the two cannot be told apart.
    store = quality_store(tmp_path, {2: 0.3, 5: 0.3, 10: 0.3}, {2: 0.3, 5: 0.3, 10: 0.3}, rbbs_censored_at=(2,))
    verdict = by_claim(store)["C2"]
    assert verdict.excluded == ["bar a=2: budget artefact (rbbs 60/60 censored)"]
    assert verdict.verdict == "not reproduced"
    assert "a=2" not in verdict.evidence[0].split(". Steps left out")[0]


def test_spread_difference_interval_covers_the_true_difference():
    rng = np.random.default_rng(1)
    lfbs = [rng.binomial(30, p, 200) / 30 for p in (0.2, 0.2, 0.2)]
    rbbs = [rng.binomial(30, p, 200) / 30 for p in (0.2, 0.3, 0.4)]  # relative spread 0.2 / 0.3
    d = spread_difference(lfbs, rbbs)["relative"]
    assert d["low"] < -2 / 3 < d["high"]
    assert d["high"] < 0 and d["p_smaller"] < 0.01 and d["p_larger"] > 0.99


def prm_run(success: bool, seconds: float, nodes: int) -> dict:
    return {"success": float(success), "seconds": seconds, "nodes": nodes, "collision_checks": 10}


def test_c4_leaves_out_runs_whose_sampler_gave_up_and_counts_them(tmp_path):
    store = ResultStore(tmp_path / "p.sqlite")
    for seed in range(30):
        # a=0.5: every RBBS run hit the sampler's cap and built no roadmap; LFBS plans
        store.add(TrialSpec("prm", "maze", "lfbs", 0.5, seed), prm_run(True, 1 + seed / 100, 502))
        store.add(TrialSpec("prm", "maze", "rbbs", 0.5, seed), prm_run(False, 40 + seed / 100, 2))
        # a=1: LFBS slower and failing more, but 5 of its failures are the cap's, not the planner's
        store.add(
            TrialSpec("prm", "maze", "lfbs", 1.0, seed), prm_run(seed >= 5, 1 + seed / 100, 2 if seed < 5 else 502)
        )
        store.add(TrialSpec("prm", "maze", "rbbs", 1.0, seed), prm_run(True, 5 + seed / 100, 502))
    verdict = by_claim(store)["C4"]
    assert verdict.excluded == [
        f"maze a=0.5: rbbs 30 runs censored by the sampler's {SAMPLER_CAP:,}-check cap (no roadmap)",
        f"maze a=1: 5 lfbs runs censored by the sampler's {SAMPLER_CAP:,}-check cap (no roadmap)",
    ]
    # only a=1 is judged, on LFBS's 25 runs that built a roadmap (25/25 vs 30/30, faster): it holds
    assert verdict.verdict == "reproduced"
    assert "success lfbs 25/25" in verdict.evidence[1] and verdict.evidence[1].endswith("holds")


def test_c4_reversed_when_lfbs_succeeds_significantly_less_often(tmp_path):
    store = ResultStore(tmp_path / "p.sqlite")
    for seed in range(30):
        store.add(TrialSpec("prm", "maze", "lfbs", 1.0, seed), prm_run(seed < 10, 1 + seed / 100, 502))
        store.add(TrialSpec("prm", "maze", "rbbs", 1.0, seed), prm_run(True, 5 + seed / 100, 502))
    verdict = by_claim(store)["C4"]
    assert verdict.verdict == "reversed"
    assert verdict.reversals[0].startswith("maze a=1: lfbs succeeds less often, one-sided Fisher p=")


def test_a_scene_where_no_sampler_reaches_the_passage_judges_neither_c1_nor_c2(tmp_path):
    store = quality_store(tmp_path, {5: 0.0, 10: 0.01, 20: 0.0}, {5: 0.02, 10: 0.04, 20: 0.01})
    verdicts = by_claim(store)
    assert verdicts["C1"].verdict == verdicts["C2"].verdict == "no data"
    assert verdicts["C2"].excluded == ["bar: at the floor (mean passage yields below 0.05)"]


def test_checks_per_passage_sample_is_a_ratio_of_totals_with_an_interval():
    rows = [
        {
            "experiment": "sampling",
            "scene": "bar",
            "method": "lfbs",
            "step": 5.0,
            "metrics": {"collision_checks": 1000 + 100 * (i % 3), "passage_fraction": 0.2, "k": 30, "censored": False},
        }
        for i in range(30)
    ]
    # a censored trial: 5000 checks spent, 3 samples drawn, one in the passage
    rows.append(
        {
            **rows[0],
            "metrics": {
                "collision_checks": 5000,
                "passage_fraction": 1 / 3,
                "samples_drawn": 3,
                "k": 30,
                "censored": True,
            },
        }
    )
    r = checks_per_passage_sample(rows)[("bar", "lfbs", 5.0)]
    checks = sum(row["metrics"]["collision_checks"] for row in rows)
    assert r["passage"] == 30 * 6 + 1
    assert r["ratio"] == checks / (30 * 6 + 1)
    assert r["low"] < r["ratio"] < r["high"]
    none = [{**rows[0], "metrics": {"collision_checks": 10, "passage_fraction": 0.0, "k": 30}}] * 3
    assert checks_per_passage_sample(none)[("bar", "lfbs", 5.0)]["ratio"] == np.inf


def test_trend_says_which_way_and_only_when_the_test_says_so():
    rng = np.random.default_rng(0)
    steps = np.repeat([2.0, 5.0, 10.0, 20.0], 50)
    assert trend(steps, 10 / steps + rng.random(len(steps)))["word"] == "falls"
    assert trend(steps, rng.random(len(steps)))["word"] == "flat"
    # five published values: the word comes from rho alone
    assert trend([2, 5, 10, 15, 20], [6.96, 6.18, 6.35, 6.47, 6.84])["word"] == "flat"
    assert trend([2, 5, 10, 15, 20], [7.4, 7.6, 7.9, 9.9, 12.0])["word"] == "rises"


def test_a_trend_that_moves_both_ways_is_named_by_its_moves():
    """Down from the first step to the second, up to the third (as the tunnel's LFBS plan times): a rank correlation
    over all of them is significant one way, yet the word names both moves."""
    rng = np.random.default_rng(0)
    steps = np.repeat([0.2, 0.5, 1.0], 30)
    times = np.select([steps == 0.2, steps == 0.5], [3.5, 1.7], 2.3) + 0.2 * rng.random(len(steps))
    t = trend(steps, times)
    assert t["p"] < 0.05 and t["rho"] < 0  # Spearman alone would say "falls"
    assert t["word"] == "falls, then rises"
    steady = np.select([steps == 0.2, steps == 0.5], [3.5, 2.3], 1.7) + 0.2 * rng.random(len(steps))
    assert trend(steps, steady)["word"] == "falls"


def test_holm_adjusts_every_p_of_a_family_alike_and_keeps_their_order():
    assert holm([0.01, None, 0.04, 0.03]) == pytest.approx([0.03, None, 0.06, 0.06])
    assert holm([0.5, 0.9]) == pytest.approx([1.0, 1.0])  # capped at 1
    assert holm([]) == []


def test_paired_tests_count_the_seeds_each_way_and_test_only_the_pairs_that_differ():
    same = paired_tests([1, 1, 0], [10, 20, 100], [1, 1, 0], [10, 20, 100])
    assert same["success_mcnemar_p"] == same["checks_wilcoxon_p"] == 1.0
    assert (same["fewer_checks"], same["more_checks"], same["pairs"]) == (0, 0, 3)
    # 10 seeds, the first planner solves all, the second 2 of them: McNemar on the 8 discordant pairs
    a = paired_tests([1] * 10, list(range(10, 20)), [1, 1] + [0] * 8, [20, 30] + [100] * 8)
    assert a["success_mcnemar_p"] == pytest.approx(2 * 0.5**8)
    assert (a["fewer_checks"], a["more_checks"]) == (10, 0) and a["checks_wilcoxon_p"] < 0.01
