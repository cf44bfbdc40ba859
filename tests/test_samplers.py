"""The seven samplers: free in-bounds samples, real bridges, heavy Lévy tails, reproducibility, honest counts, CLI."""

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.bench.sampling import run_trial
from app.errors import SamplerBudgetExceeded, UserError
from app.samplers import SAMPLERS, make_sampler
from app.samplers.levy import hill_tail_index, levy_stable
from app.samplers.walk import Walker
from independent import raw_free

NAMES = ["uniform", "gaussian", "rbbs", "rws", "lfs", "rwbs", "lfbs"]
BRIDGED = ["rbbs", "rwbs", "lfbs"]
SCENES = ["bar", "teeth3d"]


def _check_samples(oracle, X, k):
    assert X.shape == (k, oracle.space.dim)
    assert np.all(np.isfinite(X))
    assert oracle.space.within_bounds(X).all()
    assert np.all(X[:, oracle.space.continuous] >= -np.pi) and np.all(X[:, oracle.space.continuous] < np.pi)
    assert all(raw_free(oracle, q) for q in X)  # re-checked by SceneGraph directly, not by the sampling oracle


def test_registry_names_and_errors(checkers):
    assert list(SAMPLERS) == NAMES
    with pytest.raises(UserError, match="known: uniform, gaussian, rbbs, rws, lfs, rwbs, lfbs"):
        make_sampler("levy", checkers("bar"))
    with pytest.raises(UserError, match="sampler 'lfbs'"):
        make_sampler("lfbs", checkers("bar"), stepsize=3)
    with pytest.raises(UserError):
        make_sampler("rws", checkers("bar"), step=float("nan"))


def test_four_walkers_are_one_class_with_two_switches(checkers):
    expected = {"rws": ("gaussian", False), "lfs": ("levy", False), "rwbs": ("gaussian", True), "lfbs": ("levy", True)}
    for name, (law, bridge) in expected.items():
        s = make_sampler(name, checkers("bar"), step=5)
        assert type(s) is Walker and (s.step_law, s.bridge, s.name) == (law, bridge, name)


@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("name", NAMES)
def test_samples_are_free_and_in_bounds(checkers, scene, name):
    oracle = checkers(scene)
    k = 4 if name == "rbbs" else 8
    sampler = make_sampler(name, oracle, step=10)
    X = sampler.sample(k, np.random.default_rng(3))
    _check_samples(oracle, X, k)
    for key in ("gave_up", "attempts"):
        assert isinstance(sampler.stats[key], int) and sampler.stats[key] >= 0


@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("name", BRIDGED)
def test_bridge_endpoints_collide_and_straddle_the_sample(checkers, scene, name):
    oracle = checkers(scene)
    k = 4 if name == "rbbs" else 8
    sampler = make_sampler(name, oracle, step=10)
    X = sampler.sample(k, np.random.default_rng(5))
    ends = sampler.bridges
    assert ends.shape == (k, 2, oracle.space.dim)
    for q, (a, b) in zip(X, ends):
        assert oracle.space.within_bounds(a).all() and oracle.space.within_bounds(b).all()
        assert not raw_free(oracle, a) and not raw_free(oracle, b)
        # the sample is the bridge's midpoint: b = extend(a, q) = q + (q - a), angles the short way round
        far = oracle.space.wrap(q + oracle.space.difference(a, q))
        assert np.allclose(oracle.space.difference(far, b), 0.0, atol=1e-9)


def test_unbridged_samplers_report_no_bridges(checkers):
    s = make_sampler("lfs", checkers("bar"), step=10)
    s.sample(3, np.random.default_rng(0))
    assert s.bridges is None


def test_levy_draws_are_heavy_tailed_and_gaussian_ones_are_not():
    rng = np.random.default_rng(7)
    for alpha in (1.9, 1.1):
        assert abs(hill_tail_index(levy_stable(rng, alpha, 200_000)) - alpha) < 0.2
    assert hill_tail_index(rng.normal(size=200_000)) > 4.0


@settings(max_examples=25, deadline=None)
@given(alpha=st.floats(0.3, 2.0), seed=st.integers(0, 2**32 - 1))
def test_levy_draws_are_finite_for_any_alpha(alpha, seed):
    x = levy_stable(np.random.default_rng(seed), alpha, 2000)
    assert x.shape == (2000,) and np.all(np.isfinite(x))


