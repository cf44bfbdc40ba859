"""`bench queries`: many queries in one cell, answered by fresh single queries, by one persistent cell roadmap, by
OMPL's multi-query PRM and by OMPL's RRTConnect, all through the same collision oracle.

The query set (`make_queries`), deterministic from the seed, is made once per scene and every method answers it:
- a scene with a tool frame and named poses (the UR3 cells window, welding) is a work cell's sequence of tool poses:
  query i goes from where the robot is -- home (the scene's start) for the first, then the goal the method reached
  in query i-1, or that query's start when it failed: a cell's robot waits where it is -- to a tool pose, alternately
  one in the hard region -- a named pose of the scene (the hatch, the part behind it, the weld seam) moved by up to
  HARD_SHIFT and turned by up to HARD_TURN -- and one outside it: the tool pose of a random free configuration.
  Its goal is every distinct IK solution found for the pose (`app.planning.ik.distinct_solutions`), any of which
  will do. A hard pose is kept only if the arm reaches it in the posture the scene's job uses for the named pose
  (IK from that posture, `solve_poses`): moved and turned, a seam can leave the arm only postures wedged among the
  obstacles, from which no method found a way out (bench pages, "Many queries in one cell"). A fixed start per query
  (the previous query's first goal) chained such a posture, or a posture beyond an obstacle the robot never reached,
  into the next query, which then no method could answer either.
- any other scene: independent random free start/goal pairs (uniform samples the oracle finds free).

Methods (`METHODS`), on a per-query budget (`--budget`: a CHECK budget, so ours are machine-independent; OMPL only
stops on time, so its planners get `ompl_seconds` per query):
- fresh: `app.plan` per query (a new roadmap each time);
- cell: one `CellRoadmap.build` (its seconds, checks, nodes and edges reported apart), then `cell.solve` per query
  in order, the roadmap keeping what each query learned; in a chained set, each query also answered fresh from the
  start the roadmap's own answers left it at, outside its seconds, so that every query has its fresh counterpart;
- ompl-prm: one OMPL PRM whose graph is kept across queries (`OmplProblem.set_query`: `clearQuery()`, new start and
  goal states). Its build is `PRM.growRoadmap` for as many seconds as the cell's build took in this run (so
  `cell` must be among the methods); after that, its own queries grow it further (PRM's solve keeps sampling);
- ompl-rrtconnect: a fresh RRTConnect per query.
An answer of ours is smoothed, certified and time-parameterised within the query's time. OMPL's is smoothed
(`simplifySolution`, inside the query's time) but neither certified nor time-parameterised: its certified share is
0 by construction, not by a failed proof. Each query's checks are its own (a QueryContext, or the OMPL problem's
checker counted before and after); a path's start and end are compared with the query's start and goals
(`from_start`, `reached`) so that a row shows which query it answered.

One stored trial (`app.bench.store`) per scene and method holds all its queries: a killed run resumes at the next
method. A trial's key holds a digest of its query set, so trials of other queries are never mixed in.
"""

from __future__ import annotations

import hashlib
import math
import os
import re
import time
from dataclasses import dataclass
from functools import partial

import numpy as np
from tqdm import tqdm

from app.bench.store import ResultStore, Reuse, TrialSpec
from app.checking.budget import Budget
from app.errors import NoPath, SamplerBudgetExceeded, UserError
from app.planning.query import plan
from app.planning.settings import PlanSettings, default_step
from app.samplers import make_sampler

# app.planning.cell and app.ompl_bridge (which loads OMPL, optional) are imported by the methods that use them.

