"""Same seed, same plan -- in this process and in another -- and what every plan must be whatever its seed: from the
start to the goal, every edge free under an independent fine check, certified, and timed within the limits.

These hold through an honest change to the planner (a new sampling rule gives other paths, still reproducible and
still free), where comparing against recorded paths would not."""

import json

import numpy as np
import pytest

from app.checking.certify import certify_path
from app.planning.query import plan
from app.planning.settings import PlanSettings
from independent import fine_points, raw_free

CASES = [("bar", 0), ("maze", 1)]


@pytest.fixture(scope="module")
def planned(oracles):
    """Each case planned twice in this process."""
    return {case: [plan(oracles(case[0]), PlanSettings(seed=case[1])) for _ in range(2)] for case in CASES}


def _answer(result) -> dict:
    """What a plan decides: its paths, its cost in collision checks and its timed motion."""
    answer = result.to_json()
    return {key: answer[key] for key in ("roadmap_path", "path", "collision_checks", "trajectory")}


@pytest.mark.parametrize("case", CASES, ids=[f"{s}-seed{n}" for s, n in CASES])
def test_the_same_seed_gives_the_same_plan_here_and_in_a_child_process(planned, run_app, case):
    first, again = planned[case]
    assert first.certified and again.certified
    assert _answer(first) == _answer(again)
    scene, seed = case
    child = run_app("plan", scene, "--seed", seed, "--json")
    assert child.returncode == 0, child.stderr
    assert _answer(first) == {key: value for key, value in json.loads(child.stdout).items() if key in _answer(first)}


def test_another_seed_gives_another_plan(oracles, planned):
    other = plan(oracles("bar"), PlanSettings(seed=7))
    assert other.certified and _answer(other)["roadmap_path"] != _answer(planned[("bar", 0)][0])["roadmap_path"]


@pytest.mark.parametrize("case", CASES, ids=[f"{s}-seed{n}" for s, n in CASES])
def test_a_plan_is_free_certified_and_within_the_limits(oracles, planned, case):
    oracle = oracles(case[0])
    scene, result = oracle.scene, planned[case][0]
    path = np.array(result.path)
    assert np.array_equal(path[0], scene.start) and np.array_equal(path[-1], scene.goal)
    for a, b in zip(path[:-1], path[1:]):
        points = fine_points(oracle, np.array([a, b]), oracle.space.resolution / 4)
        assert all(raw_free(oracle, q) for q in points), f"edge {a} -> {b} collides"
    ok, stats = certify_path(oracle.context(), path)
    assert ok and stats["failed"] == []
    motion = result.trajectory
    assert motion.certified and np.all(np.diff(motion.times) > 0)
    assert np.allclose(motion.positions[0], oracle.space.unwrap(path)[0])
    assert np.allclose(oracle.space.wrap(motion.positions[-1]), scene.goal)
    assert np.all(np.abs(motion.velocities) <= scene.velocity_limits * (1 + 1e-6) + 1e-9)
    assert np.all(np.abs(motion.accelerations) <= scene.acceleration_limits * (1 + 1e-6) + 1e-9)
