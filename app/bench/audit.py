"""`bench audit`: random problems in every shipped scene, planned with the default planner under a short budget,
and every returned trajectory re-checked by a checker that shares nothing with the planner's.

The re-check (`Recheck`) builds its own Drake diagram from the scene file and asks SceneGraph directly: a state
collides if `HasCollisions` (FCL's boolean test, not the signed distances the certificate starts from) says so;
the deepest signed distance of a colliding state is its penetration. The states are the trajectory's samples,
planned every SAMPLE_PERIOD seconds, and between consecutive samples points of the quintic Hermite curve through
their positions, velocities and accelerations, no more than 1/64 of the scene's resolution apart (weighted metric).
That curve is the executed motion itself wherever the path and Toppra's s(t) are polynomial across the interval,
i.e. almost everywhere; across a break, where the acceleration jumps by J, it is off by about 1e-2 J h^2, a few
micrometres or microradians at h = SAMPLE_PERIOD. No shape is padded.
Start and goal must be met exactly, at rest, and velocities and accelerations stay within the scene's limits.
What a controller that interpolates linearly is given is re-checked too: the same answer timed at the planner's
default sample period (PlanSettings().dt, the same curve: timing is deterministic), and the straight lines between
its samples checked at the same spacing; and the path polyline (`path`, the waypoints), edge by edge.

Problems are trials of experiment "audit" in the results store (a killed run resumes); problem i of a scene draws
its start and goal, free and within bounds, from numpy's generator seeded with (seed, scene's index, i). Each plans
under a budget of collision checks, not seconds, so the same problem gets the same answer on any machine at any
load.

Stored roadmaps are audited the same way (experiment "audit-roadmap"): per scene a cell roadmap is built (seeded,
so every process builds the same one), saved, and read back as it is ("saved") or after every edge it found
colliding was rewritten in the file as free and proved ("tampered": the forgery an attacker would try; the
file's fingerprint kept). Problems drawn as above are planned on a fresh load of the file, every answer re-checked,
and the path's roadmap edges compared with the forged ones: a forged edge may steer the search, never an answer.

With it, the bad-input table (app.bench.bad_input.ROWS): each row run as `python -m app` in a fresh folder, with its
exit code, first stderr line, files written and seconds, and whether it behaved (`behaved`). Its rows are trials of
experiment "bad-input" in the same store.
"""

import atexit
import io
import math
import shutil
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
from tqdm import tqdm

from app.bench import bad_input
from app.bench.runner import sweep
from app.bench.store import ResultStore, Reuse, TrialSpec
from app.checking.budget import Budget
from app.errors import NoPath
from app.motion.timing import time_path
from app.planning.cell import BuildSettings, CellRoadmap
from app.planning.query import plan
from app.planning.settings import PlanSettings, default_step
from app.scene.model import Scene, scene_names

# The re-check looks at states this fraction of the scene's resolution apart.
DIVISOR = 64
# Trajectory sample period of the audited plans (s): fine enough that the quintic between samples is the motion
# (see the module doc), coarse enough that sampling a trajectory costs less than re-checking it.
SAMPLE_PERIOD = 0.004
# A sample over a velocity or acceleration limit by more than this fraction of it is a violation.
LIMIT_SLACK = 1e-6
# Start and goal must be met to this much (weighted metric).
ENDPOINT_TOLERANCE = 1e-9
# Tries at drawing a free start or goal before a problem is given up as undrawable.
DRAWS = 1000
# Collision checks a problem may spend (the default of --checks).
CHECKS = 100_000
# Nodes of the cell roadmap each scene's stored-roadmap problems are planned on (its build budget: BuildSettings').
ROADMAP_NODES = 500
# How a stored roadmap is read back for its problems.
ROADMAP_VARIANTS = ("saved", "tampered")
# A bad-input case must be answered within this many seconds (the "hang" is > 10 s before the first line);
# one still running after CASE_TIMEOUT is killed and counted as a hang.
ANSWER_SECONDS = 10.0
CASE_TIMEOUT = 60.0