METHODS = ("fresh", "cell", "ompl-prm", "ompl-rrtconnect")
EXPERIMENT, PROTOCOL = "queries", "query-set+answers"
# The hard region of a UR3 cell: a named pose moved this far (m, per axis) and turned this much (rad) at most; in the
# held-out mix, further.
HARD_SHIFT, HARD_TURN = 0.02, math.radians(10.0)
HELD_OUT_SHIFT, HELD_OUT_TURN = 0.03, math.radians(15.0)
MIXES = ("own", "held-out")
# Free configurations (the random pairs, the outside poses) are the uniform sampler's, a fixed batch a round, so that
# a query set does not depend on the yield seen so far; at most FREE_ROUNDS rounds.
FREE_BATCH, FREE_ROUNDS = 256, 1000
# Tool poses tried per query before the query set gives up (a moved named pose may have no free IK solution).
POSE_ATTEMPTS = 50
# How near (scene metric) a path's end must be to a goal to count as reaching it.
REACHED = 1e-6
# The goals for the total time of the queries, and for any one query's checks over its fresh counterpart's.
GOALS = {"cell vs fresh": 0.1, "cell vs ompl-prm": 0.5, "query vs fresh": 1.1}


@dataclass
class QuerySet:
    """The queries of one scene: goals (each (k, dim): any will do), whether each is in the hard region, how they
    were made (`kind`), and their starts: every query's (n, dim), or when `chained` the first query's only (1, dim),
    each later query starting where the method left the robot (`start`)."""

    kind: str
    starts: np.ndarray
    goals: list
    hard: np.ndarray
    chained: bool = False

    def __len__(self) -> int:
        return len(self.goals)

    def start(self, i: int, robot) -> np.ndarray:
        """Query i's start, `robot` being where the method left the robot after query i-1."""
        return robot if self.chained and i > 0 else self.starts[i]

    def digest(self) -> str:
        """A hash of the queries (to 1e-9): what a stored trial's key holds."""
        h = hashlib.sha256(self.kind.encode())
        h.update(np.round(self.starts, 9).tobytes())
        for goals in self.goals:
            h.update(np.round(goals, 9).tobytes())
        return h.hexdigest()[:16]

    def to_json(self) -> dict:
        return {
            "kind": self.kind,
            "count": len(self),
            "hard": int(self.hard.sum()),
            "digest": self.digest(),
            "chained": self.chained,
            "queries": [
                {
                    "start": self.starts[i].tolist() if i < len(self.starts) else None,
                    "goals": g.tolist(),
                    "hard": bool(h),
                }
                for i, (g, h) in enumerate(zip(self.goals, self.hard))
            ],
        }


def answer_all(queries: QuerySet, answer, progress) -> list[dict]:
    """answer(i, start, goals) -> dict for every query in order, each starting where `queries.start` says: where the
    previous answer left the robot (the goal it reached; its start when it failed). Each answer records its start."""
    answers, robot = [], None
    for i, goals in enumerate(queries.goals):
        start = queries.start(i, robot)
        a = answer(i, start, goals)
        a["start"] = np.asarray(start, float).tolist()
        robot = goals[a["reached"]] if a["success"] and a["reached"] is not None else start
        answers.append(a)
        progress()
    return answers


def make_queries(oracle, n: int, seed: int, progress=None, mix: str = "own") -> QuerySet:
    """`n` queries in the oracle's cell (see the module docstring), the same for the same seed; `mix` "held-out" in
    a UR3 cell: `_held_out_queries`. progress(), if given, is called once per query made."""
    rng = np.random.default_rng(seed)
    scene = oracle.scene
    progress = progress or (lambda: None)
    if scene.tool_frame is not None and scene.poses:
        make = _held_out_queries if mix == "held-out" else _tool_queries
        return make(oracle, n, rng, progress)
    free = _free_configurations(oracle, 2 * n, rng)
    for _ in range(n):
        progress()
    return QuerySet("random free start/goal pairs", free[0::2], [g[None] for g in free[1::2]], np.zeros(n, bool))


def _free_configurations(oracle, n: int, rng) -> np.ndarray:
    """n free configurations uniform in the bounds: the uniform sampler, FREE_BATCH candidates a round."""
    sampler = make_sampler("uniform", oracle.context(), batch=FREE_BATCH, max_rounds=FREE_ROUNDS)
    try:
        return sampler.sample(n, rng)
    except SamplerBudgetExceeded:
        raise UserError(
            f"scene {oracle.scene.name}: fewer than {n} free configurations in {FREE_ROUNDS * FREE_BATCH} samples"
        ) from None


