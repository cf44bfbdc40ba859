"""`bench changes`: a work cell that changes, and what each change costs a stored roadmap -- repaired
(`CellRoadmap.changed`) against built again for the new cell -- and the queries after it.

Per cell (window, welding), from one roadmap built as `roadmap build` builds it (covered), each change of `CHANGES`
is applied to that roadmap on its own (a fixture moved by 1, 5 and 20 cm, a box added in the work area, an obstacle
removed, a 10 cm part attached at the tool), and in the cell it leaves:
- repair: the roadmap repaired, its checks and seconds; then the change's query set answered on it, in order, the
  roadmap keeping what each query learned (as `plan --roadmap --update` would);
- rebuild: a roadmap built again for the new cell (covered), its checks and seconds; then the same queries on it;
- fresh: each query planned on its own (`app.plan`);
- ompl-prm (not among the default methods: it re-checks the whole graph and OMPL stops on time only): one OMPL PRM,
  grown in the cell for as many seconds as the cell's roadmap build took, keeping its milestones in order
  (`OmplProblem.use_milestones`); after the change, that graph re-validated in the new cell, as MoveIt re-checks a
  persistent roadmap after a scene change: every milestone checked again through our checker and the free ones
  added again in order, each connected as PRM connects them, every motion checked (`OmplProblem.regrow`; its checks
  and seconds are the method's preparation); then the queries, the graph kept across them (`clearQuery()`, as
  `bench queries`' ompl-prm), `ompl_seconds` each, smoothed, never certified.
Queries are the `bench queries` set of the new cell ("own" mix: a work cell's chained tool poses, half of them in its
hard region), made with the same seed for every change. Every answer is re-checked by the audit's independent checker
(app.bench.audit.Recheck, a diagram of its own built from the changed cell's files) at 1/64 of the resolution: the
colliding states are counted, payload included.

Each (cell, change, method) is a trial of experiment "changes" in the results store, so a killed run resumes at the
next trial; the base roadmap is built again when a cell has a trial to run (the build is seeded: the same roadmap).
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np
from tqdm import tqdm

from app.bench.queries import Settings, _ompl_answer, _ours, answer_all, build_cell, make_queries
from app.bench.statistics import median_or_none
from app.bench.store import ResultStore, TrialSpec
from app.planning.settings import default_step
from app.scene.changes import Attachment, CellChange, Move, Placement, Solid

EXPERIMENT = "changes"
METHODS = ("repair", "rebuild", "fresh", "ompl-prm")
DEFAULT_METHODS = ("repair", "rebuild", "fresh")
GOALS = {"repair over rebuild": 0.1, "median query seconds": 0.06}
# A 10 cm part held beside the torch, along it (ahead of the tip, it would keep the tool off the named poses).
PART = Attachment(name="part", link="tcp", cylinder=[0.02, 0.1], pose=Placement(xyz=[0.0, 0.05, -0.08]))
CRATE = Solid(name="crate", box=[0.1, 0.1, 0.1], pose=Placement(xyz=[0.0, 0.4, 0.45]))  # on the side table
CLAMP = Solid(name="clamp", box=[0.1, 0.1, 0.1], pose=Placement(xyz=[0.3, -0.5, 0.93]))  # over the near rail


def _moves(name: str, axis: int) -> list[tuple[str, CellChange]]:
    out = []
    for cm in (1, 5, 20):
        offset = [0.0, 0.0, 0.0]
        offset[axis] = cm / 100
        out.append((f"move {name} {cm} cm", CellChange(move=[Move(name=name, pose=Placement(xyz=offset), by=True)])))
    return out


# Per cell: (label, change). The window's fixture holds the part behind the hatch; the welding cell's cross members
# stand in the chassis section the torch works in.
CHANGES = {
    "window": [
        *_moves("fixture", 1),
        ("add a box", CellChange(add=[CRATE])),
        ("remove the fixture", CellChange(remove=["fixture"])),
        ("attach a 10 cm part", CellChange(attach=[PART])),
    ],
    "welding": [
        *_moves("cross_member_2", 0),
        (
            "add a box",
            CellChange(add=[Solid(name="clamp", box=[0.1, 0.1, 0.1], pose=Placement(xyz=[0.3, -0.5, 0.93]))]),
        ),
        ("remove a cross member", CellChange(remove=["cross_member_1"])),
        ("attach a 10 cm part", CellChange(attach=[PART])),
    ],
}


def _answer_checked(recheck, oracle, solve, start, goals, seed, budget) -> dict:
    """`_ours`, with the answer re-checked by the independent checker at 1/64 of the resolution."""
    from app.bench.audit import DIVISOR, states

    kept = {}

    def solved(*args):
        kept["result"] = solve(*args)
        return kept["result"]

    out = _ours(oracle, solved, start, goals, seed, budget)
    if out["success"]:
        trajectory = kept["result"].trajectory
        Q = states(trajectory, oracle.space.weights, oracle.space.resolution / DIVISOR)
        colliding, _ = recheck.check(Q)
        out.update(states_rechecked=len(Q), colliding_states=int(colliding.sum()))
    return out


def _colliding(recheck, oracle, path) -> dict:
    """The independent re-check of a path's straight lines at 1/64 of the resolution."""
    from app.bench.audit import DIVISOR, lines

    Q = lines(path, oracle.space.weights, oracle.space.resolution / DIVISOR)
    colliding, _ = recheck.check(Q)
    return {"states_rechecked": len(Q), "colliding_states": int(colliding.sum())}


