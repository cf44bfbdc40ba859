"""`bench plan`: PRM success rate and time per narrow-passage sampler, at one fixed roadmap size, over many seeds.

Each trial is one `app.planning.planner.plan` call (up to narrow + uniform samples; `--full-roadmap` for the paper's
protocol of the whole roadmap first, with no budget of its own: only each sampler call's cap, `Sampler.max_checks`,
2,000,000 checks, ends it early, and a run it ends has no roadmap: `nodes` 2) on a per-process oracle;
rows go to the results store (`experiment` "prm"), so a killed run resumes and the claims report can read them.
`run_trial_spec` also serves other benchmarks: params {"mode": "budget", "budget": seconds} plans in rounds until
connected or out of time (as `plan --budget 30s`).
"""

import os
import time

import numpy as np

from app.bench.oracle import raw_checks_per_second
from app.bench.runner import sweep
from app.bench.store import Reuse, TrialSpec
from app.checking.budget import Budget
from app.errors import NoPath
from app.planning.query import plan
from app.planning.settings import DEFAULT_BUDGET, PlanSettings, default_step
from app.scene.cspace import ConfigurationSpace
from app.scene.model import Scene

COMPARED_SAMPLERS = ["uniform", "gaussian", "rbbs", "lfbs"]  # the default of `bench plan --samplers`
MODES = {"query": False, "full": True}  # roadmap mode -> plan(full_roadmap=...)
# What a plain `plan` does: the same roadmap size, k (None: k-PRM*) and smoothing.
SIZE = {
    "narrow": PlanSettings.narrow,
    "uniform": PlanSettings.uniform,
    "k": PlanSettings.k,
    "smooth": PlanSettings.smooth_rounds,
}


def drake_seconds(oracle) -> float:
    """Seconds the oracle has spent in Drake's answers (collision checks, signed distances, point queries) since it
    was made: the difference over a run is the part of the run's time that Drake's queries took."""
    return sum(oracle.seconds.values())


def run_trial_spec(oracle, spec: TrialSpec) -> dict:
    """One plan: success, seconds (whole pipeline; `seconds_drake` of them in Drake's queries), seconds to a path,
    checks, roadmap and path facts."""
    p = spec.params
    # Without a budget of its own a trial has the planner's default; the paper's fixed roadmap is not cut short.
    full_roadmap = bool(p.get("full_roadmap", True))
    budget = (
        Budget(seconds=float(p["budget"]))
        if p.get("mode") == "budget"
        else Budget()
        if full_roadmap
        else DEFAULT_BUDGET
    )
    narrow = int(p.get("narrow", SIZE["narrow"]))
    uniform = int(p.get("uniform", SIZE["uniform"]))
    if spec.method == "uniform":  # the same roadmap size, all of it uniform
        narrow, uniform = 0, narrow + uniform
    load = os.getloadavg()[0]  # the machine's 1-minute load as the trial starts: what its seconds were measured under
    start, drake = time.perf_counter(), drake_seconds(oracle)
    try:
        r = plan(
            oracle,
            PlanSettings(
                sampler=spec.method,
                narrow=narrow,
                uniform=uniform,
                step=spec.step,
                seed=spec.seed,
                budget=budget,
                k=p.get("k", SIZE["k"]),
                smooth_rounds=int(p.get("smooth", SIZE["smooth"])),
                full_roadmap=full_roadmap,
                workspace=float(p.get("workspace", PlanSettings.workspace)),
            ),
        )
    except NoPath as exc:
        d = getattr(exc, "details", {})
        return {
            "success": 0.0,
            "seconds": time.perf_counter() - start,
            "seconds_drake": drake_seconds(oracle) - drake,
            "seconds_to_path": None,
            "collision_checks": d.get("collision_checks"),
            "nodes": d.get("roadmap", {}).get("nodes"),
            "components": d.get("roadmap", {}).get("components"),
            "rounds": d.get("rounds"),
            "load_average": load,
        }
    s = r.stats.seconds
    drake = drake_seconds(oracle) - drake
    return {
        "success": 1.0,
        "seconds": s.total,
        "seconds_drake": drake,
        # beside the plan, so that its ratio is to Drake's pace on this machine at this moment
        "raw_checks_per_second": raw_checks_per_second(oracle, seed=spec.seed),
        "seconds_sampling": s.sampling,
        "seconds_to_path": s.sampling + s.roadmap + s.search,
        "collision_checks": r.collision_checks,
        "nodes": r.stats.roadmap.nodes,
        "components": r.stats.roadmap.components,
        "rounds": r.stats.rounds,
        "narrow_on_path": r.narrow_on_path,
        "workspace_on_path": r.workspace_on_path,
        "path_length": r.smoothing.length_after,
        "duration": r.trajectory.duration,
        "certified": bool(r.certified),
        "load_average": load,
    }


