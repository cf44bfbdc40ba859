"""OMPL on our oracle (app/ompl_bridge.py): OMPL's Gaussian and bridge-test samplers as re-implemented, our
samplers behind OMPL's interface, and OMPL's PRM solving bar-3link on a short budget.

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

from app.ompl_bridge import BridgeTestSampler, GaussianSampler, OmplProblem, ProjectSampler
from app.planner import default_step

SCENE = "bar-3link"
BUDGET = 5.0  # seconds, at most, per OMPL solve


@pytest.fixture
def problem(oracles):
    oracle = oracles(SCENE)
    oracle.reset()
    return OmplProblem(oracle, seed=0)


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
    oracle = problem.oracle
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
    oracle = problem.oracle
    sampler = BridgeTestSampler(problem.si, None)
    drawn = _draw(sampler, problem, 5)
    assert len(drawn) >= 3, "the bridge test found too few samples on bar-3link"
    for q, a, b in drawn:
        assert oracle.is_free(q)
        assert not oracle.is_free(a) and not oracle.is_free(b)
        assert np.allclose(q, (a + b) / 2, atol=1e-9)


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
    problem.solve(1.0)
    assert problem._samplers and all(isinstance(s, ProjectSampler) for s in problem._samplers)
    assert handed, "OMPL's PRM drew no state from the lfbs adapter"
    assert problem.oracle.are_free(np.array(handed)).all()


@pytest.mark.parametrize("name", ["lfbs", "ompl-uniform"])
def test_each_sampler_drives_ompls_prm_on_bar_3link(oracles, name):
    """Each sampler drives OMPL's PRM, and a path it finds runs from start to goal through free states. LFBS must
    solve within the budget, with a path free at a quarter of the resolution. OMPL's uniform sampler need not: it
    takes from under a second to more than the budget, depending on OMPL's per-process draw, and OMPL checks motions
    only at its own resolution (`bench ompl` holds its paths to ours)."""
    oracle = oracles(SCENE)
    oracle.reset()
    problem = OmplProblem(oracle, seed=0)
    problem.use_sampler(name, **({"step": default_step(oracle.scene)} if name == "lfbs" else {}))
    solved = problem.solve(BUDGET)
    expected = ProjectSampler if name == "lfbs" else problem.ob.UniformValidStateSampler
    assert problem._samplers and all(type(s) is expected for s in problem._samplers)
    assert oracle.checks > 0
    assert solved or name != "lfbs", f"OMPL's PRM with lfbs did not solve {SCENE} in {BUDGET:g} s"
    if solved:
        path = problem.solution_for_oracle()
        assert np.allclose(path[0], oracle.scene.start, atol=1e-6)
        assert np.allclose(path[-1], oracle.scene.goal, atol=1e-6)
        assert all(raw_free(oracle, q) for q in problem.solution())
    if name == "lfbs":
        # OMPL interpolates continuous angles linearly; solution_for_oracle adds waypoints so our edges follow suit
        assert oracle.edges_free(path[:-1], path[1:], oracle.space.resolution / 4).all()


def test_straight_waypoints_make_short_way_edges_follow_ompls_linear_motion(oracles):
    from app.ompl_bridge import straight_waypoints

    oracle = oracles(SCENE)
    a = np.array([20.0, 80.0, -3.0, 0.0, 0.0])
    b = np.array([30.0, 80.0, 3.0, 0.0, 0.0])  # linear: 6 rad the long way; the short way is 0.28 rad
    dense = straight_waypoints(oracle, np.array([a, b]))
    assert np.allclose(dense[0], a) and np.allclose(dense[-1], b) and len(dense) > 2
    steps = np.diff(dense, axis=0)
    assert np.allclose([oracle.space.difference(p, q) for p, q in zip(dense[:-1], dense[1:])], steps)


def test_the_oracle_counts_ompls_validity_calls(problem):
    oracle = problem.oracle
    oracle.reset()
    state = problem.space.allocState()
    sampler = problem.si.allocStateSampler()
    for _ in range(25):
        sampler.sampleUniform(state)
        problem.si.isValid(state)
    assert oracle.checks == 25
    problem.use_sampler("ompl-uniform")
    problem.solve(0.5)
    assert oracle.checks > 25


def test_bench_ompl_ends_without_ompls_leak_report(tmp_path, run_app):
    """`python -m app` ends right after a command that loaded OMPL, so its answer is the last thing printed (not
    nanobind's report of objects alive at interpreter shutdown)."""
    result = run_app("bench", "ompl", "--scenes", SCENE, "--methods", "ompl-uniform", "--seeds", "1", "--budget", "1",
                     "--store", tmp_path / "ompl.sqlite", "--json")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["ompl"][0]["runs"] == 1
    assert "leak" not in result.stderr
