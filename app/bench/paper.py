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

The report is built from the store alone (`--report-only` rebuilds it without running anything): the claims C1-C5
judged by `app.bench.claims.judge` (under each reading stored), markdown tables, and PNG figures next to report.md.
Every trial is also kept as DIR/trials.csv.gz, and a store starts from that file: committed results are continued.
"""

from __future__ import annotations

import csv
import gzip
import io
import json
import os
import platform
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.bench import jobs, sampling, uav
from app.bench.claims import (
    ALPHA,
    RULES,
    SAMPLER_CAP,
    checks_per_passage_sample,
    claim_c3,
    detectable_drop,
    judge,
    median_ci,
    p_text,
    sampler_gave_up,
    success_ci,
    trend,
)
from app.bench.plan import scene_step
from app.bench.runner import run_sweep
from app.bench.store import ResultStore, TrialSpec, is_results_store
from app.checking.oracle import CollisionOracle
from app.errors import UserError
from app.io import check_input, write_atomically
from app.planning.planner import default_step
from app.samplers import SAMPLERS
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


# --------------------------------------------------------------------------------------------------- the report


def _sampling_rows(rows) -> list[dict]:
    """Store rows of experiment "sampling" in the shape `sampling.summarise` reads."""
    out = []
    for r in rows:
        if r["experiment"] != "sampling":
            continue
        m = dict(r["metrics"])
        m.update(scene=r["scene"], sampler=r["method"], step=r["step"])
        if m.get("passage_fraction") is None:
            m["passage_fraction"] = float("nan")
        out.append(m)
    return out


def _fmt(value, digits=3) -> str:
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "–"
    return f"{value:.{digits}g}" if abs(value) < 1000 else f"{value:.0f}"


def _interval(cell: dict, key: str, digits=3, mark="") -> str:
    v = cell[key]
    if not np.isfinite(v["median"]):
        return "–"
    return f"{mark}{_fmt(v['median'], digits)} [{_fmt(v['lo'], digits)}, {_fmt(v['hi'], digits)}]"


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


def _figure_sample_pictures(scenes, samplers, max_checks, folder: Path) -> list[tuple[str, list[tuple[str, str]]]]:
    """One seed's K_c samples per scene x sampler, as in the paper's Figs. 3, 5, 6 (drawn as `sample --png` does)."""
    from app.draw import draw_samples  # loads matplotlib: only when a report is drawn

    out = []
    for scene in scenes:
        oracle = CollisionOracle(Scene(scene), threads=1)
        step = PICTURE_STEPS.get(scene, 10.0)
        pictures = []
        for sampler in samplers:
            r = sampling.run_trial(oracle, sampler, step, 0, k=30, max_checks=max_checks, keep_samples=True)
            name = _picture_name(scene, sampler)
            note = "" if r["ok"] else f" — over the {max_checks}-check budget with {len(r['samples'])} of 30 samples"
            draw_samples(
                oracle, r["samples"], str(folder / name), title=f"{scene}: {sampler}, step {step:g}, seed 0{note}"
            )
            pictures.append((f"{sampler}{note}", name))
        out.append((f"{scene} (step {step:g})", pictures))
    return out


def prm_cells(prm_rows) -> list[dict]:
    """Per maze/tunnel cell (scene, step, sampler): runs, successes with their interval, the runs whose sampler
    gave up at its own check cap before any roadmap (`claims.sampler_gave_up`), and the median plan time T_PRM with
    its bootstrap interval over the runs that built a roadmap (over the others, when none did: then `gave_up_only`)."""
    groups = {}
    for r in prm_rows:
        groups.setdefault((r["scene"], r["step"], r["method"]), []).append(r["metrics"])
    out = []
    for (scene, step, sampler), metrics in sorted(groups.items()):
        capped = [m for m in metrics if sampler_gave_up(m)]
        built = [m for m in metrics if not sampler_gave_up(m)]
        timed = built or capped
        med, lo, hi = median_ci([m["seconds"] for m in timed])
        ok = int(sum(m["success"] for m in metrics))
        sampling_s = [m["seconds_sampling"] for m in built if m.get("seconds_sampling") is not None]
        out.append(
            {
                "scene": scene,
                "step": step,
                "sampler": sampler,
                "runs": len(metrics),
                "successes": ok,
                "success_ci": success_ci(ok, len(metrics)),
                "gave_up": len(capped),
                "gave_up_only": not built,
                "t_prm": (med, lo, hi),
                "t_eps": float(np.median(sampling_s)) if sampling_s else None,
                "checks": float(np.median([m["collision_checks"] for m in metrics])),
            }
        )
    return out


def _figure_prm(cells: list[dict], path: Path) -> None:
    """Success rate (exact 95 % interval) and median T_PRM (95 % bootstrap interval, log scale) per maze/tunnel cell
    and sampler; a cell whose runs all gave up at the sampler's check cap is drawn hollow and hatched (censored, not
    a result); the legend below the panels."""
    # matplotlib (and app.draw, which loads it) only when a report is drawn: the command line imports this module.
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    from app.draw import save

    labels = sorted({(c["scene"], c["step"]) for c in cells})
    samplers = sorted({c["sampler"] for c in cells})
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.0))
    x = np.arange(len(labels))
    width = 0.8 / max(len(samplers), 1)
    for n, sampler in enumerate(samplers):
        by = {(c["scene"], c["step"]): c for c in cells if c["sampler"] == sampler}
        colour = f"C{n}"
        for i, label in enumerate(labels):
            c = by.get(label)
            if c is None:
                continue
            xi = x[i] + (n - (len(samplers) - 1) / 2) * width
            censored = c["gave_up_only"]
            style = (
                {"facecolor": "none", "edgecolor": colour, "hatch": "///", "linewidth": 1.0}
                if censored
                else {"color": colour}
            )
            rate = c["successes"] / c["runs"]
            lo, hi = c["success_ci"]
            if censored:  # no roadmap was built: the runs measured the cap, and the rate is unknown (all of [0, 1])
                axes[0].bar(xi, 1.0, width, alpha=0.45, **style)
                axes[0].text(
                    xi, 0.5, "censored: rate unknown", ha="center", va="center", fontsize=7, rotation=90, color=colour
                )
            else:
                axes[0].bar(xi, rate, width, **style)
                axes[0].errorbar(xi, rate, yerr=[[rate - lo], [hi - rate]], fmt="none", ecolor="black", capsize=3)
            med, tlo, thi = c["t_prm"]
            axes[1].bar(xi, med, width, **style)
            axes[1].errorbar(xi, med, yerr=[[med - tlo], [thi - med]], fmt="none", ecolor="black", capsize=3)
    ticks = [f"{s}\na = {a:g}" for s, a in labels]
    for ax in axes:
        ax.set_xticks(x, ticks, fontsize=9)
        ax.set_xlabel("scene and step a")
        ax.grid(alpha=0.3, axis="y", which="both")
    runs = max((c["runs"] for c in cells), default=0)
    axes[0].set_ylim(0, 1.05)
    axes[0].set_ylabel(f"PRM success rate ({runs} runs per cell)")
    axes[0].set_title("success, exact 95 % interval", fontsize=10)
    axes[1].set_yscale("log")
    axes[1].yaxis.set_major_formatter(ScalarFormatter())
    axes[1].yaxis.set_minor_formatter(NullFormatter())
    axes[1].set_yticks([1, 2, 5, 10, 20, 50, 100])
    axes[1].set_ylim(1, 100)
    axes[1].set_ylabel("median T_PRM (s), log scale")
    axes[1].set_title("whole plan time, 95 % bootstrap interval", fontsize=10)
    handles = [Patch(color=f"C{n}", label=s.upper()) for n, s in enumerate(samplers)]
    handles.append(
        Patch(
            facecolor="none",
            edgecolor="grey",
            hatch="///",
            label=f"censored: every run's sampler gave up at its {SAMPLER_CAP:,}-check cap (time to the cap)",
        )
    )
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    save(fig, str(path))


def build_report(
    store: ResultStore,
    folder: Path,
    config: Config | None = None,
    pictures: bool = True,
    wall_seconds: float | None = None,
    run_nothing: bool = False,
) -> Path:
    """report.md and its figures from what the store holds (every row of every experiment in it). The sample
    pictures (with `pictures` and a `config`) are drawn from new trials, or with `run_nothing` (--report-only)
    linked as earlier runs left them in `folder`."""
    folder = Path(folder)
    stored = store.rows()
    rows = reading_rows(stored, "default")
    srows = _sampling_rows(rows)
    summary = sampling.summarise(srows)
    order = {name: i for i, name in enumerate(SAMPLERS)}
    summary.sort(key=lambda s: (s["scene"], order.get(s["sampler"], 99), s["step"]))
    verdicts = judge(rows)
    claims = _claims_section(verdicts)
    readings = _readings_section(stored)
    sampling_lines = _sampling_section(srows, summary, folder)
    per_passage, per_passage_found = _checks_per_passage_section(rows)
    table1, table1_found = _table1_section(summary, rows)
    prm, prm_found = _prm_section(rows, folder)
    ur3, ur3_found = _ur3_section(rows)
    lines = _overview_section(store, stored, folder, config, wall_seconds)
    lines += _findings_section(verdicts, rows, table1_found + prm_found + ur3_found + per_passage_found)
    lines += claims + readings + sampling_lines + per_passage + table1
    if pictures and config is not None:
        lines += _pictures_section(config, folder, run_nothing)
    lines += prm + ur3
    return write_atomically(folder / "report.md", "\n".join(lines) + "\n")


def _overview_section(
    store: ResultStore, rows, folder: Path, config: Config | None, wall_seconds: float | None
) -> list[str]:
    """Title, then the machine, the code versions and trial counts in the store, and this invocation's options."""
    lines = ["# Levy-flight narrow-passage PRM: the paper's Section IV, reproduced", ""]
    lines += [
        f"Generated {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())} from `{store.path.name}` "
        f"({len(rows)} trials, every one in `{TRIALS_CSV}` beside this report). Rebuild with "
        f"`python -m app bench paper --out {folder} --report-only`.",
        "",
    ]
    by_experiment = {}
    for r in rows:
        by_experiment[r["experiment"]] = by_experiment.get(r["experiment"], 0) + 1
    versions = sorted({r["code_version"] for r in rows})
    lines += ["## Machine, code, trials", ""]
    lines += [f"- Machine: {m}" for m in machine()]
    spent = sum(float(r["metrics"].get("seconds") or 0.0) for r in rows)
    lines += [
        f"- Code version(s) of the stored trials: {', '.join(f'`{v}`' for v in versions) or '–'}",
        "- Trials per experiment: " + (", ".join(f"{k} {v}" for k, v in sorted(by_experiment.items())) or "none"),
        f"- Time in trials: {spent / 3600:.1f} h (every stored trial's own seconds, summed over the sessions and "
        "workers that ran them)",
    ]
    if config is not None:
        lines += [
            f"- Options of this invocation{' (--quick)' if config.quick else ''}: {config.trials} trials per "
            f"sampling cell, steps {', '.join(f'{a:g}' for a in config.steps)}, K_c = {config.k}, check budget "
            f"{config.max_checks} per sampling trial, {config.prm_seeds} seeds per PRM cell, "
            f"{config.ur3_runs} run(s) per UR3 job and sampler; parts: {', '.join(config.parts)}"
        ]
    if wall_seconds is not None:
        lines.append(f"- Wall time of this run's sweeps: {wall_seconds:.0f} s")
    if config is not None and config.quick:
        lines.append(
            "- **Quick run**: a handful of trials per cell. The verdicts below show the pipeline works; "
            "with so few trials most comparisons cannot reach significance, so they are not conclusive."
        )
    lines += [
        "- Timings come from trials run side by side on the worker processes; they compare samplers "
        "measured alike, not absolute speeds.",
        "",
    ]
    return lines