def scene_step(scene: str, step: float | None) -> float:
    """The sampler step a benchmark uses in `scene`: `step` if given, checked against the scene before any trial
    runs (a step longer than its diagonal never ends a walk), else the scene's default."""
    model = Scene(scene)
    return ConfigurationSpace.of(model).check_step(step) if step else default_step(model)


def specs(scenes, samplers, seeds, params, step) -> list[TrialSpec]:
    out = []
    for scene in scenes:
        a = scene_step(scene, step)
        out.extend(TrialSpec("prm", scene, m, a, seed, dict(params)) for m in samplers for seed in range(seeds))
    return out


def summarise(rows) -> list[dict]:
    cells = {}
    for r in rows:
        mode = "full" if r["params"]["full_roadmap"] else "query"
        cells.setdefault((r["scene"], r["method"], mode), []).append(r["metrics"])
    table = []
    for (scene, method, mode), metrics in cells.items():
        ok = np.array([m["success"] for m in metrics], bool)
        seconds = np.array([m["seconds"] for m in metrics])
        checks = np.array([m["collision_checks"] for m in metrics])
        to_path = np.array([m["seconds_to_path"] for m in metrics if m["success"]])
        narrow = np.array([m["narrow_on_path"] for m in metrics if m["success"]])
        certified = [m["certified"] for m in metrics if m["success"] and "certified" in m]
        placed = [m["workspace_on_path"] for m in metrics if m["success"] and "workspace_on_path" in m]
        # rows stored before the time in Drake's queries was measured have none
        shares = [m["seconds_drake"] / m["seconds"] for m in metrics if "seconds_drake" in m and m["seconds"] > 0]
        of_raw = [
            m["collision_checks"] / m["seconds"] / m["raw_checks_per_second"]
            for m in metrics
            if m["success"] and m.get("raw_checks_per_second") and m["seconds"] > 0
        ]
        table.append(
            {
                "scene": scene,
                "sampler": method,
                "roadmap": mode,
                "runs": len(metrics),
                "successes": int(ok.sum()),
                "success_rate": float(ok.mean()),
                "median_seconds": float(np.median(seconds)),
                "median_seconds_to_path": float(np.median(to_path)) if ok.any() else None,
                "median_checks": float(np.median(checks)),
                "median_narrow_on_path": float(np.median(narrow)) if ok.any() else None,
                "median_workspace_on_path": float(np.median(placed)) if placed else None,
                "median_checks_per_second": float(np.median(checks / seconds)),
                # of the successes; rows stored before this was recorded have none
                "certified_share": float(np.mean(certified)) if certified else None,
                "median_drake_share": float(np.median(shares)) if shares else None,
                # a plan's checks per second over a raw HasCollisions loop's beside it (rows stored before this
                # was measured have none)
                "median_of_raw": float(np.median(of_raw)) if of_raw else None,
            }
        )
    return table


def trial_params(
    narrow: int, uniform: int, k: int | None, smooth: int, budget: float | None = None, workspace: float | None = None
) -> dict:
    """A plan trial's params: roadmap size, k (None: k-PRM*'s) and shortcut rounds; with `budget` (seconds),
    rounds go on until connected or spent instead of one roadmap of that size; with `workspace`, that share of the
    narrow-passage samples placed in workspace gaps instead of the planner's default (0: the sampler alone). Left
    out when not given, so that trials stored before keep their keys (a key hashes the params)."""
    params = {"narrow": narrow, "uniform": uniform, "k": k, "smooth": smooth}
    if budget is not None:
        params.update(mode="budget", budget=budget)
    if workspace is not None:
        params["workspace"] = workspace
    return params


def measure(
    scenes: list[str],
    samplers: list[str],
    seeds: int,
    params: dict,
    store,
    modes=("query",),
    step: float | None = None,
    workers: int = 1,
    fresh: bool = False,
) -> tuple[list[dict], Reuse]:
    """The plan trials (`trial_params`) of every scene x sampler x roadmap mode (`MODES`) for seeds 0..seeds-1 that
    `store` has no reusable row for (`runner.sweep`), then the summary of exactly these trials: one row per scene x
    sampler x mode, in that order; and what was reused."""
    todo = []
    for mode in modes:
        todo += specs(scenes, samplers, seeds, {**params, "full_roadmap": MODES[mode]}, step)
    rows, reuse = sweep(todo, store, workers=workers, desc="bench plan", fresh=fresh)
    order = {key: i for i, key in enumerate((sc, sa, mode) for sc in scenes for sa in samplers for mode in modes)}
    return sorted(summarise(rows), key=lambda r: order.get((r["scene"], r["sampler"], r["roadmap"]), 1e9)), reuse
