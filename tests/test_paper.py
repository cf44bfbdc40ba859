"""`bench paper`: deterministic sweeps, a report with the claim verdicts and figures, and a resumed run that runs
nothing new. The default-run test uses a tiny configuration (one scene, two samplers, one trial per cell)."""

import json
import shutil
import sqlite3
from pathlib import Path

import pytest

from app.bench import jobs, paper, paper_figures, paper_report, paper_sections, sampling
from app.bench.runner import EXPERIMENTS
from app.bench.statistics import detectable_drop
from app.bench.store import ResultStore, TrialSpec
from app.cli import main

TINY = [
    "bench",
    "paper",
    "--quick",
    "--trials",
    "1",
    "--scenes",
    "bar-3link",
    "--samplers",
    "lfbs,rbbs",
    "--parts",
    "sampling",
    "--max-checks",
    "20000",
    "--workers",
    "1",
]


def test_sweeps_are_deterministic_and_share_the_bar_cells():
    config = paper.Config(trials=2, steps=[2.0, 10.0], samplers=["lfbs", "rbbs", "gaussian"], prm_seeds=1, ur3_runs=1)
    first = [(name, [s.key for s in specs]) for name, specs in paper.sweeps(config)]
    second = [(name, [s.key for s in specs]) for name, specs in paper.sweeps(config)]
    assert first == second
    assert [name for name, _ in first] == paper.PARTS
    keys = dict(first)
    assert len(keys["sampling"]) == 4 * 3 * 2 * 2
    assert len(keys["table1"]) == 3 * 2 * 2 * 2
    assert len(set(keys["sampling"]) & set(keys["table1"])) == 2 * 2 * 2  # bar x (rbbs, lfbs): the same trials
    assert all(s.experiment == "ur3" for s in paper.ur3_specs(1))
    assert EXPERIMENTS["ur3"] == "app.bench.jobs:run_trial_spec"


def test_the_readings_sweep_reruns_only_the_samplers_each_reading_changes():
    config = paper.Config(trials=2, steps=[2.0], scenes=["bar"], samplers=["lfbs", "rbbs", "rwbs"], parts=["sampling"])
    assert [name for name, _ in paper.sweeps(config)] == ["sampling"]
    config.readings = True
    sweeps = dict(paper.sweeps(config))
    assert {s.method for s in sweeps["reading alpha-density"]} == {"lfbs"}  # the Lévy walker of the three
    assert {s.method for s in sweeps["reading bridge-move"]} == {"lfbs", "rwbs"}  # the bridge walkers
    assert sweeps["reading angle-gaussian"][0].params["sampler_params"] == {"angle_law": "gaussian"}
    keys = [s.key for specs in sweeps.values() for s in specs]
    assert len(keys) == len(set(keys))  # every reading's trials are trials of their own


def test_each_reading_is_judged_on_its_own_trials_and_the_default_ones_of_the_other_samplers(tmp_path):
    store = ResultStore(tmp_path / "r.sqlite")
    base = {"k": 30, "max_checks": 1000}
    trial = {"k": 30, "ok": True, "censored": False, "seconds": 0.1, "collision_checks": 500}
    for seed in range(4):
        for method in ("lfbs", "rbbs"):
            store.add(TrialSpec("sampling", "bar", method, 10.0, seed, base), {**trial, "passage_fraction": 0.2})
        gaussian = {**base, "sampler_params": {"angle_law": "gaussian"}}
        store.add(TrialSpec("sampling", "bar", "lfbs", 10.0, seed, gaussian), {**trial, "passage_fraction": 0.9})
    rows = store.rows()
    default, angle = paper.reading_rows(rows, "default"), paper.reading_rows(rows, "angle-gaussian")
    assert len(default) == len(angle) == 8
    assert {r["metrics"]["passage_fraction"] for r in angle if r["method"] == "lfbs"} == {0.9}
    assert {r["method"] for r in angle if r["metrics"]["passage_fraction"] == 0.2} == {"rbbs"}
    paper_report.build_report(store, tmp_path, pictures=False)
    report = (tmp_path / "report.md").read_text()
    table = report.split("## Sensitivity to the paper's readings")[1]
    assert "| default | (default) |" in table and "| angle-gaussian | angle_law=gaussian |" in table
    assert "alpha-density" not in table  # no trials of that reading in the store


