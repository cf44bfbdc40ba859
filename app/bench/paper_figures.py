"""`bench paper`'s figures beside report.md: one seed's samples per scene and sampler (the paper's Figs. 3, 5, 6),
and the maze/tunnel PRM cells (`prm_cells`, which the PRM table reads too) with their figure."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from app.bench import sampling
from app.bench.claims import SAMPLER_CAP, sampler_gave_up
from app.bench.paper import PICTURE_STEPS
from app.bench.statistics import median_ci, success_ci
from app.checking.oracle import CollisionOracle
from app.scene.model import Scene


def sample_pictures(scenes, samplers, max_checks, folder: Path) -> list[tuple[str, list[tuple[str, str]]]]:
    """One seed's K_c samples per scene x sampler, as in the paper's Figs. 3, 5, 6 (drawn as `sample --png` does)."""
    from app.draw import draw_samples  # loads matplotlib: only when a report is drawn

    out = []
    for scene in scenes:
        oracle = CollisionOracle(Scene(scene), threads=1)
        step = PICTURE_STEPS.get(scene, 10.0)
        pictures = []
        for sampler in samplers:
            r = sampling.run_trial(oracle, sampler, step, 0, k=30, max_checks=max_checks, keep_samples=True)
            name = picture_name(scene, sampler)
            note = "" if r["ok"] else f" — over the {max_checks}-check budget with {len(r['samples'])} of 30 samples"
            draw_samples(
                oracle, r["samples"], str(folder / name), title=f"{scene}: {sampler}, step {step:g}, seed 0{note}"
            )
            pictures.append((f"{sampler}{note}", name))
        out.append((f"{scene} (step {step:g})", pictures))
    return out


def picture_name(scene: str, sampler: str) -> str:
    return f"samples-{scene}-{sampler}.png"


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


def prm_figure(cells: list[dict], path: Path) -> None:
    """Success rate (exact 95 % interval) and median T_PRM (95 % bootstrap interval, log scale) per maze/tunnel cell
    and sampler; a cell whose runs all gave up at the sampler's check cap is drawn hollow and hatched (censored, not
    a result): a stub without height among the success rates, its time to the cap (a lower bound) among the times;
    the legend below the panels."""
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
            if censored:  # no roadmap was built: the runs measured the cap, and the rate is unknown: no bar height
                axes[0].bar(xi, 0.03, width, **style)
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
