"""`bench uav`: the paper's maze and tunnel tables (LFBS vs RBBS in a PRM), reproduced on our quadrotor scenes.

Paper set-up: maze with 200 narrow + 300 PRM samples at steps 0.5 and 1; tunnel with 100 + 200 at steps 0.2, 0.5
and 1. Columns as in the paper -- t_eps (sampling time) and T_PRM (whole plan) -- plus what the paper does not
give: success rate over seeds and collision checks. Trials are `bench plan --roadmap full` trials (the whole
roadmap, every edge checked, k = 10, no budget of the plan's own) in the same results store, so a killed run resumes.
A narrow-passage sampler still gives up after its own per-call cap (`Sampler.max_checks`, 2,000,000 checks): such a
run builds no roadmap (`nodes` 2) and the paper report counts it as censored (app.bench.claims.sampler_gave_up).
"""

import numpy as np

from app.bench.claims import sampler_gave_up
from app.bench.runner import sweep
from app.bench.store import Reuse, TrialSpec

PAPER = {
    "maze": {"narrow": 200, "uniform": 300, "steps": [0.5, 1.0]},
    "tunnel": {"narrow": 100, "uniform": 200, "steps": [0.2, 0.5, 1.0]},
}
PAPER_SECONDS = {
    ("maze", 0.5): (78.49, 298.57, 162.48, 396.83),
    ("maze", 1.0): (40.22, 269.91, 102.87, 330.6),
    ("tunnel", 0.2): (74.81, 202.20, 124.56, 253.09),
    ("tunnel", 0.5): (46.67, 192.20, 102.6, 248.27),
    ("tunnel", 1.0): (28.40, 172.09, 75.11, 224.65),
}  # t_eps LFBS, T_PRM LFBS, t_eps RBBS, T_PRM RBBS
COMPARED_SAMPLERS = ["lfbs", "rbbs"]


def specs(seeds: int, scenes=PAPER) -> list[TrialSpec]:
    out = []
    for scene, setup in scenes.items():
        params = {"narrow": setup["narrow"], "uniform": setup["uniform"], "k": 10, "smooth": 10, "full_roadmap": True}
        out.extend(
            TrialSpec("prm", scene, sampler, step, seed, params)
            for step in setup["steps"]
            for sampler in COMPARED_SAMPLERS
            for seed in range(seeds)
        )
    return out


def table(rows) -> list[dict]:
    cells = {}
    for r in rows:
        cells.setdefault((r["scene"], r["step"], r["method"]), []).append(r["metrics"])
    out = []
    for (scene, step, sampler), metrics in sorted(cells.items()):
        ok = np.array([m["success"] for m in metrics], bool)
        sampling = [m["seconds_sampling"] for m in metrics if m.get("seconds_sampling") is not None]
        out.append(
            {
                "scene": scene,
                "step": step,
                "sampler": sampler,
                "runs": len(metrics),
                # runs whose sampler spent its own check cap and built no roadmap: censored, not PRM failures
                "sampler_gave_up": sum(sampler_gave_up(m) for m in metrics),
                "success_rate": float(ok.mean()),
                "median_t_eps": float(np.median(sampling)) if sampling else None,
                "median_t_prm": float(np.median([m["seconds"] for m in metrics])),
                "median_checks": float(np.median([m["collision_checks"] for m in metrics])),
            }
        )
    return out


def measure(seeds: int, store, workers: int = 1, fresh: bool = False) -> tuple[list[dict], Reuse]:
    """The paper's maze and tunnel cells for seeds 0..seeds-1 (trials `store` has no reusable row for are run;
    `runner.sweep`), as `table` rows; and what was reused."""
    rows, reuse = sweep(specs(seeds), store, workers=workers, desc="bench uav", fresh=fresh)
    return table(rows), reuse
