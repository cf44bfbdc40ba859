"""`bench ompl`: our planner beside OMPL's planners -- RRTConnect, BIT*, PRM, KPIECE1 -- all on our collision oracle.

Every method plans from the scene's start to its goal (the UR3 scenes too) on the same wall-clock budget, and every
collision check goes through the same oracle, so "checks" means the same thing everywhere (configurations handed
to Drake). Per run:

- success: a path within the budget, after smoothing free at our fine resolution (FINE x the scene's: OMPL's
  path is held to the standard our planner's paths are held to; runs whose path fails that are counted apart);
- checks and seconds to the first solution. OMPL: `solve(budget)`, which returns at the first solution for all
  four planners (PRM and BIT* are given a path-length objective whose cost threshold is infinite), checks counted
  at its return (the problem's set-up before `solve` is not timed). Ours: the whole query up to its first path, i.e.
  all of it but smoothing, the proof of the smoothed path and timing, which come after it; the planner's first run
  on a scene in a process is a warm-up, not timed (`_warm`), so one-time costs (imports, caches) are not charged to
  the first seed;
- smoothing checks and seconds (OMPL: `simplifySolution()`; ours: its shortcuts; our paths are then proved by the
  certificate, which counts distance queries, not checks, its seconds stored as `proof_seconds`) and the smoothed
  path's length in our metric.

Methods: `ours:default` (our planner as `plan` runs it: a single query, rounds until connected), `ours:full` (the
paper's protocol: the whole first roadmap, every edge checked), `ours:SAMPLER` and `ours:SAMPLER:full` for another
narrow-passage sampler; `ompl:PLANNER` for PLANNER in app.ompl_bridge.PLANNERS; `ompl:PRM+SAMPLER`: OMPL's PRM with
a valid-state sampler (ompl-uniform, ompl-obstacle, ompl-gaussian, ompl-bridge, or one of ours). OMPL's
state spaces and motion-check spacing are described in app.ompl_bridge; `motion_checks` reports the spacing
measured per scene. OMPL's RNG is seeded once per process, so an OMPL run is not reproducible from its seed.
"""

import dataclasses
import os
import time

import numpy as np

from app.bench.plan import scene_step
from app.bench.runner import sweep
from app.bench.statistics import median_or_none
from app.bench.store import Reuse, TrialSpec
from app.checking.budget import Budget
from app.errors import NoPath, UserError
from app.motion.path import FINE, path_length
from app.planning.query import plan
from app.planning.settings import PlanSettings
from app.samplers import check_name
from app.scene.model import Scene

# app.ompl_bridge loads OMPL (optional) when imported: it is imported by the functions that run OMPL, so that the
# command line starts, and the other benchmarks run, without it. Its planner names are repeated here for that reason.

OMPL_PLANNERS = ["RRTConnect", "BITstar", "PRM", "KPIECE1"]  # app.ompl_bridge.PLANNERS
OMPL_PRM_SAMPLERS = ["ompl-uniform", "ompl-obstacle", "ompl-gaussian", "ompl-bridge"]
DEFAULT_METHODS = ["ours:default", "ours:full"] + [f"ompl:{p}" for p in OMPL_PLANNERS]
MORE_METHODS = [f"ompl:PRM+{s}" for s in OMPL_PRM_SAMPLERS + ["lfbs", "rbbs"]]  # OMPL's PRM, other samplers
OURS = "ours:default"  # the row the ratio is taken of
# In every trial's key, so rows of the earlier PRM-only benchmark in the same store are not mixed in.
PROTOCOL = "first-solution+smoothing"