def _moved_pose(oracle, rng, shift: float, turn: float):
    """A named pose of the scene, chosen at random, moved by up to `shift` per axis and turned by up to `turn` about
    a random axis: (its name, the pose)."""
    from pydrake.math import RigidTransform, RotationMatrix

    names = list(oracle.scene.poses)
    name = names[rng.integers(len(names))]
    X = oracle.scene.poses[name]
    axis = rng.normal(size=3)
    frame = RotationMatrix.MakeFromOneVector(axis / np.linalg.norm(axis), 2)  # any frame with z = axis
    spin = RotationMatrix.MakeZRotation(rng.uniform(-turn, turn))
    about = frame.multiply(spin).multiply(frame.inverse())  # a turn about `axis`
    return name, RigidTransform(about.multiply(X.rotation()), X.translation() + rng.uniform(-1, 1, 3) * shift)


def _job_postures(oracle) -> dict:
    """The job's postures for the named poses (the same for every seed, as in the job)."""
    from app.planning.ik import solve_poses

    return solve_poses(oracle, np.random.default_rng(0), reference=np.asarray(oracle.scene.start, float))


def _first_reached(oracle, attempt):
    """What `attempt()` returns the first time it is not None (a tool pose the arm reaches), within POSE_ATTEMPTS
    tries (a moved named pose may have no free IK solution)."""
    for _ in range(POSE_ATTEMPTS):
        found = attempt()
        if found is not None:
            return found
    raise UserError(f"scene {oracle.scene.name}: no reachable tool pose in {POSE_ATTEMPTS} tries")


def _tool_goals(oracle, rng, hard: bool, reference, postures):
    """The IK solutions of a tool pose (None: none free): a moved named pose from the job's posture for it (`hard`),
    else the pose of a random free configuration; sorted from `reference`."""
    from app.planning.ik import distinct_solutions, tool_pose

    if hard:
        name, pose = _moved_pose(oracle, rng, HARD_SHIFT, HARD_TURN)
        found = distinct_solutions(oracle, pose, rng, reference, posture=postures[name])
    else:
        q = _free_configurations(oracle, 1, rng)[0]
        found = distinct_solutions(oracle, tool_pose(oracle, q), rng, reference, known=[q])
    return found if len(found) else None


def _held_out_query(oracle, rng, from_free: bool, postures):
    """(start, goals) of a held-out query, or None: the start a random free configuration (`from_free`) or a moved
    named pose solved from the job's posture; the goals the IK solutions of another moved named pose."""
    from app.planning.ik import distinct_solutions

    if from_free:
        start = _free_configurations(oracle, 1, rng)[0]
    else:
        name, pose = _moved_pose(oracle, rng, HELD_OUT_SHIFT, HELD_OUT_TURN)
        found = distinct_solutions(oracle, pose, rng, postures[name], posture=postures[name])
        if not len(found):
            return None
        start = found[0]
    _, pose = _moved_pose(oracle, rng, HELD_OUT_SHIFT, HELD_OUT_TURN)
    found = distinct_solutions(oracle, pose, rng, start)
    return (start, found) if len(found) else None


def _tool_queries(oracle, n: int, rng, progress) -> QuerySet:
    home = np.asarray(oracle.scene.start, float)
    postures = _job_postures(oracle)  # a hard pose's own posture
    goals, hard = [], []
    reference = home  # IK solutions are sorted by distance from here: the previous query's nearest goal
    for i in range(n):
        in_hard = i % 2 == 0
        found = _first_reached(oracle, partial(_tool_goals, oracle, rng, in_hard, reference, postures))
        goals.append(found)
        hard.append(in_hard)
        reference = found[0]
        progress()
    kind = (
        "tool poses, a work cell's sequence: each query from where the robot is (home first; then the goal it "
        f"reached, or where it waited) to every IK solution found for a tool pose, alternately a named pose moved "
        f"<= {HARD_SHIFT * 100:g} cm and turned <= {math.degrees(HARD_TURN):g} deg that the arm reaches in the "
        "job's posture for it (hard), and the pose of a random free configuration"
    )
    return QuerySet(kind, home[None], goals, np.array(hard), chained=True)