def _findings_section(verdicts, rows, found: list[str]) -> list[str]:
    """What holds, what came out reversed (with its test), and what was left out as an artefact, in one place."""
    lines = [
        "## What holds, what is reversed, what is an artefact",
        "",
        "Each claim's verdict (rules and evidence under Claims), the comparisons that came out significantly the "
        "other way, and what was left out of a verdict and why; then the paper's other figures beside ours.",
        "",
    ]
    for v in verdicts:
        lines.append(f"- **{v.claim}: {v.verdict}.** {v.text}")
        if v.reversals:
            lines.append("  Reversed: " + "; ".join(v.reversals) + ".")
        if v.excluded:
            lines.append("  Left out: " + "; ".join(v.excluded) + ".")
    joint = claim_c3(rows, scene="joint")
    if joint.evidence:
        word = {"reproduced": "contradicted", "reversed": "borne out"}.get(joint.verdict, "not settled")
        lines.append(
            f"- **The paper's statement that LFBS costs more than RBBS in the joint scene: {word}.** Collision checks "
            f"to K_c samples per step in joint, judged as C3 (LFBS fewer, one-sided log-rank): {joint.verdict}. "
            + "; ".join(
                e.split(": ", 1)[0] + ": " + e.rsplit("(log-rank ", 1)[-1].split(")")[0] for e in joint.evidence
            )
            + "."
        )
    lines += [f"- {f}" for f in found]
    lines.append("")
    return lines


