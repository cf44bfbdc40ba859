"""The scripted UR3 jobs (`run welding|window`): IK goals, legs planned or straight, one joined trajectory."""

import json
from dataclasses import replace

import numpy as np
import pytest

from app.jobs import HOME, JOB_SETTINGS, run_job
from app.motion.path import FINE
from app.motion.timing import time_path
from independent import fine_points, raw_free


@pytest.fixture(scope="module")
def window_run(oracles):
    return run_job(oracles("window"), "window", JOB_SETTINGS)


def test_window_route_goes_through_the_window_and_back(oracles, window_run):
    oracle = oracles("window")
    legs = [(leg.start, leg.goal) for leg in window_run.legs]
    assert legs == [(HOME, "window"), ("window", "reach"), ("reach", "window"), ("window", "place"), ("place", HOME)]
    assert any(leg.method == "lfbs" for leg in window_run.legs)  # at least one leg needed the planner
    # In the hatch, no roadmap: the joint move to the part where it is free, else the tool's straight line (a joint
    # move between other postures there swings the forearm into the frame); out again the same way, reversed.
    joint_free = oracle.context().edges_free(window_run.configurations["window"], window_run.configurations["reach"])[0]
    assert [leg.method for leg in window_run.legs[1:3]] == ["straight" if joint_free else "tool line", "back"]
    assert np.array_equal(window_run.legs[2].path, window_run.legs[1].path[::-1])
    assert window_run.legs[2].collision_checks == 0
    for a, b in zip(window_run.legs[:-1], window_run.legs[1:]):  # legs meet where the previous one stopped
        assert oracle.space.distance(a.path[-1], b.path[0]) < 1e-9


def test_every_leg_is_free_under_an_independent_fine_check(oracles, window_run):
    oracle = oracles("window")
    for leg in window_run.legs:
        points = fine_points(oracle, leg.path, FINE * oracle.space.resolution)
        assert all(raw_free(oracle, q) for q in points), f"{leg.start} -> {leg.goal}"


def test_joined_trajectory_is_continuous_and_within_the_limits(oracles, window_run):
    scene = oracles("window").scene
    traj = window_run.trajectory
    t, X = traj.times, traj.positions
    assert np.all(np.diff(t) > 0) and abs(t[-1] - traj.duration) < 1e-9
    assert traj.duration == pytest.approx(sum(leg.duration for leg in window_run.legs))
    V = np.diff(X, axis=0) / np.diff(t)[:, None]
    assert np.all(np.abs(V) <= scene.velocity_limits * (1 + 1e-3) + 1e-6)  # no jump where legs join
    # Back home, the continuous wrist included: this job once ended a whole turn from where it began (smoothing
    # wound wrist 3 round; app.motion.path.unwind turns it back the short way).
    assert np.allclose(X[0], window_run.configurations[HOME]) and np.allclose(X[-1], X[0], atol=1e-9)


def test_the_robot_rests_at_the_jobs_poses_and_passes_through_the_hatch(oracles, window_run):
    """The scene marks the hatch pose `stop: false`: the joined motion goes through it without slowing to rest
    (blended and certified there), and rests at home, at the part and above the table."""
    oracle = oracles("window")
    run = run_job(oracle, "window", replace(JOB_SETTINGS, dt=0.001))  # sampled finely: speeds at the poses
    traj = run.trajectory
    assert traj.certified and oracle.scene.pass_through == {"window"}
    ends = np.cumsum([leg.duration for leg in run.legs])
    speed = np.abs(traj.velocities / oracle.scene.velocity_limits).max(axis=1)
    for leg, t in zip(run.legs, ends):
        at = speed[np.argmin(np.abs(traj.times - t))]  # within 0.5 ms: a stop's speed is then below 0.002
        assert (at > 0.05) if leg.goal == "window" else (at < 0.005), (leg.goal, at)
    # Legs joined through the hatch are timed only together; timed on its own, each would start and end at rest.
    assert [leg.trajectory is None for leg in run.legs] == [
        leg.goal in ("window", "reach", "place") for leg in run.legs
    ]


@pytest.fixture(scope="module")
def welding_run(oracles):
    return run_job(oracles("welding"), "welding", replace(JOB_SETTINGS, dt=0.001))


def test_the_welding_job_threads_the_hole_once_and_then_moves_straight(welding_run):
    """Only the way in, home to the torch lined up inside the cell, needs the roadmap: the 4 cm in to the seam and
    the 2 cm seam steps are joint moves, and the robot rests at each weld point."""
    methods = [(leg.start, leg.goal, leg.method) for leg in welding_run.legs]
    assert methods[0] == (HOME, "approach", "lfbs") and welding_run.legs[0].narrow_samples > 0
    assert [m for _, _, m in methods[1:]] == ["straight"] * 4
    assert [g for _, g, _ in methods[1:]] == ["seam_0", "seam_1", "seam_2", "seam_3"]
    assert all(leg.trajectory is not None for leg in welding_run.legs)


def test_passing_through_the_hatch_is_faster_than_stopping_there(oracles, window_run):
    """window's hatch is `stop: false`: the legs on either side timed as one curve take less time than the same legs
    from rest to rest."""
    alone = sum(time_path(oracles("window").context(), leg.path, 0.001).duration for leg in window_run.legs)
    assert window_run.trajectory.duration < 0.99 * alone


def test_same_seed_same_run(oracles, window_run):
    again = run_job(oracles("window"), "window", JOB_SETTINGS)
    assert np.array_equal(again.trajectory.positions, window_run.trajectory.positions)


def test_cli_run_prints_the_legs_and_rejects_an_unknown_job(tmp_path, cli, one_line_error):
    out = tmp_path / "welding.json"
    result = cli("run", "welding", "--json", "--out", out)
    assert result.returncode == 0, result.stderr
    doc = json.loads(result.stdout)
    assert doc["legs"][0]["from"] == HOME and len(doc["legs"]) >= 2
    assert doc["success"] is True
    assert json.loads(out.read_text())["time_from_start"] == doc["trajectory"]["time_from_start"]
    assert "unknown job 'parking'" in one_line_error(cli("run", "parking"), 2)