def _held_out_queries(oracle, n: int, rng, progress) -> QuerySet:
    """Queries unlike those a cell's build and jobs answer: each from its own start, alternately a random free
    configuration and a hard posture (a named pose moved <= HELD_OUT_SHIFT and turned <= HELD_OUT_TURN, solved
    from the job's posture for it), to every IK solution found for another such hard pose, any posture."""
    postures = _job_postures(oracle)
    starts, goals = [], []
    for i in range(n):
        start, found = _first_reached(oracle, partial(_held_out_query, oracle, rng, i % 2 == 0, postures))
        starts.append(start)
        goals.append(found)
        progress()
    kind = (
        "held-out tool poses: each query from its own start, alternately a random free configuration and a named "
        f"pose moved <= {HELD_OUT_SHIFT * 100:g} cm and turned <= {math.degrees(HELD_OUT_TURN):g} deg (solved from "
        "the job's posture), to every IK solution found for another such pose"
    )
    return QuerySet(kind, np.array(starts), goals, np.ones(n, bool))


@dataclass(frozen=True)
class Settings:
    """What a run measures: queries per scene, the seed of the query set and of every planner, our per-query budget,
    OMPL's seconds per query, the cell build's nodes, budget and worker processes."""

    queries: int = 100
    seed: int = 0
    budget: Budget = Budget(checks=200_000)
    ompl_seconds: float = 10.0
    build_nodes: int = 1500
    build_budget: Budget = Budget(checks=3_000_000)
    workers: int = 1
    mix: str = "own"


# ---- the methods --------------------------------------------------------------------------------------------------
def _ends(oracle, path, start, goals) -> dict:
    """Whether a path starts at the query's start and which of its goals it ends at (None: none)."""
    if path is None or len(path) == 0:
        return {"from_start": None, "reached": None}
    d = oracle.space.distance(np.atleast_2d(goals), np.asarray(path[-1])[None])
    reached = int(np.argmin(d)) if float(np.min(d)) <= REACHED else None
    return {"from_start": bool(float(oracle.space.distance(path[0], start)) <= REACHED), "reached": reached}


def _ours(oracle, solve, start, goals, seed: int, budget: Budget) -> dict:
    """One query answered by our planner: solve(start, goals, PlanSettings) is app.plan or CellRoadmap.solve."""
    clock = time.perf_counter()
    try:
        r = solve(start, goals, PlanSettings(budget=budget, seed=seed))
    except NoPath as failure:
        details = getattr(failure, "details", {}) or {}
        return {
            "success": False,
            "seconds": time.perf_counter() - clock,
            "checks": details.get("collision_checks"),
            "certified": False,
            "timed": False,
            **_ends(oracle, None, start, goals),
        }
    return {
        "success": True,
        "seconds": time.perf_counter() - clock,
        "checks": int(r.collision_checks),
        "distance_queries": int(r.stats.distance_queries),
        "certify_seconds": r.stats.seconds.certify,
        "timing_seconds": r.stats.seconds.timing,
        "certified": bool(r.trajectory is not None and r.trajectory.certified),
        "timed": r.trajectory is not None,
        **_ends(oracle, r.path, start, goals),
    }


def _plan_fresh(oracle, start, goals, plan_settings):
    """A fresh single query, as `_ours` asks its solver."""
    return plan(oracle, plan_settings, start=start, goal=goals)


def _fresh(oracle, queries: QuerySet, settings: Settings, progress, build_seconds=None) -> dict:
    def answer(i, start, goals):
        return _ours(oracle, partial(_plan_fresh, oracle), start, goals, settings.seed + i, settings.budget)

    return {"build": None, "answers": answer_all(queries, answer, progress)}


def build_cell(oracle, settings: Settings, progress=None):
    """A cell roadmap of the oracle's cell as `roadmap build` builds it (its cover included): (roadmap, seconds,
    collision checks, what the cover answered). progress as CellRoadmap.grow takes it."""
    from app.jobs import cover
    from app.planning.cell import BuildSettings, CellRoadmap

    build_settings = BuildSettings(nodes=settings.build_nodes, budget=settings.build_budget, seed=settings.seed)
    clock = time.perf_counter()
    cell = CellRoadmap.build(oracle, build_settings, workers=settings.workers, progress=progress)
    covered = cover(cell, seed=settings.seed)
    checks = cell.provenance["builds"][-1]["collision_checks"] + sum(c["collision_checks"] for c in covered)
    return cell, time.perf_counter() - clock, int(checks), covered


