"""`bench moveit`: a folder of MoveIt problems planned by our planner and by OMPL's RRTConnect, through one checker.

A problem is a `moveit_msgs/PlanningScene` and a `moveit_msgs/MotionPlanRequest` file beside it (`sceneNNNN.yaml`,
`requestNNNN.yaml`, as MotionBenchMaker lays them out; the folder they are in is the problem's kind). Both methods
plan on the same oracle (app.scene.moveit reads the files once per problem), so a check is the same configuration
handed to Drake on either side, under the same check budget. What is timed is what a MoveIt user waits for:

- ours: `plan` as `plan --moveit-request` runs it, to a certified, time-parameterized trajectory (sampling, search,
  smoothing, the certificate and the timing);
- RRTConnect: `solve` until its first solution, `simplifySolution()`, then the same Toppra timing of the simplified
  path, rest to rest at its waypoints (app.motion.timing.parameterize: not certified, as MoveIt's timing is not).

Neither side's time includes loading the scene or solving IK for pose goals. Every returned path is then held to
the bench's own fine check (1/4 of the scene's resolution, counted apart): our certified paths pass it, and a
simplified RRTConnect path that fails it is counted (`colliding`). OMPL's RNG is seeded once per process, so its
runs are not reproducible from their seed; ours are.
"""

from __future__ import annotations

import hashlib
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from app.bench.runner import sweep
from app.bench.statistics import median_or_none, shown
from app.bench.store import Reuse, TrialSpec
from app.checking.budget import SAFETY_NET_SECONDS, Budget
from app.errors import NoPath, UserError
from app.motion.path import FINE, path_length
from app.scene.files import PACKAGES, ROOT

OURS, RRT = "ours", "ompl:RRTConnect"
METHODS = [OURS, RRT]
EXAMPLES = ROOT / "examples" / "moveit" / "mbm-panda"
PANDA = PACKAGES["npp_robots"] / "panda"
# The issue's goals for the default method against RRTConnect, each a ratio of medians over the problems both solved.
GOALS = {"seconds": 1.0, "checks": 1.0}


@dataclass(frozen=True)
class Problem:
    name: str  # KIND/NNNN
    kind: str
    scene: Path
    request: Path


@dataclass(frozen=True)
class Robot:
    urdf: Path
    srdf: Path | None = None
    package_path: tuple[str, ...] = ()


def find_problems(folder: str | Path, per_kind: int | None = None) -> list[Problem]:
    """Every `requestNNNN.yaml` with its `sceneNNNN.yaml` under `folder`, by kind (the folder holding the pair) and
    number; the first `per_kind` of each kind. One UserError when there are none."""
    root = Path(folder).expanduser()
    if not root.is_dir():
        raise UserError(f"no folder {folder}")
    found: dict[str, list[Problem]] = {}
    for request in sorted(root.rglob("request*.yaml")):
        number = request.stem.removeprefix("request")
        scene = request.with_name(f"scene{number}.yaml")
        if not scene.is_file():
            continue
        kind = request.parent.relative_to(root).as_posix() if request.parent != root else root.name
        found.setdefault(kind, []).append(Problem(f"{kind}/{number}", kind, scene.resolve(), request.resolve()))
    if not found:
        raise UserError(f"no MoveIt problems (requestNNNN.yaml beside sceneNNNN.yaml) under {folder}")
    return [p for kind in sorted(found) for p in found[kind][:per_kind]]


def _digest(paths) -> str:
    h = hashlib.sha256()
    for path in paths:
        h.update(Path(path).read_bytes())
    return h.hexdigest()[:16]


def specs(problems: list[Problem], robot: Robot, methods: list[str], seeds: int, checks: int) -> list[TrialSpec]:
    """One trial per problem, method and seed. Its key holds the files' contents (a changed file runs again)."""
    robot_files = [robot.urdf, *([robot.srdf] if robot.srdf else [])]
    robot_digest = _digest(robot_files)
    out = []
    for problem in problems:
        params = {
            "scene": str(problem.scene),
            "request": str(problem.request),
            "robot": str(robot.urdf),
            "srdf": str(robot.srdf or ""),
            "package_path": list(robot.package_path),
            "files": _digest([problem.scene, problem.request]) + robot_digest,
            "checks": int(checks),
        }
        out += [TrialSpec("moveit", problem.name, m, 0.0, s, params) for m in methods for s in range(seeds)]
    return out


_loaded: dict[tuple, tuple] = {}  # the last problem read in this process and its oracle: both methods share them


