"""`bench ablation`: what each source of our planner's narrow-passage samples adds.

The planner's narrow rounds draw from two sources: workspace-gap placements (`PlanSettings.workspace` of them) and
the narrow-passage sampler (the Lévy bridge walkers by default). Each variant below removes or swaps one source and
plans the scene's own query with everything else as `plan` runs it, on a collision-check budget (so success and
checks do not depend on the machine or on what else runs on it). Per run: success within the budget, checks to the
first solution (all checks but smoothing's and timing's) and how many of the roadmap path's nodes each source
supplied.
"""

import numpy as np

from app.bench.runner import sweep
from app.bench.statistics import holm, paired_tests
from app.bench.store import Reuse, TrialSpec
from app.checking.budget import Budget
from app.errors import NoPath
from app.planning.query import plan
from app.planning.settings import PlanSettings, default_step
from app.scene.model import Scene

# variant -> (narrow-passage sampler, share of the narrow samples placed in workspace gaps)
VARIANTS = {
    "default": ("lfbs", PlanSettings.workspace),
    "lfbs-alone": ("lfbs", 0.0),
    "placements+uniform": ("uniform", PlanSettings.workspace),
    "uniform-alone": ("uniform", 0.0),
    "rbbs+placements": ("rbbs", PlanSettings.workspace),
    "placements+rwbs": ("rwbs", PlanSettings.workspace),
    "placements+gaussian": ("gaussian", PlanSettings.workspace),
    "rwbs-alone": ("rwbs", 0.0),
    "adaptive": ("adaptive", PlanSettings.workspace),
}
DEFAULT_CHECKS = 100_000
ALPHA = 0.05  # a difference from the default is named when its Holm-adjusted p is below this (family-wise)
# Run after every other variant's seeds: uniform samples alone cost one check each, so within a check budget the lazy
# roadmap grows far larger than the other variants' and its searches take far longer (benchmark pages). A sweep
# stopped early then still holds the same seeds of every other variant.
RUN_LAST = ("uniform-alone",)


def run_trial_spec(oracle, spec: TrialSpec) -> dict:
    """One query of variant `spec.method` on `spec.params["checks"]` collision checks."""
    sampler, workspace = VARIANTS[spec.method]
    try:
        r = plan(
            oracle,
            PlanSettings(
                sampler=sampler,
                step=spec.step,
                seed=spec.seed,
                budget=Budget(checks=int(spec.params["checks"])),
                workspace=workspace,
            ),
        )
    except NoPath as exc:
        checks = getattr(exc, "details", {}).get("collision_checks")
        return {"success": 0.0, "checks": checks, "code": getattr(exc, "code", None)}
    after = r.stats.checks.smoothing + r.stats.checks.timing
    path_nodes = len(r.path_nodes)
    return {
        "success": 1.0,
        "checks": r.collision_checks - after,
        "checks_total": r.collision_checks,
        "rounds": r.stats.rounds,
        "path_nodes": path_nodes,
        "narrow_on_path": r.narrow_on_path,
        "workspace_on_path": r.workspace_on_path,
        # start and goal are on every path and come from no sampler
        "uniform_on_path": path_nodes - 2 - r.narrow_on_path - r.workspace_on_path,
    }


def specs(scenes: list[str], variants: list[str], seeds: int, checks: int) -> list[TrialSpec]:
    """Seed-major, so a sweep stopped part way holds the same seeds of every cell; the variants of RUN_LAST after all
    the others."""
    steps = {scene: default_step(Scene(scene)) for scene in scenes}
    groups = [[v for v in variants if v not in RUN_LAST], [v for v in variants if v in RUN_LAST]]
    return [
        TrialSpec("ablation", scene, variant, steps[scene], seed, {"checks": checks})
        for group in groups
        for seed in range(seeds)
        for scene in scenes
        for variant in group
    ]