def _claims_section(verdicts) -> list[str]:
    """The verdict table of claims C1-C5, then each claim's evidence."""
    lines = [
        "## Claims",
        "",
        "Each claim is a set of comparisons, each of which holds, fails (no significant difference either way) or "
        "is reversed (significant the other way). All hold: reproduced; all reversed: reversed; none holds: not "
        "reproduced; some: partly; no rows: no data. The rules, fixed in `app/bench/claims.py`:",
        "",
        *[f"- {rule}" for rule in RULES],
        "",
        "A sampling trial that spent its check budget is censored, not dropped: its checks count as at least what "
        "it spent, and its passage yield (passage samples per K_c requested) counts the samples it drew.",
        "",
        "| claim | verdict | statement |",
        "|---|---|---|",
    ]
    lines += [f"| {v.claim} | **{v.verdict}** | {v.text} |" for v in verdicts]
    lines.append("")
    for v in verdicts:
        lines += [f"### {v.claim}: {v.verdict}", "", v.text, ""]
        lines += [f"- {e}" for e in v.evidence] or ["- (no rows for this claim)"]
        if v.excluded:
            lines += ["", "Left out of the verdict: " + "; ".join(v.excluded) + "."]
        lines.append("")
    return lines


def _readings_section(rows) -> list[str]:
    """One verdict table, a row per reading of the paper's ambiguous points, and each reading's evidence for the
    claims its sampling trials judge (C4 is judged on the default reading's PRM trials in every row)."""
    stored = {json.dumps(r["params"].get("sampler_params", {}), sort_keys=True) for r in rows}
    others = [name for name in READINGS if name != "default" and json.dumps(READINGS[name], sort_keys=True) in stored]
    if not others:
        return []
    from app.samplers.walk import DEFAULT_READING

    default = ", ".join(f"{key} = {value}" for key, value in DEFAULT_READING.items())
    lines = [
        "## Sensitivity to the paper's readings",
        "",
        f"The paper is ambiguous on three points (`app/samplers/README.md`, Readings). The default reading ({default}) "
        "is the one above; each other row changes one choice for the samplers it affects (lfs/lfbs for the Lévy "
        "law, rwbs/lfbs for the bridge rule) and judges the claims with the same rules. C4 uses the default "
        "reading's PRM trials in every row.",
        "",
        "| reading | sampler params | C1 | C2 | C3 | C4 | C5 |",
        "|---|---|---|---|---|---|---|",
    ]
    verdicts = {name: judge(reading_rows(rows, name)) for name in ["default", *others]}
    for name, vs in verdicts.items():
        params = ", ".join(f"{k}={v}" for k, v in READINGS[name].items()) or "(default)"
        lines.append(f"| {name} | {params} | " + " | ".join(v.verdict for v in vs) + " |")
    lines.append("")
    for name in others:
        lines += [f"### Reading {name}", ""]
        for v in verdicts[name]:
            if v.claim != "C4":
                lines += [f"- {v.claim}: {e}" for e in v.evidence] or [f"- {v.claim}: no rows"]
        lines.append("")
    return lines