def _cell(oracle, queries: QuerySet, settings: Settings, progress, build_seconds=None) -> dict:
    bar = tqdm(
        total=settings.build_nodes, desc=f"  build {oracle.scene.name}", unit="node", leave=False, dynamic_ncols=True
    )

    def grown(nodes, target, checks):
        bar.update(nodes - bar.n)
        bar.set_postfix(checks=checks, refresh=False)

    try:
        cell, seconds, checks, covered = build_cell(oracle, settings, grown)
    finally:
        bar.close()
    record = cell.provenance["builds"][-1]
    info = cell.info()
    build = {
        "seconds": seconds,
        "checks": checks,
        "covered": covered,
        "nodes": info["nodes"],
        "edges": int(sum(info["edges"].values())),
        "ended": record["ended"],
        "workers": settings.workers,
    }

    def answer(i, start, goals):
        out = _ours(oracle, cell.solve, start, goals, settings.seed + i, settings.budget)
        out["nodes"] = len(cell)  # the roadmap after this query, with what the query added and kept
        if queries.chained and i > 0:  # from where this roadmap's answers left the robot: its own fresh counterpart
            fresh = _ours(oracle, partial(_plan_fresh, oracle), start, goals, settings.seed + i, settings.budget)
            out["fresh_checks"] = fresh["checks"]
        return out

    answers = answer_all(queries, answer, progress)
    return {"build": build, "answers": answers, "builds": len(cell.provenance["builds"])}


def _ompl_answer(oracle, problem, start, goals, seconds: float) -> dict:
    from app.bench.ompl import _fine_check

    checks0, clock = problem.checker.checks, time.perf_counter()
    problem.set_query(start, goals)
    solved = problem.solve(seconds)
    solve_seconds = time.perf_counter() - clock
    out = {"success": solved, "certified": False, "timed": False}
    path = None
    if solved:
        problem.simplify()
        path = problem.solution_for_oracle()
        out["smoothing_seconds"] = time.perf_counter() - clock - solve_seconds
    out.update(seconds=time.perf_counter() - clock, checks=problem.checker.checks - checks0)
    if solved:
        out.update(_fine_check(oracle, path))  # ours, counted apart: whether OMPL's answer is free at our fine step
    return {**out, **_ends(oracle, path, start, goals)}


def _ompl_prm(oracle, queries: QuerySet, settings: Settings, progress, build_seconds=None) -> dict:
    from app.ompl_bridge import OmplProblem

    problem = OmplProblem(oracle, seed=settings.seed, planner="PRM")
    clock = time.perf_counter()
    problem.grow(build_seconds)
    build = {
        "seconds": time.perf_counter() - clock,
        "checks": int(problem.checker.checks),
        "nodes": int(problem.planner.milestoneCount()),
        "edges": int(problem.planner.edgeCount()),
        "ended": "seconds (the cell build's)",
        "workers": 1,
    }

    def answer(i, start, goals):
        out = _ompl_answer(oracle, problem, start, goals, settings.ompl_seconds)
        return {**out, "nodes": int(problem.planner.milestoneCount())}

    return {"build": build, "answers": answer_all(queries, answer, progress)}


def _ompl_rrtconnect(oracle, queries: QuerySet, settings: Settings, progress, build_seconds=None) -> dict:
    from app.ompl_bridge import OmplProblem

    def answer(i, start, goals):
        problem = OmplProblem(oracle, seed=settings.seed + i, planner="RRTConnect")  # a fresh tree per query
        return _ompl_answer(oracle, problem, start, goals, settings.ompl_seconds)

    return {"build": None, "answers": answer_all(queries, answer, progress)}


RUNNERS = {"fresh": _fresh, "cell": _cell, "ompl-prm": _ompl_prm, "ompl-rrtconnect": _ompl_rrtconnect}