def _answers(recheck, oracle, queries, solve, settings: Settings, progress) -> list[dict]:
    def answer(i, start, goals):
        return _answer_checked(recheck, oracle, solve, start, goals, settings.seed + i, settings.budget)

    return answer_all(queries, answer, progress)


def grow_prm(oracle, settings: Settings, seconds: float) -> dict:
    """OMPL's PRM grown in the cell for `seconds`: its milestones in the order it added them, and what it took."""
    from app.ompl_bridge import OmplProblem

    problem = OmplProblem(oracle, seed=settings.seed, planner="PRM")
    problem.use_milestones()
    clock = time.perf_counter()
    problem.grow(seconds)
    return {
        "milestones": problem.milestones,
        "seconds": time.perf_counter() - clock,
        "checks": int(problem.checker.checks),
        "nodes": int(problem.planner.milestoneCount()),
        "edges": int(problem.planner.edgeCount()),
    }


def _ompl_prm(prm: dict, oracle, recheck, queries, settings: Settings, progress) -> dict:
    """The PRM grown in the cell (`grow_prm`), its graph re-validated in the changed cell `oracle`, then the queries."""
    from app.ompl_bridge import OmplProblem

    problem = OmplProblem(oracle, seed=settings.seed, planner="PRM")
    clock = time.perf_counter()
    problem.regrow(prm["milestones"])
    prepare = {
        "seconds": time.perf_counter() - clock,
        "checks": int(problem.checker.checks),
        "nodes": int(problem.planner.milestoneCount()),
        "edges": int(problem.planner.edgeCount()),
        "grown": {key: prm[key] for key in ("seconds", "checks", "nodes", "edges")},
    }

    def answer(i, start, goals):
        out = _ompl_answer(oracle, problem, start, goals, settings.ompl_seconds)
        if out["success"]:
            out.update(_colliding(recheck, oracle, problem.solution_for_oracle()))
        return out

    return {"prepare": prepare, "answers": answer_all(queries, answer, progress)}


