"""`bench paper`: the paper's Section IV in one command -- every sweep into one results store, then DIR/report.md.

Sweeps (each a list of TrialSpecs built deterministically from the options, run by `runner.run_sweep`, so a killed
run started again with the same options skips every stored trial):

1. sampling -- the seven samplers x bar, joint, joint3d, teeth3d x steps 2..20 x N trials, K_c = 30 samples each,
   with a per-trial collision-check budget (a trial that spends it is censored: its t_eps and gamma_c are lower
   bounds and its passage fraction is over the samples it drew);
   with `readings`, the same for the walkers each other reading of the paper (READINGS) changes;
2. table1 -- RBBS and LFBS t_eps vs step on bar-3link, bar-5link and bar (the paper's Table 1; the bar cells are the
   same trials as sweep 1 and are not run twice);
3. prm -- the maze/tunnel LFBS-vs-RBBS PRM tables (`bench uav` specs);
4. ur3 -- the scripted UR3 welding and window jobs (`app.jobs.run_job`), timed (experiment "ur3", the trial of
   `bench jobs`).

The report is built from the store alone (app.bench.paper_report; `--report-only` rebuilds it without running
anything): the claims C1-C5 judged by `app.bench.claims.judge` (under each reading stored), markdown tables, and PNG
figures next to report.md. Every trial is also kept as DIR/trials.csv.gz, and a store starts from that file:
committed results are continued.
"""

from __future__ import annotations

import csv
import gzip
import io
import json
import os
import platform
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.bench import uav
from app.bench.plan import scene_step
from app.bench.runner import run_sweep
from app.bench.store import ResultStore, TrialSpec, is_results_store
from app.errors import UserError
from app.io import check_input, write_atomically
from app.planning.settings import default_step
from app.scene.model import Scene

SAMPLING_SCENES = ["bar", "joint", "joint3d", "teeth3d"]
TABLE1_SCENES = ["bar-3link", "bar-5link", "bar"]
TABLE1_METHODS = ["rbbs", "lfbs"]
STEPS = [2.0, 5.0, 10.0, 15.0, 20.0]
QUICK_STEPS = [2.0, 10.0]
PARTS = ["sampling", "table1", "prm", "ur3"]
UR3_JOBS = ["welding", "window"]
UR3_SAMPLERS = ["lfbs", "rbbs"]
# The paper: 200 LFBS samples, a 100-node PRM, built whole before the query.
UR3_SIZE = {"narrow": 200, "uniform": 100, "budget": 30.0, "full_roadmap": True}
PICTURE_STEPS = {"bar": 2.0, "joint": 10.0, "joint3d": 10.0, "teeth3d": 10.0}  # the paper's Figs. 3, 5, 6
PAPER_TABLE1 = {
    "bar-3link": [6.9561, 6.1784, 6.3532, 6.4736, 6.8388],
    "bar-5link": [7.4344, 7.60037, 7.9361, 9.9487, 12.005],
    "bar": [10.923, 9.3731, 9.5287, 12.665, 17.128],
}  # RBBS t_eps (s) at steps 2, 5, 10, 15, 20
PAPER_UR3 = {"welding": 233.0, "window": 253.0}  # LFBS-PRM, average seconds
# The readings of the paper's ambiguous points (app/samplers/walk.py) the claims are judged under: the default
# reading (walk.DEFAULT_READING), then each other choice alone. Sampler params, as a Walker takes them.
READINGS = {
    "default": {},
    "alpha-density": {"alpha_convention": "density"},
    "angle-length": {"angle_law": "length"},
    "angle-gaussian": {"angle_law": "gaussian"},
    "bridge-move": {"bridge_fail": "move"},
}
TARGET_TRIALS = 300  # trials per cell the protocol asks for
# A sampling cell whose first CENSORED_CAP trials all spent their check budget gets no more: 30 of 30 censored
# bounds the chance that one of its trials finishes within the budget below 9.5 % (exact one-sided 95 % binomial
# bound, 1 - 0.05 ** (1 / 30)), tighter than any verdict needs, and each further trial would cost the whole budget.
CENSORED_CAP = 30
# The samplers whose draws each choice changes: the Lévy walkers' steps, the bridge walkers' rule.
READING_SAMPLERS = {"alpha_convention": ("lfs", "lfbs"), "angle_law": ("lfs", "lfbs"), "bridge_fail": ("rwbs", "lfbs")}