def parse_method(name: str) -> dict:
    """A method's parts: {"ours": True, "sampler", "full", "alone"} or {"ours": False, "planner", "sampler" (or
    None)}; UserError naming the fault for anything else. ours:SAMPLER:alone is the query planner with no
    workspace-gap placements (PlanSettings.workspace = 0): the sampler alone."""
    kind, _, rest = name.partition(":")
    if kind == "ours" and rest:
        parts = rest.split(":")
        mode = parts.pop() if len(parts) > 1 or parts[0] in ("full", "alone") else None
        if len(parts) > 1 or mode not in (None, "full", "alone"):
            raise UserError(f"bad method '{name}': use ours:default, ours:full, ours:SAMPLER[:full|:alone]")
        sampler = PlanSettings.sampler if not parts or parts[0] == "default" else check_name(parts[0])
        return {"ours": True, "sampler": sampler, "full": mode == "full", "alone": mode == "alone"}
    if kind == "ompl" and rest:
        planner, _, sampler = rest.partition("+")
        if planner not in OMPL_PLANNERS:
            raise UserError(
                f"bad method '{name}': unknown OMPL planner '{planner}' (known: {', '.join(OMPL_PLANNERS)})"
            )
        if sampler and planner != "PRM":
            raise UserError(f"bad method '{name}': only OMPL's PRM draws from a valid-state sampler")
        if sampler and sampler not in OMPL_PRM_SAMPLERS:
            check_name(sampler)
        return {"ours": False, "planner": planner, "sampler": sampler or None}
    raise UserError(
        f"bad method '{name}': use ours:default, ours:full, ours:SAMPLER[:full|:alone], ompl:PLANNER "
        f"({', '.join(OMPL_PLANNERS)}) or ompl:PRM+SAMPLER"
    )


def run_trial_spec(oracle, spec: TrialSpec) -> dict:
    """One run of `spec.method` on `spec.scene` (see the module docstring for what is measured)."""
    method = parse_method(spec.method)
    budget = float(spec.params["budget"])
    load = os.getloadavg()[0]  # the machine's 1-minute load as the run starts: its budget is wall-clock seconds
    metrics = (_ours if method["ours"] else _ompl)(oracle, spec, method, budget)
    # A run succeeds when its first solution came within the budget and its smoothed path passes the fine check.
    metrics["late"] = float(bool(metrics["solved"]) and metrics["seconds"] > budget)
    metrics["success"] = float(
        bool(metrics["solved"]) and not metrics["late"] and bool(metrics.get("fine_check_passed", 0.0))
    )
    metrics["load_average"] = load
    return metrics


# (oracle, method) pairs this process has run the planner on once (`_warm`).
_warmed: set[tuple[int, str]] = set()
WARM_SEED = 2**31 - 1  # the warm-up's seed: none a bench runs


def _warm(oracle, spec: TrialSpec, settings: PlanSettings) -> None:
    """Run the planner once, untimed, before its first timed run on this oracle in this process: the first query in
    a process pays for imports and caches that every later one finds ready, and OMPL's problem set-up is not timed
    either."""
    key = (id(oracle), spec.method)
    if key not in _warmed:
        _warmed.add(key)
        try:
            plan(oracle, dataclasses.replace(settings, seed=WARM_SEED))
        except NoPath:
            pass


def _ours(oracle, spec: TrialSpec, method: dict, budget: float) -> dict:
    settings = PlanSettings(
        sampler=method["sampler"],
        step=spec.step,
        seed=spec.seed,
        budget=Budget(seconds=budget),
        full_roadmap=method["full"],
        workspace=0.0 if method["alone"] else PlanSettings.workspace,
    )
    _warm(oracle, spec, settings)
    start = time.perf_counter()
    try:
        r = plan(oracle, settings)
    except NoPath as failure:
        checks = getattr(failure, "details", {}).get("collision_checks")
        return {"solved": 0.0, "seconds": time.perf_counter() - start, "checks": checks}
    # To the first solution: what the query spent before smoothing, proving and timing its path, the work that
    # follows OMPL's solve too (smoothing) or that OMPL does not do (the proof, which comes after smoothing).
    checks, seconds = r.stats.checks, r.stats.seconds
    out = {
        "solved": 1.0,
        "checks": r.collision_checks - checks.smoothing - checks.certify - checks.timing,
        "seconds": seconds.total - seconds.smoothing - seconds.certify - seconds.timing,
        "smoothing_checks": checks.smoothing,
        "smoothing_seconds": seconds.smoothing,
        "proof_seconds": seconds.certify,
        "raw_length": r.smoothing.raw_length,
        "path_length": r.smoothing.length_after,
    }
    return {**out, **_fine_check(oracle, r.path)}


