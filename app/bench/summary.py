"""`bench summary`: the tables the benchmark page opens with, one per question a user asks, read from the results
stores under results/. Nothing is run: every figure is a stored trial's, summarised as the bench that wrote it
summarises it (`plan.summarise`, `ompl.summarise`, `queries.summarise`), and each table names the command that makes
its store (run again, that command reuses the stored trials and prints the same figures; with --fresh it measures
the current code) and the code versions and dates of the rows it read.

- How fast on the shipped scenes: `bench plan` rows of the planner's default sampler and roadmap size, query mode,
  no budget of their own (what `plan SCENE --seed S` does), results/plan/bench-plan.sqlite.
- Against OMPL: `bench ompl` rows of `ours:default` and OMPL's four planners on one budget,
  results/ompl/bench-ompl.sqlite.
- With a stored roadmap: the latest `bench queries` run per scene, results/queries/bench-queries.sqlite.
- On MoveIt's problems: not measured yet; the table's place says so.

The tables go between the two marker lines (BEGIN, END) of the page, which nothing else writes.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from app.bench import moveit, ompl, plan, queries
from app.bench.store import ResultStore, TrialSpec, is_results_store
from app.checking.budget import SAFETY_NET_SECONDS, Budget
from app.errors import UserError
from app.io import check_input, write_atomically
from app.planning.settings import PlanSettings
from app.scene.files import ROOT
from app.scene.model import scene_names

PAGE = ROOT / "docs" / "benchmarks.md"
RESULTS = ROOT / "results"
BEGIN = "<!-- bench summary: begin (python -m app bench summary writes from here to the end line; edits are lost) -->"
END = "<!-- bench summary: end -->"

# Each table's store, relative to the results folder (and named so in the commands shown, under results/).
STORES = {
    "scenes": "plan/bench-plan.sqlite",
    "ompl": "ompl/bench-ompl.sqlite",
    "queries": "queries/bench-queries.sqlite",
    "moveit": "moveit/moveit.sqlite",
}
# The rows of `bench plan` that are a plain `plan`: the default sampler, roadmap size, k and smoothing, query mode.
PLAN_PARAMS = {
    **plan.trial_params(**{k: plan.SIZE[k] for k in ("narrow", "uniform", "k", "smooth")}),
    "full_roadmap": False,
}
OMPL_METHODS = [ompl.OURS] + [f"ompl:{p}" for p in ompl.OMPL_PLANNERS]
OMPL_NAMES = {"ompl:RRTConnect": "RRTConnect", "ompl:BITstar": "BIT\\*", "ompl:PRM": "PRM", "ompl:KPIECE1": "KPIECE1"}
QUERY_NAMES = {
    "fresh": "fresh single queries",
    "cell": "one cell roadmap",
    "ompl-prm": "OMPL PRM, graph kept",
    "ompl-rrtconnect": "OMPL RRTConnect",
}
# bench queries' command-line defaults, left out of the command shown
QUERY_DEFAULTS = {
    "budget": str(Budget(seconds=SAFETY_NET_SECONDS, checks=queries.Settings.budget.checks)),
    "build_budget": str(queries.Settings.build_budget),
    "build_nodes": queries.Settings.build_nodes,
    "ompl_seconds": queries.Settings.ompl_seconds,
}


@dataclass
class Stored:
    """A store's rows of one table, with when each was written (seconds since the epoch)."""

    path: str  # as the commands shown name it: results/...
    rows: list[dict]
    finished: list[float]


def _open(results: Path, table: str, command: str) -> tuple[str, ResultStore]:
    shown = f"results/{STORES[table]}"
    path = Path(results) / STORES[table]
    if not path.exists():
        raise UserError(f"no results store {path}: `{command.replace(shown, str(path))}` makes it")
    check_input(path, "results store")
    if not is_results_store(path):
        raise UserError(f"{path} is not a results store (a SQLite file with a trials table)")
    return shown, ResultStore(path)


def _read(results: Path, table: str, command: str, keep) -> Stored:
    """The rows of `table`'s store that `keep(row)` takes; UserError (one line) when the store is missing or holds
    none."""
    stored_as, store = _open(results, table, command)
    try:
        rows = [r for r in store.rows() if keep(r)]
        finished = store.finished()
    finally:
        store.close()
    if not rows:
        path = results / STORES[table]
        raise UserError(f"{path} holds no rows for this table: `{command.replace(stored_as, str(path))}` adds them")
    when = [
        finished[TrialSpec(r["experiment"], r["scene"], r["method"], r["step"], r["seed"], r["params"]).key]
        for r in rows
    ]
    return Stored(stored_as, rows, when)