@dataclass
class Config:
    trials: int = TARGET_TRIALS
    steps: list = field(default_factory=lambda: list(STEPS))
    scenes: list = field(default_factory=lambda: list(SAMPLING_SCENES))
    samplers: list = field(default_factory=list)
    max_checks: int = 200_000
    k: int = 30
    prm_seeds: int = 30
    ur3_runs: int = 20
    parts: list = field(default_factory=lambda: list(PARTS))
    quick: bool = False
    readings: bool = False  # also the sampling sweep of the walkers each non-default reading changes


# ----------------------------------------------------------------------------------------------------- the sweeps


def sampling_specs(scenes, samplers, steps, trials, k=30, max_checks=200_000, sampler_params=None) -> list[TrialSpec]:
    params = {"k": int(k), "max_checks": int(max_checks)}
    if sampler_params:
        params["sampler_params"] = dict(sampler_params)
    return [
        TrialSpec("sampling", scene, sampler, float(step), seed, dict(params))
        for scene in scenes
        for sampler in samplers
        for step in steps
        for seed in range(trials)
    ]


def ur3_specs(runs: int) -> list[TrialSpec]:
    steps = {job: default_step(Scene(job)) for job in UR3_JOBS}
    return [
        TrialSpec("ur3", job, sampler, steps[job], seed, dict(UR3_SIZE))
        for job in UR3_JOBS
        for sampler in UR3_SAMPLERS
        for seed in range(runs)
    ]


def sweeps(config: Config) -> list[tuple[str, list[TrialSpec]]]:
    """Every sweep's specs, in a fixed order: the same options always give the same list (and keys)."""
    out = []
    if "sampling" in config.parts:
        out.append(
            (
                "sampling",
                sampling_specs(
                    config.scenes, config.samplers, config.steps, config.trials, config.k, config.max_checks
                ),
            )
        )
    if "table1" in config.parts:
        out.append(
            (
                "table1",
                sampling_specs(TABLE1_SCENES, TABLE1_METHODS, config.steps, config.trials, config.k, config.max_checks),
            )
        )
    if "sampling" in config.parts and config.readings:
        for name, params in READINGS.items():
            changed = [s for s in config.samplers if s in reading_samplers(params)]
            if changed:
                specs = sampling_specs(
                    config.scenes, changed, config.steps, config.trials, config.k, config.max_checks, params
                )
                out.append((f"reading {name}", specs))
    if "prm" in config.parts:
        out.append(("prm", uav.specs(config.prm_seeds)))  # the maze/tunnel cells of `bench uav`
    if "ur3" in config.parts:
        out.append(("ur3", ur3_specs(config.ur3_runs)))
    return out


def check_steps(config: Config) -> None:
    """Before any trial: every sampling scene is known and takes every step (a UserError names the first that is
    not or does not), so a typo fails at once instead of in a worker after the store is made."""
    scenes = (config.scenes if "sampling" in config.parts else []) + (TABLE1_SCENES if "table1" in config.parts else [])
    for scene in dict.fromkeys(scenes):
        for step in config.steps:
            scene_step(scene, step)


# ------------------------------------------------------------------------------------------ the committed trials

TRIALS_CSV = "trials.csv.gz"
CSV_COLUMNS = ["experiment", "scene", "method", "step", "seed", "params", "metrics", "code_version"]


STORE = "results.sqlite"


def results_in(folder: Path) -> bool:
    """Whether `folder` holds results of `bench paper`: a results store, or a trials file with this CSV header."""
    folder = Path(folder)
    if is_results_store(folder / STORE):
        return True
    trials = folder / TRIALS_CSV
    try:
        with gzip.open(trials, "rt", newline="") as f:
            return next(csv.reader([f.readline()]), None) == CSV_COLUMNS
    except (OSError, EOFError, UnicodeDecodeError):
        return False


def check_folder(folder: Path, report_only: bool) -> None:
    """Before any work: `folder` may receive a report. A new or empty folder, or one of bench paper's own (see
    `results_in`); never another folder, whose files a report would overwrite. --report-only needs results there."""
    folder = Path(folder)
    has_results = folder.is_dir() and results_in(folder)
    if report_only and not has_results:
        raise UserError(
            f"--report-only: {folder} holds no results of bench paper ({STORE} or {TRIALS_CSV}); it runs nothing, "
            "so there is nothing to report"
        )
    if folder.is_dir() and not has_results and any(folder.iterdir()):
        raise UserError(
            f"--out {folder} is a folder of other files (no {STORE} or {TRIALS_CSV} of bench paper in it), which the "
            "report would overwrite; name a new or empty folder"
        )