def _fine_check(oracle, path: np.ndarray) -> dict:
    """The smoothed path held to our fine check, counted apart: the bench's own verdict, not the planner's work."""
    checker = oracle.context()
    free = checker.edges_free(path[:-1], path[1:], FINE * oracle.space.resolution)
    return {"verify_checks": checker.checks, "fine_check_passed": float(free.all())}


def _ompl(oracle, spec: TrialSpec, method: dict, budget: float) -> dict:
    from app.ompl_bridge import OmplProblem

    problem = OmplProblem(oracle, seed=spec.seed, planner=method["planner"])
    sampler = method["sampler"]
    if sampler is not None:
        problem.use_sampler(sampler, **({} if sampler in OMPL_PRM_SAMPLERS else {"step": spec.step}))
    checker, start = problem.checker, time.perf_counter()
    solved = problem.solve(budget)
    out = {
        "solved": float(solved),
        "seconds": time.perf_counter() - start,
        "checks": checker.checks,
        "space": problem.map.kind,
    }
    if not solved:
        return out
    raw = problem.solution_for_oracle()
    checks0, start = checker.checks, time.perf_counter()
    problem.simplify()
    out.update(smoothing_checks=checker.checks - checks0, smoothing_seconds=time.perf_counter() - start)
    path = problem.solution_for_oracle()  # OMPL's own motions, as our oracle's edges
    out.update(_fine_check(oracle, path))
    # Whether the first solution, before smoothing, would have passed: tells the planner's grazes from the
    # simplifier's. Ours, not OMPL's work: counted apart.
    verifier = oracle.context()
    raw_free = verifier.edges_free(raw[:-1], raw[1:], FINE * oracle.space.resolution)
    out.update(
        verify_checks=out["verify_checks"] + verifier.checks,
        raw_fine_check_passed=float(raw_free.all()),
        raw_length=path_length(oracle, raw),
        path_length=path_length(oracle, path),
    )
    return out


def specs(scenes, methods, seeds, budget, step) -> list[TrialSpec]:
    out = []
    for scene in scenes:
        a = scene_step(scene, step)
        params = {"budget": budget, "protocol": PROTOCOL}
        out.extend(
            TrialSpec("ompl", scene, method, a, seed, dict(params)) for method in methods for seed in range(seeds)
        )
    return out


def summarise(rows) -> list[dict]:
    """One row per scene x method (in the order first seen): success rate with its 95 % binomial interval, and
    medians over the successful runs of checks and seconds to the first solution, smoothing checks and path
    length, and of checks per second to the first solution. `checks_spent` is the median over all runs (what an
    unsuccessful method spent: the figure's x)."""
    from scipy.stats import binomtest

    cells = {}
    for r in rows:
        cells.setdefault((r["scene"], r["method"]), []).append(r["metrics"])
    table = []
    for (scene, method), metrics in cells.items():
        won = [m for m in metrics if m["success"]]
        n, k = len(metrics), len(won)
        ci = binomtest(k, n).proportion_ci(confidence_level=0.95)
        table.append(
            {
                "scene": scene,
                "method": method,
                "runs": n,
                "successes": k,
                "success_rate": k / n,
                "success_ci": [float(ci.low), float(ci.high)],
                "median_checks": median_or_none([m["checks"] for m in won]),
                "median_seconds": median_or_none([m["seconds"] for m in won]),
                # throughput: checks per second of planning, everything included (the planners' own work too)
                "median_checks_per_second": median_or_none(
                    [m["checks"] / m["seconds"] for m in won if m["seconds"] > 0]
                ),
                "median_smoothing_checks": median_or_none([m.get("smoothing_checks") for m in won]),
                "median_path_length": median_or_none([m.get("path_length") for m in won]),
                "checks_spent": median_or_none([m["checks"] for m in metrics]),
                # a path found, but later than the budget, or failing our fine check after smoothing
                "late": sum(1 for m in metrics if m.get("late")),
                "failed_fine_check": sum(1 for m in metrics if m["solved"] and not m.get("fine_check_passed", 0.0)),
                # of those, how many had a first solution (before smoothing) that passed it
                "failed_fine_check_after_smoothing": sum(
                    1 for m in metrics if m["solved"] and not m["fine_check_passed"] and m.get("raw_fine_check_passed")
                ),
            }
        )
    return table