# ---- formatting ---------------------------------------------------------------------------------------------------
def _date(seconds: float) -> str:
    return time.strftime("%Y-%m-%d", time.gmtime(seconds))


def _version(version: str) -> str:
    """A code version as a commit's short hash, '+dirty' when the tree had uncommitted changes."""
    commit, _, dirty = version.partition("+")
    return f"{commit[:7]}{'+dirty' if dirty else ''}"


def _dates(times: list[float]) -> str:
    first, last = _date(min(times)), _date(max(times))
    return first if first == last else f"{first} to {last}"


def _provenance(stored: Stored, by=lambda r: "") -> str:
    """The code versions and dates of the rows, grouped by what `by` names of a row: "ours: code `a1b2c3d`,
    2026-12-06; OMPL: code `d4e5f6a`, `0718293`, 2026-12-02" (the latest first)."""
    groups: dict[str, dict[str, list[float]]] = {}
    for r, t in zip(stored.rows, stored.finished):
        groups.setdefault(by(r), {}).setdefault(r["code_version"], []).append(t)
    parts = []
    for name, versions in sorted(groups.items(), key=lambda g: -max(max(t) for t in g[1].values())):
        order = sorted(versions, key=lambda v: -max(versions[v]))
        when = _dates([t for v in order for t in versions[v]])
        label = f"{name}: " if name else ""
        parts.append(f"{label}code {', '.join(f'`{_version(v)}`' for v in order)}, {when}")
    return "; ".join(parts)


def _load(rows: list[dict]) -> str:
    """The machine's load average the rows' seconds were measured under, where they recorded it."""
    values = [r["metrics"]["load_average"] for r in rows if r["metrics"].get("load_average") is not None]
    if not values:
        return ""
    said = f"{min(values):.1f}-{max(values):.1f}" if len(values) > 1 else f"{values[0]:.1f}"
    where = "" if len(values) == len(rows) else f" (recorded by {len(values):,} of the {len(rows):,} rows)"
    return f"; load average {said}{where}"


def _count(value) -> str:
    return "-" if value is None else f"{value:,.0f}"


def _short(value) -> str:
    """A check count in three figures at most: 950, 4.1k, 32k, 151k, 1.2M."""
    if value is None:
        return "-"
    for unit, scale in (("M", 1e6), ("k", 1e3)):
        if value >= scale:
            v = value / scale
            return f"{v:.1f}{unit}" if v < 10 else f"{v:.0f}{unit}"
    return f"{value:.0f}"


def _seconds(value) -> str:
    if value is None:
        return "-"
    return f"{value:.3f}" if value < 1 else f"{value:.2f}" if value < 10 else f"{value:.1f}"


def _ratio(value) -> str:
    return "-" if value is None else f"{value:.3g}x"


def _share(value) -> str:
    return "-" if value is None else f"{value:.0%}".replace("%", " %")


def _wrapped(command: str, width: int = 80) -> str:
    """A command as a shell block shows it: broken before a flag where a line would pass `width`, each break a
    backslash, the lines after indented."""
    lines, line = [], ""
    for word in command.replace(" --", "\0--").split("\0"):
        if line and len(line) + 1 + len(word) > width:
            lines.append(line + " \\")
            line = "    " + word
        else:
            line = f"{line} {word}" if line else word
    return "\n".join([*lines, line])


def _scene_order(names) -> list[str]:
    shipped = scene_names()
    return sorted(set(names), key=lambda s: (shipped.index(s) if s in shipped else len(shipped), s))