def test_tiny_paper_run_writes_the_report_and_resumes(tmp_path, capsys):
    out = tmp_path / "paper"
    assert main([*TINY, "--out", str(out)]) == 0
    said = capsys.readouterr()
    assert "4 trials run" in said.out
    written = [line.removeprefix("wrote ") for line in said.err.splitlines() if line.startswith("wrote ")]
    assert {"results.sqlite", "report.md", "trials.csv.gz", "sampling-bar-3link.png"} <= {Path(w).name for w in written}
    assert all(Path(w).is_file() for w in written)
    report = (out / "report.md").read_text()
    assert "## Claims" in report
    for claim in ("C1", "C2", "C3", "C4", "C5"):
        assert f"| {claim} | **" in report
    assert "## Machine, code, trials" in report and "Trial" in report
    assert "### bar-3link" in report
    figures = sorted(p.name for p in out.glob("*.png"))
    assert "sampling-bar-3link.png" in figures and "samples-bar-3link-lfbs.png" in figures
    for name in figures:
        assert f"]({name})" in report
    store = ResultStore(out / "results.sqlite")
    rows = store.rows("sampling")
    assert len(rows) == 4 and {r["method"] for r in rows} == {"lfbs", "rbbs"}
    assert all("censored" in r["metrics"] and "sample_checksum" in r["metrics"] for r in rows)
    store.close()

    assert main([*TINY, "--out", str(out)]) == 0  # killed or finished: the same options run nothing again
    assert "0 trials run" in capsys.readouterr().out
    assert ResultStore(out / "results.sqlite").count() == 4

    committed = tmp_path / "committed"  # what the repository keeps: the trials as CSV, no store
    committed.mkdir()
    shutil.copy(out / "trials.csv.gz", committed)
    assert main([*TINY, "--out", str(committed)]) == 0
    said = capsys.readouterr().out
    assert "4 trials added to the store" in said and "0 trials run" in said
    assert ResultStore(committed / "results.sqlite").count() == 4
    assert (committed / "trials.csv.gz").read_bytes() == (out / "trials.csv.gz").read_bytes()

    (out / "report.md").unlink()
    assert main([*TINY, "--out", str(out), "--report-only", "--ompl-db", str(tmp_path / "benchmark.db")]) == 0
    assert "## Claims" in (out / "report.md").read_text()
    runs = sqlite3.connect(tmp_path / "benchmark.db").execute("SELECT COUNT(*) FROM runs").fetchone()[0]
    assert runs == 4  # one OMPL run per stored trial


def test_report_only_runs_no_trial_and_links_the_pictures_an_earlier_run_drew(tmp_path, capsys, monkeypatch):
    out = tmp_path / "paper"
    assert main([*TINY, "--out", str(out)]) == 0
    (out / "samples-bar-3link-rbbs.png").unlink()
    before = {p.name for p in out.iterdir()}
    store = ResultStore(out / "results.sqlite")
    stored = store.count()
    store.close()

    def no_trials(*args, **kwargs):
        raise AssertionError("--report-only ran a sampling trial")

    monkeypatch.setattr(sampling, "run_trial", no_trials)
    monkeypatch.setattr(paper, "run_sweep", no_trials)
    capsys.readouterr()
    assert main([*TINY, "--out", str(out), "--report-only"]) == 0
    assert "0 trials run" in capsys.readouterr().out
    assert {p.name for p in out.iterdir()} == before  # the missing picture is not drawn again
    assert ResultStore(out / "results.sqlite").count() == stored
    report = (out / "report.md").read_text()
    assert "](samples-bar-3link-lfbs.png)" in report and "samples-bar-3link-rbbs.png" not in report
    assert "1 of 2 pictures as an earlier run drew them; 1 not drawn" in report


