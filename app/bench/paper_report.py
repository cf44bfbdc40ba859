"""`bench paper`'s report.md, from the results store alone: the overview (machine, code, trials, options), what
holds and what is reversed, the claims C1-C5 with their evidence, the readings of the paper's ambiguous points, then
each experiment's section (app.bench.paper_sections)."""

from __future__ import annotations

import json
import time
from pathlib import Path

from app.bench import sampling
from app.bench.claims import RULES, claim_c3, judge
from app.bench.paper import READINGS, TRIALS_CSV, Config, machine, reading_rows
from app.bench.paper_sections import (
    checks_per_passage_section,
    pictures_section,
    prm_section,
    sampling_section,
    table1_section,
    ur3_section,
)
from app.bench.store import ResultStore
from app.io import all_or_nothing, write_atomically
from app.samplers import SAMPLERS

# What the last run that added trials recorded beside its report, for `--report-only`, which runs nothing: the
# machine it ran on, its sweeps' wall time and its sample pictures' captions (whether a sampler ran over its budget
# is not in the store).
RUN_RECORD = "run.json"


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
    sampling_lines = sampling_section(srows, summary, folder)
    per_passage, per_passage_found = checks_per_passage_section(rows)
    table1, table1_found = table1_section(summary, rows)
    prm, prm_found = prm_section(rows, folder)
    ur3, ur3_found = ur3_section(rows)
    record = _run_record(folder, run_nothing, wall_seconds)
    lines = _overview_section(store, stored, folder, config, record)
    lines += _findings_section(verdicts, rows, table1_found + prm_found + ur3_found + per_passage_found)
    lines += claims + readings + sampling_lines + per_passage + table1
    if pictures and config is not None:
        section, captions = pictures_section(config, folder, run_nothing, record.get("pictures"))
        record["pictures"] = captions
        lines += section
    lines += prm + ur3
    with all_or_nothing():
        if not run_nothing:
            write_atomically(folder / RUN_RECORD, json.dumps(record, indent=1) + "\n")
        return write_atomically(folder / "report.md", "\n".join(lines) + "\n")


def _run_record(folder: Path, run_nothing: bool, wall_seconds: float | None) -> dict:
    """This run's record (its machine and the wall time of its sweeps), or with `run_nothing` the one the last run
    left in `folder`; without one, this machine's, said to be the rebuild's."""
    if not run_nothing:
        return {"machine": machine(), "wall_seconds": wall_seconds}
    try:
        record = json.loads((folder / RUN_RECORD).read_text())
    except (OSError, ValueError):
        record = None
    lines = record.get("machine") if isinstance(record, dict) else None
    if not (isinstance(lines, list) and all(isinstance(line, str) for line in lines)):
        return {"machine": [f"{line} (this rebuild's; the trials' machine was not recorded)" for line in machine()]}
    captions = record.get("pictures")
    if not (isinstance(captions, dict) and all(isinstance(c, str) for c in captions.values())):
        captions = {}
    wall = record.get("wall_seconds")
    wall = wall if isinstance(wall, (int, float)) and not isinstance(wall, bool) else None
    return {"machine": lines, "pictures": captions, "wall_seconds": wall}


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


def _overview_section(store: ResultStore, rows, folder: Path, config: Config | None, record: dict) -> list[str]:
    """Title, then the machine and wall time (the run record), the code versions and trial counts in the store, and
    this invocation's options."""
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
    lines += [f"- Machine: {m}" for m in record["machine"]]
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
    if record.get("wall_seconds") is not None:
        lines.append(f"- Wall time of the run's sweeps: {record['wall_seconds']:.0f} s")
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