# ---- the tables ---------------------------------------------------------------------------------------------------
def scenes_table(results: Path) -> list[str]:
    """How fast on the shipped scenes: success, median checks and seconds, certified share, per scene."""
    sampler = PlanSettings.sampler
    command = (
        f"python -m app bench plan --scenes {','.join(scene_names())} --samplers {sampler} --seeds 20 --workers 1 "
        f"--store results/{STORES['scenes']}"
    )
    stored = _read(
        results,
        "scenes",
        command,
        lambda r: r["experiment"] == "prm" and r["method"] == sampler and r["params"] == PLAN_PARAMS,
    )
    cells = {r["scene"]: r for r in plan.summarise(stored.rows)}
    order = _scene_order(cells)
    seeds = max(r["seed"] for r in stored.rows) + 1
    runs = sorted({c["runs"] for c in cells.values()})
    command = command.replace(f"--scenes {','.join(scene_names())}", f"--scenes {','.join(order)}")
    command = command.replace("--seeds 20", f"--seeds {seeds}")
    lines = [
        "### How fast on the shipped scenes?",
        "",
        f"Each scene's own query planned as `plan SCENE --seed S` plans it (sampler `{sampler}`, certified and "
        f"timed), {' or '.join(map(str, runs))} seeds a scene. Checks: collision checks of the whole query, the same "
        "on any machine; seconds: the whole query, on the machine and load of the run. Store: `python -m app bench "
        f"plan` rows in `{stored.path}`, {_provenance(stored)}{_load(stored.rows)}.",
        "",
        "```sh",
        _wrapped(command),
        "```",
        "",
        "| scene | success | median checks | median seconds | certified |",
        "|---|---:|---:|---:|---:|",
    ]
    for scene in order:
        c = cells[scene]
        lines.append(
            f"| `{scene}` | {c['successes']}/{c['runs']} | {_count(c['median_checks'])} | "
            f"{_seconds(c['median_seconds'])} | {_share(c.get('certified_share'))} |"
        )
    lines += [
        "",
        "Medians over all runs, failures included (a failure counts what it spent); certified: of the successes.",
    ]
    return lines


def _budget_of(rows: list[dict]) -> float:
    """The budget most of the OMPL table's rows were run on."""
    budgets = [float(r["params"]["budget"]) for r in rows]
    values, counts = np.unique(budgets, return_counts=True)
    return float(values[np.argmax(counts)])


def ompl_table(results: Path) -> list[str]:
    """Against OMPL: successes and median checks to the first solution, ours and OMPL's four planners, per scene."""
    command = (
        f"python -m app bench ompl --methods {','.join(OMPL_METHODS)} --seeds 20 --budget 10 --workers 1 "
        f"--store results/{STORES['ompl']}"
    )

    def keep(r):
        return (
            r["experiment"] == "ompl" and r["method"] in OMPL_METHODS and r["params"].get("protocol") == ompl.PROTOCOL
        )

    stored = _read(results, "ompl", command, keep)
    budget = _budget_of(stored.rows)
    index = [i for i, r in enumerate(stored.rows) if float(r["params"]["budget"]) == budget]
    stored = Stored(stored.path, [stored.rows[i] for i in index], [stored.finished[i] for i in index])
    summary = ompl.summarise(stored.rows)
    order = _scene_order(r["scene"] for r in summary)
    methods = [m for m in OMPL_METHODS if any(r["method"] == m for r in summary)]
    seeds = max(r["seed"] for r in stored.rows) + 1
    command = command.replace("--seeds 20 --budget 10", f"--seeds {seeds} --budget {budget:g}")
    command = command.replace(f"--methods {','.join(OMPL_METHODS)}", f"--methods {','.join(methods)}")
    if order != scene_names():
        command = command.replace("--methods", f"--scenes {','.join(order)} --methods")
    ompl_rows = [r for r in stored.rows if r["method"].startswith("ompl:")]
    ompl_hours = sum(r["metrics"]["seconds"] + r["metrics"].get("smoothing_seconds", 0.0) for r in ompl_rows) / 3600
    names = [OMPL_NAMES.get(m, m) for m in methods]
    lines = [
        "### Against OMPL?",
        "",
        f"Each scene's own query, {seeds} runs a method, {budget:g} s (wall clock) to the first solution; every "
        "collision check through our oracle, so checks count the same thing for every planner; a path counts once it "
        f"is smoothed and passes our fine check at 1/4 of the resolution. Ours: `{ompl.OURS}`, the planner as "
        "`plan` runs it. Cells: successes, and in brackets the "
        "median checks to the first solution over them; last column: our median checks over the best OMPL planner's "
        f"(most successes, then fewer checks). Store: `{stored.path}`, "
        f"{_provenance(stored, by=lambda r: 'ours' if r['method'].startswith('ours:') else 'OMPL')}"
        f"{_load(stored.rows)}. OMPL's planners stop on time, not on checks, so their rows are kept when ours are "
        f"run again (`--methods {ompl.OURS} --fresh`): OMPL's {len(ompl_rows):,} runs took {ompl_hours:.1f} h.",
        "",
        "```sh",
        _wrapped(command),
        "```",
        "",
        "| scene | " + " | ".join(["ours", *names[1:]]) + " | ours / best OMPL |",
        "|---|" + "---:|" * (len(methods) + 1),
    ]
    for scene in order:
        rows = {r["method"]: r for r in summary if r["scene"] == scene}
        cells = []
        for m in methods:
            r = rows.get(m)
            if r is None:
                cells.append("-")
            else:
                checks = f" ({_short(r['median_checks'])})" if r["successes"] else ""
                cells.append(f"{r['successes']}/{r['runs']}{checks}")
        comparison = ompl.compare([rows[m] for m in methods if m in rows])
        ratio = comparison["checks_ratio"]
        if ratio is not None:
            best = OMPL_NAMES.get(comparison["best_ompl"], comparison["best_ompl"])
            last = f"{ratio:.2g} ({best})"
        elif comparison["best_ompl"] and not rows[comparison["best_ompl"]]["successes"]:
            last = "OMPL none"
        else:
            last = "-"
        lines.append(f"| `{scene}` | " + " | ".join(cells) + f" | {last} |")
    return lines


