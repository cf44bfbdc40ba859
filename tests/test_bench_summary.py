"""`bench summary` (app/bench/summary.py): the benchmark page's opening tables are the stores' figures, written
between the page's two marker lines and nowhere else; a missing store is one line and exit code 2; and the tables
docs/benchmarks.md opens with are those the committed stores give."""

from pathlib import Path

from app.bench import summary
from app.bench.ompl import PROTOCOL
from app.bench.store import ResultStore, TrialSpec

BEFORE, AFTER = "# Benchmarks\n\nText before.\n\n", "\n\n## What each benchmark measures\n\nText after.\n"


def _plan_rows(store: ResultStore) -> None:
    """bar: 3 default plans (checks 1,000, 1,500 and 9,000; the last a failure); a row of another sampler and one
    of the full roadmap, which the table leaves out."""
    for seed, (checks, seconds, ok) in enumerate([(1000, 0.2, True), (1500, 0.4, True), (9000, 3.0, False)]):
        metrics = {"success": float(ok), "seconds": seconds, "collision_checks": checks, "load_average": 1.5}
        if ok:
            metrics.update(seconds_to_path=seconds / 2, narrow_on_path=1, certified=seed == 0)
        store.add(TrialSpec("prm", "bar", "lfbs", 10.0, seed, dict(summary.PLAN_PARAMS)), metrics)
    other = {"success": 1.0, "seconds": 9.0, "collision_checks": 99, "seconds_to_path": 1.0, "narrow_on_path": 0}
    store.add(TrialSpec("prm", "bar", "uniform", 10.0, 0, dict(summary.PLAN_PARAMS)), other)
    store.add(TrialSpec("prm", "bar", "lfbs", 10.0, 0, {**summary.PLAN_PARAMS, "full_roadmap": True}), other)


def _ompl_rows(store: ResultStore) -> None:
    """bar, 2 seeds: ours solves both (4,000 and 6,000 checks), RRTConnect one (50,000), the others none."""
    params = {"budget": 10.0, "protocol": PROTOCOL}
    solved = {"ours:default": [4000, 6000], "ompl:RRTConnect": [50000, None]}
    for method in summary.OMPL_METHODS:
        for seed in range(2):
            checks = solved.get(method, [None, None])[seed]
            ok = checks is not None
            metrics = {"solved": float(ok), "success": float(ok), "late": 0.0, "seconds": 1.0 if ok else 10.0}
            metrics.update(checks=checks if ok else 80000, fine_check_passed=float(ok), smoothing_checks=10)
            store.add(TrialSpec("ompl", "bar", method, 10.0, seed, params), metrics)


def _answer(checks: int, seconds: float, ok: bool = True, certified: bool = True) -> dict:
    return {"success": ok, "checks": checks, "seconds": seconds, "certified": certified and ok, "timed": ok}


def _queries_rows(store: ResultStore) -> None:
    """window, 3 queries: fresh 2,000/3,000/40,000 checks, the cell 100/200/300 on a 1,500-node build."""
    params = {"protocol": "query-set+answers", "queries": 3, "query_set": "abc", "budget": "600s,200000checks"}
    fresh = [_answer(2000, 0.2), _answer(3000, 0.3), _answer(40000, 4.0, ok=False)]
    cell = [_answer(100, 0.05), _answer(200, 0.04), _answer(300, 0.06)]
    build = {"seconds": 17.0, "checks": 1_500_000, "nodes": 1500, "edges": 9000, "ended": "nodes", "workers": 1}
    cell_params = {**params, "build_nodes": 1500, "build_budget": "3000000checks", "workers": 1}
    store.add(TrialSpec("queries", "window", "fresh", 0.2, 0, params), {"build": None, "answers": fresh})
    store.add(TrialSpec("queries", "window", "cell", 0.2, 0, cell_params), {"build": build, "answers": cell})


def _moveit_rows(store: ResultStore) -> None:
    """box/0001 solved by both (ours 1,000 checks in 0.5 s, RRTConnect 4,000 in 1.0 s, its path colliding),
    cage/0001 by ours alone."""
    params = {"checks": 100_000}
    cells = {
        ("box/0001", "ours"): (1.0, 1000, 0.5, 0.0),
        ("box/0001", "ompl:RRTConnect"): (1.0, 4000, 1.0, 1.0),
        ("cage/0001", "ours"): (1.0, 3000, 2.0, 0.0),
        ("cage/0001", "ompl:RRTConnect"): (0.0, 100_000, 20.0, 0.0),
    }
    for (problem, method), (solved, checks, seconds, colliding) in cells.items():
        metrics = {"solved": solved, "checks": checks, "seconds": seconds, "colliding": colliding}
        store.add(TrialSpec("moveit", problem, method, 0.0, 0, params), metrics)