def _bootstrap_median(values: np.ndarray, seed: int = 0) -> tuple[float, float] | None:
    """95 % percentile-bootstrap interval of the median (None for fewer than two values)."""
    from scipy.stats import bootstrap

    if len(values) < 2 or np.all(values == values[0]):
        return (float(values[0]), float(values[0])) if len(values) else None
    res = bootstrap((values,), np.median, confidence_level=0.95, method="percentile", random_state=seed)
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def summarise(rows: list[dict], scenes: list[str], variants: list[str]) -> list[dict]:
    """One row per scene x variant (in that order, cells with no trial left out): success with its 95 % binomial
    interval; median checks to the first solution over successful runs with a bootstrap interval; and, summed over
    the successful runs, the path nodes each source supplied. `vs_default`: the variant against the default on the
    seeds both ran (every variant runs the same seeds, so the runs pair up): an exact McNemar test of success and a
    Wilcoxon signed-rank test of checks with every unsolved run counted at the budget (a censored value no solved
    run exceeds), each also Holm-adjusted over every comparison in the table, so all are corrected alike."""
    from scipy.stats import binomtest

    cells = {}
    for r in rows:
        cells.setdefault((r["scene"], r["method"]), []).append(r)
    table = []
    for scene in scenes:
        base = {r["seed"]: r["metrics"] for r in cells.get((scene, "default"), [])}
        for variant in variants:
            runs = cells.get((scene, variant))
            if not runs:
                continue
            metrics = [r["metrics"] for r in runs]
            budget = runs[0]["params"]["checks"]
            won = [m for m in metrics if m["success"]]
            n, k = len(metrics), len(won)
            ci = binomtest(k, n).proportion_ci(confidence_level=0.95)
            checks = np.array([m["checks"] for m in won], float)
            row = {
                "scene": scene,
                "variant": variant,
                "runs": n,
                "successes": k,
                "success_ci": [float(ci.low), float(ci.high)],
                "median_checks": float(np.median(checks)) if k else None,
                "median_checks_ci": _bootstrap_median(checks) if k else None,
                "budget_checks": budget,
                "path_nodes_from": {
                    source: int(sum(m[f"{source}_on_path"] for m in won))
                    for source in ("workspace", "narrow", "uniform")
                },
                "vs_default": None,
            }
            paired = sorted(r["seed"] for r in runs if r["seed"] in base)
            if variant != "default" and paired:
                mine = {r["seed"]: r["metrics"] for r in runs}
                a, b = [mine[s] for s in paired], [base[s] for s in paired]
                censored = [[m["checks"] if m["success"] else budget for m in side] for side in (a, b)]
                default_median = _median_of(base.values())
                row["vs_default"] = {
                    **paired_tests([m["success"] for m in a], censored[0], [m["success"] for m in b], censored[1]),
                    "checks_ratio": row["median_checks"] / default_median if k and default_median else None,
                }
            table.append(row)
    comparisons = [r["vs_default"] for r in table if r["vs_default"]]
    tests = ("success_mcnemar_p", "checks_wilcoxon_p")
    adjusted = holm([c[t] for c in comparisons for t in tests])
    for i, c in enumerate(comparisons):
        c["success_p_adjusted"], c["checks_p_adjusted"] = adjusted[2 * i], adjusted[2 * i + 1]
    return table


def _median_of(metrics) -> float | None:
    """Median checks to the first solution over the solved runs (their metrics), or None when none solved."""
    won = [m["checks"] for m in metrics if m["success"]]
    return float(np.median(won)) if won else None


def measure(
    scenes: list[str],
    variants: list[str],
    seeds: int,
    checks: int,
    store,
    workers: int = 1,
    run: bool = True,
    fresh: bool = False,
) -> tuple[list[dict], Reuse, int, tuple[str, ...]]:
    """Run what `store` has no row for (none with run=False; with `fresh`, also the trials of other code versions),
    then the summary of the stored trials; what was reused, how many of the trials the store holds, and the code
    versions that ran them (those run now included)."""
    from app.bench.store import ResultStore

    todo = specs(scenes, variants, seeds, checks)
    if run:
        rows, reuse = sweep(todo, store, workers=workers, desc="bench ablation", fresh=fresh)
    else:
        s = ResultStore(store)
        try:
            reuse, rows = s.reuse(todo), s.rows_for(todo)
        finally:
            s.close()
    versions = tuple(sorted({str(r["code_version"]) for r in rows}))
    return summarise(rows, scenes, variants), reuse, len(rows), versions


def _fmt_checks(value) -> str:
    if value is None:
        return "-"
    return f"{value / 1000:.1f}k" if value >= 1000 else f"{value:.0f}"


