"""`bench ompl`: OMPL's PRM on our oracle with OMPL's samplers and ours, beside our own PRM, on one budget.

Every method gets the same wall-clock budget per seed and the same collision oracle, so "checks" means the same
thing everywhere (configurations handed to Drake). OMPL's PRM alternates grow (valid-state sampler) and expand
(uniform bounce walks) phases on its own schedule; all OMPL rows share that schedule, and the sampler is the only
thing that changes between them. Our PRM (`ours:NAME`) runs its own narrow+uniform schedule under the same budget.
"""
import time

import numpy as np

from app.bench.runner import sweep
from app.bench.store import TrialSpec
from app.planner import default_step
from app.scene import Scene
# app.ompl_bridge loads OMPL (optional) when imported: it is imported by the functions that run OMPL, so that the
# command line starts, and the other benchmarks run, without it.

OMPL_METHODS = ["ompl-uniform", "ompl-obstacle", "ompl-gaussian", "ompl-bridge", "ompl+lfbs", "ompl+rbbs"]
OURS = ["ours:lfbs", "ours:rbbs", "ours:uniform"]


def run_trial_spec(oracle, spec: TrialSpec) -> dict:
    """One OMPL PRM run: success, seconds to the first solution (or the budget), checks."""
    from app.ompl_bridge import OmplProblem

    oracle.reset()
    problem = OmplProblem(oracle, seed=spec.seed)
    name = spec.method
    if name.startswith("ompl+"):
        problem.use_sampler(name[len("ompl+"):], step=spec.step)
    else:
        problem.use_sampler(name)
    start = time.perf_counter()
    success = problem.solve(spec.params["budget"])
    seconds = time.perf_counter() - start
    if success:  # OMPL's path is checked at OMPL's resolution; hold it to ours, as our planner's paths are held
        path = problem.solution_for_oracle()  # OMPL's own motions (it does not wrap angles), not short-way edges
        success = bool(oracle.edges_free(path[:-1], path[1:], oracle.space.resolution / 4).all())
    return {"success": float(success), "seconds": seconds, "collision_checks": oracle.checks}


def specs(scenes, methods, seeds, budget, step) -> list[TrialSpec]:
    out = []
    for scene in scenes:
        a = step or default_step(Scene(scene))
        for method in methods:
            experiment = "prm" if method.startswith("ours:") else "ompl"
            name = method.split(":", 1)[1] if experiment == "prm" else method
            params = {"budget": budget}
            if experiment == "prm":
                params.update(mode="budget", full_roadmap=False)  # our planner as `plan` runs it
            out.extend(TrialSpec(experiment, scene, name, a, seed, params) for seed in range(seeds))
    return out


def summarise(rows) -> list[dict]:
    cells = {}
    for r in rows:
        label = r["method"] if r["experiment"] == "ompl" else f"ours:{r['method']}"
        cells.setdefault((r["scene"], label), []).append(r["metrics"])
    table = []
    for (scene, method), metrics in sorted(cells.items()):
        ok = np.array([m["success"] for m in metrics], bool)
        seconds = np.array([m["seconds"] for m in metrics])
        checks = np.array([m["collision_checks"] for m in metrics])
        table.append({"scene": scene, "method": method, "runs": len(metrics), "success_rate": float(ok.mean()),
                      "median_seconds": float(np.median(seconds)),
                      "median_seconds_solved": float(np.median(seconds[ok])) if ok.any() else None,
                      "median_checks": float(np.median(checks))})
    return table


def measure(scenes: list[str], methods: list[str], seeds: int, budget: float, step: float | None, store,
            workers: int = 1) -> list[dict]:
    """Every scene x method for seeds 0..seeds-1 on `budget` seconds each (trials `store` lacks are run), as
    `summarise` rows. A missing OMPL is one UserError before anything runs."""
    from app.ompl_bridge import ompl_modules

    ompl_modules()
    return summarise(sweep(specs(scenes, methods, seeds, budget, step), store, workers=workers, desc="bench ompl"))
