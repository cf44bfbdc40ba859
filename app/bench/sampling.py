"""`bench sampling`: the paper's sampling experiment (its Figs. 4 and 7) for every scene x sampler x step.

Each trial draws K_c = 30 samples with one sampler at one step from seed s and records the time t_eps, the
collision checks gamma_c, the fraction of samples in the scene's passage, and what the samples sit between
(environment, the robot itself, both, neither, within `margin`). `run_trial` is one such trial and returns a plain
row, so a process pool or a results store can run and keep the same trials.
"""
from __future__ import annotations

import time

import numpy as np

from app.cli import float_list, positive_float, positive_int, print_json

STEPS = [2.0, 5.0, 10.0, 15.0, 20.0]
METRICS = [("seconds", "t_eps (s)"), ("collision_checks", "gamma_c (checks)"), ("passage_fraction", "in passage")]


def register(kinds) -> None:
    from app.samplers import SAMPLERS

    p = kinds.add_parser("sampling", help="t_eps, gamma_c and passage fraction of the seven samplers vs step")
    p.add_argument("--scenes", default="bar,teeth3d", help="comma-separated scene names")
    p.add_argument("--samplers", default=",".join(SAMPLERS), help="comma-separated sampler names")
    p.add_argument("--steps", type=float_list, default=STEPS, help="comma-separated steps a (default 2,5,10,15,20)")
    p.add_argument("--trials", type=positive_int, default=10, help="trials (seeds 0..N-1) per cell")
    p.add_argument("-k", type=positive_int, default=30, help="samples per trial (the paper's K_c = 30)")
    p.add_argument("--margin", type=positive_float, default=None,
                   help="contact margin for 'sits between' (default: twice the scene's resolution)")
    p.add_argument("--max-checks", type=positive_int, default=200_000,
                   help="collision-check budget per trial; a trial that spends it is reported as censored")
    p.add_argument("--threads", type=positive_int, default=None, help="oracle threads (default: up to 2)")
    p.add_argument("--png", help="figure: one panel per metric vs step, one line per sampler, a row per scene")
    p.add_argument("--json", action="store_true", help="rows and summary as one JSON object on stdout")
    p.set_defaults(func=run)


def sits_between(oracle, samples: np.ndarray, margin: float) -> dict[str, float]:
    """Fractions of samples within `margin` of the environment only, the robot itself only, both, or neither."""
    counts = dict.fromkeys(("environment", "self", "both", "neither"), 0)
    for q in samples:
        c = oracle.contacts(q, margin)
        key = ("both" if c["self"] else "environment") if c["environment"] else ("self" if c["self"] else "neither")
        counts[key] += 1
    n = max(len(samples), 1)
    return {key: value / n for key, value in counts.items()}


def run_trial(oracle, sampler_name: str, step: float, seed: int, k: int = 30, margin: float | None = None,
              max_checks: int | None = None, keep_samples: bool = False, **params) -> dict:
    """One trial: k samples from `sampler_name` at `step` with seed `seed`, and what they cost and where they are.

    A trial that exhausts its check budget returns ok=False with the checks it spent (a censored value).
    """
    from app.samplers import SamplerBudgetExceeded, make_sampler

    if max_checks is not None:
        params["max_checks"] = max_checks
    sampler = make_sampler(sampler_name, oracle, step=step, **params)
    rng = np.random.default_rng(seed)
    before = oracle.checks
    start = time.perf_counter()
    try:
        samples, ok = sampler.sample(k, rng), True
    except SamplerBudgetExceeded:
        samples, ok = np.empty((0, oracle.dim)), False
    seconds = time.perf_counter() - start
    row = {
        "scene": oracle.scene.name, "sampler": sampler_name, "step": float(step), "seed": int(seed), "k": int(k),
        "ok": ok, "seconds": seconds, "collision_checks": int(oracle.checks - before),
        "passage_fraction": float(oracle.in_passage(samples).mean()) if len(samples) else float("nan"),
        "gave_up": int(sampler.stats.get("gave_up", 0)), "attempts": int(sampler.stats.get("attempts", 0)),
    }
    if margin is not None and len(samples):
        row.update({f"near_{key}": v for key, v in sits_between(oracle, samples, margin).items()})
    if keep_samples:
        row["samples"] = samples
        row["bridges"] = sampler.bridges
    return row


def run_trial_spec(oracle, spec) -> dict:
    """One sampling trial from a results-store TrialSpec (experiment "sampling"; method = sampler name).

    params: k (default 30), max_checks (default none), margin (default twice the scene's resolution). The row
    holds `censored` (the trial spent its check budget: collision_checks and seconds are then lower bounds and
    passage_fraction is None) and `sample_checksum`, a hash of the samples that is the same wherever the trial ran.
    """
    import hashlib

    p = spec.params
    margin = p.get("margin")
    margin = 2 * oracle.resolution if margin is None else float(margin)
    oracle.reset()
    row = run_trial(oracle, spec.method, spec.step, spec.seed, k=int(p.get("k", 30)), margin=margin,
                    max_checks=p.get("max_checks"), keep_samples=True)
    samples = np.round(np.asarray(row.pop("samples"), float), 9)
    row.pop("bridges", None)
    row["sample_checksum"] = hashlib.sha256(samples.tobytes()).hexdigest()[:16] if len(samples) else None
    row["censored"] = not row["ok"]
    if not np.isfinite(row["passage_fraction"]):
        row["passage_fraction"] = None  # no samples: no fraction (JSON has no NaN)
    return row