def _trial(method, base, oracle, recheck, queries, settings, progress) -> dict:
    """One method's trial in the changed cell `oracle`: how it came by its roadmap (none for fresh) and its answers.
    `base`: the cell's roadmap, or for ompl-prm the PRM grown in the cell (`grow_prm`)."""
    from app.planning.query import plan

    if method == "ompl-prm":
        return _ompl_prm(base, oracle, recheck, queries, settings, progress)
    if method == "fresh":

        def solve(start, goals, plan_settings):
            return plan(oracle, plan_settings, start=start, goal=goals)

        return {"prepare": None, "answers": _answers(recheck, oracle, queries, solve, settings, progress)}
    if method == "repair":
        clock = time.perf_counter()
        cell = base.changed(oracle.scene.changes)
        seconds = time.perf_counter() - clock
        record = cell.provenance["changes"][-1]
        prepare = {"seconds": seconds, "checks": record["collision_checks"], "record": record}
    else:
        cell, seconds, checks, _ = build_cell(oracle, settings)
        prepare = {"seconds": seconds, "checks": checks}
    prepare["nodes"] = len(cell)
    answers = _answers(recheck, cell.oracle, queries, cell.solve, settings, progress)
    return {"prepare": prepare, "answers": answers}


def measure(scenes: list[str], methods: list[str], settings: Settings, store_path, fresh: bool = False):
    """Every cell's changes, each with its query set answered by every method (stored trials reused). Returns
    (report, Reuse)."""
    from app.bench.audit import Recheck
    from app.bench.queries import _merged
    from app.checking.oracle import CollisionOracle, default_threads
    from app.scene.changes import changed_scene
    from app.scene.model import Scene

    if "ompl-prm" in methods:
        from app.ompl_bridge import ompl_modules

        ompl_modules()  # not installed: one line, before any build
    store = ResultStore(store_path)
    out, reused = [], []
    try:
        for name in scenes:
            oracle = CollisionOracle(Scene(name), threads=max(settings.workers, default_threads()))
            step = default_step(oracle.scene)
            specs = {
                (label, method): TrialSpec(
                    EXPERIMENT, name, method, step, settings.seed, _params(label, method, settings)
                )
                for label, _ in CHANGES[name]
                for method in methods
            }
            reused.append(store.reuse(list(specs.values()), fresh=fresh))
            pending = {s.key for s in store.pending(list(specs.values()), fresh=fresh)}
            base, prm = None, None
            if pending:
                print(f"{name}: building the cell's roadmap", file=sys.stderr, flush=True)  # (stdout: the answer)
                base, base_seconds, base_checks, _ = build_cell(oracle, settings)
            if "ompl-prm" in methods and any(specs[label, "ompl-prm"].key in pending for label, _ in CHANGES[name]):
                print(f"{name}: growing OMPL's PRM for {base_seconds:.1f} s", file=sys.stderr, flush=True)
                prm = grow_prm(oracle, settings, base_seconds)
            rows = []
            for label, change in CHANGES[name]:
                todo = [m for m in methods if specs[label, m].key in pending]
                if todo:
                    changed = oracle.of_scene(changed_scene(oracle.scene, [change]))
                    recheck = Recheck(str(changed.scene.path))
                    with tqdm(total=settings.queries, desc=f"{name} {label}: queries", leave=False) as bar:
                        queries = make_queries(changed, settings.queries, settings.seed, bar.update)
                for method in todo:
                    with tqdm(total=settings.queries, desc=f"{name} {label}: {method}", leave=False) as bar:
                        roadmap = prm if method == "ompl-prm" else base
                        metrics = _trial(method, roadmap, changed, recheck, queries, settings, bar.update)
                    metrics.update(query_set=queries.digest(), load_average=os.getloadavg()[1], change=change.to_dict())
                    if method == "rebuild":
                        metrics["base"] = {"seconds": base_seconds, "checks": base_checks}
                    store.add(specs[label, method], metrics)
                stored = {m: store.rows_for([specs[label, m]])[0] for m in methods}
                rows.append(summarise(label, {m: r["metrics"] for m, r in stored.items()}))
                rows[-1]["code_versions"] = {m: r["code_version"] for m, r in stored.items()}
            out.append({"scene": name, "changes": rows})
        reuse = _merged(reused)
    finally:
        store.close()
    report = {
        "scenes": out,
        "queries": settings.queries,
        "seed": settings.seed,
        "budget": str(settings.budget),
        "build_nodes": settings.build_nodes,
        "workers": settings.workers,
        "methods": list(methods),
        "ompl_seconds": settings.ompl_seconds if "ompl-prm" in methods else None,
        "goals": GOALS,
    }
    return report, reuse


