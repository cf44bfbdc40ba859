"""report.md's section on each experiment of `bench paper`: its tables, its figures (app.bench.paper_figures) and
what it finds. Each `..._section` returns its markdown lines (and, where it finds something, those findings too)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from app.bench import jobs, sampling, uav
from app.bench.claims import SAMPLER_CAP, checks_per_passage_sample, sampler_gave_up
from app.bench.paper import (
    CENSORED_CAP,
    PAPER_TABLE1,
    PAPER_UR3,
    PICTURE_STEPS,
    STEPS,
    TABLE1_METHODS,
    TABLE1_SCENES,
    TARGET_TRIALS,
    UR3_SIZE,
    Config,
)
from app.bench.paper_figures import picture_name, prm_cells, prm_figure, sample_pictures
from app.bench.statistics import ALPHA, detectable_drop, p_text, success_ci, trend
from app.samplers import SAMPLERS


def _fmt(value, digits=3) -> str:
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "–"
    return f"{value:.{digits}g}" if abs(value) < 1000 else f"{value:.0f}"


def _interval(cell: dict, key: str, digits=3, mark="") -> str:
    v = cell[key]
    if not np.isfinite(v["median"]):
        return "–"
    return f"{mark}{_fmt(v['median'], digits)} [{_fmt(v['lo'], digits)}, {_fmt(v['hi'], digits)}]"


def _per_step_head(title: str, rows: str, steps: list[float]) -> list[str]:
    """A title, then the head of a markdown table with a column per step a."""
    return [title, "", f"| {rows} | " + " | ".join(f"a={a:g}" for a in steps) + " |", "|---|" + "---:|" * len(steps)]


def _moves(word: str) -> str:
    """A trend's word as a verb: 'rises', 'falls', 'is flat'."""
    return "is flat" if word == "flat" else word


def sampling_section(srows: list[dict], summary: list[dict], folder: Path) -> list[str]:
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


def table1_section(summary: list[dict], rows) -> tuple[list[str], list[str]]:
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
        f"understated), falls/rises when p < {ALPHA:g}, or named by its moves (e.g. 'falls, then rises') when "
        "neighbouring steps differ significantly both ways (Mann-Whitney, Bonferroni over the pairs). The paper's: "
        "the rank correlation of its five RBBS values "
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


def checks_per_passage_section(rows) -> tuple[list[str], list[str]]:
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
            top = max(sorted(set(best)), key=best.count)  # a tie goes to the first name, not to the set's hash order
            cheapest.append(f"{scene} {top} ({best.count(top)} of {len(best)} steps)")
        reading += " Cheapest per passage sample, at most steps: " + ", ".join(cheapest) + "."
        lines += [reading, ""]
        found.append(reading)
    return lines, found


def pictures_section(
    config: Config, folder: Path, run_nothing: bool, labels: dict | None = None
) -> tuple[list[str], dict[str, str]]:
    """One seed's samples per scene and sampler of this invocation, drawn into `folder` (not read from the store);
    with `run_nothing`, the pictures earlier runs drew there, captioned as `labels` (picture name -> caption, what
    the run that drew them recorded), and a note for those missing. Also the captions shown, by picture name."""
    lines = [
        "## Sample pictures (Figs. 3, 5, 6)",
        "",
        "Seed 0, K_c = 30 samples (red: in the passage). bar at step 2, the others at step 10.",
        "",
    ]
    if run_nothing:
        labels = labels or {}
        wanted = [
            (scene, sampler, picture_name(scene, sampler)) for scene in config.scenes for sampler in config.samplers
        ]
        found = [w for w in wanted if (folder / w[2]).is_file()]
        missing = len(wanted) - len(found)
        if missing:
            lines += [
                f"Rebuilt with `--report-only`, which runs no trial: {len(found)} of {len(wanted)} pictures as an "
                f"earlier run drew them; {missing} not drawn (a run without --report-only draws them).",
                "",
            ]
        sections = [
            (
                f"{scene} (step {PICTURE_STEPS.get(scene, 10.0):g})",
                [(labels.get(n, s), n) for sc, s, n in found if sc == scene],
            )
            for scene in config.scenes
        ]
    else:
        sections = sample_pictures(config.scenes, config.samplers, config.max_checks, folder)
    for title, items in sections:
        if items:
            lines += [f"### {title}", ""]
            lines += [f"![{label}]({name})" for label, name in items]
            lines.append("")
    return lines, {name: label for _, items in sections for label, name in items}