# ---- the benchmark ------------------------------------------------------------------------------------------------
def check_methods(methods) -> list[str]:
    """The methods in METHODS order (the cell before ompl-prm, whose build lasts as long as the cell's); UserError
    for an unknown one, or ompl-prm without cell."""
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise UserError(f"unknown method {', '.join(unknown)} (known: {', '.join(METHODS)})")
    if "ompl-prm" in methods and "cell" not in methods:
        raise UserError("ompl-prm grows its roadmap for as long as the cell build took: add cell to --methods")
    return [m for m in METHODS if m in methods]


def _params(method: str, settings: Settings, digest: str) -> dict:
    """What a trial's key holds: the query set and the settings the method's answers depend on."""
    out = {"protocol": PROTOCOL, "queries": settings.queries, "query_set": digest}
    if method in ("fresh", "cell"):
        out["budget"] = str(settings.budget)
    if method in ("cell", "ompl-prm"):
        out.update(build_nodes=settings.build_nodes, build_budget=str(settings.build_budget), workers=settings.workers)
    if method.startswith("ompl-"):
        out["ompl_seconds"] = settings.ompl_seconds
    return out


def _quantile(values, q: float):
    values = [v for v in values if v is not None]
    return float(np.quantile(values, q)) if values else None


def summarise(method: str, metrics: dict) -> dict:
    """One method's row: its build, and over all its queries (failures included: they spent their budget) the
    median and p95 checks and seconds, success rate, certified share (of the successes) and totals."""
    answers = metrics["answers"]
    won = [a for a in answers if a["success"]]
    checks = [a["checks"] for a in answers]
    seconds = [a["seconds"] for a in answers]
    return {
        "method": method,
        "queries": len(answers),
        "build": metrics["build"],
        "successes": len(won),
        "success_rate": len(won) / len(answers) if answers else None,
        "certified_share": sum(a["certified"] for a in won) / len(won) if won else None,
        "timed_share": sum(a["timed"] for a in won) / len(won) if won else None,
        "median_checks": _quantile(checks, 0.5),
        "p95_checks": _quantile(checks, 0.95),
        "median_seconds": _quantile(seconds, 0.5),
        # ours: the part of a query's seconds spent proving and timing its path (OMPL does neither: None)
        "median_certify_timing_seconds": _quantile(
            [a["certify_seconds"] + a["timing_seconds"] for a in answers if "certify_seconds" in a], 0.5
        ),
        "p95_seconds": _quantile(seconds, 0.95),
        "total_checks": int(sum(c for c in checks if c is not None)),
        "total_seconds": float(sum(seconds)),
        "failed_fine_check": sum(1 for a in won if a.get("fine_check_passed") == 0.0),
        "builds": metrics.get("builds"),
        "answers": answers,
    }


def _with_build(row: dict, key: str) -> float:
    return row[f"total_{key}"] + (row["build"][key] if row["build"] else 0)


def _over(a, b):
    return a / b if b else None


def _both_answered(a: dict, b: dict, key: str) -> tuple[int, float | None]:
    """(how many queries both rows answered, a's total `key` over b's on those queries)."""
    pairs = [(x[key], y[key]) for x, y in zip(a["answers"], b["answers"]) if x["success"] and y["success"]]
    return len(pairs), _over(sum(x for x, _ in pairs), sum(y for _, y in pairs))


def _per_query(cell: dict, fresh: dict) -> dict:
    """Each query's checks on the cell roadmap over its fresh counterpart's: the fresh query from the same start. In
    a chained query set a method starts where its own last answer left the robot, so the cell method answers each
    query fresh from its own start too (`fresh_checks`); in a run stored without those, the fresh method's answer
    where it started from the same configuration. How many queries compare, how many do not, the indices of those
    over the goal, and the largest ratio."""
    same = []
    for i, (a, b) in enumerate(zip(cell["answers"], fresh["answers"])):
        if "fresh_checks" in a:
            same.append((i, a["checks"], a["fresh_checks"]))
        elif "start" in a and "start" in b and np.allclose(a["start"], b["start"], rtol=0, atol=1e-9):
            same.append((i, a["checks"], b["checks"]))
    same = [(i, c, f) for i, c, f in same if c is not None and f is not None]
    over = [c / f if f else (math.inf if c else 1.0) for _, c, f in same]
    return {
        "same_start": len(same),
        "other_start": len(cell["answers"]) - len(same),
        "dearer": [i for (i, _, _), r in zip(same, over) if r > GOALS["query vs fresh"]],
        "dearest": max(over, default=None),
    }