def test_report_only_rebuilds_the_runs_report_byte_for_byte_but_its_time(tmp_path, monkeypatch):
    """The machine and the pictures' captions are the run's (recorded in run.json beside the report), not the
    rebuilding machine's; without the record the machine line says it is the rebuild's."""
    out = tmp_path / "paper"
    assert main([*TINY, "--out", str(out)]) == 0
    first = (out / "report.md").read_text()
    record = json.loads((out / "run.json").read_text())
    assert set(record["pictures"]) == {"samples-bar-3link-lfbs.png", "samples-bar-3link-rbbs.png"}
    (out / "run.json").write_text(json.dumps({**record, "machine": ["the machine that ran the trials"]}))
    monkeypatch.setattr(paper, "run_sweep", lambda *a, **k: pytest.fail("--report-only ran trials"))
    monkeypatch.setattr(sampling, "run_trial", lambda *a, **k: pytest.fail("--report-only drew pictures"))
    assert main([*TINY, "--out", str(out), "--report-only"]) == 0
    again = (out / "report.md").read_text()

    def unstamped(report: str, machine: str) -> str:
        lines = [line for line in report.splitlines() if not line.startswith("Generated ")]
        return "\n".join(lines).replace(machine, "MACHINE")

    ran_on = "\n".join(f"- Machine: {line}" for line in record["machine"])
    assert unstamped(again, "- Machine: the machine that ran the trials") == unstamped(first, ran_on)
    (out / "run.json").unlink()
    assert main([*TINY, "--out", str(out), "--report-only"]) == 0
    assert "(this rebuild's; the trials' machine was not recorded)" in (out / "report.md").read_text()