def _params(label: str, method: str, settings: Settings) -> dict:
    ompl = {"ompl_seconds": settings.ompl_seconds} if method == "ompl-prm" else {}
    return {
        **ompl,
        "change": label,
        "queries": settings.queries,
        "budget": str(settings.budget),
        "build_nodes": settings.build_nodes,
        "build_budget": str(settings.build_budget),
        "workers": settings.workers,
    }


def summarise(label: str, found: dict) -> dict:
    """One change's row: per method its preparation (repair or rebuild), success, certified share, median query
    checks and seconds, colliding states re-checked; and repair over rebuild in checks and seconds."""
    methods = {}
    for method, metrics in found.items():
        answers = metrics["answers"]
        won = [a for a in answers if a["success"]]
        methods[method] = {
            "prepare": metrics["prepare"],
            "queries": len(answers),
            "successes": len(won),
            "certified": sum(a["certified"] for a in won),
            "median_checks": median_or_none([a["checks"] for a in answers]),
            "median_seconds": median_or_none([a["seconds"] for a in answers]),
            "states_rechecked": sum(a.get("states_rechecked", 0) for a in won),
            "colliding_states": sum(a.get("colliding_states", 0) for a in won),
            "seconds": [a["seconds"] for a in answers],
        }
    row = {"change": label, "methods": methods}
    repair, rebuild = methods.get("repair"), methods.get("rebuild")
    if repair and rebuild:
        row["repair_over_rebuild"] = {
            key: repair["prepare"][key] / rebuild["prepare"][key] if rebuild["prepare"][key] else None
            for key in ("checks", "seconds")
        }
    return row


def figure(report: dict, path: str) -> None:
    """Per cell: for each change, what repair and rebuild took (seconds, log scale), and each method's median query
    seconds beside them."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from app.draw import save

    scenes = report["scenes"]
    fig, axes = plt.subplots(
        2, len(scenes), figsize=(7.4 * len(scenes), 7.0), squeeze=False, layout="constrained", sharey="row"
    )
    for column, s in enumerate(scenes):
        labels = [r["change"] for r in s["changes"]]
        x = np.arange(len(labels))
        top, bottom = axes[0, column], axes[1, column]
        prepared = [m for m in report["methods"] if m != "fresh"]
        width = 0.8 / max(1, len(prepared))
        for i, method in enumerate(prepared):
            seconds = [r["methods"].get(method, {}).get("prepare", {}) or {} for r in s["changes"]]
            offset = (i - (len(prepared) - 1) / 2) * width
            top.bar(x + offset, [p.get("seconds", np.nan) for p in seconds], width * 0.95, label=method, color=f"C{i}")
        top.set_yscale("log")
        top.set_title(f"{s['scene']}: preparing the roadmap for the change", fontsize=10)
        top.set_ylabel("seconds", fontsize=9)
        width = 0.8 / len(report["methods"])
        for i, method in enumerate(report["methods"]):
            medians = [r["methods"].get(method, {}).get("median_seconds") for r in s["changes"]]
            offset = (i - (len(report["methods"]) - 1) / 2) * width
            bottom.bar(x + offset, [np.nan if m is None else m for m in medians], width * 0.95, label=method)
        bottom.axhline(GOALS["median query seconds"], color="black", lw=1, ls=":", label="60 ms")
        bottom.set_yscale("log")
        bottom.set_title(
            f"{s['scene']}: median seconds per query after the change ({report['queries']} queries)", fontsize=10
        )
        bottom.set_ylabel("seconds", fontsize=9)
        for ax in (top, bottom):
            ax.set_xticks(x, labels, rotation=20, ha="right", fontsize=8)
            ax.grid(alpha=0.3, axis="y", which="both")
            ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))  # beside the bars, hiding none
    save(fig, path)


def check_methods(methods: list[str]) -> list[str]:
    return [m for m in METHODS if m in methods]