def per_query_words(per_query: dict) -> str:
    """`_per_query` in words: "0 of 49 (1 from another start; the dearest 1.02x)"."""
    words = f"{len(per_query['dearer'])} of {per_query['same_start']}"
    notes = [f"{per_query['other_start']} from another start"] if per_query["other_start"] else []
    if per_query["dearer"]:
        notes.append("queries " + ", ".join(str(i) for i in per_query["dearer"]))
    if per_query["dearest"] is not None:
        notes.append(f"the dearest {per_query['dearest']:.3g}x")
    return words + (f" ({'; '.join(notes)})" if notes else "")


def ratios(rows: list[dict]) -> list[dict]:
    """The cell's totals over fresh's and ompl-prm's, queries only and with each build added (None when a method
    is missing); and over the queries both answered (a query neither can answer costs each its whole budget, which
    bounds the ratio of the totals from below); over fresh's also query by query (`_per_query`)."""
    by = {r["method"]: r for r in rows}
    cell = by.get("cell")
    out = []
    for other, goal in (("fresh", GOALS["cell vs fresh"]), ("ompl-prm", GOALS["cell vs ompl-prm"])):
        if cell is None or other not in by:
            continue
        o = by[other]
        both, seconds_both = _both_answered(cell, o, "seconds")
        out.append(
            {
                "of": "cell",
                "over": other,
                "checks": _over(cell["total_checks"], o["total_checks"]),
                "seconds": _over(cell["total_seconds"], o["total_seconds"]),
                "checks_with_builds": _over(_with_build(cell, "checks"), _with_build(o, "checks")),
                "seconds_with_builds": _over(_with_build(cell, "seconds"), _with_build(o, "seconds")),
                "both_answered": both,
                "checks_both_answered": _both_answered(cell, o, "checks")[1],
                "seconds_both_answered": seconds_both,
                "goal_seconds": goal,
                "per_query": _per_query(cell, o) if other == "fresh" else None,
            }
        )
    return out


def measure(scenes: list[str], methods: list[str], settings: Settings, store_path, fresh: bool = False):
    """Every scene's query set answered by every method (trials the store holds are reused). Returns (report,
    Reuse): {"scenes": [{"scene", "query_set", "methods": summarise rows, "ratios"}], settings...}."""
    from app.checking.oracle import CollisionOracle, default_threads
    from app.scene.model import Scene

    methods = check_methods(methods)
    if any(m.startswith("ompl-") for m in methods):
        from app.ompl_bridge import ompl_modules

        ompl_modules()
    store = ResultStore(store_path)
    out, reused = [], []
    try:
        for name in scenes:
            oracle = CollisionOracle(Scene(name), threads=max(settings.workers, default_threads()))
            step = default_step(oracle.scene)
            with tqdm(total=settings.queries, desc=f"{name} queries", unit="query", dynamic_ncols=True) as bar:
                queries = make_queries(oracle, settings.queries, settings.seed, bar.update, settings.mix)
            specs = [
                TrialSpec(EXPERIMENT, name, m, step, settings.seed, _params(m, settings, queries.digest()))
                for m in methods
            ]
            reused.append(store.reuse(specs, fresh=fresh))
            pending = {s.key for s in store.pending(specs, fresh=fresh)}
            rows = {}
            for spec in specs:
                if spec.key in pending:
                    # ompl-prm's build lasts as long as the cell's (run or reused just before: METHODS order)
                    build_seconds = rows["cell"]["build"]["seconds"] if spec.method == "ompl-prm" else None
                    bar = tqdm(total=len(queries), desc=f"{name} {spec.method}", unit="query", dynamic_ncols=True)
                    try:
                        metrics = RUNNERS[spec.method](oracle, queries, settings, bar.update, build_seconds)
                    finally:
                        bar.close()
                    # the machine's 5-minute load as the method ends: what its seconds were measured under
                    load = os.getloadavg()[1]
                    store.add(spec, {**metrics, "query_set": queries.digest(), "load_average": load})
                rows[spec.method] = store.rows_for([spec])[0]["metrics"]
            table = [summarise(m, rows[m]) for m in methods]
            out.append({"scene": name, "query_set": queries.to_json(), "methods": table, "ratios": ratios(table)})
        reuse = _merged(reused)
    finally:
        store.close()
    report = {
        "scenes": out,
        "queries": settings.queries,
        "seed": settings.seed,
        "budget": str(settings.budget),
        "ompl_seconds": settings.ompl_seconds,
        "build_nodes": settings.build_nodes,
        "build_budget": str(settings.build_budget),
        "workers": settings.workers,
        "mix": settings.mix,
        "goals": GOALS,
    }
    return report, reuse