def _sampling_section(srows: list[dict], summary: list[dict], folder: Path) -> list[str]:
    """Per scene, a table of the sampling metrics per sampler and step, and their figure (drawn into `folder`)."""
    censored = sum(bool(r["censored"]) for r in srows)
    lines = [
        "## Sampling experiment (Figs. 4 and 7)",
        "",
        f"{len(srows)} trials of K_c samples each; {censored} of them spent their collision-check budget "
        "(censored): for those t_eps and gamma_c are lower bounds (marked ≥ where any trial in the cell was "
        "censored) and the passage fraction is over the samples drawn within the budget. Cells: median "
        "[95 % bootstrap confidence interval].",
        "",
    ]
    capped_now = [s for s in summary if s["trials"] == s["censored"] == CENSORED_CAP]
    if capped_now:
        lines += [
            f"Cells whose first {CENSORED_CAP} trials all spent the budget get no more trials: {CENSORED_CAP} of "
            f"{CENSORED_CAP} censored bounds the chance that a trial of the cell finishes within the budget below "
            f"{1 - 0.05 ** (1 / CENSORED_CAP):.1%} (exact one-sided 95 % binomial bound), and each further trial "
            "would cost the whole budget. Capped: "
            + ", ".join(f"{s['scene']} {s['sampler']} a={s['step']:g}" for s in capped_now)
            + ".",
            "",
        ]
    for scene in dict.fromkeys(s["scene"] for s in summary):
        cells = [s for s in summary if s["scene"] == scene]
        lines += [
            f"### {scene}",
            "",
            "| sampler | step | trials | censored | t_eps s | gamma_c | passage fraction |",
            "|---|---:|---:|---:|---|---|---|",
        ]
        for s in cells:
            mark = "≥" if s["censored"] else ""
            lines.append(
                f"| {s['sampler']} | {s['step']:g} | {s['trials']} | {s['censored']} | "
                f"{_interval(s, 'seconds', 3, mark)} | {_interval(s, 'collision_checks', 4, mark)} | "
                f"{_interval(s, 'passage_fraction', 2)} |"
            )
        name = f"sampling-{scene}.png"
        sampling.figure(cells, str(folder / name))
        lines += ["", f"![{scene}: metrics vs step]({name})", ""]
    return lines


def _per_step_head(title: str, rows: str, steps: list[float]) -> list[str]:
    """A title, then the head of a markdown table with a column per step a."""
    return [title, "", f"| {rows} | " + " | ".join(f"a={a:g}" for a in steps) + " |", "|---|" + "---:|" * len(steps)]


