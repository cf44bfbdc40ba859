"""Smooth time parameterization (app.motion.timing.parameterize_smooth): corners blended and certified, Toppra along the
curve. Checked independently of what Toppra reports: limits from finite differences of the positions, collisions
of samples no more than 1/64 of the resolution apart by SceneGraph directly, start and goal exact, no velocity
jumps; and it is faster than stopping at every waypoint."""

import json
from pathlib import Path

import numpy as np
import pytest

import app
from app.motion.timing import parameterize, parameterize_smooth
from independent import raw_free

PINNED = json.loads((Path(__file__).parent / "data" / "pinned_plans.json").read_text())


def _zigzag(start, step, wiggle, n) -> np.ndarray:
    """n short segments advancing by `step` and alternating by +-`wiggle` (mild corners, a stop costs most)."""
    k = np.arange(n + 1)[:, None]
    return np.asarray(start, float) + k * np.asarray(step, float) + (k % 2) * np.asarray(wiggle, float)


# Polylines in free space: the quadrotor in the maze's open south-east room, the planar arm's base beside the wall.
ZIGZAGS = {
    "maze": _zigzag([14.5, 2.0, 1.5, 0.0], [0.4, 0.0, 0.0, 0.05], [0.0, 0.2, 0.1, 0.0], 9),
    "bar": _zigzag(
        [12.0, 80.0, -1.5708, 0, 0, 0, 0, 0, 0], [2.0, 0, 0, 0, 0, 0, 0, 0.05, 0], [0, 1.0, 0.05, 0, 0, 0, 0, 0, 0], 9
    ),
}


def _times(oracle, W, **kw):
    scene = oracle.scene
    stats = {}
    smooth = parameterize_smooth(
        oracle, W, scene.velocity_limits, scene.acceleration_limits, joint_names=oracle.space.names, stats=stats, **kw
    )
    rest = parameterize(oracle.oracle.plant, W, scene.velocity_limits, scene.acceleration_limits)
    return smooth, rest, stats


def _check_motion(oracle, trajectory, W):
    """Limits (finite differences), no velocity jumps, start and goal exact and at rest."""
    scene, X, t = oracle.scene, trajectory.positions, trajectory.times
    v, a = scene.velocity_limits, scene.acceleration_limits
    V = np.diff(X, axis=0) / np.diff(t)[:, None]
    assert np.all(np.abs(V) <= v * 1.01 + 1e-9)
    # Samples come every dt, with more where straight lines between them would leave the curve (and at stops).
    h = np.diff(t)
    even = np.flatnonzero(np.isclose(h[:-1], h[1:]))  # two equal intervals in a row
    A = (X[even + 2] - 2 * X[even + 1] + X[even]) / h[even, None] ** 2
    assert len(even) and np.all(np.abs(A) <= a * 1.01 + 1e-9)
    # The reported velocities are within the limits, and are the motion's own (continuous, no jumps).
    assert np.all(np.abs(trajectory.velocities) <= v * (1 + 1e-6) + 1e-9)
    assert np.all(np.abs(trajectory.accelerations) <= a * (1 + 1e-6) + 1e-9)
    assert np.all(np.abs(np.diff(trajectory.velocities, axis=0)) <= a * h[:, None] * 1.01 + 1e-9)
    assert np.allclose(0.5 * (trajectory.velocities[1:] + trajectory.velocities[:-1]), V, atol=a.max() * h.max())
    assert np.array_equal(X[0], W[0]) and np.array_equal(X[-1], W[-1])
    assert np.allclose(trajectory.velocities[[0, -1]], 0, atol=1e-9)


def _check_free(oracle, W, **kw):
    """The smooth motion sampled so densely that consecutive samples are at most 1/64 of the resolution apart
    (weighted metric) is free under SceneGraph's own answer."""
    space, scene = oracle.space, oracle.scene
    coarse = parameterize_smooth(oracle, W, scene.velocity_limits, scene.acceleration_limits, **kw)
    speed = np.linalg.norm(coarse.velocities * space.weights, axis=1).max()
    fine = parameterize_smooth(
        oracle, W, scene.velocity_limits, scene.acceleration_limits, dt=space.resolution / 64 / speed / 1.5, **kw
    )
    assert np.allclose(fine.duration, coarse.duration)
    assert space.distance(fine.positions[:-1], fine.positions[1:]).max() <= space.resolution / 64
    assert all(raw_free(oracle, q) for q in space.wrap(fine.positions))


