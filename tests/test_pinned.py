"""Same seed, same plan: `plan bar --seed 0` and `plan maze --seed 1` give the paths recorded in
tests/data/pinned_plans.json. A change that alters them on purpose (a new planning rule) records them anew and
says why in its commit."""

import json
from pathlib import Path

import numpy as np
import pytest

from app.planning.planner import PlanSettings, plan

PINNED = json.loads((Path(__file__).parent / "data" / "pinned_plans.json").read_text())


@pytest.mark.parametrize("key", list(PINNED))
def test_plan_reproduces_the_pinned_path(oracles, key):
    scene, _, seed = key.split()
    oracle = oracles(scene)
    result = plan(oracle, PlanSettings(seed=int(seed)))
    want = PINNED[key]
    np.testing.assert_allclose(result.roadmap_path, want["roadmap_path"], atol=1e-9)
    np.testing.assert_allclose(result.path, want["path"], atol=1e-9)
