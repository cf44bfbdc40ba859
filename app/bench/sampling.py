"""`bench sampling`: the paper's sampling experiment (its Figs. 4 and 7) for every scene x sampler x step.

Each trial draws K_c = 30 samples with one sampler at one step from seed s and records the time t_eps, the
collision checks gamma_c, the fraction of samples in the scene's passage, and what the samples sit between
(environment, the robot itself, both, neither, within `margin`). `run_trial` is one such trial and returns a plain
row, so a process pool or a results store can run and keep the same trials.
"""

from __future__ import annotations

import time

import numpy as np
from tqdm import tqdm

from app.bench.statistics import median_ci
from app.checking.oracle import CollisionOracle
from app.errors import SamplerBudgetExceeded
from app.samplers import make_sampler
from app.scene.model import Scene

STEPS = [2.0, 5.0, 10.0, 15.0, 20.0]
METRICS = [("seconds", "t_eps (s)"), ("collision_checks", "gamma_c (checks)"), ("passage_fraction", "in passage")]


def sits_between(oracle, samples: np.ndarray, margin: float) -> dict[str, float]:
    """Fractions of samples within `margin` of the environment only, the robot itself only, both, or neither."""
    counts = dict.fromkeys(("environment", "self", "both", "neither"), 0)
    for q in samples:
        c = oracle.diagnostics.contacts(q, margin)
        key = ("both" if c["self"] else "environment") if c["environment"] else ("self" if c["self"] else "neither")
        counts[key] += 1
    n = max(len(samples), 1)
    return {key: value / n for key, value in counts.items()}


def run_trial(
    oracle,
    sampler_name: str,
    step: float,
    seed: int,
    k: int = 30,
    margin: float | None = None,
    max_checks: int | None = None,
    keep_samples: bool = False,
    **params,
) -> dict:
    """One trial: k samples from `sampler_name` at `step` with seed `seed`, and what they cost and where they are.

    A trial that exhausts its check budget returns ok=False with the checks it spent (a censored value) and the
    samples it had drawn by then (`samples_drawn` of k; passage_fraction is over those).
    """
    if max_checks is not None:
        params["max_checks"] = max_checks
    checker = oracle.context()
    sampler = make_sampler(sampler_name, checker, step=oracle.space.check_step(step), **params)
    rng = np.random.default_rng(seed)
    start = time.perf_counter()
    try:
        samples, ok = sampler.sample(k, rng), True
    except SamplerBudgetExceeded as exc:
        samples, ok = exc.samples, False
    seconds = time.perf_counter() - start
    row = {
        "scene": oracle.scene.name,
        "sampler": sampler_name,
        "step": float(step),
        "seed": int(seed),
        "k": int(k),
        "ok": ok,
        "seconds": seconds,
        "collision_checks": int(checker.checks),
        "samples_drawn": len(samples),
        "passage_fraction": float(oracle.workspace.in_passage(samples).mean()) if len(samples) else float("nan"),
        "gave_up": int(sampler.stats.get("gave_up", 0)),
        "attempts": int(sampler.stats.get("attempts", 0)),
    }
    if margin is not None and len(samples):
        row.update({f"near_{key}": v for key, v in sits_between(oracle, samples, margin).items()})
    if keep_samples:
        row["samples"] = samples
        row["bridges"] = sampler.bridges
    return row


def run_trial_spec(oracle, spec) -> dict:
    """One sampling trial from a results-store TrialSpec (experiment "sampling"; method = sampler name).

    params: k (default 30), max_checks (default none), margin (default twice the scene's resolution),
    sampler_params (default none: keyword arguments of the sampler, e.g. a reading of the paper). The row
    holds `censored` (the trial spent its check budget: collision_checks and seconds are then lower bounds, and
    passage_fraction is over the samples_drawn < k it had, None if none) and `sample_checksum`, a hash of the
    samples that is the same wherever the trial ran.
    """
    import hashlib

    p = spec.params
    margin = p.get("margin")
    margin = 2 * oracle.space.resolution if margin is None else float(margin)
    row = run_trial(
        oracle,
        spec.method,
        spec.step,
        spec.seed,
        k=int(p.get("k", 30)),
        margin=margin,
        max_checks=p.get("max_checks"),
        keep_samples=True,
        **p.get("sampler_params", {}),
    )
    samples = np.round(np.asarray(row.pop("samples"), float), 9)
    row.pop("bridges", None)
    row["sample_checksum"] = hashlib.sha256(samples.tobytes()).hexdigest()[:16] if len(samples) else None
    row["censored"] = not row["ok"]
    if not np.isfinite(row["passage_fraction"]):
        row["passage_fraction"] = None  # no samples: no fraction (JSON has no NaN)
    return row