def best_ompl(rows: list[dict]) -> dict | None:
    """The OMPL method with the most successes, ties broken by fewer median checks (None: no OMPL row)."""
    ompl = [r for r in rows if r["method"].startswith("ompl:")]
    if not ompl:
        return None
    return min(ompl, key=lambda r: (-r["successes"], r["median_checks"] if r["median_checks"] is not None else np.inf))


def compare(rows: list[dict], ours: str = OURS) -> dict:
    """For one scene's rows: the best OMPL method (`best_ompl`) and our default planner's median checks to the
    first solution over that method's (None when either never succeeded)."""
    best = best_ompl(rows)
    mine = next((r for r in rows if r["method"] == ours), None)
    ratio = None
    if best is not None and mine is not None and best["median_checks"] and mine["median_checks"] is not None:
        ratio = mine["median_checks"] / best["median_checks"]
    return {
        "ours": ours,
        "best_ompl": best["method"] if best is not None else None,
        "checks_ratio": ratio,
        "rule": "best OMPL method: most successes, ties broken by fewer median checks to the first solution",
    }


def motion_checks(scene: str, methods: list[str], edges: int = 200) -> list[dict]:
    """The motion-check spacing of the OMPL state spaces `methods` use on `scene` (app.ompl_bridge.motion_spacing):
    one entry per space, naming the planners that use it."""
    from app.ompl_bridge import REAL_VECTOR_ONLY, motion_spacing
    from app.scene.cspace import ConfigurationSpace

    cspace = ConfigurationSpace.of(Scene(scene))
    spaces = {}
    for method in methods:
        parts = parse_method(method)
        if not parts["ours"]:
            spaces.setdefault(parts["planner"] not in REAL_VECTOR_ONLY, []).append(method)
    out = []
    for wrap, users in spaces.items():
        out.append({**motion_spacing(cspace, wrap_angles=wrap, edges=edges), "methods": users})
    return out


def measure(
    scenes: list[str],
    methods: list[str],
    seeds: int,
    budget: float,
    step: float | None,
    store,
    workers: int = 1,
    fresh: bool = False,
) -> tuple[dict, Reuse]:
    """Every scene x method for seeds 0..seeds-1 on `budget` seconds each (trials `store` has no reusable row for
    are run; `runner.sweep`), and what was reused.

    Returns {"scenes": [{"scene", "methods": summarise rows in `methods` order, "comparison": compare(...),
    "motion_checks": motion_checks(...)}], "budget_seconds", "seeds"}. A missing OMPL or a bad method is one
    UserError before anything runs."""
    for method in methods:
        parse_method(method)
    if any(not parse_method(m)["ours"] for m in methods):
        from app.ompl_bridge import ompl_modules

        ompl_modules()
    rows, reuse = sweep(
        specs(scenes, methods, seeds, budget, step), store, workers=workers, desc="bench ompl", fresh=fresh
    )
    table = summarise(rows)
    out = []
    for scene in scenes:
        cells = {r["method"]: r for r in table if r["scene"] == scene}
        ordered = [cells[m] for m in methods if m in cells]
        out.append(
            {
                "scene": scene,
                "methods": ordered,
                "comparison": compare(ordered),
                "motion_checks": motion_checks(scene, methods),
            }
        )
    return {"scenes": out, "budget_seconds": budget, "seeds": seeds}, reuse


