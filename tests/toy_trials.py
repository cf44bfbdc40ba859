"""A cheap deterministic trial for testing the store and runners: a few seeded collision checks."""

import time

import numpy as np


def run(oracle, spec):
    rng = np.random.default_rng(spec.seed)
    checker = oracle.context()
    free = checker.are_free(oracle.space.uniform(rng, int(spec.params.get("n", 20))))
    time.sleep(float(spec.params.get("sleep", 0.0)))
    return {"free": int(free.sum()), "collision_checks": checker.checks}