def summarise(rows: list[dict]) -> list[dict]:
    """Median and 95 % interval (2.5 / 97.5 percentiles) of each metric per scene x sampler x step."""
    cells: dict[tuple, list[dict]] = {}
    for r in rows:
        cells.setdefault((r["scene"], r["sampler"], r["step"]), []).append(r)
    out = []
    for (scene, sampler, step), group in cells.items():
        s = {"scene": scene, "sampler": sampler, "step": step, "trials": len(group),
             "censored": sum(not r["ok"] for r in group)}
        for key, _ in METRICS:
            values = np.array([r[key] for r in group], float)
            values = values[np.isfinite(values)]
            if len(values):
                lo, med, hi = np.percentile(values, [2.5, 50, 97.5])
            else:
                lo = med = hi = float("nan")
            s[key] = {"median": float(med), "lo": float(lo), "hi": float(hi)}
        for key in ("near_environment", "near_self", "near_both", "near_neither"):
            values = [r[key] for r in group if key in r]
            if values:
                s[key] = float(np.mean(values))
        out.append(s)
    return out


def print_table(summary: list[dict]) -> None:
    print(f"{'scene':<9} {'sampler':<8} {'step':>5} {'t_eps s (95% int.)':>26} {'gamma_c (95% int.)':>28} "
          f"{'passage (95% int.)':>20} {'env':>5} {'self':>5} {'both':>5} {'none':>5}")
    for s in summary:
        t, c, p = s["seconds"], s["collision_checks"], s["passage_fraction"]
        mark = "≥" if s["censored"] else " "
        near = " ".join(f"{s.get(k, float('nan')):>5.2f}" for k in
                        ("near_environment", "near_self", "near_both", "near_neither"))
        print(f"{s['scene']:<9} {s['sampler']:<8} {s['step']:>5g} "
              f"{mark}{t['median']:>7.3f} ({t['lo']:>7.3f}-{t['hi']:>7.3f}) "
              f"{mark}{c['median']:>8.0f} ({c['lo']:>8.0f}-{c['hi']:>8.0f}) "
              f"{p['median']:>6.2f} ({p['lo']:.2f}-{p['hi']:.2f}) {near}"
              + (f"  [{s['censored']}/{s['trials']} over budget]" if s["censored"] else ""))


def figure(summary: list[dict], path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from app.draw import save

    scenes = list(dict.fromkeys(s["scene"] for s in summary))
    samplers = list(dict.fromkeys(s["sampler"] for s in summary))
    fig, axes = plt.subplots(len(scenes), len(METRICS), figsize=(4.2 * len(METRICS), 3.4 * len(scenes)),
                             squeeze=False)
    for i, scene in enumerate(scenes):
        for j, (key, label) in enumerate(METRICS):
            ax = axes[i][j]
            for n, sampler in enumerate(samplers):
                cell = sorted((s for s in summary if s["scene"] == scene and s["sampler"] == sampler),
                              key=lambda s: s["step"])
                x = [s["step"] for s in cell]
                med = [s[key]["median"] for s in cell]
                ax.plot(x, med, marker="o", ms=3, color=f"C{n}", label=sampler)
                ax.fill_between(x, [s[key]["lo"] for s in cell], [s[key]["hi"] for s in cell],
                                color=f"C{n}", alpha=0.12)
                censored = [(s["step"], s[key]["median"]) for s in cell if s["censored"]]
                if censored:  # some trials spent the whole budget: the median is a lower bound
                    ax.scatter(*zip(*censored), marker="^", s=40, facecolors="none", edgecolors=f"C{n}")
            if key != "passage_fraction":
                ax.set_yscale("log")
            ax.set(xlabel="step a", ylabel=label, title=f"{scene}: {label}")
            ax.grid(alpha=0.3)
    axes[0][-1].legend(fontsize=7)
    fig.text(0.01, 0.0, "bands: 95 % interval over trials; open triangles: some trials hit the check budget "
                        "(the median is a lower bound)", fontsize=7)
    fig.tight_layout()
    save(fig, path)


def run(args) -> int:
    from tqdm import tqdm

    from app.errors import UserError
    from app.oracle import CollisionOracle
    from app.samplers import SAMPLERS
    from app.scene import Scene

    scenes = [s.strip() for s in args.scenes.split(",") if s.strip()]
    samplers = [s.strip() for s in args.samplers.split(",") if s.strip()]
    unknown = [s for s in samplers if s not in SAMPLERS]
    if unknown or not samplers or not scenes:
        raise UserError(f"unknown sampler(s) {', '.join(unknown) or '(none given)'} (known: {', '.join(SAMPLERS)})")
    if any(not (a > 0) for a in args.steps):
        raise UserError("steps must be positive")
    oracles = {name: CollisionOracle(Scene(name), threads=args.threads) for name in scenes}
    todo = [(sc, sa, a, seed) for sc in scenes for sa in samplers for a in args.steps for seed in range(args.trials)]
    rows = []
    for scene, sampler, step, seed in tqdm(todo, desc="bench sampling", unit="trial"):
        oracle = oracles[scene]
        margin = args.margin if args.margin is not None else 2 * oracle.resolution
        rows.append(run_trial(oracle, sampler, step, seed, k=args.k, margin=margin, max_checks=args.max_checks))
    summary = summarise(rows)
    if args.png:
        figure(summary, args.png)
    if args.json:
        print_json({"rows": rows, "summary": summary})
    else:
        print_table(summary)
        if args.png:
            print(args.png)
    return 0