def _problem(params: dict, threads: int):
    from app.checking.oracle import CollisionOracle
    from app.scene.moveit import read_problem

    key = (params["scene"], params["request"], params["files"], threads)
    if key not in _loaded:
        _loaded.clear()
        problem = read_problem(
            request=params["request"],
            scene=params["scene"],
            robot=params["robot"],
            srdf=params["srdf"] or None,
            package_path=params["package_path"],
            collisions="all",
        )
        _loaded[key] = problem, CollisionOracle(problem.scene, threads=threads)
    return _loaded[key]


def run_trial_spec(spec: TrialSpec, threads: int = 1) -> dict:
    """One method on one problem (the module docstring says what is measured). A problem that cannot be read, or
    whose start or goal is invalid, is a row that says so (`invalid`), for both methods alike. A method that fails
    with an unexpected error is a row that names it (`crashed`, unsolved): one problem's bug does not end the run,
    and the table counts it."""
    from app.planning.moveit import goal_configurations

    try:
        problem, oracle = _problem(spec.params, threads)
        started = time.perf_counter()
        goals = goal_configurations(oracle, problem, seed=spec.seed)
        ik_seconds = time.perf_counter() - started
    except UserError as exc:
        return {"solved": 0.0, "invalid": exc.code, "message": str(exc)[:300]}
    budget = Budget(checks=int(spec.params["checks"]), seconds=SAFETY_NET_SECONDS)
    run = _ours if spec.method == OURS else _rrt_connect
    load = os.getloadavg()[0]  # what else the machine was doing: seconds depend on it, checks do not
    try:
        found = run(oracle, problem, goals, spec.seed, budget)
    except Exception as exc:  # (not BaseException: Ctrl-C still ends the run)
        found = {"solved": 0.0, "crashed": f"{type(exc).__name__}: {' '.join(str(exc).split())}"[:300]}
    return {**found, "ik_seconds": ik_seconds, "load_average": load}


def _ours(oracle, problem, goals: np.ndarray, seed: int, budget: Budget) -> dict:
    from app.planning.query import plan
    from app.planning.settings import PlanSettings

    settings = PlanSettings(
        seed=seed,
        budget=budget,
        velocity_scale=problem.velocity_scale,
        acceleration_scale=problem.acceleration_scale,
    )
    started = time.perf_counter()
    try:
        r = plan(oracle, settings, start=problem.start, goal=goals)
    except NoPath as failure:
        details = getattr(failure, "details", {}) or {}
        return {
            "solved": 0.0,
            "code": failure.code,
            "checks": details.get("collision_checks"),
            "seconds": time.perf_counter() - started,
        }
    seconds, checks = r.stats.seconds, r.stats.checks
    return {
        "solved": 1.0,
        "certified": float(r.certified),
        "checks": r.collision_checks,
        "seconds": seconds.total,
        "phase_seconds": {
            "sampling": seconds.sampling,
            "roadmap": seconds.roadmap,
            "search": seconds.search,
            "smoothing": seconds.smoothing,
            "certify": seconds.certify,
            "timing": seconds.timing,
        },
        "sampling_checks": checks.sampling,
        "path_length": r.smoothing.length_after,
        "duration": float(r.trajectory.times[-1]) if r.trajectory is not None else None,
        **_fine_check(oracle, r.path),
    }


def _rrt_connect(oracle, problem, goals: np.ndarray, seed: int, budget: Budget) -> dict:
    from app.motion.timing import parameterize, scaled_limits
    from app.ompl_bridge import OmplProblem

    ompl = OmplProblem(oracle, seed=seed, planner="RRTConnect")
    ompl.set_query(problem.start, goals)
    checker = ompl.checker
    started = time.perf_counter()
    solved = ompl.solve(budget.seconds, checks=budget.checks)
    solve_seconds = time.perf_counter() - started
    out = {"solved": float(solved), "checks": checker.checks, "solve_seconds": solve_seconds, "seconds": solve_seconds}
    if not solved:
        return out
    before, started = checker.checks, time.perf_counter()
    ompl.simplify()
    simplify_seconds = time.perf_counter() - started
    path = ompl.solution_for_oracle()  # OMPL's own motions, as our oracle's edges
    started = time.perf_counter()
    velocity, acceleration = scaled_limits(oracle.scene, problem.velocity_scale, problem.acceleration_scale)
    trajectory = parameterize(oracle.plant, oracle.space.unwrap(path), velocity, acceleration)
    timing_seconds = time.perf_counter() - started
    return {
        **out,
        "checks": checker.checks,
        "simplify_checks": checker.checks - before,
        "seconds": solve_seconds + simplify_seconds + timing_seconds,
        "phase_seconds": {"solve": solve_seconds, "simplify": simplify_seconds, "timing": timing_seconds},
        "path_length": path_length(oracle, path),
        "duration": float(trajectory.times[-1]),
        **_fine_check(oracle, path),
    }