def _latest_run(stored: Stored) -> Stored:
    """Per scene, the rows of its latest `bench queries` run: those sharing the query set and settings of the row
    written last."""
    latest: dict[str, tuple[float, str]] = {}
    for r, t in zip(stored.rows, stored.finished):
        run = _run_key(r)
        if r["scene"] not in latest or t > latest[r["scene"]][0]:
            latest[r["scene"]] = (t, run)
    index = [i for i, r in enumerate(stored.rows) if latest[r["scene"]][1] == _run_key(r)]
    return Stored(stored.path, [stored.rows[i] for i in index], [stored.finished[i] for i in index])


def _run_key(row: dict) -> str:
    p = row["params"]
    return f"{row['seed']} {p.get('queries')} {p.get('query_set')}"


def _queries_command(rows: list[dict], scenes: list[str]) -> str:
    methods = [m for m in queries.METHODS if any(r["method"] == m for r in rows)]
    params = {}
    for r in rows:
        params.update(r["params"])
    seed = rows[0]["seed"]
    parts = [f"python -m app bench queries --scenes {','.join(scenes)} --queries {params['queries']}"]
    parts.append(f"--methods {','.join(methods)}")
    if seed:
        parts.append(f"--seed {seed}")
    for key, flag in (("budget", "--budget"), ("ompl_seconds", "--ompl-seconds"), ("build_nodes", "--build-nodes"),
                      ("build_budget", "--build-budget")):  # fmt: skip
        if key in params and params[key] != QUERY_DEFAULTS[key]:
            parts.append(f"{flag} {params[key]:g}" if isinstance(params[key], float) else f"{flag} {params[key]}")
    if "workers" in params:
        parts.append(f"--workers {params['workers']}")
    return " ".join(parts) + f" --store results/{STORES['queries']}"