def _merged(parts: list[Reuse]) -> Reuse:
    """What was reused over several scenes (each looked at before its trials ran)."""
    return Reuse(
        store=parts[0].store,
        trials=sum(p.trials for p in parts),
        reused=sum(p.reused for p in parts),
        versions=tuple(sorted({v for p in parts for v in p.versions})),
        current=parts[0].current,
    )


def figure(report: dict, path: str) -> None:
    """Per-query seconds of every method, one panel per scene (log y): each query a dot (a cross when it failed),
    with the median and p95 marked; the build seconds written under the method's name."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from app.draw import save

    scenes = report["scenes"]
    width = 1.0 + 1.6 * max(len(s["methods"]) for s in scenes)
    # Constrained layout makes room for the two-line suptitle and no more.
    fig, axes = plt.subplots(1, len(scenes), figsize=(width * len(scenes), 4.2), squeeze=False, layout="constrained")
    rng = np.random.default_rng(0)  # the dots' horizontal jitter
    for ax, s in zip(axes.flat, scenes):
        labels = []
        for x, r in enumerate(s["methods"]):
            seconds = np.maximum(np.array([a["seconds"] for a in r["answers"]], float), 1e-4)
            won = np.array([a["success"] for a in r["answers"]], bool)
            jitter = x + rng.uniform(-0.18, 0.18, len(seconds))
            ax.scatter(jitter[won], seconds[won], s=10, color=f"C{x}", alpha=0.6, linewidths=0)
            ax.scatter(jitter[~won], seconds[~won], s=18, color="black", marker="x", linewidths=1)
            for q, style in ((r["median_seconds"], "-"), (r["p95_seconds"], ":")):
                if q:
                    ax.plot([x - 0.3, x + 0.3], [q, q], style, color="black", lw=1.5)
            build = r["build"]
            labels.append(r["method"] + (f"\nbuild {build['seconds']:.0f} s" if build else ""))
        ax.set_yscale("log")
        ax.set_xticks(range(len(labels)), labels, fontsize=8)
        ax.set_xlim(-0.6, len(labels) - 0.4)
        ax.grid(alpha=0.3, which="both", axis="y")
        ax.set_title(f"{s['scene']}: {s['query_set']['count']} queries", fontsize=10)
        ax.set_ylabel("seconds per query", fontsize=9)
    fig.suptitle(
        "every query a dot (x: failed); line: median, dotted: p95\n"
        f"ours: {_spelled(report['budget'])} per query, certified and timed; "
        f"OMPL: {report['ompl_seconds']:g} s per query, smoothed, neither certified nor timed",
        fontsize=8,
    )
    save(fig, path)


def _spelled(budget: str) -> str:
    """A budget as the command line writes it ("200000checks,10s") spelled for a caption ("200,000 checks, 10 s")."""
    if budget == "none":
        return "no limit"
    parts = []
    for part in budget.split(","):
        number, unit = re.fullmatch(r"([0-9.e+-]+)(\D*)", part).groups()
        parts.append(f"{float(number):,.0f} checks" if unit == "checks" else f"{float(number):g} s")
    return ", ".join(parts)
