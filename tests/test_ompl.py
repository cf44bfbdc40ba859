"""OMPL on our oracle (app/ompl_bridge.py) and `bench ompl` (app/bench/ompl.py): OMPL's Gaussian and bridge-test
samplers as re-implemented, our samplers behind OMPL's interface, OMPL's PRM, RRTConnect and BIT* solving bar-3link
through our oracle, the motion-check rule, and the benchmark's summary and ratio.

OMPL's RNG takes one seed per process (the first OmplProblem sets it), so these tests check properties that hold
for any draw, not particular states. nanobind may print leak warnings when the interpreter exits: harmless.
"""

import json

import numpy as np
import pytest

from independent import raw_free

try:
    import ompl  # noqa: F401
except ImportError as exc:  # pragma: no cover - depends on the machine
    pytest.skip(f"OMPL is not installed ({exc}); pip install '.[ompl]'", allow_module_level=True)

from app.bench.ompl import PROTOCOL, best_ompl, compare, parse_method, run_trial_spec, summarise
from app.bench.store import TrialSpec
from app.errors import UserError
from app.ompl_bridge import (
    BridgeTestSampler,
    GaussianSampler,
    OmplProblem,
    OmplSpace,
    ProjectSampler,
    motion_check_steps,
    motion_spacing,
)
from app.planning.settings import default_step
from app.scene.cspace import ConfigurationSpace
from app.scene.model import Scene

SCENE = "bar-3link"
# OMPL's planners stop on time, not on checks. The tests that need a solution give them this long: they return at
# their first solution (the problem's cost threshold is infinite), in well under a second here, so only a hang
# comes near it and the verdict does not depend on the machine's load.
HANG_GUARD = 120.0  # seconds


@pytest.fixture
def problem(oracles):
    return OmplProblem(oracles(SCENE), seed=0)


def _draw(sampler, problem, n, tries=400):
    """Up to n states from an OMPL ValidStateSampler (each sample() call makes at most 100 attempts)."""
    out = []
    state = problem.space.allocState()
    for _ in range(tries):
        if sampler.sample(state):
            out.append((problem.to_q(state), problem.to_q(sampler.a), problem.to_q(sampler.b)))
            if len(out) == n:
                break
    return out


def test_gaussian_sampler_returns_valid_states_next_to_invalid_ones(problem):
    oracle = problem.oracle.context()
    sampler = GaussianSampler(problem.si, None)
    drawn = _draw(sampler, problem, 10)
    assert len(drawn) == 10
    states = np.array([q for q, _, _ in drawn])
    assert oracle.are_free(states).all()
    # the returned state is one of the pair and the other one is in collision
    for q, a, b in drawn:
        other = b if np.allclose(q, a) else a
        assert np.allclose(q, a) or np.allclose(q, b)
        assert not oracle.is_free(other)


def test_bridge_test_sampler_returns_valid_midpoints_of_invalid_endpoints(problem):
    oracle = problem.oracle.context()
    sampler = BridgeTestSampler(problem.si, None)
    drawn = _draw(sampler, problem, 5)
    assert len(drawn) >= 3, "the bridge test found too few samples on bar-3link"
    space = oracle.space
    for q, a, b in drawn:
        assert oracle.is_free(q)
        assert not oracle.is_free(a) and not oracle.is_free(b)
        # the midpoint of OMPL's motion, which takes the short way round on the angles (SO2 subspaces)
        assert space.distance(q, a + space.difference(a, b) / 2) < 1e-9


def test_our_sampler_feeds_ompls_prm_only_free_states(problem, monkeypatch):
    handed = []
    original = ProjectSampler.sample

    def recording(self, state):
        ok = original(self, state)
        if ok:
            handed.append(self.problem.to_q(state))
        return ok

    monkeypatch.setattr(ProjectSampler, "sample", recording)
    problem.use_sampler("lfbs", step=default_step(problem.oracle.scene))
    problem.solve(HANG_GUARD)  # until its first solution: the states it drew are there whatever the load
    assert problem._samplers and all(isinstance(s, ProjectSampler) for s in problem._samplers)
    assert handed, "OMPL's PRM drew no state from the lfbs adapter"
    assert problem.oracle.context().are_free(np.array(handed)).all()