def summarise(rows: list[dict]) -> list[dict]:
    """Median and its 95 % bootstrap confidence interval (`statistics.median_ci`) of each metric per scene x sampler x
    step. Censored trials count with their values (lower bounds for checks and time)."""
    cells: dict[tuple, list[dict]] = {}
    for r in rows:
        cells.setdefault((r["scene"], r["sampler"], r["step"]), []).append(r)
    out = []
    for (scene, sampler, step), group in cells.items():
        s = {
            "scene": scene,
            "sampler": sampler,
            "step": step,
            "trials": len(group),
            "censored": sum(not r["ok"] for r in group),
        }
        for key, _ in METRICS:
            values = np.array([r[key] for r in group], float)
            values = values[np.isfinite(values)]
            med, lo, hi = median_ci(values)
            s[key] = {"median": med, "lo": lo, "hi": hi}
        for key in ("near_environment", "near_self", "near_both", "near_neither"):
            values = [r[key] for r in group if key in r]
            if values:
                s[key] = float(np.mean(values))
        out.append(s)
    return out


def figure(summary: list[dict], path: str) -> None:
    # matplotlib (and app.draw, which loads it) only when a figure is drawn: the command line imports this module.
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from app.draw import save

    scenes = list(dict.fromkeys(s["scene"] for s in summary))
    samplers = list(dict.fromkeys(s["sampler"] for s in summary))
    fig, axes = plt.subplots(len(scenes), len(METRICS), figsize=(4.2 * len(METRICS), 3.4 * len(scenes)), squeeze=False)
    for i, scene in enumerate(scenes):
        for j, (key, label) in enumerate(METRICS):
            ax = axes[i][j]
            for n, sampler in enumerate(samplers):
                cell = sorted(
                    (s for s in summary if s["scene"] == scene and s["sampler"] == sampler), key=lambda s: s["step"]
                )
                x = [s["step"] for s in cell]
                med = [s[key]["median"] for s in cell]
                ax.plot(x, med, marker="o", ms=3, color=f"C{n}", label=sampler)
                ax.fill_between(
                    x, [s[key]["lo"] for s in cell], [s[key]["hi"] for s in cell], color=f"C{n}", alpha=0.12
                )
                if key == "passage_fraction":  # mostly censored: the budget, not the sampler, set the fraction
                    censored = [(s["step"], s[key]["median"]) for s in cell if 2 * s["censored"] >= s["trials"]]
                    marker = "s"
                else:  # some trials spent the whole budget: the median of their costs is a lower bound
                    censored = [(s["step"], s[key]["median"]) for s in cell if s["censored"]]
                    marker = "^"
                if censored:
                    ax.scatter(*zip(*censored), marker=marker, s=45, facecolors="white", edgecolors=f"C{n}", zorder=3)
            if key != "passage_fraction":
                ax.set_yscale("log")
            steps = sorted({s["step"] for s in summary})
            ax.set_xticks(steps, [f"{a:g}" for a in steps])
            ax.set(xlabel="step a", ylabel=label, title=f"{scene}: {label}")
            ax.grid(alpha=0.3)
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=len(samplers), fontsize=8, frameon=False)
    height = fig.get_figheight()  # legend and note take a fixed strip of inches at the bottom, whatever the rows
    fig.text(
        0.5,
        0.4 / height,
        "median per cell; bands: 95 % bootstrap confidence interval of the median; open triangles: some trials hit "
        "the check budget (the median is a lower bound); open squares: at least half did (a budget artefact); in "
        "passage: of the samples drawn (a trial that hit the budget: before it)",
        fontsize=7,
        ha="center",
    )
    fig.tight_layout(rect=(0, 0.62 / height, 1, 1))
    save(fig, path)


def measure(
    scenes: list[str],
    samplers: list[str],
    steps: list[float],
    trials: int,
    k: int = 30,
    margin: float | None = None,
    max_checks: int | None = None,
    threads: int | None = None,
) -> list[dict]:
    """Every scene x sampler x step trial for seeds 0..trials-1, in this process (a progress bar on stderr); the
    rows in that order. margin None: twice each scene's resolution."""
    oracles = {name: CollisionOracle(Scene(name), threads=threads) for name in scenes}
    todo = [(sc, sa, a, seed) for sc in scenes for sa in samplers for a in steps for seed in range(trials)]
    rows = []
    for scene, sampler, step, seed in tqdm(todo, desc="bench sampling", unit="trial"):
        oracle = oracles[scene]
        near = margin if margin is not None else 2 * oracle.space.resolution
        rows.append(run_trial(oracle, sampler, step, seed, k=k, margin=near, max_checks=max_checks))
    return rows
