"""`bench ompl`'s measure of our planner (app/bench/ompl.py `_ours`): checks and seconds to the first solution leave
out what follows it (smoothing, the proof of the smoothed path, timing), and the first run on an oracle is an
untimed warm-up. The planner is replaced by one returning fixed figures, so the arithmetic is what is tested."""

import dataclasses
from types import SimpleNamespace

import numpy as np

from app.bench import ompl
from app.bench.store import TrialSpec


def _answer():
    return SimpleNamespace(
        collision_checks=1000,
        stats=SimpleNamespace(
            checks=SimpleNamespace(smoothing=30, certify=0, timing=5),
            seconds=SimpleNamespace(total=10.0, smoothing=1.0, certify=2.0, timing=3.0),
        ),
        smoothing=SimpleNamespace(raw_length=2.0, length_after=1.5),
        path=np.zeros((2, 3)),
    )


def test_ours_counts_to_the_first_solution_after_one_untimed_warm_up(monkeypatch):
    seeds = []

    def planner(oracle, settings):
        seeds.append(settings.seed)
        return _answer()

    monkeypatch.setattr(ompl, "plan", planner)
    monkeypatch.setattr(ompl, "_fine_check", lambda oracle, path: {"verify_checks": 0, "fine_check_passed": 1.0})
    monkeypatch.setattr(ompl, "_warmed", set())
    oracle = object()
    spec = TrialSpec("ompl", "bar", "ours:default", 0.1, 4, {"budget": 20, "protocol": ompl.PROTOCOL})

    m = ompl.run_trial_spec(oracle, spec)
    assert (m["checks"], m["seconds"], m["proof_seconds"], m["smoothing_seconds"]) == (965, 4.0, 2.0, 1.0)
    assert m["success"] == 1.0
    assert seeds == [ompl.WARM_SEED, 4]

    ompl.run_trial_spec(oracle, dataclasses.replace(spec, seed=5))
    assert seeds == [ompl.WARM_SEED, 4, 5]  # warmed once per oracle and method
    ompl.run_trial_spec(oracle, dataclasses.replace(spec, method="ours:uniform", seed=5))
    assert seeds == [ompl.WARM_SEED, 4, 5, ompl.WARM_SEED, 5]