@pytest.mark.parametrize("name", ["lfbs", "ompl-uniform"])
def test_each_sampler_drives_ompls_prm_on_bar_3link(oracles, name):
    """Each sampler drives OMPL's PRM, and a path it finds runs from start to goal through free states. LFBS must
    solve, with a path free at a quarter of the resolution. OMPL's uniform sampler need not: it takes from under a
    second to minutes, depending on OMPL's per-process draw, so it is given 5 s and only what it did is checked
    (the start's validity check and the sampler's allocation come before PRM looks at the time), and OMPL checks
    motions only at its own resolution (`bench ompl` holds its paths to ours)."""
    oracle = oracles(SCENE)
    problem = OmplProblem(oracle, seed=0)
    problem.use_sampler(name, **({"step": default_step(oracle.scene)} if name == "lfbs" else {}))
    solved = problem.solve(HANG_GUARD if name == "lfbs" else 5.0)
    expected = ProjectSampler if name == "lfbs" else problem.ob.UniformValidStateSampler
    assert problem._samplers and all(type(s) is expected for s in problem._samplers)
    assert problem.checker.checks > 0
    assert solved or name != "lfbs", f"OMPL's PRM with lfbs did not solve {SCENE} in {HANG_GUARD:g} s"
    if solved:
        path = problem.solution_for_oracle()
        assert np.allclose(path[0], oracle.scene.start, atol=1e-6)
        assert np.allclose(path[-1], oracle.scene.goal, atol=1e-6)
        assert all(raw_free(oracle, q) for q in problem.solution())
    if name == "lfbs":
        # OMPL interpolates continuous angles linearly; solution_for_oracle adds waypoints so our edges follow suit
        assert oracle.context().edges_free(path[:-1], path[1:], oracle.space.resolution / 4).all()


def test_straight_waypoints_make_short_way_edges_follow_ompls_linear_motion(oracles):
    from app.ompl_bridge import straight_waypoints

    oracle = oracles(SCENE)
    a = np.array([20.0, 80.0, -3.0, 0.0, 0.0])
    b = np.array([30.0, 80.0, 3.0, 0.0, 0.0])  # linear: 6 rad the long way; the short way is 0.28 rad
    dense = straight_waypoints(oracle, np.array([a, b]))
    assert np.allclose(dense[0], a) and np.allclose(dense[-1], b) and len(dense) > 2
    steps = np.diff(dense, axis=0)
    assert np.allclose([oracle.space.difference(p, q) for p, q in zip(dense[:-1], dense[1:])], steps)


def test_the_problem_counts_ompls_validity_calls(problem):
    checker = problem.checker
    state = problem.space.allocState()
    sampler = problem.si.allocStateSampler()
    for _ in range(25):
        sampler.sampleUniform(state)
        problem.si.isValid(state)
    assert checker.checks == 25
    problem.use_sampler("ompl-uniform")
    problem.solve(0.5)
    assert checker.checks > 25


def test_bench_ompl_ends_without_ompls_leak_report(tmp_path, run_app):
    """`python -m app` ends right after a command that loaded OMPL, so its answer is the last thing printed (not
    nanobind's report of objects alive at interpreter shutdown)."""
    result = run_app(
        "bench",
        "ompl",
        "--scenes",
        SCENE,
        "--methods",
        "ompl:RRTConnect",
        "--seeds",
        "1",
        "--budget",
        "5",
        "--store",
        tmp_path / "ompl.sqlite",
        "--png",
        tmp_path / "ompl.png",
        "--json",
    )
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    scene = report["scenes"][0]
    assert scene["scene"] == SCENE and scene["methods"][0]["runs"] == 1
    assert scene["motion_checks"][0]["space"] == "compound"
    assert (tmp_path / "ompl.png").stat().st_size > 0
    assert "leak" not in result.stderr


