"""`bench certify`: what continuous certification and smooth timing cost, and what the smooth timing gains.

Per scene and seed, one default query (`plan SCENE --seed S`): its phase timings say how long certifying the path (phase
"certify") and timing it smoothly with certified blends (phase "timing") took. What a planner without certification
would do instead is then done to the same path: re-check it at the fine resolution (FINE x the scene's, the discrete
check the certificate replaced) and time it rest to rest at every waypoint (`app.motion.timing.parameterize`); that time
stands in for both phases in the plan time "without". So the two plan times compare the same query, in one run. The
certificate's cost per configuration is its own time (set-up and every proof, of the path and of its blends) over the
distance queries it asked Drake, beside the time of those queries alone. Per UR3 job and seed (`run window --seed S`):
the joined trajectory's duration against each leg's path timed rest to rest at every waypoint.

Trials are experiments "certify" (scenes) and "certify-job" in the results store, so a killed run resumes.
"""

import time
from dataclasses import replace

import numpy as np

from app.bench.plan import drake_seconds
from app.bench.runner import sweep
from app.bench.store import Reuse, TrialSpec
from app.errors import NoPath, UserError
from app.jobs import JOB_SETTINGS, run_job
from app.motion.path import verify
from app.motion.timing import parameterize
from app.planning.query import plan
from app.planning.settings import PlanSettings, default_step
from app.scene.model import Scene


def _rest_to_rest(oracle, path: np.ndarray) -> tuple[float, float]:
    """(duration, seconds to compute) of `path` timed rest to rest at every waypoint."""
    scene, clock = oracle.scene, time.perf_counter()
    trajectory = parameterize(oracle.plant, oracle.space.unwrap(path), scene.velocity_limits, scene.acceleration_limits)
    return trajectory.duration, time.perf_counter() - clock


def _full_speed(oracle, path: np.ndarray) -> float:
    """A lower bound on the duration of any motion along `path`'s straight edges within the velocity limits (the
    slowest joint of each edge at full speed all along it, no acceleration limit): what timing can gain is bounded
    by it, whatever the blends and the acceleration limits."""
    W = oracle.space.unwrap(path)
    return float(np.sum(np.max(np.abs(np.diff(W, axis=0)) / np.asarray(oracle.scene.velocity_limits), axis=1)))


def run_trial_spec(oracle, spec: TrialSpec) -> dict:
    """One default query on a scene: plan seconds with certification and smooth timing, and without (the phases
    replaced by a fine re-check and rest-to-rest timing), the seconds of the query in Drake's queries, and the
    smooth and rest-to-rest durations."""
    drake, distances = drake_seconds(oracle), oracle.seconds["distances"]
    try:
        r = plan(oracle, PlanSettings(seed=spec.seed, step=spec.step))
    except NoPath:
        return {"success": False}
    drake, distances = drake_seconds(oracle) - drake, oracle.seconds["distances"] - distances
    duration, seconds = _rest_to_rest(oracle, r.path)
    clock = time.perf_counter()
    verify(oracle.context(), r.path)
    seconds += time.perf_counter() - clock
    s = r.stats.seconds
    return {
        "success": True,
        "seconds": s.total,
        "seconds_drake": drake,
        "seconds_certify": s.certify,
        "seconds_timing": s.timing,
        "seconds_without": s.total - s.certify - s.timing + seconds,
        "certified": bool(r.trajectory.certified),
        "distance_queries": r.stats.distance_queries,
        "seconds_certificate": r.stats.certificate_seconds,
        "seconds_distances": distances,
        "duration": r.trajectory.duration,
        "duration_rest_to_rest": duration,
        "duration_full_speed": _full_speed(oracle, r.path),
    }


def run_job_trial_spec(oracle, spec: TrialSpec) -> dict:
    """One scripted UR3 job: its duration, and its legs' paths timed rest to rest at every waypoint."""
    try:
        r = run_job(oracle, spec.scene, replace(JOB_SETTINGS, seed=spec.seed))
    except UserError:
        return {"success": False}
    return {
        "success": True,
        "seconds": r.seconds["total"],
        "duration": r.trajectory.duration,
        "duration_rest_to_rest": sum(_rest_to_rest(oracle, leg.path)[0] for leg in r.legs),
        "duration_full_speed": sum(_full_speed(oracle, leg.path) for leg in r.legs),
    }


def _median(metrics: list[dict], key: str) -> float | None:
    values = [m[key] for m in metrics if m["success"]]
    return float(np.median(values)) if values else None


def summarise(rows: list[dict], cells: list[tuple[str, str]]) -> list[dict]:
    """Per (experiment, scene or job) of `cells`, in that order: runs, successes, median plan seconds with and
    without certification and smooth timing and the overhead (with / without - 1, of the medians), and the median
    duration ratios over rest to rest, per run: of the smooth trajectory, and of the full-speed lower bound."""
    out = []
    for experiment, name in cells:
        metrics = [r["metrics"] for r in rows if (r["experiment"], r["scene"]) == (experiment, name)]
        ok = [m for m in metrics if m["success"]]
        row = {
            "name": name if experiment == "certify" else f"{name} job",
            "runs": len(metrics),
            "successes": len(ok),
            "median_seconds": _median(metrics, "seconds"),
        }
        if ok and "seconds_without" in ok[0]:
            row["median_seconds_without"] = _median(metrics, "seconds_without")
            row["median_seconds_certify"] = _median(metrics, "seconds_certify")
            row["median_seconds_timing"] = _median(metrics, "seconds_timing")
            row["overhead"] = row["median_seconds"] / row["median_seconds_without"] - 1
            row["certified"] = sum(m["certified"] for m in ok)
            # rows stored before the time in Drake's queries was measured have none
            shares = [m["seconds_drake"] / m["seconds"] for m in ok if "seconds_drake" in m and m["seconds"] > 0]
            row["median_drake_share"] = float(np.median(shares)) if shares else None
            # The certificate's cost per configuration it asks Drake about, all its work included, beside Drake's
            # distance query alone (rows stored before these were measured have none).
            asked = [m for m in ok if m.get("seconds_certificate") is not None and m["distance_queries"] > 0]
            for key, seconds in (("certificate", "seconds_certificate"), ("drake", "seconds_distances")):
                per = [1e3 * m[seconds] / m["distance_queries"] for m in asked]
                row[f"median_{key}_ms_per_configuration"] = float(np.median(per)) if per else None
        ratio_of = {"median_duration_ratio": "duration", "median_full_speed_ratio": "duration_full_speed"}
        for key, duration in ratio_of.items():
            # rows stored before the full-speed bound was measured have none
            pairs = [(m.get(duration), m["duration_rest_to_rest"]) for m in ok]
            ratios = [d / rest for d, rest in pairs if d and rest > 0]
            row[key] = float(np.median(ratios)) if ratios else None
        out.append(row)
    return out


def measure(scenes: list[str], jobs: list[str], seeds: int, store, fresh: bool = False) -> tuple[list[dict], Reuse]:
    """Seeds 0..seeds-1 of every scene's default query and every job, in this process (timings undisturbed)."""
    todo = [TrialSpec("certify", s, "default", default_step(Scene(s)), seed) for s in scenes for seed in range(seeds)]
    todo += [TrialSpec("certify-job", j, JOB_SETTINGS.sampler, 0.0, seed) for j in jobs for seed in range(seeds)]
    cells = [("certify", s) for s in scenes] + [("certify-job", j) for j in jobs]
    rows, reuse = sweep(todo, store, workers=1, desc="bench certify", fresh=fresh)
    return summarise(rows, cells), reuse
