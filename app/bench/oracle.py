"""Oracle throughput against a raw SceneGraph `HasCollisions` loop on the same configurations.

Raw, 1-thread and 2-thread runs are interleaved per repeat so machine noise hits all three alike; the median of
the repeats counts. The raw loop is what a user would write by hand: set positions, evaluate the query port, ask.
"""
import time

import numpy as np
from tqdm import tqdm

from app.cli import positive_int, print_json
from app.oracle import CollisionOracle
from app.scene import Scene


def register(kinds) -> None:
    o = kinds.add_parser("oracle", help="oracle checks/s vs raw HasCollisions on 1 and 2 threads")
    o.add_argument("--scenes", default="bar,joint3d", help="comma-separated scene names")
    o.add_argument("-n", type=positive_int, default=20000, help="configurations per measurement")
    o.add_argument("--repeats", type=positive_int, default=5, help="runs per measurement (the median counts)")
    o.add_argument("--seed", type=int, default=0)
    o.add_argument("--json", action="store_true")
    o.set_defaults(func=run)


def run(args) -> int:
    rows = bench_oracle(args.scenes.split(","), n=args.n, repeats=args.repeats, seed=args.seed)
    if args.json:
        print_json({"oracle": rows})
        return 0
    print(f"{'scene':<10} {'raw k/s':>9} {'1 thread k/s':>13} {'ratio':>6} {'2 threads k/s':>14} {'ratio':>6}")
    for r in rows:
        print(f"{r['scene']:<10} {r['raw_per_s'] / 1e3:>9.1f} {r['oracle_1_per_s'] / 1e3:>13.1f} "
              f"{r['ratio_1']:>6.2f} {r['oracle_2_per_s'] / 1e3:>14.1f} {r['ratio_2']:>6.2f}")
    return 0


def _raw_loop(oracle: CollisionOracle, Q: np.ndarray) -> np.ndarray:
    plant, context, port = oracle.plant, oracle._ctx, oracle._query_port
    out = np.empty(len(Q), bool)
    for i, q in enumerate(Q):
        plant.SetPositions(context, q)
        out[i] = not port.Eval(context).HasCollisions()
    return out


def _timed(fn, *args):
    start = time.perf_counter()
    result = fn(*args)
    return time.perf_counter() - start, result


def bench_oracle(scene_names: list[str], n: int, repeats: int, seed: int) -> list[dict]:
    rows = []
    for name in scene_names:
        scene = Scene(name.strip())
        one, two = CollisionOracle(scene, threads=1), CollisionOracle(Scene(name.strip()), threads=2)
        Q = one.uniform(np.random.default_rng(seed), n)
        times = {"raw": [], "one": [], "two": []}
        for _ in tqdm(range(repeats), desc=f"bench oracle {name}", leave=False):
            t_raw, raw = _timed(_raw_loop, one, Q)
            t_one, free_one = _timed(one.are_free, Q)
            t_two, free_two = _timed(two.are_free, Q)
            if not (np.array_equal(raw, free_one) and np.array_equal(raw, free_two)):
                raise RuntimeError(f"{name}: oracle and raw HasCollisions disagree")
            times["raw"].append(t_raw)
            times["one"].append(t_one)
            times["two"].append(t_two)
        med = {k: float(np.median(v)) for k, v in times.items()}
        rows.append({
            "scene": name, "configurations": n, "repeats": repeats, "free_fraction": float(raw.mean()),
            "raw_per_s": n / med["raw"], "oracle_1_per_s": n / med["one"], "oracle_2_per_s": n / med["two"],
            "ratio_1": med["raw"] / med["one"], "ratio_2": med["raw"] / med["two"],
        })
    return rows