def test_rrtconnect_through_the_oracle_counts_checks_and_returns_a_fine_checked_path(oracles, monkeypatch):
    oracle = oracles(SCENE)
    spec = TrialSpec(
        "ompl", SCENE, "ompl:RRTConnect", default_step(oracle.scene), 0, {"budget": HANG_GUARD, "protocol": PROTOCOL}
    )
    answered = []  # configurations Drake answered, counted at the oracle's three entry points
    single, batch, edges = oracle.free, oracle.free_batch, oracle.first_hits

    def first_hits(*args):
        passed, checked = edges(*args)
        answered.append(checked)
        return passed, checked

    monkeypatch.setattr(oracle, "free", lambda q: answered.append(1) or single(q))
    monkeypatch.setattr(oracle, "free_batch", lambda Q: answered.append(len(Q)) or batch(Q))
    monkeypatch.setattr(oracle, "first_hits", first_hits)
    m = run_trial_spec(oracle, spec)
    assert m["success"] == 1.0 and m["space"] == "compound", m
    # every check OMPL asked for went through the oracle: first solution + smoothing + our verification
    assert m["checks"] > 0 and m["smoothing_checks"] > 0
    assert sum(answered) == m["checks"] + m["smoothing_checks"] + m["verify_checks"]
    assert m["fine_check_passed"] == 1.0 and m["path_length"] <= m["raw_length"] + 1e-9


def test_bitstar_in_the_real_vector_space_solves_bar_3link_with_a_fine_checked_path(oracles):
    oracle = oracles(SCENE)
    problem = OmplProblem(oracle, seed=0, planner="BITstar")
    assert not problem.map.compound  # BIT*'s informed sampler refuses compound spaces
    assert problem.solve(HANG_GUARD), "BIT* found no path on bar-3link"
    assert problem.checker.checks > 0
    path = problem.solution_for_oracle()
    assert np.allclose(path[0], oracle.scene.start) and np.allclose(path[-1], oracle.scene.goal)
    assert oracle.context().edges_free(path[:-1], path[1:], oracle.space.resolution / 4).all()


def test_motion_checks_are_never_coarser_than_the_resolution():
    steps = motion_check_steps([141.4, 12 * np.pi, 8 * np.pi], 0.5)
    assert np.isclose(np.sum(steps**2), 0.25)
    for scene in (SCENE, "maze"):
        cspace = ConfigurationSpace.of(Scene(scene))
        for wrap in (True, False):
            m = motion_spacing(cspace, wrap_angles=wrap, edges=100)
            assert m["space"] == ("compound" if wrap else "real-vector")
            assert m["max_spacing_over_resolution"] <= 1 + 1e-9, m
            assert 1.0 <= m["checks_over_exact_median"] < 2.0, m


def test_the_subspace_steps_survive_omplss_set_up(oracles):
    oracle = oracles(SCENE)
    problem = OmplProblem(oracle, seed=0, planner="RRTConnect")
    problem.setup.setup()
    space = problem.map
    assert space.compound and len(space.angles) == 3
    assert np.allclose(space.segment_lengths(), motion_check_steps(space.extents, oracle.space.resolution))


def test_states_convert_both_ways_with_angles_wrapped():
    cspace = ConfigurationSpace.of(Scene(SCENE))
    q = np.array([20.0, 80.0, 3.5, -0.25, 7.0])
    for wrap in (True, False):
        space = OmplSpace(cspace, wrap_angles=wrap)
        back = space.q(space.state(q))
        assert np.allclose(back, cspace.wrap(q)) and cspace.distance(back, q) < 1e-9


