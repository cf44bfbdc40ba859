"""The results store as OMPL's benchmark database, so OMPL's tools (Planner Arena, `ompl_benchmark_statistics.py`
--plot) can read and plot our runs.

The layout is the SQLite one `ompl_benchmark_statistics.py` writes from OMPL benchmark logs (OMPL 2.0): tables
experiments, plannerConfigs, enums (the `status` enum of ompl::base::PlannerStatus), runs (one column per run
property) and progress (left empty: trials record no progress over time). Mapping:
- one experiment per experiment kind x scene x step ("sampling bar a=10"), its `setup` the trials' parameters;
- one planner config per method (sampler) of an experiment, its `settings` the method's parameters;
- one run per trial: `time` (seconds), `solved` (a sampling trial drew its K_c samples within the check budget, a
  PRM or UR3 trial succeeded), `status` (EXACT_SOLUTION when solved, else TIMEOUT: what OMPL reports when its
  termination condition ends a planner without a solution), `seed`, and every other numeric metric of the trial
  (collision_checks, passage_fraction, ...), plus `passage_yield` for sampling trials (`claims.passage_yield`).
"""

from __future__ import annotations

import json
import platform
import sqlite3
import time
from pathlib import Path

from app.bench.claims import passage_yield
from app.bench.paper import machine
from app.io import write_atomically

# ompl::base::PlannerStatus::asString() for StatusType 0..7, as OMPL's benchmark logs list the enum.
STATUS = [
    "Unknown status",
    "Invalid start",
    "Invalid goal",
    "Unrecognized goal type",
    "Timeout",
    "Approximate solution",
    "Exact solution",
    "Crash",
]
TIMEOUT, EXACT_SOLUTION = STATUS.index("Timeout"), STATUS.index("Exact solution")

SCHEMA = """
CREATE TABLE experiments
    (id INTEGER PRIMARY KEY AUTOINCREMENT, name VARCHAR(512), totaltime REAL, timelimit REAL, memorylimit REAL,
    runcount INTEGER, version VARCHAR(128), hostname VARCHAR(1024), cpuinfo TEXT, date DATETIME, seed VARCHAR(24),
    setup TEXT);
CREATE TABLE plannerConfigs (id INTEGER PRIMARY KEY AUTOINCREMENT, name VARCHAR(512) NOT NULL, settings TEXT);
CREATE TABLE enums (name VARCHAR(512), value INTEGER, description TEXT, PRIMARY KEY (name, value));
CREATE TABLE runs
    (id INTEGER PRIMARY KEY AUTOINCREMENT, experimentid INTEGER, plannerid INTEGER,
    FOREIGN KEY (experimentid) REFERENCES experiments(id) ON DELETE CASCADE,
    FOREIGN KEY (plannerid) REFERENCES plannerConfigs(id) ON DELETE CASCADE);
CREATE TABLE progress
    (runid INTEGER, time REAL, PRIMARY KEY (runid, time), FOREIGN KEY (runid) REFERENCES runs(id) ON DELETE CASCADE);
"""


def run_properties(row: dict) -> dict:
    """The run properties of one store row: OMPL's time/solved/status, the seed, and the trial's metrics (`write`
    keeps those that are numbers)."""
    m = row["metrics"]
    solved = bool(m["success"]) if "success" in m else not m.get("censored", False)
    props = {
        "time": m.get("seconds"),
        "solved": solved,
        "status": EXACT_SOLUTION if solved else TIMEOUT,
        "seed": int(row["seed"]),
    }
    if row["experiment"] == "sampling":
        props["passage_yield"] = passage_yield(m)
    props.update({key: value for key, value in m.items() if key not in props and key != "seconds"})
    return props


def _column_type(key: str, values: list) -> str | None:
    """The SQL type OMPL's logs would give a run property; None for a property that is not a number."""
    present = [v for v in values if v is not None]
    if key == "status":
        return "ENUM"
    if not present or not all(isinstance(v, (bool, int, float)) for v in present):
        return None
    if all(isinstance(v, bool) for v in present):
        return "BOOLEAN"
    return "INTEGER" if all(isinstance(v, int) for v in present) else "REAL"


def write(rows: list[dict], path: str | Path) -> Path:
    """Write the store rows `rows` to `path` as an OMPL benchmark database (replacing the file, atomically)."""
    groups: dict[tuple, dict[str, list[dict]]] = {}
    for r in rows:
        groups.setdefault((r["experiment"], r["scene"], float(r["step"])), {}).setdefault(r["method"], []).append(r)
    props = {id(r): run_properties(r) for r in rows}
    values: dict[str, list] = {}
    for p in props.values():
        for key, value in p.items():
            values.setdefault(key, []).append(value)
    columns = {key: _column_type(key, v) for key, v in values.items()}
    columns = {key: kind for key, kind in columns.items() if kind}
    hostname, cpuinfo = platform.node(), "\n".join(machine())
    date = time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime())
    db = sqlite3.connect(":memory:")
    db.executescript(SCHEMA)
    for key, kind in columns.items():
        db.execute(f'ALTER TABLE runs ADD "{key}" {kind}')
    db.executemany("INSERT INTO enums VALUES (?,?,?)", [("status", i, text) for i, text in enumerate(STATUS)])
    planners: dict[tuple, int] = {}
    for (experiment, scene, step), methods in sorted(groups.items()):
        trials = [r for method_rows in methods.values() for r in method_rows]
        versions = sorted({r["code_version"] for r in trials})
        params = trials[0]["params"]
        cursor = db.execute(
            "INSERT INTO experiments (name, totaltime, timelimit, memorylimit, runcount, version, hostname, cpuinfo, "
            "date, seed, setup) VALUES (?,?,?,?,?,?,?,?,?,?,?)",
            (
                f"{experiment} {scene} a={step:g}",
                sum(props[id(r)]["time"] or 0.0 for r in trials),
                float(params.get("budget", 0.0)),
                0.0,
                max(len(v) for v in methods.values()),
                "narrow-passage-planner " + ", ".join(versions),
                hostname,
                cpuinfo,
                date,
                "0",
                json.dumps({"experiment": experiment, "scene": scene, "step": step, "params": params}, sort_keys=True),
            ),
        )
        experiment_id = cursor.lastrowid
        for method, method_rows in sorted(methods.items()):
            settings = json.dumps(method_rows[0]["params"], sort_keys=True)
            if (method, settings) not in planners:
                cursor = db.execute("INSERT INTO plannerConfigs (name, settings) VALUES (?,?)", (method, settings))
                planners[(method, settings)] = cursor.lastrowid
            for r in sorted(method_rows, key=lambda r: r["seed"]):
                p = {key: value for key, value in props[id(r)].items() if key in columns}
                names = ", ".join(f'"{k}"' for k in p)
                db.execute(
                    f"INSERT INTO runs (experimentid, plannerid, {names}) VALUES (?,?,{','.join('?' * len(p))})",
                    (experiment_id, planners[(method, settings)], *p.values()),
                )
    db.commit()
    content = db.serialize()
    db.close()
    return write_atomically(path, content)