def _table1_section(summary: list[dict], rows) -> tuple[list[str], list[str]]:
    """The paper's Table 1: median t_eps per bar scene and step for RBBS and LFBS, the paper's RBBS values beside;
    then how t_eps moves with the step, the paper's and ours side by side. Returns the lines and the findings."""
    lines = [
        "## Table 1: t_eps (s) vs step, bar scenes",
        "",
        "Median t_eps over trials (≥: some trials censored at the check budget, so a lower bound); the "
        "paper's RBBS values in brackets.",
        "",
    ]
    steps = sorted({s["step"] for s in summary if s["scene"] in TABLE1_SCENES})
    if not steps:
        return lines + ["No rows.", ""], []
    for method in TABLE1_METHODS:
        lines += _per_step_head(f"**{method.upper()}**", "scene", steps)
        for scene in TABLE1_SCENES:
            cells = {s["step"]: s for s in summary if s["scene"] == scene and s["sampler"] == method}
            if not cells:
                continue
            out = []
            for a in steps:
                s = cells.get(a)
                text = "–" if s is None else f"{'≥' if s['censored'] else ''}{s['seconds']['median']:.3f}"
                if method == "rbbs" and a in STEPS:
                    text += f" ({PAPER_TABLE1[scene][STEPS.index(a)]:g})"
                out.append(text)
            lines.append(f"| {scene} | " + " | ".join(out) + " |")
        lines.append("")
    lines += [
        "**Trend with the step.** Ours: Spearman's rank correlation of every trial's t_eps with a (censored trials at "
        "their lower bounds, which lie at the small steps where t_eps is largest, so a falling trend is if anything "
        f"understated), falls/rises when p < {ALPHA:g}. The paper's: the rank correlation of its five RBBS values "
        "(no spread is published to test), rises/falls when |rho| ≥ 0.5.",
        "",
        "| scene | sampler | paper | ours | trend compared |",
        "|---|---|---|---|---|",
    ]
    found = []
    for scene in TABLE1_SCENES:
        for method in TABLE1_METHODS:
            trials = [
                r for r in rows if r["experiment"] == "sampling" and r["scene"] == scene and r["method"] == method
            ]
            if len(trials) < 3:
                continue
            ours = trend([r["step"] for r in trials], [r["metrics"]["seconds"] for r in trials])
            ours_text = f"{ours['word']} (rho {ours['rho']:+.2f}, {p_text(ours['p'])}, {ours['n']} trials)"
            if method == "rbbs":
                paper = trend(STEPS, PAPER_TABLE1[scene])
                paper_text = f"{paper['word']} (rho {paper['rho']:+.2f} over its 5 values)"
                compared = (
                    "same"
                    if paper["word"] == ours["word"]
                    else ("reversed" if {paper["word"], ours["word"]} == {"rises", "falls"} else "differs")
                )
                if compared != "same":
                    cells = sorted(
                        (x for x in summary if x["scene"] == scene and x["sampler"] == method), key=lambda x: x["step"]
                    )
                    first, last = cells[0], cells[-1]
                    found.append(
                        f"Table 1, {scene}: the paper's RBBS t_eps {_moves(paper['word'])} with a "
                        f"(rho {paper['rho']:+.2f} over its values, {PAPER_TABLE1[scene][0]:g} s to "
                        f"{PAPER_TABLE1[scene][-1]:g} s); ours "
                        f"{_moves(ours['word'])} ({'≥' if first['censored'] else ''}"
                        f"{first['seconds']['median']:.2f} s at "
                        f"a={first['step']:g} to {last['seconds']['median']:.2f} s at a={last['step']:g}; Spearman rho "
                        f"{ours['rho']:+.2f}, {p_text(ours['p'])}): **{compared}**."
                    )
            else:
                paper_text, compared = "–", "–"
            lines.append(f"| {scene} | {method} | {paper_text} | {ours_text} | {compared} |")
    lines.append("")
    return lines, found


def _moves(word: str) -> str:
    """A trend's word as a verb: 'rises', 'falls', 'is flat'."""
    return "is flat" if word == "flat" else word