def test_sampling_trial_spec_is_deterministic_and_marks_censoring(oracles):
    from app.bench.sampling import run_trial_spec

    oracle = oracles("bar-3link")
    spec = TrialSpec("sampling", "bar-3link", "lfbs", 10.0, 3, {"k": 10, "max_checks": 50_000})
    a, b = run_trial_spec(oracle, spec), run_trial_spec(oracle, spec)
    for key in ("collision_checks", "passage_fraction", "sample_checksum", "censored"):
        assert a[key] == b[key]
    assert not a["censored"] and a["sample_checksum"]
    starved = run_trial_spec(oracle, TrialSpec("sampling", "bar-3link", "rbbs", 2.0, 0, {"k": 30, "max_checks": 500}))
    assert starved["censored"] and starved["passage_fraction"] is None and starved["collision_checks"] >= 500
    full = run_trial_spec(oracle, TrialSpec("sampling", "bar-3link", "lfbs", 10.0, 0, {"k": 30}))
    half = {"k": 30, "max_checks": full["collision_checks"] // 2}
    cut = run_trial_spec(oracle, TrialSpec("sampling", "bar-3link", "lfbs", 10.0, 0, half))
    # a trial cut short keeps the samples it drew: they count toward its passage yield
    assert cut["censored"] and 0 < cut["samples_drawn"] < 30 and cut["passage_fraction"] is not None


@pytest.mark.slow
def test_ur3_trial_times_a_job(oracles):
    """A UR3 trial under the paper's protocol (a full roadmap per leg) times a whole job. Window's LFBS seed 1 is one
    of the 14 of 20 runs that succeed (results/paper/report.md); a failed run, such as every welding LFBS run under
    this protocol, is a row without times."""
    # The protocol's seconds a leg (UR3_SIZE's 30) lifted to a hang guard: a full roadmap of fixed size answers the
    # same given any time (the window job took 3.5 s in all), so the verdicts cannot depend on the machine's load.
    by_key = {(s.scene, s.method, s.seed): s for s in paper.ur3_specs(2)}
    unhurried = {key: TrialSpec(**{**vars(s), "params": {**s.params, "budget": 3600.0}}) for key, s in by_key.items()}
    done = jobs.run_trial_spec(oracles("window"), unhurried["window", "lfbs", 1])
    assert done["success"] == 1.0
    assert done["seconds"] >= done["seconds_planning"] > 0 and done["collision_checks"] > 0
    failed = jobs.run_trial_spec(oracles("welding"), unhurried["welding", "lfbs", 0])
    assert failed["success"] == 0.0 and failed["seconds_planning"] is None and "no path" in failed["error"]


@pytest.mark.slow
def test_quick_paper_run(tmp_path):
    out = tmp_path / "paper"
    assert main(["bench", "paper", "--quick", "--out", str(out)]) == 0
    report = (out / "report.md").read_text()
    assert "## Maze and tunnel" in report and "| maze |" in report and "| welding |" in report


def test_exported_trials_read_back_as_the_same_rows(tmp_path):
    store = ResultStore(tmp_path / "a.sqlite")
    store.add(TrialSpec("sampling", "bar", "lfbs", 2.0, 0, {"k": 30}), {"passage_fraction": None, "checks": 7})
    store.add(
        TrialSpec("sampling", "bar", "lfbs", 2.0, 0, {"k": 30, "sampler_params": {"angle_law": "length"}}),
        {"passage_fraction": 0.25, "censored": True},
    )
    store.add(TrialSpec("prm", "maze", "rbbs", 0.5, 3, {"narrow": 200}), {"success": 1.0, "seconds": 1.5})
    path = paper.export_trials(store, tmp_path / "trials.csv.gz")
    copy = ResultStore(tmp_path / "b.sqlite")
    assert paper.import_trials(copy, path) == 3
    assert sorted(map(json.dumps, copy.rows())) == sorted(map(json.dumps, store.rows()))
    assert paper.import_trials(copy, path) == 0  # no trial twice
    assert paper.export_trials(copy, tmp_path / "again.csv.gz").read_bytes() == path.read_bytes()


def test_a_cell_whose_first_trials_all_spend_the_budget_gets_no_more(tmp_path):
    """rbbs at small steps: 30 of 30 censored says what more trials would (each costing the whole budget)."""
    store = ResultStore(tmp_path / "r.sqlite")
    base = {"k": 30, "max_checks": 1000}
    spent = {"k": 30, "ok": False, "censored": True, "seconds": 4.0, "collision_checks": 1000, "passage_fraction": 0}
    done = {**spent, "ok": True, "censored": False, "collision_checks": 900}
    for seed in range(paper.CENSORED_CAP):
        store.add(TrialSpec("sampling", "bar", "rbbs", 2.0, seed, base), spent)
        store.add(TrialSpec("sampling", "bar", "rbbs", 5.0, seed, base), done if seed == 7 else spent)
    specs = paper.sampling_specs(["bar"], ["rbbs"], [2.0, 5.0], 40, max_checks=1000)
    kept = paper.capped(specs, store)
    assert {(s.step, s.seed) for s in specs} - {(s.step, s.seed) for s in kept} == {
        (2.0, seed) for seed in range(paper.CENSORED_CAP, 40)
    }  # a step-5 trial finished: that cell runs on
    paper_report.build_report(store, tmp_path, pictures=False)
    assert "Capped: bar rbbs a=2." in (tmp_path / "report.md").read_text()


@pytest.mark.parametrize("runs", [1, 30])
def test_the_prm_section_says_what_its_runs_can_tell_apart(tmp_path, runs):
    rows = [
        {
            "experiment": "prm",
            "scene": "maze",
            "method": method,
            "step": 0.5,
            "seed": seed,
            "params": {},
            "metrics": {"success": 1.0, "seconds": 2.0, "seconds_sampling": 1.0, "collision_checks": 1000},
            "code_version": "x",
        }
        for method in ("lfbs", "rbbs")
        for seed in range(runs)
    ]
    text = "\n".join(paper_sections.prm_section(rows, tmp_path)[0])
    assert f"Runs per cell: {runs}, not {paper.TARGET_TRIALS}" in text
    if runs == 30:
        assert f"flags LFBS at {detectable_drop(30, 30)}/30 or fewer against RBBS's 30/30" in text
    else:  # one run against one cannot show anything
        assert "flags no LFBS count (too few runs) against RBBS's 1/1" in text
    assert (tmp_path / "prm.png").exists()


def test_prm_runs_whose_sampler_gave_up_are_marked_censored_in_the_table(tmp_path):
    def row(method, seed, metrics):
        return {
            "experiment": "prm",
            "scene": "tunnel",
            "method": method,
            "step": 0.2,
            "seed": seed,
            "params": {},
            "metrics": metrics,
            "code_version": "x",
        }

    rows = [
        row(
            "lfbs",
            s,
            {"success": 1.0, "seconds": 2.0 + s, "seconds_sampling": 1.0, "collision_checks": 1000, "nodes": 302},
        )
        for s in range(4)
    ]
    # three RBBS runs hit the sampler's cap (no roadmap), one planned and failed
    rows += [
        row("rbbs", s, {"success": 0.0, "seconds": 40.0 + s, "collision_checks": 2_000_100, "nodes": 2})
        for s in range(3)
    ]
    rows.append(row("rbbs", 3, {"success": 0.0, "seconds": 9.0, "collision_checks": 90_000, "nodes": 302}))
    lines, found = paper_sections.prm_section(rows, tmp_path)
    text = "\n".join(lines)
    assert "| tunnel | 0.2 | rbbs | 4 | 3 | 0/4 [0%, 60%] | – (124.56) | 9.00 [9.00, 9.00] (253.09) |" in text
    assert "| tunnel | 0.2 | lfbs | 4 | 0 |" in text
    assert found[0].startswith("PRM: 3 of 8 runs (tunnel a=0.2 rbbs 3/4) built no roadmap")
    cells = {c["sampler"]: c for c in paper_figures.prm_cells(rows)}
    assert cells["rbbs"]["gave_up"] == 3 and not cells["rbbs"]["gave_up_only"]
    assert (tmp_path / "prm.png").exists()


def test_the_ur3_section_gives_success_intervals_and_what_more_runs_would_cost():
    rows = [
        {
            "experiment": "ur3",
            "scene": "window",
            "method": "lfbs",
            "step": 0.2,
            "seed": seed,
            "params": {"full_roadmap": True},
            "metrics": {
                "success": float(seed < 3),
                "seconds": 36.0,
                "seconds_ik": 1.0,
                "seconds_planning": 35.0,
                "collision_checks": 1000,
            },
            "code_version": "x",
        }
        for seed in range(4)
    ]
    lines, found = paper_sections.ur3_section(rows)
    text = "\n".join(lines)
    assert found == [
        "UR3 window under the paper's protocol (one full roadmap of 300 samples per leg): LFBS 3/4, median 36 s per "
        "job (paper: 253 s average)."
    ]
    assert "| window | lfbs | full | 4 | 3/4 [19%, 99%] |" in text  # Clopper-Pearson for 3 of 4
    assert f"Runs per job and sampler: 4, not {paper.TARGET_TRIALS}" in text
    assert "about 3 h of one core" in text  # 300 runs x 36 s, one cell


def test_bench_uav_table_counts_the_runs_whose_sampler_gave_up():
    from app.bench import uav

    def row(seed, metrics):
        return {"scene": "maze", "step": 0.5, "method": "rbbs", "seed": seed, "metrics": metrics}

    rows = [row(s, {"success": 0.0, "seconds": 40.0, "collision_checks": 2_000_300, "nodes": 2}) for s in range(2)]
    rows.append(row(2, {"success": 0.0, "seconds": 9.0, "collision_checks": 80_000, "nodes": 502}))
    rows.append(row(3, {"success": 1.0, "seconds": 5.0, "collision_checks": 90_000, "nodes": 502}))
    (cell,) = uav.table(rows)
    assert (cell["runs"], cell["sampler_gave_up"], cell["success_rate"]) == (4, 2, 0.25)