def markdown(table: list[dict], held: int, planned: int, checks: int, seeds: int, versions=()) -> str:
    """The ablation's table and what each source put on the paths, as markdown; `versions`: the code versions of
    the trials it summarises."""
    lines = [
        "# Ablation: what each source of narrow-passage samples adds",
        "",
        f"{held} of {planned} trials ({seeds} seeds per scene and variant), each the scene's own query planned as "
        f"`plan` does, on a budget of {checks:,} collision checks (machine-independent). Variants: "
        + "; ".join(f"`{v}` = sampler {s}, workspace share {w:g}" for v, (s, w) in VARIANTS.items())
        + "."
        + (
            f" The sweep stopped before its end: `python -m app bench ablation --seeds {seeds} --checks {checks}` "
            "resumes it (stored trials are reused, not run again); the variants' seeds run in the order of "
            "`app.bench.ablation.specs`, so the cells left short are those run last."
            if held < planned
            else ""
        ),
        *(
            [
                "",
                f"Code version(s) of the trials: {', '.join(f'`{v}`' for v in versions)}"
                + (
                    " -- mixed: not every trial ran on the same code, so the comparisons mix versions "
                    "(`--fresh` runs the trials of other versions again)."
                    if len(versions) > 1
                    else "."
                ),
            ]
            if versions
            else []
        ),
        "",
        "success: solved within the budget, with its 95 % Clopper-Pearson interval. checks: median checks to the "
        "first solution over the solved runs, with a 95 % bootstrap interval. Against `default`, on the seeds both "
        "ran (the runs pair up by seed): p (success), an exact McNemar test; p (checks), a Wilcoxon signed-rank test "
        "of the checks with unsolved runs counted at the budget; both Holm-adjusted over every comparison in the "
        f"table (a difference is named when below {ALPHA:g}); fewer / more: the seeds on which the variant needed "
        "fewer / more checks than `default`. path nodes: the roadmap path's nodes (start and goal left out) over all "
        "solved runs, by the source that drew them: workspace-gap placements / the narrow-passage sampler (for the "
        "uniform variants: the uniform samples drawn in its place in the narrow rounds) / the uniform rounds.",
        "",
        *reading(table),
        "",
        "| scene | variant | success | 95 % CI | checks | 95 % CI | p (success) | p (checks) | fewer / more "
        "| path nodes placed / sampler / uniform |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in table:
        lo, hi = r["success_ci"]
        cci = r["median_checks_ci"]
        vs = r["vs_default"]
        src = r["path_nodes_from"]
        lines.append(
            f"| {r['scene']} | {r['variant']} | {r['successes']}/{r['runs']} | {lo:.2f}-{hi:.2f} | "
            f"{_fmt_checks(r['median_checks'])} | "
            + (f"{_fmt_checks(cci[0])}-{_fmt_checks(cci[1])}" if cci else "-")
            + " | "
            + (
                f"{vs['success_p_adjusted']:.2g} | {vs['checks_p_adjusted']:.2g} | "
                f"{vs['fewer_checks']} / {vs['more_checks']}"
                if vs
                else "- | - | -"
            )
            + f" | {src['workspace']} / {src['narrow']} / {src['uniform']} |"
        )
    return "\n".join(lines) + "\n"


def best(rows: list[dict]) -> dict:
    """The variant with the most successes, ties broken by fewer median checks to the first solution."""
    return min(rows, key=lambda r: (-r["successes"], r["median_checks"] if r["median_checks"] is not None else 1e18))


def reading(table: list[dict]) -> list[str]:
    """What the table says about the default: per scene the best variant, where a variant differs from the default
    by the paired tests (Holm-adjusted p < ALPHA), and which source put the narrow nodes on the default's paths."""
    scenes = list(dict.fromkeys(r["scene"] for r in table))
    if not scenes:
        return []
    lines = ["## What the numbers say", ""]
    wins = {}
    for scene in scenes:
        rows = [r for r in table if r["scene"] == scene]
        wins.setdefault(best(rows)["variant"], []).append(scene)
    lines.append(
        "- Best variant per scene (most successes, then fewest median checks): "
        + "; ".join(f"`{v}` in {', '.join(s)}" for v, s in wins.items())
        + "."
    )
    for variant in dict.fromkeys(r["variant"] for r in table if r["variant"] != "default"):
        better, worse = [], []
        for r in table:
            vs = r["vs_default"]
            if r["variant"] != variant or vs is None:
                continue
            base = next(b for b in table if b["scene"] == r["scene"] and b["variant"] == "default")
            if vs["success_p_adjusted"] < ALPHA:
                ahead = r["successes"] > base["successes"]
            elif vs["checks_p_adjusted"] < ALPHA:
                ahead = vs["fewer_checks"] > vs["more_checks"]
            else:
                continue
            (better if ahead else worse).append(
                f"{r['scene']} ({r['successes']}/{r['runs']} vs {base['successes']}/{base['runs']}, "
                f"{_fmt_checks(r['median_checks'])} vs {_fmt_checks(base['median_checks'])} checks, fewer in "
                f"{vs['fewer_checks']} of {vs['pairs']} seeds)"
            )
        same = len([r for r in table if r["variant"] == variant]) - len(better) - len(worse)
        lines.append(
            f"- `{variant}` against `default`: better in {len(better)} scene(s)"
            + (": " + "; ".join(better) if better else "")
            + f"; worse in {len(worse)}"
            + (": " + "; ".join(worse) if worse else "")
            + f"; no significant difference in {same}."
        )
    default = [r for r in table if r["variant"] == "default"]
    placed = sum(r["path_nodes_from"]["workspace"] for r in default)
    walked = sum(r["path_nodes_from"]["narrow"] for r in default)
    if placed + walked:
        lines.append(
            f"- On the default's solved paths, {placed} narrow-passage nodes were workspace-gap placements and "
            f"{walked} came from the Lévy walkers ({walked / (placed + walked):.0%}); scenes where the walkers "
            "supplied any: "
            + (", ".join(r["scene"] for r in default if r["path_nodes_from"]["narrow"]) or "none")
            + "."
        )
    return lines


def figure(table: list[dict], path: str, checks: int) -> None:
    """Per scene, one bar per variant. Top: success within the budget with its 95 % interval. Bottom: median checks to
    the first solution (log scale) with its bootstrap interval, faded where some runs went unsolved; a variant with
    no solved run is drawn hollow and hatched up to the budget (censored: at least the budget)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    from app.draw import save

    scenes = list(dict.fromkeys(r["scene"] for r in table))
    variants = list(dict.fromkeys(r["variant"] for r in table))
    colours = {v: f"C{i}" for i, v in enumerate(variants)}
    width = 0.8 / len(variants)
    fig, (top, bottom) = plt.subplots(
        2, 1, figsize=(max(8.0, 1.25 * len(scenes)), 6.4), sharex=True, gridspec_kw={"height_ratios": [1, 1.6]}
    )
    cells = {(r["scene"], r["variant"]): r for r in table}
    runs = max((r["runs"] for r in table), default=0)
    fewest = min((r["runs"] for r in table), default=0)
    for i, scene in enumerate(scenes):
        for j, variant in enumerate(variants):
            r = cells.get((scene, variant))
            if r is None:
                continue
            x = i - 0.4 + width * (j + 0.5)
            c = colours[variant]
            rate = r["successes"] / r["runs"]
            lo, hi = r["success_ci"]
            top.bar(x, rate, width, color=c)
            if r["runs"] < runs:  # fewer seeds than the others: said on the bar
                top.text(x, 1.02, f"n={r['runs']}", ha="center", va="bottom", fontsize=6)
            top.errorbar(x, rate, yerr=[[rate - lo], [hi - rate]], fmt="none", ecolor="black", capsize=2, lw=0.8)
            if r["median_checks"] is None:
                bottom.bar(x, checks, width, facecolor="none", edgecolor=c, hatch="///", linewidth=0.8)
                continue
            lo, hi = r["median_checks_ci"]
            m = r["median_checks"]
            bottom.bar(x, m, width, color=c, alpha=0.9 if r["successes"] == r["runs"] else 0.4, edgecolor=c)
            bottom.errorbar(x, m, yerr=[[m - lo], [hi - m]], fmt="none", ecolor="black", capsize=2, lw=0.8)
    seeds = f"{runs} seeds a bar" if fewest == runs else f"{fewest}-{runs} seeds a bar (n above those with fewer)"
    top.set_ylim(0, 1.12)
    top.set_ylabel("success within budget\n(exact 95 % interval)")
    top.grid(axis="y", alpha=0.3)
    bottom.axhline(checks, color="grey", lw=0.8, ls="--")
    bottom.set_yscale("log")
    bottom.set_ylim(top=checks * 1.6)
    bottom.set_xticks(range(len(scenes)), scenes, rotation=20)
    bottom.set_ylabel("median checks to first solution\n(solved runs, 95 % bootstrap interval)")
    bottom.set_xlabel("scene")
    bottom.grid(axis="y", alpha=0.3, which="both")
    top.set_title(
        f"Ablation of the planner's narrow-passage sources, {checks:,}-check budget (dashed line), {seeds}.\n"
        "Faded: some runs unsolved; hatched: none solved",
        fontsize=9,
    )
    handles = [Patch(color=colours[v], label=v) for v in variants]
    handles.append(Patch(facecolor="none", edgecolor="grey", hatch="///", label="no run solved (≥ budget)"))
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    save(fig, path)
