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
from app.bench.claims import ALPHA, RULES, detectable_drop, judge, success_ci
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


def _figure_prm(table: list[dict], path: Path) -> None:
    # matplotlib (and app.draw, which loads it) only when a report is drawn: the command line imports this module.
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from app.draw import save

    labels = sorted({(r["scene"], r["step"]) for r in table})
    samplers = sorted({r["sampler"] for r in table})
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    x = np.arange(len(labels))
    width = 0.8 / max(len(samplers), 1)
    for n, sampler in enumerate(samplers):
        cells = {(r["scene"], r["step"]): r for r in table if r["sampler"] == sampler}
        ok = [cells[c]["success_rate"] if c in cells else np.nan for c in labels]
        t = [cells[c]["median_t_prm"] if c in cells else np.nan for c in labels]
        axes[0].bar(x + n * width, ok, width, label=sampler, color=f"C{n}")
        axes[1].bar(x + n * width, t, width, label=sampler, color=f"C{n}")
    for ax, title in zip(axes, ("PRM success rate", "median T_PRM (s)")):
        ax.set_xticks(x + width * (len(samplers) - 1) / 2, [f"{s} a={a:g}" for s, a in labels], fontsize=8)
        ax.set_title(title)
        ax.grid(alpha=0.3, axis="y")
    axes[0].set_ylim(0, 1.05)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
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
    lines = _overview_section(store, stored, folder, config, wall_seconds)
    lines += _claims_section(rows)
    lines += _readings_section(stored)
    lines += _sampling_section(srows, summary, folder)
    lines += _table1_section(summary)
    if pictures and config is not None:
        lines += _pictures_section(config, folder, run_nothing)
    lines += _prm_section(rows, folder)
    lines += _ur3_section(rows)
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


def _claims_section(rows) -> list[str]:
    """The verdict table of claims C1-C5, then each claim's evidence."""
    lines = [
        "## Claims",
        "",
        "Each claim is a set of comparisons. All hold: reproduced; none: not reproduced; some: partly; no rows: "
        "no data. The rules, fixed in `app/bench/claims.py`:",
        "",
        *[f"- {rule}" for rule in RULES],
        "",
        "A sampling trial that spent its check budget is censored, not dropped: its checks count as at least what "
        "it spent, and its passage yield (passage samples per K_c requested) counts the samples it drew.",
        "",
        "| claim | verdict | statement |",
        "|---|---|---|",
    ]
    verdicts = judge(rows)
    lines += [f"| {v.claim} | **{v.verdict}** | {v.text} |" for v in verdicts]
    lines.append("")
    for v in verdicts:
        lines += [f"### {v.claim}: {v.verdict}", "", v.text, ""]
        lines += [f"- {e}" for e in v.evidence] or ["- (no rows for this claim)"]
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


def _table1_section(summary: list[dict]) -> list[str]:
    """The paper's Table 1: median t_eps per bar scene and step for RBBS and LFBS, the paper's RBBS values beside."""
    lines = [
        "## Table 1: t_eps (s) vs step, bar scenes",
        "",
        "Median t_eps over trials (≥: some trials censored at the check budget, so a lower bound); the "
        "paper's RBBS values in brackets.",
        "",
    ]
    steps = sorted({s["step"] for s in summary if s["scene"] in TABLE1_SCENES})
    if not steps:
        return lines + ["No rows.", ""]
    for method in TABLE1_METHODS:
        lines += [
            f"**{method.upper()}**",
            "",
            "| scene | " + " | ".join(f"a={a:g}" for a in steps) + " |",
            "|---|" + "---:|" * len(steps),
        ]
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
    return lines


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


def _prm_section(rows, folder: Path) -> list[str]:
    """The maze and tunnel PRM table (LFBS vs RBBS, the paper's seconds beside) and its figure."""
    prm_rows = [r for r in rows if r["experiment"] == "prm" and r["scene"] in uav.PAPER]
    lines = ["## Maze and tunnel: LFBS vs RBBS in a PRM (Tables on maze and tunnel)", ""]
    if not prm_rows:
        return lines + ["No rows.", ""]
    table = uav.table(prm_rows)
    lines += [
        "The whole roadmap, every edge checked, k = 10 (maze 200 narrow + 300 uniform, tunnel 100 + 200). "
        "t_eps = sampling time (successful runs), T_PRM = whole plan; medians; paper seconds in brackets.",
        "",
        "| scene | step | sampler | runs | success [95 % CI] | t_eps s | T_PRM s | checks |",
        "|---|---:|---|---:|---:|---:|---:|---:|",
    ]
    for r in table:
        paper = uav.PAPER_SECONDS.get((r["scene"], r["step"]))
        pe, pt = ((paper[0], paper[1]) if r["sampler"] == "lfbs" else (paper[2], paper[3])) if paper else (None, None)
        eps = f"{r['median_t_eps']:.2f}" if r["median_t_eps"] is not None else "–"
        lo, hi = success_ci(round(r["success_rate"] * r["runs"]), r["runs"])
        lines.append(
            f"| {r['scene']} | {r['step']:g} | {r['sampler']} | {r['runs']} | "
            f"{r['success_rate']:.0%} [{lo:.0%}, {hi:.0%}] | {eps} ({pe}) | {r['median_t_prm']:.2f} ({pt}) | "
            f"{r['median_checks']:.0f} |"
        )
    _figure_prm(table, folder / "prm.png")
    runs = min(r["runs"] for r in table)
    hours_at = {n: n * sum(r["median_t_prm"] for r in table) / 3600 for n in (runs, TARGET_TRIALS)}

    def flagged(successes: int) -> str:
        edge = detectable_drop(runs, successes)
        return f"LFBS at {edge}/{runs} or fewer" if edge >= 0 else "no LFBS count (too few runs)"

    return lines + [
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
    ]


def _ur3_section(rows) -> list[str]:
    """The UR3 welding and window jobs timed end to end, the paper's LFBS average beside."""
    lines = ["## UR3 welding and window jobs (the paper's UR3 timing table)", ""]
    ur3 = jobs.table(rows)
    if not ur3:
        return lines + ["No rows.", ""]
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
    return lines + [
        "",
        f"Runs per job and sampler: {runs}, not {TARGET_TRIALS}. A run is a whole job (IK, then a full roadmap of up "
        f"to {UR3_SIZE['budget']:g} s for each leg that is not a straight move), so {TARGET_TRIALS} runs per cell "
        f"would take about {hours:.0f} h of one core here (the mean run, failed ones included, x {TARGET_TRIALS} x "
        f"{len(ur3)} cells). The table times the jobs against the paper's; it judges no claim. Success: exact 95 % "
        "binomial interval.",
        "",
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