@pytest.mark.parametrize("name", NAMES)
def test_same_seed_same_samples(checkers, name):
    oracle = checkers("bar")
    k, step = (2, 20) if name == "rbbs" else (6, 10)  # long bridges are cheap ones
    a = make_sampler(name, oracle, step=step).sample(k, np.random.default_rng(11))
    sampler = make_sampler(name, oracle, step=step)
    sampler.sample(2, np.random.default_rng(99))  # state left over from an earlier call must not matter
    b = sampler.sample(k, np.random.default_rng(11))
    assert np.array_equal(a, b)


class _CountingChecker:
    """The oracle's collision checker, counting the configurations its batch query is given."""

    def __init__(self, checker):
        self._checker, self.configurations = checker, 0

    def CheckConfigsCollisionFree(self, configs, **kwargs):
        self.configurations += len(configs)
        return self._checker.CheckConfigsCollisionFree(configs, **kwargs)

    def __getattr__(self, name):
        return getattr(self._checker, name)


@pytest.mark.parametrize("name", ["uniform", "gaussian", "lfs", "lfbs"])
def test_reported_checks_are_the_configurations_drake_answered(oracles, monkeypatch, name):
    """gamma_c counts every configuration handed to Drake for a collision answer, counted here at Drake's two
    entry points (one at a time, and batched), so a check that bypassed the counter or a miscount would show.

    The oracle's third path, a batch split with its helper processes, answers part of a batch in those processes,
    where these counters cannot see it; whether it is taken depends on the machine's load (the helpers start once
    batches have taken half a second), so the test keeps the oracle to the two paths in this process."""
    oracle = oracles("teeth3d")
    monkeypatch.setattr(oracle, "_helpers", None)  # no split path: the counts below cannot depend on timing
    monkeypatch.setattr(oracle, "_paths", {})  # path choices made with the helpers: made again without them
    single = []
    raw = oracle.free_raw
    monkeypatch.setattr(oracle, "free_raw", lambda Q: single.extend([1] * len(Q)) or raw(Q))
    batch = _CountingChecker(oracle.checker)
    monkeypatch.setattr(oracle, "checker", batch)
    row = run_trial(oracle, name, 10.0, seed=2, k=5, keep_samples=True)
    assert row["ok"] and len(row["samples"]) == 5
    assert row["collision_checks"] == len(single) + batch.configurations > 0


def test_budget_is_bounded_and_reported(checkers):
    oracle = checkers("bar")
    sampler = make_sampler("rbbs", oracle, step=2, max_checks=500)
    before = oracle.checks
    with pytest.raises(SamplerBudgetExceeded, match="gave up after"):
        sampler.sample(30, np.random.default_rng(0))
    assert oracle.checks - before < 500 + 5000  # stops within one round of the budget


@settings(max_examples=6, deadline=None)
@given(
    step=st.floats(2.0, 20.0),
    seed=st.integers(0, 10_000),
    walkers=st.sampled_from([None, 1, 7, 64]),
    name=st.sampled_from(["rws", "lfs", "rwbs", "lfbs"]),
)
def test_walkers_free_in_bounds_for_any_step_and_pool(checkers, step, seed, walkers, name):
    oracle = checkers("bar")
    sampler = make_sampler(name, oracle, step=step, walkers=walkers)
    X = sampler.sample(3, np.random.default_rng(seed))
    _check_samples(oracle, X, 3)


def test_walk_length_is_bounded_and_counted(checkers):
    # One-step walks often do not end free: those are abandoned, and each abandonment is counted.
    sampler = make_sampler("rws", checkers("bar"), step=5, max_steps=1, walkers=32)
    sampler.sample(2, np.random.default_rng(0))
    assert sampler.stats["gave_up"] > 0


def test_proposals_never_leave_the_bounds(checkers):
    oracle = checkers("bar")
    sampler = make_sampler("lfs", oracle, step=20)
    sampler.stats = {"gave_up": 0}
    Q = oracle.space.uniform(np.random.default_rng(1), 500)
    Q[:, 0] = oracle.space.upper[0]  # on the edge: about half the steps leave the bounds at first
    P, ok = sampler._propose(np.random.default_rng(2), Q, sampler._draw)
    assert oracle.space.within_bounds(P[ok]).all() and ok.mean() > 0.95


