"""The adaptive mixture of sample sources: shares learned from reward per check, a floor for every source, capped
sampler calls, the same answer for a seed, and what each source did recorded in the answer."""

import math

import numpy as np
import pytest

from app.errors import SamplerBudgetExceeded, UserError
from app.planning.query import plan
from app.planning.settings import PlanSettings
from app.planning.sources import ADAPTIVE, EXPLORE, MIN_CALL, MIXED, Mixture
from app.samplers import SAMPLERS, make_sampler
from toy_checker import toy_checker


def test_the_mixture_gives_its_checks_to_the_source_that_earns_rewards_and_keeps_a_floor_for_the_others():
    mixture = Mixture(("a", "b", "c"))
    for name in mixture.names:
        mixture.spent(name, samples=10, checks=1000)
    mixture.reward("a", 50)
    mixture.reward("b", 5)
    shares = dict(zip(mixture.names, mixture.shares(list(mixture.names))))
    assert shares["a"] > shares["b"] > shares["c"]
    assert shares["c"] >= EXPLORE / 3
    assert sum(shares.values()) == pytest.approx(1.0)
    # A source off (it gave up) is not allotted anything; the others share the whole.
    assert mixture.shares(["b", "c"]).sum() == pytest.approx(1.0)


def test_the_mixture_saves_a_small_share_up_until_it_buys_a_call_and_counts_what_a_call_overspent():
    mixture = Mixture(("a", "b"))
    mixture.checks.update(a=1000, b=10_000)  # as if spent before: a earned 100 rewards, b none
    mixture.reward("a", 100)  # almost everything to a; b's share is little more than the floor
    first = mixture.allot(10, 2 * MIN_CALL, ["a", "b"])
    assert "a" in first and "b" not in first
    rounds = 1
    while "b" not in mixture.allot(10, 2 * MIN_CALL, ["a", "b"]):
        rounds += 1
    assert rounds > 1
    mixture.spent("b", samples=1, checks=int(mixture.credit["b"]) + 500)  # a call overran its credit
    assert mixture.credit["b"] < 0 and "b" not in mixture.allot(10, 2 * MIN_CALL, ["a", "b"])


def test_a_cheap_source_draws_no_more_than_its_share_of_the_round_samples_and_banks_no_flood():
    mixture = Mixture(("cheap", "dear"))
    mixture.checks.update(cheap=1000, dear=1000)
    mixture.samples.update(cheap=1000, dear=10)  # a check a sample, against a hundred
    mixture.reward("cheap", 10)
    mixture.reward("dear", 10)
    for _ in range(20):  # rounds in which nothing is drawn: credit is saved up to two rounds' share only
        allotted = mixture.allot(50, 1000, ["cheap", "dear"])
    share = mixture.shares(["cheap", "dear"])[0]
    credit, most = allotted["cheap"]
    assert credit <= 2 * share * 1000 + 1e-9
    assert most == math.ceil(share * 50) < credit / mixture.per_sample("cheap")


@pytest.mark.parametrize("name", list(SAMPLERS))
def test_a_capped_sampler_call_is_not_overrun_by_a_batch_sized_for_many_samples(name):
    checker = toy_checker()
    sampler = make_sampler(name, checker, step=5.0)
    cap = 5
    sampler.max_checks = cap
    with pytest.raises(SamplerBudgetExceeded):
        sampler.sample(500, np.random.default_rng(0))
    # One more round may start while the call is within its cap; a round asks at most two checks per check of room.
    assert checker.checks <= 2 * cap + 2


def test_sampler_parameters_need_a_named_sampler():
    with pytest.raises(UserError, match="need a named sampler"):
        PlanSettings(sampler=ADAPTIVE, sampler_params={"alpha_angle": 1.1})
    with pytest.raises(UserError, match="adaptive"):
        PlanSettings(sampler="adaptve")


@pytest.fixture(scope="module")
def adaptive_plans(oracles):
    return [plan(oracles("bar"), PlanSettings(sampler=ADAPTIVE, seed=1)) for _ in range(2)]


def test_the_adaptive_mixture_gives_the_same_certified_plan_for_a_seed(adaptive_plans):
    first, again = (r.to_json() for r in adaptive_plans)
    assert adaptive_plans[0].certified
    for key in ("roadmap_path", "path", "collision_checks", "sampler_stats", "sources_on_path"):
        assert first[key] == again[key]


def test_the_answer_records_what_each_source_drew_earned_and_put_on_the_path(adaptive_plans):
    answer = adaptive_plans[0].to_json()
    stats = answer["sampler_stats"]
    assert set(stats) == {"uniform", *MIXED}
    for name in MIXED:
        assert {"samples", "rewards", "share", "checks"} <= set(stats[name])
    assert sum(stats[name]["share"] for name in MIXED) == pytest.approx(1.0)
    assert sum(stats[name]["checks"] for name in stats) <= answer["checks"]["sampling"]
    # Every node of the roadmap path but start and goal was drawn by this query, and is counted once.
    assert sum(answer["sources_on_path"].values()) == len(answer["roadmap_path"]) - 2
    assert set(answer["sources_on_path"]) <= {"uniform", *MIXED}