def queries_table(results: Path) -> list[str]:
    """With a stored roadmap: per cell, fresh single queries against one cell roadmap (and OMPL's PRM keeping its
    graph): success, per-query checks and seconds, certified share, totals."""
    command = (
        "python -m app bench queries --scenes window,welding --queries 50 --methods fresh,cell,ompl-prm --workers 1 "
        f"--store results/{STORES['queries']}"
    )
    stored = _latest_run(_read(results, "queries", command, lambda r: r["experiment"] == queries.EXPERIMENT))
    order = _scene_order(r["scene"] for r in stored.rows)
    command = _queries_command(stored.rows, order)
    by = {(r["scene"], r["method"]): r for r in stored.rows}
    lines = [
        "### With a stored roadmap?",
        "",
        "A stream of queries in one UR3 cell (a work cell's sequence of tool poses, each query from where the robot "
        "is; half the poses near the scene's named poses, through the hatch or at the seam), answered by a fresh "
        "single query each, by one cell roadmap built once (as `roadmap build` builds it, the scene's own query "
        "and jobs answered on it) and kept, and by OMPL's PRM keeping its graph (grown for "
        "as long as the cell's build took), in one run through one oracle. Ours: a check budget per query, answers "
        "certified and timed; OMPL: seconds per query, answers smoothed only. Medians and p95 over all queries (a "
        "failure counts what it spent). Store: "
        f"`{stored.path}`, {_provenance(stored)}{_load(stored.rows)}.",
        "",
        "```sh",
        _wrapped(command),
        "```",
        "",
        "| cell | method | success | checks median / p95 | seconds median / p95 | certified | total seconds |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    ratios, unfree = [], []
    for scene in order:
        table = [queries.summarise(m, by[scene, m]["metrics"]) for m in queries.METHODS if (scene, m) in by]
        for r in table:
            name = QUERY_NAMES.get(r["method"], r["method"])
            if r["build"] and r["method"] == "cell":
                name += f" (built once: {r['build']['nodes']:,} nodes, {_seconds(r['build']['seconds'])} s)"
            lines.append(
                f"| `{scene}` | {name} | {r['successes']}/{r['queries']} | {_count(r['median_checks'])} / "
                f"{_count(r['p95_checks'])} | {_seconds(r['median_seconds'])} / {_seconds(r['p95_seconds'])} | "
                f"{_share(r['certified_share'])} | {_seconds(r['total_seconds'])} |"
            )
            if r["failed_fine_check"]:
                unfree.append(f"`{scene}` {r['failed_fine_check']}")
        for q in queries.ratios(table):
            each = "-" if q["per_query"] is None else queries.per_query_words(q["per_query"])
            ratios.append(
                f"| `{scene}` | {QUERY_NAMES.get(q['over'], q['over'])} | {_ratio(q['checks'])} | "
                f"{_ratio(q['seconds'])} | {_ratio(q['seconds_with_builds'])} | {each} |"
            )
    if unfree:
        lines += [
            "",
            "OMPL's answers not free at our fine step (1/4 of the resolution), counted as successes: "
            f"{', '.join(unfree)}.",
        ]
    if ratios:
        lines += [
            "",
            "The cell roadmap's totals over the other methods' on the same queries, in the same run, and the queries "
            f"whose checks on the cell roadmap came to over {queries.GOALS['query vs fresh']:g}x those of the fresh "
            "query from the same start (each method starts where its own last answer left the robot, so the cell "
            "method also answers each query fresh from its own start):",
            "",
            f"| cell | over | checks | seconds | seconds, builds included | queries over "
            f"{queries.GOALS['query vs fresh']:g}x |",
            "|---|---|---:|---:|---:|---|",
            *ratios,
        ]
    return lines


def moveit_table(results: Path) -> list[str]:
    """On MoveIt's problems: the shipped MotionBenchMaker Panda problems, ours against RRTConnect (app.bench.moveit)."""
    command = f"python -m app bench moveit --store results/{STORES['moveit']} --png results/moveit/mbm-panda.png"
    stored = _read(results, "moveit", command, lambda r: r["experiment"] == "moveit")
    methods = [m for m in moveit.METHODS if any(r["method"] == m for r in stored.rows)]
    report = {
        **moveit.summarise(stored.rows, methods),
        "folder": "examples/moveit/mbm-panda",
        "problems": len({r["scene"] for r in stored.rows}),
        "seeds": max(r["seed"] for r in stored.rows) + 1,
        "checks": stored.rows[0]["params"]["checks"],
        "methods": methods,
    }
    body = moveit.table(report).split("\n")
    return [
        "### On MoveIt's problems?",
        "",
        "MotionBenchMaker's Panda problems as MoveIt poses them (`examples/moveit/mbm-panda`: 10 of each of 7 scene "
        "kinds; PlanningScene and MotionPlanRequest files read by `plan --moveit-request`), ours against OMPL's "
        f"RRTConnect through one Drake checker. Store: `{stored.path}`, {_provenance(stored)}{_load(stored.rows)}.",
        "",
        "```sh",
        _wrapped(command),
        "```",
        "",
        *body[2:],
        "",
        body[0],
        "",
        "![MoveIt problems: median seconds per kind, and per problem](results/moveit/mbm-panda.png)",
    ]


def tables(results: Path = RESULTS) -> str:
    """The page's opening block: one table per question, from the stores in `results`. UserError (one line) when a
    store is missing or holds no rows for its table."""
    results = Path(results)
    parts = [
        [
            "The tables below are written by `python -m app bench summary` from the [results "
            "stores](#results-stores) under `results/`; no figure in them is typed in. Each names the command that "
            "makes its store (run again, it reuses the stored trials; with `--fresh` it measures the current code) "
            "and the code versions and dates of the rows it read."
        ],
        scenes_table(results),
        ompl_table(results),
        queries_table(results),
        moveit_table(results),
    ]
    return "\n\n".join("\n".join(p) for p in parts)


def write_page(block: str, page: Path = PAGE) -> bool:
    """Put `block` between the page's BEGIN and END lines; returns whether the page changed. UserError when the page
    lacks either line."""
    page = Path(page)
    try:
        text = page.read_text()
    except FileNotFoundError:
        raise UserError(f"page not found: {page}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read {page}: {getattr(exc, 'strerror', None) or exc}") from None
    start, end = text.find(BEGIN), text.find(END)
    if start < 0 or end < start:
        raise UserError(f"{page} has no lines '{BEGIN}' and '{END}' (in that order) to write the tables between")
    new = text[: start + len(BEGIN)] + "\n\n" + block + "\n\n" + text[end:]
    if new == text:
        return False
    write_atomically(page, new)
    return True