@pytest.mark.parametrize("name", list(ZIGZAGS))
def test_a_zigzag_in_free_space_is_smooth_certified_and_free(checkers, name):
    oracle = checkers(name)
    W = ZIGZAGS[name]
    smooth, _, stats = _times(oracle, W)
    assert smooth.certified and stats["stops"] == 0 and stats["distance_queries"] > 0
    _check_motion(oracle, smooth, W)
    _check_free(oracle, W)


def test_stopping_at_every_corner_is_slower_where_segments_are_short(checkers):
    ratios = []
    for name, W in ZIGZAGS.items():
        smooth, rest, _ = _times(checkers(name), W)
        ratios.append(smooth.duration / rest.duration)
    assert np.median(ratios) <= 0.6


@pytest.mark.parametrize("key", list(PINNED))
def test_planned_paths_are_timed_smoothly_within_limits(checkers, key):
    oracle = checkers(key.split()[0])
    W = oracle.space.unwrap(np.array(PINNED[key]["path"]))
    smooth, rest, stats = _times(oracle, W)
    assert smooth.certified and stats["stops"] == 0
    # On these long segments a stop costs v/a per corner only: faster, but not by as much as on the zigzags.
    assert smooth.duration < 0.9 * rest.duration
    _check_motion(oracle, smooth, W)
    # It passes every waypoint in order, and its waypoint times are when it is nearest them.
    assert np.all(np.diff(smooth.waypoint_times) > 0) and smooth.waypoint_times[-1] == pytest.approx(smooth.duration)


def test_a_planned_window_path(checkers):
    from app.planning.ik import solve_pose

    oracle = checkers("window")
    # Home to the torch through the hatch, the job's first leg (the scene's goal, deep inside, is a harder query
    # than a test of timing should wait for).
    goal = solve_pose(oracle.oracle, "window", np.random.default_rng(0))
    result = app.plan(oracle.oracle, app.PlanSettings(seed=1, budget=app.Budget(checks=200_000)), goal=goal)
    W = oracle.space.unwrap(result.path)
    smooth, rest, _ = _times(oracle, W)
    assert smooth.duration < 0.8 * rest.duration
    _check_motion(oracle, smooth, W)
    if smooth.certified:
        _check_free(oracle, W)


def test_a_corner_toppra_cannot_time_becomes_a_stop(checkers):
    """Drake's Toppra finds no solution where a blend is tiny (seen: a window path with a corner 2e-5 from the next,
    left by a partial shortcut); such corners become stops instead of failing the query."""
    oracle = checkers("window")
    steps = [[0.3, 0, 0, 0, 0, 0], [0, 0, 0, 0, 1e-4, 0], [0, 0.2, 0, 0, 0, 0]]
    W = np.cumsum(np.vstack([oracle.scene.start, steps]), axis=0)
    smooth, _, stats = _times(oracle, W)
    assert smooth.certified and stats["stops"] >= 1
    _check_motion(oracle, smooth, W)


def _round_the_pillar(clearance: float) -> np.ndarray:
    """The quadrotor along the bottom face of maze pillar_1, then up its right face, `clearance` from both: a
    wide blend of the corner between would cut into the pillar's corner."""
    low, right = 9.0 - 0.35 - clearance, 5.1 + 0.35 + clearance
    return np.array([[3.0, low, 1.5, 0.0], [right, low, 1.5, 0.0], [right, 11.5, 1.5, 0.0]])


def test_a_blend_that_would_hit_an_obstacle_is_tightened(checkers):
    oracle = checkers("maze")
    W = _round_the_pillar(0.01)
    smooth, rest, stats = _times(oracle, W)
    assert smooth.certified and stats["rounds"] > 1 and stats["stops"] == 0
    assert smooth.duration < rest.duration
    _check_free(oracle, W)


def test_a_blend_that_cannot_be_tightened_becomes_a_stop(checkers):
    oracle = checkers("maze")
    W = _round_the_pillar(0.01)
    smooth, rest, stats = _times(oracle, W, tighten=0)
    assert smooth.certified and stats["stops"] == 1
    corner = np.argmin(np.abs(smooth.times - smooth.waypoint_times[1]))
    assert np.allclose(smooth.positions[corner], W[1], atol=1e-3)
    assert np.abs(smooth.velocities[corner]).max() < 0.1  # at rest there (within a sample)
    assert smooth.duration == pytest.approx(rest.duration, rel=0.01)  # one corner, one stop: rest to rest
    _check_motion(oracle, smooth, W)
    _check_free(oracle, W, tighten=0)