def prm_section(rows, folder: Path) -> tuple[list[str], list[str]]:
    """The maze and tunnel PRM table (LFBS vs RBBS, the paper's seconds beside), the runs censored by the sampler's
    cap, the trend of T_PRM with the step and LFBS's time over RBBS's beside the paper's, and the figure."""
    prm_rows = [r for r in rows if r["experiment"] == "prm" and r["scene"] in uav.PAPER]
    lines = ["## Maze and tunnel: LFBS vs RBBS in a PRM (Tables on maze and tunnel)", ""]
    if not prm_rows:
        return lines + ["No rows.", ""], []
    cells = prm_cells(prm_rows)
    prm_figure(cells, folder / "prm.png")
    trends, found = _prm_trends(prm_rows, cells)
    return lines + _prm_table(prm_rows, cells) + trends + _prm_ratios(cells), _censored(prm_rows, cells) + found


def _prm_table(prm_rows, cells) -> list[str]:
    """The table of the PRM cells, the paper's seconds in brackets, then the figure and what the runs can tell."""
    gave_up = sum(c["gave_up"] for c in cells)
    lines = [
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
    runs = min(c["runs"] for c in cells)
    hours_at = {n: n * sum(c["t_prm"][0] for c in cells) / 3600 for n in (runs, TARGET_TRIALS)}

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
    ]


def _censored(prm_rows, cells) -> list[str]:
    """The finding that some runs built no roadmap (their sampler's cap ended them), if any did."""
    gave_up = sum(c["gave_up"] for c in cells)
    if not gave_up:
        return []
    where = ", ".join(
        f"{c['scene']} a={c['step']:g} {c['sampler']} {c['gave_up']}/{c['runs']}" for c in cells if c["gave_up"]
    )
    return [
        f"PRM: {gave_up} of {len(prm_rows)} runs ({where}) built no roadmap: their sampler gave up at its own "
        f"{SAMPLER_CAP:,}-check cap. They are censored (the cap, not the planner, ended them) and left out of C4."
    ]


def _prm_trends(prm_rows, cells) -> tuple[list[str], list[str]]:
    """T_PRM against the step per scene and sampler, ours (Spearman) beside the paper's direction; a finding where
    the directions differ."""
    lines = [
        "",
        "**Side by side with the paper.** T_PRM against the step, per scene and sampler (ours: Spearman's rank "
        f"correlation over the runs that built a roadmap, falls/rises when p < {ALPHA:g}, or named by its moves, e.g. "
        "'falls, then rises', when neighbouring steps differ significantly both ways (Mann-Whitney, Bonferroni over "
        "the pairs); the paper's: the direction of its published values), and LFBS's median T_PRM over RBBS's per "
        "cell. Absolute seconds differ by two orders "
        "of magnitude (other machine, other implementation); the ratios and directions are what compare.",
        "",
        "| scene | sampler | paper T_PRM by a | ours median T_PRM by a | paper trend | ours trend |",
        "|---|---|---|---|---|---|",
    ]
    found = []
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
    return lines, found


def _prm_ratios(cells) -> list[str]:
    """LFBS's median T_PRM over RBBS's per cell, the paper's beside."""
    lines = ["", "| scene | step | paper LFBS/RBBS T_PRM | ours LFBS/RBBS T_PRM |", "|---|---:|---:|---:|"]
    for (scene, step), paper in uav.PAPER_SECONDS.items():
        pair = {c["sampler"]: c for c in cells if c["scene"] == scene and c["step"] == step}
        if set(pair) != {"lfbs", "rbbs"}:
            continue
        ours = pair["lfbs"]["t_prm"][0] / pair["rbbs"]["t_prm"][0]
        note = " (RBBS censored: time to the cap)" if pair["rbbs"]["gave_up_only"] else ""
        lines.append(f"| {scene} | {step:g} | {paper[1] / paper[3]:.2f} | {ours:.2f}{note} |")
    return lines + [""]


def ur3_section(rows) -> tuple[list[str], list[str]]:
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