def _checks_per_passage_section(rows) -> tuple[list[str], list[str]]:
    """Collision checks per sample that lands in the passage, per scene x sampler x step, with intervals; and what
    they say of LFBS against RBBS."""
    ratios = checks_per_passage_sample(rows)
    if not ratios:
        return [], []
    order = {name: i for i, name in enumerate(SAMPLERS)}
    steps = sorted({k[2] for k in ratios})
    lines = [
        "## Checks per passage sample",
        "",
        "What a sample in the passage costs: a cell's collision checks over the passage samples its trials delivered "
        "(censored trials count what they spent and what they drew), with a 95 % percentile-bootstrap interval "
        "(trials resampled, checks and samples together; ∞: no passage sample in the cell or in some resamples). "
        "Lower is cheaper.",
        "",
    ]

    def text(r) -> str:
        if not np.isfinite(r["ratio"]):
            return "∞ (none)"
        hi = "∞" if not np.isfinite(r["high"]) else _fmt(r["high"], 3)
        return f"{_fmt(r['ratio'], 3)} [{_fmt(r['low'], 3)}, {hi}]"

    for scene in sorted({k[0] for k in ratios}):
        samplers = sorted({k[1] for k in ratios if k[0] == scene}, key=lambda m: order.get(m, 99))
        lines += _per_step_head(f"### {scene}", "sampler", steps)
        for m in samplers:
            lines.append(
                f"| {m} | "
                + " | ".join(text(ratios[(scene, m, a)]) if (scene, m, a) in ratios else "–" for a in steps)
                + " |"
            )
        lines.append("")
    pairs = [
        (k, ratios[(k[0], "rbbs", k[2])]["ratio"] / r["ratio"])
        for k, r in ratios.items()
        if k[1] == "lfbs" and (k[0], "rbbs", k[2]) in ratios and np.isfinite(r["ratio"]) and r["ratio"] > 0
    ]
    found = []
    if pairs:
        lo, hi = min(pairs, key=lambda x: x[1]), max(pairs, key=lambda x: x[1])
        disjoint = sum(ratios[(k[0], "lfbs", k[2])]["high"] < ratios[(k[0], "rbbs", k[2])]["low"] for k, _ in pairs)
        reading = (
            f"Per sample that lands in the passage, LFBS needs {lo[1]:.1f}× ({lo[0][0]} a={lo[0][2]:g}) to "
            f"{hi[1]:.0f}× ({hi[0][0]} a={hi[0][2]:g}) fewer collision checks than RBBS; in {disjoint} of "
            f"{len(pairs)} scene × step cells the two intervals do not overlap. C1 counts the share of the samples "
            "drawn that land in the passage; this counts what each of them cost, bridge tests rejected on the way "
            "included."
        )
        cheapest = []
        for scene in sorted({k[0] for k in ratios}):
            best = [
                min((r["ratio"], k[1]) for k, r in ratios.items() if k[0] == scene and k[2] == a)[1]
                for a in steps
                if any(k[0] == scene and k[2] == a for k in ratios)
            ]
            top = max(set(best), key=best.count)
            cheapest.append(f"{scene} {top} ({best.count(top)} of {len(best)} steps)")
        reading += " Cheapest per passage sample, at most steps: " + ", ".join(cheapest) + "."
        lines += [reading, ""]
        found.append(reading)
    return lines, found


def _pictures_section(config: Config, folder: Path, run_nothing: bool) -> list[str]:
    """One seed's samples per scene and sampler of this invocation, drawn into `folder` (not read from the store);
    with `run_nothing`, the pictures earlier runs drew there, and a note for those missing."""
    lines = [
        "## Sample pictures (Figs. 3, 5, 6)",
        "",
        "Seed 0, K_c = 30 samples (red: in the passage). bar at step 2, the others at step 10.",
        "",
    ]
    if run_nothing:
        wanted = [
            (scene, sampler, _picture_name(scene, sampler)) for scene in config.scenes for sampler in config.samplers
        ]
        found = [w for w in wanted if (folder / w[2]).is_file()]
        missing = len(wanted) - len(found)
        lines += [
            f"Rebuilt with `--report-only`, which runs no trial: {len(found)} of {len(wanted)} pictures as an earlier "
            "run drew them" + (f"; {missing} not drawn (a run without --report-only draws them)." if missing else "."),
            "",
        ]
        sections = [
            (f"{scene} (step {PICTURE_STEPS.get(scene, 10.0):g})", [(s, n) for sc, s, n in found if sc == scene])
            for scene in config.scenes
        ]
    else:
        sections = _figure_sample_pictures(config.scenes, config.samplers, config.max_checks, folder)
    for title, items in sections:
        if items:
            lines += [f"### {title}", ""]
            lines += [f"![{label}]({name})" for label, name in items]
            lines.append("")
    return lines


def _picture_name(scene: str, sampler: str) -> str:
    return f"samples-{scene}-{sampler}.png"


