"""The compiled loops (app.checking.kernels): the oracle loads them for the argument types the planner passes, so
that no query compiles one (a first run compiles each for seconds, and a kernel called with other types -- another
array layout, another integer type -- would compile again inside a query's time)."""

import numba
import numpy as np
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


@pytest.mark.parametrize("name", ["bar", "welding"])
def test_an_edge_check_asks_the_points_an_interpolation_gives_coarse_to_fine(oracles, name):
    """The compiled edge points are the edge's interpolation (the same count of pieces, the same points, continuous
    angles wrapped), its ends first, then round by round, each round's points between those asked before."""
    space = oracles(name).space
    rng = np.random.default_rng(3)
    Q1, Q2 = space.uniform(rng, 40), space.uniform(rng, 40)
    Q2 = Q1 + (Q2 - Q1) * rng.uniform(0, 1, (40, 1)) ** 3  # short and long edges
    points, owner, inside, last, round_end, outside, opening = kernels.edge_points(
        Q1, Q2, space.resolution, 0, np.zeros(40, np.int64), *space.edge_table
    )
    assert inside.all() and outside == len(points)
    # rounds follow one another: each point's round ends after it; the opening rounds 0-2 hold up to 7 an edge
    assert (np.diff(round_end) >= 0).all() and (round_end > np.arange(len(points))).all()
    assert opening == round_end[opening - 1] and opening == sum(min(7, n) for n in np.bincount(owner))
    for e in range(40):
        expected = space.interpolate(Q1[e], Q2[e])
        mine = points[owner == e]
        assert last[e] == np.flatnonzero(owner == e)[-1]
        assert len(mine) == len(expected)
        np.testing.assert_array_equal(mine[:2], expected[[0, -1]])
        np.testing.assert_array_equal(np.unique(mine, axis=0), np.unique(expected, axis=0))


def test_a_cut_kills_exactly_the_nodes_below_it():
    """After edges leave a shortest-path tree, a node is dead exactly when its path to the root used one of them."""
    from app.planning.graph import SearchTree

    rng = np.random.default_rng(0)
    n = 300
    pred = np.array([-1] + [int(rng.integers(0, v)) for v in range(1, n)], np.int32)  # parents come first
    tree = SearchTree(pred)
    gone = set()
    for _ in range(6):
        P = np.array([[int(pred[v]), v] if rng.random() < 0.8 else [v, int(rng.integers(0, n))]
                      for v in rng.integers(1, n, 3)], np.int64)  # fmt: skip
        tree.cut(P)
        gone |= {(int(u), int(v)) for u, v in P if pred[v] == u} | {(int(v), int(u)) for u, v in P if pred[u] == v}
        for v in range(n):
            expected, w = False, v
            while pred[w] >= 0:  # up the tree to its root
                expected |= (int(pred[w]), w) in gone
                w = int(pred[w])
            assert tree.dead[v] == expected, v