def figure(report: dict, path: str) -> None:
    """Success rate (with its 95 % interval) against median checks to the first solution, one panel per scene (log
    x), one marker per method; ours highlighted. A method that never succeeded is drawn hollow at y = 0, at the
    median checks it spent."""
    # matplotlib (and app.draw, which loads it) only when a figure is drawn: the command line imports this module.
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from app.draw import save

    scenes = report["scenes"]
    methods = list(dict.fromkeys(r["method"] for s in scenes for r in s["methods"]))
    style = _styles(methods)
    cols = min(5, len(scenes))
    rows = -(-len(scenes) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.3 * cols, 3.0 * rows), squeeze=False)
    for ax, s in zip(axes.flat, scenes):
        _panel(ax, s, style)
    for ax in axes.flat[len(scenes) :]:
        ax.set_visible(False)
    for ax in axes[:, 0]:
        ax.set_ylabel("success rate", fontsize=9)
    for ax in axes[-1, :]:
        ax.set_xlabel("median checks to first solution", fontsize=9)
    handles = [
        Line2D([], [], linestyle="none", marker=style[m]["marker"], color=style[m]["color"], ms=min(style[m]["ms"], 11),
               label=m)
        for m in methods
    ]  # fmt: skip
    legend = {"loc": "lower center", "fontsize": 9, "frameon": False, "bbox_to_anchor": (0.5, -0.02)}
    fig.legend(handles=handles, ncol=min(len(methods), 6), **legend)
    fig.suptitle(
        f"{report['seeds']} runs per method, {report['budget_seconds']:g} s budget each; bars: 95 % binomial "
        f"interval; hollow: no successful run (x: median checks spent)\npanel titles: our median checks over the "
        f"best OMPL planner's (most successes, then fewer checks)",
        fontsize=9,
    )
    fig.tight_layout(rect=(0, 0.06 + 0.02 * (len(methods) > 6), 1, 1))
    save(fig, path)


def _styles(methods: list[str]) -> dict:
    """A marker and colour per method: ours are stars, the default red and every other variant a colour of its own;
    OMPL's planners a marker each."""
    ompl_markers = iter(["o", "s", "^", "D", "v", "P", "X", "<", ">", "h", "p", "8"])
    other_ours = iter(["tab:orange", "tab:purple", "tab:cyan", "tab:olive", "gold", "black"])
    style = {}
    for i, m in enumerate(methods):
        if m.startswith("ours:"):
            colour = "tab:red" if m == OURS else next(other_ours, "tab:orange")
            style[m] = {"marker": "*", "color": colour, "ms": 15, "zorder": 5}
        else:
            colour = f"C{[0, 2, 4, 5, 6, 7, 8, 9, 1, 3][i % 10]}"
            style[m] = {"marker": next(ompl_markers, "o"), "color": colour, "ms": 8, "zorder": 3}
    return style


def _panel(ax, scene: dict, style: dict) -> None:
    """One scene's panel: each method's success rate (with its interval) at its median checks."""
    from matplotlib.ticker import NullFormatter

    for r in scene["methods"]:
        st = style[r["method"]]
        solved = r["median_checks"] is not None
        x = r["median_checks"] if solved else r["checks_spent"]
        if not x:
            continue
        y = r["success_rate"]
        err = [[y - r["success_ci"][0]], [r["success_ci"][1] - y]]
        ax.errorbar([x], [y], yerr=err, fmt="none", ecolor=st["color"], alpha=0.5, capsize=2, zorder=st["zorder"] - 1)
        face = st["color"] if solved else "none"
        ax.plot([x], [y], linestyle="none", marker=st["marker"], ms=st["ms"], color=st["color"],
                markerfacecolor=face, markeredgecolor=st["color"], zorder=st["zorder"])  # fmt: skip
    ax.set_xscale("log")
    ax.xaxis.set_minor_formatter(NullFormatter())  # labels at 2x, 3x ... 10^k overlapped on narrow panels
    ax.set_ylim(-0.08, 1.08)
    ax.margins(x=0.25)
    c = scene["comparison"]
    best = (c["best_ompl"] or "").split(":", 1)[-1]
    ratio = c["checks_ratio"]
    if ratio is not None:
        ratio = f"{ratio:.0f}" if ratio >= 10 else f"{ratio:.2g}"
    ax.set_title(scene["scene"] + (f"\n{OURS} / {best}: {ratio}x checks" if ratio is not None else ""), fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.tick_params(labelsize=8)