def export_trials(store: ResultStore, path: Path) -> Path:
    """Every trial of `store` as gzipped CSV (params and metrics as JSON), in a fixed order and with no timestamp
    inside, so the same trials always give the same file."""
    rows = sorted(
        store.rows(),
        key=lambda r: (r["experiment"], r["scene"], r["method"], r["step"], r["seed"], json.dumps(r["params"])),
    )
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for r in rows:
        writer.writerow(
            [
                *(r[c] for c in CSV_COLUMNS[:5]),
                json.dumps(r["params"], sort_keys=True),
                json.dumps(r["metrics"]),
                r["code_version"],
            ]
        )
    return write_atomically(path, gzip.compress(text.getvalue().encode(), mtime=0))


def import_trials(store: ResultStore, path: Path) -> int:
    """Add the trials of an `export_trials` file that `store` lacks (a run resumed from committed results runs only
    the rest); returns how many were added."""
    with gzip.open(check_input(path, "trials file"), "rt", newline="") as f:
        rows = [
            {
                **r,
                "step": float(r["step"]),
                "seed": int(r["seed"]),
                "params": json.loads(r["params"]),
                "metrics": json.loads(r["metrics"]),
            }
            for r in csv.DictReader(f)
        ]
    return store.import_rows(rows)


def _cell(scene: str, method: str, step: float, params: dict) -> tuple:
    return scene, method, float(step), json.dumps(params, sort_keys=True)


def capped_cells(rows) -> set[tuple]:
    """The sampling cells whose seeds 0..CENSORED_CAP-1 are all stored and all censored (see CENSORED_CAP)."""
    censored: dict[tuple, list] = {}
    for r in rows:
        if r["experiment"] == "sampling" and r["seed"] < CENSORED_CAP:
            cell = _cell(r["scene"], r["method"], r["step"], r["params"])
            censored.setdefault(cell, []).append(not r["metrics"]["ok"])
    return {cell for cell, flags in censored.items() if len(flags) == CENSORED_CAP and all(flags)}


def capped(specs: list[TrialSpec], store: ResultStore) -> list[TrialSpec]:
    """`specs` without the seeds from CENSORED_CAP on of the capped cells."""
    full = capped_cells(store.rows("sampling"))
    return [
        s
        for s in specs
        if not (
            s.experiment == "sampling" and s.seed >= CENSORED_CAP and _cell(s.scene, s.method, s.step, s.params) in full
        )
    ]


def reading_samplers(params: dict) -> set[str]:
    """The samplers whose draws a reading's sampler params change."""
    return {s for key in params for s in READING_SAMPLERS[key]}


def reading_rows(rows, name: str) -> list[dict]:
    """The rows the claims are judged on under reading `name`: the sampling trials of the samplers it changes run
    with its params, every other row as in the default reading."""
    params = READINGS[name]
    changed = reading_samplers(params)

    def belongs(r) -> bool:
        own = r["params"].get("sampler_params", {})
        return own == params if r["experiment"] == "sampling" and r["method"] in changed else own == {}

    return [r for r in rows if belongs(r)]


def machine() -> list[str]:
    import sys

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        from importlib.metadata import version

        drake = version("drake")
    except Exception:  # noqa: BLE001 - a report line, never a failure
        drake = "unknown"
    return [
        f"{platform.node()}: {platform.system()} {platform.release()}, {cpu}, {os.cpu_count()} cores",
        f"Python {sys.version.split()[0]}, Drake {drake}, numpy {np.__version__}",
    ]


def run_sweeps(config: Config, store: ResultStore, workers: int = 0, scheduler=None, fresh: bool = False):
    """Run every sweep of `config` into `store` (trials it holds a reusable row for are skipped, see
    `ResultStore.pending`; a trial in two sweeps runs once). Yields (sweep name, what it reused (a Reuse), how many
    ran now) as each sweep ends. workers, scheduler, fresh: as `runner.run_sweep`."""
    seen = set()
    for name, specs in sweeps(config):
        specs = [s for s in specs if not (s.key in seen or seen.add(s.key))]  # table1's bar = sampling's bar
        specs = capped(specs, store)
        reuse = store.reuse(specs, fresh=fresh)
        ran = run_sweep(specs, store, workers=workers, scheduler=scheduler, desc=f"paper {name}", fresh=fresh)
        yield name, reuse, ran