def _results(folder: Path) -> Path:
    for table, fill in (
        ("scenes", _plan_rows), ("ompl", _ompl_rows), ("queries", _queries_rows), ("moveit", _moveit_rows)
    ):  # fmt: skip
        store = ResultStore(folder / summary.STORES[table])
        try:
            fill(store)
        finally:
            store.close()
    return folder


def _page(tmp_path: Path, block: str = "old tables") -> Path:
    page = tmp_path / "benchmarks.md"
    page.write_text(f"{BEFORE}{summary.BEGIN}\n{block}\n{summary.END}{AFTER}")
    return page


def test_the_tables_are_the_stores_figures_written_between_the_markers(cli, tmp_path):
    results, page = _results(tmp_path / "results"), _page(tmp_path)
    result = cli("bench", "summary", "--results", results, "--page", page)
    assert result.returncode == 0, result.stderr
    text = page.read_text()
    assert text.startswith(BEFORE + summary.BEGIN) and text.endswith(summary.END + AFTER)
    assert "old tables" not in text
    flat = text.replace(" \\\n    ", " ")  # the commands shown, each on one line
    # how fast: 2 of 3 successes, medians over all three runs, certified: 1 of the 2 successes
    assert "| `bar` | 2/3 | 1,500 | 0.400 | 50 % |" in text
    assert "python -m app bench plan --scenes bar --samplers lfbs --seeds 3 --workers 1" in flat
    assert "load average 1.5" in text
    # against OMPL: ours 4,000 and 6,000 checks, RRTConnect once at 50,000, the best OMPL planner
    assert "| `bar` | 2/2 (5.0k) | 1/2 (50k) | 0/2 | 0/2 | 0/2 | 0.1 (RRTConnect) |" in text
    assert "--seeds 2 --budget 10 --workers 1 --store results/ompl/bench-ompl.sqlite" in flat
    # with a stored roadmap: per-query medians and p95, the build, the ratio of the totals
    assert "| `window` | fresh single queries | 2/3 | 3,000 / 36,300 | 0.300 / 3.63 | 100 % | 4.50 |" in text
    assert "| `window` | one cell roadmap (built once: 1,500 nodes, 17.0 s) | 3/3 | 200 / 290 |" in text
    assert "| `window` | fresh single queries | 0.0133x | 0.0333x | 3.81x |" in text
    assert "--queries 3 --methods fresh,cell --workers 1 --store results/queries/bench-queries.sqlite" in flat
    # on MoveIt's problems: medians over the problems both solved, colliding paths counted
    assert "| all | 2 | 2, 1 | 1,000 vs 4,000 | 0.25 | 0.50 vs 1.00 (-) | 0.50 | 0.50 | 0, 1 |" in text
    assert "python -m app bench moveit --store results/moveit/moveit.sqlite" in flat
    # the same stores again: the page is left as it is
    again = cli("bench", "summary", "--results", results, "--page", page)
    assert again.returncode == 0 and "up to date" in again.stderr and page.read_text() == text


def test_a_missing_store_or_page_markers_are_one_line_and_exit_2(cli, one_line_error, tmp_path):
    results, page = _results(tmp_path / "results"), _page(tmp_path)
    (results / summary.STORES["queries"]).unlink()
    line = one_line_error(cli("bench", "summary", "--results", results, "--page", page), 2)
    assert "no results store" in line and "python -m app bench queries" in line
    assert "old tables" in page.read_text()  # nothing written
    (results / summary.STORES["ompl"]).write_text("not a store")
    line = one_line_error(cli("bench", "summary", "--results", results, "--page", page), 2)
    assert "not a results store" in line
    (results / summary.STORES["ompl"]).unlink()
    _results(results)
    page.write_text("# Benchmarks\n\nno markers\n")
    line = one_line_error(cli("bench", "summary", "--results", results, "--page", page), 2)
    assert "bench summary: begin" in line and page.read_text() == "# Benchmarks\n\nno markers\n"


def test_the_benchmark_page_opens_with_the_tables_the_committed_stores_give():
    text = summary.PAGE.read_text()
    block = text.split(summary.BEGIN, 1)[1].split(summary.END, 1)[0].strip()
    assert block == summary.tables(summary.RESULTS), "run `python -m app bench summary` and commit the page"
