"""Oracle throughput against a raw SceneGraph `HasCollisions` loop on the same configurations.

Raw, 1-core and 2-core runs are interleaved per repeat so machine noise hits all three alike; the median of the
repeats counts. On 2 cores the oracle takes its cheapest batch path: Drake's threaded batch or the raw loop split with
a helper process (app.checking.oracle), whose start is timed apart. The raw loop is what a user would write by hand:
set positions, evaluate the query port, ask (`CollisionOracle.query_object` does the first two, on the oracle's
policy context).

A scene is a shipped name, a problem file or a custom scene file (robot/env keys): each is loaded twice into an
empty mesh cache of its own, so the first load includes building the mesh decompositions and the second reads them
from the cache; both times include Drake's set-up of the collision checker.
"""

import tempfile
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from app.checking.oracle import CollisionOracle
from app.scene.custom import load_scene


def raw_loop(oracle: CollisionOracle, Q: np.ndarray) -> np.ndarray:
    """Free flags by HasCollisions in a plain Python loop: what Drake does per configuration, nothing around it."""
    out = np.empty(len(Q), bool)
    for i, q in enumerate(Q):
        out[i] = not oracle.query_object(q).HasCollisions()
    return out


def raw_checks_per_second(oracle: CollisionOracle, n: int = 500, seed: int = 0) -> float:
    """How many configurations per second `raw_loop` answers on this machine now (n uniform ones): the limit a
    planner's checks per second is measured against."""
    Q = oracle.space.uniform(np.random.default_rng(seed), n)
    seconds, _ = _timed(raw_loop, oracle, Q)
    return n / seconds


def _timed(fn, *args):
    start = time.perf_counter()
    result = fn(*args)
    return time.perf_counter() - start, result


def bench_oracle(scene_names: list[str], n: int, repeats: int, seed: int) -> list[dict]:
    rows = []
    for name in scene_names:
        with tempfile.TemporaryDirectory(prefix="npp-bench-oracle-") as cache:
            rows.append(_bench_scene(name, Path(cache), n, repeats, seed))
    return rows


def _bench_scene(name: str, cache: Path, n: int, repeats: int, seed: int) -> dict:
    load_first, one = _timed(lambda: CollisionOracle(load_scene(name, cache_dir=cache), threads=1))
    load_cached, two = _timed(lambda: CollisionOracle(load_scene(name, cache_dir=cache), threads=2))
    helpers_start, helpers_ready = _timed(two.start_helpers)  # at once, not after half a second of batches
    Q = one.space.uniform(np.random.default_rng(seed), n)
    # The 2-core oracle tries every batch path before it settles on the cheapest: those calls are not timed.
    warm, choice = one.space.uniform(np.random.default_rng(seed + 1), n), two.paths_for(n)
    while not choice.settled:
        two.context().are_free(warm)
    times = {"raw": [], "one": [], "two": []}
    in_drake = one.seconds["checks"]
    for _ in tqdm(range(repeats), desc=f"bench oracle {name}", leave=False):
        t_raw, raw = _timed(raw_loop, one, Q)
        t_one, free_one = _timed(one.context().are_free, Q)
        t_two, free_two = _timed(two.context().are_free, Q)
        if not (np.array_equal(raw, free_one) and np.array_equal(raw, free_two)):
            raise RuntimeError(f"{name}: oracle and raw HasCollisions disagree")
        times["raw"].append(t_raw)
        times["one"].append(t_one)
        times["two"].append(t_two)
    in_drake = one.seconds["checks"] - in_drake
    med = {k: float(np.median(v)) for k, v in times.items()}
    return {
        "scene": name,
        "load_first_s": load_first,
        "load_cached_s": load_cached,
        "helpers_start_s": helpers_start,
        "helpers_ready": bool(helpers_ready),
        "us_per_check_1": 1e6 * med["one"] / n,
        "configurations": n,
        "repeats": repeats,
        "free_fraction": float(raw.mean()),
        "raw_per_s": n / med["raw"],
        "oracle_1_per_s": n / med["one"],
        "oracle_2_per_s": n / med["two"],
        "ratio_1": med["raw"] / med["one"],
        "ratio_2": med["raw"] / med["two"],
        "drake_share_1": in_drake / sum(times["one"]),
    }