def _fine_check(oracle, path: np.ndarray) -> dict:
    """The bench's own verdict on a returned path, at 1/4 of the resolution, counted apart from the method's."""
    checker = oracle.context()
    free = checker.edges_free(path[:-1], path[1:], FINE * oracle.space.resolution)
    return {"colliding": float(not free.all()), "verify_checks": checker.checks}


# ---- the report ---------------------------------------------------------------------------------------------------


def _ratio(a: float | None, b: float | None) -> float | None:
    return a / b if a is not None and b else None


def summarise(rows: list[dict], methods: list[str]) -> dict:
    """Per kind and over all problems: each method's successes, and medians over the problems every method solved
    (paired: the same problems on each side) of checks, seconds and checks per second; RRTConnect's solve-only
    seconds; simplified paths that failed the fine check; our certified answers."""
    by_problem: dict[str, dict[str, dict]] = {}
    kinds: dict[str, str] = {}
    for r in rows:
        by_problem.setdefault(r["scene"], {})[r["method"]] = {**r["metrics"], "version": r.get("code_version")}
        kinds[r["scene"]] = r["scene"].rsplit("/", 1)[0]
    groups = {"all": sorted(by_problem)}
    for name in sorted(by_problem):
        groups.setdefault(kinds[name], []).append(name)
    out = []
    for group, names in groups.items():
        valid = [n for n in names if not any(m.get("invalid") for m in by_problem[n].values())]
        both = [n for n in valid if all(by_problem[n].get(m, {}).get("solved") for m in methods)]
        row = {"kind": group, "problems": len(names), "invalid": len(names) - len(valid), "both_solved": len(both)}
        for m in methods:
            cells = [by_problem[n].get(m, {}) for n in valid]
            paired = [by_problem[n][m] for n in both]
            row[m] = {
                "solved": sum(1 for c in cells if c.get("solved")),
                "colliding": sum(1 for c in cells if c.get("solved") and c.get("colliding")),
                "crashed": sum(1 for c in cells if c.get("crashed")),
                "certified": sum(1 for c in cells if c.get("certified")),
                "median_checks": median_or_none([c["checks"] for c in paired]),
                "median_seconds": median_or_none([c["seconds"] for c in paired]),
                "median_solve_seconds": median_or_none([c.get("phase_seconds", {}).get("solve") for c in paired]),
                "median_checks_per_second": median_or_none(
                    [c["checks"] / c["seconds"] for c in paired if c["seconds"] > 0]
                ),
            }
        if len(methods) == 2:
            a, b = (row[m] for m in methods)
            row["ratio"] = {
                "checks": _ratio(a["median_checks"], b["median_checks"]),
                "seconds": _ratio(a["median_seconds"], b["median_seconds"]),
                "checks_per_second": _ratio(a["median_checks_per_second"], b["median_checks_per_second"]),
            }
        out.append(row)
    versions = sorted({r.get("code_version") or "?" for r in rows})
    return {"kinds": out, "code_versions": versions}


def measure(
    folder: str | Path,
    robot: Robot,
    *,
    methods: list[str] = METHODS,
    per_kind: int | None = 10,
    seeds: int = 1,
    checks: int = 100_000,
    store,
    workers: int = 1,
    fresh: bool = False,
) -> tuple[dict, Reuse]:
    """The problems of `folder` (`find_problems`) by every method, trials the store lacks run (`runner.sweep`).
    Returns ({"kinds": summarise(...), "problems", "methods", "checks", "seeds", "folder", "rows": per trial}, what
    was reused). No OMPL, a bad method or an empty folder: one UserError before anything runs."""
    unknown = [m for m in methods if m not in METHODS]
    if unknown or not methods:
        raise UserError(f"unknown method(s) {', '.join(unknown) or '(none)'} (known: {', '.join(METHODS)})")
    for path in (robot.urdf, robot.srdf):
        if path is not None and not Path(path).is_file():
            raise UserError(f"no file {path}")
    if RRT in methods:
        from app.ompl_bridge import ompl_modules

        ompl_modules()
    problems = find_problems(folder, per_kind)
    rows, reuse = sweep(specs(problems, robot, methods, seeds, checks), store, workers=workers, desc="bench moveit",
                        fresh=fresh)  # fmt: skip
    report = summarise(rows, methods)
    trials = [
        {"problem": r["scene"], "method": r["method"], "seed": r["seed"], **r["metrics"]}
        for r in sorted(rows, key=lambda r: (r["scene"], r["method"], r["seed"]))
    ]
    return {
        **report,
        "folder": str(folder),
        "robot": str(robot.urdf),
        "methods": methods,
        "problems": len(problems),
        "seeds": seeds,
        "checks": checks,
        "goals": GOALS,
        "trials": trials,
    }, reuse