def _prm_section(rows, folder: Path) -> tuple[list[str], list[str]]:
    """The maze and tunnel PRM table (LFBS vs RBBS, the paper's seconds beside), the runs censored by the sampler's
    cap, the trend of T_PRM with the step and LFBS's time over RBBS's beside the paper's, and the figure."""
    prm_rows = [r for r in rows if r["experiment"] == "prm" and r["scene"] in uav.PAPER]
    lines = ["## Maze and tunnel: LFBS vs RBBS in a PRM (Tables on maze and tunnel)", ""]
    if not prm_rows:
        return lines + ["No rows.", ""], []
    cells = prm_cells(prm_rows)
    gave_up = sum(c["gave_up"] for c in cells)
    lines += [
        "The whole roadmap, every edge checked, k = 10 (maze 200 narrow + 300 uniform, tunnel 100 + 200). "
        "t_eps = sampling time (runs that built a roadmap), T_PRM = whole plan, median [95 % bootstrap interval] over "
        "the runs that built a roadmap; paper seconds in brackets. The trial gives the plan no budget, but each call "
        f"of a narrow-passage sampler stops at its own cap of {SAMPLER_CAP:,} collision checks "
        "(`app/samplers/base.py`, `Sampler.max_checks`); a run whose sampler hit it built no roadmap (nodes = start "
        "and goal) and failed. Such a run measures the cap, not the planner: it is **censored**, counted in 'gave up', "
        f"and left out of C4 ({gave_up} of {len(prm_rows)} runs). A cell where every run gave up shows the time to the "
        "cap (≥).",
        "",
        "| scene | step | sampler | runs | gave up (no roadmap) | success [95 % CI] | t_eps s | T_PRM s | checks |",
        "|---|---:|---|---:|---:|---:|---:|---:|---:|",
    ]
    for c in cells:
        paper = uav.PAPER_SECONDS.get((c["scene"], c["step"]))
        pe, pt = ((paper[0], paper[1]) if c["sampler"] == "lfbs" else (paper[2], paper[3])) if paper else (None, None)
        eps = f"{c['t_eps']:.2f}" if c["t_eps"] is not None else "–"
        lo, hi = c["success_ci"]
        med, tlo, thi = c["t_prm"]
        mark = "≥" if c["gave_up_only"] else ""
        lines.append(
            f"| {c['scene']} | {c['step']:g} | {c['sampler']} | {c['runs']} | {c['gave_up']} | "
            f"{c['successes']}/{c['runs']} [{lo:.0%}, {hi:.0%}] | {eps} ({pe}) | "
            f"{mark}{med:.2f} [{tlo:.2f}, {thi:.2f}] ({pt}) | {c['checks']:.0f} |"
        )
    _figure_prm(cells, folder / "prm.png")
    runs = min(c["runs"] for c in cells)
    hours_at = {n: n * sum(c["t_prm"][0] for c in cells) / 3600 for n in (runs, TARGET_TRIALS)}

    def flagged(successes: int) -> str:
        edge = detectable_drop(runs, successes)
        return f"LFBS at {edge}/{runs} or fewer" if edge >= 0 else "no LFBS count (too few runs)"

    lines += [
        "",
        "![PRM success and time](prm.png)",
        "",
        f"Runs per cell: {runs}, not {TARGET_TRIALS}. A PRM run is a whole plan (RBBS spends up to a minute), so "
        f"{TARGET_TRIALS} runs per cell would take about {hours_at[TARGET_TRIALS]:.0f} h of one core here (the "
        f"cells' median plan times x {TARGET_TRIALS}; {hours_at[runs]:.1f} h at {runs}). What {runs} runs can tell "
        f"apart: the C4 success test (one-sided, p < {ALPHA:g}) flags {flagged(runs)} against RBBS's "
        f"{runs}/{runs} and {flagged(round(0.9 * runs))} against {round(0.9 * runs)}/{runs}; each cell's p values "
        "are in C4's evidence above.",
        "",
        "**Side by side with the paper.** T_PRM against the step, per scene and sampler (ours: Spearman's rank "
        f"correlation over the runs that built a roadmap, falls/rises when p < {ALPHA:g}; the paper's: the direction "
        "of its published values), and LFBS's median T_PRM over RBBS's per cell. Absolute seconds differ by two orders "
        "of magnitude (other machine, other implementation); the ratios and directions are what compare.",
        "",
        "| scene | sampler | paper T_PRM by a | ours median T_PRM by a | paper trend | ours trend |",
        "|---|---|---|---|---|---|",
    ]
    found = []
    if gave_up:
        where = ", ".join(
            f"{c['scene']} a={c['step']:g} {c['sampler']} {c['gave_up']}/{c['runs']}" for c in cells if c["gave_up"]
        )
        found.append(
            f"PRM: {gave_up} of {len(prm_rows)} runs ({where}) built no roadmap: their sampler gave up at its own "
            f"{SAMPLER_CAP:,}-check cap. They are censored (the cap, not the planner, ended them) and left out of C4."
        )
    for scene in uav.PAPER:
        steps = uav.PAPER[scene]["steps"]
        for sampler in uav.COMPARED_SAMPLERS:
            mine = {c["step"]: c for c in cells if c["scene"] == scene and c["sampler"] == sampler}
            if not mine:
                continue
            col = 1 if sampler == "lfbs" else 3
            paper_t = [uav.PAPER_SECONDS[(scene, a)][col] for a in steps]
            built = [
                r
                for r in prm_rows
                if r["scene"] == scene and r["method"] == sampler and not sampler_gave_up(r["metrics"])
            ]
            ours = (
                trend([r["step"] for r in built], [r["metrics"]["seconds"] for r in built])
                if len({r["step"] for r in built}) > 1
                else None
            )
            paper = trend(steps, paper_t)
            ours_by = ", ".join(
                f"{'≥' if mine[a]['gave_up_only'] else ''}{mine[a]['t_prm'][0]:.2f}" if a in mine else "–"
                for a in steps
            )
            ours_text = (
                f"{ours['word']} (rho {ours['rho']:+.2f}, {p_text(ours['p'])})"
                if ours
                else "– (one step with a roadmap)"
            )
            lines.append(
                f"| {scene} | {sampler} | {', '.join(f'{t:g}' for t in paper_t)} | {ours_by} | {paper['word']} | "
                f"{ours_text} |"
            )
            if ours and ours["word"] != paper["word"]:
                found.append(
                    f"{scene} {sampler}: the paper's T_PRM {_moves(paper['word'])} with a; ours {_moves(ours['word'])} "
                    f"(Spearman rho {ours['rho']:+.2f}, {p_text(ours['p'])})."
                )
    lines += ["", "| scene | step | paper LFBS/RBBS T_PRM | ours LFBS/RBBS T_PRM |", "|---|---:|---:|---:|"]
    for (scene, step), paper in uav.PAPER_SECONDS.items():
        pair = {c["sampler"]: c for c in cells if c["scene"] == scene and c["step"] == step}
        if set(pair) != {"lfbs", "rbbs"}:
            continue
        ours = pair["lfbs"]["t_prm"][0] / pair["rbbs"]["t_prm"][0]
        note = " (RBBS censored: time to the cap)" if pair["rbbs"]["gave_up_only"] else ""
        lines.append(f"| {scene} | {step:g} | {paper[1] / paper[3]:.2f} | {ours:.2f}{note} |")
    lines.append("")
    return lines, found