def test_a_path_that_cannot_be_certified_is_timed_but_not_certified(checkers):
    oracle = checkers("maze")
    W = _round_the_pillar(-1e-3)  # the straight legs themselves touch the pillar
    smooth, _, _ = _times(oracle, W)
    assert not smooth.certified and smooth.duration > 0


def test_a_corner_the_blend_cuts_off_is_proved_too_the_polyline_is_part_of_the_answer(checkers):
    """A corner inside pillar_1 is refused although a wide blend would pass the pillar: the waypoints' polyline is
    returned beside the trajectory, and a controller may follow it. Round the pillar 1 cm off, the corner the blend
    cuts off is proved (it may come nearer than the blend, not nearer than half the clearance)."""
    from app.checking.certify import Certifier, certify_path
    from app.motion.timing import prove_blends

    oracle = checkers("maze")
    W = np.array([[3.0, 7.5, 1.5, 0.0], [4.9, 8.8, 1.5, 0.0], [3.0, 10.0, 1.5, 0.0]])
    assert not raw_free(oracle, W[1]) and not certify_path(oracle, W)[0]
    assert prove_blends(Certifier(oracle), W).failed
    W = _round_the_pillar(0.01)
    proof = prove_blends(Certifier(oracle), W, clearance=0.004)
    assert not proof.failed and proof.radii[1] > 0 and proof.clearance == 0.004
    smooth, _, stats = _times(oracle, W, proof=proof)
    assert smooth.certified and smooth.clearance == 0.004 and stats["distance_queries"] == 0  # nothing proved again
    _check_motion(oracle, smooth, W)
    corner = np.linspace(W[1] - proof.radii[1] * (W[1] - W[0]) / np.linalg.norm(W[1] - W[0]), W[1], 64)
    assert min(oracle.diagnostics.clearance(q, 1.0) for q in corner) >= 0.002


def test_straight_lines_between_the_samples_keep_half_the_clearance(checkers):
    """A controller that interpolates linearly between the samples cuts the blends' curves; the samples are placed
    so that those straight lines keep half the clearance the curve keeps (checked at 16 points per line with
    Drake's own distances), with more samples where the curve bends than the sample period alone gives (every
    half second, lines between them would cut into the pillar by centimetres)."""
    oracle = checkers("maze")
    W, scene = _round_the_pillar(0.0045), oracle.scene
    wide = parameterize_smooth(oracle, W, scene.velocity_limits, scene.acceleration_limits, dt=0.5, clearance=0.004)
    assert wide.certified and wide.clearance == 0.004
    off_grid = [t for t in wide.times[:-1] if not np.isclose(t / 0.5, round(t / 0.5))]
    assert off_grid and np.isclose(np.diff(wide.times).max(), 0.5)  # samples added, only where needed
    X = wide.positions
    lines = X[:-1, None, :] + np.linspace(0, 1, 16)[None, :, None] * (X[1:] - X[:-1])[:, None, :]
    assert min(oracle.diagnostics.clearance(q, 1.0) for q in lines.reshape(-1, X.shape[1])) >= 0.002 * (1 - 1e-6)


def test_a_straight_part_that_cannot_be_proved_names_its_edge_of_the_path(checkers):
    """Where the straight legs themselves touch the pillar the proof fails on them, by their index in the path
    given (a repeated waypoint is an edge of no length, skipped but counted), and reversing a proof reverses it."""
    from app.checking.certify import Certifier
    from app.motion.timing import prove_blends

    oracle = checkers("maze")
    W = _round_the_pillar(-1e-3)
    failed = prove_blends(Certifier(oracle), W).failed
    assert failed and set(failed) <= {0, 1}
    repeated = prove_blends(Certifier(oracle), W[[0, 0, 1, 2]])
    assert repeated.failed == [i + 1 for i in failed]
    assert repeated.reversed().failed == sorted(2 - i for i in repeated.failed)


def test_one_waypoint_is_a_motionless_trajectory(checkers):
    oracle = checkers("maze")
    q = oracle.scene.start
    smooth, _, _ = _times(oracle, np.array([q, q]))
    assert smooth.duration == 0 and np.array_equal(smooth.positions, [q])