def _solved(method: dict) -> str:
    """A method's successes, and its crashes if any."""
    return f"{method['solved']}" + (f" ({method['crashed']} crashed)" if method.get("crashed") else "")


def table(report: dict) -> str:
    """The report as a markdown table: a row per kind and one over all problems."""
    ours, other = report["methods"][0], report["methods"][-1]
    lines = [
        f"{report['problems']} MoveIt problems from `{report['folder']}`, {report['seeds']} seed(s) each, "
        f"{report['checks']:,} checks per run, one Drake checker for both methods. Medians over the problems both "
        f"solved; seconds: {ours} to a certified, timed trajectory, {other} solve + simplify + timing (solve alone "
        f"in brackets). colliding: returned paths that fail the fine check (1/4 of the resolution). Code version(s): "
        + ", ".join(f"`{v}`" for v in report["code_versions"]),
        "",
        f"| kind | problems | solved: {ours}, {other} | median checks | ratio | median s | ratio | checks/s ratio "
        f"| colliding: {ours}, {other} |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for row in report["kinds"]:
        a, b = row[ours], row[other]
        ratio = row.get("ratio", {})
        solve = b["median_solve_seconds"]
        lines.append(
            f"| {row['kind']} | {row['problems']}"
            + (f" ({row['invalid']} invalid)" if row["invalid"] else "")
            + f" | {_solved(a)}, {_solved(b)} | {shown(a['median_checks'], ',.0f')} vs "
            f"{shown(b['median_checks'], ',.0f')} | {shown(ratio.get('checks'), '.2f')} | "
            f"{shown(a['median_seconds'], '.2f')} vs {shown(b['median_seconds'], '.2f')} ({shown(solve, '.2f')}) | "
            f"{shown(ratio.get('seconds'), '.2f')} | {shown(ratio.get('checks_per_second'), '.2f')} | "
            f"{a['colliding']}, {b['colliding']} |"
        )
    return "\n".join(lines)


def figure(report: dict, path: str) -> None:
    """Left: per kind, the median seconds of each method (paired problems). Right: per problem solved by both, our
    seconds against RRTConnect's (log-log, the diagonal is parity), coloured by kind."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from app.draw import save

    ours, other = report["methods"][0], report["methods"][-1]
    kinds = [row for row in report["kinds"] if row["kind"] != "all"]
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.6))
    x = np.arange(len(kinds))
    for offset, method, colour in ((-0.2, ours, "tab:red"), (0.2, other, "tab:blue")):
        values = [row[method]["median_seconds"] or 0.0 for row in kinds]
        left.bar(x + offset, values, 0.4, color=colour, label=method)
    labels = [f"{row['kind']}\nsolved {row[ours]['solved']} / {row[other]['solved']}" for row in kinds]
    left.set_xticks(x, labels, rotation=30, ha="right", fontsize=8)
    left.set_ylabel("median seconds (problems both solved)")
    left.legend(fontsize=8, frameon=False)
    left.grid(alpha=0.3, axis="y")
    by_problem: dict[str, dict] = {}
    for t in report["trials"]:
        if t.get("solved"):
            by_problem.setdefault((t["problem"], t["seed"]), {})[t["method"]] = t["seconds"]
    colours = {row["kind"]: f"C{i % 10}" for i, row in enumerate(kinds)}
    for kind, colour in colours.items():
        pairs = [(v[other], v[ours]) for (name, _), v in by_problem.items() if name.rsplit("/", 1)[0] == kind
                 and ours in v and other in v]  # fmt: skip
        if pairs:
            xs, ys = zip(*pairs)
            right.scatter(xs, ys, s=14, color=colour, label=kind, alpha=0.8)
    lo = min([min(v.values()) for v in by_problem.values()] or [0.01])
    hi = max([max(v.values()) for v in by_problem.values()] or [1.0])
    right.plot([lo, hi], [lo, hi], color="grey", lw=1, ls="--")
    right.set_xscale("log")
    right.set_yscale("log")
    right.set_xlabel(f"{other}: solve + simplify + timing (s)")
    right.set_ylabel(f"{ours}: to a certified, timed trajectory (s)")
    right.legend(fontsize=7, frameon=False, ncol=2)
    right.grid(alpha=0.3, which="both")
    total = next(row for row in report["kinds"] if row["kind"] == "all")
    ratio = total.get("ratio", {})
    fig.suptitle(
        f"{report['problems']} MoveIt problems, {report['checks']:,} checks per run; over all problems both solved: "
        f"median checks {shown(ratio.get('checks'), '.2f')}x, median seconds {shown(ratio.get('seconds'), '.2f')}x "
        f"{other}'s",
        fontsize=10,
    )
    fig.tight_layout()
    save(fig, path)
