"""The ablation's summary and pictures on small synthetic trial tables whose answers are known."""

import pytest

from app.bench.ablation import RUN_LAST, VARIANTS, figure, markdown, specs, summarise


def row(variant: str, seed: int, success: bool, checks: int, placed: int = 0, walked: int = 0, uniform: int = 0):
    metrics = {"success": float(success), "checks": checks}
    if success:
        metrics.update(workspace_on_path=placed, narrow_on_path=walked, uniform_on_path=uniform)
    return {"scene": "bar", "method": variant, "seed": seed, "params": {"checks": 50_000}, "metrics": metrics}


def test_specs_are_seed_major_so_a_stopped_sweep_covers_every_cell_alike():
    todo = specs(["bar", "maze"], list(VARIANTS), 3, 50_000)
    assert len(todo) == 2 * len(VARIANTS) * 3
    quick = [v for v in VARIANTS if v not in RUN_LAST]
    first = todo[: 2 * len(quick)]
    assert {s.seed for s in first} == {0}
    assert {(s.scene, s.method) for s in first} == {(sc, v) for sc in ("bar", "maze") for v in quick}
    # the slow variants come after every seed of the others, seed-major too
    tail = todo[2 * len(quick) * 3 :]
    assert {s.method for s in tail} == set(RUN_LAST) and [s.seed for s in tail] == sorted(s.seed for s in tail)
    assert len({s.key for s in todo}) == len(todo)


def test_summary_counts_success_compares_with_the_default_and_names_the_path_sources(tmp_path):
    rows = [row("default", s, True, 1000 + s, placed=2, walked=1) for s in range(20)]
    rows += [row("uniform-alone", s, s < 4, 30_000 + s if s < 4 else 50_000, uniform=3) for s in range(20)]
    table = {r["variant"]: r for r in summarise(rows, ["bar"], ["default", "uniform-alone"])}
    base, alone = table["default"], table["uniform-alone"]
    assert (base["successes"], alone["successes"]) == (20, 4)
    assert base["vs_default"] is None
    vs = alone["vs_default"]  # paired by seed: 16 seeds only the default solved, 20 on which it checked less
    assert vs["pairs"] == 20 and (vs["fewer_checks"], vs["more_checks"]) == (0, 20)
    assert vs["success_mcnemar_p"] == pytest.approx(2 * 0.5**16)
    assert vs["checks_wilcoxon_p"] < 1e-3
    # Holm over the table's two tests: the smaller p doubled, the larger kept (but not below the smaller's)
    assert vs["success_mcnemar_p"] < vs["checks_wilcoxon_p"]
    assert vs["success_p_adjusted"] == pytest.approx(2 * vs["success_mcnemar_p"])
    assert vs["checks_p_adjusted"] == pytest.approx(max(vs["checks_wilcoxon_p"], vs["success_p_adjusted"]))
    assert base["path_nodes_from"] == {"workspace": 40, "narrow": 20, "uniform": 0}
    assert alone["path_nodes_from"] == {"workspace": 0, "narrow": 0, "uniform": 12}
    assert base["median_checks_ci"][0] <= base["median_checks"] <= base["median_checks_ci"][1]
    text = markdown(list(table.values()), 40, 40, 50_000, 20)
    assert "| bar | uniform-alone | 4/20 |" in text
    assert "| 40 / 20 / 0 |" in text
    assert "`uniform-alone` against `default`: better in 0 scene(s); worse in 1: bar (4/20 vs 20/20" in text
    assert "fewer in 0 of 20 seeds)" in text and "| 0 / 20 |" in text
    assert "Best variant per scene (most successes, then fewest median checks): `default` in bar." in text
    assert "40 narrow-passage nodes were workspace-gap placements and 20 came from the Lévy walkers (33%)" in text


@pytest.mark.parametrize("solved", [0, 3])
def test_figure_draws_cells_with_and_without_a_solved_run(tmp_path, solved):
    rows = [row("default", s, True, 1000 + 10 * s, placed=1) for s in range(5)]
    rows += [row("lfbs-alone", s, s < solved, 9000 + s if s < solved else 50_000) for s in range(5)]
    table = summarise(rows, ["bar"], ["default", "lfbs-alone"])
    figure(table, str(tmp_path / "a.png"), 50_000)
    assert (tmp_path / "a.png").stat().st_size > 10_000


def test_the_command_fills_its_store_and_rebuilds_the_table_from_it_alone(cli, tmp_path):
    import json

    argv = ["bench", "ablation", "--scenes", "bar-3link", "--variants", "default,lfbs-alone", "--seeds", "2"]
    argv += ["--checks", "20000", "--store", tmp_path / "a.sqlite", "--out", tmp_path / "out", "--json"]
    first = cli(*argv)
    assert first.returncode == 0, first.stderr
    answer = json.loads(first.stdout)
    assert (answer["trials"], answer["planned"], answer["reused"]["reused"]) == (4, 4, 0)
    table = (tmp_path / "out" / "table.md").read_text()
    assert "4 of 4 trials" in table and "| bar-3link | lfbs-alone |" in table
    assert (tmp_path / "out" / "ablation.png").is_file()
    (tmp_path / "out" / "table.md").unlink()
    # --report-only runs nothing: asked for 3 seeds, it reports the 4 stored trials of 6
    again = cli(*[a if a != "2" else "3" for a in argv], "--report-only")
    assert again.returncode == 0, again.stderr
    assert json.loads(again.stdout)["trials"] == 4
    assert "4 of 6 trials" in (tmp_path / "out" / "table.md").read_text()
    # a trial of other code is reused, and named in the table, until --fresh runs it again
    import sqlite3

    with sqlite3.connect(tmp_path / "a.sqlite") as db:
        db.execute("UPDATE trials SET code_version = 'older' WHERE seed = 0 AND method = 'default'")
    kept = cli(*argv)
    assert json.loads(kept.stdout)["reused"]["reused"] == 4 and "`older`" in (tmp_path / "out" / "table.md").read_text()
    fresh = cli(*argv, "--fresh")
    assert json.loads(fresh.stdout)["reused"]["reused"] == 3
    assert "older" not in (tmp_path / "out" / "table.md").read_text()
    # trials run now are named as well as those reused: one more seed on other code makes the table mixed
    with sqlite3.connect(tmp_path / "a.sqlite") as db:
        db.execute("UPDATE trials SET code_version = 'older'")
    grown = cli(*[a if a != "2" else "3" for a in argv])
    table = (tmp_path / "out" / "table.md").read_text()
    assert json.loads(grown.stdout)["reused"]["reused"] == 4
    versions = table.split("Code version(s) of the trials: ")[1].split(" -- ")[0]
    assert "`older`" in versions and versions.count("`") == 4 and "mixed" in table


def test_the_schema_names_every_variant():
    import json
    from pathlib import Path

    schema = json.loads((Path(__file__).parents[1] / "docs/schemas/bench-ablation.json").read_text())

    def enums(node):
        if isinstance(node, dict):
            if "enum" in node and "default" in node["enum"]:
                yield node["enum"]
            for value in node.values():
                yield from enums(value)
        elif isinstance(node, list):
            for value in node:
                yield from enums(value)

    assert list(enums(schema)) == [list(VARIANTS)]