def test_edges_already_proved_are_not_certified_again(checkers):
    """Told that the polyline's edges are proved (as the planner's certificate does), the timing certifies only the
    blends: the same motion, certified, for fewer distance queries."""
    from app.checking.certify import certify_path

    oracle = checkers("maze")
    W, scene = ZIGZAGS["maze"], oracle.scene
    assert certify_path(oracle, W)[0]
    every, blends = {}, {}
    whole = parameterize_smooth(oracle, W, scene.velocity_limits, scene.acceleration_limits, stats=every)
    only = parameterize_smooth(
        oracle, W, scene.velocity_limits, scene.acceleration_limits, stats=blends, edges_proved=True
    )
    assert whole.certified and only.certified and only.duration == pytest.approx(whole.duration)
    assert 0 < blends["distance_queries"] < every["distance_queries"]


def test_a_toppra_solution_holding_nans_is_not_used(checkers, monkeypatch):
    """Drake's Toppra has returned s(t) full of NaNs (a tunnel path in `bench audit`); evaluating the path there
    aborts the whole process. Such a solution counts as none: the next grid is tried."""
    import pydrake.multibody.optimization as optimization
    from pydrake.trajectories import PiecewisePolynomial

    calls = []

    class FirstAnswerNan(optimization.Toppra):
        def SolvePathParameterization(self):
            calls.append(1)
            if len(calls) == 1:
                return PiecewisePolynomial.FirstOrderHold([0.0, 1.0], np.full((1, 2), np.nan))
            return super().SolvePathParameterization()

    monkeypatch.setattr(optimization, "Toppra", FirstAnswerNan)
    oracle = checkers("maze")
    W = ZIGZAGS["maze"]
    smooth, _, _ = _times(oracle, W)
    assert len(calls) > 1 and np.all(np.isfinite(smooth.positions))
    _check_motion(oracle, smooth, W)


def test_scaling_slows_the_motion_within_the_scaled_limits(checkers):
    from app.motion.timing import time_path

    oracle = checkers("bar")
    W = ZIGZAGS["bar"]
    full = time_path(oracle, W, 0.01, edges_proved=True)
    half = time_path(oracle, W, 0.01, edges_proved=True, velocity_scale=0.5, acceleration_scale=0.25)
    v, a = oracle.scene.velocity_limits, oracle.scene.acceleration_limits
    assert np.all(np.abs(half.velocities) <= 0.5 * v * (1 + 1e-6) + 1e-9)
    assert np.all(np.abs(half.accelerations) <= 0.25 * a * (1 + 1e-6) + 1e-9)
    assert np.max(np.abs(full.velocities) / v) > 0.5 or np.max(np.abs(full.accelerations) / a) > 0.25
    # Half the speed and a quarter of the acceleration is the same motion at half the pace (time-optimal both).
    assert half.duration == pytest.approx(2 * full.duration, rel=0.05)
    assert np.array_equal(half.positions[[0, -1]], full.positions[[0, -1]])


@pytest.mark.parametrize("scale", [0.0, 1.5, float("nan")])
def test_a_scale_outside_zero_to_one_is_refused(oracles, scale):
    from app.errors import UserError
    from app.motion.timing import time_path

    with pytest.raises(UserError, match="velocity_scale must be a fraction in"):
        time_path(oracles("bar").context(), ZIGZAGS["bar"], 0.01, velocity_scale=scale)


def test_a_blended_curves_variation_is_each_coordinates_travel():
    """Over a blend and over parts of it (where a coordinate's rate turns through zero, and where it does not),
    `variation` is each coordinate's travel along the curve, summed finely, to rounding: never less (the
    certificate's bound rests on it) and not the larger bound of its greatest rate times the length."""
    from app.motion.blends import _Curve, first_radii, legs_between_stops
    from app.motion.timing import _prepare

    W = np.array([[0.0, 0.0], [1.0, 0.2], [0.4, 1.0], [1.3, 1.4]])
    W, _, _, tangent, arc = _prepare(W, np.ones(2), np.ones(2), np.ones(2))
    curve = _Curve(legs_between_stops(W, tangent, arc, first_radii(np.diff(arc))))
    blends = [(s0, s1) for leg in curve.legs for s0, s1, corner in leg.pieces if corner is not None]
    assert blends
    looser = 0
    for s0, s1 in blends + [(a + 0.3 * (b - a), a + 0.6 * (b - a)) for a, b in blends]:
        s = np.linspace(s0, s1, 20001)
        travel = np.abs(np.diff(curve.position(s), axis=0)).sum(axis=0)
        bound = curve.variation(np.array([s0]), np.array([s1]))[0]
        assert np.all(bound >= travel * (1 - 1e-9))
        assert np.allclose(bound, travel, rtol=1e-6, atol=1e-12)
        x = np.array([s0, s1 - 1e-9])
        rates = np.abs(curve.variation(x, x + 1e-9) / 1e-9).max(axis=0)
        looser += np.any(rates * (s1 - s0) > bound * 1.01)
    assert looser  # the travel is tighter than the old bound somewhere