def test_resumed_batches_carry_walkers_over_and_stay_reproducible(checkers):
    oracle = checkers("bar")

    def batches(resume):
        sampler, rng = make_sampler("lfbs", oracle, step=10), np.random.default_rng(4)
        before = oracle.checks
        out = np.concatenate([sampler.sample(10, rng, resume=resume) for _ in range(4)])
        return out, oracle.checks - before, sampler.stats

    resumed, resumed_checks, stats = batches(True)
    again, again_checks, _ = batches(True)
    fresh, fresh_checks, _ = batches(False)
    assert np.array_equal(resumed, again) and resumed_checks == again_checks
    assert len(resumed) == 40 and all(raw_free(oracle, q) for q in resumed)
    assert stats["checks"] < resumed_checks  # stats cover the last call alone
    assert resumed_checks < fresh_checks  # fresh calls abandon their unfinished walkers every time


def test_lfbs_puts_far_more_samples_in_the_bar_passage_than_uniform(checkers):
    oracle = checkers("bar")
    lfbs = make_sampler("lfbs", oracle, step=10).sample(60, np.random.default_rng(0))
    uniform = make_sampler("uniform", oracle).sample(1000, np.random.default_rng(0))
    assert oracle.workspace.in_passage(uniform).mean() < 0.02
    assert oracle.workspace.in_passage(lfbs).mean() >= 5 * max(oracle.workspace.in_passage(uniform).mean(), 0.01)


# ---- CLI ---------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "args",
    [
        ["--sampler", "levy"],
        ["--sampler", "lfbs", "-k", "0"],
        ["--sampler", "lfbs", "--step", "nan"],
    ],
)
def test_cli_bad_input_is_one_line_exit_2(cli, one_line_error, args):
    result = cli("sample", "bar", *args)
    one_line_error(result, 2)
    assert result.stdout == ""


def test_cli_json(tmp_path, cli):
    png = tmp_path / "s.png"
    result = cli("sample", "bar", "--sampler", "lfbs", "-k", "5", "--step", "10", "--seed", "4", "--json", "--png", png)
    assert result.returncode == 0, result.stderr
    out = json.loads(result.stdout)
    for key in (
        "scene",
        "sampler",
        "k",
        "step",
        "seed",
        "samples",
        "collision_checks",
        "seconds",
        "passage_fraction",
        "gave_up",
    ):
        assert key in out
    assert len(out["samples"]) == 5 and out["collision_checks"] > 0 and png.stat().st_size > 0


def test_the_density_reading_of_alpha_gives_tail_index_alpha_minus_one(checkers):
    oracle = checkers("bar-3link")
    for convention, expected in (("stability", 1.9), ("density", 0.9)):
        walker = make_sampler("lfs", oracle, step=10.0, angle_law="length", alpha_convention=convention)
        d = walker._draw(np.random.default_rng(0), 200_000)
        lengths = np.linalg.norm(d * oracle.space.weights, axis=1)  # a (1 + |L|): every coordinate on one line
        assert abs(hill_tail_index(lengths / 10.0 - 1.0) - expected) < 0.2


def test_each_angle_law_moves_the_angles_its_own_way(checkers):
    oracle = checkers("bar-3link")
    angles = oracle.space.angular

    def increments(law):
        walker = make_sampler("lfs", oracle, step=10.0, angle_law=law)
        return walker._draw(np.random.default_rng(1), 200_000)[:, angles]

    paper, length, gaussian = increments("paper"), increments("length"), increments("gaussian")
    # the paper's law maps a forward move into at most a full turn; the Lévy length alone has no such bound
    assert paper[paper > 0].max() <= 2 * np.pi < length.max()
    assert hill_tail_index(gaussian) > 4.0  # Gaussian tails


def test_the_bridge_fail_rule_decides_whether_a_walk_leaves_the_obstacle(checkers):
    oracle = checkers("bar-3link")
    starts = {}
    for rule in ("stay", "move"):
        walker = make_sampler("rwbs", oracle, step=10.0, bridge_fail=rule)
        walker.sample(60, np.random.default_rng(2))
        starts[rule] = oracle.are_free(walker.bridges[:, 0])
    assert not starts["stay"].any()  # the walk only ever stands on colliding configurations
    assert starts["move"].any()  # moved on to a free q' that failed the bridge test


def test_an_unknown_reading_is_bad_input(checkers):
    with pytest.raises(UserError, match="angle_law"):
        make_sampler("lfbs", checkers("bar-3link"), angle_law="sideways")