def _ur3_section(rows) -> tuple[list[str], list[str]]:
    """The UR3 welding and window jobs timed end to end, the paper's LFBS average beside."""
    lines = ["## UR3 welding and window jobs (the paper's UR3 timing table)", ""]
    ur3 = jobs.table(rows)
    if not ur3:
        return lines + ["No rows.", ""], []
    lines += [
        f"`app.jobs.run_job`: IK for the route's poses, then each leg straight or by PRM "
        f"(a full roadmap of {UR3_SIZE['narrow']} narrow + {UR3_SIZE['uniform']} uniform samples, "
        f"{UR3_SIZE['budget']:g} s per leg). Medians over successful runs; the paper's LFBS average in "
        "brackets (Gazebo/MoveIt set-up, step 0.5).",
        "",
        "| job | sampler | roadmap | runs | success [95 % CI] | total s | IK s | planning s | checks |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for r in ur3:
        paper = f" ({PAPER_UR3[r['job']]:g})" if r["sampler"] == "lfbs" and r["job"] in PAPER_UR3 else ""
        lo, hi = success_ci(r["successes"], r["runs"])
        lines.append(
            f"| {r['job']} | {r['sampler']} | {r['roadmap']} | {r['runs']} | "
            f"{r['successes']}/{r['runs']} [{lo:.0%}, {hi:.0%}] | "
            f"{_fmt(r['median_total'])}{paper} | {_fmt(r['median_ik'])} | "
            f"{_fmt(r['median_planning'])} | {r['median_checks']:.0f} |"
        )
    runs = min(r["runs"] for r in ur3)
    seconds = [r["metrics"]["seconds"] for r in rows if r["experiment"] == "ur3"]
    hours = TARGET_TRIALS * len(ur3) * float(np.mean(seconds)) / 3600
    found = [
        f"UR3 {r['job']} under the paper's protocol (one full roadmap of {UR3_SIZE['narrow'] + UR3_SIZE['uniform']} "
        f"samples per leg): LFBS {r['successes']}/{r['runs']}"
        + (
            f", median {_fmt(r['median_total'])} s per job (paper: {PAPER_UR3[r['job']]:g} s average)."
            if r["successes"]
            else f" — it never completes the job (paper: {PAPER_UR3[r['job']]:g} s average)."
        )
        for r in ur3
        if r["sampler"] == "lfbs" and r["job"] in PAPER_UR3
    ]
    return lines + [
        "",
        f"Runs per job and sampler: {runs}, not {TARGET_TRIALS}. A run is a whole job (IK, then a full roadmap of up "
        f"to {UR3_SIZE['budget']:g} s for each leg that is not a straight move), so {TARGET_TRIALS} runs per cell "
        f"would take about {hours:.0f} h of one core here (the mean run, failed ones included, x {TARGET_TRIALS} x "
        f"{len(ur3)} cells). The table times the jobs against the paper's; it judges no claim. Success: exact 95 % "
        "binomial interval.",
        "",
    ], found


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