def test_the_time_at_a_path_parameter_is_where_toppras_s_of_t_reaches_it():
    """times_at inverts Toppra's s(t) (piecewise quadratic) in closed form: at the times it gives, s(t) is the asked s
    to rounding, all along a blended leg, and the times rise with s from the leg's start."""
    from app.motion.blends import first_radii, legs_between_stops
    from app.motion.leg_timing import _sliders, _toppra, times_at
    from app.motion.timing import _prepare

    W = np.array([[0.0, 0.0], [1.0, 0.2], [0.4, 1.0], [1.3, 1.4]])
    W, v, a, tangent, arc = _prepare(W, np.ones(2), np.ones(2), np.ones(2))
    (leg,) = legs_between_stops(W, tangent, arc, first_radii(np.diff(arc)))
    s_of_t = _toppra(_sliders(2), leg, v, a)
    s = np.linspace(0.0, arc[-1], 301)
    t = times_at(s_of_t, s)
    assert t[0] == 0.0 and np.all(np.diff(t) > 0) and t[-1] <= s_of_t.end_time()
    assert np.allclose(s_of_t.vector_values(t).ravel(), s, rtol=0, atol=1e-12 * arc[-1])


def test_a_grid_point_rounded_past_the_legs_end_is_not_toppras_last():
    """A leg whose last break, recomputed as s0 + (s1 - s0), rounds one bit past the path's end (numbers from a
    MotionBenchMaker Panda problem, where Drake's Toppra then refused the grid and planning failed): the grid ends
    exactly where the path does, and Toppra times the leg."""
    from pydrake.trajectories import PiecewisePolynomial

    from app.motion.blends import Leg
    from app.motion.leg_timing import _grid, _sliders, _toppra

    middle, end = 3.58661499371691, 7.807026541280375
    assert middle + (end - middle) != end  # the rounding this test is about
    path = PiecewisePolynomial.FirstOrderHold([0.0, middle, end], np.array([[0.0, middle, end], [0.0, 0.0, 0.0]]))
    leg = Leg(0, 2, 0.0, path, [(0.0, middle, None), (middle, end, None)])
    for on_breaks in (True, False):
        grid = _grid(leg, 16, on_breaks)
        assert grid[0] == 0.0 and grid[-1] == end and np.all(np.diff(grid) > 0)
    s_of_t = _toppra(_sliders(2), leg, np.ones(2), np.ones(2))
    assert np.isclose(s_of_t.vector_values([s_of_t.end_time()])[0, 0], end)


def test_lines_the_curves_margins_cover_are_proved_without_asking_and_keep_half_the_clearance(checkers):
    """The curve's proof keeps what each of its pieces keeps from everything (its margin); a line between two
    samples whose distance from the curve moves no pair more than that margin less half the clearance is proved
    with no distance asked. Round the pillar with the planner's clearance: the lines are asked for nothing with the
    margins, for distances without them, and keep half the clearance either way (Drake's distances, 16 points a
    line)."""
    import dataclasses

    from app.checking.certify import Certifier
    from app.motion.timing import prove_blends

    oracle = checkers("maze")
    W, scene = _round_the_pillar(0.02), oracle.scene
    proof = prove_blends(Certifier(oracle), W)
    assert not proof.failed and proof.margins is not None
    asked = {}
    for margins in (proof.margins, None):
        stats = {}
        timed = parameterize_smooth(
            oracle,
            W,
            scene.velocity_limits,
            scene.acceleration_limits,
            stats=stats,
            proof=dataclasses.replace(proof, margins=margins),
        )
        assert timed.certified
        asked[margins is None] = stats["distance_queries"]
        X = timed.positions
        lines = X[:-1, None, :] + np.linspace(0, 1, 16)[None, :, None] * (X[1:] - X[:-1])[:, None, :]
        half = proof.clearance / 2
        assert min(oracle.diagnostics.clearance(q, 1.0) for q in lines.reshape(-1, X.shape[1])) >= half * (1 - 1e-6)
    assert asked[False] == 0 < asked[True]
    assert proof.reversed().margins is None  # placed by arc length, which the reversed path adds up anew