class Recheck:
    """Collision answers for a scene from a diagram of its own (not the planner's oracle), under the scene's policy:
    robot against environment, and robot against robot where the scene counts self-collisions."""

    def __init__(self, scene_name: str):
        from pydrake.geometry import CollisionFilterDeclaration, GeometrySet

        self.scene = Scene(scene_name)
        self.plant = self.scene.plant
        self.root = self.scene.diagram.CreateDefaultContext()
        self.context = self.plant.GetMyContextFromRoot(self.root)
        robot = [
            g
            for instance in self.scene.robot_instances
            for body in self.plant.GetBodyIndices(instance)
            for g in self.plant.GetCollisionGeometriesForBody(self.plant.get_body(body))
        ]
        self.robot = set(robot)
        if not self.scene.self_collisions:
            scene_graph = self.scene.diagram.scene_graph()
            scene_graph.collision_filter_manager(scene_graph.GetMyMutableContextFromRoot(self.root)).Apply(
                CollisionFilterDeclaration().ExcludeWithin(GeometrySet(robot))
            )
        self.port = self.plant.get_geometry_query_input_port()

    def check(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(colliding, depth) per configuration of Q: FCL's boolean answer, and for a colliding state the deepest
        penetration among the counted pairs' signed distances (0 if they all come out >= 0)."""
        Q = np.atleast_2d(np.asarray(Q, float))
        colliding, depth = np.zeros(len(Q), bool), np.zeros(len(Q))
        for i, q in enumerate(Q):
            self.plant.SetPositions(self.context, q)
            query = self.port.Eval(self.context)
            if query.HasCollisions():
                colliding[i] = True
                pairs = query.ComputeSignedDistancePairwiseClosestPoints(0.0)
                depth[i] = max((-p.distance for p in pairs if p.id_A in self.robot or p.id_B in self.robot), default=0)
        return colliding, depth


def states(trajectory, weights: np.ndarray, spacing: float) -> np.ndarray:
    """The trajectory's samples and, between each two, points of the quintic Hermite curve through their positions,
    velocities and accelerations, no two consecutive ones more than `spacing` apart in the weighted metric."""
    t, P, V, A = trajectory.times, trajectory.positions, trajectory.velocities, trajectory.accelerations
    if len(t) < 2:
        return P.copy()
    h = np.diff(t)[:, None]
    # The quintic's speed is within a small factor of its end speeds and its chord; doubling is checked below.
    reach = np.maximum.reduce(
        [np.linalg.norm(np.diff(P, axis=0) * weights, axis=1)]
        + [np.linalg.norm(X * weights, axis=1) * h[:, 0] for X in (V[:-1], V[1:])]
    )
    counts = np.maximum(1, np.ceil(2 * reach / spacing)).astype(int)
    while True:
        out = [P[:1]]
        for i, n in enumerate(counts):
            tau = np.arange(1, n + 1)[:, None] / n
            out.append(_quintic(P[i], V[i], A[i], P[i + 1], V[i + 1], A[i + 1], h[i, 0], tau))
        pieces = out[1:]
        gaps = [
            np.linalg.norm(np.diff(np.vstack([P[i : i + 1], piece]), axis=0) * weights, axis=1).max()
            for i, piece in enumerate(pieces)
        ]
        wide = np.array(gaps) > spacing
        if not wide.any():
            return np.vstack(out)
        counts[wide] *= 2


def lines(P: np.ndarray, weights: np.ndarray, spacing: float) -> np.ndarray:
    """The rows of P and points of the straight lines between consecutive rows, no two consecutive ones more than
    `spacing` apart in the weighted metric."""
    P = np.atleast_2d(np.asarray(P, float))
    if len(P) < 2:
        return P.copy()
    counts = np.maximum(1, np.ceil(np.linalg.norm(np.diff(P, axis=0) * weights, axis=1) / spacing)).astype(int)
    out = [P[:1]] + [P[i] + np.arange(1, n + 1)[:, None] / n * (P[i + 1] - P[i]) for i, n in enumerate(counts)]
    return np.vstack(out)


def _quintic(p0, v0, a0, p1, v1, a1, h: float, tau: np.ndarray) -> np.ndarray:
    """Quintic Hermite interpolation on [0, h] at fractions tau (n, 1) of it."""
    t2, t3 = tau**2, tau**3
    t4, t5 = t3 * tau, t3 * t2
    h0 = 1 - 10 * t3 + 15 * t4 - 6 * t5
    h1 = tau - 6 * t3 + 8 * t4 - 3 * t5
    h2 = 0.5 * (t2 - 3 * t3 + 3 * t4 - t5)
    h3 = 0.5 * (t3 - 2 * t4 + t5)
    h4 = -4 * t3 + 7 * t4 - 3 * t5
    h5 = 10 * t3 - 15 * t4 + 6 * t5
    return h0 * p0 + h1 * h * v0 + h2 * h * h * a0 + h3 * h * h * a1 + h4 * h * v1 + h5 * p1


def audit_trajectory(recheck: Recheck, space, trajectory, start: np.ndarray, goal: np.ndarray, scene) -> dict:
    """The re-check of one trajectory: colliding states, deepest penetration, states checked, limit violations
    (samples over a velocity or acceleration limit by more than LIMIT_SLACK of it), the worst such fraction, and
    whether it starts at `start` and ends at `goal` at rest."""
    Q = states(trajectory, space.weights, space.resolution / DIVISOR)
    colliding, depth = recheck.check(Q)
    # Each sample's largest velocity or acceleration as a fraction of its limit.
    ratio = np.maximum(
        (np.abs(trajectory.velocities) / np.asarray(scene.velocity_limits, float)).max(axis=1),
        (np.abs(trajectory.accelerations) / np.asarray(scene.acceleration_limits, float)).max(axis=1),
    )

    def off(q, target) -> float:
        d = np.asarray(q, float) - target
        d[space.continuous] = (d[space.continuous] + np.pi) % (2 * np.pi) - np.pi
        return float(np.linalg.norm(d * space.weights))

    ends = max(off(trajectory.positions[0], start), off(trajectory.positions[-1], goal))
    at_rest = not (np.any(trajectory.velocities[0]) or np.any(trajectory.velocities[-1]))
    return {
        "states": len(Q),
        "colliding_states": int(colliding.sum()),
        "max_penetration": float(depth.max(initial=0.0)),
        "limit_violations": int(np.sum(ratio > 1 + LIMIT_SLACK)),
        "worst_limit_ratio": float(ratio.max(initial=0.0)),
        "endpoints_exact": bool(ends <= ENDPOINT_TOLERANCE and at_rest),
    }


_rechecks: dict = {}


def _recheck(scene: str) -> Recheck:
    if scene not in _rechecks:
        _rechecks[scene] = Recheck(scene)
    return _rechecks[scene]


def problem(oracle, seed: int, index: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Problem `index` of the oracle's scene: a free start and goal within bounds, or None if DRAWS tries found
    none (a scene almost all collision)."""
    scene_index = scene_names().index(oracle.scene.name)
    rng = np.random.default_rng([seed, scene_index, index])
    found = []
    for _ in range(math.ceil(DRAWS / 16)):
        Q = oracle.space.uniform(rng, 16)
        found.extend(Q[oracle.context().are_free(Q)])
        if len(found) >= 2:
            return found[0], found[1]
    return None


def run_trial_spec(oracle, spec: TrialSpec) -> dict:
    """One audit problem (experiment "audit", seed = problem index; params: base seed and the check budget)."""
    p = spec.params
    endpoints = problem(oracle, int(p["seed"]), spec.seed)
    if endpoints is None:
        return {"drawn": False, "solved": False}
    start, goal = endpoints
    settings = PlanSettings(seed=spec.seed, budget=Budget(checks=int(p["checks"])), dt=SAMPLE_PERIOD, step=spec.step)
    clock = time.perf_counter()
    try:
        result = plan(oracle, settings, start=start, goal=goal)
    except NoPath as failure:
        return {
            "drawn": True,
            "solved": False,
            "seconds": time.perf_counter() - clock,
            "checks": getattr(failure, "details", {}).get("collision_checks"),
        }
    seconds = time.perf_counter() - clock
    trajectory = result.trajectory
    recheck = _recheck(spec.scene)
    check = audit_trajectory(recheck, oracle.space, trajectory, start, goal, oracle.scene)
    return {
        "drawn": True,
        "solved": True,
        "certified": bool(trajectory.certified),
        "seconds": seconds,
        "checks": result.collision_checks,
        "duration": trajectory.duration,
        **check,
        **audit_lines(recheck, oracle, result),
    }


# ---- stored roadmaps ------------------------------------------------------------------------------------------------
_stored: dict = {}
_folder: list[Path] = []


def stored_roadmap(oracle, seed: int, nodes: int, variant: str) -> tuple[Path, set]:
    """The file of the scene's cell roadmap (built once per process: seeded, the same in every process) as `variant`
    (ROADMAP_VARIANTS), and the forged edges' ends as pairs of configurations (bytes; none for "saved")."""
    key = (oracle.scene.name, seed, nodes)
    if key not in _stored:
        if not _folder:
            _folder.append(Path(tempfile.mkdtemp(prefix="npp-audit-")))
            atexit.register(shutil.rmtree, _folder[0], True)
        saved = _folder[0] / f"{oracle.scene.name}-{seed}-{nodes}.npz"
        CellRoadmap.build(oracle, BuildSettings(nodes=nodes, seed=seed)).save(saved)
        with np.load(saved, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
        # Every edge the build found colliding, rewritten as decided free and proved.
        dead = ~arrays["alive"]
        Q, ends = arrays["Q"], arrays["ends"][dead]
        forged = {frozenset((Q[a].tobytes(), Q[b].tobytes())) for a, b in ends.tolist()}
        for flag in ("alive", "checked", "proved"):
            arrays[flag] = arrays[flag] | dead
        buffer = io.BytesIO()
        np.savez_compressed(buffer, **arrays)
        tampered = saved.with_name(saved.stem + "-tampered.npz")
        tampered.write_bytes(buffer.getvalue())
        _stored[key] = {"saved": (saved, set()), "tampered": (tampered, forged)}
    return _stored[key][variant]


def run_roadmap_trial_spec(oracle, spec: TrialSpec) -> dict:
    """One stored-roadmap audit problem (experiment "audit-roadmap", method: the variant, seed: problem index;
    params: base seed, check budget, roadmap nodes): planned on a fresh load of the file, re-checked as
    run_trial_spec's, with the forged edges its roadmap path used (must be 0)."""
    p = spec.params
    endpoints = problem(oracle, int(p["seed"]), spec.seed)
    if endpoints is None:
        return {"drawn": False, "solved": False}
    start, goal = endpoints
    path, forged = stored_roadmap(oracle, int(p["seed"]), int(p["nodes"]), spec.method)
    settings = PlanSettings(seed=spec.seed, budget=Budget(checks=int(p["checks"])), dt=SAMPLE_PERIOD, step=spec.step)
    clock = time.perf_counter()
    try:
        result = CellRoadmap.load(path, oracle).solve(start, goal, settings)
    except NoPath as failure:
        return {"drawn": True, "solved": False, "checks": getattr(failure, "details", {}).get("collision_checks")}
    seconds = time.perf_counter() - clock
    raw = result.roadmap_path
    used = sum(frozenset((a.tobytes(), b.tobytes())) in forged for a, b in zip(raw[:-1], raw[1:]))
    recheck = _recheck(spec.scene)
    return {
        "drawn": True,
        "solved": True,
        "certified": bool(result.trajectory.certified),
        "seconds": seconds,
        "checks": result.collision_checks,
        "forged_edges": len(forged),
        "forged_edges_on_path": int(used),
        **audit_trajectory(recheck, oracle.space, result.trajectory, start, goal, oracle.scene),
        **audit_lines(recheck, oracle, result),
    }


def roadmap_specs(scenes: list[str], problems: int, seed: int, checks: int, nodes: int) -> list[TrialSpec]:
    """`problems` in all over the scenes and ROADMAP_VARIANTS, in turn as `specs` shares them."""
    steps = {scene: default_step(Scene(scene)) for scene in scenes}
    params = {"seed": seed, "checks": checks, "nodes": nodes}
    turns = [(scene, variant) for scene in scenes for variant in ROADMAP_VARIANTS]
    order = [(i, *turn) for i in range(math.ceil(problems / len(turns))) for turn in turns][:problems]
    return [TrialSpec("audit-roadmap", scene, variant, steps[scene], i, params) for i, scene, variant in order]


def audit_lines(recheck: Recheck, oracle, result) -> dict:
    """What a controller that interpolates linearly follows, re-checked: the straight lines between the samples of
    the answer timed at the default sample period, and the path polyline; states checked and colliding states of
    each, at 1/DIVISOR of the resolution."""
    settings = PlanSettings()
    controller = time_path(
        oracle.context(),
        result.path,
        settings.dt,
        proof=result.blends,
        edges_proved=result.blends is None,
        clearance=result.certificate.clearance,
    )
    space, spacing = oracle.space, oracle.space.resolution / DIVISOR
    out = {}
    for name, P in (("sample_lines", controller.positions), ("polyline", space.unwrap(result.path))):
        Q = lines(P, space.weights, spacing)
        colliding, _ = recheck.check(Q)
        out[f"{name}_states"], out[f"colliding_{name}_states"] = len(Q), int(colliding.sum())
    return out


def specs(scenes: list[str], problems: int, seed: int, checks: int) -> list[TrialSpec]:
    """`problems` in all, shared out over the scenes as evenly as can be, taking the scenes in turn (so a run cut
    short has audited every scene alike); each may spend `checks` collision checks."""
    steps = {scene: default_step(Scene(scene)) for scene in scenes}
    params = {"seed": seed, "checks": checks}
    order = [(i, scene) for i in range(math.ceil(problems / len(scenes))) for scene in scenes][:problems]
    return [TrialSpec("audit", scene, "default", steps[scene], i, params) for i, scene in order]


def summarise(rows: list[dict], scenes: list[str], label=lambda row: row["scene"]) -> list[dict]:
    """One row per scene (in `scenes` order; or per other `label` of a stored row) and a total row: problems,
    solved, certified, colliding trajectories, colliding states, deepest penetration, limit violations, inexact
    endpoints, states checked (and of stored roadmaps, the forged edges their paths used)."""
    table = []
    for scene in [*scenes, "total"]:
        metrics = [r["metrics"] for r in rows if scene in ("total", label(r))]
        solved = [m for m in metrics if m["solved"]]
        table.append(
            {
                "scene": scene,
                "problems": len(metrics),
                "undrawable": sum(not m["drawn"] for m in metrics),
                "solved": len(solved),
                "certified": sum(m["certified"] for m in solved),
                "colliding_trajectories": sum(m["colliding_states"] > 0 for m in solved),
                "colliding_states": sum(m["colliding_states"] for m in solved),
                "max_penetration": max((m["max_penetration"] for m in solved), default=0.0),
                "limit_violations": sum(m["limit_violations"] for m in solved),
                # None if no row has it (rows stored before the audit measured it).
                "worst_limit_ratio": max(
                    (m["worst_limit_ratio"] for m in solved if "worst_limit_ratio" in m), default=None
                ),
                "inexact_endpoints": sum(not m["endpoints_exact"] for m in solved),
                # None unless every row has them (rows stored before the audit checked them do not).
                **{
                    key: sum(m[key] for m in solved) if solved and all(key in m for m in solved) else None
                    for key in (
                        "sample_lines_states",
                        "colliding_sample_lines_states",
                        "polyline_states",
                        "colliding_polyline_states",
                    )
                },
                "states_checked": sum(m["states"] for m in solved),
                **(
                    {
                        # Every problem of a roadmap file sees all its forged edges: a file's count once.
                        "forged_edges": sum(
                            max(r["metrics"].get("forged_edges", 0) for r in rows if label(r) == name)
                            for name in {label(r) for r in rows if scene in ("total", label(r))}
                        ),
                        "forged_edges_on_paths": sum(m["forged_edges_on_path"] for m in solved),
                    }
                    if solved and all("forged_edges_on_path" in m for m in solved)
                    else {}
                ),
                "median_seconds": float(np.median([m["seconds"] for m in solved])) if solved else None,
            }
        )
    return table


def measure(
    scenes: list[str], problems: int, seed: int, checks: int, store, workers: int = 1, fresh: bool = False
) -> tuple[list[dict], Reuse]:
    """Run the audit problems `store` has no reusable row for and summarise all of them (see `summarise`); and what
    was reused."""
    rows, reuse = sweep(specs(scenes, problems, seed, checks), store, workers=workers, desc="bench audit", fresh=fresh)
    return summarise(rows, scenes), reuse


def measure_roadmaps(
    scenes: list[str],
    problems: int,
    seed: int,
    checks: int,
    store,
    nodes: int = ROADMAP_NODES,
    workers: int = 1,
    fresh: bool = False,
) -> tuple[list[dict], Reuse]:
    """The stored-roadmap problems as `measure` runs the others: one row per scene and variant ("window saved",
    "window tampered", ...) and a total."""
    todo = roadmap_specs(scenes, problems, seed, checks, nodes)
    rows, reuse = sweep(todo, store, workers=workers, desc="bench audit: stored roadmaps", fresh=fresh)
    labels = [f"{scene} {variant}" for scene in scenes for variant in ROADMAP_VARIANTS]
    return summarise(rows, labels, label=lambda row: f"{row['scene']} {row['method']}"), reuse


# ---- the bad-input table ------------------------------------------------------------------------------------------
def bad_input_specs(rows=bad_input.ROWS) -> list[TrialSpec]:
    """One trial of experiment "bad-input" per row of the table: what it runs and what it must answer."""
    return [
        TrialSpec("bad-input", "-", " ".join(argv), 0.0, 0, {"argv": argv, "exit_code": code, "fragment": fragment})
        for argv, code, fragment in rows
    ]


def behaved(case: dict, expected: dict) -> bool:
    """A case behaved: the expected exit code, one line on stderr holding the expected fragment, no traceback, an
    answer within ANSWER_SECONDS, nothing written."""
    return (
        case["exit_code"] == expected["exit_code"]
        and case["stderr_lines"] == 1
        and expected["fragment"] in case["first_line"]
        and not case["traceback"]
        and case["seconds"] <= ANSWER_SECONDS
        and not case["written"]
    )


def measure_bad_input(store, workers: int = 1, fresh: bool = False, rows=bad_input.ROWS) -> tuple[list[dict], Reuse]:
    """Run the table's cases `store` has no reusable row for (`workers` at a time, each its own process), and every
    case's answer: command, expected and actual exit code, first stderr line, files written, seconds, behaved."""
    cases = bad_input_specs(rows)
    results = ResultStore(store)
    try:
        reuse = results.reuse(cases, fresh=fresh)
        pending = results.pending(cases, fresh=fresh)
        if pending:
            with (
                ThreadPoolExecutor(max_workers=workers) as pool,
                tqdm(total=len(pending), desc="bad input", unit="case", dynamic_ncols=True) as progress,
            ):
                runs = pool.map(lambda spec: (spec, bad_input.run_case(spec.params["argv"], CASE_TIMEOUT)), pending)
                for spec, case in runs:
                    results.add(spec, case)
                    progress.update()
        order = {spec.method: i for i, spec in enumerate(cases)}
        stored = sorted(results.rows_for(cases), key=lambda r: order[r["method"]])
    finally:
        results.close()
    table = [
        {
            "command": r["method"],
            "expected_exit_code": r["params"]["exit_code"],
            **r["metrics"],
            "behaved": behaved(r["metrics"], r["params"]),
        }
        for r in stored
    ]
    return table, reuse


def bad_input_counts(table: list[dict]) -> dict:
    """The table's totals: cases, behaved, tracebacks, hangs (killed after CASE_TIMEOUT), slow answers (over
    ANSWER_SECONDS), wrong exit codes, cases that wrote files."""
    return {
        "cases": len(table),
        "behaved": sum(c["behaved"] for c in table),
        "tracebacks": sum(c["traceback"] for c in table),
        "hangs": sum(c["exit_code"] is None for c in table),
        "slow": sum(c["seconds"] > ANSWER_SECONDS for c in table),
        "wrong_exit_code": sum(c["exit_code"] != c["expected_exit_code"] for c in table),
        "wrote_files": sum(bool(c["written"]) for c in table),
    }