def test_a_state_on_the_bounds_comes_back_inside_them():
    """The weighted scaling's rounding must not put a configuration at a joint limit outside it (our checker would
    call it invalid: RRTConnect once skipped such a goal and spun until its time ran out)."""
    weights = np.random.default_rng(0).uniform(0.05, 1.0, 6)  # (with these, the old conversion stepped out)
    dim = len(weights)
    cspace = ConfigurationSpace(
        lower=np.full(dim, -np.pi), upper=np.full(dim, np.pi), weights=weights, angular=np.ones(dim, bool),
        continuous=np.zeros(dim, bool), resolution=0.01,
    )  # fmt: skip
    for wrap in (True, False):
        space = OmplSpace(cspace, wrap_angles=wrap)
        for bound in (cspace.lower, cspace.upper):
            back = space.q(space.state(bound))
            assert np.all(back >= cspace.lower) and np.all(back <= cspace.upper)
            assert cspace.distance(back, bound) < 1e-9


def test_method_names():
    assert parse_method("ours:default") == {"ours": True, "sampler": "lfbs", "full": False, "alone": False}
    assert parse_method("ours:full") == {"ours": True, "sampler": "lfbs", "full": True, "alone": False}
    assert parse_method("ours:rbbs:full") == {"ours": True, "sampler": "rbbs", "full": True, "alone": False}
    assert parse_method("ours:lfbs:alone") == {"ours": True, "sampler": "lfbs", "full": False, "alone": True}
    assert parse_method("ompl:BITstar") == {"ours": False, "planner": "BITstar", "sampler": None}
    assert parse_method("ompl:PRM+ompl-bridge")["sampler"] == "ompl-bridge"
    for bad in ("ompl:RRTstarish", "ompl:RRTConnect+lfbs", "ours:nope", "ompl-uniform", "ours", "ours:lfbs:full:alone"):
        with pytest.raises(UserError):
            parse_method(bad)


def _row(scene, method, success, checks, seconds=1.0, smoothing=100, length=10.0):
    m = {
        "solved": 1.0 if success else 0.0,
        "success": 1.0 if success else 0.0,
        "checks": checks,
        "seconds": seconds,
        "late": 0.0,
    }
    if success:
        m.update(smoothing_checks=smoothing, path_length=length, fine_check_passed=1.0)
    return {"scene": scene, "method": method, "metrics": m}


def test_summary_and_ratio_on_synthetic_rows():
    from scipy.stats import binomtest

    rows = (
        [_row("s", "ours:default", True, c) for c in (100, 200, 300)]
        + [_row("s", "ours:default", False, 9999)]
        + [_row("s", "ompl:RRTConnect", True, c) for c in (400, 500)]
        + [_row("s", "ompl:RRTConnect", False, 1)] * 2
        + [_row("s", "ompl:PRM", True, c) for c in (1000, 2000)]
        + [_row("s", "ompl:PRM", False, 1)] * 2
        + [_row("s", "ompl:KPIECE1", False, 5)] * 4
    )
    table = {r["method"]: r for r in summarise(rows)}
    ours = table["ours:default"]
    assert ours["runs"] == 4 and ours["successes"] == 3 and ours["success_rate"] == 0.75
    ci = binomtest(3, 4).proportion_ci()
    assert ours["success_ci"] == pytest.approx([ci.low, ci.high])
    assert ours["median_checks"] == 200  # successful runs only
    assert ours["checks_spent"] == 250  # all runs
    assert table["ompl:KPIECE1"]["median_checks"] is None
    # RRTConnect and PRM tie on successes; RRTConnect needs fewer checks
    assert best_ompl(list(table.values()))["method"] == "ompl:RRTConnect"
    c = compare(list(table.values()))
    assert c["best_ompl"] == "ompl:RRTConnect" and c["checks_ratio"] == pytest.approx(200 / 450)
    # more successes win over fewer checks
    rows += [_row("s", "ompl:BITstar", True, 50000)] * 3
    c = compare(summarise(rows))
    assert c["best_ompl"] == "ompl:BITstar" and c["checks_ratio"] == pytest.approx(200 / 50000)
    # no OMPL success: no ratio
    c = compare(summarise([r for r in rows if r["method"] in ("ours:default", "ompl:KPIECE1")]))
    assert c["best_ompl"] == "ompl:KPIECE1" and c["checks_ratio"] is None