def test_the_edges_a_curves_proof_covers_whole_count_as_proved_and_are_not_proved_again(checkers):
    """Round the pillar: the curve's proof proves the straight parts at the clearance and the corners the blends
    cut off at half of it, with margins; where those pieces cover an edge of the path whole, each keeping the
    clearance, the edge counts as proved (Drake's distances, 64 points an edge, agree), and a later proof of the same
    curve with those edges known proves fewer pieces and blends no less."""
    from app.checking.certify import Certifier
    from app.motion.timing import prove_blends

    oracle = checkers("maze")
    W = _round_the_pillar(0.02)
    first = prove_blends(Certifier(oracle), W)
    assert not first.failed and first.whole
    for i in first.whole:
        edge = W[i] + np.linspace(0, 1, 64)[:, None] * (W[i + 1] - W[i])
        assert min(oracle.diagnostics.clearance(q, 1.0) for q in edge) >= first.clearance
    again = prove_blends(Certifier(oracle), W, known=first.whole)
    assert not again.failed and not set(again.whole) & set(first.whole)
    assert again.cost["pieces"] < first.cost["pieces"] and np.all(again.radii >= first.radii)
    assert first.reversed().whole == tuple(sorted(len(W) - 2 - i for i in first.whole))


def test_a_curves_margins_cover_a_span_only_where_its_pieces_meet():
    from app.motion.blends import Margins

    margins = Margins()
    rows = np.array([[0.0, 1.0, 3.0], [1.0, 2.0, 2.0], [2.5, 3.0, 5.0]])  # a gap from 2 to 2.5
    a, b = np.array([0.2, 0.5, 1.5, 2.6, 0.0]), np.array([0.8, 1.5, 2.6, 2.9, 3.0])
    assert margins.least(rows, a, b).tolist() == [3.0, 2.0, -np.inf, 5.0, -np.inf]
    assert margins.least(rows[:0], a, b).tolist() == [-np.inf] * 5


def test_a_corner_whose_own_distances_prove_no_blend_becomes_a_stop_at_its_second_failure(checkers, monkeypatch):
    """At its second failure a corner's blend is weighed against the corner's own distances: round the pillar 1 cm
    off, they prove a blend clear (Drake's distances along it and the corner it cuts off keep twice the clearance)
    at a radius well above the last halving's, so halving goes on; where they prove none, the corner is a stop at
    once, certified, for fewer rounds."""
    import app.motion.blends as blends
    from app.checking.certify import CLEARANCE
    from app.motion.blends import path_geometry

    oracle = checkers("maze")
    W = _round_the_pillar(0.01)
    asked, weighed = [], blends._BlendRounds.safe_radius

    def spy(self, i, radius):
        asked.append((i, radius, weighed(self, i, radius)))
        return asked[-1][2]

    monkeypatch.setattr(blends._BlendRounds, "safe_radius", spy)
    smooth, _, halved = _times(oracle, W)
    assert smooth.certified and halved["stops"] == 0 and halved["rounds"] > blends.STOP_TEST
    [(i, radius, safe)] = asked
    assert radius / 2.0 ** (blends.TIGHTEN - blends.STOP_TEST) < safe < radius
    _, tangent, _, _ = path_geometry(W, oracle.space.weights)
    u = np.linspace(0, 1, 64)[:, None]
    before, after = W[i] - safe * tangent[i - 1], W[i] + safe * tangent[i]
    curve = (1 - u) ** 2 * before + 2 * u * (1 - u) * W[i] + u**2 * after
    cut_off = np.vstack([W[i] + u * (before - W[i]), W[i] + u * (after - W[i])])
    assert min(oracle.diagnostics.clearance(q, 1.0) for q in np.vstack([curve, cut_off])) >= 2 * CLEARANCE * (1 - 1e-6)
    monkeypatch.setattr(blends._BlendRounds, "safe_radius", lambda self, i, radius: 0.0)
    stopped, _, stats = _times(oracle, W)
    assert stopped.certified and stats["stops"] == 1 and stats["rounds"] == blends.STOP_TEST + 1 < halved["rounds"]
