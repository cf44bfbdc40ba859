"""The compiled loops (app.checking.kernels): the oracle loads them for the argument types the planner passes, so
that no query compiles one (a first run compiles each for seconds, and a kernel called with other types -- another
array layout, another integer type -- would compile again inside a query's time)."""

import numba
import pytest

import app
from app.checking import kernels


@pytest.mark.parametrize("name", ["window", "maze"])
def test_a_plan_compiles_no_kernel_the_oracle_did_not_load(oracles, name):
    oracle = oracles(name)
    loaded = _signatures()
    for seed in range(2):
        assert app.plan(oracle, app.PlanSettings(seed=seed)).certificate.proved
    assert _signatures() == loaded
    assert all(count == 1 for count in loaded.values()), loaded


def _signatures() -> dict:
    """The compiled signatures of each kernel the other modules call."""
    dispatchers = {name: getattr(kernels, name) for name in dir(kernels) if not name.startswith("_")}
    return {
        name: len(kernel.signatures)
        for name, kernel in dispatchers.items()
        if isinstance(kernel, numba.core.registry.CPUDispatcher)
    }
